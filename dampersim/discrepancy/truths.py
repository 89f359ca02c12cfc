"""Harder truths for synthetic campaigns: random effect shapes, effect pairs and changes the
effect library does not contain.

The diagnosis fits one parameter per effect, its magnitude
(:data:`dampersim.discrepancy.effects.EFFECTS`), and keeps the other parameters at the
library's defaults. A truth that uses those defaults is an easy problem. Here a truth
effect gets its shape parameters drawn within :data:`SHAPE_RANGES` (narrower than the
parameters' ``lo``/``hi`` validation bounds, which admit anything numerically valid), its
magnitude at one of :data:`LEVELS`, and a campaign may hide two effects at once.

Truths outside the library (:data:`OUT_OF_LIBRARY`) change what neither the library nor
the calibration (:data:`dampersim.discrepancy.diagnose.CALIBRATION`) can reach: a rig
shaft or inertia, the shape of the Makkar friction law ([thesis] §5.4), the friction
split of the inner set, the output motor's speed control. A correct diagnosis names no
library effect for them. Controls (:data:`CONTROLS`) change only what the calibration
can absorb, or rig parts whose modes lie far above the orders read.

Every builder returns a JSON-ready dict ``{"effects": [[name, {param: value}], ...],
"updates": {dotted name: value}, "description": text}`` for
:func:`dampersim.discrepancy.synth.synthesize` (``effects``, ``updates``).
"""

from __future__ import annotations

import math

from dampersim.discrepancy.diagnose import CALIBRATION
from dampersim.discrepancy.effects import info, parameters_of
from dampersim.errors import InputError
from dampersim.parameters import default_parameters
from dampersim.parameters.io import flat_values

#: magnitude levels of a truth effect: the library's weak, typical, strong ones and a
#: subtler one below weak (:func:`magnitude_at`)
LEVELS = ("subtle", "weak", "typical", "strong")

#: the subtle level of the effects whose magnitude value falls as the effect grows; the
#: others use half the weak value. Clutch capacity: the largest campaign torque peak is
#: about 840 N m (500 N m mean plus 340 N m of 2nd order), the weak 620 N m clips about
#: 220 N m of it, 720 N m about half that. Transducer cut-off: the amplitude loss at a
#: frequency f well below the cut-off fc is about (f/fc)^2 / 2, half the weak 400 Hz loss
#: at 400 sqrt(2) = 566 Hz, rounded to 600 Hz.
SUBTLE = {"clutch_slip": 720.0, "transducer_bandwidth": 600.0}

#: ranges [low, high] of the shape parameters drawn uniformly for a truth effect, with the
#: reasons (effects missing here have no shape parameter worth varying)
SHAPE_RANGES = {
    # production absorbers are tuned 2-10 % above their order to stay stable at large
    # swing; track tolerances move the tuning a few per cent either way. Damping 0.005-0.08
    # N m s/rad is a damping ratio of about 1-13 % for 0.001 kg m^2 at order 2, 1500 rpm
    "pendulum_absorber": {"order": (1.9, 2.2), "damping": (0.005, 0.08)},
    # slip speed: the friction of a closing clutch builds up over 5 mrad/s (dry-like
    # onset) to 0.1 rad/s (soft, wet onset); the oil film drags 5-60 N m s/rad; cover and
    # pump make 45-75 % of the lumped primary inertia
    "clutch_slip": {"slip_speed": (0.005, 0.1), "viscous": (5.0, 60.0), "drive_inertia_fraction": (0.45, 0.75)},
    # the short springs engage at 0.05-0.15 rad of inner windup (3-9 deg), inside the
    # 15 deg travel, reached at about 120-360 N m; 1-3 of the 5 pairs are short
    "inner_short_springs": {"clearance": (0.05, 0.15), "count": (1, 3)},
}

#: two-effect truths: pairs with different signatures, and pairs that overlap (the
#: absorber and the clutch both cut output orders; preload and radial transfer both add
#: friction)
PAIRS = (
    ("pendulum_absorber", "spring_preload"),
    ("turbine_drag", "inner_short_springs"),
    ("clutch_slip", "transducer_bandwidth"),
    ("output_backlash", "nested_radial_transfer"),
    ("pendulum_absorber", "clutch_slip"),
    ("spring_preload", "nested_radial_transfer"),
)

OUT_OF_LIBRARY = ("rig_shaft", "rig_inertia", "friction_shape", "friction_split", "motor_control")
CONTROLS = ("none", "calibration", "rig_stiff_parts")

