"""Each kind's stored result document, read back by GET /v1/calibrations/{id},
checked against that operation's 200 response schema in openapi.yaml (a oneOf
of the kinds: exactly one must match): a single axis (the paper's Table 1), a
triad (examples/triad-recording.json), a temperature model
(examples/thermal-chamber.json) and a triad's (examples/thermal-triad.json).
Schemathesis rarely stores the last three (its bodies carry no temperatures,
its triads seldom calibrate), so they are stored here. Usage: documents.py BASE_URL TOKEN
"""
import json
import sys
import urllib.request

import jsonschema_rs
import yaml

base, token = sys.argv[1], sys.argv[2]
spec = yaml.safe_load(open("openapi.yaml"))
response = spec["paths"]["/v1/calibrations/{id}"]["get"]["responses"]["200"]
schema = dict(response["content"]["application/json"]["schema"], components=spec["components"])
validator = jsonschema_rs.validator_for(schema)


def call(method, path, body=None):
    req = urllib.request.Request(base + path, method=method, data=body, headers={
        "Authorization": f"Bearer {token}", "Content-Type": "application/json"})
    with urllib.request.urlopen(req) as res:
        return json.load(res)


failed = False
for route, example in [("/v1/calibrations", "examples/paper-table1.json"),
                       ("/v1/calibrations/triad", "examples/triad-recording.json"),
                       ("/v1/calibrations/thermal", "examples/thermal-chamber.json"),
                       ("/v1/calibrations/thermal/triad", "examples/thermal-triad.json")]:
    stored = call("POST", route, open(example, "rb").read())
    doc = call("GET", f"/v1/calibrations/{stored['id']}")
    errors = [str(e) for e in validator.iter_errors(doc)]
    print(f"contract: GET /v1/calibrations/{{id}} of {example}: {'ok' if not errors else errors[:3]}")
    failed = failed or bool(errors)
sys.exit(1 if failed else 0)
