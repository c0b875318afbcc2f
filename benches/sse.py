#!/usr/bin/env python3
"""Clients of GET /v1/events and webhook receivers for the benchmarks
(issue 47 item 6).

  sse.py read    BASE TOKEN         reads the stream, counting events, until killed
  sse.py stall   BASE TOKEN         opens the stream and never reads it
  sse.py latency BASE TOKEN N       submits the paper's Table 1 N times, one at a
                                    time, and prints the p50 and p99 (ms) from each
                                    POST's answer to its event on an open stream
  sse.py hooklatency BASE TOKEN N   the same to the arrival of its webhook at a
                                    receiver on loopback (the server needs
                                    --webhook-allow-private)
  sse.py receive PORT               a webhook receiver answering 204, until killed
  sse.py blackhole PORT             a dead receiver: takes connections, never answers

Standard library only. Measures, never judges.
"""
import json
import socket
import sys
import threading
import time
import urllib.request
from urllib.parse import urlparse


def stream(base, token):
    req = urllib.request.Request(f"{base}/v1/events", headers={"Authorization": f"Bearer {token}"})
    return urllib.request.urlopen(req)


def events(res):
    """Yields (arrival time, event data) for each event of the stream."""
    data = None
    for raw in res:
        line = raw.decode().rstrip("\n")
        if line.startswith("data: "):
            data = json.loads(line[6:])
        elif line == "" and data is not None:
            yield time.monotonic(), data
            data = None


def read(base, token):
    n = 0
    for _ in events(stream(base, token)):
        n += 1


def stall(base, token):
    url = urlparse(base)
    s = socket.create_connection((url.hostname, url.port))
    s.sendall(
        f"GET /v1/events HTTP/1.1\r\nHost: {url.netloc}\r\nAuthorization: Bearer {token}\r\n\r\n".encode()
    )
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    while True:
        time.sleep(3600)


class Arrivals:
    """When each calibration's event arrived, by calibration id."""

    def __init__(self):
        self.at = {}
        self.seen = threading.Condition()

    def arrived(self, at, event):
        with self.seen:
            self.at[event.get("calibration_id")] = at
            self.seen.notify_all()


def timed(base, token, n, sensor, arrivals, what):
    """Submits the paper's Table 1 for `sensor` n times, one at a time, and
    prints the p50 and p99 (ms) from each POST's answer to its arrival."""
    body = json.load(open("examples/paper-table1.json"))
    body["sensor_id"] = sensor
    out = []
    for i in range(n):
        body["performed_at"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(946684800 + i))
        req = urllib.request.Request(
            f"{base}/v1/calibrations",
            data=json.dumps(body).encode(),
            headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json"},
        )
        with urllib.request.urlopen(req) as r:
            cid = json.load(r)["id"]
        answered = time.monotonic()
        with arrivals.seen:
            if not arrivals.seen.wait_for(lambda: cid in arrivals.at, timeout=10):
                sys.exit(f"no {what} for {cid} within 10 s")
            out.append((arrivals.at[cid] - answered) * 1000)
    out.sort()
    print(f"{out[len(out) // 2]:.1f} {out[min(len(out) - 1, int(len(out) * 0.99))]:.1f}")


def latency(base, token, n):
    arrivals = Arrivals()
    res = stream(base, token)

    def follow():
        for at, e in events(res):
            arrivals.arrived(at, e)

    threading.Thread(target=follow, daemon=True).start()
    timed(base, token, n, "SSE-LATENCY", arrivals, "event")


def receiver(port, on_post=None):
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):
            body = self.rfile.read(int(self.headers.get("content-length", 0)))
            if on_post:
                on_post(time.monotonic(), json.loads(body))
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args):
            pass

    return ThreadingHTTPServer(("127.0.0.1", port), Handler)


def blackhole(port):
    s = socket.create_server(("127.0.0.1", port), backlog=1024)
    held = []
    while True:
        conn, _ = s.accept()
        held.append(conn)


def hook_latency(base, token, n):
    arrivals = Arrivals()
    server = receiver(0, lambda at, payload: arrivals.arrived(at, payload["data"]))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}/hook"
    req = urllib.request.Request(
        f"{base}/v1/webhooks/bench-latency", method="PUT",
        data=json.dumps({"url": url, "sensors": ["HOOK-LATENCY"]}).encode(),
        headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json"})
    urllib.request.urlopen(req).read()
    timed(base, token, n, "HOOK-LATENCY", arrivals, "webhook")


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "receive":
        receiver(int(sys.argv[2])).serve_forever()
    elif mode == "blackhole":
        blackhole(int(sys.argv[2]))
    elif mode == "hooklatency":
        hook_latency(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        base, token = sys.argv[2:4]
        {"read": read, "stall": stall}.get(mode, lambda b, t: latency(b, t, int(sys.argv[4])))(base, token)
