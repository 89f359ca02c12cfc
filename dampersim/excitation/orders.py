"""Engine-order excitation with the start-up of [thesis] §6.2.1 (docs/model.md §7)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError


@dataclass(frozen=True)
class OrderSum:
    """T_in(t) = T_mean + sum_k A_k cos(k * speed * t + phase_k) after a start-up.

    Start-up ([thesis] §6.2.1): the mean torque ramps linearly from 0 over
    ``mean_ramp`` [s], then the fluctuation amplitude ramps linearly from 0 over
    ``amplitude_ramp`` [s]; the steady signal follows.

    speed: nominal shaft speed [rad/s]; mean_torque [N m];
    orders: tuple of (order [-], amplitude [N m], phase [rad]); orders may be fractional.
    """

    speed: float
    mean_torque: float
    orders: tuple = ()
    mean_ramp: float = 0.3
    amplitude_ramp: float = 0.3

    def __post_init__(self):
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"speed = {self.speed!r} rad/s: accepted is a positive finite speed")
        if not math.isfinite(self.mean_torque):
            raise InputError(f"mean torque = {self.mean_torque!r} N m: accepted is a finite torque")
        norm = []
        for item in self.orders:
            if len(item) == 2:
                item = (item[0], item[1], 0.0)
            k, a, ph = (float(x) for x in item)
            if not (k > 0 and math.isfinite(k)):
                raise InputError(f"order {k!r}: accepted is a positive order (integer or fractional)")
            if not (a >= 0 and math.isfinite(a)):
                raise InputError(f"order {k:g} amplitude {a!r} N m: accepted is a finite amplitude >= 0")
            if not math.isfinite(ph):
                raise InputError(f"order {k:g} phase {ph!r} rad: accepted is a finite angle")
            norm.append((k, a, ph))
        object.__setattr__(self, "orders", tuple(norm))
        for name in ("mean_ramp", "amplitude_ramp"):
            if not (getattr(self, name) >= 0):
                raise InputError(f"{name} = {getattr(self, name)!r} s: accepted is a duration >= 0")

    @property
    def steady_start(self) -> float:
        """Time [s] from which the signal is steady."""
        return self.mean_ramp + self.amplitude_ramp

    def torque(self, t: np.ndarray) -> np.ndarray:
        """Input torque [N m] at times t [s]."""
        t = np.asarray(t, dtype=float)
        mean = self.mean_torque * (np.clip(t / self.mean_ramp, 0.0, 1.0) if self.mean_ramp > 0 else 1.0)
        if self.amplitude_ramp > 0:
            env = np.clip((t - self.mean_ramp) / self.amplitude_ramp, 0.0, 1.0)
        else:
            env = (t >= self.mean_ramp).astype(float)
        fl = np.zeros_like(t)
        for k, a, ph in self.orders:
            fl += a * np.cos(k * self.speed * t + ph)
        return mean + env * fl

    def order_spec(self) -> OrderSpec:
        """This order sum as plain numbers and arrays, for the solver to evaluate on its
        step grid in one compiled pass (:func:`dampersim.solver.driver.torque_grid`)."""
        return OrderSpec(
            speed=float(self.speed),
            mean_torque=float(self.mean_torque),
            mean_ramp=float(self.mean_ramp),
            amplitude_ramp=float(self.amplitude_ramp),
            orders=np.array([o[0] for o in self.orders], dtype=np.float64),
            amplitudes=np.array([o[1] for o in self.orders], dtype=np.float64),
            phases=np.array([o[2] for o in self.orders], dtype=np.float64),
        )


@dataclass(frozen=True, eq=False)
class OrderSpec:
    """The description of an :class:`OrderSum` the solver reads: speed [rad/s], mean
    torque [N m], ramps [s], and per order its order [-], amplitude [N m] and phase [rad]
    (float64 arrays of equal length)."""

    speed: float
    mean_torque: float
    mean_ramp: float
    amplitude_ramp: float
    orders: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray


def parse_orders(text: str) -> tuple:
    """Parse ``"2:300,4:100@90"`` -> ((2, 300, 0), (4, 100, pi/2)).

    Each item is ORDER:AMPLITUDE_NM with an optional @PHASE_DEG. Raises InputError with
    the offending item and the accepted form.
    """
    form = 'ORDER:AMPLITUDE[@PHASE_DEG] items separated by commas, e.g. "2:300,4:100@90"'
    if text is None or not str(text).strip():
        return ()
    out = []
    seen = set()
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        try:
            head, _, phase = item.partition("@")
            k_s, a_s = head.split(":")
            k, a = float(k_s), float(a_s)
            ph = math.radians(float(phase)) if phase else 0.0
        except ValueError:
            raise InputError(f"--orders item {item!r} is malformed: accepted is {form}") from None
        if not (k > 0 and math.isfinite(k)) or not (a >= 0 and math.isfinite(a)) or not math.isfinite(ph):
            raise InputError(f"--orders item {item!r}: order must be > 0 and amplitude >= 0 N m ({form})")
        if k in seen:
            raise InputError(f"--orders item {item!r}: order {k:g} is given twice")
        seen.add(k)
        out.append((k, a, ph))
    return tuple(out)
