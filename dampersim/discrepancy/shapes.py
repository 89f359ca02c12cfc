"""The shape parameters of a missing effect: which are fitted with its magnitude, which are
searched by the screen before any fit, and their prior terms.

A shape parameter (a pendulum's tuning order, the short springs' clearance) changes the form
of an effect's signature rather than its size. The continuous ones (:data:`SHAPES`) are
fitted in log scale under a Gaussian prior of spread SHAPE_PRIOR_SD around the parameter set's
own value (the library's default unless the user's set says otherwise). Where the signature
is so non-linear in a shape that a fit from the library's value cannot reach the truth (the
short springs act only beyond their clearance; a point below it sees none of them), the
screen first reads the effect over a grid of values (:data:`SCREEN_FACTORS`, weighted by the
same prior; :func:`variants`), and the fit starts from the best of them; a pair's partner
screen also reads the pendulum's tuning order, whose signature changes sign at an excited
order (:data:`PARTNER_FACTORS`). The linear screen scales a signature as a whole and so
cannot tell a spring count from a stiffness: the discrete choices (:data:`SCREEN_CHOICES`,
equal prior mass each; :func:`choices`) are compared by real runs at the same total
(:func:`magnitude_at_choice`) before the fit, which holds the best.
"""

from __future__ import annotations

import math

from dampersim.discrepancy.effects import clip_to_range, parameters_of
from dampersim.discrepancy.selection import SHAPE_PRIOR_SD

#: shape parameters fitted with an effect's magnitude (log scale, prior SHAPE_PRIOR_SD around
#: the parameter set's value): the pendulum's tuning order and damping, the clutch's slip law,
#: the short springs' clearance; the other effects have one parameter that matters
SHAPES = {
    "pendulum_absorber": ("order", "damping"),
    "clutch_slip": ("slip_speed", "viscous"),
    "inner_short_springs": ("clearance",),
}
#: continuous shapes the screen reads at several values, as factors on the parameter set's
#: value: the short springs' clearance 0.05 to 0.14 rad around the library's 0.1 rad in steps of
#: sqrt(2) (the range a production damper's short springs engage in is 0.05-0.15 rad,
#: dampersim.discrepancy.truths.SHAPE_RANGES; a point whose inner windup lies between two
#: grid values sees the springs at one and not the other, which a linear fit cannot bridge)
SCREEN_FACTORS = {"inner_short_springs": {"clearance": (0.5, 0.5 * math.sqrt(2.0), 1.0, math.sqrt(2.0))}}
#: continuous shapes a pair's partner screen reads besides SCREEN_FACTORS: the pendulum's tuning
#: order 4 % either side of the parameter set's (the library's 2.0) as well as at it. The
#: library tunes the pendulum to order 2.0, an order the drive excites, and there the absorber's
#: effective inertia at that order, J_a / (1 - (2 / n_t)^2), changes sign with the tuning; a pair
#: holds its second effect's shape, so the order it is held at is read on top of the first fit.
#: The single screen keeps the library's order: read there at 1.92, 2.0 and 2.08, the bundled
#: example's absorber (tuned to 2.0) was fitted to 1.959 and the diagnosis lost it
#: (docs/discrepancy.md, Benchmark, "The absorber's tuning order screened on both sides")
PARTNER_FACTORS = {"pendulum_absorber": {"order": (0.96, 1.0, 1.04)}}
#: discrete shapes the screen chooses among, with equal prior mass: 1 to 3 of the inner set's
#: five pairs carry a short spring. The count is not only a factor on the stiffness: below
#: the clearance each short pair lacks its full-length inner spring, so the set is softer there
SCREEN_CHOICES = {"inner_short_springs": {"count": (1, 2, 3)}}
#: effects whose magnitude is per unit of a discrete choice: the short springs' stiffness is one
#: spring's, so counts are compared at the same engaged rate, count x stiffness
PER_UNIT = {"inner_short_springs": "count"}


def logsumexp(values) -> float:
    """log(sum(exp(values))) (scipy.special.logsumexp): exact for a single value, -inf when every
    value is -inf or there is none."""
    from scipy.special import logsumexp as lse  # scipy loads only when a diagnosis runs

    vals = [float(v) for v in values]
    return float(lse(vals)) if vals else -math.inf


def renormalised(options) -> list:
    """[(values, log weight)] with the weights scaled to sum to one (those left after some
    were dropped)."""
    norm = logsumexp(lw for _, lw in options)
    return [(v, lw - norm) for v, lw in options]


