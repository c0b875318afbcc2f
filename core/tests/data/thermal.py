#!/usr/bin/env python3
"""Independent reference for coefficients over temperature (issue 45), with
numpy and scipy (not accelcal's code): for each case, a coefficient's
estimates at temperature set points with their standard uncertainties, the
weighted least-squares polynomial about the reference temperature
(numpy's lstsq on the rows scaled by 1/u), its covariance (XᵀWX)⁻¹ inflated
by max(1, χ²/ν), the degree by backward elimination from the
highest the set points allow (what accelcal does) and by the issue's forward
selection (recorded beside it: it stops short of a planted cubic), each
partial F test by scipy's F survival function at level 1 %, the polynomial and its standard uncertainty
at a temperature, its slope there, and the condition number of the
column-scaled design (numpy's cond).

    python3 -m venv /tmp/v && /tmp/v/bin/pip install numpy scipy
    /tmp/v/bin/python core/tests/data/thermal.py > core/tests/data/thermal.json
"""
import json
from decimal import ROUND_HALF_UP, Decimal

import numpy as np
from scipy import stats

ALPHA = 0.01
MAX_DEGREE = 3


def design(t, tref, degree):
    return np.vander(np.asarray(t) - tref, degree + 1, increasing=True)


def weighted(t, c, u, tref, degree):
    X = design(t, tref, degree)
    A = X / u[:, None]
    b = c / u
    a, *_ = np.linalg.lstsq(A, b, rcond=None)
    chi2 = float(np.sum((A @ a - b) ** 2))
    cov = np.linalg.inv(A.T @ A)
    return a, cov, chi2


def select(t, c, u, tref):
    n = len(t)
    d = 0
    _, _, chi2 = weighted(t, c, u, tref, 0)
    tests = []
    while d < MAX_DEGREE and d + 1 <= n - 2:
        _, _, nxt = weighted(t, c, u, tref, d + 1)
        df2 = n - d - 2
        f = (chi2 - nxt) / (nxt / df2)
        p = float(stats.f.sf(f, 1, df2))
        tests.append({"f": f, "df2": df2, "p_value": p})
        if not p < ALPHA:
            break
        d += 1
        chi2 = nxt
    return d, tests


def backward(t, c, u, tref):
    """Backward elimination: from the highest degree the set points allow
    (at most 3, D ≤ N − 2), drop the top degree while its partial F against
    the larger model's residual is not significant at 1 %."""
    n = len(t)
    d = min(MAX_DEGREE, n - 2)
    tests = []
    while d > 0:
        _, _, big = weighted(t, c, u, tref, d)
        _, _, small = weighted(t, c, u, tref, d - 1)
        df2 = n - d - 1
        f = (small - big) / (big / df2)
        p = float(stats.f.sf(f, 1, df2))
        tests.append({"f": f, "df2": df2, "p_value": p})
        if p < ALPHA:
            break
        d -= 1
    return d, tests


def case(name, t, c, u, degree=None, at=33.0):
    t, c, u = (np.asarray(x, dtype=float) for x in (t, c, u))
    # The mean rounded to 0.1 K, halves away from zero (not Python's
    # round, which rounds halves to even).
    tref = float(Decimal(repr(float(np.mean(t)))).quantize(Decimal("0.1"), ROUND_HALF_UP))
    tests, forward = [], None
    if degree is None:
        forward_degree, forward_tests = select(t, c, u, tref)
        forward = {"degree": forward_degree, "tests": forward_tests}
        degree, tests = backward(t, c, u, tref)
    a, cov, chi2 = weighted(t, c, u, tref, degree)
    nu = len(t) - degree - 1
    cov = cov * max(1.0, chi2 / nu)
    v = (at - tref) ** np.arange(degree + 1)
    slope = sum(d * a[d] * (at - tref) ** (d - 1) for d in range(1, degree + 1))
    X = design(t, tref, degree)
    X = X / np.linalg.norm(X, axis=0)
    return {
        "name": name,
        "temperatures_c": t.tolist(),
        "values": c.tolist(),
        "std_uncertainties": u.tolist(),
        "fixed": name.startswith("fixed"),
        "reference_c": tref,
        "degree": degree,
        "coefficients": a.tolist(),
        "covariance": cov.tolist(),
        "chi2": chi2,
        "dof": nu,
        "tests": tests,
        "forward": forward,
        "at_c": at,
        "value_at": float(v @ a),
        "std_uncertainty_at": float(np.sqrt(v @ cov @ v)),
        "slope_at": float(slope),
        "condition": float(np.linalg.cond(X)),
    }


def planted(a, t, tref=20.0):
    t = np.asarray(t, dtype=float)
    return sum(ad * (t - tref) ** d for d, ad in enumerate(a))


rng = np.random.default_rng(45)
chamber = [-20.0, 0.0, 20.0, 40.0, 60.0]
cases = []

# A MEMS bias: quadratic, 2 mg over the range, noise at its u.
u = np.array([4e-5, 3e-5, 2e-5, 3e-5, 5e-5])
c = planted([0.012, 3.1e-4, 2.4e-6], chamber) + u * rng.standard_normal(5)
cases.append(case("quadratic bias, five set points", chamber, c, u))

# A scale factor: linear, noise at u, nine set points.
nine = [-30.0, -15.0, 0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0]
u = np.full(9, 2e-5)
c = planted([1.0021, -3.5e-5], nine) + u * rng.standard_normal(9)
cases.append(case("linear scale factor, nine set points", nine, c, u))

# A cubic, well resolved at seven set points.
seven = [-40.0, -20.0, 0.0, 20.0, 40.0, 60.0, 85.0]
u = np.full(7, 1e-5)
c = planted([0.003, 2e-5, 4e-6, 6e-9], seven) + u * rng.standard_normal(7)
cases.append(case("cubic, seven set points", seven, c, u, at=-5.0))

# A cubic whose quadratic term is small: forward selection stops at the
# line, since the quadratic's partial F is judged against a residual that
# still holds the cubic (the selection's known blind spot; the Birge ratio
# then carries the misfit into the line's uncertainty).
c = planted([0.003, 2e-5, -4e-7, 6e-9], seven) + u * rng.standard_normal(7)
cases.append(case("cubic with a small quadratic, seven set points", seven, c, u, at=-5.0))

# Scatter ten times the stated u: the Birge ratio inflates the covariance.
u = np.full(5, 1e-5)
c = planted([0.5, 1e-4], chamber) + 1e-4 * rng.standard_normal(5)
cases.append(case("fixed degree 1, scatter beyond u", chamber, c, u, degree=1))

# Uneven set points and uncertainties, degree 2 asked for.
uneven = [-10.0, 5.0, 23.0, 24.5, 50.0, 71.0]
u = np.array([6e-5, 2e-5, 1e-5, 1e-5, 3e-5, 8e-5])
c = planted([-0.02, 1.5e-4, -8e-7], uneven) + u * rng.standard_normal(6)
cases.append(case("fixed degree 2, uneven", uneven, c, u, degree=2, at=71.0))

print(json.dumps({"cases": cases}, indent=1))
