#!/usr/bin/env python3
"""Independent reference for the model-adequacy statistics of issue 27, with
numpy and scipy (not accelcal's code): pure error, the lack-of-fit F test, the
noisy-run F tests, unmodelled-term partial F tests, the model component of
the budget, the indexing component of explicit positions (by central finite
differences of small rotations through the least-squares fit, not by the
derivative formula accelcal uses) and fusion with the consistency floor;
and (issue 42) each coefficient's coverage: the statistical component's
degrees of freedom from the batches and the weights they were fused with,
the stand's components (indexing of dividing-head angles and gravity, by
central differences of the model), Welch-Satterthwaite's effective degrees
of freedom and scipy's Student t coverage factor for p = 0.9545; and a
table of scipy's factors for 1 to 60 degrees of freedom.

    python3 -m venv /tmp/v && /tmp/v/bin/pip install numpy scipy
    /tmp/v/bin/python core/tests/data/adequacy.py > core/tests/data/adequacy.json

Each case holds its inputs (model, positions, runs of samples, batches, the
stand's angle uncertainty) and what the definitions give for them.
"""
import json
import math

import numpy as np
from scipy import stats

ARCSEC = math.pi / (180 * 3600)
TERMS = ["k0", "ki", "kp", "ko", "kio", "kop", "kpi", "kii", "kpp", "koo", "kiii"]


def regressor(t, a):
    i, p, o = a
    return {"k0": 1.0, "ki": i, "kp": p, "ko": o, "kio": i * o, "kop": o * p, "kpi": p * i,
            "kii": i * i, "kpp": p * p, "koo": o * o, "kiii": i ** 3}[t]


def design(model, gravity):
    return np.array([[regressor(t, a) for t in model] for a in gravity])


def pendulum(deg):
    th = math.radians(deg)
    return [-math.sin(th), math.cos(th), 0.0]


def lstsq(A, y):
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    return c, y - A @ c


def identifiable(A):
    s = np.linalg.svd(A, compute_uv=False)
    return A.shape[0] >= A.shape[1] and s.min() > 1e-10 * s.max()


def batches(n, k):
    base, extra = divmod(n, k)
    out, start = [], 0
    for b in range(k):
        ln = base + (1 if b < extra else 0)
        out.append((start, start + ln))
        start += ln
    return out


