"""The diagnosis likelihood and model selection arithmetic (no simulation)."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import selection
from dampersim.discrepancy.likelihood import DELAY_PRIOR_SD, ROBUST_C, Likelihood, cell_sigma, robust_weights

ORDERS = np.arange(1.0, 9.0)


def _campaign(n=12, seed=0, sigma=0.05):
    rng = np.random.default_rng(seed)
    speed = rng.uniform(100.0, 300.0, n)  # rad/s
    model = (rng.uniform(1.0, 20.0, (n, 8)) * np.exp(1j * rng.uniform(-3, 3, (n, 8))))
    noise = sigma / math.sqrt(2) * (rng.standard_normal((n, 8)) + 1j * rng.standard_normal((n, 8)))
    return speed, model, noise, np.full((n, 8), sigma)


def test_channel_skew_and_gain_are_fitted_not_left_as_misfit():
    """A 0.2 ms output delay and a 2 % gain error are recovered as nuisance; the remaining
    misfit is at the noise level (reduced chi^2 near 1). Without the nuisance fit the skew
    alone leaves a misfit hundreds of times the noise: it would read as a physical effect
    such as a transducer's bandwidth."""
    speed, model, noise, sigma = _campaign()
    tau, gain = 2e-4, 1.02
    meas = gain * model * np.exp(-1j * np.outer(speed, ORDERS) * tau) + noise
    lik = Likelihood(meas, sigma, speed, ORDERS)
    rows = list(range(len(meas)))
    unfitted = lik.reduced_chi2(model, rows)
    nu = lik.fit_nuisance(model, rows)
    assert nu[1] == pytest.approx(tau, rel=0.01)  # the delay to 1 % (noise 0.05 N m on orders of 1-20 N m)
    assert math.exp(nu[0]) == pytest.approx(gain, rel=0.002)
    fitted = lik.reduced_chi2(model, rows)
    assert unfitted > 100.0
    assert 0.7 < fitted < 1.3  # 192 real residuals: chi^2/dof within +-0.3 of 1 at about 3 sigma


def test_robust_loss_flags_the_one_bad_point_and_bounds_its_weight():
    speed, model, noise, sigma = _campaign(seed=1)
    meas = model + noise
    meas[5] += 3.0  # one point 60 sigma off at every order
    lik = Likelihood(meas, sigma, speed, ORDERS)
    rows = list(range(len(meas)))
    flags = lik.outliers(model, rows)
    assert np.flatnonzero(flags).tolist() == [5]
    chi = lik.point_chi2(model, rows)
    _, loss, _ = robust_weights(chi, 16)
    # the bad point's loss grows linearly, not quadratically, with its misfit
    assert loss[5] < 0.2 * chi[5]
    assert np.allclose(np.delete(loss, 5), np.delete(chi, 5))


def test_the_reweighting_gives_the_robust_loss_slope_where_the_stored_weights_do_not():
    """A Gauss-Newton step of the robust loss at a model must weigh each point by that model's
    Huber weight: the loss's change along a model change dy is -2 (f r) . (f w(dy)) to first
    order, r and w(dy) standardised at the stored weights, f the reweighting. The stored weights
    (all 1 here) give the one bad point its full quadratic pull. With the threshold held: the
    median point's RMS misfit stays below 1 here (above it, the threshold moves with the median
    point, a term re-weighted least squares leaves out)."""
    speed, model, noise, _ = _campaign(seed=1)
    meas = model + noise
    meas[5] += 3.0  # one point 30 sigma off at every order
    sigma = np.full(meas.shape, 0.1)  # the good points' RMS standardised misfit about 0.6: the threshold stays 3
    lik = Likelihood(meas, sigma, speed, ORDERS)
    rows = list(range(len(meas)))
    nu = lik.fit_nuisance(model, rows, refresh_weights=False)
    assert np.all(lik.weights == 1.0)
    dy = np.zeros_like(model)
    dy[[2, 5]] = np.random.default_rng(3).normal(size=(2, 8)) * (1 + 0.5j)
    f = lik.reweighting(model, rows, nu)
    assert f.shape == (2 * len(rows) * len(ORDERS),) and np.sum(f < 1.0) == 16  # the bad point's 16 rows
    r = lik.mvec(rows) - lik.vec(model, rows)
    slope_reweighted = -2.0 * float((f * r) @ (f * lik.vec(dy, rows)))
    slope_stored = -2.0 * float(r @ lik.vec(dy, rows))
    t = 1e-6  # small against the misfit (the loss's curvature term is t^2 |w(dy)|^2, 1e-9 of the slope)
    slope = (lik.loss(model + t * dy, rows) - lik.loss(model - t * dy, rows)) / (2 * t)
    assert slope == pytest.approx(slope_reweighted, rel=1e-6)
    assert abs(slope_stored - slope) > 0.5 * abs(slope)


