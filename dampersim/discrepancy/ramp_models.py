"""The ramps in each fitted model's evidence: the windups a model fitted on the torsional
points predicts, their log likelihood given that fit, and the sizing by the ramps of the
most probable effect.

The ramps' likelihood itself (sample uncertainties, angle offsets, effective share) is
:mod:`dampersim.discrepancy.ramps`; this module runs the models through it.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import drive, fitting, naming
from dampersim.discrepancy import ramps as ramps_lik
from dampersim.discrepancy.effects import info, with_effect
from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system

#: half width of the search in log magnitude when the ramps size an effect (a factor 4.5 either
#: way of the torsional fit), and the smallest move worth re-running the torsional points (5 %)
RAMP_SEARCH = 1.5
RAMP_UPDATE_MIN = 0.05
#: log magnitudes at which a single effect's ramps are replayed (:func:`replay_profile`)
PROFILE_POINTS = 21


def magnitude(system, name) -> float:
    """The magnitude parameter's value of effect ``name`` in ``system`` (in its unit)."""
    return float(getattr(getattr(system.effects, name), info(name).magnitude))


def evidence(runner, system, x, models, points):
    """Each model's ramp prediction: (RampLikelihood, {model: windups}, {model: log
    likelihood}, {model: chi^2}); the RampLikelihood's ``scales`` holds each model's fitted
    uncertainty scale. The ramps' sensitivities to the calibration factors are run
    once at the calibrated model (kept as the RampLikelihood's ``cols_x``).

    A single effect's ramps are replayed along its magnitude (:func:`replay_profile`) and
    its log likelihood is that profile integrated over the torsional fit's Gaussian on the
    log magnitude (:func:`integrate_profile`), the share of independent samples applied
    inside the integral. A pair's magnitudes are carried through one sensitivity each
    (linearised), run once per fitted pair. Shape parameters are not carried over.

    Why the single effects are replayed: a free play that the torsional points cannot
    see keeps a wide magnitude uncertainty, and a linearised sensitivity at the fitted
    magnitude then lets the ramps move it both ways as if the windup followed it linearly
    (smaller than none included). On control/none/7 of the hard benchmark that gave a free
    play a ramp lead of 7 nats that no replayed magnitude supports
    (docs/discrepancy.md, "The ramps' evidence replayed along the magnitude")."""
    h = fitting.CAL_DERIVATIVE_STEPS[0]
    lik_r, runs = ramps_lik.ramp_likelihood(runner, calibrated_system(system, x), points)
    runs = {"none": runs}
    cols_x = []
    for k in range(len(x)):
        xk = x.copy()
        xk[k] += h
        cols_x.append(lik_r.column(ramps_lik.run_ramps(runner, calibrated_system(system, xk), points), runs["none"], h))
    lik_r.cols_x = cols_x
    ll, chi, profiles = {}, {}, {}
    cov_none = models["none"]["cov"]  # the same kind of covariance as the effect models'
    pad = [np.zeros(lik_r.residuals)] * (cov_none.shape[0] - len(cols_x))  # the channels: not on the ramps
    ll["none"], chi["none"], _, _ = lik_r.predictive(runs["none"], np.column_stack([*cols_x, *pad]), cov_none)
    scales, whitened = {"none": lik_r.scale}, {"none": lik_r.whitened}
    n_cal = len(CALIBRATION)
    for label, fit in models.items():
        if label == "none":
            continue
        runs[label] = ramps_lik.run_ramps(runner, fit["system"], points)
        if len(fit["effects"]) == 1:
            u0, var0 = math.log(fit["m"]), max(float(fit["cov"][n_cal, n_cal]), 1e-12)
            us = magnitude_grid(fit["effects"][0], u0, var0)
            rows = replay_profile(runner, lik_r, fit, points, us)
            lls = np.array([r[0] for r in rows])
            ll[label] = integrate_profile(us, lls, u0, var0)
            k = int(np.argmax(np.where(np.isfinite(lls), lls - 0.5 * (us - u0) ** 2 / var0, -np.inf)))
            chi[label], scales[label], whitened[label] = rows[k][1], rows[k][2], rows[k][3]
            profiles[label] = (us, lls, u0, var0)
            continue
        cols = list(cols_x)
        for name in fit["effects"]:
            m_fd, step = naming.fd_magnitude(name, magnitude(fit["system"], name))
            moved = with_effect(fit["system"], name, {info(name).magnitude: m_fd})
            cols.append(lik_r.column(ramps_lik.run_ramps(runner, moved, points), runs[label], step))
        cols += [np.zeros(lik_r.residuals)] * (fit["cov"].shape[0] - len(cols))  # shapes, channels: not on the ramps
        ll[label], chi[label], _, _ = lik_r.predictive(runs[label], np.column_stack(cols), fit["cov"])
        scales[label], whitened[label] = lik_r.scale, lik_r.whitened
    # the model that explains the ramps best fixes their effective share (scaling every
    # model's log likelihood from here on) and the noise scale of detectability
    ll = lik_r.settle(ll, scales, whitened)
    for label, (us, lls, u0, var0) in profiles.items():  # the share inside the integral
        ll[label] = integrate_profile(us, lik_r.fraction * lls, u0, var0)
    return lik_r, runs, ll, chi


