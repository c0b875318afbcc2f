"""A receiver of accelcal's webhooks, in Python, with the Standard Webhooks
library (`pip install standardwebhooks`).

Every request is verified before anything is done with it: its signature
(HMAC-SHA256 under the endpoint's `whsec_…` secret, shown once when the
endpoint was registered), and its timestamp (within five minutes). accelcal
delivers at least once: a retry, a redelivery or a crash repeats an event
with the same `webhook-id`, so act on each id once. Answer 2xx only once
the event is safely handled; any other answer (or none within accelcal's
timeout) is retried with backoff, the next event waiting behind it.

    ACCELCAL_WEBHOOK_SECRET=whsec_… python3 receiver.py 8000

(tests/webhooks/check.py runs this receiver against a real accelcal.)
"""

import json
import os
import sys
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from standardwebhooks.webhooks import Webhook, WebhookVerificationError


def make_server(port, secret, on_event):
    """An HTTP server on 127.0.0.1:`port` that verifies each request with
    `secret` and hands its webhook-id and payload to `on_event(id, payload)`;
    a request that does not verify is answered 400, an exception of
    `on_event` 503 (accelcal tries again later), success 204."""
    verifier = Webhook(secret)

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):
            body = self.rfile.read(int(self.headers.get("content-length", 0)))
            try:
                payload = verifier.verify(body, dict(self.headers))
            except WebhookVerificationError as e:
                self.send_error(400, f"not from accelcal: {e}")
                return
            try:
                on_event(self.headers["webhook-id"], payload)
            except Exception as e:  # not handled: accelcal retries
                self.send_error(503, str(e))
                return
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args):
            pass

    return ThreadingHTTPServer(("127.0.0.1", port), Handler)


def main():
    seen = set()

    def on_event(webhook_id, payload):
        if webhook_id in seen:
            return  # a repeat: already handled
        seen.add(webhook_id)
        data = payload["data"]
        # A control system reloads the sensor's coefficients when they
        # changed: another calibration served, none, or the served one held
        # or released (`coefficients.calibration_id` names the one served).
        reload = (data.get("coefficients") or {}).get("changed", False)
        print(json.dumps({"id": webhook_id, "type": payload["type"],
                          "sensor": data.get("sensor_id"),
                          "calibration": data.get("calibration_id"),
                          "reload": reload}), flush=True)

    port = int(sys.argv[1]) if len(sys.argv) > 1 else 8000
    make_server(port, os.environ["ACCELCAL_WEBHOOK_SECRET"], on_event).serve_forever()


if __name__ == "__main__":
    main()
