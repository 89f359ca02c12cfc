"""The kernel's branch-free friction law against the textbook tanh form ([thesis] Eq. 27).

The kernel evaluates tanh through a polynomial expm1 so that the contact loop compiles
to SIMD code (docs/model.md, "Speed"). These tests pin its accuracy, compiled with the
same options as the hot loop, over the whole slip range the damper visits and beyond.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampersim.solver.kernels import fastmath, friction
from dampersim.solver import layout as L

# Slip speeds [m/s]: zero, tiny (where 1 - exp would cancel), the Stribeck hump near
# 1/gamma2, and far beyond saturation; both signs.
_MAG = np.concatenate([[0.0, 1e-12, 1e-9], np.logspace(-7, 1.5, 400)])
SLIPS = np.concatenate([-_MAG[::-1], _MAG])

THESIS = (0.2, 100.0, 10.0, 0.2, 100.0, 0.01)  # gamma1..gamma6 of the default damper
GENERAL = (0.15, 80.0, 12.0, 0.25, 300.0, 0.02)  # no gamma2 = gamma5 = 10 gamma3 pattern


def exact(v, g):
    """mu and d(mu)/dv from math.tanh, evaluated one value at a time."""
    g1, g2, g3, g4, g5, g6 = g
    a, b, c = math.tanh(g2 * v), math.tanh(g3 * v), math.tanh(g5 * v)
    mu = g1 * (a - b) + g4 * c + g6 * v
    dmu = g1 * (g2 * (1 - a * a) - g3 * (1 - b * b)) + g4 * g5 * (1 - c * c) + g6
    return mu, dmu


@pytest.mark.parametrize("g", [THESIS, GENERAL], ids=["thesis-pattern", "general"])
def test_friction_law_matches_tanh_form(g):
    # 1e-13 of the law's scale: the polynomial and the doublings are accurate to a few
    # ulp; anything looser would hide a lost digit (e.g. a cancelling 1 - exp form loses
    # all digits at slips below 1e-9 m/s).
    scale = g[0] + g[3] + g[5] * 30
    dscale = g[0] * g[1] + g[3] * g[4] + g[5]
    for v in SLIPS:
        mu, dmu = friction.makkar(float(v), *g)
        mu_x, dmu_x = exact(float(v), g)
        assert abs(mu - mu_x) <= 1e-13 * scale, (v, mu, mu_x)
        assert abs(dmu - dmu_x) <= 1e-13 * dscale, (v, dmu, dmu_x)
        # odd law, exactly: the sign comes from copysign
        assert friction.makkar(-float(v), *g)[0] == -mu


def test_expm1_polynomial_relative_accuracy():
    # relative accuracy, not just absolute: near y = 0 the result is ~ -y and must keep
    # its digits there (1e-14: a few ulp after seven doublings)
    for y in np.concatenate([[1e-300, 1e-15, 1e-8], np.logspace(-6, 1.6, 300)]):
        got = fastmath.expm1_neg(float(y))
        want = math.expm1(-float(y))
        assert abs(got - want) <= 1e-14 * abs(want), (y, got, want)
    assert fastmath.expm1_neg(1e6) == -1.0  # clamped: exp(-40) is below resolution next to 1


def test_contact_loop_equals_scalar_law():
    # the SIMD loop over all contacts gives the scalar law's values at every contact
    nc = 13  # not a multiple of the 8-lane padding
    rng = np.random.default_rng(3)
    v0 = rng.normal(0.0, 2.0, nc + 1)
    v0[0] = 0.0
    CI = np.array([[i + 1, 0] for i in range(nc)], dtype=np.int64)
    CF = np.column_stack([np.ones(nc), rng.uniform(0.05, 0.12, nc)])
    FN = rng.uniform(10.0, 500.0, nc + 1)
    P = np.zeros(L.P_SIZE)
    P[L.P_G1:L.P_G6 + 1] = THESIS
    npad = (nc + 7) // 8 * 8
    XS, MU, DMU, TH = np.full(npad, np.nan), np.zeros(npad), np.zeros(npad), np.zeros(npad)
    W = np.zeros(2 * nc)
    invj = np.full(nc + 1, 100.0)
    friction.contact_laws(v0, v0, FN, P, CI, CF, invj, 1.0 / 60000.0, W, XS, MU, DMU, TH)
    for c in range(nc):
        mu, dmu = exact(float((v0[CI[c, 0]] - v0[CI[c, 1]]) * CF[c, 1]), THESIS)
        assert MU[c] == pytest.approx(mu, rel=1e-13, abs=1e-15)
        assert DMU[c] == pytest.approx(dmu, rel=1e-13, abs=1e-13)