def analyse(case):
    model, runs = case["model"], case["runs"]
    gravity = [pendulum(p["angle_deg"]) if "angle_deg" in p else p["a"] for p in case["positions"]]
    A = design(model, gravity)
    P, p, m = A.shape[0], A.shape[1], len(runs)
    means = np.array([[np.mean(s) for s in run] for run in runs])  # m x P
    out = {}

    # Pure error.
    ss = [sum(float(np.sum((np.array(s) - np.mean(s)) ** 2)) for s in run) for run in runs]
    dof = [sum(len(s) - 1 for s in run) for run in runs]
    out["pure_error"] = {
        "std": math.sqrt(sum(ss) / sum(dof)) if sum(dof) else None,
        "dof": sum(dof),
        "runs": [{"std": math.sqrt(a / d) if d else None, "dof": d} for a, d in zip(ss, dof)],
    }

    # Per-run fits.
    fits = [lstsq(A, means[j]) for j in range(m)]
    nu = P - p
    cov = np.linalg.inv(A.T @ A)
    run_se = [np.sqrt(np.diag(cov) * float(r @ r) / nu) if nu else None for _, r in fits]

    # Lack of fit.
    df1, df2 = m * nu, sum(dof)
    if df1 and df2 and sum(ss) > 0:
        num = sum(len(s) * r_i ** 2 for run, (_, r) in zip(runs, fits) for s, r_i in zip(run, r)) / df1
        f = num / (sum(ss) / df2)
        out["lack_of_fit"] = {"f": f, "df1": df1, "df2": df2, "p_value": float(stats.f.sf(f, df1, df2)),
                              "flagged": bool(f > stats.f.isf(0.001, df1, df2))}
    else:
        out["lack_of_fit"] = None

    # Noisy runs: every run's F test and whether it is flagged.
    out["noisy"] = []
    if m >= 2 and nu:
        for j in range(m):
            s2 = float(fits[j][1] @ fits[j][1]) / nu
            others = sum(float(fits[l][1] @ fits[l][1]) for l in range(m) if l != j) / ((m - 1) * nu)
            f = s2 / others
            out["noisy"].append({"run": j, "f": f, "df1": nu, "df2": (m - 1) * nu,
                                 "p_value": float(stats.f.sf(f, nu, (m - 1) * nu)),
                                 "flagged": bool(f > stats.f.isf(0.01 / m, nu, (m - 1) * nu))})

    # Run-averaged fit: the model component and unmodelled terms.
    xt = means.mean(axis=0)
    c, r = lstsq(A, xt)
    rss = float(r @ r)
    model_se = np.sqrt(np.diag(cov) * rss / nu) if nu else None
    flagged = out["lack_of_fit"] is not None and out["lack_of_fit"]["flagged"]
    out["model"] = dict(zip(model, map(float, model_se))) if flagged else None
    out["unmodelled"] = []
    if P - p - 1 >= 1:
        for t in TERMS:
            if t in model:
                continue
            At = design(model + [t], gravity)
            if not identifiable(At):
                continue
            _, rt = lstsq(At, xt)
            rss_t = float(rt @ rt)
            f = max(0.0, (rss - rss_t) / (rss_t / (P - p - 1)))
            out["unmodelled"].append({"term": t, "f": f, "df1": 1, "df2": P - p - 1,
                                      "p_value": float(stats.f.sf(f, 1, P - p - 1)),
                                      "flagged": bool(f > stats.f.isf(0.001, 1, P - p - 1))})

    # Indexing of explicit positions, by finite rotations through the fit.
    sigma = case["angle_std_arcsec"] * ARCSEC
    explicit = [j for j, q in enumerate(case["positions"]) if "a" in q]
    if explicit:
        h = 1e-6
        sq = np.zeros(p)
        for j in explicit:
            for axis in range(3):
                e = np.zeros(3)
                e[axis] = 1.0
                der = []
                for angle in (h, -h):
                    v = np.array(gravity[j])
                    turned = (v * math.cos(angle) + np.cross(e, v) * math.sin(angle)
                              + e * (e @ v) * (1 - math.cos(angle)))
                    g2 = list(gravity)
                    g2[j] = list(turned)
                    der.append(lstsq(design(model, g2), xt)[0])
                sq += ((der[0] - der[1]) / (2 * h)) ** 2
        out["explicit_indexing"] = dict(zip(model, map(float, sigma * np.sqrt(sq))))

    # Fusion with the consistency floor.
    k = case["batches"]
    coeff = np.array([fits[j][0] for j in range(m)])  # m x p
    fused, fused_se, floors, consistent = {}, {}, {}, []
    for col, t in enumerate(model):
        floor = 0.01 * float(np.median([se[col] for se in run_se])) if nu else 0.0
        floors[t] = floor
        if m == 1:
            # A single run is its own estimate, with its own standard errors.
            fused[t], fused_se[t] = float(coeff[0, col]), float(run_se[0][col])
            continue
        w_sum = wx = 0.0
        for b, (lo, hi) in enumerate(batches(m, k)):
            xs = coeff[lo:hi, col]
            s = float(np.std(xs, ddof=1))
            if s < floor:
                consistent.append({"batch": b, "term": t, "std": s, "floor": floor})
            w = (hi - lo) / max(s, floor) ** 2
            w_sum += w
            wx += w * float(np.mean(xs))
        fused[t] = wx / w_sum
        fused_se[t] = 1 / math.sqrt(w_sum)
    out["floors"] = floors if nu else None
    out["fused"] = fused
    out["fused_std_error"] = fused_se
    out["implausibly_consistent"] = consistent
    out["coverage"] = coverage(case, model, gravity, A, fits, run_se, floors, fused, fused_se, out["model"], nu,
                               out.get("explicit_indexing", {}))
    return out


P_DEFAULT = 0.9545


