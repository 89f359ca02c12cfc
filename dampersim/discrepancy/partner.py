"""A pair's second effect: each other candidate screened on what the leading single fit leaves.

The second effect of a pair has to explain the misfit that remains once the first is fitted,
not the whole discrepancy: ranking the partners by their own single fits picks the effect
that best imitates the first one. So every other candidate is run once at its typical
magnitude (and at each screened shape) on top of the leading fit, and the linear screen of
:meth:`~dampersim.discrepancy.naming.Namer.screen` (calibration factors re-fitted under their
prior, the effect's scale under its magnitude prior) reads that signature against the leading
fit's standardised residual. The candidate whose evidence gains most over the leading fit
alone is the partner. Once the second magnitude is fitted on top of the first fit, the pair's
factors and both magnitudes take one Gauss-Newton step together (:func:`joint_step`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from dampersim.discrepancy import fitting, selection, shapes
from dampersim.discrepancy.effects import clip_magnitude, info, with_effect
from dampersim.discrepancy.fitting import PRIOR_LOG_SD
from dampersim.discrepancy.naming import MIN_SCREEN_SCALE
from dampersim.errors import ParameterError


class Gain(NamedTuple):
    """One candidate's result in the partner screen (:func:`gains`)."""

    nats: float  # log evidence gain of adding it to the leading fit; -inf: every run failed or refused
    shape: dict  # the shape values of its best screened variant ({}: the parameter set's own)
    scale: float  # that variant's linear scale on the typical magnitude, at the learning rate (1 when failed)


def pair_label(first: str, second: str) -> str:
    """The posterior's key of a pair: the two effect names sorted, joined by "+"."""
    return "+".join(sorted([first, second]))


def gains(namer, lead: str, fit: dict, candidates, eta: float = 1.0) -> dict:
    """{candidate: :class:`Gain` (log evidence gain [nats] of adding it to the leading fit, the
    shape values of its best screened variant, that variant's linear scale on the typical
    magnitude, read at the learning rate like the gain)} for every candidate but ``lead``. ``fit``: the leading
    single fit (system, factors ``x``, training coefficients ``y``); ``namer``: the naming
    step's :class:`~dampersim.discrepancy.naming.Namer`; eta: the learning rate the
    likelihood is tempered by. The gain sums the candidate's screened shapes with their prior
    weights (shapes.variants), like the single screen; it is -inf, with the parameter set's
    own shape ({}), when every run of the candidate on top of the leading fit failed or the
    parameter set refuses it there. Failed runs are recorded against the candidate, as its
    own screen's are: the effect is what made the model fail there. A failed candidate's scale
    is 1."""
    k = math.sqrt(eta)
    jac = namer.jac_of(fit)
    nu = namer.lik.profile(fit["y"], namer.train)[1]
    with namer.lik.using(nu):
        r = namer.lik.mvec(namer.train) - namer.lik.vec(fit["y"], namer.train)
    z_lead = selection.linear_screen_evidence(k * r, k * jac, None, fit["x"], PRIOR_LOG_SD)[0]
    out = {}
    for name in candidates:
        if name == lead:
            continue
        e = info(name)
        scored = []
        for vals, lw in namer.screen_variants(name):
            try:
                system = with_effect(fit["system"], name, {**vals, e.magnitude: e.magnitudes[1]})
            except ParameterError:  # refused beside the leading effect: not run
                scored.append((vals, -math.inf, 1.0))
                continue
            y, failed = namer.runs(system, name)
            if failed:
                scored.append((vals, -math.inf, 1.0))
                continue
            with namer.lik.using(nu):
                d = namer.w(y - fit["y"])
            z, scale = selection.linear_screen_evidence(k * r, k * jac, k * d, fit["x"], PRIOR_LOG_SD,
                                                        min_scale=MIN_SCREEN_SCALE)[:2]
            scored.append((vals, lw + z, scale))
        total = shapes.logsumexp(t[1] for t in scored)
        best = max(scored, key=lambda t: t[1]) if math.isfinite(total) else ({}, -math.inf, 1.0)  # the set's own
        out[name] = Gain(total - z_lead, best[0], best[2])
    return out


def shape(namer, second: str, lead_fit: dict, gained: dict, models: dict, label: str, extra_prior: float) -> tuple:
    """(shape values, log prior mass of its discrete choices) the pair holds its second effect
    ``second`` at, on top of the leading fit ``lead_fit``.

    An effect the screen reads over a shape grid (the short springs: clearance, then count) takes
    both from what the leading fit leaves, since its own single fit, where it had one, took up
    the leading effect's signature as well: its best screened clearance on top of that fit
    (``gained``, from :func:`gains`) and the count :meth:`Namer.choose
    <dampersim.discrepancy.naming.Namer.choose>` picks by real runs there, at that variant's
    scale (read at the learning rate, so nearer the typical magnitude than an untempered one:
    it only sets where the counts are compared, the fit then searches the magnitude), failures
    recorded against the pair ``label``; ``extra_prior``: the first effect's prior terms, the same for
    every count. Any other effect, and one whose partner screen failed (the fallback partner),
    keeps the shape its single fit reached (``models``), or, not fitted alone, its best screened
    shape; a discrete choice not chosen by runs takes its equal prior share."""
    g, screened, scale = gained.get(second, Gain(-math.inf, {}, 1.0))
    if math.isfinite(g) and (second in shapes.SCREEN_FACTORS or second in shapes.SCREEN_CHOICES):
        start = (lead_fit["system"], lead_fit["x"], lead_fit["y"])
        return namer.choose(second, {"start": start, "shape": screened, "scale": scale},
                            jac=namer.jac_of(lead_fit), label=label, extra_prior=extra_prior)
    if second in models:
        return namer.shape_values(second, models[second]["system"]), models[second].get("log_mass", 0.0)
    return screened, -math.log(max(1, len(shapes.choices(second))))


