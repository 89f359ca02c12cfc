"""Ramp windup curves in the likelihood (no simulation: windups are given)."""

import dataclasses
import math

import numpy as np
import pytest

from dampersim.discrepancy.ramps import OFFSET_PRIOR_DEG, RampLikelihood, windup_noise
from tests.discrepancy import fake_rig as F


def _noisy(p, sd, seed=0):
    rng = np.random.default_rng(seed)
    return dataclasses.replace(p, windup=p.windup + rng.normal(0.0, sd, p.windup.size))


def test_a_matching_model_scores_chi2_near_its_sample_count():
    """Pure white noise on the windup channel: the model that produced the ramp scores a
    chi^2 per sample near 1 (the noise estimate after the 10 Hz low pass is right)."""
    sd = math.radians(0.5)
    pts = [_noisy(F.ramp(f"r{i}"), sd, i) for i in range(4)]
    truth = {p.id: F.ramp(p.id).windup for p in pts}
    lik = RampLikelihood(pts, truth, truth)
    total, per = lik.chi2(truth)
    assert 0.5 < total / lik.residuals < 1.6  # 24 samples: chi^2/dof scatters by about +-0.3 at 1 sigma
    assert set(per) == {p.id for p in pts}
    assert windup_noise(pts[0]) == pytest.approx(sd * math.sqrt(math.pi * 10.0 / 1000.0), rel=0.1)


def test_an_angle_offset_is_a_nuisance_but_a_free_play_step_is_not():
    p = F.ramp("r0")
    lik = RampLikelihood([p], {p.id: p.windup}, {p.id: p.windup})
    offset = np.radians(OFFSET_PRIOR_DEG)  # one prior sd: costs about 1
    assert lik.chi2({p.id: p.windup + offset})[0] < 2.0
    # a 0.2 deg step where the torque changes sign (free play) is not absorbed
    tq = p.input_torque
    step = np.where(np.gradient(tq) > 0, 0.0, np.radians(0.2))
    assert lik.chi2({p.id: p.windup + step})[0] > 100.0


def test_a_failed_ramp_run_is_never_a_match():
    p = F.ramp("r0")
    lik = RampLikelihood([p], {p.id: p.windup}, {p.id: p.windup})
    assert lik.chi2({p.id: "SimulationDiverged: runaway windup"})[0] == math.inf
    assert lik.chi2({})[0] == math.inf


def test_the_ramp_prediction_carries_the_fit_uncertainty_and_sizes_the_parameter():
    """A model whose parameter the torsional fit left uncertain (log sd 1) is not condemned by
    a ramp that needs the parameter 30 % larger: the prediction's covariance holds that
    direction, and the conditioned update recovers the parameter (linear toy: windup
    proportional to the parameter)."""
    p = _noisy(F.ramp("r0"), math.radians(0.05))
    shape = F.ramp("r0").windup  # windup at parameter value 1 (log parameter 0)
    meas = dataclasses.replace(p, windup=1.3 * shape + (p.windup - shape))
    model = {p.id: shape}
    lik = RampLikelihood([meas], model, model)
    col = lik.column({p.id: shape * math.exp(0.01)}, model, 0.01)  # d samples / d log parameter
    ll_unsure, chi_unsure, upd, cov = lik.predictive(model, col[:, None], np.array([[1.0]]))
    assert lik.scale < 2.0  # the uncertain parameter explains the ramp: channel noise is enough
    ll_sure, chi_sure, _, _ = lik.predictive(model, col[:, None], np.array([[1e-6]]))
    assert lik.scale > 10.0  # a sure, wrong parameter: only a large misfit scale makes the ramp likely
    assert ll_unsure > ll_sure + 10  # odds above 20 000 to 1
    assert math.exp(upd[0]) == pytest.approx(1.3, rel=0.05)  # linearised in log: exp(0.262) against 1.3
    assert cov[0, 0] < 0.01


def test_a_ramp_signature_counts_only_what_offsets_and_parameters_cannot_absorb():
    p = F.ramp("r0")
    base = {p.id: p.windup}
    lik = RampLikelihood([p], base, base)
    col = lik.column({p.id: p.windup * math.exp(0.01)}, base, 0.01)[:, None]  # a stiffness-like direction
    cov = np.array([[1e-4]])
    offset = {p.id: p.windup + np.radians(0.05)}
    step = {p.id: p.windup + np.where(np.gradient(p.input_torque) > 0, 0.0, np.radians(0.2))}
    scaled = {p.id: p.windup * 1.001}
    assert lik.signature_gain(offset, base, col, cov, 1.0) < 1.0  # an angle zero: the offset nuisance takes it
    assert lik.signature_gain(scaled, base, col, cov, 1.0) < 1.0  # inside the parameter's uncertainty
    assert lik.signature_gain(step, base, col, cov, 1.0) > 100.0  # a free-play step is not absorbed
    assert lik.signature_gain(step, base, col, cov, 10.0) < lik.signature_gain(step, base, col, cov, 1.0) / 50


