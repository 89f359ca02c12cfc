"""A measured input-torque record as the drive ([thesis] §6.2.1 validation mode)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dampersim.errors import InputError


@dataclass(frozen=True, eq=False)
class MeasuredTorque:
    """Drive the model with a measured torque ``torque`` [N m] sampled at times ``time`` [s].

    As in the thesis, the record is preceded by a start-up: ``mean_ramp`` [s] from 0 to
    the record's mean torque, then ``amplitude_ramp`` [s] in which the fluctuation of the
    record's first samples is faded in. ``speed`` is the nominal shaft speed [rad/s].
    """

    speed: float
    time: np.ndarray = field(repr=False)
    torque_samples: np.ndarray = field(repr=False)
    mean_ramp: float = 0.3
    amplitude_ramp: float = 0.3

    def __post_init__(self):
        t = np.asarray(self.time, dtype=float)
        y = np.asarray(self.torque_samples, dtype=float)
        if t.ndim != 1 or y.shape != t.shape or len(t) < 16:
            raise InputError("measured torque: time and torque must be 1-D arrays of equal length >= 16")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
            raise InputError("measured torque contains NaN/inf samples: accepted is finite data")
        if np.any(np.diff(t) <= 0):
            raise InputError("measured torque: time stamps must increase strictly")
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"speed = {self.speed!r} rad/s: accepted is a positive finite speed")
        object.__setattr__(self, "time", t - t[0])
        object.__setattr__(self, "torque_samples", y)

    @property
    def steady_start(self) -> float:
        return self.mean_ramp + self.amplitude_ramp

    @property
    def duration(self) -> float:
        """Start-up plus record length [s]."""
        return self.steady_start + float(self.time[-1])

    def torque(self, t):
        """Input torque [N m] at times t [s]."""
        t = np.asarray(t, dtype=float)
        mean = float(np.mean(self.torque_samples))
        rec = np.interp(t - self.steady_start, self.time, self.torque_samples)
        ramp = mean * np.clip(t / self.mean_ramp, 0, 1) if self.mean_ramp > 0 else np.full_like(t, mean)
        if self.amplitude_ramp > 0:
            env = np.clip((t - self.mean_ramp) / self.amplitude_ramp, 0, 1)
        else:
            env = (t >= self.mean_ramp).astype(float)
        # during the start-up, fade in the record's own fluctuation, played backwards in
        # time so that it joins the record without a jump at steady_start
        lead = np.interp(self.steady_start - t, self.time, self.torque_samples) - mean
        return np.where(t >= self.steady_start, rec, ramp + env * lead)
