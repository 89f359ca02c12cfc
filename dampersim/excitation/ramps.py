"""Torque ramps for hysteresis loops ([thesis] §3.3.1, Table 3.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError

# name -> (start, positive peak, negative peak, end) [N m], Table 3.1; None = not visited
PROTOCOLS = {
    "full-100": (0.0, 100.0, -100.0, 0.0),
    "full-450": (0.0, 450.0, -180.0, 0.0),
    "full-500": (0.0, 500.0, -200.0, 0.0),
    "pos-100-300": (100.0, 300.0, None, 100.0),
    "neg-50-150": (-50.0, None, -150.0, -50.0),
    "pos-250-350": (250.0, 350.0, None, 250.0),
    "pos-350-450": (350.0, 450.0, None, 350.0),
}


@dataclass(frozen=True)
class TorqueRamp:
    """Piecewise-linear torque through ``points`` [N m] at ``rate`` [N m/s], holding each
    interior point for ``hold`` [s] (the thesis holds the peaks for 2 s).

    speed: nominal shaft speed [rad/s]. ``lead`` [s] of constant start torque first.
    """

    speed: float
    points: tuple
    rate: float = 50.0
    hold: float = 2.0
    lead: float = 0.5

    def __post_init__(self):
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"speed = {self.speed!r} rad/s: accepted is a positive finite speed")
        if len(self.points) < 2 or not all(math.isfinite(p) for p in self.points):
            raise InputError(f"ramp points {self.points!r}: accepted is two or more finite torques [N m]")
        if not (self.rate > 0):
            raise InputError(f"ramp rate {self.rate!r} N m/s: accepted is a positive rate")
        object.__setattr__(self, "points", tuple(float(p) for p in self.points))

    def knots(self):
        """(times [s], torques [N m]) of the piecewise-linear demand."""
        t = [0.0, self.lead]
        y = [self.points[0], self.points[0]]
        for i in range(1, len(self.points)):
            dt = abs(self.points[i] - self.points[i - 1]) / self.rate
            t.append(t[-1] + dt)
            y.append(self.points[i])
            if i < len(self.points) - 1 and self.hold > 0:
                t.append(t[-1] + self.hold)
                y.append(self.points[i])
        t.append(t[-1] + self.lead)
        y.append(self.points[-1])
        return np.array(t), np.array(y)

    @property
    def duration(self) -> float:
        """Total length of the protocol [s]."""
        return float(self.knots()[0][-1])

    def torque(self, t):
        """Demanded torque [N m] at times t [s]."""
        kt, ky = self.knots()
        return np.interp(np.asarray(t, dtype=float), kt, ky)


def ramp_protocol(name: str, speed: float, rate: float = 50.0, hold: float = 2.0) -> TorqueRamp:
    """A Table 3.1 protocol by name (see PROTOCOLS) at ``speed`` [rad/s]."""
    if name not in PROTOCOLS:
        raise InputError(f"protocol {name!r}: accepted is one of {', '.join(PROTOCOLS)}")
    start, pos, neg, end = PROTOCOLS[name]
    pts = [start] + [p for p in (pos, neg) if p is not None] + [end]
    if start != 0.0:
        # the model starts unloaded ([thesis] §3.3.1): ramp up to the start torque first
        # and hold there before the loop itself
        pts = [0.0] + pts
    return TorqueRamp(speed=speed, points=tuple(pts), rate=rate, hold=hold)