def test_correlated_ramp_samples_count_as_fewer_independent_ones():
    """An AR(1) residual with lag-one correlation 0.8 carries (1 - 0.8) / (1 + 0.8) = 11 % of
    its samples' evidence; white noise all of it (20 000 samples: the estimate of rho is
    within about 0.01, the share within 0.01)."""
    from dampersim.discrepancy.ramps import effective_share

    rng = np.random.default_rng(8)
    white = rng.standard_normal(20000)
    assert effective_share(white, [20000]) > 0.97
    ar = np.zeros(20000)
    for t in range(1, 20000):
        ar[t] = 0.8 * ar[t - 1] + white[t]
    assert effective_share(ar, [10000, 10000]) == pytest.approx(0.2 / 1.8, abs=0.01)
    # the autocorrelation is read within each ramp: two ramps whose misfits differ by a
    # constant (each ramp has its own angle offset) are white inside; pooled as one ramp the
    # step between them reads as a strong correlation
    steps = np.concatenate([white[:100] + 10.0, white[100:200] - 10.0])
    assert effective_share(steps, [100, 100]) > 0.7
    assert effective_share(steps, [200]) < 0.05
    # a pure trend is worth about one and a half samples (rho = 0.94 for 50 samples), and a
    # ramp never counts as less than one sample
    assert 1.0 / 50 <= effective_share(np.linspace(0.0, 1.0, 50), [50]) < 0.05
    # a smooth half wave in each of two ramps: about one sample per ramp, never fewer
    assert 2.0 / 200 <= effective_share(np.tile(np.cos(np.linspace(0.0, np.pi, 100)), 2), [100, 100]) < 0.011


def test_the_ramp_noise_is_read_off_the_best_ramp_prediction():
    """The detectability of a ramp effect is read against the uncertainty scale of the model
    that predicts the ramps best, not that of "none": with a free play in the data, "none"
    fits a scale inflated by the free play's own misfit, and the present effect would read
    undetectable (as benchmark case effect/output_backlash/strong/s0 did)."""
    import math

    from dampersim.discrepancy.ramps import ramp_reference

    assert ramp_reference({"none": -120.0, "output_backlash": -40.0, "clutch_slip": -118.0}) == "output_backlash"
    assert ramp_reference({"none": -10.0, "output_backlash": -math.inf}) == "none"
    assert ramp_reference({"none": -math.inf, "turbine_drag": -math.inf}) == "none"


def test_detectability_reads_the_ramps_at_the_best_predictions_noise_scale():
    """settle() takes the ramps' noise scale from the model that predicts them best, and a
    signature's gain is read against it by default: against the scale "none" fits to a
    campaign holding a free play, that same free play would look undetectable (benchmark
    case effect/output_backlash/strong/s0, commit 19acb87)."""
    p = F.ramp("r0")
    base = {p.id: p.windup}
    lik = RampLikelihood([p], base, base)
    col = lik.column({p.id: p.windup * math.exp(0.01)}, base, 0.01)[:, None]
    cov = np.array([[1e-4]])
    step = {p.id: p.windup + np.where(np.gradient(p.input_torque) > 0, 0.0, np.radians(0.2))}
    # the best prediction's whitened residual is a slow trend: its samples count as fewer
    # independent ones, and every model's log likelihood is scaled by that share
    trend = np.linspace(-1.0, 1.0, lik.residuals)
    ll = lik.settle({"none": -900.0, "output_backlash": -40.0},
                    {"none": 8.0, "output_backlash": 1.5}, {"none": None, "output_backlash": trend})
    assert lik.noise_scale == 1.5
    assert 0.0 < lik.fraction < 0.9
    assert ll == pytest.approx({"none": -900.0 * lik.fraction, "output_backlash": -40.0 * lik.fraction})
    assert lik.signature_gain(step, base, col, cov) == lik.signature_gain(step, base, col, cov, 1.5)
    assert lik.signature_gain(step, base, col, cov) > 10 * lik.signature_gain(step, base, col, cov, 8.0)
    # every prediction failed: ramp_reference falls back to "none", and so does the scale
    lik.settle({"none": -math.inf, "output_backlash": -math.inf}, {"none": 3.0, "output_backlash": 1.0}, {})
    assert lik.noise_scale == 3.0


# --- a single effect's ramps replayed along its magnitude (ramp_models) -------------------