#: friction-law shapes of the out-of-library truth (factors on the Makkar parameters,
#: [thesis] Eq. 27: gamma1 Stribeck level, gamma2/gamma5 rise rates, gamma3 Stribeck decay,
#: gamma4 Coulomb level, gamma6 viscous slope [s/m]). Sliding speeds of the coils are of
#: the order of 0.1-1 m/s in the torsional points.
FRICTION_SHAPES = {
    # a pronounced static hump that decays slowly: stiction carries over to higher speeds
    "stribeck": {"gamma1": (1.5, 2.5), "gamma3": (0.2, 0.5)},
    # a wet contact: lower Coulomb level, viscous slope 0.1-0.3 s/m (10-100x the default)
    "viscous": {"gamma4": (0.7, 0.9), "gamma6": (10.0, 30.0)},
    # friction builds up over 0.03-0.1 m/s instead of 0.01 m/s: a soft stick-slip transition
    "soft_onset": {"gamma2": (0.1, 0.3), "gamma5": (0.1, 0.3)},
}


def magnitude_at(name: str, level: str) -> float:
    """Magnitude value of effect ``name`` at ``level`` (one of :data:`LEVELS`)."""
    e = info(name)
    if level not in LEVELS:
        raise InputError(f"level {level!r}: accepted is one of {', '.join(LEVELS)}")
    if level != "subtle":
        return float(e.magnitudes[LEVELS.index(level) - 1])
    return float(SUBTLE[name]) if not e.grows else 0.5 * float(e.magnitudes[0])


def random_shape(name: str, rng) -> dict:
    """Shape parameters of effect ``name`` drawn from :data:`SHAPE_RANGES` ({} if none);
    whole-number parameters (``count``) drawn as integers."""
    kinds = {p["name"]: type(p["default"]) for p in parameters_of(name)}
    out = {}
    for par, (lo, hi) in SHAPE_RANGES.get(name, {}).items():
        if kinds[par] is int:
            out[par] = int(rng.integers(int(lo), int(hi) + 1))
        else:
            out[par] = float(rng.uniform(lo, hi))
    return out


def effect_truth(name: str, level: str, rng, shape: bool = True) -> list:
    """``[name, {magnitude, shape...}]`` of a truth effect at ``level``, its shape drawn
    from ``rng`` (library defaults without ``shape``)."""
    values = random_shape(name, rng) if shape else {}
    values[info(name).magnitude] = magnitude_at(name, level)
    return [name, values]


def _text(values: dict) -> str:
    return ", ".join(f"{k}={v:.4g}" for k, v in values.items())


def single(name: str, level: str, rng, shape: bool = True) -> dict:
    """A truth hiding effect ``name`` at ``level`` with a random shape."""
    eff = effect_truth(name, level, rng, shape)
    return {"effects": [eff], "updates": {}, "description": f"{name} ({level}) {_text(eff[1])}"}


def pair(a: str, b: str, rng, level: str = "typical") -> dict:
    """A truth hiding effects ``a`` and ``b``, both at ``level`` with random shapes."""
    if a == b:
        raise InputError(f"effect pair {a}+{b}: accepted are two different effects")
    effs = [effect_truth(a, level, rng), effect_truth(b, level, rng)]
    return {"effects": effs, "updates": {}, "description": f"{a} {_text(effs[0][1])} + {b} {_text(effs[1][1])} ({level})"}


def _element(base, name: str):
    for e in base.rig.elements:
        if e.name == name:
            return e
    raise InputError(f"rig element {name!r}: not in the parameter set ({', '.join(e.name for e in base.rig.elements)})")


def _factor(rng, lo: float, hi: float) -> float:
    """1 + or - U(lo, hi), the sign at random."""
    return float(1.0 + (1 if rng.uniform() < 0.5 else -1) * rng.uniform(lo, hi))


