"""The unnamed smooth misfit's evidence (no simulation: residuals and windups are given)."""

import dataclasses
import inspect
import math

import numpy as np
import pytest

from dampersim.discrepancy import unnamed as U
from dampersim.discrepancy.likelihood import Likelihood
from dampersim.discrepancy.ramps import SCALES, RampLikelihood
from tests.discrepancy import fake_rig as F


def _dense_gain(r0, s, basis, sds):
    """The same gain by dense Gaussian densities: log mean_sd N(r0; 0, S + sd^2 BB') / N(r0; 0, S)."""
    def logpdf(c):
        return -0.5 * float(r0 @ np.linalg.solve(c, r0)) - 0.5 * np.linalg.slogdet(c)[1]

    t = np.array([logpdf(s + sd ** 2 * basis @ basis.T) - logpdf(s) for sd in sds])
    return float(t.max() + math.log(np.mean(np.exp(t - t.max()))))


@pytest.mark.parametrize("size", [0.0, 1.0, 30.0])
def test_the_torsional_gain_is_the_linear_gaussian_evidence_ratio(size):
    """Woodbury and the determinant lemma against dense covariances: S = I / eta + J P^-1 J'
    with the residual taken back to the prior centre (r_fit + J offset). Agreement to 1e-8
    relative: both are exact, the difference is rounding in 60 x 60 solves."""
    rng = np.random.default_rng(1)
    n, p, k, eta = 60, 5, 8, 0.6
    jac, prec = rng.normal(size=(n, p)), rng.uniform(0.5, 3.0, p)
    offset, basis = 0.3 * rng.normal(size=p), 2.0 * rng.normal(size=(n, k))
    r_fit = rng.normal(size=n) / math.sqrt(eta) + basis @ rng.normal(size=k) * 0.03 * size
    s = np.eye(n) / eta + jac @ np.diag(1.0 / prec) @ jac.T
    want = _dense_gain(r_fit + jac @ offset, s, basis, U.TORSION_SDS)
    assert U.torsion_gain(r_fit, jac, prec, offset, eta, basis) == pytest.approx(want, rel=1e-8, abs=1e-9)


def test_a_white_residual_pays_little_and_a_smooth_misfit_gains():
    """With no misfit the gain lies between -log(len(grid)) (the bound: the grid's sd = 0
    term is 0) and 0.5 (white noise rarely looks smooth); a relative amplitude error growing
    with frequency by 5 % across the band, 20 times the noise, is worth many nats."""
    orders = np.arange(1.0, 9.0)
    speed = np.radians(6.0) * np.array([1000.0, 1300.0, 1600.0, 1900.0, 2200.0, 2500.0])
    y = (50.0 / orders)[None, :] * np.exp(1j * 0.1 * orders)[None, :] * np.ones((len(speed), 1))
    sigma = np.abs(y) * 0.0025  # 0.25 % per cell
    rows = list(range(len(speed)))
    rng = np.random.default_rng(3)
    noise = sigma / math.sqrt(2.0) * (rng.normal(size=y.shape) + 1j * rng.normal(size=y.shape))
    f = np.log(np.outer(speed, orders))
    tilt = 1.0 + 0.05 * (f - f.min()) / np.ptp(f)
    zero = np.zeros(2)
    for meas, lo, hi in [(y + noise, -math.log(len(U.TORSION_SDS)), 0.5), (y * tilt + noise, 50.0, math.inf)]:
        lik = Likelihood(meas, sigma, speed, orders)
        basis = U.torsion_basis(lik, y, rows, zero)
        r = lik.mvec(rows) - lik.vec(y, rows)
        jac = np.zeros((len(r), 1))  # one parameter that does not act: S = I
        gain = U.torsion_gain(r, jac, np.ones(1), np.zeros(1), 1.0, basis)
        assert lo <= gain <= hi


def _ramp_gain(lik, windups, jac, cov):
    """The ramps' gain as the diagnosis reads it: ramp_gain_of of ramp_inputs."""
    return U.ramp_gain_of(U.ramp_inputs(lik, windups, jac, cov), SCALES)


def _ramp_dense(lik, model, jac, cov):
    """The ramps' gain by brute force with scipy's Gaussian density: for each sd the best
    scale's log likelihood, tempered by the effective share inside the mean over the sds."""
    from scipy.stats import multivariate_normal

    r = lik.residual(model)
    j, c, sig2 = lik.parts(jac, cov)
    basis = U.ramp_basis(lik)
    best = [max(multivariate_normal(np.zeros(len(r)), np.diag(sig2 * scale ** 2) + j @ c @ j.T
                                    + sd ** 2 * basis @ basis.T).logpdf(r) for scale in SCALES)
            for sd in np.radians(U.RAMP_SDS_DEG)]
    t = lik.fraction * (np.array(best) - best[0])
    return float(t.max() + math.log(np.mean(np.exp(t - t.max()))))


