#!/usr/bin/env python3
"""Writes examples/triad-recording.json: a recording of a MEMS triad turned
by hand through twelve orientations, as a station would send it to
POST /v1/identify/triad.

The triad (outputs in m/s2): bias b = (0.183, -0.127, 0.342), S = T^-1 with
T lower-triangular (the convention of accelcal's fit) from scale factors
(0.9981, 1.0047, 0.9923) and small cross-axis terms; white noise of
0.012 m/s2 per axis and a slow 0.004 m/s2 drift, sampled at 50 Hz. The
hand holds each orientation 4 to 6 s (the first 6 s is the initial still
period) and turns for about 1.5 s between them, not exactly along the
faces. Deterministic: run it again and the file is the same.
"""
import json
import math
import random

G = 9.80665
RATE = 50.0
rng = random.Random(20261125)

b = [0.183, -0.127, 0.342]
# T (g per m/s2) lower-triangular; outputs u = b + T^-1 g.
t = [[1 / (0.9981 * G), 0.0, 0.0],
     [0.0021 / G, 1 / (1.0047 * G), 0.0],
     [-0.0034 / G, 0.0016 / G, 1 / (0.9923 * G)]]


def outputs(g):
    x0 = g[0] / t[0][0]
    x1 = (g[1] - t[1][0] * x0) / t[1][1]
    x2 = (g[2] - t[2][0] * x0 - t[2][1] * x1) / t[2][2]
    return [x0 + b[0], x1 + b[1], x2 + b[2]]


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


# Twelve orientations: the faces and six in between, each a little off.
holds = [[0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, -1],
         [1, 1, 1], [-1, 1, -1], [1, -1, -1], [-1, -1, 1], [1, 0, -1], [0, 1, 1]]
holds = [unit([x + rng.uniform(-0.08, 0.08) for x in h]) for h in holds]

samples = []
k = 0


def emit(g):
    global k
    u = outputs(g)
    drift = 0.004 * math.sin(2 * math.pi * k / (RATE * 60))
    samples.append([round(u[m] + rng.gauss(0, 0.012) + drift, 4) for m in range(3)])
    k += 1


for i, g in enumerate(holds):
    if i > 0:
        turn = int(RATE * rng.uniform(1.3, 1.8))
        a = holds[i - 1]
        for s in range(turn):
            w = (1 - math.cos(math.pi * s / turn)) / 2
            emit(unit([a[m] * (1 - w) + g[m] * w for m in range(3)]))
    for _ in range(int(RATE * (6.0 if i == 0 else rng.uniform(4.0, 6.0)))):
        emit(g)

body = {"sensor_id": "IMU-DEMO-1", "unit": "m/s2",
        "recording": {"rate_hz": RATE, "samples": samples}}
with open("examples/triad-recording.json", "w") as f:
    json.dump(body, f, separators=(",", ":"))
    f.write("\n")
print(len(samples), "samples")
