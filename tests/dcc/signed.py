"""accelcal's signed DCCs checked by outside verifiers (issue 46 item 5).

Against a running accelcal (BASE, admin token in ACCELCAL_ADMIN_TOKEN, the
laboratory configured, signing with WORK/lab.key and WORK/lab.pem):

  issue    approves a single-axis calibration (the paper's Table 1) and a
           triad (examples/triad-recording.json), fetches both DCCs and
           checks each with Debian's xmlsec1 (`--verify --enabled-key-data
           x509 --trusted-pem`) and Python's signxml (XMLVerifier and
           XAdESVerifier, given the laboratory's certificate); one changed
           digit of a coefficient, of the signing time or of the item's
           serial number makes both refuse it; `POST /v1/dcc/verify` and
           `accelcal dcc verify` say the same; the printed certificate names
           the signer and the DCC file's SHA-256; a second request answers
           the same bytes; PTB's dcc-json-toolkit still reads them.
  rotated  run after the service restarted with WORK/rotated.key: the DCCs
           issued before still answer the same bytes and verify with the
           certificate they embed; a calibration approved now is signed by
           the new certificate, and not by the old.

The test certificates (tests/data/signing/make.sh) are issued by a test CA:
xmlsec1 is given that CA (`--trusted-pem ca.pem`) and checks the chain from
the certificate the DCC embeds; signxml is pinned to the laboratory's
certificate itself.

Exits non-zero on any finding. Usage: python3 tests/dcc/signed.py PHASE BASE WORK BIN
"""

import hashlib
import json
import os
import re
import subprocess
import sys
import urllib.error
import urllib.request

from dcc_json_toolkit import DccSourceContent
from dcc_json_toolkit.content_validation import validate_dcc_content
from signxml import XMLVerifier
from signxml.exceptions import InvalidInput, InvalidSignature
from signxml.xades import XAdESVerifier

PHASE, BASE, WORK, BIN = sys.argv[1:5]
ADMIN = os.environ["ACCELCAL_ADMIN_TOKEN"]
SERIALS = {"PAPER-2005": "SN-4711", "IMU-DEMO-1": "SN-0815"}


def call(method, path, body=None, accept="application/json", content_type="application/json"):
    data = None
    if body is not None:
        data = body if isinstance(body, bytes) else json.dumps(body).encode()
    req = urllib.request.Request(BASE + path, data=data, method=method)
    req.add_header("Authorization", f"Bearer {ADMIN}")
    req.add_header("Accept", accept)
    if data is not None:
        req.add_header("Content-Type", content_type)
    try:
        with urllib.request.urlopen(req) as res:
            raw = res.read()
    except urllib.error.HTTPError as e:
        sys.exit(f"{method} {path}: {e.code} {e.read().decode()}")
    return raw if accept != "application/json" else json.loads(raw or b"null")


def leaf(pem_file):
    """The first certificate of a PEM file (the signer's, before its chain)."""
    text = open(pem_file).read()
    end = "-----END CERTIFICATE-----"
    return text[: text.index(end) + len(end)] + "\n"


def xmlsec1(path, trusted):
    r = subprocess.run(["xmlsec1", "--verify", "--enabled-key-data", "x509",
                        "--trusted-pem", trusted, path], capture_output=True, text=True)
    return r.returncode == 0, (r.stdout + r.stderr).strip().splitlines()[-1:]


def signxml(data, cert_file):
    """signxml's XML-DSig and XAdES verifiers, pinned to cert_file's certificate."""
    try:
        XMLVerifier().verify(data, x509_cert=leaf(cert_file), expect_references=2)
        XAdESVerifier().verify(data, x509_cert=leaf(cert_file), expect_references=2)
        return True, ""
    except (InvalidSignature, InvalidInput) as e:
        return False, f"{type(e).__name__}: {e}"


def accelcal_verify(path, cert):
    r = subprocess.run([BIN, "dcc", "verify", path, "--cert", cert], capture_output=True, text=True)
    return r.returncode, r.stdout + r.stderr


