"""Test points and test-point grids for speed / mean-torque sweeps.

A sweep is a list of :class:`TestPoint` (speed [rad/s], mean torque [N m], excitation
orders). The rig tests of the thesis step the speed by 10 rpm so that FFT colourmaps need
no interpolation ([thesis] §3.3.2); :func:`parse_range` reads such ranges the way engineers
write them ("900:2800:10", rpm) and converts them to rad/s, the unit the library works in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError
from dampersim.units import rad_s_to_rpm, rpm_to_rad_s
from dampersim.excitation import OrderSum, parse_orders

#: Speeds accepted in sweeps [rpm] (the same limits as ``dampersim simulate --speed``).
MIN_RPM, MAX_RPM = 300.0, 6000.0
#: Mean torques accepted in sweeps [N m] (the same limit as ``dampersim simulate``).
MAX_ABS_TORQUE = 5000.0
#: Largest number of values one range may expand to (guards against a mistyped step).
MAX_RANGE_VALUES = 100_000

_RANGE_FORM = (
    "a value, a comma-separated list, or START:STOP:STEP with an inclusive STOP "
    '(e.g. "1500", "1200,1500,1800" or "900:2800:10")'
)


@dataclass(frozen=True)
class TestPoint:
    """One steady test point of a sweep.

    speed: shaft speed [rad/s] (from rpm: ``rpm * 2 pi / 60``, see :func:`parse_range`);
    mean_torque: mean input torque [N m];
    orders: excitation as a tuple of (engine order [-], amplitude [N m], phase [rad]);
    ``(order, amplitude)`` pairs get phase 0. Values are normalised to floats so that equal
    points compare (and hash into the result cache) equal however they were built.
    """

    __test__ = False  # the name starts with "Test": keep pytest from collecting it

    speed: float
    mean_torque: float
    orders: tuple = ()

    def __post_init__(self):
        try:
            speed = float(self.speed)
            torque = float(self.mean_torque)
        except (TypeError, ValueError):
            raise InputError(
                f"test point speed {self.speed!r} rad/s / mean torque {self.mean_torque!r} N m: "
                "accepted are numbers"
            ) from None
        if not (math.isfinite(speed) and speed > 0):
            raise InputError(f"test point speed = {speed!r} rad/s: accepted is a positive finite speed")
        if not math.isfinite(torque):
            raise InputError(f"test point mean torque = {torque!r} N m: accepted is a finite torque")
        orders = _normalise_orders(self.orders)
        object.__setattr__(self, "speed", speed)
        object.__setattr__(self, "mean_torque", torque)
        object.__setattr__(self, "orders", orders)

    @property
    def speed_rpm(self) -> float:
        """Shaft speed [rpm]."""
        return float(rad_s_to_rpm(self.speed))

    def excitation(self):
        """The :class:`dampersim.OrderSum` that drives this test point (with the start-up
        ramps of [thesis] §6.2.1)."""

        return OrderSum(speed=self.speed, mean_torque=self.mean_torque, orders=self.orders)


def _normalise_orders(orders) -> tuple:
    """Orders as a tuple of (order, amplitude [N m], phase [rad]) floats; a string is parsed
    with :func:`dampersim.excitation.parse_orders` ("2:300,4:100@90")."""
    if orders is None:
        return ()
    if isinstance(orders, str):
        return parse_orders(orders)
    out = []
    seen = set()
    try:
        items = list(orders)
    except TypeError:
        raise InputError(
            f"orders {orders!r}: accepted is a sequence of (order, amplitude N m[, phase rad]) "
            'or a string like "2:300,4:100"'
        ) from None
    for item in items:
        try:
            vals = [float(v) for v in item]
        except (TypeError, ValueError):
            vals = []
        if len(vals) == 2:
            vals.append(0.0)
        if len(vals) != 3:
            raise InputError(
                f"excitation order {item!r}: accepted is (order, amplitude N m) or "
                "(order, amplitude N m, phase rad)"
            )
        k, a, ph = vals
        if not (math.isfinite(k) and k > 0):
            raise InputError(f"excitation order {k!r}: accepted is a positive order (integer or fractional)")
        if not (math.isfinite(a) and a >= 0):
            raise InputError(f"order {k:g} amplitude {a!r} N m: accepted is a finite amplitude >= 0")
        if not math.isfinite(ph):
            raise InputError(f"order {k:g} phase {ph!r} rad: accepted is a finite angle")
        if k in seen:
            raise InputError(f"excitation order {k:g} is given twice")
        seen.add(k)
        out.append((k, a, ph))
    return tuple(out)


def _number(part, item, option, unit):
    try:
        value = float(part)
    except (TypeError, ValueError):
        raise InputError(
            f"{option} {_shown(item)}: {_shown(part)} is not a number in {unit}; accepted is {_RANGE_FORM}"
        ) from None
    if not math.isfinite(value):
        raise InputError(f"{option} {_shown(item)}: accepted are finite numbers in {unit}")
    return value


def _range_parts(item, option, unit):
    """(start, stop, step) of a "START:STOP:STEP" item, or None for a single value."""
    parts = item.split(":")
    if len(parts) == 1:
        return None
    if len(parts) != 3:
        raise InputError(
            f"{option} {_shown(item)} is malformed ({len(parts)} fields separated by ':'); "
            f"accepted is {_RANGE_FORM}"
        )
    start, stop, step = (_number(p.strip(), item, option, unit) for p in parts)
    if step <= 0:
        raise InputError(f"{option} {_shown(item)}: the step must be > 0 {unit}")
    if stop < start:
        raise InputError(f"{option} {_shown(item)}: STOP ({stop:g}) is below START ({start:g}); accepted is START <= STOP")
    return start, stop, step


def _range_count(start, stop, step) -> float:
    """Values of an inclusive range, from its numbers alone (inf when too many to count)."""
    q = (stop - start) / step
    if not math.isfinite(q) or q > 1e15:
        return math.inf
    return float(math.floor(q + 1e-9) + 1)


def _shown(item) -> str:
    """An item for a message: its repr, shortened when long."""
    text = str(item)
    return repr(text) if len(text) <= 60 else repr(text[:57]) + f"… ({len(text)} characters)"


def count_values(text, option="--torque", unit="N m") -> float:
    """How many values ``text`` (see :func:`parse_values`) expands to, computed from each
    item's START, STOP and STEP without building any array (inf when uncountable).
    Raises InputError for malformed text, as :func:`parse_values`."""
    if text is None or not str(text).strip():
        raise InputError(f"{option}: no value given; accepted is {_RANGE_FORM}")
    total = 0.0
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            raise InputError(f"{option} {_shown(text)}: empty list item; accepted is {_RANGE_FORM}")
        parts = _range_parts(item, option, unit)
        if parts is None:
            _number(item, item, option, unit)
            total += 1
        else:
            total += _range_count(*parts)
    return total


def parse_values(text, option="--torque", unit="N m", limit=MAX_RANGE_VALUES) -> tuple:
    """Expand a value, a list or an inclusive range into a tuple of floats (unit unchanged).

    Accepted: ``"200"``, ``"100,200,300"`` and ``"START:STOP:STEP"`` (STOP included when
    it lies on the step grid, within 1e-9 of a step); list items may themselves be ranges.
    Values are computed as ``START + i * STEP`` (no accumulated rounding). ``option`` and
    ``unit`` only phrase the error messages. The count of every item is computed from its
    numbers first (:func:`count_values`): a text whose items add up to more than ``limit``
    values is refused before any value is built.

    Raises:
        InputError: empty or malformed text, non-finite numbers, STEP <= 0, STOP < START,
            or more than ``limit`` values in all (default 100 000).
    """
    count = count_values(text, option, unit)
    if count > limit:
        shown = "more than 1e15" if not math.isfinite(count) else f"{count:.0f}"
        raise InputError(
            f"{option} {_shown(text)} expands to {shown} values; at most {limit} are accepted "
            "(check the step)"
        )
    values: list[float] = []
    for item in str(text).split(","):
        item = item.strip()
        parts = _range_parts(item, option, unit)
        if parts is None:
            values.append(_number(item, item, option, unit))
            continue
        start, stop, step = parts
        count = int(_range_count(start, stop, step))
        # round away the binary noise of start + i * step (e.g. 0.1 steps), keeping ~15 digits
        grid = start + step * np.arange(count)
        scale = max(abs(start), abs(stop), step)
        decimals = max(0, 12 - int(math.floor(math.log10(scale))) if scale > 0 else 12)
        values.extend(float(v) for v in np.round(grid, decimals))
    return tuple(values)


def parse_range(text) -> np.ndarray:
    """Speeds given in rpm (``"900:2800:10"``, ``"1500"`` or ``"1200,1500"``) -> rad/s.

    The end of a range is inclusive: ``"900:2800:10"`` gives the 191 speeds of a thesis
    colourmap sweep, 10 rpm apart ([thesis] §3.3.2). Every speed must lie within
    300-6000 rpm. The conversion is explicit: rad/s = rpm * 2 pi / 60.

    Returns:
        1-D float array of speeds [rad/s], in the order given.

    Raises:
        InputError: malformed text (the message shows the accepted forms), a step <= 0,
            STOP < START, or a speed outside 300-6000 rpm.
    """
    rpm = parse_values(text, option="--speeds", unit="rpm")
    for value in rpm:
        if not (MIN_RPM <= value <= MAX_RPM):
            raise InputError(
                f"--speeds {text!r}: {value:g} rpm is outside the accepted {MIN_RPM:g} to {MAX_RPM:g} rpm"
            )
    return np.array([rpm_to_rad_s(v) for v in rpm], dtype=float)


def parse_torques(text) -> tuple:
    """Mean torques [N m] from ``"200"``, ``"50,200"`` or ``"50:500:50"`` (inclusive end);
    each within +-5000 N m."""
    values = parse_values(text, option="--torque", unit="N m")
    for value in values:
        if abs(value) > MAX_ABS_TORQUE:
            raise InputError(f"--torque {text!r}: {value:g} N m is outside the accepted +-{MAX_ABS_TORQUE:g} N m")
    return values


def make_grid(speeds, mean_torques, orders=()) -> tuple:
    """All combinations speeds x mean torques with one excitation.

    Args:
        speeds: shaft speeds [rad/s] (e.g. from :func:`parse_range`); a scalar is allowed.
        mean_torques: mean input torques [N m]; a scalar is allowed.
        orders: (order, amplitude [N m], phase [rad]) tuples or a string "2:300,4:100".

    Returns:
        Tuple of :class:`TestPoint`, mean torque in the outer loop and speed in the inner
        loop, so each torque level is a contiguous speed sweep (a colourmap, [thesis] §3.3.2).

    Raises:
        InputError: no speeds or no torques, or an invalid speed, torque or order.
    """
    speeds = np.atleast_1d(np.asarray(speeds, dtype=float))
    torques = np.atleast_1d(np.asarray(mean_torques, dtype=float))
    if speeds.ndim != 1 or speeds.size == 0:
        raise InputError("a sweep needs at least one speed [rad/s]")
    if torques.ndim != 1 or torques.size == 0:
        raise InputError("a sweep needs at least one mean torque [N m]")
    norm = _normalise_orders(orders)
    return tuple(TestPoint(float(w), float(tq), norm) for tq in torques for w in speeds)


def speed_sweep(rpm_range="900:2800:10", mean_torque=200.0, orders="2:300") -> tuple:
    """Convenience: a speed sweep at one mean torque [N m], speeds given in rpm as text
    (see :func:`parse_range`). The defaults are the thesis's 900-2800 rpm range in 10 rpm
    steps ([thesis] §3.3.2)."""
    return make_grid(parse_range(rpm_range), [mean_torque], orders)


__all__ = [
    "TestPoint",
    "count_values",
    "parse_values",
    "parse_range",
    "parse_torques",
    "make_grid",
    "speed_sweep",
    "MIN_RPM",
    "MAX_RPM",
]
