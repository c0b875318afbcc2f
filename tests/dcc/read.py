"""accelcal's DCCs read by PTB's own libraries (issue 43 item 2).

Against a running accelcal (BASE, admin token in ACCELCAL_ADMIN_TOKEN, the
laboratory configured): approves a single-axis calibration (the paper's
Table 1), a triad (examples/triad-recording.json), a temperature model
(examples/thermal-chamber.json, its a_d in units per K^d) and a triad's
(examples/thermal-triad.json) whose free text is
hostile but accepted, fetches their Digital Calibration Certificates, and
reads each with dcc-json-toolkit's content validation (ISO dates, D-SI
units, quantity tables) and every si:unit with dsiUnits. The text must come
back as sent. Exits non-zero on any finding.

Usage: python3 tests/dcc/read.py BASE WORKDIR
"""

import json
import os
import sys
import urllib.error
import urllib.request
import warnings
import xml.etree.ElementTree as ET

from dcc_json_toolkit import DccSourceContent
from dcc_json_toolkit.content_validation import HAS_VALIDATE_CONTENT_IMPORTS, validate_dcc_content
from dsi_unit import DsiUnit

BASE, WORK = sys.argv[1], sys.argv[2]
ADMIN = os.environ["ACCELCAL_ADMIN_TOKEN"]
NS = {"dcc": "https://ptb.de/dcc", "si": "https://ptb.de/si"}

# Text a station or an admin may send: markup, a CDATA end, quotes, an
# entity's text, astral and combining characters, the replacement character.
HOSTILE = "a<b>&amp;]]>\"q\" 'r' <!-- 𝔤 e\u0301 \ufffd z"


def call(method, path, token, body=None, accept="application/json"):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(BASE + path, data=data, method=method)
    req.add_header("Authorization", f"Bearer {token}")
    req.add_header("Accept", accept)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(req) as res:
            raw = res.read()
    except urllib.error.HTTPError as e:
        sys.exit(f"{method} {path}: {e.code} {e.read().decode()}")
    return raw if accept != "application/json" else json.loads(raw or b"null")


def approved(path, body, reviewer, comment):
    stored = call("POST", path, ADMIN, body)
    call("POST", f"/v1/calibrations/{stored['id']}/review", reviewer,
         {"decision": "approve", "comment": comment})
    return stored["id"]


def main():
    # Without its optional imports the toolkit validates nothing, silently.
    if not HAS_VALIDATE_CONTENT_IMPORTS:
        sys.exit("dcc-json-toolkit cannot validate content: install tests/dcc/requirements.txt")
    reviewer = call("POST", "/v1/tokens", ADMIN,
                    {"role": "reviewer", "holder": "Rita " + HOSTILE})["token"]
    call("PUT", "/v1/customers/ACME", ADMIN,
         {"name": "Acme " + HOSTILE, "address": HOSTILE, "due_date_agreed": True})
    for sensor in ["PAPER-2005", "IMU-DEMO-1", "MEMS-TC-7", "IMU-TC-3"]:
        call("PUT", f"/v1/sensors/{sensor}/item", ADMIN,
             {"manufacturer": HOSTILE, "model": HOSTILE, "serial": HOSTILE, "customer": "ACME"})
    stand = json.load(open("examples/standard-stand.json"))
    stand["description"] = HOSTILE
    stand["traceability"] = HOSTILE
    call("PUT", "/v1/standards/STAND-1", ADMIN, stand)

    single = json.load(open("examples/paper-table1.json"))
    # Performed while the stand was in calibration (its certificate: 2026).
    single.update({"unit": "mA", "item_condition": HOSTILE, "standards": {"stand": "STAND-1"},
                   "performed_at": "2026-06-01T08:00:00Z"})
    triad = json.load(open("examples/triad-recording.json"))
    triad["unit"] = "<&]]>\"𝔤'"  # at most 32 characters
    thermometer = dict(stand, kind="thermometer", temperature_std_c=0.05)
    del thermometer["angle_std_arcsec"]
    call("PUT", "/v1/standards/TH-1", ADMIN, thermometer)
    call("PUT", "/v1/sensor-types/IMU-TC", ADMIN,
         {"label": HOSTILE, "unit": "m/s2", "decision_rule": "guarded", "interval_days": 365,
          "limits": {"k0": {"min": -0.5, "max": 0.5}, "ki": {"min": 9.6, "max": 10.0}}})
    thermal_triad = json.load(open("examples/thermal-triad.json"))
    # Judged by a type, with a stand and a thermometer.
    thermal_triad.update({"sensor_type": "IMU-TC", "performed_at": "2026-06-01T08:00:00Z",
                          "standards": {"stand": "STAND-1", "thermometer": "TH-1"}})
    thermal = json.load(open("examples/thermal-chamber.json"))
    thermal.update({"standards": {"stand": "STAND-1"}, "performed_at": "2026-06-01T08:00:00Z"})
    ids = {
        "single-axis": approved("/v1/calibrations", single, reviewer, HOSTILE),
        "triad": approved("/v1/calibrations/triad", triad, reviewer, HOSTILE),
        "temperature model": approved("/v1/calibrations/thermal", thermal, reviewer, HOSTILE),
        "triad temperature model": approved("/v1/calibrations/thermal/triad", thermal_triad,
                                            reviewer, HOSTILE),
    }
    findings = []
    for kind, id_ in ids.items():
        xml = call("GET", f"/v1/calibrations/{id_}/certificate", ADMIN, accept="application/xml")
        path = os.path.join(WORK, f"{kind}.xml")
        with open(path, "wb") as f:
            f.write(xml)
        try:
            root = ET.fromstring(xml)
        except ET.ParseError as e:
            line, col = e.position
            text = xml.decode().splitlines()[line - 1]
            sys.exit(f"{kind}: the DCC is not well-formed: {e}: …{text[max(col - 80, 0):col + 80]}…")
        judged = [c.text for c in root.iter(f"{{{NS['dcc']}}}conformity")]
        if kind == "triad temperature model" and judged != ["pass"]:
            findings.append(f"{kind}: judged by IMU-TC, its DCC states conformity {judged}")
        customer = root.find("dcc:administrativeData/dcc:customer/dcc:name/dcc:content", NS)
        if customer is None or customer.text != "Acme " + HOSTILE:
            findings.append(f"{kind}: the customer's name did not come back as sent")
        errors = validate_dcc_content(DccSourceContent(path))
        findings += [f"{kind}: dcc-json-toolkit: {e}" for e in errors]
        units = [u.text for u in root.iter(f"{{{NS['si']}}}unit")]
        for unit in units:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                parsed = DsiUnit(unit)
            if not parsed.valid or parsed.warnings:
                findings.append(f"{kind}: dsiUnits: {unit!r}: {parsed.warnings}")
        print(f"{kind}: {len(xml)} bytes, {len(units)} si:unit read by dsiUnits "
              f"({', '.join(sorted(set(units)))}), content validation: {len(errors)} finding(s)")
    if findings:
        print("\n".join(findings), file=sys.stderr)
        sys.exit(1)
    print("dcc: every kind's DCC read by dcc-json-toolkit and dsiUnits, the text as sent")


main()
