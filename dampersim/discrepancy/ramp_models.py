"""The ramps in each fitted model's evidence: the windups a model fitted on the torsional
points predicts, their log likelihood given that fit, and the sizing by the ramps of the
most probable effect.

The ramps' likelihood itself (sample uncertainties, angle offsets, effective share) is
:mod:`dampersim.discrepancy.ramps`; this module runs the models through it.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import drive, fitting, naming, unnamed
from dampersim.discrepancy import ramps as ramps_lik
from dampersim.discrepancy.effects import info, with_effect
from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system

#: half width of the search in log magnitude when the ramps size an effect (a factor 4.5 either
#: way of the torsional fit), and the smallest move worth re-running the torsional points (5 %)
RAMP_SEARCH = 1.5
RAMP_UPDATE_MIN = 0.05


def magnitude(system, name) -> float:
    """The magnitude parameter's value of effect ``name`` in ``system`` (in its unit)."""
    return float(getattr(getattr(system.effects, name), info(name).magnitude))


def evidence(runner, system, x, models, points):
    """Each model's ramp prediction: (RampLikelihood, {model: windups}, {model: log
    likelihood}, {model: chi^2}); the RampLikelihood's ``scales`` holds each model's fitted
    uncertainty scale, its ``unnamed_inputs`` what the ramps' evidence gain of an unnamed
    smooth misfit beside "none" is computed from
    (:func:`~dampersim.discrepancy.unnamed.ramp_inputs`). The ramps' sensitivities to the
    calibration factors are run once at the calibrated model (kept as the RampLikelihood's
    ``cols_x``), to each effect's magnitude once per fitted model; shape parameters are not
    carried over."""
    h = fitting.CAL_DERIVATIVE_STEPS[0]
    lik_r, runs = ramps_lik.ramp_likelihood(runner, calibrated_system(system, x), points)
    runs = {"none": runs}
    cols_x = []
    for k in range(len(x)):
        xk = x.copy()
        xk[k] += h
        cols_x.append(lik_r.column(ramps_lik.run_ramps(runner, calibrated_system(system, xk), points), runs["none"], h))
    ll, chi = {}, {}
    cov_none = models["none"]["cov"]  # the same kind of covariance as the effect models'
    pad = [np.zeros(lik_r.residuals)] * (cov_none.shape[0] - len(cols_x))  # the channels: not on the ramps
    jac_none = np.column_stack([*cols_x, *pad])
    ll["none"], chi["none"], _, _ = lik_r.predictive(runs["none"], jac_none, cov_none)
    scales, whitened = {"none": lik_r.scale}, {"none": lik_r.whitened}
    for label, fit in models.items():
        if label == "none":
            continue
        runs[label] = ramps_lik.run_ramps(runner, fit["system"], points)
        cols = list(cols_x)
        for name in fit["effects"]:
            m_fd, step = fitting.fd_magnitude(name, magnitude(fit["system"], name))
            moved = with_effect(fit["system"], name, {info(name).magnitude: m_fd})
            cols.append(lik_r.column(ramps_lik.run_ramps(runner, moved, points), runs[label], step))
        cols += [np.zeros(lik_r.residuals)] * (fit["cov"].shape[0] - len(cols))  # shapes, channels: not on the ramps
        ll[label], chi[label], _, _ = lik_r.predictive(runs[label], np.column_stack(cols), fit["cov"])
        scales[label], whitened[label] = lik_r.scale, lik_r.whitened
    # the model that explains the ramps best fixes their effective share (scaling every
    # model's log likelihood from here on) and the noise scale of detectability
    ll = lik_r.settle(ll, scales, whitened)
    lik_r.cols_x = cols_x
    # what the unnamed smooth misfit's evidence on the ramps beside "none" is computed from, at the settled share
    lik_r.unnamed_inputs = unnamed.ramp_inputs(lik_r, runs["none"], jac_none, cov_none)
    return lik_r, runs, ll, chi


def log_range(name: str, u0: float, span: float) -> tuple:
    """The log-magnitude range u0 ± span of effect ``name``, kept inside its accepted range."""
    return (math.log(naming.clip_magnitude(name, math.exp(u0 - span))),
            math.log(naming.clip_magnitude(name, math.exp(u0 + span))))


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
    lo, hi = log_range(name, u0, RAMP_SEARCH)
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
    fit["sized_by_ramps"] = True  # its interval is the ramps' (intervals.effects_of)
    return True


__all__ = ["RAMP_SEARCH", "RAMP_UPDATE_MIN", "evidence", "log_range", "magnitude", "size_by_ramps"]
