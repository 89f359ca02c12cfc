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
