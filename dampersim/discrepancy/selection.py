"""Model selection by evidence: "no missing effect" against each candidate and pairs.

Every model is the calibrated damper (six log calibration factors under a Gaussian prior of
spread PRIOR_LOG_SD), the channels' nuisance (gain and delay, see
:mod:`dampersim.discrepancy.likelihood`) and, for an effect, the log of its magnitude
parameter under a Gaussian prior centred on the effect's typical value with spread
MAGNITUDE_PRIOR_SD. The evidence is the Laplace approximation around the fit:

    log Z = -(eta L + Q)/2 + g'A^-1 g/2 + log det(P)/2 - log det(A)/2,  A = eta J'J + P

(g'A^-1 g/2: the step from the untempered fit to the tempered optimum, see
:func:`log_evidence`) with L the fit's robust chi^2, Q the priors' quadratic terms, J the Jacobian of the
standardised residuals with respect to all fitted parameters, P the priors' precision and
eta the likelihood's learning rate (:func:`learning_rate`; 1 when the best model fits to
the noise, and then C = L + Q is the minimised objective). The last two terms are the Occam
factor: a parameter the data do not need costs evidence. Posterior probabilities follow
from the evidence and the model priors of MODEL_PRIOR (stated in docs/discrepancy.md); 90 %
intervals of a fitted parameter are its estimate +- 1.645 posterior standard deviations in
log space (from A^-1); the reported ones (:mod:`dampersim.discrepancy.intervals`) widen them
where leaving out a training point moves a parameter further.
"""

from __future__ import annotations

import math

import numpy as np

#: prior spread of an effect's log magnitude around its typical value (a factor e = 2.7 per
#: standard deviation: the library's weak and strong values lie within one of it)
MAGNITUDE_PRIOR_SD = 1.0
#: prior spread of a fitted shape parameter's log around its starting value
SHAPE_PRIOR_SD = 0.5
#: prior probability of the model classes: no missing effect, one effect (shared equally),
#: a pair of effects (shared equally among the pairs tried)
MODEL_PRIOR = {"none": 0.5, "single": 0.4, "pair": 0.1}
#: the normal quantile of a two-sided 90 % interval
Z90 = 1.6448536269514722
#: posterior probability a named effect must reach against "none" for detection
DETECTION_POSTERIOR = 0.9


def learning_rate(loss: float, residuals: int, parameters: int) -> float:
    """The likelihood's learning rate eta = min(1, (n - p) / loss) from the best-fitting
    model's data loss (its robust chi^2) over n real residuals with p fitted parameters.

    When even the best model leaves a reduced chi^2 above 1, the uncertainties are
    optimistic (a misfit the model cannot express: the rig, friction laws a factor does not
    reach). Raising the likelihood to the power eta (a tempered, "generalised Bayes"
    posterior) is the same as widening every sigma by 1/sqrt(eta): evidence differences
    and intervals are then read against the misfit that is really there, and a candidate
    that only absorbs part of a systematic misfit does not gain certainty from it."""
    dof = max(1, int(residuals) - int(parameters))
    if not math.isfinite(loss) or loss <= dof:
        return 1.0
    return float(dof / loss)


def log_evidence(cost: float, jac, prior_precision, eta: float = 1.0, loss: float = 0.0, offset=None) -> float:
    """Laplace log evidence of a fit (up to a constant common to all models).

    cost: minimised objective (chi^2 plus prior quadratic terms); jac: Jacobian of the
    standardised residuals w.r.t. the fitted parameters (rows x parameters); prior_precision:
    the parameters' prior precisions (1 / sd^2); eta: the likelihood's learning rate
    (:func:`learning_rate`), which scales the data part ``loss`` of the cost and J'J.

    The fit minimises the untempered objective; with eta < 1 the tempered one has its
    minimum elsewhere. offset: the fitted parameters minus their prior centres; the tempered
    objective's gradient there is 2 g with g = (1 - eta) P offset, its Hessian 2 A with
    A = eta J'J + P, and one Newton step to its minimum adds g'A^-1 g / 2 to log Z (exact
    for a linear model)."""
    if not math.isfinite(cost):
        return -math.inf
    jac = np.asarray(jac, dtype=float)
    p = np.asarray(prior_precision, dtype=float)
    a = eta * (jac.T @ jac) + np.diag(p)
    sign, logdet = np.linalg.slogdet(a)
    if sign <= 0:
        return -math.inf
    newton = 0.0
    if offset is not None and eta < 1.0:
        g = (1.0 - eta) * p * np.asarray(offset, dtype=float)
        newton = 0.5 * float(g @ np.linalg.solve(a, g))
    return float(-0.5 * (cost - (1.0 - eta) * loss) + newton + 0.5 * np.sum(np.log(p)) - 0.5 * logdet)


