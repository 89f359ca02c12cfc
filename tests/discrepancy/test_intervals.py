"""The reported 90 % intervals: the Laplace covariance's, widened by a delete-one-point
jackknife where leaving out a training point moves a parameter further
(dampersim.discrepancy.intervals; no simulation)."""

import math

import numpy as np
import pytest

from dampersim.discrepancy import intervals, selection
from dampersim.discrepancy.effects import with_effect
from dampersim.discrepancy.fitting import CALIBRATION
from dampersim.discrepancy.likelihood import Likelihood
from dampersim.parameters import default_parameters

N_POINTS, N_ORDERS = 8, 8  # the diagnosis's training points of a 12-point campaign, its orders


def test_point_groups_follow_the_likelihoods_vector_layout():
    """Each point's measured orders carry its own value, so the standardised vector shows
    which point every row belongs to."""
    n = 5
    meas = np.repeat((np.arange(n) + 1.0)[:, None], N_ORDERS, axis=1) * (1 + 1j)
    lik = Likelihood(meas, np.ones((n, N_ORDERS)), np.full(n, 200.0), np.arange(1.0, N_ORDERS + 1))
    rows = list(range(n))
    v = lik.mvec(rows)
    np.testing.assert_array_equal(np.rint(v / v.min()).astype(int) - 1, intervals.point_groups(n, N_ORDERS))


def _linear_problem(rng, n_par=3):
    jac = rng.standard_normal((2 * N_POINTS * N_ORDERS, n_par))
    prec = np.full(n_par, 1e-2)  # weak priors: the data set the parameters
    return jac, prec, intervals.point_groups(N_POINTS, N_ORDERS)


def test_each_leave_one_out_estimate_is_the_exact_minimiser_without_that_point():
    """The jackknife's downdated normal equations against least squares solved afresh without
    the point's rows (the priors as extra rows): the two routes agree to rounding."""
    rng = np.random.default_rng(1)
    jac, prec, groups = _linear_problem(rng)
    r, offset = rng.standard_normal(len(jac)), rng.standard_normal(jac.shape[1])
    est = []
    for k in range(N_POINTS):
        keep = groups != k
        a = np.vstack([jac[keep], np.diag(np.sqrt(prec))])
        b = np.concatenate([r[keep], -np.sqrt(prec) * offset])
        est.append(np.linalg.lstsq(a, b, rcond=None)[0])
    est = np.array(est)
    expected = (N_POINTS - 1) / N_POINTS * np.sum((est - est.mean(axis=0)) ** 2, axis=0)
    np.testing.assert_allclose(intervals.jackknife(r, jac, prec, offset, groups)[0], expected, rtol=1e-9)


def test_the_expected_variance_is_the_mean_over_noise_draws():
    """The closed-form expectation under r ~ N(0, I / eta) against the mean of 4000 draws'
    jackknife variances at eta = 0.5: within 6 % (the draws' mean of a variance over 7
    degrees of freedom scatters by about sqrt(2 / 7 / 4000) = 0.8 %; for the third parameter,
    which one point dominates, by about 2 %, so 6 % is about three of its standard errors).
    The prior offset's part is checked exactly: with a zero residual the jackknife's variance
    is the pulls' spread alone, which is what the offset adds to the expectation."""
    rng = np.random.default_rng(3)
    jac, _, groups = _linear_problem(rng)
    jac[groups == 0, 2] *= 6.0  # one point dominates the third parameter: leverage
    prec = np.array([1e-2, 1.0, 1e-2])  # a prior that pulls the second parameter
    offset = np.array([0.3, -1.0, 0.5])
    eta = 0.5
    draws = [intervals.jackknife(rng.standard_normal(len(jac)) / math.sqrt(eta), jac, prec, offset, groups, eta)
             for _ in range(4000)]
    expected = draws[0][1]
    np.testing.assert_allclose(np.mean([d[0] for d in draws], axis=0), expected, rtol=0.06)
    assert all(np.array_equal(d[1], expected) for d in draws)  # it does not depend on the residual
    zero = np.zeros(len(jac))
    pulls, with_offset = intervals.jackknife(zero, jac, prec, offset, groups, eta)
    without = intervals.jackknife(zero, jac, prec, 0.0 * offset, groups, eta)[1]
    assert np.all(pulls > 0)
    np.testing.assert_allclose(pulls, with_offset - without, rtol=1e-9)


def test_fewer_than_two_points_leave_nothing_to_leave_out_and_a_failed_input_gives_no_jackknife():
    jac = np.ones((4, 2))
    assert np.all(np.concatenate(intervals.jackknife(np.ones(4), jac, np.ones(2), np.zeros(2), np.zeros(4))) == 0.0)
    r = np.array([1.0, np.nan, 0.0, 0.0])
    assert np.all(np.isnan(np.concatenate(intervals.jackknife(r, jac, np.ones(2), np.zeros(2), [0, 0, 1, 1]))))


