#!/usr/bin/env python3
"""Writes examples/thermal-triad.json: a MEMS accelerometer triad tumbled
through its six faces in a thermal chamber at five set points (-20, 0, 20,
40, 60 C), as a station sends it to POST /v1/identify/thermal/triad (add
?export=px4 for PX4's thermal parameters) or stores it with
POST /v1/calibrations/thermal/triad (then compensated at a temperature and
exported from the record: docs/users.md, "A worked example").

The triad (outputs in m/s2, u = b(T) + S(T) g, g in g) about T0 = 20 C:
  b(T) = (0.183, -0.127, 0.342) + (1.6e-3, -0.9e-3, 2.4e-3) (T - T0)
         + (1.1e-5, 0, -0.8e-5) (T - T0)^2                   m/s2
  S(T) = S0 (1 + 4e-5 (T - T0)) on the diagonal              m/s2 per g
with S0 the scale factors (0.9981, 1.0047, 0.9923) times 9.80665 and small
cross-axis terms: a bias that moves by about 1.6 mg/K (typical of consumer
MEMS) and scale factors that move by 40 ppm/K — which PX4 and
ArduPilot cannot carry: their exports are refused (409) and `c` or `json`
carry the model. Ten runs per set point, two
samples a face, white noise of 0.004 m/s2; each run's temperature within
0.05 K of its set point. Deterministic: run it again and the file is the
same.
"""
import json
import random

G = 9.80665
rng = random.Random(20261130)
SET_POINTS = [-20.0, 0.0, 20.0, 40.0, 60.0]
FACES = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
B0 = [0.183, -0.127, 0.342]
B1 = [1.6e-3, -0.9e-3, 2.4e-3]
B2 = [1.1e-5, 0.0, -0.8e-5]
S0 = [[0.9981 * G, 0.0021, -0.0034],
      [0.0013, 1.0047 * G, 0.0016],
      [-0.0025, 0.0009, 0.9923 * G]]


def triad(t):
    dt = t - 20.0
    b = [B0[m] + B1[m] * dt + B2[m] * dt * dt for m in range(3)]
    s = [[S0[m][n] * (1 + 4e-5 * dt) if m == n else S0[m][n] for n in range(3)] for m in range(3)]
    return b, s


runs = []
for t in SET_POINTS:
    for _ in range(10):
        temperature = round(t + rng.uniform(-0.05, 0.05), 3)
        b, s = triad(temperature)
        samples = []
        for g in FACES:
            u = [b[m] + sum(s[m][n] * g[n] for n in range(3)) for m in range(3)]
            samples.append([[round(x + rng.gauss(0.0, 0.004), 5) for x in u] for _ in range(2)])
        runs.append({"samples": samples, "temperature_c": temperature})

body = {
    "sensor_id": "IMU-TC-3",
    "station_id": "CHAMBER-1",
    "unit": "m/s2",
    "orientations": "six_faces",
    "batches": 2,
    "runs": runs,
}
with open("examples/thermal-triad.json", "w") as f:
    json.dump(body, f, separators=(",", ":"))
    f.write("\n")
