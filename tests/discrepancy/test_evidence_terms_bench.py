"""The ramp profile of bench/bench_evidence_terms.py (``--ramp-profile``), on a fake runner
and a fake ramp likelihood (no diagnosis is run): docs/discrepancy.md quotes its replayed
ramp evidence against the linearised term ("The ramps' evidence replayed along the
magnitude")."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import drive
from dampersim.discrepancy.effects import with_effect
from dampersim.parameters import default_parameters
from tests.discrepancy.benches import NullRunner, load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_evidence_terms")


def gauss_product(u0, s0, mu, s1):
    """log of the integral of N(u; u0, s0^2) exp(-(u - mu)^2 / (2 s1^2)) du."""
    v = s0 ** 2 + s1 ** 2
    return 0.5 * math.log(s1 ** 2 / v) - 0.5 * (u0 - mu) ** 2 / v


def test_the_replayed_evidence_is_the_gaussian_integral_on_a_grid_that_holds_it(bench):
    # 41 points over +-4 sd of the fit's Gaussian, a ramp likelihood of sd 0.3 in log magnitude
    # (wider than the 0.1 spacing): the grid sum is the integral to well below 0.01 nats
    u0, s0, mu, s1 = math.log(0.03), 0.5, math.log(0.01), 0.3
    us = np.linspace(u0 - 4 * s0, u0 + 4 * s0, 41)
    rel = -0.5 * ((us - mu) / s1) ** 2
    assert bench.replayed_evidence(us, rel, u0, s0 ** 2) == pytest.approx(gauss_product(u0, s0, mu, s1), abs=0.01)
    assert bench.replayed_evidence(us, np.full(us.size, -math.inf), u0, s0 ** 2) is None
    # a failed replay leaves its grid point out of the sum and of the weights
    part = rel.copy()
    part[::2] = -math.inf
    assert bench.replayed_evidence(us, part, u0, s0 ** 2) == pytest.approx(
        bench.replayed_evidence(us[1::2], rel[1::2], u0, s0 ** 2))


class _Runner(NullRunner):
    """Replays a ramp as a one-sample windup equal to the system's free play [rad]."""

    def map(self, tasks):
        return [{"windup": np.array([s.effects.output_backlash.free_play])} for s, _ in tasks]


class _Ramps:
    """A ramp likelihood peaked at a free play of 0.01 rad (sd 0.3 in log), with share 0.5."""

    cols_x = [np.zeros(1)] * 6
    fraction = 0.5

    def predictive(self, w, cols, cov):
        return -0.5 * ((math.log(float(w["r"][0])) - math.log(0.01)) / 0.3) ** 2, 0.0, None, None


class _Point:
    id = "r"


def test_the_profile_replays_the_grid_and_reads_it_against_none(bench, monkeypatch):
    monkeypatch.setattr(drive, "Runner", _Runner)
    monkeypatch.setattr(drive, "diagnosis_system", lambda s: s)
    cov = np.eye(7) * 0.01
    cov[6, 6] = 0.5 ** 2
    fit = {"effects": ["output_backlash"], "m": 0.03, "cov": cov,
           "system": with_effect(default_parameters(), "output_backlash", {"free_play": 0.03})}
    out = bench.ramp_profile(fit, _Ramps(), [_Point()], ll_none=-1.0, ll_lin=2.0, workers=1)
    mags = [m for m, _ in out["rows"]]
    assert len(mags) == bench.PROFILE_POINTS
    # the grid spans the fit's log magnitude +- 4 sd (2 here, above the sizing's 1.5)
    assert math.log(mags[0]) == pytest.approx(math.log(0.03) - 2.0, abs=1e-3)
    assert math.log(mags[-1]) == pytest.approx(math.log(0.03) + 2.0, abs=1e-3)
    assert out["linearised"] == pytest.approx(3.0) and out["share"] == 0.5
    assert 0.0085 < out["best"] < 0.0115  # the grid point nearest the peak (spacing 0.2 in log)
    # relative to "none": every row and the sum are shifted by +1 nat
    assert out["replayed"] == pytest.approx(gauss_product(math.log(0.03), 0.5, math.log(0.01), 0.3) + 1.0, abs=0.01)