def test_the_reweighting_carries_vectors_from_the_stored_weights_to_the_models_own():
    """The stored weights and nuisance are another model's (one point moved so that it is
    down-weighted there), and the model is read at a nuisance of its own: the factors squared
    times the stored weights are the model's Huber weights at that nuisance, per point, on the
    real and the imaginary halves alike."""
    speed, model, noise, sigma = _campaign(seed=2)
    meas = model + noise
    lik = Likelihood(meas, sigma, speed, ORDERS)
    rows = list(range(len(meas)))
    other = model.copy()
    other[4] += 1.0  # 20 sigma: point 4 is down-weighted in the stored weights
    lik.fit_nuisance(other, rows)
    stored = lik.weights.copy()
    assert stored[4] < 0.5 and np.all(np.delete(stored, 4) == 1.0)
    current = model.copy()
    current[7] -= 1.0  # the model's own outlier: point 7
    nu = np.array([1e-3, 2e-7])  # not the stored nuisance, and small against sigma (the median point stays below 1)
    assert not np.allclose(nu, lik.nuisance)
    f = lik.reweighting(current, rows, nu)
    w_model = robust_weights(lik.point_chi2(current, rows, nu), 2 * len(ORDERS))[0]
    assert w_model[7] < 0.5 and w_model[4] == 1.0
    per_row = np.repeat(w_model, len(ORDERS))
    np.testing.assert_allclose(f ** 2 * np.tile(np.repeat(stored, len(ORDERS)), 2), np.tile(per_row, 2), rtol=1e-12)
    lik.weights[3] = 0.0  # a point the stored model gave no weight: no factor, never a division by zero
    assert np.all(lik.reweighting(current, rows, nu).reshape(2, len(rows), len(ORDERS))[:, 3] == 0.0)


def test_robust_threshold_follows_the_median_point():
    """When every point misfits alike (a missing effect), none is an outlier."""
    chi = np.full(10, 16 * 50.0)
    _, _, big = robust_weights(chi, 16)
    assert not big.any()
    chi[3] *= (2 * ROBUST_C) ** 2
    assert robust_weights(chi, 16)[2].tolist() == [i == 3 for i in range(10)]


def test_cell_sigma_pools_the_repeatability_per_order():
    rep = np.ones((6, 8)) * 0.1
    rep[2, 3] = 0.0  # a single lucky split-half sample must not make a cell exact
    s = cell_sigma(rep, np.zeros((6, 8)), np.full((6, 8), 10.0))
    assert s[2, 3] >= 0.07  # half the pooled variance at least
    # a typical cell: the mean of its own variance and the pooled one (median / ln 2), plus the floor
    assert s[0, 0] == pytest.approx(math.sqrt(0.5 * (0.01 + 0.01 / math.log(2.0)) + 1e-4), rel=1e-9)


