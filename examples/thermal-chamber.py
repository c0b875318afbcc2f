#!/usr/bin/env python3
"""Writes examples/thermal-chamber.json: a pendulous MEMS accelerometer
tumbled in a thermal chamber at five set points (-20, 0, 20, 40, 60 C),
as a station sends it to POST /v1/calibrations/thermal (or
POST /v1/identify/thermal to fit without storing).

The sensor (outputs in mA, model k0 + ki a_i + kp a_p) moves with the
temperature as MEMS parts do, about T0 = 20 C:
  k0(T) = 0.0021 + 3.5e-5 (T - T0) + 2.2e-7 (T - T0)^2  mA   (bias: 35 uA/K)
  ki(T) = 1.2148 (1 - 1.2e-4 (T - T0))                  mA/g (scale: -120 ppm/K)
  kp    = 0.0032                                         mA/g
Eight four-position runs per set point (0, 90, 180, 270 degrees, two
readings each), fused in two batches of four runs (batches of two
runs make poor weights: docs/users.md); white noise of 1.5e-5 mA; each
run's temperature within 0.05 K of its set point (a chamber soaked
before the tumble). Deterministic: run it again and the file is the same.
"""
import json
import math
import random

rng = random.Random(20261129)
SET_POINTS = [-20.0, 0.0, 20.0, 40.0, 60.0]
ANGLES = [0.0, 90.0, 180.0, 270.0]


def model(t):
    dt = t - 20.0
    return (0.0021 + 3.5e-5 * dt + 2.2e-7 * dt * dt, 1.2148 * (1 - 1.2e-4 * dt), 0.0032)


runs = []
for t in SET_POINTS:
    for _ in range(8):
        temperature = round(t + rng.uniform(-0.05, 0.05), 3)
        k0, ki, kp = model(temperature)
        readings = []
        for deg in ANGLES:
            th = math.radians(deg)
            u = k0 + ki * -math.sin(th) + kp * math.cos(th)
            readings.append([round(u + rng.gauss(0.0, 1.5e-5), 7) for _ in range(2)])
        runs.append({"readings": readings, "temperature_c": temperature})

body = {
    "sensor_id": "MEMS-TC-7",
    "station_id": "CHAMBER-1",
    "unit": "mA",
    "model": ["k0", "ki", "kp"],
    "mount": "pendulum",
    "positions": [{"angle_deg": a} for a in ANGLES],
    "batches": 2,
    "runs": runs,
}
with open("examples/thermal-chamber.json", "w") as f:
    json.dump(body, f, indent=1)
    f.write("\n")