def approve(reviewer, path, body):
    stored = call("POST", path, body)
    req = urllib.request.Request(BASE + f"/v1/calibrations/{stored['id']}/review",
                                 data=json.dumps({"decision": "approve", "comment": "checked"}).encode(),
                                 method="POST")
    req.add_header("Authorization", f"Bearer {reviewer}")
    req.add_header("Content-Type", "application/json")
    urllib.request.urlopen(req).read()
    return stored["id"]


def single_axis(performed_at):
    s = json.load(open("examples/paper-table1.json"))
    s.update({"unit": "mA", "standards": {"stand": "STAND-1"}, "performed_at": performed_at})
    return s


def tampered(xml, what):
    """xml with one digit changed: of a coefficient, the signing time, or the serial."""
    if what == "coefficient":
        results = xml.index("<dcc:measurementResults>")
        m = re.compile(r"<si:value>(-?)(\d)").search(xml, results)
        start = m.start(2)
    elif what == "signing time":
        m = re.search(r"<xades:SigningTime>[^<]*?(\d)Z</xades:SigningTime>", xml)
        start = m.start(1)
    else:
        serial = next(s for s in SERIALS.values() if s in xml)
        start = xml.index(serial) + len(serial) - 1
    digit = str((int(xml[start]) + 1) % 10)
    return xml[:start] + digit + xml[start + 1:]


def check_issued(findings, kind, id_, xml_bytes):
    path = os.path.join(WORK, f"{kind}.xml")
    with open(path, "wb") as f:
        f.write(xml_bytes)
    ok, out = xmlsec1(path, os.path.join(WORK, "ca.pem"))
    if not ok:
        findings.append(f"{kind}: xmlsec1 refused the signed DCC: {out}")
    # Signed, it is still read by PTB's toolkit as before.
    findings += [f"{kind}: dcc-json-toolkit: {e}" for e in validate_dcc_content(DccSourceContent(path))]
    ok, why = signxml(xml_bytes, os.path.join(WORK, "lab.pem"))
    if not ok:
        findings.append(f"{kind}: signxml refused the signed DCC: {why}")
    code, out = accelcal_verify(path, os.path.join(WORK, "lab.pem"))
    if code != 0 or "signer: CN=DCC signing 2026" not in out:
        findings.append(f"{kind}: accelcal dcc verify answered {code}: {out}")
    answer = call("POST", "/v1/dcc/verify", xml_bytes, content_type="application/xml")
    if not (answer["valid"] and answer["signer"]["subject"].startswith("CN=DCC signing 2026")
            and answer["signing_time"] and answer["sha256"] == hashlib.sha256(xml_bytes).hexdigest()):
        findings.append(f"{kind}: POST /v1/dcc/verify answered {answer}")
    text = xml_bytes.decode()
    for what in ["coefficient", "signing time", "serial number"]:
        forged = tampered(text, what)
        assert forged != text
        forged_path = os.path.join(WORK, f"{kind}-forged.xml")
        with open(forged_path, "w") as f:
            f.write(forged)
        if xmlsec1(forged_path, os.path.join(WORK, "ca.pem"))[0]:
            findings.append(f"{kind}: xmlsec1 accepted a DCC with its {what} changed")
        if signxml(forged.encode(), os.path.join(WORK, "lab.pem"))[0]:
            findings.append(f"{kind}: signxml accepted a DCC with its {what} changed")
        if accelcal_verify(forged_path, os.path.join(WORK, "lab.pem"))[0] != 1:
            findings.append(f"{kind}: accelcal dcc verify accepted a DCC with its {what} changed")
        answer = call("POST", "/v1/dcc/verify", forged.encode(), content_type="application/xml")
        if answer["valid"] or not answer["reason"]:
            findings.append(f"{kind}: POST /v1/dcc/verify accepted its {what} changed: {answer}")
    again = call("GET", f"/v1/calibrations/{id_}/certificate", accept="application/xml")
    if again != xml_bytes:
        findings.append(f"{kind}: a second request answered other bytes")
    html = call("GET", f"/v1/calibrations/{id_}/certificate", accept="text/html").decode()
    sha = hashlib.sha256(xml_bytes).hexdigest()
    if sha not in html or "Signed (XML Signature, XAdES) by CN=DCC signing 2026" not in html:
        findings.append(f"{kind}: the printed certificate does not name the DCC's SHA-256 {sha} and its signer")
    print(f"{kind}: signed DCC ({len(xml_bytes)} bytes) verified by xmlsec1, signxml (XAdES), "
          f"accelcal dcc verify and POST /v1/dcc/verify; coefficient, signing time and serial "
          f"number changes refused by all four")


