// @hey-api/openapi-ts's SDK (its own fetch client): the same calls as
// typed.ts, compiled with `tsc --strict` and run against a server.
import { readFileSync } from "node:fs";
import { strict as assert } from "node:assert";
import { client } from "../gen/hey/client.gen.js";
import {
  getCoefficients,
  getStability,
  getSubmission,
  listSensorCalibrations,
  submitCalibration,
} from "../gen/hey/sdk.gen.js";
import type { PositionIn, Submission } from "../gen/hey/types.gen.js";

client.setConfig({
  baseUrl: process.env.ACCELCAL_URL!,
  headers: { Authorization: `Bearer ${process.env.ACCELCAL_TOKEN!}` },
});

const byAngle: PositionIn = { angle_deg: 90 };
const byGravity: PositionIn = { a: [0, 1, 0], label: "PA up" };
assert.equal(byAngle.angle_deg + byGravity.a.length, 93);

const paper = JSON.parse(readFileSync("examples/paper-table1.json", "utf8")) as Submission;
const json = await submitCalibration({ body: { ...paper, sensor_id: "TS-HEY" } });
assert.equal(json.response.status, 201);
const id: string = json.data!.id;
const csvText = readFileSync("examples/paper-table1.csv", "utf8").replace("PAPER-CSV", "TS-HEY-CSV");
const csv = await submitCalibration({
  body: csvText as unknown as Submission,
  bodySerializer: (b: unknown) => b as string,
  headers: { "Content-Type": "text/csv" },
});
assert.equal(csv.response.status, 201);
assert.equal(csv.data!.sensor_id, "TS-HEY-CSV");

const coefficients = await getCoefficients({ path: { sensor_id: "TS-HEY" } });
assert.equal(coefficients.data!.calibration_id, id);
const history = await listSensorCalibrations({ path: { sensor_id: "TS-HEY" }, query: { limit: 10 } });
assert.equal(history.data!.items[0].id, id);
const stability = await getStability({ path: { sensor_id: "TS-HEY" } });
assert.equal(stability.data!.calibrations, 1);
const stored = await getSubmission({ path: { id: csv.data!.id }, parseAs: "text" });
assert.equal(stored.data, csvText, "the CSV comes back byte for byte");

const bad = await submitCalibration({ body: { ...paper, batches: 0 } });
assert.equal(bad.response.status, 422);
assert.equal(bad.error!.errors![0].pointer, "/batches");
console.log("SDK client (@hey-api/openapi-ts): ok");