def magnitude_grid(name, u0: float, var0: float) -> np.ndarray:
    """PROFILE_POINTS log magnitudes of effect ``name`` spaced evenly over u0 ± max(RAMP_SEARCH,
    4 sqrt(var0)) (u0 the torsional fit's log magnitude, var0 its Laplace variance), kept
    inside the magnitude's accepted range (u0 alone when that range leaves no width)."""
    span = max(RAMP_SEARCH, 4.0 * math.sqrt(var0))
    lo = math.log(naming.clip_magnitude(name, math.exp(u0 - span)))
    hi = math.log(naming.clip_magnitude(name, math.exp(u0 + span)))
    return np.linspace(lo, hi, PROFILE_POINTS) if hi > lo else np.array([u0])


def replay_profile(runner, ramp_lik, fit, points, us) -> list:
    """The ramps replayed with the single effect of ``fit`` at each log magnitude of ``us``:
    per magnitude (log likelihood, chi^2, uncertainty scale, whitened residual) of
    :meth:`RampLikelihood.predictive` with the calibration factors' covariance of the fit
    carried through the ramps' sensitivities ``ramp_lik.cols_x`` (the magnitude is held,
    not carried; (-inf, inf, scale, None) where a run failed)."""
    name = fit["effects"][0]
    n_cal = len(CALIBRATION)
    systems = [with_effect(fit["system"], name, {info(name).magnitude: math.exp(u)}) for u in us]
    out = runner.map([(drive.diagnosis_system(s), p) for s in systems for p in points])
    cols, cov = np.column_stack(ramp_lik.cols_x), fit["cov"][:n_cal, :n_cal]
    rows = []
    for k in range(len(us)):
        w = {p.id: (o["windup"] if "windup" in o else o.get("error", "no result"))
             for p, o in zip(points, out[k * len(points):(k + 1) * len(points)])}
        ll, chi2 = ramp_lik.predictive(w, cols, cov)[:2]
        rows.append((ll, chi2, ramp_lik.scale, ramp_lik.whitened))
    return rows


def integrate_profile(us, ll, u0: float, var0: float) -> float:
    """log of the integral over log magnitude u of exp(ll(u)) times the torsional fit's
    Gaussian N(u0, var0), on the grid ``us`` (even spacing; the Gaussian renormalised to the
    grid, so a grid that holds all of its mass gives the plain integral); -inf when every
    replay failed."""
    us, ll = np.asarray(us, dtype=float), np.asarray(ll, dtype=float)
    logw = -0.5 * (us - u0) ** 2 / var0
    ok = np.isfinite(ll)
    if not ok.any():
        return -math.inf
    return float(np.logaddexp.reduce(ll[ok] + logw[ok]) - np.logaddexp.reduce(logw))


def size_by_ramps(runner, fit, pts, train, held, lik, ramp_lik, points):
    """Size the single effect of ``fit`` by the ramps: a bounded search in log magnitude
    (RAMP_SEARCH around the torsional fit) of the ramps' predictive log likelihood plus the
    torsional fit's information on the magnitude (its Laplace variance), then the torsional
    points re-run at the new magnitude. An effect that shows mainly in ramps (free play) is
    sized by them; its interval comes from the curvature of that objective. True when the
    model moved."""
    from scipy.optimize import minimize_scalar  # scipy loads only when a diagnosis runs

    if len(fit["effects"]) != 1:
        return False
    name = fit["effects"][0]
    e = info(name)
    n_cal = len(CALIBRATION)
    u0 = math.log(fit["m"])
    lo = math.log(naming.clip_magnitude(name, math.exp(u0 - RAMP_SEARCH)))
    hi = math.log(naming.clip_magnitude(name, math.exp(u0 + RAMP_SEARCH)))
    var0 = max(float(fit["cov"][n_cal, n_cal]), 1e-12)
    cov_x = fit["cov"][:n_cal, :n_cal]
    seen = {}

    def objective(u):
        if u not in seen:
            w = ramps_lik.run_ramps(runner, with_effect(fit["system"], name, {e.magnitude: math.exp(u)}), points)
            ll = ramp_lik.predictive(w, np.column_stack(ramp_lik.cols_x), cov_x)[0]
            seen[u] = -ll + 0.5 * (u - u0) ** 2 / var0
        return seen[u]

    with np.errstate(invalid="ignore", over="ignore"):
        res = minimize_scalar(objective, bounds=(lo, hi), method="bounded",
                              options={"xatol": 0.02, "maxiter": 10})
    u = float(res.x)
    if not math.isfinite(objective(u)) or abs(u - u0) < RAMP_UPDATE_MIN:
        return False
    d = 0.05
    uc = min(max(u, lo + d), hi - d)  # the curvature is read inside the range
    curv = (objective(uc + d) - 2.0 * objective(uc) + objective(uc - d)) / d ** 2 if hi - lo > 2 * d else 0.0
    moved = with_effect(fit["system"], name, {e.magnitude: math.exp(u)})
    y = drive.coefficients_of(runner, moved, pts)
    if not np.all(np.isfinite(y)):
        return False  # not adopted: the moved model fails somewhere
    fit["system"], fit["y"], fit["yh"], fit["m"] = moved, y[train], y[held], math.exp(u)
    fit["nuisance"] = lik.profile(fit["y"], train)[1]
    fit["cov"] = fit["cov"].copy()
    fit["cov"][n_cal, n_cal] = 1.0 / curv if curv > 0 else var0
    return True


__all__ = ["RAMP_SEARCH", "RAMP_UPDATE_MIN", "PROFILE_POINTS", "evidence", "magnitude", "magnitude_grid",
           "replay_profile", "integrate_profile", "size_by_ramps"]