def issue():
    findings = []
    reviewer = call("POST", "/v1/tokens", {"role": "reviewer", "holder": "Rita Reviewer"})["token"]
    call("PUT", "/v1/customers/ACME", {"name": "Acme", "address": "Main St 1", "due_date_agreed": True})
    for sensor, serial in SERIALS.items():
        call("PUT", f"/v1/sensors/{sensor}/item",
             {"manufacturer": "Inertia AG", "model": "QA-3000", "serial": serial, "customer": "ACME"})
    call("PUT", "/v1/standards/STAND-1", json.load(open("examples/standard-stand.json")))
    triad = json.load(open("examples/triad-recording.json"))
    ids = {
        "single-axis": approve(reviewer, "/v1/calibrations", single_axis("2026-06-01T08:00:00Z")),
        "triad": approve(reviewer, "/v1/calibrations/triad", triad),
    }
    digests = {}
    for kind, id_ in ids.items():
        xml = call("GET", f"/v1/calibrations/{id_}/certificate", accept="application/xml")
        check_issued(findings, kind, id_, xml)
        digests[kind] = hashlib.sha256(xml).hexdigest()
    json.dump({"ids": ids, "digests": digests, "reviewer": reviewer},
              open(os.path.join(WORK, "issued.json"), "w"))
    return findings


def rotated():
    findings = []
    issued = json.load(open(os.path.join(WORK, "issued.json")))
    for kind, id_ in issued["ids"].items():
        xml = call("GET", f"/v1/calibrations/{id_}/certificate", accept="application/xml")
        if hashlib.sha256(xml).hexdigest() != issued["digests"][kind]:
            findings.append(f"{kind}: after the key was rotated, the issued DCC changed")
        path = os.path.join(WORK, f"{kind}-old.xml")
        with open(path, "wb") as f:
            f.write(xml)
        # Its embedded certificate, the rotated-out one.
        ok, out = xmlsec1(path, os.path.join(WORK, "ca.pem"))
        if not ok:
            findings.append(f"{kind}: signed with the rotated-out key, xmlsec1 refused it: {out}")
        ok, why = signxml(xml, os.path.join(WORK, "lab.pem"))
        if not ok:
            findings.append(f"{kind}: signed with the rotated-out key, signxml refused it: {why}")
        answer = call("POST", "/v1/dcc/verify", xml, content_type="application/xml")
        if not answer["valid"] or not answer["signer"]["subject"].startswith("CN=DCC signing 2026"):
            findings.append(f"{kind}: POST /v1/dcc/verify after rotation answered {answer}")
    new = approve(issued["reviewer"], "/v1/calibrations", single_axis("2026-06-02T08:00:00Z"))
    xml = call("GET", f"/v1/calibrations/{new}/certificate", accept="application/xml")
    path = os.path.join(WORK, "new.xml")
    with open(path, "wb") as f:
        f.write(xml)
    if not xmlsec1(path, os.path.join(WORK, "ca.pem"))[0]:
        findings.append("a DCC issued after the rotation does not verify with the new certificate")
    if not signxml(xml, os.path.join(WORK, "rotated.pem"))[0]:
        findings.append("signxml refused a DCC issued after the rotation, given the new certificate")
    if signxml(xml, os.path.join(WORK, "lab.pem"))[0]:
        findings.append("signxml accepted a DCC issued after the rotation as signed by the old certificate")
    if accelcal_verify(path, os.path.join(WORK, "lab.pem"))[0] != 1:
        findings.append("accelcal dcc verify --cert OLD accepted a DCC the new key signed")
    print("rotation: the DCCs issued before answer the same bytes and verify with their embedded "
          "certificate; a new DCC is signed by the new certificate only")
    return findings


findings = issue() if PHASE == "issue" else rotated()
if findings:
    print("\n".join(findings), file=sys.stderr)
    sys.exit(1)