def test_the_profile_integral_is_the_gaussian_closed_form():
    """A Gaussian log likelihood in u times the fit's Gaussian on u integrates to the
    closed form when the grid holds both (tolerance: 21 grid points over +-4 sd; the
    trapezoid on a smooth Gaussian product is good to well below 0.01 nats)."""
    from dampersim.discrepancy.ramp_models import integrate_profile

    u0, s0, mu, s1 = math.log(0.03), 0.5, math.log(0.01), 0.3
    us = np.linspace(u0 - 4 * s0, u0 + 4 * s0, 21)
    ll = -0.5 * ((us - mu) / s1) ** 2
    v = s0 ** 2 + s1 ** 2
    exact = 0.5 * math.log(s1 ** 2 / v) - 0.5 * (u0 - mu) ** 2 / v
    assert integrate_profile(us, ll, u0, s0 ** 2) == pytest.approx(exact, abs=0.01)
    # a failed replay is no match: it adds nothing to the integral but keeps its prior mass
    ll_failed = ll.copy()
    ll_failed[10] = -math.inf
    assert integrate_profile(us, ll_failed, u0, s0 ** 2) < integrate_profile(us, ll, u0, s0 ** 2)
    assert integrate_profile(us, np.full(us.size, -math.inf), u0, s0 ** 2) == -math.inf


def test_the_magnitude_grid_stays_in_the_accepted_range():
    from dampersim.discrepancy import naming
    from dampersim.discrepancy.ramp_models import PROFILE_POINTS, RAMP_SEARCH, magnitude_grid

    us = magnitude_grid("output_backlash", math.log(0.03), 0.01)  # narrow fit: the search half width
    assert len(us) == PROFILE_POINTS
    assert us[0] == pytest.approx(math.log(0.03) - RAMP_SEARCH) and us[-1] == pytest.approx(math.log(0.03) + RAMP_SEARCH)
    wide = magnitude_grid("output_backlash", math.log(0.03), 4.0)  # 4 sd = 8 in log: clipped to the range
    assert all(math.exp(u) == pytest.approx(naming.clip_magnitude("output_backlash", math.exp(u))) for u in wide)


class _StepRunner:
    """Replays a ramp as the clean windup plus a free play's signature: an offset of the
    free play on the unloading branch (where the input torque falls)."""

    def __init__(self, p):
        self.base = p.windup.copy()
        self.falling = np.gradient(p.input_torque) < 0

    def windup(self, gap):
        return self.base + np.where(self.falling, gap, 0.0)

    def map(self, tasks):
        return [{"windup": self.windup(s.effects.output_backlash.free_play)} for s, _ in tasks]


def _replayed_lead(measured_gap, fitted_gap=0.01, sd_log=1.0):
    """The ramps' replayed evidence of a fitted free play against the clean model, with the
    ramp measured at ``measured_gap`` [rad] (channel noise 0.05 deg)."""
    from dampersim.discrepancy.effects import with_effect
    from dampersim.discrepancy.fitting import CALIBRATION
    from dampersim.discrepancy.ramp_models import integrate_profile, magnitude_grid, replay_profile
    from dampersim.parameters import default_parameters

    clean = F.ramp("r0")
    runner = _StepRunner(clean)
    meas = _noisy(dataclasses.replace(clean, windup=runner.windup(measured_gap)), math.radians(0.05))
    lik = RampLikelihood([meas], {meas.id: clean.windup}, {meas.id: clean.windup})
    n = len(CALIBRATION)
    lik.cols_x = [np.zeros(lik.residuals)] * n
    cov = np.eye(n + 1) * 0.01
    cov[n, n] = sd_log ** 2
    ll_none = lik.predictive({meas.id: clean.windup}, np.column_stack(lik.cols_x), cov[:n, :n])[0]
    u0 = math.log(fitted_gap)
    fit = {"effects": ["output_backlash"], "m": fitted_gap, "cov": cov,
           "system": with_effect(default_parameters(), "output_backlash", {"free_play": fitted_gap})}
    us = magnitude_grid("output_backlash", u0, sd_log ** 2)
    lls = np.array([r[0] for r in replay_profile(runner, lik, fit, [meas], us)])
    return integrate_profile(us, lls, u0, sd_log ** 2) - ll_none


def test_replayed_ramps_favour_a_free_play_only_when_the_ramp_shows_one():
    """With no free play in the measured ramp every replayed magnitude fits worse than the
    clean model, so the integral over the magnitude cannot lead (-5.8 nats here); with a
    0.01 rad free play (0.57 deg, about 11 times the channel noise) the replays near that
    magnitude lead by 12.7 nats (not more: each model fits its own uncertainty scale, so
    the clean model widens its samples to its misfit). 10 nats is decisive and leaves room
    for the grid's placement."""
    assert _replayed_lead(0.0) < 0.0
    assert _replayed_lead(0.01) > 10.0