def variants(name: str, effect, grid=None) -> list:
    """The continuous shape values the screen reads effect ``name`` at: a list of (values
    {parameter: value}, log prior weight), the weights summing to one over the list.
    ``effect``: the effect's parameters in the parameter set (their values are the grid's
    centre); ``grid``: {effect: {parameter: factors}}, default :data:`SCREEN_FACTORS` (the
    partner screen passes :func:`partner_grid`). An effect without screened shapes has the
    single variant ({}, 0.0): it is read as the set has it. The discrete choices are not read
    by the screen (:func:`choices`)."""
    meta = {p["name"]: p for p in parameters_of(name)}
    out = [({}, 0.0)]
    for q, factors in (SCREEN_FACTORS if grid is None else grid).get(name, {}).items():
        v0 = float(getattr(effect, q))
        logw = [-0.5 * (math.log(f) / SHAPE_PRIOR_SD) ** 2 for f in factors]
        norm = logsumexp(logw)
        axis = [({q: clip_to_range(v0 * f, meta[q])}, lw - norm) for f, lw in zip(factors, logw)]
        out = [({**a, **b}, la + lb) for a, la in out for b, lb in axis]
    return out


def partner_grid() -> dict:
    """The shape grid of a pair's partner screen: :data:`SCREEN_FACTORS` and
    :data:`PARTNER_FACTORS`, merged per effect (an effect in both gets both axes)."""
    out = {name: dict(axes) for name, axes in SCREEN_FACTORS.items()}
    for name, axes in PARTNER_FACTORS.items():
        out[name] = {**out.get(name, {}), **axes}
    return out


def choices(name: str) -> list:
    """Effect ``name``'s discrete shape choices (:data:`SCREEN_CHOICES`) as a list of
    {parameter: value}; [] for an effect without any. A parameter set whose own value lies
    outside them is fitted at one of them when the effect is named."""
    out = [{}]
    for q, values in SCREEN_CHOICES.get(name, {}).items():
        out = [{**a, q: v} for a in out for v in values]
    return out if len(out) > 1 else []


def magnitude_at_choice(name: str, m: float, held: dict, choice: dict) -> float:
    """The magnitude that keeps effect ``name``'s total at ``choice`` what magnitude ``m`` gives
    at the choices ``held``: a magnitude per unit of a choice (:data:`PER_UNIT`) scales by the
    ratio of the units; otherwise m."""
    q = PER_UNIT.get(name)
    if q is None or not held.get(q) or not choice.get(q):
        return m
    return m * float(held[q]) / float(choice[q])


def choice_log_mass(name: str, values: dict, scored) -> float:
    """The log prior mass a model at the discrete choices in ``values`` carries: the choices'
    equal prior share, -log(number of choices scored), plus log sum_k exp(s_k - s_mine) over
    the best score s_k of each choice in ``scored`` ([(shape values, log evidence or -objective
    / 2)], one entry or more per choice tried; -inf where its run failed), the estimate of how
    much the other choices would add to the sum over choices. 0 for an effect without discrete
    choices; between -log(number of choices) (the others explain nothing) and 0 for the best."""
    keys = list(SCREEN_CHOICES.get(name, {}))
    if not keys:
        return 0.0
    best = {}
    for vals, z in scored:
        k = tuple(vals.get(q) for q in keys)
        best[k] = max(best.get(k, -math.inf), z)
    share = -math.log(max(1, len(best)))
    mine = best.get(tuple(values.get(q) for q in keys), -math.inf)
    if not math.isfinite(mine):
        return share
    return share + logsumexp([z - mine for z in best.values()])


def prior_term(name: str, values: dict, centre) -> float:
    """The continuous shapes' prior term of the objective (chi^2 units): sum of
    (log(value / centre) / SHAPE_PRIOR_SD)^2 over the fitted shapes of ``values``; ``centre``:
    the effect's parameters in the parameter set (or a dict of their values)."""
    total = 0.0
    for q in SHAPES.get(name, ()):
        c = centre[q] if isinstance(centre, dict) else float(getattr(centre, q))
        if q in values:
            total += (log_ratio(values[q], c) / SHAPE_PRIOR_SD) ** 2
    return total


def log_ratio(a: float, b: float) -> float:
    """log(a / b), 0 where either is not positive (a shape whose prior centre is 0 has no log scale)."""
    return math.log(a / b) if a > 0 and b > 0 else 0.0


__all__ = ["SHAPES", "SCREEN_FACTORS", "PARTNER_FACTORS", "partner_grid", "SCREEN_CHOICES",
           "PER_UNIT", "logsumexp", "renormalised", "variants", "choices", "magnitude_at_choice",
           "choice_log_mass", "prior_term", "log_ratio"]