def _long_ramp(pid, seconds=30.0):
    """A 0 -> 300 -> 0 N m ramp of ``seconds`` (60 compared samples at 30 s)."""
    t = np.arange(int(seconds * 1000.0) + 1) / 1000.0
    tq = 300.0 * np.minimum(t, seconds - t) / (seconds / 2.0)
    return dataclasses.replace(F.ramp(pid), time=t, input_torque=tq, output_torque=tq,
                               input_speed_rpm=np.full(t.size, 1500.0), output_speed_rpm=np.full(t.size, 1500.0),
                               windup=tq / 3000.0)


def test_the_ramp_gain_sees_a_loop_width_error_and_not_noise():
    """A loading/unloading width error of 0.3 deg (half the difference between the branches)
    on a 30 s 0 -> 300 -> 0 N m ramp is what the basis's s P_0 term expresses: a large gain
    (the fitted uncertainty scale alone takes only part of it); the same ramp with noise only
    gains at most a little. The gain equals a brute-force sum."""
    rng = np.random.default_rng(0)
    p = _long_ramp("r0")
    model = {p.id: p.windup}
    width = np.where(np.gradient(p.input_torque) > 0, -1.0, 1.0) * math.radians(0.3)
    noise = rng.normal(0.0, math.radians(0.05), p.windup.size)
    cov = np.eye(1)
    gains = []
    for extra in (np.zeros_like(width), width):
        meas = dataclasses.replace(p, windup=p.windup + extra + noise)
        lik = RampLikelihood([meas], model, model)
        j = np.zeros((lik.residuals, 1))
        g = _ramp_gain(lik, model, j, cov)
        # two routes to the same Gaussian densities: agreement to 1e-7 relative (rounding)
        assert g == pytest.approx(_ramp_dense(lik, model, j, cov), rel=1e-7, abs=1e-7)
        gains.append(g)
        lik.fraction = 0.3  # the ramps' effective share tempers every spread's likelihood
        assert _ramp_gain(lik, model, j, cov) == pytest.approx(_ramp_dense(lik, model, j, cov), rel=1e-7, abs=1e-7)
    assert -math.log(len(U.RAMP_SDS_DEG)) - 1e-9 <= gains[0] < 1.0  # the bound, reached when no spread helps
    assert gains[1] > 5.0


def test_a_failed_ramp_run_gains_nothing():
    p = F.ramp("r0")
    lik = RampLikelihood([p], {p.id: p.windup}, {p.id: p.windup})
    assert _ramp_gain(lik, {p.id: "SimulationDiverged"}, np.zeros((lik.residuals, 1)), np.eye(1)) == 0.0


def test_the_detectability_counts_what_a_smooth_misfit_would_take_of_a_signature():
    """signature_share: a signature smooth in frequency (a 2 % amplitude tilt) is taken up by
    the unnamed misfit nearly as well as by the effect, so its share is most of its chi^2
    (at least 70 %: the misfit's Occam factor over 8 coefficients costs a few nats); a
    signature the basis cannot follow (one order at one point) keeps most of its chi^2 (share
    below 20 % of it)."""
    orders = np.arange(1.0, 9.0)
    speed = np.radians(6.0) * np.array([1000.0, 1300.0, 1600.0, 1900.0, 2200.0, 2500.0])
    y = (50.0 / orders)[None, :] * np.exp(1j * 0.1 * orders)[None, :] * np.ones((len(speed), 1))
    sigma = np.abs(y) * 0.0025
    rows = list(range(len(speed)))
    lik = Likelihood(y, sigma, speed, orders)
    basis = U.torsion_basis(lik, y, rows, np.zeros(2))
    f = np.log(np.outer(speed, orders))
    smooth = lik.vec(y * 0.02 * (f - f.min()) / np.ptp(f), rows)
    spike = np.zeros_like(smooth)
    spike[3 * len(orders) + 2] = 12.0  # 12 sigma in one real residual
    jac = np.zeros((len(smooth), 1))
    s_eye = np.eye(len(smooth))  # S with a parameter that does not act
    for d, lo, hi in [(smooth, 0.7, 1.0), (spike, 0.0, 0.2)]:
        chi2 = float(d @ d)
        assert chi2 > 100.0
        share = U.signature_share(d, jac, np.ones(1), 1.0, basis)
        assert lo * chi2 <= share <= hi * chi2
        # the same from dense densities (rounding: 1e-8 relative)
        dense = 2.0 * (U.combined(_dense_gain(d, s_eye, basis, U.TORSION_SDS), 0.0)
                       - U.combined(_dense_gain(0.0 * d, s_eye, basis, U.TORSION_SDS), 0.0))
        assert share == pytest.approx(dense, rel=1e-8, abs=1e-8)


