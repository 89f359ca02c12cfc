"""The effect library: candidate physics the thesis's model leaves out.

Each effect is a frozen dataclass in ``DamperSystem.effects`` (see
:mod:`dampersim.parameters.model`), off by default, with its own parameters, units and
bounds; the kernel implements it (:mod:`dampersim.solver.kernels.effects`).
This module holds what an engineer needs to judge a candidate: the physical cause, the
signature it leaves in measurements, and which parameter sets its magnitude (the one
the diagnosis fits).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from dampersim.errors import InputError
from dampersim.parameters import model as m
from dampersim.parameters import with_updates


@dataclass(frozen=True)
class EffectInfo:
    """Registry entry of one effect.

    name: stable identifier (``effects.<name>`` in parameter files);
    cls: its parameter dataclass; magnitude: the parameter fitted by the diagnosis;
    grows: True when a larger magnitude value means a larger effect;
    magnitudes: three typical values (weak, typical, strong) used by synthetic tests;
    description, cause, signature: text for reports and ``effects --json``.
    """

    name: str
    cls: type
    magnitude: str
    grows: bool
    magnitudes: tuple
    description: str
    cause: str
    signature: str


EFFECTS = {
    e.name: e
    for e in (
        EffectInfo(
            "clutch_slip", m.ClutchSlip, "capacity", False, (620.0, 540.0, 470.0),
            "Lock-up clutch of finite capacity between the input and J_pri",
            "The lock-up clutch closes the converter by friction between the cover and a "
            "piston plate. Its capacity is the clamp force times friction coefficient, "
            "plate radius and surface count; when the torque it has to pass (mean plus the "
            "fluctuation not absorbed by the cover and pump inertia) exceeds that capacity "
            "it slips, and an oil film adds drag proportional to slip speed. The thesis "
            "suspected this slip behind the windup creep at a held peak torque ([thesis] "
            "§6.3.2).",
            "Only at high mean torque with large fluctuation: output order amplitudes fall "
            "below the model (the clutch clips torque peaks), lower orders first; hysteresis "
            "windup (input flange to output) creeps while a high torque is held; no change "
            "at low torque.",
        ),
        EffectInfo(
            "output_backlash", m.OutputBacklash, "free_play", True, (0.015, 0.03, 0.06),
            "Free play in the transmission output (first rig shaft after J_ter)",
            "Spline and gear clearances in the transmission input shaft or gearbox leave an "
            "angular free play in which no torque passes. It matters only when the shaft "
            "torque changes sign.",
            "Ramps: a flat step of the free play in the windup where the torque crosses "
            "zero; torsional points: extra higher orders (rattle) only at low mean torque "
            "where the output torque reverses; nothing at high mean torque.",
        ),
        EffectInfo(
            "inner_short_springs", m.InnerShortSprings, "stiffness", True, (120.0, 240.0, 480.0),
            "Shorter inner-of-pair springs in some nested pairs: a third stiffness stage",
            "In some nested pairs the inner spring is shorter than its slot ([thesis] §5.1, "
            "the smaller damper), so it only starts to carry torque once the inner set has "
            "wound up by the clearance. Until then those pairs work with their outer spring "
            "alone: the inner set's first stage is softer than with full-length pairs, and it "
            "stiffens in a third stage beyond the clearance.",
            "Changes at low torque too: below the clearance windup the inner set is softer "
            "than with full-length pairs only (with the defaults, 2 of 5 pairs short: 1920 "
            "instead of 2400 N m/rad), so it winds up more and its resonances move down. "
            "Above the clearance (high mean torque) the short springs join and the set "
            "stiffens by count x stiffness (back to 2400 N m/rad with the default 240 N m/rad, "
            "stiffer than full-length pairs with a stiffer short spring): resonances move up "
            "again; hysteresis loops show a third slope at high torque.",
        ),
        EffectInfo(
            "turbine_drag", m.TurbineDrag, "coefficient", True, (1.5, 3.0, 6.0),
            "Hydrodynamic drag torque on J_sec against the housing",
            "Oil in the closed converter couples the turbine (J_sec) to the housing and pump: "
            "with the lock-up closed the relative speed is the damper's oscillation, and the "
            "fluid transmits a drag torque roughly proportional to it, in parallel to the "
            "outer springs.",
            "Viscous path across the outer set: output amplitudes rise with excitation "
            "frequency (high orders, high speed) where the springs isolate well; resonance "
            "peaks flatten; independent of mean torque.",
        ),
        EffectInfo(
            "pendulum_absorber", m.PendulumAbsorber, "inertia", True, (0.0005, 0.001, 0.002),
            "Centrifugal pendulum absorber on J_sec tuned to an engine order",
            "Pendulum masses on the turbine side swing in curved tracks; the centrifugal "
            "field makes their natural frequency proportional to speed, so they absorb one "
            "engine order at every speed (here linearised, small swing).",
            "The tuned order's output amplitude drops at all speeds and torques; neighbouring "
            "orders change little; the effect does not depend on mean torque.",
        ),
        EffectInfo(
            "nested_radial_transfer", m.NestedRadialTransfer, "fraction", True, (0.3, 0.6, 1.0),
            "Inner spring's radial force loads the outer spring of each nested pair",
            "The inner spring of a nested pair lies inside the outer one ([thesis] §5.3.2): "
            "its centrifugal and redirection forces push it against the outer spring's coils, "
            "which pass them on to the housing, raising the outer spring's friction.",
            "More friction in the inner set, growing with speed squared: output amplitudes "
            "differ most at high speed and high torque where the inner set works alone; "
            "loops are wider at high speed.",
        ),
        EffectInfo(
            "spring_preload", m.SpringPreload, "force", True, (8.0, 15.0, 30.0),
            "Radial preload on the arc springs",
            "Arc springs are wound straight and bent into the housing or pre-curved with a "
            "different radius: they press on the race even at standstill, adding a "
            "speed-independent normal force to the centrifugal one.",
            "More friction at every speed, relatively most at low speed where the "
            "centrifugal force is small: at low speed the damper transmits more of the "
            "higher orders (springs stick); loops are wider at low speed.",
        ),
        EffectInfo(
            "transducer_bandwidth", m.TransducerBandwidth, "cutoff", False, (400.0, 250.0, 150.0),
            "Low-pass of the output torque transducer chain",
            "The torque transducer, its amplifier and anti-alias filter have a finite "
            "bandwidth; a first-order low pass attenuates and delays the measured output "
            "torque.",
            "Output amplitudes reduced by 1/sqrt(1 + (f/fc)^2) at every point: grows with "
            "order times speed, independent of mean torque; no change to loops at 10 Hz.",
        ),
    )
}

NAMES = tuple(EFFECTS)


def info(name: str) -> EffectInfo:
    """Registry entry of ``name``; unknown names raise InputError listing the valid ones."""
    if name not in EFFECTS:
        raise InputError(f"effect {name!r}: accepted is one of {', '.join(NAMES)}")
    return EFFECTS[name]


def parameters_of(name: str) -> list[dict]:
    """Parameters of effect ``name`` as ``[{name, unit, default, min, max, doc}]`` (not ``enabled``)."""
    out = []
    for f in dataclasses.fields(info(name).cls):
        if f.name == "enabled":
            continue
        meta = f.metadata
        out.append({
            "name": f.name,
            "unit": meta.get("unit", "-"),
            "default": f.default,
            "min": meta.get("lo"),
            "max": meta.get("hi"),
            "doc": meta.get("doc", ""),
        })
    return out


def describe(name: str) -> dict:
    """JSON-ready description of effect ``name`` (the ``effects --json`` item)."""
    e = info(name)
    return {
        "name": e.name,
        "description": e.description,
        "cause": e.cause,
        "signature": e.signature,
        "magnitude_parameter": e.magnitude,
        "parameters": parameters_of(name),
    }


def catalogue() -> list[dict]:
    """Every effect as :func:`describe` returns it."""
    return [describe(n) for n in NAMES]


def parse_effect_spec(text: str) -> tuple[str, dict]:
    """``"NAME[:param=value,...]"`` -> (name, {param: float}); values checked by the
    parameter validation when applied."""
    name, _, rest = str(text).partition(":")
    name = name.strip()
    info(name)
    known = {p["name"]: p for p in parameters_of(name)}
    values = {}
    for item in filter(None, (x.strip() for x in rest.split(","))):
        if "=" not in item:
            raise InputError(f"--effect {text!r}: accepted is NAME[:param=value,...], e.g. clutch_slip:capacity=450")
        key, val = (x.strip() for x in item.split("=", 1))
        if key not in known:
            raise InputError(f"--effect {name}: parameter {key!r}: accepted is one of {', '.join(known)}")
        try:
            values[key] = float(val)
        except ValueError:
            raise InputError(f"--effect {name}:{key}={val!r}: accepted is a number in {known[key]['unit']}") from None
    return name, values


def with_effect(system, name: str, values: dict | None = None, enabled: bool = True):
    """``system`` with effect ``name`` switched on (or off) and its parameters set."""

    info(name)
    updates = {f"effects.{name}.enabled": enabled}
    for k, v in (values or {}).items():
        updates[f"effects.{name}.{k}"] = v
    return with_updates(system, updates)


def clip_to_range(v: float, meta: dict) -> float:
    """v inside a parameter's accepted range (``meta`` from :func:`parameters_of`; an open lower
    bound above 0 is kept just above it)."""
    lo, hi = meta["min"], meta["max"]
    if lo is not None:
        v = max(v, lo * 1.0001 if lo > 0 else v)
    if hi is not None:
        v = min(v, hi)
    return float(v)


def clip_magnitude(name: str, m: float) -> float:
    """Magnitude ``m`` of effect ``name`` kept inside its parameter's accepted range (an
    open lower bound of 0 kept strictly positive)."""
    e = info(name)
    meta = next(p for p in parameters_of(name) if p["name"] == e.magnitude)
    return clip_to_range(m, meta) if meta["min"] is None or meta["min"] > 0 else max(clip_to_range(m, meta), 1e-12)


def enabled_effects(system) -> list[str]:
    """Names of the effects switched on in ``system``."""
    return [n for n in NAMES if getattr(system.effects, n).enabled]


__all__ = ["EffectInfo", "EFFECTS", "NAMES", "info", "parameters_of", "describe", "catalogue",
           "parse_effect_spec", "with_effect", "clip_to_range", "clip_magnitude", "enabled_effects"]