def coverage(case, model, gravity, A, fits, run_se, floors, fused, fused_se, model_u, nu, explicit):
    """Each term's budget components with their degrees of freedom, the
    effective degrees of freedom (GUM G.2b, truncated) and k for p = 0.9545
    (scipy's t.ppf), from the definitions of issue 42."""
    m, k = len(fits), case["batches"]
    P, p = A.shape
    sigma = case["angle_std_arcsec"] * ARCSEC
    u_grav = case.get("gravity_rel_std", 0.0)
    pinv = np.linalg.pinv(A)
    coeff = np.array([fits[j][0] for j in range(m)])

    def output(a, c):
        return sum(c[t] * regressor(t, a) for t in model)

    h = 1e-6
    # d_j: the output's change per radian of the head's angle at position j.
    d = []
    for q in case["positions"]:
        if "angle_deg" not in q:
            d.append(0.0)
            continue
        up, down = pendulum(q["angle_deg"] + math.degrees(h)), pendulum(q["angle_deg"] - math.degrees(h))
        d.append((output(up, fused) - output(down, fused)) / (2 * h))
    # s_j: the output's change per unit relative change of gravity.
    s = [(output([x * (1 + h) for x in a], fused) - output([x * (1 - h) for x in a], fused)) / (2 * h)
         for a in gravity]
    out = {}
    for col, t in enumerate(model):
        if m == 1:
            nu_stat = float(nu)
            u_stat = float(run_se[0][col])
        else:
            ws = []
            for lo, hi in batches(m, k):
                sd = float(np.std(coeff[lo:hi, col], ddof=1))
                ws.append((hi - lo, (hi - lo) / max(sd, floors.get(t, 0.0)) ** 2))
            W = sum(w for _, w in ws)
            nu_stat = 1.0 / sum((w / W) ** 2 / (n - 1) for n, w in ws)
            u_stat = fused_se[t]
        u_idx = math.hypot(sigma * math.sqrt(sum((pinv[col, j] * d[j]) ** 2 for j in range(P))),
                           explicit.get(t, 0.0))
        u_g = u_grav * abs(sum(pinv[col, j] * s[j] for j in range(P)))
        u_mod = model_u[t] if model_u else 0.0
        comps = [(u_stat, nu_stat), (u_idx, math.inf), (u_g, math.inf), (u_mod, float(P - p))]
        uc2 = sum(u * u for u, _ in comps)
        den = sum(u ** 4 / v for u, v in comps if u > 0 and math.isfinite(v))
        nu_eff = math.floor(uc2 ** 2 / den) if den > 0 else None
        kf = float(stats.t.ppf((1 + P_DEFAULT) / 2, nu_eff)) if nu_eff else float(stats.norm.ppf((1 + P_DEFAULT) / 2))
        out[t] = {"statistical": u_stat, "statistical_dof": nu_stat, "indexing": u_idx, "gravity": u_g,
                  "model": u_mod, "combined": math.sqrt(uc2), "effective_dof": nu_eff, "coverage_factor": kf,
                  "expanded": kf * math.sqrt(uc2),
                  "probability_at_k2": float(2 * stats.t.cdf(2.0, nu_eff) - 1) if nu_eff else None}
    return out


def tumble(angles):
    return [{"angle_deg": float(d)} for d in angles]


def simulate(rng, gravity, truth, runs, samples, noise, run_noise=None):
    out = []
    for j in range(runs):
        sd = noise if run_noise is None else run_noise(j)
        bias = rng.normal(0, 10 * noise)  # a run-to-run bias change: fits absorb it
        out.append([[float(sum(v * regressor(t, a) for t, v in truth.items()) + bias + x)
                     for x in rng.normal(0, sd, samples)] for a in gravity])
    return out


