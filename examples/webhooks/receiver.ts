// A receiver of accelcal's webhooks, in TypeScript on Node, with the
// Standard Webhooks library (`npm install standardwebhooks`).
//
// Every request is verified before anything is done with it: its signature
// (HMAC-SHA256 under the endpoint's `whsec_…` secret, shown once when the
// endpoint was registered) and its timestamp (within five minutes).
// accelcal delivers at least once: act on each `webhook-id` once. Answer
// 2xx only once the event is handled; anything else is retried with
// backoff, the endpoint's next event waiting behind it.
//
//   ACCELCAL_WEBHOOK_SECRET=whsec_… npx tsx receiver.ts 8000
//
// (tests/clients/run.sh type-checks this file against the library.)
import { createServer } from "node:http";
import { Webhook } from "standardwebhooks";

interface Payload {
  type: string;
  timestamp: string;
  data: {
    seq: number;
    sensor_id: string | null;
    calibration_id: string | null;
    change: unknown;
    // For an act on a calibration: what it did to the served coefficients.
    coefficients?: { changed: boolean; calibration_id?: string | null };
  };
}

const verifier = new Webhook(process.env.ACCELCAL_WEBHOOK_SECRET ?? "");
const seen = new Set<string>();

createServer((req, res) => {
  const chunks: Buffer[] = [];
  req.on("data", (c: Buffer) => chunks.push(c));
  req.on("end", () => {
    const body = Buffer.concat(chunks).toString("utf8");
    const headers: Record<string, string> = {};
    for (const [k, v] of Object.entries(req.headers)) if (typeof v === "string") headers[k] = v;
    let payload: Payload;
    try {
      payload = verifier.verify(body, headers) as Payload;
    } catch {
      res.writeHead(400).end("not from accelcal");
      return;
    }
    const id = headers["webhook-id"];
    if (!seen.has(id)) {
      seen.add(id);
      // A control system reloads the sensor's coefficients when they changed
      // (another calibration served, none, or the served one held or released).
      const reload = payload.data.coefficients?.changed ?? false;
      console.log(JSON.stringify({ id, type: payload.type, sensor: payload.data.sensor_id, reload }));
    }
    res.writeHead(204).end();
  });
}).listen(Number(process.argv[2] ?? 8000), "127.0.0.1");