def out_of_library(kind: str, rng, base=None) -> dict:
    """A truth outside the effect library and the calibration's reach (:data:`OUT_OF_LIBRARY`):

    * ``rig_shaft``: the gearbox shaft (the rig's softest, 10.5 kN m/rad, its mode in the
      measured band) 20-30 % stiffer or softer: a different gearbox or shaft;
    * ``rig_inertia``: the gearbox inertia 20-30 % larger or smaller;
    * ``friction_shape``: the Makkar law of another shape (:data:`FRICTION_SHAPES`);
    * ``friction_split``: the inner set's housing friction carried 20-35 % (or 65-80 %) by
      J_sec instead of half and half;
    * ``motor_control``: the output motor's PI gains both scaled by 0.5-0.7 or 1.5-2.0 (a
      retuned drive).
    """
    base = base or default_parameters()
    flat = flat_values(base)
    if kind == "rig_shaft":
        f = _factor(rng, 0.2, 0.3)
        upd = {"rig.elements.gearbox.shaft_stiffness": _element(base, "gearbox").shaft_stiffness * f}
        text = f"gearbox shaft stiffness x{f:.3f}"
    elif kind == "rig_inertia":
        f = _factor(rng, 0.2, 0.3)
        upd = {"rig.elements.gearbox.inertia": _element(base, "gearbox").inertia * f}
        text = f"gearbox inertia x{f:.3f}"
    elif kind == "friction_shape":
        shape = list(FRICTION_SHAPES)[int(rng.integers(len(FRICTION_SHAPES)))]
        upd = {f"friction.{g}": float(flat[f"friction.{g}"]) * float(rng.uniform(lo, hi))
               for g, (lo, hi) in FRICTION_SHAPES[shape].items()}
        text = f"friction law shape {shape}"
    elif kind == "friction_split":
        a = float(rng.uniform(0.2, 0.35) if rng.uniform() < 0.5 else rng.uniform(0.65, 0.8))
        upd = {"friction.alpha_sec": a, "friction.alpha_ter": 1.0 - a}
        text = f"inner-set friction split {a:.2f}/{1 - a:.2f}"
    elif kind == "motor_control":
        f = float(rng.uniform(0.5, 0.7) if rng.uniform() < 0.5 else rng.uniform(1.5, 2.0))
        upd = {"motor.proportional_gain": base.motor.proportional_gain * f, "motor.integral_gain": base.motor.integral_gain * f}
        text = f"output motor PI gains x{f:.2f}"
    else:
        raise InputError(f"out-of-library truth {kind!r}: accepted is one of {', '.join(OUT_OF_LIBRARY)}")
    return {"effects": [], "updates": upd, "description": text}


def control(kind: str, rng, base=None) -> dict:
    """A truth with no missing effect (:data:`CONTROLS`):

    * ``none``: only the synthesis's usual perturbation of the estimated parameters;
    * ``calibration``: one or two calibration groups off by 10-30 % (factors 0.70-0.90 or
      1.10-1.30, inside the calibration's factor range 1/2 to 2);
    * ``rig_stiff_parts``: the stiff rig shafts (flanges, transducer, coupling; 1.5-2.5
      MN m/rad, modes above 1 kHz, far above order 8 at 2800 rpm, 373 Hz) 10-20 % off and
      the output motor inertia 5-10 % off (held by its speed control).
    """
    base = base or default_parameters()
    flat = flat_values(base)
    if kind == "none":
        return {"effects": [], "updates": {}, "description": "no effect"}
    if kind == "calibration":
        groups = list(CALIBRATION)
        pick = rng.choice(len(groups), size=int(rng.integers(1, 3)), replace=False)
        upd, parts = {}, []
        for k in sorted(int(i) for i in pick):
            f = _factor(rng, 0.1, 0.3)
            for name in CALIBRATION[groups[k]]:
                upd[name] = float(flat[name]) * f
            parts.append(f"{groups[k]} x{f:.3f}")
        return {"effects": [], "updates": upd, "description": "calibration " + ", ".join(parts)}
    if kind == "rig_stiff_parts":
        upd = {}
        for e in base.rig.elements[1:-1]:
            upd[f"rig.elements.{e.name}.shaft_stiffness"] = e.shaft_stiffness * _factor(rng, 0.1, 0.2)
        last = base.rig.elements[-1]
        upd[f"rig.elements.{last.name}.inertia"] = last.inertia * _factor(rng, 0.05, 0.1)
        return {"effects": [], "updates": upd, "description": "stiff rig parts and motor inertia"}
    raise InputError(f"control {kind!r}: accepted is one of {', '.join(CONTROLS)}")


def true_magnitude(truth: dict, name: str) -> float | None:
    """Magnitude value of effect ``name`` in a truth dict (None if it is not hidden there)."""
    for n, values in truth.get("effects", ()):
        if n == name:
            v = values.get(info(name).magnitude)
            return None if v is None or not math.isfinite(float(v)) else float(v)
    return None


__all__ = ["LEVELS", "SUBTLE", "SHAPE_RANGES", "PAIRS", "OUT_OF_LIBRARY", "CONTROLS", "FRICTION_SHAPES",
           "magnitude_at", "random_shape", "effect_truth", "single", "pair", "out_of_library", "control",
           "true_magnitude"]