def joint_step(namer, first: str, second: str, lead_fit: dict, pair_fit: dict, shape_2: dict, label: str) -> dict:
    """The pair's fit after one Gauss-Newton step on the calibration factors and both magnitudes
    together, accepted when a real run lowers its objective.

    The pair's second magnitude is fitted on top of the first effect's single fit, whose
    magnitude and factors were fitted without the second effect and may have taken up part of
    its signature (the drag + short springs case: the drag at 3.40 alone against the truth's
    3); its search re-calibrates only in the linearised objective and keeps the single fit's
    factors. The step (:func:`~dampersim.discrepancy.fitting.prior_step`, at the fit's own
    robust weights, as :meth:`Namer.refit <dampersim.discrepancy.naming.Namer.refit>` steps)
    reads the factors' Jacobian the first fit is read with, the first magnitude's column of its
    single fit and the second's of the pair fit, under the factors' and the magnitudes' priors;
    the step lengths of :data:`~dampersim.discrepancy.fitting.CAL_STEP_FRACTIONS` are tried,
    longest first, one run of the training points each, failures recorded against the pair
    ``label``. The shapes stay: the first at its single fit's, the second at ``shape_2``, their
    prior terms in the objective as before. The columns returned are those the step was taken
    with (one step behind an accepted step, as after a refit); a parameter whose column is zero
    (its derivative run failed) is held. ``pair_fit``: the pair's fit from :meth:`Namer.fit
    <dampersim.discrepancy.naming.Namer.fit>`, its ``m`` the second magnitude; returned
    unchanged (the same object) when no step length lowers the objective."""
    e1, e2 = info(first), info(second)
    m1, m2, x0 = float(lead_fit["m"]), float(pair_fit["m"]), np.asarray(pair_fit["x"], dtype=float)
    shape_1 = {**lead_fit.get("shape_start", {}), **lead_fit.get("shapes", {})}
    held = namer.shape_prior(first, shape_1) + namer.shape_prior(second, shape_2)
    jac = np.column_stack([namer.jac_of(lead_fit), lead_fit["column"], pair_fit["column"]])
    n = len(x0)
    prec = np.concatenate([namer.prec_cal, np.full(2, 1.0 / selection.MAGNITUDE_PRIOR_SD ** 2)])
    centre = np.concatenate([-x0, [math.log(e1.magnitudes[1] / m1), math.log(e2.magnitudes[1] / m2)]])
    _, r, rw = namer._at_own_weights(pair_fit["y"])
    ok = np.any(jac != 0.0, axis=0)  # a failed derivative run left a zero column: no direction, so no
    step = np.zeros(n + 2)  # pull to the prior alone either (that parameter stays, as in Namer.refit)
    if ok.any():
        step[ok] = fitting.prior_step(jac[:, ok] * rw[:, None], r * rw, prec[ok], centre[ok])

    def trial(frac):
        """(objective, factors, first magnitude, second magnitude, coefficients, set) a fraction along the step."""
        x = np.clip(x0 + frac * step[:n], -fitting.CAL_BOUND, fitting.CAL_BOUND)
        a = clip_magnitude(first, m1 * math.exp(frac * float(step[n])))
        b = clip_magnitude(second, m2 * math.exp(frac * float(step[n + 1])))
        system = fitting.calibrated_system(pair_fit["system"], x - x0)  # the factors relative to the pair's
        system = with_effect(with_effect(system, first, {e1.magnitude: a}), second, {e2.magnitude: b})
        y, failed = namer.runs(system, label)
        prior = namer._magnitude_prior(first, a) + namer._magnitude_prior(second, b) + held
        return (math.inf if failed else namer.cost(y, x, prior)), x, a, b, y, system

    found = fitting.first_lower(trial, pair_fit["cost"]) if step.any() and np.all(np.isfinite(step)) else None
    if found is None:
        return pair_fit
    c, x, a, b, y, system = found
    return {**pair_fit, "cost": c, "x": x, "m": b, "m_first": a, "y": y, "system": system}


def choose(gained: dict, fallback: str | None) -> str | None:
    """The partner: the candidate of highest gain (the first listed on ties); ``fallback`` when
    no candidate has a finite gain."""
    finite = [(n, g) for n, (g, *_) in gained.items() if math.isfinite(g)]
    return max(finite, key=lambda t: t[1])[0] if finite else fallback  # max keeps the first of equals


__all__ = ["Gain", "pair_label", "gains", "shape", "joint_step", "choose"]