def posterior_covariance(jac, prior_precision, eta: float = 1.0) -> np.ndarray:
    """(eta J'J + P)^-1: the Laplace posterior covariance of the fitted parameters."""
    jac = np.asarray(jac, dtype=float)
    return np.linalg.inv(eta * (jac.T @ jac) + np.diag(np.asarray(prior_precision, dtype=float)))


def interval90(log_value: float, log_sd: float) -> list:
    """90 % interval [low, high] of a parameter estimated in log space."""
    return [math.exp(log_value - Z90 * log_sd), math.exp(log_value + Z90 * log_sd)]


def model_priors(singles, pairs) -> dict:
    """Prior probability of every model: "none", each single effect, each pair "a+b"."""
    out = {"none": MODEL_PRIOR["none"]}
    share = MODEL_PRIOR["single"] + (0.0 if pairs else MODEL_PRIOR["pair"])
    for s in singles:
        out[s] = share / len(singles)
    for p in pairs:
        out[p] = MODEL_PRIOR["pair"] / len(pairs)
    total = sum(out.values())
    return {k: v / total for k, v in out.items()}


def posterior(log_z: dict, priors: dict) -> dict:
    """Posterior probabilities {model: p} from log evidences and model priors (models with
    -inf evidence get 0); they sum to 1."""
    logs = {m: math.log(priors[m]) + z for m, z in log_z.items() if math.isfinite(z)}
    if not logs:
        return {m: (1.0 if m == "none" else 0.0) for m in log_z}
    top = max(logs.values())
    w = {m: math.exp(v - top) for m, v in logs.items()}
    s = sum(w.values())
    return {m: w.get(m, 0.0) / s for m in log_z}


def linear_screen_evidence(r_w, jac_w, d_w, x0, prior_sd, mag_sd=MAGNITUDE_PRIOR_SD, min_scale: float = 0.0):
    """Laplace evidence of the linearised joint fit r_w ~ jac_w dx + d_w s (exact for a linear
    model): calibration change dx under the prior on the total factors x0 + dx (spread
    prior_sd), effect scale s = magnitude / typical magnitude under N(1, mag_sd) (d_w None:
    calibration only). An effect cannot act backwards: when the best s is below
    ``min_scale`` the scale is held there (its prior term paid, no Occam factor for it).
    Returns (log evidence, s, dx, cost)."""
    n = jac_w.shape[1]

    def solve(cols, r, centre, prec):
        a = cols.T @ cols + np.diag(prec)
        sol = np.linalg.solve(a, cols.T @ r + prec * centre)
        res = r - cols @ sol
        cost = float(res @ res + np.sum(prec * (sol - centre) ** 2))
        logz = -0.5 * cost + 0.5 * float(np.sum(np.log(prec))) - 0.5 * np.linalg.slogdet(a)[1]
        return logz, sol, cost

    prec_x = np.full(n, 1.0 / prior_sd ** 2)
    if d_w is None:
        logz, sol, cost = solve(jac_w, r_w, -np.asarray(x0, dtype=float), prec_x)
        return logz, 0.0, sol, cost
    cols = np.column_stack([jac_w, d_w])
    prec = np.concatenate([prec_x, [1.0 / mag_sd ** 2]])
    logz, sol, cost = solve(cols, r_w, np.concatenate([-np.asarray(x0, dtype=float), [1.0]]), prec)
    if sol[n] >= min_scale:
        return logz, float(sol[n]), sol[:n], cost
    held = ((min_scale - 1.0) / mag_sd) ** 2
    logz, sol, cost = solve(jac_w, r_w - d_w * min_scale, -np.asarray(x0, dtype=float), prec_x)
    return logz - 0.5 * held, float(min_scale), sol, cost + held


def detection_chi2(prior_single: float, prior_none: float, mag_sd: float = MAGNITUDE_PRIOR_SD) -> float:
    """The chi^2 improvement an effect must bring for its posterior to reach
    DETECTION_POSTERIOR against "none" (two models): 2 ln(odds x prior ratio) plus the
    Occam penalty ln(1 + needed x mag_sd^2) of a fitted magnitude at that improvement
    (solved by fixed-point iteration; it converges in a few steps)."""
    base = 2.0 * math.log(DETECTION_POSTERIOR / (1.0 - DETECTION_POSTERIOR) * prior_none / prior_single)
    needed = base
    for _ in range(30):
        needed = base + math.log(1.0 + needed * mag_sd ** 2)
    return needed