def _coverage(point_sd: float, informed_by: int | None = None, trials: int = 400, seed: int = 7) -> dict:
    """For the first parameter of a linear model with unit noise plus, per point, a
    systematic pull along a random parameter direction of spread ``point_sd`` (a misfit the
    model cannot express, different at each point): the share of trials whose interval holds
    the truth (0) with the Laplace variance alone ("laplace"), the reported one, the larger
    of it and the jackknife's ("reported"), and the Laplace variance plus the jackknife's
    excess over its noise-alone expectation ("excess", the alternative not taken); and the
    mean ratios of the jackknife's variance to the Laplace one ("raw") and to its
    expectation ("to_expected"). With ``informed_by`` only that many points inform the
    parameter (the others' rows carry 5 % of their sensitivity to it)."""
    rng = np.random.default_rng(seed)
    jac, prec, groups = _linear_problem(rng)
    if informed_by is not None:
        jac[groups >= informed_by, 0] *= 0.05
    cov = selection.posterior_covariance(jac, prec)
    held = {"laplace": 0, "reported": 0, "excess": 0}
    raw, to_expected = [], []
    for _ in range(trials):
        pull = jac @ (point_sd * rng.standard_normal((N_POINTS, jac.shape[1]))).T  # rows x points
        r = rng.standard_normal(len(jac)) + pull[np.arange(len(jac)), groups]
        est = cov @ (jac.T @ r)  # the fit; prior centre at the truth, 0
        var, expected = intervals.jackknife(r - jac @ est, jac, prec, est, groups)
        lap = cov[0, 0]
        excess = lap + max(0.0, var[0] - expected[0])
        for key, v in (("laplace", lap), ("reported", max(lap, var[0])), ("excess", excess)):
            held[key] += abs(est[0]) <= selection.Z90 * math.sqrt(v)
        raw.append(var[0] / lap)
        to_expected.append(var[0] / expected[0])
    return {**{k: v / trials for k, v in held.items()}, "raw": float(np.mean(raw)),
            "to_expected": float(np.mean(to_expected))}


def test_with_noise_alone_the_interval_stays_near_the_laplace_one():
    """Noise as stated, every point informing the parameter: the jackknife's variance averages
    near the Laplace one (0.8 to 1.25: with 8 points each trial's jackknife variance scatters
    like chi^2 on about 7 degrees of freedom, 400 trials average that to a few %), and the
    reported interval, widened in the trials whose jackknife happens to exceed the Laplace
    variance, holds the truth in at most 96 % (0.94 at this seed; 400 trials: one binomial
    standard deviation is 1.5 %)."""
    c = _coverage(0.0)
    assert 0.8 <= c["raw"] <= 1.25, c
    assert c["laplace"] >= 0.86 and c["reported"] <= 0.96, c
    # the figures docs/discrepancy.md (Intervals) quotes, at this seed: 92 % and 94 %
    # (0.0125: five of the 400 trials either way)
    assert (c["laplace"], c["reported"]) == pytest.approx((0.9175, 0.9375), abs=0.0125)


def test_a_misfit_that_differs_between_points_widens_the_interval_to_cover_it():
    """Per-point pulls that give the estimate four times the variance the noise gives it
    (spread 0.5 per parameter, averaged over 8 points against the noise's 1/128): the Laplace
    interval holds the truth in about half the trials (0.50 at this seed), the reported one in
    at least 80 % (0.84; not 90 %: with 8 points the jackknife's variance is itself uncertain,
    a Student t on about 7 degrees of freedom gives 86 % at the normal quantile)."""
    c = _coverage(0.5)
    assert c["laplace"] < 0.6, c
    assert c["reported"] >= 0.8, c
    assert (c["laplace"], c["reported"]) == pytest.approx((0.4975, 0.8425), abs=0.0125)  # the docs' 50 % and 84 %
    assert c["raw"] > 3.0, c  # about 5 expected: (1/128 + 0.25/8) / (1/128)


def test_a_parameter_one_point_informs_is_widened_and_the_expectation_says_why():
    """Only one of 8 points informs the parameter. With noise alone the jackknife is several
    times the Laplace variance (leaving that point out leaves the parameter to the prior) and
    the reported interval over-covers (0.975 at this seed, at least 95 % asserted); the
    jackknife's noise-alone expectation accounts for that (their ratio averages 0.8 to 1.25,
    as for noise with evenly informed points), so the diagnosis's interval_spread_noise shows
    the leverage. With per-point misfit as above the reported interval still holds the truth
    in at least 85 % (0.93), where the Laplace variance plus the jackknife's excess over its
    expectation holds it in under 75 % (0.70): why the plain jackknife is kept."""
    alone = _coverage(0.0, informed_by=1)
    assert alone["raw"] > 5.0 and alone["reported"] >= 0.95, alone
    assert 0.8 <= alone["to_expected"] <= 1.25, alone
    pulled = _coverage(0.5, informed_by=1)
    assert pulled["reported"] >= 0.85 and pulled["excess"] < 0.75, pulled
    # the docs' 97.5 %, 93 % and 70 %
    figures = (alone["reported"], pulled["reported"], pulled["excess"])
    assert figures == pytest.approx((0.975, 0.9275, 0.695), abs=0.0125)


