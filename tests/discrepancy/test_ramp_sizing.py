"""The ramps' sizing of an effect (ramp_models.size_by_ramps) with the calibration factors held
where the torsional fit would put them at each trial magnitude (no simulation: the ramps and the
torsional runs are stand-ins)."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import drive, fitting, ramp_models
from dampersim.discrepancy.effects import with_effect
from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system
from dampersim.parameters import default_parameters
from dampersim.parameters.io import named_values

N_CAL = len(CALIBRATION)


def _covariance(seed=5):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((N_CAL + 3, N_CAL + 3))
    return a @ a.T / 10.0 + 0.01 * np.eye(N_CAL + 3)  # factors, log magnitude, two more (shapes, channels)


def test_the_factors_given_the_magnitude_are_the_gaussian_conditional():
    """Checked against the precision matrix's form of the same conditional over the factors and the
    magnitude (mean shift -P_xx^-1 P_xu per unit of log magnitude, covariance P_xx^-1): rel 1e-9,
    two factorisations of one well-conditioned matrix. A magnitude without variance moves nothing."""
    cov = _covariance()
    joint = cov[:N_CAL + 1, :N_CAL + 1]  # the other parameters marginalised out
    prec = np.linalg.inv(joint)
    gain, cond = ramp_models.factors_given_magnitude(cov, N_CAL)
    p_xx_inv = np.linalg.inv(prec[:N_CAL, :N_CAL])
    assert gain == pytest.approx(-p_xx_inv @ prec[:N_CAL, N_CAL], rel=1e-9)
    assert cond == pytest.approx(p_xx_inv, rel=1e-9)
    flat = cov.copy()
    flat[N_CAL, :] = flat[:, N_CAL] = 0.0
    gain0, cond0 = ramp_models.factors_given_magnitude(flat, N_CAL)
    assert np.all(gain0 == 0.0) and np.array_equal(cond0, flat[:N_CAL, :N_CAL])


class _Ramps:
    """A ramp likelihood whose best free play is 0.02 rad when the inner springs' factor is 1 and
    moves with that factor, as a free play and the inner rate trade on a windup curve; it records
    every system it is asked about."""

    cols_x = [np.zeros(1)] * N_CAL

    def __init__(self):
        self.covs = []

    def predictive(self, w, cols, cov):
        self.covs.append(cov)
        return -50.0 * (math.log(w["free_play"]) - math.log(0.02)) ** 2, 0.0, None, None


class _Lik:
    def profile(self, y, rows):
        return 0.0, np.zeros(2)


def _sized(monkeypatch, cov, x0):
    seen = []
    base = named_values(default_parameters())

    def run_ramps(runner, system, points):
        flat = named_values(system)
        seen.append((system.effects.output_backlash.free_play,
                     flat["inner.spring.stiffness"] / base["inner.spring.stiffness"]))
        return {"free_play": system.effects.output_backlash.free_play}

    monkeypatch.setattr(ramp_models.ramps_lik, "run_ramps", run_ramps)
    monkeypatch.setattr(drive, "coefficients_of", lambda runner, system, pts: np.ones((3, 2)))
    system = with_effect(calibrated_system(default_parameters(), x0), "output_backlash", {"free_play": 0.03})
    fit = {"effects": ["output_backlash"], "m": 0.03, "cov": cov, "x": x0.copy(), "system": system}
    ramps = _Ramps()
    moved = ramp_models.size_by_ramps(None, fit, [0, 1, 2], [0, 1], [2], _Lik(), ramps, ["r"])
    return moved, fit, seen, ramps


def test_each_trial_magnitude_is_replayed_at_the_factors_the_torsional_fit_gives_it(monkeypatch):
    """The inner springs' factor moves by 0.4 per unit of log free play in the torsional fit's
    covariance (cov_xu / var_u): every replay's factor is exp(x0 + 0.4 (u - u0)) (rel 1e-9: the
    same products in another order), the moved model keeps the factors at the chosen magnitude,
    and the ramps read the conditional covariance, not the marginal one."""
    i = list(CALIBRATION).index("inner_stiffness")
    cov = 0.01 * np.eye(N_CAL + 3)
    cov[N_CAL, N_CAL] = 0.25
    cov[i, N_CAL] = cov[N_CAL, i] = 0.1  # K = 0.1 / 0.25
    x0 = np.full(N_CAL, 0.05)
    moved, fit, seen, ramps = _sized(monkeypatch, cov, x0)
    assert moved and fit["m"] == pytest.approx(0.02, rel=0.03)
    for free_play, factor in seen:
        assert factor == pytest.approx(math.exp(0.05 + 0.4 * math.log(free_play / 0.03)), rel=1e-9)
    shift = 0.4 * math.log(fit["m"] / 0.03)
    assert fit["x"][i] == pytest.approx(0.05 + shift, rel=1e-9)
    others = [k for k in range(N_CAL) if k != i]
    assert np.array_equal(fit["x"][others], x0[others])
    flat, base = named_values(fit["system"]), named_values(default_parameters())
    assert flat["inner.spring.stiffness"] / base["inner.spring.stiffness"] == pytest.approx(math.exp(0.05 + shift))
    assert flat["inner.nested.stiffness"] / base["inner.nested.stiffness"] == pytest.approx(math.exp(0.05 + shift))
    assert fit["system"].effects.output_backlash.free_play == pytest.approx(fit["m"])
    expected_cov = cov[:N_CAL, :N_CAL].copy()
    expected_cov[i, i] -= 0.1 ** 2 / 0.25
    assert all(np.allclose(c, expected_cov, rtol=0, atol=1e-15) for c in ramps.covs)


def test_the_moved_factors_stay_inside_their_range(monkeypatch):
    """A gain that would carry a factor past its bound (log 2) stops it there."""
    i = list(CALIBRATION).index("inner_stiffness")
    cov = 0.01 * np.eye(N_CAL + 3)
    cov[N_CAL, N_CAL] = 0.25
    cov[i, N_CAL] = cov[N_CAL, i] = -2.5  # K = -10: a free play 40 % smaller would double the rate
    x0 = np.zeros(N_CAL)
    moved, fit, seen, _ = _sized(monkeypatch, cov, x0)
    assert moved
    assert max(f for _, f in seen) == pytest.approx(2.0, rel=1e-12)
    assert fit["x"][i] == pytest.approx(fitting.CAL_BOUND, rel=1e-12)
