"""A pair's second effect: each other candidate screened on what the leading single fit leaves.

The second effect of a pair has to explain the misfit that remains once the first is fitted,
not the whole discrepancy: ranking the partners by their own single fits picks the effect
that best imitates the first one. So every other candidate is run once at its typical
magnitude (and at each screened shape) on top of the leading fit, and the linear screen of
:meth:`~dampersim.discrepancy.naming.Namer.screen` (calibration factors re-fitted under their
prior, the effect's scale under its magnitude prior) reads that signature against the leading
fit's standardised residual. The candidate whose evidence gains most over the leading fit
alone is the partner.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from dampersim.discrepancy import selection, shapes
from dampersim.discrepancy.effects import info, with_effect
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
    magnitude, read at the learning rate like the gain)} for every candidate but ``lead``.
    ``fit``: the leading single fit (system, factors ``x``, training coefficients ``y``);
    ``namer``: the naming step's :class:`~dampersim.discrepancy.naming.Namer`; eta: the
    learning rate the likelihood is tempered by. The gain sums the candidate's screened
    shapes with their prior weights, like the single screen, over shapes.partner_grid (the
    single screen's grid and the absorber's tuning orders); it is -inf,
    with the parameter set's own shape ({}), when every run of the candidate on top of the
    leading fit failed or the parameter set refuses it there. Failed runs are recorded
    against the candidate, as its own screen's are: the effect is what made the model fail
    there. A failed candidate's scale is 1."""
    k = math.sqrt(eta)
    jac = namer.jac_of(fit)
    nu = namer.lik.profile(fit["y"], namer.train)[1]
    with namer.lik.using(nu):
        r = namer.lik.mvec(namer.train) - namer.lik.vec(fit["y"], namer.train)
    z_lead = selection.linear_screen_evidence(k * r, k * jac, None, fit["x"], PRIOR_LOG_SD)[0]
    out, grid = {}, shapes.partner_grid()
    for name in candidates:
        if name == lead:
            continue
        e = info(name)
        scored = []
        for vals, lw in namer.screen_variants(name, grid):
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

    An effect the screen reads over a shape grid (the short springs: clearance, then count; the
    absorber: its tuning order) takes the screened shapes from what the leading fit leaves, since
    its own single fit, where it had one, took up the leading effect's signature as well: its best
    screened values on top of that fit (``gained``, from :func:`gains`) and the count
    :meth:`Namer.choose <dampersim.discrepancy.naming.Namer.choose>` picks by real runs there, at
    that variant's scale (read at the learning rate, so nearer the typical magnitude than an
    untempered one: it only sets where the counts are compared, the fit then searches the
    magnitude), failures recorded against the pair ``label``; ``extra_prior``: the first effect's
    prior terms, the same for every count. Its shapes the screen does not read (the absorber's
    damping) stay as its single fit reached them. Any other effect, and one whose partner screen
    failed (the fallback partner), keeps the shape its single fit reached (``models``), or, not
    fitted alone, its best screened shape; a discrete choice not chosen by runs takes its equal
    prior share."""
    g, screened, scale = gained.get(second, Gain(-math.inf, {}, 1.0))
    read = shapes.partner_grid().get(second, {})
    if math.isfinite(g) and (read or second in shapes.SCREEN_CHOICES):
        start = (lead_fit["system"], lead_fit["x"], lead_fit["y"])
        chosen, mass = namer.choose(second, {"start": start, "shape": screened, "scale": scale},
                                    jac=namer.jac_of(lead_fit), label=label, extra_prior=extra_prior)
        # its continuous shapes the partner screen does not read (the absorber's damping) as fitted alone
        unread = set(shapes.SHAPES.get(second, ())) - set(read)
        alone = namer.shape_values(second, models[second]["system"]) if second in models else {}
        return {**{q: v for q, v in alone.items() if q in unread}, **chosen}, mass
    if second in models:
        return namer.shape_values(second, models[second]["system"]), models[second].get("log_mass", 0.0)
    return screened, -math.log(max(1, len(shapes.choices(second))))


def choose(gained: dict, fallback: str | None) -> str | None:
    """The partner: the candidate of highest gain (the first listed on ties); ``fallback`` when
    no candidate has a finite gain."""
    finite = [(n, g) for n, (g, *_) in gained.items() if math.isfinite(g)]
    return max(finite, key=lambda t: t[1])[0] if finite else fallback  # max keeps the first of equals


__all__ = ["Gain", "pair_label", "gains", "shape", "choose"]
