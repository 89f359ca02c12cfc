"""Checks a :class:`DamperSystem` field by field and as a whole.

Every failure raises :class:`dampersim.errors.ParameterError` naming the dotted field,
the value given and what is accepted.
"""

from __future__ import annotations

import dataclasses
import math
import re

from dampersim.errors import ParameterError
from dampersim.parameters import model as m

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

#: Most rig elements of a parameter set. The thesis's rig has five (gearbox, flanges,
#: transducer, coupling, output motor); every element is a degree of freedom of the
#: model, and the solver's stability check solves a dense eigenproblem over all of them.
MAX_RIG_ELEMENTS = 64
#: Most degrees of freedom of the model a parameter set may describe (bodies, spring
#: segments, rig elements and effect DOFs: :func:`degrees_of_freedom`). The segment
#: ranges allow at most ~670; the cap keeps the stability check's dense eigen-solve
#: (cubic in the DOFs: ~1 s at 2000) bounded whatever else changes.
MAX_DEGREES_OF_FREEDOM = 2000


def check_rig_size(n_elements: int, field: str = "rig.elements") -> None:
    """Refuse more than :data:`MAX_RIG_ELEMENTS` rig elements (ParameterError naming the
    field, the count and the limit)."""
    if n_elements > MAX_RIG_ELEMENTS:
        raise ParameterError(field, f"{n_elements} elements", f"at most {MAX_RIG_ELEMENTS} rig elements")


def degrees_of_freedom(system: m.DamperSystem) -> int:
    """Degrees of freedom of the model of ``system``: the three damper bodies, the inner
    nodes of each discretised spring (outer, pair outer and, when nested, pair inner; the
    short pair's two springs when effect inner_short_springs adds them), the rig elements
    and one per enabled clutch-slip or pendulum-absorber effect (as the solver lays them
    out)."""
    sv, eff = system.solver, system.effects
    springs = (sv.outer_segments - 1) + (sv.inner_segments - 1) * (2 if system.inner.nested is not None else 1)
    if system.short_pairs > 0:
        springs += 2 * (sv.inner_segments - 1)
    extra = int(bool(eff.clutch_slip.enabled)) + int(bool(eff.pendulum_absorber.enabled))
    return 3 + springs + len(system.rig.elements) + extra


def describe_range(meta) -> str:
    """What a numeric field accepts, from its metadata: "a value in [4, 200]", "a value > 0 kg m^2"."""
    lo, hi, lo_open = meta.get("lo"), meta.get("hi"), meta.get("lo_open")
    unit = meta.get("unit", "")
    unit = "" if unit in ("-", "") else f" {unit}"
    if lo is not None and hi is not None:
        left = "(" if lo_open else "["
        return f"a value in {left}{lo:g}, {hi:g}]{unit}"
    if lo is not None:
        return f"a value {'>' if lo_open else '>='} {lo:g}{unit}"
    if hi is not None:
        return f"a value <= {hi:g}{unit}"
    return "a finite value"


def check_fields(obj, prefix=""):
    """Check every field of the dataclass ``obj`` (recursively) against the bounds its
    metadata declares; ParameterError names the dotted field (``prefix`` + name)."""
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        path = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(v):
            check_fields(v, path + ".")
            continue
        if isinstance(v, tuple):
            for i, e in enumerate(v):
                check_fields(e, f"{path}[{i}].")
            continue
        meta = f.metadata
        kind = meta.get("kind")
        if kind is None:
            continue
        if kind is bool:
            if not isinstance(v, bool):
                raise ParameterError(path, v, "true or false")
            continue
        if kind is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise ParameterError(path, v, "a whole number")
        if kind is float and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ParameterError(path, v, "a number")
        if not math.isfinite(v):
            raise ParameterError(path, v, describe_range(meta))
        lo, hi = meta.get("lo"), meta.get("hi")
        if lo is not None and (v < lo or (meta.get("lo_open") and v <= lo)):
            raise ParameterError(path, v, describe_range(meta))
        if hi is not None and v > hi:
            raise ParameterError(path, v, describe_range(meta))


def _check_set(s: m.SpringSet, name: str):
    for part in ("spring",):
        if getattr(s, part) is None:
            raise ParameterError(f"{name}.{part}", None, "an arc spring table")
    if s.slot_arc <= 0:
        raise ParameterError(
            f"{name}.primary_stopper_half_width",
            s.primary_stopper_half_width,
            f"stoppers narrower than half the pitch ({math.degrees(s.pitch) / 2:.1f} deg)",
        )
    for part in ("spring", "nested"):
        sp = getattr(s, part)
        if sp is None:
            continue
        path = f"{name}.{part}"
        if sp.arc >= s.pitch:
            raise ParameterError(
                f"{path}.arc",
                sp.arc,
                f"an arc shorter than the stopper pitch 2*pi/{s.count} = {s.pitch:.4f} rad",
                "a spring longer than the pitch cannot fit between two stoppers",
            )
        block = sp.active_coils * sp.wire_thickness / sp.effective_radius
        if block >= sp.arc:
            raise ParameterError(
                f"{path}.wire_thickness",
                sp.wire_thickness,
                f"coils x wire / r_eff below the free arc {sp.arc:.4f} rad (block arc is {block:.4f} rad)",
            )
        if sp.arc > s.slot_arc and s.slot_arc <= block:
            raise ParameterError(
                f"{path}.arc", sp.arc, f"a preload that keeps the spring longer than its block arc {block:.4f} rad"
            )
    if s.hardstop_positive >= s.slot_arc:
        raise ParameterError(f"{name}.hardstop_positive", s.hardstop_positive, f"a windup below the slot arc {s.slot_arc:.4f} rad")
    if -s.hardstop_negative >= s.slot_arc:
        raise ParameterError(f"{name}.hardstop_negative", s.hardstop_negative, f"a windup above -{s.slot_arc:.4f} rad")


