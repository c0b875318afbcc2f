"""openapi-python-client's client: the same calls as ts/typed.ts, run
against a server (tests/clients/run.sh generates the package first)."""

import io
import json
import os
from pathlib import Path

from accelcal_client import AuthenticatedClient
from accelcal_client.api.calibrations import get_submission, submit_calibration
from accelcal_client.api.sensors import get_coefficients, get_stability, list_sensor_calibrations
from accelcal_client.models import Problem, StoredCalibration, Submission
from accelcal_client.types import File

client = AuthenticatedClient(base_url=os.environ["ACCELCAL_URL"], token=os.environ["ACCELCAL_TOKEN"])

paper = json.loads(Path("examples/paper-table1.json").read_text())
paper["sensor_id"] = "PY-1"
stored = submit_calibration.sync(client=client, body=Submission.from_dict(paper))
assert isinstance(stored, StoredCalibration), stored
csv_text = Path("examples/paper-table1.csv").read_text().replace("PAPER-CSV", "PY-CSV")
csv = submit_calibration.sync(client=client, body=File(payload=io.BytesIO(csv_text.encode())))
assert isinstance(csv, StoredCalibration) and csv.sensor_id == "PY-CSV", csv

coefficients = get_coefficients.sync(client=client, sensor_id="PY-1")
assert coefficients.calibration_id == stored.id, coefficients
history = list_sensor_calibrations.sync(client=client, sensor_id="PY-1", limit=10)
assert history.items[0].id == stored.id, history
stability = get_stability.sync(client=client, sensor_id="PY-1")
assert stability.calibrations == 1, stability
for calibration, sent in [(csv.id, csv_text.encode()), (stored.id, None)]:
    body = get_submission.sync(client=client, id=calibration)
    assert isinstance(body, File), body
    got = body.payload.read()
    if sent is not None:
        assert got == sent, "the CSV comes back byte for byte"
    else:
        assert json.loads(got)["sensor_id"] == "PY-1"

bad = dict(paper, batches=0)
problem = submit_calibration.sync(client=client, body=Submission.from_dict(bad))
assert isinstance(problem, Problem) and problem.status == 422, problem
assert problem.errors[0].pointer == "/batches", problem
print("Python client (openapi-python-client): ok")