def threshold_magnitude(mags, chi2_gain, needed: float, grows: bool, bounds=(None, None)):
    """The magnitude at which the achievable chi^2 improvement reaches ``needed``.

    mags, chi2_gain: magnitudes tried (any order) and the chi^2 improvement an effect of that
    size would bring after the calibration has absorbed what it can (projected signature,
    squared). Interpolated in log magnitude and log gain; for an effect that grows with its
    magnitude extrapolated below the smallest value tried with gain ~ m^2 (small effects are
    linear in their magnitude), never beyond ``bounds``. None when no magnitude within reach
    is detectable."""
    m = np.asarray(mags, dtype=float)
    g = np.maximum(np.asarray(chi2_gain, dtype=float), 1e-300)
    o = np.argsort(m if grows else 1.0 / m)  # weakest effect first
    g, m = g[o], m[o]
    lo_b, hi_b = bounds
    if g[-1] < needed:
        return None
    if g[0] >= needed:
        if not grows:
            return float(m[0])  # weaker than the weakest tried is not extrapolated
        val = float(m[0] * math.sqrt(needed / g[0]))
        return max(val, lo_b) if lo_b is not None else val
    k = int(np.argmax(g >= needed))
    u = (math.log(needed) - math.log(g[k - 1])) / (math.log(g[k]) - math.log(g[k - 1]))
    val = float(math.exp(math.log(m[k - 1]) + u * (math.log(m[k]) - math.log(m[k - 1]))))
    if lo_b is not None:
        val = max(val, lo_b)
    if hi_b is not None:
        val = min(val, hi_b)
    return val


def held_out_penalty(lik, models, held, eta: float) -> dict:
    """{model: log-evidence penalty <= 0} for the fitted models whose held-out run worked:
    eta/2 times the amount by which the model's robust chi^2 on the held-out points (summed
    over their real residuals, at the model's training nuisance) exceeds that of "none".

    The evidence is read on the training points. A model that follows a misfit of a few of
    them (a tuned absorber's narrow response, a pair of effects) can gain evidence there and
    predict the held-out points worse than the calibrated model; the points it was not fitted
    to then count against it, as their predictive likelihood would. An improvement is not
    credited: an effect that takes up the model's own discretisation error improves the
    held-out points as much as the training ones (a transducer low pass in a clean campaign
    did), so crediting it would reward that imitation."""
    n = 2 * len(held) * len(lik.orders)
    if not held or models["none"]["yh"] is None:
        return {}
    base = lik.robust_reduced_chi2(models["none"]["yh"], held, models["none"]["nuisance"])
    out = {}
    for label, fit in models.items():
        if label == "none" or fit["yh"] is None:
            continue
        chi = lik.robust_reduced_chi2(fit["yh"], held, fit["nuisance"])
        if math.isfinite(chi) and math.isfinite(base):
            out[label] = -0.5 * eta * n * max(0.0, chi - base) + 0.0  # + 0.0: no "-0.0" in the JSON
    return out


def model_log_evidence(models: dict, candidates, pairs, screen_z: dict, ramp_ll: dict, penalty: dict,
                       unfitted, unnamed: float = 0.0) -> dict:
    """{model: log evidence} of every model the posterior compares. ``models``: the fitted
    ones ({label: fit with "log_z" and "yh", the held-out coefficients or None when that run
    failed}); a fitted model's evidence is its Laplace evidence on the training points plus
    its ramps' log likelihood (``ramp_ll``) plus its held-out penalty (``penalty``,
    :func:`held_out_penalty`). A candidate that was not fitted takes "none"'s evidence plus
    its linear screen's (``screen_z``, relative to "none"; its ramps are taken as those of
    "none"). ``unnamed``: what "none" gains from an unnamed smooth misfit
    (:func:`dampersim.discrepancy.unnamed.combined`), added after the screened candidates took
    its evidence: a screened effect is not given that misfit. A model whose held-out run failed,
    and a candidate every fit of which failed (``unfitted``), get -inf: a failed run is never a match."""
    log_z = {"none": models["none"]["log_z"] + ramp_ll.get("none", 0.0)}
    for label in [*candidates, *pairs]:
        if label in models:
            log_z[label] = models[label]["log_z"] + ramp_ll.get(label, 0.0) + penalty.get(label, 0.0)
        else:
            log_z[label] = log_z["none"] + screen_z[label]
    log_z["none"] += unnamed
    for label, fit in models.items():
        if fit["yh"] is None:
            log_z[label] = -math.inf
    for label in unfitted:
        log_z[label] = -math.inf
    return log_z


__all__ = ["MAGNITUDE_PRIOR_SD", "SHAPE_PRIOR_SD", "MODEL_PRIOR", "Z90", "DETECTION_POSTERIOR", "learning_rate",
           "log_evidence", "held_out_penalty", "model_log_evidence",
           "posterior_covariance", "interval90", "model_priors", "posterior", "linear_screen_evidence",
           "detection_chi2", "threshold_magnitude"]