def test_cell_sigma_adds_the_pickup_and_the_input_offset_check_in_quadrature():
    rep = np.full((3, 8), 0.1)
    meas = np.full((3, 8), 10.0)
    base = cell_sigma(rep, np.zeros((3, 8)), meas)
    pick = np.zeros((3, 8))
    pick[1, 1] = 0.3
    off = np.full((3, 8), 0.2)
    s = cell_sigma(rep, np.zeros((3, 8)), meas, pick, off)
    assert s == pytest.approx(np.sqrt(base ** 2 + pick ** 2 + off ** 2), rel=1e-12)
    assert cell_sigma(rep, np.zeros((3, 8)), meas, None, off) == pytest.approx(np.sqrt(base ** 2 + off ** 2))
    # the terms the benchmark's decomposition prints (bench/bench_sigma_terms.py) add up to it
    from dampersim.discrepancy.likelihood import SIGMA_FLOOR_SHARE, sigma_variances

    mc = np.full((3, 8), 0.05)
    unc = np.zeros((3, 8))
    unc[2, 1] = 0.4  # a knee point's order 2, moved by the group split
    v = sigma_variances(rep, mc, meas, pick, off, unc)
    assert sorted(v) == ["floor", "input", "mains", "model", "repeat", "uncalibrated"]
    assert np.sqrt(sum(v.values())) == pytest.approx(cell_sigma(rep, mc, meas, pick, off, unc), rel=1e-12)
    assert v["floor"] == pytest.approx(np.full((3, 8), (SIGMA_FLOOR_SHARE * 10.0) ** 2))
    assert v["mains"] == pytest.approx(pick ** 2) and v["input"] == pytest.approx(off ** 2)
    assert v["uncalibrated"] == pytest.approx(unc ** 2)
    assert cell_sigma(rep, mc, meas, pick, off, unc) == pytest.approx(
        np.sqrt(cell_sigma(rep, mc, meas, pick, off) ** 2 + unc ** 2), rel=1e-12)


def test_pooled_repeatability_is_unbiased_for_gaussian_noise():
    """Split-half samples of complex Gaussian noise of variance v: the pooled variance
    (median / ln 2) estimates v without the 31 % bias of a plain median."""
    rng = np.random.default_rng(5)
    v = 0.04
    rep = np.abs(math.sqrt(v / 2) * (rng.standard_normal((4000, 8)) + 1j * rng.standard_normal((4000, 8))))
    s = cell_sigma(rep, np.zeros_like(rep), np.full_like(rep, 1e-3))
    assert np.mean(s ** 2) == pytest.approx(v, rel=0.03)  # 32 000 samples: about 1 % statistical error
    assert np.all(s >= 1e-3 * 10.0)


def test_laplace_evidence_is_exact_for_a_linear_gaussian_model():
    """For r = J theta + noise with a Gaussian prior the Laplace evidence is exact: compare
    with the closed form of the marginal likelihood N(r; 0, I + J P^-1 J')."""
    rng = np.random.default_rng(2)
    jac = rng.standard_normal((30, 3))
    prec = np.array([4.0, 1.0, 25.0])
    r = jac @ rng.standard_normal(3) + rng.standard_normal(30)
    a = jac.T @ jac + np.diag(prec)
    theta = np.linalg.solve(a, jac.T @ r)
    cost = float((r - jac @ theta) @ (r - jac @ theta) + theta @ (prec * theta))
    lz = selection.log_evidence(cost, jac, prec)
    cov = np.eye(30) + jac @ np.diag(1 / prec) @ jac.T
    exact = -0.5 * r @ np.linalg.solve(cov, r) - 0.5 * np.linalg.slogdet(cov)[1]
    assert lz == pytest.approx(exact, abs=1e-9)


def test_a_tempered_evidence_equals_the_evidence_with_widened_uncertainties():
    """Learning rate eta is the same as every sigma widened by 1/sqrt(eta): the tempered
    Laplace evidence must equal the closed form with residuals and Jacobian scaled by
    sqrt(eta) (the data part of the cost scaled, the prior terms not)."""
    rng = np.random.default_rng(4)
    jac = rng.standard_normal((40, 3))
    prec = np.array([4.0, 1.0, 25.0])
    r = jac @ rng.standard_normal(3) + 2.0 * rng.standard_normal(40)  # noise twice the stated sigma
    eta = 0.25
    js, rs = math.sqrt(eta) * jac, math.sqrt(eta) * r
    theta = np.linalg.solve(js.T @ js + np.diag(prec), js.T @ rs)
    # the objective at the tempered optimum, split into its data loss (unscaled) and prior terms
    loss = float((r - jac @ theta) @ (r - jac @ theta))
    cost = loss + float(theta @ (prec * theta))
    lz = selection.log_evidence(cost, jac, prec, eta, loss)
    cov = np.eye(40) + js @ np.diag(1 / prec) @ js.T
    exact = -0.5 * rs @ np.linalg.solve(cov, rs) - 0.5 * np.linalg.slogdet(cov)[1]
    assert lz == pytest.approx(exact, abs=1e-9)
    assert np.allclose(selection.posterior_covariance(jac, prec, eta), np.linalg.inv(js.T @ js + np.diag(prec)))
    # the diagnosis fits the untempered objective: from that fit (its parameters' offset from
    # the prior centres, 0 here) the Newton step of log_evidence must land on the same value;
    # without it the evidence is too low, the more so the farther the fit is from its prior
    theta1 = np.linalg.solve(jac.T @ jac + np.diag(prec), jac.T @ r)
    loss1 = float((r - jac @ theta1) @ (r - jac @ theta1))
    cost1 = loss1 + float(theta1 @ (prec * theta1))
    assert selection.log_evidence(cost1, jac, prec, eta, loss1, offset=theta1) == pytest.approx(exact, abs=1e-9)
    assert selection.log_evidence(cost1, jac, prec, eta, loss1) < exact - 0.1


