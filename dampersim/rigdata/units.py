"""Unit conversion of rig channels into the campaign's units, from an explicit table of spellings.

A rig file states each channel's unit as text ("Nm", "kN m", "1/min", "rad/s", "°" ...).
:data:`UNITS` lists every spelling we accept, by quantity, with the factor that turns a
value in that unit into the quantity's campaign unit:

=========  ==============  ==============================================================
quantity   campaign unit   accepted spellings (factor)
=========  ==============  ==============================================================
torque     N m             N m, Nm, N*m, N.m, N·m (1); kN m, kNm, kN*m, kN.m, kN·m (1000)
speed      rpm             rpm, 1/min, min-1, min^-1, U/min (1); rad/s (60 / 2 pi);
                           Hz, rev/s (60): a speed in Hz is revolutions per second
angle      deg             deg, °, degree, degrees (1); rad (180 / pi)
time       s               s (1); ms (1e-3)
=========  ==============  ==============================================================

Spellings are matched after trimming blanks, dropping one pair of enclosing square
brackets ("[Nm]") and collapsing inner blanks, ignoring case ("NM", "RPM" and "Rad/S" are
accepted; the table has no two spellings that differ only in case). Anything else is
refused with an :class:`~dampersim.errors.InputError` that names the channel, the unit and
the accepted spellings: a wrong guess at a unit would silently scale a whole campaign.

The campaign columns (:data:`TARGETS`) each have one quantity; :func:`convert` brings a
channel's values into the column's unit and then applies an optional calibration
``gain`` and ``offset`` (both in the column's unit).
"""

from __future__ import annotations

import math
import re

import numpy as np

from dampersim.errors import InputError
from dampersim.units import DEG_TO_RAD, RPM_TO_RAD_S

#: quantity -> (campaign unit, {spelling: factor to the campaign unit}).
UNITS = {
    "torque": ("N m", {
        "N m": 1.0, "Nm": 1.0, "N*m": 1.0, "N.m": 1.0, "N·m": 1.0,
        "kN m": 1e3, "kNm": 1e3, "kN*m": 1e3, "kN.m": 1e3, "kN·m": 1e3,
    }),
    "speed": ("rpm", {
        "rpm": 1.0, "1/min": 1.0, "min-1": 1.0, "min^-1": 1.0, "U/min": 1.0,
        "rad/s": 1.0 / RPM_TO_RAD_S,
        "Hz": 60.0, "rev/s": 60.0,
    }),
    "angle": ("deg", {
        "deg": 1.0, "°": 1.0, "degree": 1.0, "degrees": 1.0,
        "rad": 1.0 / DEG_TO_RAD,
    }),
    "time": ("s", {"s": 1.0, "ms": 1e-3}),
}

#: campaign column -> quantity. The first four are required in every campaign time
#: series, the angles only by ramps (windup_deg, or both flange angles); time_s is the
#: time base (readers convert their time stamps with it).
TARGETS = {
    "input_torque_nm": "torque",
    "output_torque_nm": "torque",
    "input_speed_rpm": "speed",
    "output_speed_rpm": "speed",
    "input_flange_deg": "angle",
    "output_flange_deg": "angle",
    "windup_deg": "angle",
    "time_s": "time",
}

_FACTORS = {q: {s.casefold(): f for s, f in table.items()} for q, (_u, table) in UNITS.items()}


def normalise_unit(unit) -> str:
    """A unit string as matched against the table: trimmed, one pair of enclosing square
    brackets dropped, inner blanks collapsed to one, case folded. ``None`` gives ""."""
    text = "" if unit is None else str(unit).strip()
    if len(text) >= 2 and text[0] == "[" and text[-1] == "]":
        text = text[1:-1].strip()
    return re.sub(r"\s+", " ", text).casefold()


def quantity_of(unit) -> str | None:
    """The quantity ("torque", "speed", "angle", "time") a unit spelling belongs to, or
    None when the table does not know it (empty units included)."""
    key = normalise_unit(unit)
    for quantity, factors in _FACTORS.items():
        if key in factors:
            return quantity
    return None


def accepted_units(quantity: str) -> str:
    """The accepted spellings of ``quantity``'s units, for messages."""
    return ", ".join(repr(s) for s in UNITS[quantity][1])


def target_quantity(target: str) -> str:
    """The quantity of a campaign column (see :data:`TARGETS`); InputError for others."""
    try:
        return TARGETS[target]
    except KeyError:
        raise InputError(f"target {target!r}: accepted is one of {', '.join(TARGETS)}") from None


def target_unit(target: str) -> str:
    """The campaign unit of a column ("N m", "rpm", "deg" or "s")."""
    return UNITS[target_quantity(target)][0]


def unit_factor(unit, target: str, channel: str = "") -> float:
    """Factor turning values in ``unit`` into ``target``'s campaign unit.

    ``channel`` (the rig's channel name) only goes into the message of the InputError
    raised when ``unit`` is not an accepted spelling of ``target``'s quantity.
    """
    quantity = target_quantity(target)
    factor = _FACTORS[quantity].get(normalise_unit(unit))
    if factor is None:
        what = f"channel {channel!r}" if channel else "channel"
        other = quantity_of(unit)
        found = f" (a {other} unit)" if other else ""
        raise InputError(
            f"{what} for {target}: unit {unit!r}{found} cannot be converted to {quantity} "
            f"[{UNITS[quantity][0]}]; accepted units are {accepted_units(quantity)} "
            "(a map file's 'unit = ...' overrides the file's unit)"
        )
    return factor


def check_calibration(gain, offset, where: str = "") -> tuple[float, float]:
    """``(gain, offset)`` as floats: gain finite and non-zero, offset finite (bools are
    refused: ``gain = true`` in a map file is a typo, not 1)."""
    out = []
    for name, value, nonzero in (("gain", gain, True), ("offset", offset, False)):
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
        x = float(value) if ok else math.nan
        if not (math.isfinite(x) and (x != 0.0 or not nonzero)):
            accepted = "a finite non-zero number" if nonzero else "a finite number"
            raise InputError(f"{where}{name} = {value!r}: accepted is {accepted}")
        out.append(x)
    return out[0], out[1]


def convert(values, unit, target: str, gain: float = 1.0, offset: float = 0.0, channel: str = "") -> np.ndarray:
    """Values of a rig channel in ``target``'s campaign unit.

    Args:
        values: samples in ``unit`` (array-like of numbers; NaN stays NaN).
        unit: the channel's unit as text, one of :data:`UNITS`' spellings for the
            target's quantity.
        target: campaign column (:data:`TARGETS`), e.g. ``"input_torque_nm"``.
        gain: calibration factor applied after the unit conversion [dimensionless].
        offset: added after the gain, in the target's unit (N m, rpm, deg or s).
        channel: the channel's name, for error messages only.

    Returns:
        float64 array ``gain * values * factor(unit) + offset`` [target's unit].

    Raises:
        InputError: ``unit`` not convertible to the target's quantity (the message names
            channel, unit and the accepted units); bad gain or offset.
    """
    factor = unit_factor(unit, target, channel)
    g, o = check_calibration(gain, offset, f"channel {channel!r}: " if channel else "")
    x = np.asarray(values, dtype=float)
    return x * (factor * g) + o


__all__ = ["UNITS", "TARGETS", "normalise_unit", "quantity_of", "accepted_units", "target_quantity", "target_unit",
           "unit_factor", "check_calibration", "convert"]