def test_none_pays_little_for_the_option_and_gains_a_large_misfit_less_its_prior():
    """combined: a misfit that explains nothing (gains of at most 0) costs "none" at most
    log(1 - q) plus a little; a large one is worth its gain plus log q."""
    q = U.MISFIT_PRIOR
    assert U.combined(0.0, 0.0) == pytest.approx(0.0)
    assert math.log(1.0 - q) < U.combined(-math.log(4.0), -math.log(5.0)) < 0.0
    assert U.combined(-1e3, 0.0) == pytest.approx(math.log(1.0 - q))
    assert U.combined(30.0, 10.0) == pytest.approx(40.0 + math.log(q), abs=1e-12)


def test_the_ramp_direction_holds_its_branch_through_holds_and_noise():
    """full-450-like ramp sampled every 0.5 s: 0 -> 450 N m at 50 N m/s, a 2 s hold, down to
    -450, a hold, back to 0, with 1 N m of noise on the sampled torque. The direction is the
    branch the torque is on, including on the holds (which stay on the branch they reached) and
    at the first sample (which takes the first move's)."""
    t = np.arange(0.0, 50.0, 0.5)
    tq = np.interp(t, [0.0, 9.0, 11.0, 29.0, 31.0, 40.0, 50.0], [0.0, 450.0, 450.0, -450.0, -450.0, 0.0, 0.0])
    want = np.where(t <= 11.0, 1.0, np.where(t <= 31.0, -1.0, 1.0))
    noisy = tq + np.random.default_rng(5).normal(0.0, 1.0, t.size)
    for v in (tq, noisy):
        assert np.array_equal(U.ramp_direction(v), want)
    assert np.array_equal(U.ramp_direction(np.zeros(5)), np.ones(5))  # never moves: +1, no division by 0


def test_a_ramp_without_a_proper_covariance_gains_nothing(monkeypatch):
    """No sample variance and no parameter spread: S is singular at every scale without the
    misfit, so its log likelihood is -inf there and the gain would be nan; it reads 0."""
    p = _long_ramp("r0")
    lik = RampLikelihood([p], {p.id: p.windup}, {p.id: p.windup})
    n = lik.residuals
    monkeypatch.setattr(lik, "parts", lambda jac, cov: (np.zeros((n, 1)), np.zeros((1, 1)), np.zeros(n)))
    assert _ramp_gain(lik, {p.id: p.windup}, np.zeros((n, 1)), np.eye(1)) == 0.0


def test_the_ramp_signature_gain_is_the_fixed_scale_evidence_ratio():
    """ramp_signature_gain against scipy's Gaussian densities at the fixed scale, tempered by the
    effective share (both exact: 1e-7 relative is rounding); none's signature (zeros) gains
    at most 0, a loop-width signature much more."""
    from scipy.stats import multivariate_normal

    p = _long_ramp("r0")
    model = {p.id: p.windup}
    lik = RampLikelihood([p], model, model)
    lik.fraction = 0.4
    inputs = U.ramp_inputs(lik, model, np.zeros((lik.residuals, 1)), np.eye(1))
    width = np.where(np.gradient(p.input_torque) > 0, -1.0, 1.0)[lik.idx[p.id]] * math.radians(0.3)
    scale = 2.0
    j, c, sig2, basis = (inputs[k] for k in ("sensitivity", "covariance", "sample_variance", "basis"))
    gains = []
    for d in (np.zeros_like(width), width):
        t = np.array([multivariate_normal(np.zeros(len(d)), np.diag(sig2 * scale ** 2) + j @ c @ j.T
                                          + sd ** 2 * basis @ basis.T).logpdf(d) for sd in np.radians(U.RAMP_SDS_DEG)])
        t = lik.fraction * (t - t[0])
        want = float(t.max() + math.log(np.mean(np.exp(t - t.max()))))
        got = U.ramp_signature_gain(inputs, d, scale)
        assert got == pytest.approx(want, rel=1e-7, abs=1e-7)
        gains.append(got)
    assert gains[0] <= 0.0 < 5.0 < gains[1]
    assert U.ramp_signature_gain(None, width, scale) == 0.0  # no ramp samples: no misfit term


