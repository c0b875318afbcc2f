#!/usr/bin/env python3
"""Independent reference figures for the paper's tables, in 50-digit decimal
arithmetic, from the closed forms of the four-position tumble and the
definitions in NOTES.md (not from accelcal's code, which solves by SVD in
binary floating point).

    python3 core/tests/data/reference.py > core/tests/data/reference.json

Per run (Table 1, position value = mean of cw and ccw, pendulum mount
0°, 90°, 180°, 270° -> a = (0,1,0), (-1,0,0), (0,-1,0), (1,0,0)):
    k0 = (y0 + y90 + y180 + y270)/4,  ki = (y270 - y90)/2,  kp = (y0 - y180)/2
    e  = (y0 - y90 + y180 - y270)/4   (the one residual degree of freedom)
    residuals = (e, -e, e, -e),  rms = |e|,  sigma^2 = 4 e^2 / 1
    SE(k0) = |e|,  SE(ki) = SE(kp) = sqrt(2) |e|
Across runs, for each coefficient's values x_1..x_n in submission order:
    mean = sum x / n;  eq. 8 about K: sqrt(sum (K - x_j)^2 / (n - 1)), relative / |K|
    batches of 3 + 3: mean_p, s_p (divisor n_p - 1), w_p = n_p / s_p^2
    fused = sum w_p mean_p / sum w_p,  SE = 1 / sqrt(sum w_p)
Normalised: bias_g = k0/ki, misalignment_p_rad = kp/ki of the fused values.
"""
import csv
import json
import os
from decimal import Decimal, getcontext

getcontext().prec = 50
HERE = os.path.dirname(os.path.abspath(__file__))


def table1():
    runs = {}
    with open(os.path.join(HERE, "table1.csv")) as f:
        for row in csv.DictReader(f):
            runs.setdefault(int(row["test"]), {}).setdefault(int(row["angle_deg"]), []).append(
                Decimal(row["output"])
            )
    return [runs[t] for t in sorted(runs)]


def table2():
    with open(os.path.join(HERE, "table2.csv")) as f:
        rows = list(csv.DictReader(f))
    return {
        "k0": [Decimal(r["K0"]) for r in rows],
        "ki": [Decimal(r["K1"]) for r in rows],
        "kp": [Decimal(r["alpha"]) for r in rows],
    }


def mean(xs):
    return sum(xs) / len(xs)


def eq8(xs, k):
    d = (sum((k - x) ** 2 for x in xs) / (len(xs) - 1)).sqrt()
    return d, (d / abs(k) if k != 0 else None)


def estimates(values, batches=((0, 3), (3, 6))):
    out = {"mean": {}, "mean_dispersion": {}, "mean_relative_dispersion": {},
           "fused": {}, "fused_std_error": {}, "fused_dispersion": {},
           "fused_relative_dispersion": {}, "batch_mean": {}, "batch_std": {}}
    for term, xs in values.items():
        m = mean(xs)
        out["mean"][term] = m
        out["mean_dispersion"][term], out["mean_relative_dispersion"][term] = eq8(xs, m)
        means, stds, weights = [], [], []
        for a, b in batches:
            part = xs[a:b]
            pm = mean(part)
            s = (sum((x - pm) ** 2 for x in part) / (len(part) - 1)).sqrt()
            means.append(pm)
            stds.append(s)
            weights.append(Decimal(len(part)) / (s * s))
        fused = sum(w * x for w, x in zip(weights, means)) / sum(weights)
        out["fused"][term] = fused
        out["fused_std_error"][term] = 1 / sum(weights).sqrt()
        out["fused_dispersion"][term], out["fused_relative_dispersion"][term] = eq8(xs, fused)
        out["batch_mean"][term] = means
        out["batch_std"][term] = stds
    return out


def main():
    runs = []
    for positions in table1():
        y = {deg: mean(samples) for deg, samples in positions.items()}
        e = (y[0] - y[90] + y[180] - y[270]) / 4
        runs.append({
            "coefficients": {"k0": (y[0] + y[90] + y[180] + y[270]) / 4,
                             "ki": (y[270] - y[90]) / 2,
                             "kp": (y[0] - y[180]) / 2},
            "std_errors": {"k0": abs(e), "ki": Decimal(2).sqrt() * abs(e),
                           "kp": Decimal(2).sqrt() * abs(e)},
            "residuals": [e, -e, e, -e],
            "residual_rms": abs(e),
        })
    per_term = {t: [r["coefficients"][t] for r in runs] for t in ("k0", "ki", "kp")}
    t1 = estimates(per_term)
    t1["normalized"] = {"bias_g": t1["fused"]["k0"] / t1["fused"]["ki"],
                        "misalignment_p_rad": t1["fused"]["kp"] / t1["fused"]["ki"]}
    doc = {"table1": {"runs": runs, **t1}, "table2": estimates(table2())}

    def plain(x):
        if isinstance(x, Decimal):
            return float(x)
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items()}
        if isinstance(x, list):
            return [plain(v) for v in x]
        return x

    print(json.dumps(plain(doc), indent=1))


if __name__ == "__main__":
    main()
