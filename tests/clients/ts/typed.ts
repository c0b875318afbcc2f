// openapi-typescript's types with openapi-fetch: a dashboard's and a
// station's calls, compiled with `tsc --strict` and run against a server.
import { readFileSync } from "node:fs";
import { strict as assert } from "node:assert";
import createClient from "openapi-fetch";
import type { components, paths } from "../gen/typed/schema.js";

type Submission = components["schemas"]["Submission"];
type PositionIn = components["schemas"]["PositionIn"];

const base = process.env.ACCELCAL_URL!;
const token = process.env.ACCELCAL_TOKEN!;
const client = createClient<paths>({ baseUrl: base, headers: { Authorization: `Bearer ${token}` } });

// Position literals type-check as written (by angle, or by components).
const byAngle: PositionIn = { angle_deg: 90 };
const byGravity: PositionIn = { a: [0, 1, 0], label: "PA up" };
assert.equal(byAngle.angle_deg, 90);
assert.equal(byGravity.a?.length, 3);

const paper = JSON.parse(readFileSync("examples/paper-table1.json", "utf8")) as Submission;
const json = await client.POST("/v1/calibrations", { body: { ...paper, sensor_id: "TS-TYPED" } });
assert.equal(json.response.status, 201);
const id: string = json.data!.id; // required: no `?`, no undefined
const csvText = readFileSync("examples/paper-table1.csv", "utf8").replace("PAPER-CSV", "TS-TYPED-CSV");
const csv = await client.POST("/v1/calibrations", {
  // The CSV form: the body sent as it is.
  body: csvText as unknown as Submission,
  bodySerializer: (b: unknown) => b as string,
  headers: { "Content-Type": "text/csv" },
});
assert.equal(csv.response.status, 201);
assert.equal(csv.data!.sensor_id, "TS-TYPED-CSV");

const coefficients = await client.GET("/v1/sensors/{sensor_id}/coefficients", {
  params: { path: { sensor_id: "TS-TYPED" } },
});
assert.equal(coefficients.data!.calibration_id, id);
const history = await client.GET("/v1/sensors/{sensor_id}/calibrations", {
  params: { path: { sensor_id: "TS-TYPED" }, query: { limit: 10 } },
});
assert.equal(history.data!.items[0].id, id);
const stability = await client.GET("/v1/sensors/{sensor_id}/stability", {
  params: { path: { sensor_id: "TS-TYPED" } },
});
assert.equal(stability.data!.calibrations, 1);
const stored = await client.GET("/v1/calibrations/{id}/submission", {
  params: { path: { id: csv.data!.id } },
  parseAs: "text",
});
assert.equal(stored.data, csvText, "the CSV comes back byte for byte");

// A refusal is a problem document naming the field.
const bad = await client.POST("/v1/calibrations", { body: { ...paper, batches: 0 } });
assert.equal(bad.response.status, 422);
assert.equal(bad.error!.errors![0].pointer, "/batches");
console.log("typed client (openapi-typescript + openapi-fetch): ok");