def test_the_learning_rate_reads_the_best_models_misfit():
    """eta = dof / loss when the best model's reduced chi^2 exceeds 1, else 1: a fit at the
    noise level is not tempered, one at reduced chi^2 4 widens every sigma by 2."""
    assert selection.learning_rate(90.0, 100, 8) == 1.0  # 92 degrees of freedom
    assert selection.learning_rate(4.0 * 92, 100, 8) == pytest.approx(0.25)
    assert selection.learning_rate(math.inf, 100, 8) == 1.0  # nothing fitted: nothing to read


def test_the_diagnosis_reads_the_learning_rate_off_its_best_model_that_ran():
    """The best model is the one with the smallest loss per degree of freedom among those
    whose held-out run worked; its parameters are the six factors, gain, delay and its own
    columns (8 training points x 8 orders x 2 = 128 real residuals)."""
    from dampersim.discrepancy.diagnose import _learning_rate

    class FakeNamer:
        @staticmethod
        def data_loss(y, nuisance):
            return y

    ran = np.zeros(1)
    models = {"none": {"y": 300.0, "nuisance": None, "columns": [], "yh": ran},
              "a": {"y": 150.0, "nuisance": None, "columns": [0, 0], "yh": ran},
              "b": {"y": 100.0, "nuisance": None, "columns": [0], "yh": None}}  # failed: no match
    assert _learning_rate(FakeNamer, models, list(range(8))) == pytest.approx((128 - 10) / 150.0)
    models["a"]["y"] = 100.0  # at the noise: nothing to temper
    assert _learning_rate(FakeNamer, models, list(range(8))) == 1.0


def test_linear_screen_prefers_none_without_signal_and_the_effect_with_it():
    rng = np.random.default_rng(3)
    jac = rng.standard_normal((64, 6))
    d = rng.standard_normal(64) * 0.8  # an effect's signature at its typical magnitude
    noise = rng.standard_normal(64)
    x0 = np.zeros(6)
    z0 = selection.linear_screen_evidence(noise, jac, None, x0, 0.2)[0]
    z1 = selection.linear_screen_evidence(noise, jac, d, x0, 0.2)[0]
    assert z1 < z0  # Occam: an unneeded magnitude costs evidence
    r = noise + 3.0 * d
    z0 = selection.linear_screen_evidence(r, jac, None, x0, 0.2)[0]
    z1, s, _, _ = selection.linear_screen_evidence(r, jac, d, x0, 0.2)
    assert z1 > z0 + 10 and s == pytest.approx(3.0, rel=0.15)


def test_posterior_sums_to_one_and_follows_priors():
    pri = selection.model_priors(["a", "b"], ["a+b"])
    assert sum(pri.values()) == pytest.approx(1.0)
    assert pri["none"] == pytest.approx(0.5)
    post = selection.posterior({"none": 0.0, "a": 0.0, "b": -math.inf, "a+b": 0.0}, pri)
    assert sum(post.values()) == pytest.approx(1.0) and post["b"] == 0.0
    # equal evidence: the prior, renormalised over the models whose runs did not fail
    assert post["none"] == pytest.approx(pri["none"] / (1.0 - pri["b"]))


def test_threshold_magnitude_interpolates_and_extrapolates_honestly():
    grows = selection.threshold_magnitude([1.0, 2.0, 4.0], [1.0, 4.0, 16.0], 9.0, True)
    assert grows == pytest.approx(3.0, rel=1e-9)  # gain ~ m^2 -> 9 at m = 3
    assert selection.threshold_magnitude([1.0, 2.0, 4.0], [10.0, 40.0, 160.0], 2.5, True) == pytest.approx(0.5)
    assert selection.threshold_magnitude([1.0, 2.0, 4.0], [0.1, 0.2, 0.4], 9.0, True) is None
    # an upper threshold (clutch capacity): smaller values are the stronger effect
    upper = selection.threshold_magnitude([620.0, 540.0, 470.0], [1.0, 9.0, 50.0], 9.0, False)
    assert upper == pytest.approx(540.0)