def test_the_detectability_share_counts_the_ramps_with_the_torsional_points():
    """signature_share with the ramps' D at the signature and at none: a ramp signature the
    basis follows adds most of its own evidence to the share; (0, 0), the default, is the
    torsional points alone; the share is the joint one, not a sum of two (combined is not
    additive)."""
    rng = np.random.default_rng(4)
    n = 40
    jac, basis = rng.normal(size=(n, 2)), rng.normal(size=(n, 8))
    d = 0.01 * rng.normal(size=n)  # a torsional signature too small to matter
    prec = np.ones(2)
    alone = U.signature_share(d, jac, prec, 1.0, basis)
    assert U.signature_share(d, jac, prec, 1.0, basis, (0.0, 0.0)) == alone
    with_ramps = U.signature_share(d, jac, prec, 1.0, basis, (20.0, -1.0))
    zero = np.zeros(2)
    t_d, t_0 = (U.torsion_gain(v, jac, prec, zero, 1.0, basis) for v in (d, 0 * d))
    assert with_ramps == 2.0 * (U.combined(t_d, 20.0) - U.combined(t_0, -1.0))  # the same arithmetic: exact
    # the ramps' D of 20 nats over -1 at none: about 2 x (20 + log q - log(1 - q)) = 37 of chi^2,
    # where the torsional signature alone gives "none" next to nothing
    assert with_ramps > 30.0 and abs(alone) < 1.0
    split = alone + 2.0 * (U.combined(0.0, 20.0) - U.combined(0.0, -1.0))
    assert abs(with_ramps - split) > 0.1  # joint, not the sum of two separate shares


def test_a_diagnosis_with_a_ramp_keeps_the_misfit_inputs_and_reads_the_ramps_in_the_detectability(monkeypatch):
    """The stand-in rig with one ramp (tests/discrepancy/fake_rig.py: a slipping clutch opens a
    loop there; turbine drag does not show in ramps): the kept ramp inputs give back the
    reported ramp gain, and the detectability's share reads the ramps' misfit at the clutch's
    ramp signature (a gain above that at none: the loop is what the basis's direction term
    expresses) and at none on both sides for turbine drag, which the ramps are not read for
    (its share is then the torsional one beside the ramps' D at none)."""
    from dampersim.discrepancy import drive
    from dampersim.discrepancy.diagnose import diagnose
    from dampersim.discrepancy.naming import Namer

    monkeypatch.setattr(drive, "simulate_point", F.fake_model(None))
    seen, now = {}, []
    real_share, real_detect = U.signature_share, Namer.detectability

    def share(d, jac, prec, eta, basis, ramps=(0.0, 0.0)):
        seen.setdefault(now[-1], []).append(tuple(ramps))
        return real_share(d, jac, prec, eta, basis, ramps)

    def detect(self, name, *args, **kw):
        now.append(name)
        return real_detect(self, name, *args, **kw)

    monkeypatch.setattr(U, "signature_share", share)
    monkeypatch.setattr(Namer, "detectability", detect)
    camp = F.campaign([F.point(*p) for p in F.POINTS] + [F.ramp("r0")])
    d = diagnose(camp, workers=1, candidates=["clutch_slip", "turbine_drag"], recommend=False)
    kept = d.misfit_inputs["ramps"]
    assert kept is not None and U.ramp_gain_of(kept, SCALES) == d.likelihood["unnamed_misfit"]["ramps"]
    # the kept parts hold exactly the arrays INPUT_KEYS names (what the replay reads back)
    assert set(kept) == set(U.INPUT_KEYS["ramps"]) and set(d.misfit_inputs["torsion"]) == set(U.INPUT_KEYS["torsion"])
    assert set(inspect.signature(U.torsion_gain).parameters) - {"sds"} == set(U.INPUT_KEYS["torsion"])
    assert set(seen) == {"clutch_slip", "turbine_drag"}
    at_none = {r[1] for rs in seen.values() for r in rs}
    assert len(at_none) == 1 and at_none.pop() < 0.0  # one D at none, below 0: the misfit has nothing to follow
    assert all(at > none for at, none in seen["clutch_slip"])
    assert all(at == none for at, none in seen["turbine_drag"])