def _check_short_springs(system: m.DamperSystem) -> None:
    """Effect inner_short_springs: a second pair design inside the inner set's slots
    (docs/model.md §4). The normal pairs must remain (all pairs short is the base set with
    a shorter ``inner.nested.arc``), the short spring must fit the slot with its
    clearance and stay longer than its block arc."""
    ss = system.effects.inner_short_springs
    if not ss.enabled or ss.count == 0:
        return
    inner = system.inner
    if inner.nested is None:
        raise ParameterError("effects.inner_short_springs.enabled", True, "false, or an inner set with nested "
                             "springs (inner.nested): the short springs are inner springs of nested pairs")
    if ss.count >= inner.count:
        raise ParameterError("effects.inner_short_springs.count", ss.count,
                             f"fewer than the {inner.count} pairs of the inner set (all pairs short: shorten "
                             "inner.nested.arc instead)")
    block = ss.active_coils * inner.nested.wire_thickness / inner.nested.effective_radius
    if inner.slot_arc - ss.clearance <= block:
        raise ParameterError("effects.inner_short_springs.clearance", ss.clearance,
                             f"a clearance below the slot arc {inner.slot_arc:.4f} rad minus the short spring's "
                             f"block arc {block:.4f} rad")


def validate(system: m.DamperSystem) -> m.DamperSystem:
    """Raise ParameterError on the first invalid value; return ``system`` unchanged if valid.

    This checks each value and the relations between values. Whether the solver's time
    step is stable for the set depends on its discretisation and is checked one layer up,
    by :func:`dampersim.solver.linear.check_time_step` (``simulate`` runs both).
    """
    if not isinstance(system, m.DamperSystem):
        raise ParameterError("parameters", type(system).__name__, "a DamperSystem")
    for part in ("inertias", "outer", "inner", "friction", "rig"):
        if getattr(system, part) is None:
            raise ParameterError(part, None, "a table of values")
    for part in ("outer", "pair_outer", "pair_inner"):
        if getattr(system.friction, part) is None:
            raise ParameterError(f"friction.{part}", None, "a table with alpha (and optional preload)")
    if not isinstance(system.rig.elements, tuple):
        raise ParameterError("rig.elements", type(system.rig.elements).__name__, "a list of rig element tables")
    check_rig_size(len(system.rig.elements))  # before anything iterates over them
    check_fields(system)
    ndof = degrees_of_freedom(system)
    if ndof > MAX_DEGREES_OF_FREEDOM:
        raise ParameterError("solver", f"{ndof} degrees of freedom",
                             f"at most {MAX_DEGREES_OF_FREEDOM} (bodies, spring segments and rig elements)")
    _check_set(system.outer, "outer")
    _check_set(system.inner, "inner")
    _check_short_springs(system)
    total = system.friction.alpha_sec + system.friction.alpha_ter
    if abs(total - 1.0) > 1e-9:
        raise ParameterError("friction.alpha_ter", system.friction.alpha_ter, f"1 - alpha_sec = {1 - system.friction.alpha_sec:g}")
    elements = system.rig.elements
    if len(elements) < 1:
        raise ParameterError("rig.elements", elements, "at least one element (the output motor)")
    names = [e.name for e in elements]
    for i, n in enumerate(names):
        if not isinstance(n, str) or not _NAME_RE.match(n):
            raise ParameterError(f"rig.elements[{i}].name", n, "an identifier (letters, digits, underscore)")
    if len(set(names)) != len(names):
        raise ParameterError("rig.elements", names, "unique element names")
    if system.rig.output_transducer not in names[:-1]:
        raise ParameterError("rig.output_transducer", system.rig.output_transducer, f"one of {names[:-1]} (not the motor)")
    if system.motor.mode not in ("pi", "held"):
        raise ParameterError("motor.mode", system.motor.mode, "'pi' or 'held'")
    if system.solver.friction_scheme not in ("fitted", "backward-euler", "trapezoidal"):
        raise ParameterError("solver.friction_scheme", system.solver.friction_scheme,
                             "'fitted', 'backward-euler' or 'trapezoidal'")
    tb = system.effects.transducer_bandwidth
    if tb.enabled and tb.cutoff >= 0.5 * system.solver.output_sample_rate:
        raise ParameterError(
            "effects.transducer_bandwidth.cutoff", tb.cutoff,
            f"a cutoff below half the output sample rate ({0.5 * system.solver.output_sample_rate:g} Hz)",
        )
    return system