def _fit(cov_diag, **extra):
    system = with_effect(default_parameters(), "pendulum_absorber", {"inertia": 0.002, "order": 2.0, "damping": 0.02})
    fit = {"effects": ["pendulum_absorber"], "m": 0.002, "cov": np.diag(cov_diag), "system": system,
           "shape_start": {"order": 2.0, "damping": 0.02}, "shapes": {}}
    fit.update(extra)
    return fit


def _log_half_width(entry, par):
    low, high = entry["intervals"][par]
    return math.log(high / low) / (2 * selection.Z90)


def test_each_interval_takes_the_larger_variance_and_a_ramp_sized_magnitude_keeps_its_own():
    n_cal = len(CALIBRATION)
    lap = np.r_[np.full(n_cal, 0.01), 0.0004, 0.0001, 0.04, 0.01, 0.01]  # factors, inertia, order, damping, channels
    jack = np.r_[np.full(n_cal, 0.02), 0.0016, 0.00001, 0.09, 0.0, 0.0]
    (entry,) = intervals.effects_of("pendulum_absorber", _fit(lap), jack)
    assert _log_half_width(entry, "inertia") == pytest.approx(0.04)  # the jackknife's 0.0016
    assert _log_half_width(entry, "order") == pytest.approx(0.01)  # the Laplace 0.0001
    assert _log_half_width(entry, "damping") == pytest.approx(0.3)  # the jackknife's 0.09
    (alone,) = intervals.effects_of("pendulum_absorber", _fit(lap))
    assert _log_half_width(alone, "inertia") == pytest.approx(0.02)
    (ramps,) = intervals.effects_of("pendulum_absorber", _fit(lap, sized_by_ramps=True), jack)
    assert _log_half_width(ramps, "inertia") == pytest.approx(0.02)  # the ramps' variance, not the points'
    assert _log_half_width(ramps, "damping") == pytest.approx(0.3)
    nan = np.full(len(lap), np.nan)  # no jackknife: the Laplace intervals, and no ratio
    assert intervals.effects_of("pendulum_absorber", _fit(lap), nan) == [alone]
    assert intervals.spread(_fit(lap), nan) == {"pendulum_absorber": dict.fromkeys(["inertia", "order", "damping"])}
    spread = intervals.spread(_fit(lap), jack)
    assert spread == {"pendulum_absorber": pytest.approx({"inertia": 2.0, "order": math.sqrt(0.1), "damping": 1.5})}
    assert set(intervals.spread(_fit(lap, sized_by_ramps=True), jack)["pendulum_absorber"]) == {"order", "damping"}
    assert intervals.spread(_fit(lap), None) == {}


def test_a_pairs_magnitudes_read_their_own_columns():
    """A pair carries its two magnitudes after the calibration factors and no shape columns:
    each magnitude's interval reads its own variance, the larger of the two sources."""
    n_cal = len(CALIBRATION)
    system = with_effect(with_effect(default_parameters(), "turbine_drag", {"coefficient": 3.0}),
                         "pendulum_absorber", {"inertia": 0.002})
    lap = np.r_[np.full(n_cal, 0.01), 0.0004, 0.0009, 0.01, 0.01]  # factors, drag, inertia, channels
    jack = np.r_[np.full(n_cal, 0.0), 0.0016, 0.0001, 0.0, 0.0]
    fit = {"effects": ["turbine_drag", "pendulum_absorber"], "m_first": 3.0, "m": 0.002, "cov": np.diag(lap),
           "system": system}
    drag, absorber = intervals.effects_of("turbine_drag+pendulum_absorber", fit, jack)
    # the absorber's shapes are held, listed at the set's values with no interval
    assert drag["parameters"] == {"coefficient": 3.0}
    assert absorber["parameters"] == {"inertia": 0.002, "order": 2.0, "damping": 0.02}
    assert set(drag["intervals"]) == {"coefficient"} and set(absorber["intervals"]) == {"inertia"}
    assert _log_half_width(drag, "coefficient") == pytest.approx(0.04)  # the jackknife's 0.0016
    assert _log_half_width(absorber, "inertia") == pytest.approx(0.03)  # the Laplace 0.0009
    spread = intervals.spread(fit, jack)
    assert set(spread) == {"turbine_drag", "pendulum_absorber"}
    assert spread["turbine_drag"] == pytest.approx({"coefficient": 2.0})
    assert spread["pendulum_absorber"] == pytest.approx({"inertia": 1 / 3})
