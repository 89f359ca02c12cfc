"""The fitted effects of a model with their 90 % intervals: the Laplace covariance's, widened
where leaving out a training point moves a parameter further (a linearised delete-one-point
jackknife).

The Laplace covariance (:func:`~dampersim.discrepancy.selection.posterior_covariance`, plus the
discretisation check's shift, :meth:`~dampersim.discrepancy.naming.Namer.evidence`) assumes
that the only misfit left is scatter of the size the (tempered) uncertainties state. A
systematic misfit that differs from point to point (the model's form, a hidden perturbation
the calibration factors do not span) moves the estimate without adding to that scatter.
Leaving each training point out in turn shows it: the estimates without one point spread by
more than the Laplace standard deviation. Each reported variance is the larger of the two,
so no interval is narrower than the Laplace one. Each estimate without a point is one
Gauss-Newton step of the fit's own objective (the data and the priors) from the fitted
point, with the Jacobian and robust weights the evidence reads; a misfit shared by every
point moves all of them alike and stays unseen.

The jackknife also widens a parameter that one or two points inform, with the noise alone:
without such a point nothing else checks the estimate, and a systematic error there could
not be told from the effect. That is kept on purpose (on a linear toy with per-point misfit
it is what keeps such an interval near its 90 %, where the jackknife's excess over its
noise-alone expectation falls to about 70 %, tests/discrepancy/test_intervals.py); the
diagnosis reports beside each ratio what the jackknife would give with the noise alone
(:func:`jackknife`'s expectation), so the two causes can be told apart. With 8 training
points the jackknife's variance is itself uncertain (about 7 degrees of freedom when every
point informs the parameter alike, fewer when one point dominates): an interval it sets
for an evenly informed parameter holds about 85 % rather than 90 %.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import selection, shapes
from dampersim.discrepancy.effects import info
from dampersim.discrepancy.fitting import CALIBRATION


def point_groups(n_points: int, n_orders: int) -> np.ndarray:
    """The training point of every row of a standardised vector
    (:meth:`~dampersim.discrepancy.likelihood.Likelihood.vec`: the real parts of all points'
    orders, then the imaginary parts, each point's orders together)."""
    per_part = np.repeat(np.arange(n_points), n_orders)
    return np.concatenate([per_part, per_part])


def jackknife(r, jac, prec, offset, groups, eta: float = 1.0) -> tuple:
    """(variance, expected) of each parameter: its variance over the delete-one-group
    estimates, scaled by (n - 1) / n, and what that variance would be on average if the
    residual were the stated noise alone, widened by 1 / sqrt(eta) as the Laplace covariance
    is. A variance well above its expectation says the points disagree; an expectation well
    above the Laplace variance says few points inform the parameter (leverage).

    r: standardised training residual at the fit (measured minus model, dimensionless); jac:
    its Jacobian with respect to the parameters (rows x parameters, d model / d parameter;
    the evidence's parameters: log calibration factors, log magnitudes and shapes, log
    output gain and output delay in s, so each variance is in their squared units); prec: the
    parameters' prior precisions; offset: the parameters minus their prior centres; groups:
    the group (training point) of every row; eta: the likelihood's learning rate
    (:func:`~dampersim.discrepancy.selection.learning_rate`). The objective is |r - J d|^2 / 2
    + (offset + d)' P (offset + d) / 2; each estimate is its minimiser without one group's
    rows, so the fit's distance from the full minimiser cancels in the spread. Each estimate
    is linear in r (A_k r + b_k), so the expectation under r ~ N(0, I / eta) is exact:
    sum_k |A_k - mean A|^2 / eta + sum_k (b_k - mean b)^2, times (n - 1) / n. Fewer than two
    groups give zeros (nothing to leave out); inputs that are not all finite give NaN (no
    jackknife: the intervals keep the Laplace variance)."""
    r, jac = np.asarray(r, dtype=float), np.asarray(jac, dtype=float)
    p, offset = np.asarray(prec, dtype=float), np.asarray(offset, dtype=float)
    groups = np.asarray(groups)
    labels = np.unique(groups)
    if not all(np.all(np.isfinite(a)) for a in (r, jac, p, offset)) or not eta > 0:
        nan = np.full(jac.shape[1], np.nan)
        return nan, nan
    if len(labels) < 2:
        zero = np.zeros(jac.shape[1])
        return zero, zero
    h_all = jac.T @ jac + np.diag(p)
    maps, pulls = [], []
    for k in labels:
        out = groups == k
        kept = np.where(out[:, None], 0.0, jac)  # J without group k's rows
        h = h_all - jac[out].T @ jac[out]
        maps.append(np.linalg.solve(h, kept.T))  # A_k: parameters x rows
        pulls.append(-np.linalg.solve(h, p * offset))  # b_k
    maps, pulls = np.array(maps), np.array(pulls)
    steps = maps @ r + pulls
    n = len(labels)

    def scatter(a):  # the jackknife's variance over the first axis (the left-out groups)
        return (n - 1) / n * np.sum((a - a.mean(axis=0)) ** 2, axis=0)

    variance = scatter(steps)
    expected = np.sum(scatter(maps), axis=1) / eta + scatter(pulls)
    return variance, expected


def columns(fit) -> dict:
    """{effect: {parameter: its column in the evidence's order}} for the parameters of a
    fitted model that get an interval: each effect's magnitude (calibration factors first,
    then the magnitudes) and, for a single effect, its fitted shapes after them."""
    names, n_cal = fit.get("effects", []), len(CALIBRATION)
    out = {}
    for j, name in enumerate(names):
        out[name] = {info(name).magnitude: n_cal + j}
        if len(names) == 1:
            out[name].update({q: n_cal + 1 + i for i, q in enumerate(fit.get("shape_start", {}))})
    return out


def effects_of(label, fit, jack_var=None) -> list:
    """The ``effects`` entries of a fitted model: name, fitted parameters (magnitude and
    shape parameters) and their 90 % intervals in log space, from the larger of the Laplace
    variance (``fit["cov"]``) and ``jack_var`` (:func:`jackknife`'s variance, in the same
    parameter order; None or NaN: the Laplace variance alone). A magnitude the ramps sized
    (``fit["sized_by_ramps"]``) keeps the ramps' variance: the torsional points did not set it."""
    out = []
    names, cols_of = fit.get("effects", []), columns(fit)
    cov, own = fit.get("cov"), fit.get("sized_by_ramps", False)

    def sd(i, own=False):
        if cov is None:
            return math.nan
        v = max(float(cov[i, i]), 0.0)
        j = math.nan if jack_var is None or own else float(jack_var[i])
        return math.sqrt(max(v, j) if math.isfinite(j) else v)

    for j, name in enumerate(names):
        e, cols = info(name), cols_of[name]
        m = fit["m"] if j == len(names) - 1 else fit.get("m_first", fit["m"])
        params = {e.magnitude: m}
        intervals = {e.magnitude: selection.interval90(math.log(m), sd(cols[e.magnitude], own))}
        for q, v in reported_shapes(name, fit, len(names)).items():
            params[q] = v
            if q in cols:  # a fitted shape; a discrete one the screen chose has none
                intervals[q] = selection.interval90(math.log(v), sd(cols[q]))
        out.append({"name": name, "parameters": params, "intervals": intervals})
    return out


def spread(fit, variance) -> dict:
    """{effect: {parameter: sqrt(variance / Laplace variance)}} of a fitted model's interval
    parameters, for :func:`jackknife`'s variance (above 1: the jackknife set the width) or its
    expectation with the noise alone; None where there is no jackknife. A magnitude the ramps
    sized is left out: its interval is the ramps'."""
    cov, out = fit.get("cov"), {}
    if cov is None or variance is None:
        return out
    for name, cols in columns(fit).items():
        if fit.get("sized_by_ramps"):
            cols.pop(info(name).magnitude)
        out[name] = {q: (math.sqrt(max(float(variance[i]), 0.0) / float(cov[i, i]))
                         if cov[i, i] > 0 and math.isfinite(float(variance[i])) else None) for q, i in cols.items()}
    return out


def reported_shapes(name, fit, n_effects: int) -> dict:
    """The shape values a single effect's model holds: its fitted shapes (where the shape step
    left them, or where the fit started when the step was refused) and its discrete choices
    (:data:`~dampersim.discrepancy.shapes.SCREEN_CHOICES`). A pair holds both effects' shapes
    (the first at its single fit's, the second at :func:`~dampersim.discrepancy.partner.shape`'s):
    their values as the pair's parameter set has them, none of them fitted."""
    eff = getattr(fit["system"].effects, name)
    choices = {q: getattr(eff, q) for q in shapes.SCREEN_CHOICES.get(name, {})}
    if n_effects != 1:
        return {**{q: getattr(eff, q) for q in shapes.SHAPES.get(name, ())}, **choices}
    return {**fit.get("shape_start", {}), **fit.get("shapes", {}), **choices}


__all__ = ["point_groups", "jackknife", "columns", "effects_of", "spread", "reported_shapes"]
