"""accelcal's webhooks received and verified by the Standard Webhooks
library (issue 47 items 3 and 4), through the example receiver
(examples/webhooks/receiver.py), against the real binary:

  signed     an endpoint registered; every stored calibration's event
             arrives verified by `standardwebhooks`, in sequence order;
  down/up    the receiver fails (503) for a while: the event is retried
             with the same webhook-id, and everything arrives once it is up;
  rotated    the secret rotated with an overlap: receivers holding the old
             secret and the new one both verify what is sent;
  kill -9    submissions under load while the server is killed with
             SIGKILL at random moments, ROUNDS times, and restarted: every
             acknowledged calibration's event arrives, verified, and a
             repeat only ever repeats a webhook-id with the same event. On
             PostgreSQL a second replica serves half the load, and the
             rounds kill each replica in turn.

The server was started by tests/webhooks/run.sh (PID, on PORT, over
DATABASE); this script kills and restarts it with the same command.
Usage: python3 tests/webhooks/check.py BIN DATABASE PORT PID ROUNDS
"""

import json
import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "examples", "webhooks"))
from receiver import make_server  # noqa: E402

BIN, DATABASE, PORT, PID, ROUNDS = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
BASE = f"http://127.0.0.1:{PORT}"
TOKEN = os.environ["ACCELCAL_ADMIN_TOKEN"]
with open("examples/paper-table1.json") as f:
    PAPER = json.load(f)


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def call(method, path, body=None, timeout=10, base=None):
    req = urllib.request.Request((base or BASE) + path, method=method,
                                 data=None if body is None else json.dumps(body).encode(),
                                 headers={"authorization": f"Bearer {TOKEN}",
                                          "content-type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=timeout) as res:
            return res.status, json.loads(res.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


def submission(sensor, i):
    body = dict(PAPER)
    body["sensor_id"] = sensor
    body["performed_at"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(1.7e9 + i * 60))
    return body


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Inbox:
    """What a receiver verified: (webhook-id, payload) in arrival order."""

    def __init__(self):
        self.lock = threading.Lock()
        self.got = []
        self.down = False

    def on_event(self, webhook_id, payload):
        if self.down:
            with self.lock:
                self.got.append((webhook_id, None))
            raise RuntimeError("down for maintenance")
        with self.lock:
            self.got.append((webhook_id, payload))

    def delivered(self):
        with self.lock:
            return [(i, p) for i, p in self.got if p is not None]

    def attempts(self):
        with self.lock:
            return list(self.got)


def serve(secret, inbox):
    port = free_port()
    server = make_server(port, secret, inbox.on_event)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{port}/hook"


def wait(what, check, limit=60):
    deadline = time.time() + limit
    while time.time() < deadline:
        if check():
            return
        time.sleep(0.1)
    fail(f"{what} did not happen within {limit} s")


def stored_ids(inbox):
    return {p["data"]["calibration_id"] for _, p in inbox.delivered() if p["type"] == "calibration.stored"}


def check_repeats_and_order(inbox):
    first = {}
    order = []
    for webhook_id, p in inbox.delivered():
        if webhook_id in first:
            if first[webhook_id] != p:
                fail(f"{webhook_id} repeated with another event: {first[webhook_id]} / {p}")
            continue
        if webhook_id != f"evt_{p['data']['seq']}":
            fail(f"{webhook_id} is not the id of event {p['data']['seq']}")
        first[webhook_id] = p
        order.append(p["data"]["seq"])
    if order != sorted(order):
        fail(f"first arrivals out of sequence order: {order}")
    return len(inbox.delivered()) - len(first)


def start_server(port=PORT):
    log = open(os.environ.get("SERVER_LOG", "/dev/null"), "ab")
    proc = subprocess.Popen([BIN, "serve", "--listen", f"127.0.0.1:{port}", "--database", DATABASE],
                            stdout=log, stderr=log)
    wait("the restarted server ready", lambda: ready(port), 30)
    return proc


def ready(port=PORT):
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/readyz", timeout=1) as res:
            return res.status == 200
    except Exception:
        return False


# --- signed ---------------------------------------------------------------
inbox = Inbox()
status, created = call("PUT", "/v1/webhooks/control", {"url": "http://127.0.0.1:9/placeholder"})
if status != 201:
    fail(f"registration: {status} {created}")
secret = created["secret"]
server, url = serve(secret, inbox)
status, _ = call("PUT", "/v1/webhooks/control", {"url": url})
if status != 200:
    fail(f"changing the URL: {status}")
# The placeholder's events (none yet) and these:
acked = set()
for i in range(5):
    status, c = call("POST", "/v1/calibrations", submission("WH-SIGNED", i))
    if status != 201:
        fail(f"submission: {status} {c}")
    acked.add(c["id"])
wait("5 verified deliveries", lambda: acked <= stored_ids(inbox))
# Each is newer than the one before: each is served as it is stored.
for _, p in inbox.delivered():
    d = p["data"]
    if d.get("calibration_id") in acked and d.get("coefficients") != {
            "changed": True, "calibration_id": d["calibration_id"]}:
        fail(f"coefficients of {d['calibration_id']}: {d.get('coefficients')}")
print(f"signed: {len(inbox.delivered())} events verified by standardwebhooks, in order, "
      "each saying the coefficients it serves")

# --- down/up --------------------------------------------------------------
inbox.down = True
for i in range(5, 8):
    status, c = call("POST", "/v1/calibrations", submission("WH-DOWN", i))
    acked.add(c["id"])
wait("three refused attempts", lambda: sum(1 for _, p in inbox.attempts() if p is None) >= 3)
refused = {i for i, p in inbox.attempts() if p is None}
if len(refused) != 1:
    fail(f"more than the first event attempted while it failed: {refused}")
inbox.down = False
wait("everything after the receiver came back", lambda: acked <= stored_ids(inbox))
print(f"down/up: {len([1 for _, p in inbox.attempts() if p is None])} refused attempts of {refused.pop()}, then everything")

# --- rotated --------------------------------------------------------------
status, rotated = call("POST", "/v1/webhooks/control/secret", {"overlap_s": 600})
if status != 200:
    fail(f"rotation: {status} {rotated}")
old_inbox = Inbox()
old_server, old_url = serve(secret, old_inbox)
call("PUT", "/v1/webhooks/control", {"url": old_url})
status, c = call("POST", "/v1/calibrations", submission("WH-ROT", 20))
wait("a delivery verified with the old secret", lambda: c["id"] in stored_ids(old_inbox))
secret = rotated["secret"]
new_inbox = Inbox()
new_server, new_url = serve(secret, new_inbox)
call("PUT", "/v1/webhooks/control", {"url": new_url})
status, c = call("POST", "/v1/calibrations", submission("WH-ROT", 21))
wait("a delivery verified with the new secret", lambda: c["id"] in stored_ids(new_inbox))
print("rotated: both secrets verify during the overlap")
inbox = new_inbox

# --- kill -9 --------------------------------------------------------------
acked = set()
lock = threading.Lock()
counter = [100]


def load(stop, base):
    while not stop.is_set():
        with lock:
            counter[0] += 1
            i = counter[0]
        try:
            status, c = call("POST", "/v1/calibrations", submission(f"WH-K{i % 7}", i), timeout=5, base=base)
        except Exception:
            time.sleep(0.05)
            continue
        if status == 201:
            with lock:
                acked.add(c["id"])


# The servers: the one run.sh started (no handle: its pid), and on
# PostgreSQL a second replica on another port.
replicas = [[PORT, None]]
if DATABASE.startswith("postgres"):
    other = free_port()
    replicas.append([other, start_server(other)])
for round in range(ROUNDS):
    stop = threading.Event()
    workers = [threading.Thread(target=load, args=(stop, f"http://127.0.0.1:{replicas[k % len(replicas)][0]}"))
               for k in range(4)]
    for w in workers:
        w.start()
    time.sleep(random.uniform(0.3, 1.2))
    victim = replicas[round % len(replicas)]
    if victim[1] is None:
        os.kill(PID, signal.SIGKILL)
    else:
        victim[1].kill()
        victim[1].wait()
    stop.set()
    for w in workers:
        w.join()
    victim[1] = start_server(victim[0])
wait(f"all {len(acked)} acknowledged submissions' events", lambda: acked <= stored_ids(inbox), 120)
repeats = check_repeats_and_order(inbox)
for _, proc in replicas:
    if proc is not None:
        proc.terminate()
        proc.wait(timeout=30)
print(f"kill -9: {ROUNDS} rounds over {len(replicas)} replica(s), {len(acked)} acknowledged, every event delivered and verified; "
      f"{repeats} repeats, each with the webhook-id of its first delivery")