def main():
    rng = np.random.default_rng(27)
    cases = []

    # The paper's Table 1: cw and ccw as the two samples of each position.
    import csv
    import os
    here = os.path.dirname(os.path.abspath(__file__))
    rows = list(csv.DictReader(open(os.path.join(here, "table1.csv"))))
    runs = [[[float(r["output"]) for r in rows if int(r["test"]) == t and float(r["angle_deg"]) == d]
             for d in (0, 90, 180, 270)] for t in range(1, 7)]
    cases.append({"name": "paper", "model": ["k0", "ki", "kp"], "positions": tumble([0, 90, 180, 270]),
                  "runs": runs, "batches": 2, "angle_std_arcsec": 0.0})
    # The same on a 2 arcsec stand (issue 42: k0's effective degrees of
    # freedom about 4).
    cases.append({"name": "paper_2arcsec", "model": ["k0", "ki", "kp"], "positions": tumble([0, 90, 180, 270]),
                  "runs": runs, "batches": 2, "angle_std_arcsec": 2.0})

    # Eight angles, an unmodelled second-order term, five samples a position.
    angles = [45 * k for k in range(8)]
    g = [pendulum(d) for d in angles]
    truth = {"k0": -8.4e-4, "ki": -1.216, "kp": 6.2e-3, "kii": 2e-4}
    cases.append({"name": "unmodelled_kii", "model": ["k0", "ki", "kp"], "positions": tumble(angles),
                  "runs": simulate(rng, g, truth, 6, 5, 1e-5), "batches": 2, "angle_std_arcsec": 120.0})

    # The same, clean: the model is right.
    cases.append({"name": "clean_angles", "model": ["k0", "ki", "kp"], "positions": tumble(angles),
                  "runs": simulate(rng, g, {"k0": -8.4e-4, "ki": -1.216, "kp": 6.2e-3}, 6, 5, 1e-5),
                  "batches": 3, "angle_std_arcsec": 120.0})

    # Explicit gravity vectors (six faces and six tilts), an output-axis
    # sensitivity the default model leaves out.
    faces = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    tilts = []
    for k in range(6):
        z = 0.6 * (-1) ** k
        th = math.pi * k / 3
        r = math.sqrt(1 - z * z)
        tilts.append([r * math.cos(th), r * math.sin(th), z])
    g = [list(map(float, v)) for v in faces + tilts]
    truth = {"k0": 1.5e-3, "ki": 1.02, "kp": -4e-3, "ko": 3e-3}
    cases.append({"name": "explicit_unmodelled_ko", "model": ["k0", "ki", "kp"],
                  "positions": [{"a": v} for v in g],
                  "runs": simulate(rng, g, truth, 4, 3, 2e-5), "batches": 2, "angle_std_arcsec": 120.0})

    # Explicit, clean, a wider model.
    truth = {"k0": 1.5e-3, "ki": 1.02, "kp": -4e-3, "ko": 3e-3}
    cases.append({"name": "explicit_clean", "model": ["k0", "ki", "kp", "ko"],
                  "positions": [{"a": v} for v in g],
                  "runs": simulate(rng, g, truth, 4, 3, 2e-5), "batches": 2, "angle_std_arcsec": 60.0})

    # One run ten times noisier than the rest.
    angles = [30 * k for k in range(12)]
    g = [pendulum(d) for d in angles]
    cases.append({"name": "noisy_run", "model": ["k0", "ki", "kp"], "positions": tumble(angles),
                  "runs": simulate(rng, g, {"k0": 1e-3, "ki": -1.2, "kp": 5e-3}, 6, 1, 1e-5,
                                   run_noise=lambda j: 1e-4 if j == 4 else 1e-5),
                  "batches": 2, "angle_std_arcsec": 0.0})

    # The second batch repeats one run, one sample nudged by a few ulps.
    angles = [45 * k for k in range(8)]
    g = [pendulum(d) for d in angles]
    base = simulate(rng, g, {"k0": 1e-3, "ki": -1.2, "kp": 5e-3}, 4, 1, 1e-5)
    copy = [[list(s) for s in base[3]] for _ in range(3)]
    copy[1][2][0] += 3e-15
    copy[2][5][0] -= 5e-15
    cases.append({"name": "implausibly_consistent", "model": ["k0", "ki", "kp"], "positions": tumble(angles),
                  "runs": base[:3] + copy, "batches": 2, "angle_std_arcsec": 0.0})

    # Explicit vectors scattered without symmetry, large cross-axis
    # sensitivities (a sensor mounted askew) and an unmodelled square: every
    # component of the rotations and the residual term matter.
    v = rng.normal(size=(10, 3))
    g = [list(map(float, x / np.linalg.norm(x))) for x in v]
    truth = {"k0": 2e-3, "ki": 0.9, "kp": 0.3, "ko": -0.2, "kii": 5e-3}
    cases.append({"name": "explicit_askew", "model": ["k0", "ki", "kp", "ko"],
                  "positions": [{"a": x} for x in g],
                  "runs": simulate(rng, g, truth, 4, 3, 2e-5), "batches": 2, "angle_std_arcsec": 90.0})

    # A single run of twelve angles on a 5 arcsec stand with a gravity value
    # known to 1e-5: the run's own standard errors on P - p = 9 degrees of
    # freedom.
    angles = [30 * k for k in range(12)]
    g = [pendulum(d) for d in angles]
    cases.append({"name": "single_run", "model": ["k0", "ki", "kp"], "positions": tumble(angles),
                  "runs": simulate(rng, g, {"k0": 1e-3, "ki": -1.2, "kp": 5e-3}, 1, 1, 3e-5),
                  "batches": 1, "angle_std_arcsec": 5.0, "gravity_rel_std": 1e-5})

    for case in cases:
        case["expected"] = analyse(case)
    # scipy's two-sided 95.45 % Student t factors, 1 to 60 degrees of
    # freedom: what a triad's element is expanded with at its ν_eff.
    table = {"coverage_probability": P_DEFAULT,
             "t_factors": [float(stats.t.ppf((1 + P_DEFAULT) / 2, n)) for n in range(1, 61)]}
    print(json.dumps({"cases": cases, "students_t": table}, indent=1))


if __name__ == "__main__":
    main()