def test_interval90_covers_the_normal_quantiles():
    lo, hi = selection.interval90(math.log(2.0), 0.1)
    assert lo == pytest.approx(2.0 * math.exp(-0.1 * 1.6448536), rel=1e-7)
    assert hi == pytest.approx(2.0 * math.exp(0.1 * 1.6448536), rel=1e-7)


def test_delay_prior_keeps_an_unidentifiable_delay_at_zero():
    """With a model that has no phase information (all orders at zero amplitude) the delay
    stays at its prior mean instead of wandering."""
    speed, model, noise, sigma = _campaign(seed=4)
    lik = Likelihood(noise, sigma, speed, ORDERS)
    nu = lik.fit_nuisance(np.zeros_like(model), list(range(len(model))))
    assert abs(nu[1]) < 1e-3 * DELAY_PRIOR_SD


def test_a_model_that_predicts_the_held_out_points_worse_than_none_is_penalised():
    """eta/2 times its extra held-out chi^2 against "none"; a better prediction earns nothing
    (an effect imitating the model's own error would improve held-out points too), and a
    model whose held-out run failed gets no entry (it has no evidence at all)."""
    speed, model, noise, sigma = _campaign(seed=4)
    lik = Likelihood(model + noise, sigma, speed, ORDERS)
    held = [1, 4, 7, 10]
    over = model.copy()
    over[held] += 0.2  # 4 sigma at every held-out order: what an over-fitted pair predicts
    better = model + noise  # predicts the held-out noise exactly
    nu = np.zeros(2)
    models = {"none": {"yh": model[held], "nuisance": nu}, "overfit": {"yh": over[held], "nuisance": nu},
              "better": {"yh": better[held], "nuisance": nu}, "crashed": {"yh": None, "nuisance": nu}}
    eta = 0.5
    pen = selection.held_out_penalty(lik, models, held, eta)
    assert set(pen) == {"overfit", "better"}
    assert pen["better"] == 0.0
    n = 2 * len(held) * len(ORDERS)
    extra = lik.robust_reduced_chi2(over[held], held, nu) - lik.robust_reduced_chi2(model[held], held, nu)
    assert extra > 10.0  # the 4 sigma offset, squared, less the noise's own chi^2
    assert pen["overfit"] == pytest.approx(-0.5 * eta * n * extra)


def test_the_posterior_compares_penalised_evidences_and_never_a_failed_run():
    """What the posterior is computed from: a fitted model's Laplace evidence plus its ramps'
    log likelihood plus its held-out penalty ("none" plus an unnamed misfit's gain); an
    unfitted candidate "none"'s evidence plus its screen's; -inf for a failed held-out run or a
    candidate every fit of which failed."""
    models = {"none": {"log_z": -100.0, "yh": [1.0]},
              "a": {"log_z": -80.0, "yh": [1.0]},
              "b": {"log_z": -50.0, "yh": None},
              "a+c": {"log_z": -70.0, "yh": [1.0]}}
    z = selection.model_log_evidence(models, ["a", "b", "c", "d"], ["a+c"], {"c": 4.0, "d": 1.0},
                           {"none": -5.0, "a": -2.0, "a+c": -1.0}, {"a": -30.0, "a+c": -0.5}, ["d"])
    assert z == {"none": -105.0, "a": -112.0, "b": -math.inf, "c": -101.0, "d": -math.inf, "a+c": -71.5}
    # an unnamed smooth misfit's gain joins the evidence of "none" only; a screened candidate is
    # read against "none" without it
    z = selection.model_log_evidence(models, ["a", "b", "c", "d"], ["a+c"], {"c": 4.0, "d": 1.0},
                                     {"none": -5.0, "a": -2.0, "a+c": -1.0}, {"a": -30.0, "a+c": -0.5}, ["d"], 8.0)
    assert z == {"none": -97.0, "a": -112.0, "b": -math.inf, "c": -101.0, "d": -math.inf, "a+c": -71.5}
