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
    the record's mean torque, then ``amplitude_ramp`` [s] in which the record's
    fluctuation is faded in, then ``settle`` [s] of it at full amplitude (default 0, as in
    the thesis), so that the start-up's own transient has died away when the record begins.
    ``speed`` is the nominal shaft speed [rad/s].

    The fluctuation faded in is the record itself played in a loop, ending where the record
    begins: the loop is the stretch from the record's start, at least half of it long, whose
    end matches the record's first revolution best (:func:`loop_length`), so that the start-up carries the
    record's orders at their own phases and joins it without a jump. The model then enters
    the record in the state the record was taken in. Here we differ from the thesis
    ([thesis] §6.2.1 gives no lead-in detail) and from our first version, which played the
    record backwards: that joins without a jump, but the reversed phases excite the lightly
    damped low-frequency mode of damper and rig, whose transient still ran 0.5 s into the
    record. Driving the model with a noise-free synthetic record of itself at 900 rpm and
    150 N m (``python bench/bench_drive_startup.py --points map_900_150``), the second order
    came back 1.8 N m off (of 45) played backwards, and 0.003 N m with the loop and the
    diagnosis's settling.
    """

    speed: float
    time: np.ndarray = field(repr=False)
    torque_samples: np.ndarray = field(repr=False)
    mean_ramp: float = 0.3
    amplitude_ramp: float = 0.3
    settle: float = 0.0

    def __post_init__(self):
        t = np.asarray(self.time, dtype=float)
        y = np.asarray(self.torque_samples, dtype=float)
        if t.ndim != 1 or y.shape != t.shape or len(t) < 16:
            raise InputError("measured torque: time and torque must be 1-D arrays of equal length >= 16")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
            raise InputError("measured torque contains NaN/inf samples: accepted is finite data")
        if np.any(np.diff(t) <= 0):
            raise InputError("measured torque: time stamps must increase strictly")
        if not (math.isfinite(self.settle) and self.settle >= 0):
            raise InputError(f"settle = {self.settle!r} s: accepted is a finite time >= 0")
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"speed = {self.speed!r} rad/s: accepted is a positive finite speed")
        object.__setattr__(self, "time", t - t[0])
        object.__setattr__(self, "torque_samples", y)
        object.__setattr__(self, "_loop", loop_length(self.time, y, self.speed))

    @property
    def steady_start(self) -> float:
        """Start of the record in the run [s]: the ramps, then ``settle`` at full amplitude."""
        return self.mean_ramp + self.amplitude_ramp + self.settle

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
        # during the start-up, fade in the record's own fluctuation played in a loop that
        # ends where the record begins (class docstring); a record too short for a loop is
        # played backwards instead, which at least joins it without a jump, and forwards
        # again from its start when the lead-in is longer than the record
        if self._loop is not None:
            lead = np.interp(np.mod(t - self.steady_start, self._loop), self.time, self.torque_samples) - mean
        else:
            span = float(self.time[-1])
            back = np.mod(self.steady_start - t, 2.0 * span)
            lead = np.interp(span - np.abs(back - span), self.time, self.torque_samples) - mean
        return np.where(t >= self.steady_start, rec, ramp + env * lead)


def loop_length(time, torque, speed: float) -> float | None:
    """Length [s] of the loop the start-up plays (see :class:`MeasuredTorque`): the lag L,
    between half the record and its end less one revolution, at which the record's stretch
    [L, L + one revolution) matches its first revolution [0, one revolution) best (least
    mean square difference, mean removed). For an engine-like torque, periodic in the
    crank angle, that is a whole number of cycles. None when the record holds fewer than
    four revolutions (no loop with a matching stretch to search).

    time: sample times [s] from 0, strictly increasing (resampled here on their median
    step); torque [N m]; speed: nominal shaft speed [rad/s]."""
    t = np.asarray(time, dtype=float)
    dt = float(np.median(np.diff(t)))
    n = int(t[-1] / dt) + 1
    w = int(round(2.0 * math.pi / speed / dt))  # samples in one revolution
    if w < 4 or n < 4 * w:
        return None
    y = np.interp(np.arange(n) * dt, t, np.asarray(torque, dtype=float))
    y = y - y.mean()
    head = y[:w]
    # sum over the window of (y[l + i] - head[i])^2 for every lag l, via one FFT correlation
    size = 1 << int(math.ceil(math.log2(n + w)))
    corr = np.fft.irfft(np.fft.rfft(y, size) * np.conj(np.fft.rfft(head, size)), size)[: n - w + 1]
    c2 = np.concatenate([[0.0], np.cumsum(y * y)])
    energy = c2[w:] - c2[: n - w + 1]
    mismatch = energy - 2.0 * corr + float(head @ head)
    lo = n // 2
    lag = lo + int(np.argmin(mismatch[lo:]))
    return lag * dt
