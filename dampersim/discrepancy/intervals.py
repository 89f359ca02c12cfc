"""The fitted effects of a model with their 90 % intervals: the Laplace covariance's, widened
where the training points disagree about a parameter (a linearised delete-one-point jackknife).

The Laplace covariance (:func:`~dampersim.discrepancy.selection.posterior_covariance`, plus the
discretisation check's shift, :meth:`~dampersim.discrepancy.naming.Namer.evidence`) assumes
that the only misfit left is scatter of the size the uncertainties state, spread evenly over
the points. A systematic misfit that differs from point to point (the model's form, a hidden
perturbation the calibration factors do not span) moves the estimate without adding to that
scatter. Leaving each training point out in turn shows it: the estimates without one point
spread by more than the Laplace standard deviation when the points pull the parameter apart.
Each reported interval takes the larger of the two variances, so it is never narrower than
the Laplace interval. The jackknife is linear: each estimate without a point is one
Gauss-Newton step of the fit's own objective (data at learning rate 1, as the fit minimises
it, and the priors) from the fitted point, with the Jacobian and robust weights the evidence
reads; a misfit shared by every point moves all of them alike and stays unseen.
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


def jackknife_variance(r, jac, prec, offset, groups) -> np.ndarray:
    """Variance of each parameter over the delete-one-group estimates, scaled by (n - 1) / n.

    r: standardised training residual at the fit (measured minus model); jac: its Jacobian
    with respect to the parameters (rows x parameters, d model / d parameter); prec: the
    parameters' prior precisions; offset: the parameters minus their prior centres; groups:
    the group (training point) of every row. The objective is |r - J d|^2 / 2 + (offset +
    d)' P (offset + d) / 2; each estimate is its minimiser without one group's rows, so the
    fit's distance from the full minimiser cancels in the spread. Fewer than two groups give
    zeros (nothing to leave out); inputs that are not all finite give NaN (no jackknife: the
    intervals keep the Laplace variance)."""
    r, jac = np.asarray(r, dtype=float), np.asarray(jac, dtype=float)
    p, offset = np.asarray(prec, dtype=float), np.asarray(offset, dtype=float)
    groups = np.asarray(groups)
    labels = np.unique(groups)
    if not all(np.all(np.isfinite(a)) for a in (r, jac, p, offset)):
        return np.full(jac.shape[1], np.nan)
    if len(labels) < 2:
        return np.zeros(jac.shape[1])
    h_all = jac.T @ jac + np.diag(p)
    g_all = jac.T @ r - p * offset
    steps = []
    for k in labels:
        jk, rk = jac[groups == k], r[groups == k]
        steps.append(np.linalg.solve(h_all - jk.T @ jk, g_all - jk.T @ rk))
    steps = np.array(steps)
    n = len(labels)
    return (n - 1) / n * np.sum((steps - steps.mean(axis=0)) ** 2, axis=0)


def effects_of(label, fit, jack_var=None) -> list:
    """The ``effects`` entries of a fitted model: name, fitted parameters (magnitude and
    shape parameters) and their 90 % intervals in log space, from the larger of the Laplace
    variance (``fit["cov"]``) and ``jack_var`` (:func:`jackknife_variance`, in the same
    parameter order; None: the Laplace variance alone). A magnitude the ramps sized
    (``fit["sized_by_ramps"]``) keeps the ramps' variance: the torsional points did not set it."""
    out = []
    names = fit.get("effects", [])
    cov = fit.get("cov")
    n_cal = len(CALIBRATION)

    def sd(i, own=False):
        if cov is None:
            return math.nan
        v = max(float(cov[i, i]), 0.0)
        if jack_var is None or own or not math.isfinite(float(jack_var[i])):
            return math.sqrt(v)
        return math.sqrt(max(v, float(jack_var[i])))

    for j, name in enumerate(names):
        e = info(name)
        m = fit["m"] if j == len(names) - 1 else fit.get("m_first", fit["m"])
        params = {e.magnitude: m}
        intervals = {e.magnitude: selection.interval90(math.log(m), sd(n_cal + j, fit.get("sized_by_ramps", False)))}
        for q, v in reported_shapes(name, fit, len(names)).items():
            params[q] = v
            if q in fit.get("shape_start", {}):  # a fitted shape; a discrete one the screen chose has none
                i = n_cal + len(names) + list(fit["shape_start"]).index(q)
                intervals[q] = selection.interval90(math.log(v), sd(i))
        out.append({"name": name, "parameters": params, "intervals": intervals})
    return out


def spread(fit, jack_var) -> dict:
    """{effect: {parameter: jackknife / Laplace standard deviation}} of a fitted model's
    interval parameters: above 1 where the points' disagreement widened the interval, None
    where there was no jackknife (a magnitude the ramps sized is left out: its interval is
    the ramps')."""
    cov, out = fit.get("cov"), {}
    if cov is None or jack_var is None:
        return out
    names, n_cal = fit.get("effects", []), len(CALIBRATION)
    for j, name in enumerate(names):
        idx = {} if fit.get("sized_by_ramps") else {info(name).magnitude: n_cal + j}  # the ramps' variance
        if len(names) == 1:
            idx.update({q: n_cal + 1 + i for i, q in enumerate(fit.get("shape_start", {}))})
        out[name] = {q: (math.sqrt(max(float(jack_var[i]), 0.0) / float(cov[i, i]))
                         if cov[i, i] > 0 and math.isfinite(float(jack_var[i])) else None) for q, i in idx.items()}
    return out


def reported_shapes(name, fit, n_effects: int) -> dict:
    """The shape values a single effect's model holds: its fitted shapes (where the shape step
    left them, or where the fit started when the step was refused) and its discrete choices
    (:data:`~dampersim.discrepancy.shapes.SCREEN_CHOICES`); none for a pair, whose second
    effect keeps the shape of its own fit."""
    if n_effects != 1:
        return {}
    eff = getattr(fit["system"].effects, name)
    return {**fit.get("shape_start", {}), **fit.get("shapes", {}),
            **{q: getattr(eff, q) for q in shapes.SCREEN_CHOICES.get(name, {})}}


__all__ = ["point_groups", "jackknife_variance", "effects_of", "spread", "reported_shapes"]
