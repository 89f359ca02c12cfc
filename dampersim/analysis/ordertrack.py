"""Order tracking: engine-order amplitudes and phases of a signal on the measured shaft angle.

:func:`dampersim.signal.order_amplitudes` reads orders from a time-domain spectrum at one
nominal speed. On a rig the shaft speed drifts during a record and ripples slowly, so an
order's frequency moves: its energy spreads over neighbouring bins and the ripple's sidebands
fall onto the neighbouring orders. Order tracking removes both: the signal is resampled onto
a uniform grid of the shaft angle and transformed over a whole number N of revolutions, where
order k is exactly bin k * N whatever the speed did.

What the angle must follow is the motion the excitation is locked to. A rig's input
dynamometer generates the orders against time at the set speed's order frequencies; the
speed channel, measured on the damper's input side, also carries the damper's own torsional
vibration at those orders (tens of rpm). An angle integrated from that instantaneous speed
phase-modulates every order by the vibration and moves content between orders (order 2's
sidebands land on orders 4 and 0, order 4's on 2 and 6, ...). The speed is therefore
low-passed first: a Butterworth filter of order LOWPASS_ORDER run forwards and backwards
(zero phase), its cut-off at LOWPASS_SHARE of the lowest analysed order's frequency at the
record's mean speed (of the lowest half order when half orders are read). The drift of the
mean speed and a slow ripple below the cut-off pass and are tracked; vibration at the
analysed orders (at least twice the cut-off) is attenuated 250-fold or more.

Method, units SI inside (angle [rad], speed [rad/s], time [s]; rpm only in messages):

1. angle = cumulative trapezoidal integral of the low-passed speed (or a measured angle
   channel as given), its constant set so that it agrees on average over the record with
   the integral of the unfiltered speed, which is 0 at the first sample; interpolated
   linearly onto the signal's time stamps;
2. N = the largest whole number of revolutions in the record (a multiple of 2 when half
   orders are asked for, so that they are whole bins too), centred in the record;
3. the signal is interpolated onto M samples per revolution with a cubic spline of signal
   against angle, M at least as dense as the time samples at the record's lowest speed;
4. mean removed, periodic Hann window over the N revolutions, FFT; order k is bin k * N,
   read coherently: amplitude = 2 |X| / sum(window), phase = arg X referred to angle 0.

A component ``A cos(k angle + phase)`` comes back as (A, phase) with no leakage, because it
completes exactly k * N periods in the window; the Hann window only keeps what is not an
order (noise, non-synchronous components) from leaking into the order bins.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from dampersim.errors import InputError
from dampersim.signal import DEFAULT_ORDERS

#: Fewest whole revolutions an order spectrum is taken over.
MIN_REVOLUTIONS = 4
#: Order bins read are at least this many bins apart (the Hann main lobe half width), so a
#: record must hold 2 / (smallest order spacing) revolutions.
MIN_BINS_APART = 2
#: Lowest accepted speed in the record, relative to its mean: below it the shaft stopped or
#: ran up, which is not a steady test point.
MIN_SPEED_SHARE = 0.5
#: Largest denominator of fractional orders (2: half orders, 4: quarter orders).
MAX_ORDER_DENOMINATOR = 4
#: Fewest samples accepted.
MIN_SAMPLES = 16
#: Cut-off of the speed low-pass as a share of the lowest analysed order's frequency at the
#: record's mean speed: the lowest order lies one octave above it (attenuated 1 / (1 + 2^8)
#: by LOWPASS_ORDER forwards and backwards), while a slow ripple at 0.3 of it keeps 98 %.
LOWPASS_SHARE = 0.5
#: Order of the Butterworth speed low-pass (applied forwards and backwards: zero phase).
LOWPASS_ORDER = 4


@dataclass(frozen=True)
class TrackedOrders:
    """Order spectrum of one signal on the shaft angle.

    orders: engine orders read; amplitudes [unit of the signal, N m for a torque];
    phases [rad], in (-pi, pi], of ``amplitude * cos(order * angle + phase)`` with angle 0 at
    the first sample of the speed channel (or the angle channel's own zero); revolutions:
    whole revolutions analysed, beginning at angle ``start`` [rad]; mean_speed [rad/s] over
    them.
    """

    orders: np.ndarray = field(repr=False)
    amplitudes: np.ndarray = field(repr=False)
    phases: np.ndarray = field(repr=False)
    revolutions: int
    start: float
    mean_speed: float

    @property
    def complex(self) -> np.ndarray:
        """Complex order amplitudes ``amplitude * exp(1j * phase)``."""
        return self.amplitudes * np.exp(1j * self.phases)


def _rpm(omega) -> str:
    return f"{omega:.6g} rad/s = {omega * 30.0 / math.pi:.6g} rpm"


def _array(x, name: str, what: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: accepted is a 1-D array of {what}: {exc}") from exc
    if arr.ndim != 1 or arr.size < MIN_SAMPLES:
        raise InputError(f"{name}: accepted is a 1-D array of at least {MIN_SAMPLES} {what}, got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise InputError(f"{name}: {bad.size} NaN/inf samples (first at index {bad[0]}); accepted are finite {what}")
    return arr


def _time(t, n: int, name: str) -> np.ndarray:
    t = _array(t, "time", "time stamps [s]")
    if t.size != n:
        raise InputError(f"time has {t.size} stamps but {name} has {n} samples; they must match")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise InputError(f"time: stamps must increase strictly; t[{bad[0] + 1}] does not come after t[{bad[0]}]")
    return t


def check_speed(speed, channel: str = "speed") -> np.ndarray:
    """``speed`` [rad/s] as a float array fit for order tracking, else an :class:`InputError`
    naming ``channel``: accepted is a finite speed above 0 at every sample and above
    MIN_SPEED_SHARE of the record's mean (a shaft that stops, reverses or runs up has no
    steady order spectrum)."""
    try:
        w = np.asarray(speed, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"speed channel {channel!r}: accepted is a 1-D array of speeds: {exc}") from exc
    if w.ndim != 1 or w.size < MIN_SAMPLES:
        raise InputError(f"speed channel {channel!r}: accepted is a 1-D array of at least {MIN_SAMPLES} samples, "
                         f"got shape {w.shape}")
    accepted = ("accepted for order tracking is a finite, positive shaft speed at every sample, "
                f"nowhere below {MIN_SPEED_SHARE:.0%} of the record's mean")
    bad = np.flatnonzero(~np.isfinite(w))
    if bad.size:
        raise InputError(f"speed channel {channel!r}: {bad.size} NaN/inf samples (first at index {bad[0]}); {accepted}")
    bad = np.flatnonzero(w <= 0)
    if bad.size:
        raise InputError(f"speed channel {channel!r}: {bad.size} samples are zero or negative (first at index "
                         f"{bad[0]}: {_rpm(w[bad[0]])}); {accepted}")
    mean = float(np.mean(w))
    low = np.flatnonzero(w < MIN_SPEED_SHARE * mean)
    if low.size:
        raise InputError(f"speed channel {channel!r}: {low.size} samples below {MIN_SPEED_SHARE:.0%} of the mean "
                         f"{_rpm(mean)} (first at index {low[0]}: {_rpm(w[low[0]])}); {accepted}")
    return w


def _integral(t, w) -> np.ndarray:
    return np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))))


@functools.lru_cache(maxsize=512)
def _lowpass_sos(cutoff_hz: float, fs: float) -> np.ndarray:
    """Second-order sections of the LOWPASS_ORDER Butterworth low-pass with its cut-off at
    ``cutoff_hz`` [Hz] for sampling at ``fs`` [Hz], read-only (callers filter with a copy). Kept
    per (cut-off, rate): a diagnosis tracks every model run of a point on the same record, and
    designing the filter each time took about 1.2 ms, more than filtering a record of 5 000
    samples (about 0.4 ms). Up to 512 designs are kept, a few hundred bytes each."""
    from scipy.signal import butter  # scipy loads only when an order track runs

    sos = butter(LOWPASS_ORDER, cutoff_hz, fs=fs, output="sos")
    sos.setflags(write=False)
    return sos


def low_passed_speed(time, speed, cutoff_hz: float, channel: str = "speed") -> np.ndarray:
    """``speed`` [rad/s] at ``time`` [s] through the zero-phase Butterworth low-pass
    (LOWPASS_ORDER, forwards and backwards) with its cut-off at ``cutoff_hz`` [Hz]. Filtered
    on a uniform grid over the record (the time stamps' own when uniform)."""
    w = check_speed(speed, channel)
    t = _time(time, w.size, f"speed channel {channel!r}")
    fs = (t.size - 1) / (t[-1] - t[0])
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise InputError(f"speed channel {channel!r}: low-pass cut-off {cutoff_hz!r} Hz; accepted is a cut-off "
                         f"above 0 and below the Nyquist frequency {0.5 * fs:.6g} Hz")
    grid = np.linspace(t[0], t[-1], t.size)
    sos = _lowpass_sos(float(cutoff_hz), float(fs)).copy()  # scipy's filter takes a writable buffer
    from scipy.signal import sosfiltfilt  # scipy loads only when an order track runs

    smooth = sosfiltfilt(sos, np.interp(grid, t, w), padlen=min(t.size - 1, 3 * (2 * len(sos) + 1)))
    return np.interp(t, grid, smooth)


def shaft_angle(time, speed, channel: str = "speed", cutoff_hz: float | None = None) -> np.ndarray:
    """Shaft angle [rad] at ``time`` [s] from the measured ``speed`` [rad/s] there: the
    cumulative trapezoidal integral, 0 at the first sample. With ``cutoff_hz`` [Hz], the
    integral of :func:`low_passed_speed`, shifted to agree on average over the record with
    the unfiltered integral (so angle 0 stays at the first sample, but for the vibration)."""
    w = check_speed(speed, channel)
    t = _time(time, w.size, f"speed channel {channel!r}")
    raw = _integral(t, w)
    if cutoff_hz is None:
        return raw
    th = _integral(t, low_passed_speed(t, w, cutoff_hz, channel))
    return th + float(np.mean(raw - th))


def lowpass_cutoff(orders, mean_speed: float, share: float = LOWPASS_SHARE) -> float:
    """Cut-off [Hz] of the speed low-pass for tracking ``orders`` at ``mean_speed`` [rad/s]:
    ``share`` of the lowest order's frequency (see the module docstring)."""
    if not 0.0 < share < 1.0:
        raise InputError(f"low-pass share {share!r}: accepted is a share above 0 and below 1 of the lowest "
                         "order's frequency (None: no low-pass)")
    orders, _ = _orders(orders)
    return share * float(np.min(orders)) * mean_speed / (2.0 * math.pi)


def tracking_angle(time, speed, orders=DEFAULT_ORDERS, share: float | None = LOWPASS_SHARE,
                   channel: str = "speed") -> np.ndarray:
    """Shaft angle [rad] to track ``orders`` on: :func:`shaft_angle` of ``speed`` [rad/s]
    low-passed at :func:`lowpass_cutoff` of the record's mean speed; ``share`` None
    integrates the unfiltered speed."""
    w = check_speed(speed, channel)
    t = _time(time, w.size, f"speed channel {channel!r}")
    if share is None:
        return shaft_angle(t, w, channel)
    mean_speed = float(_integral(t, w)[-1] / (t[-1] - t[0]))
    return shaft_angle(t, w, channel, lowpass_cutoff(orders, mean_speed, share))


def _orders(orders) -> tuple:
    """(orders array, denominator q): positive distinct orders, each a multiple of 1/q."""
    arr = np.atleast_1d(np.asarray(orders, dtype=float))
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr) & (arr > 0)):
        raise InputError(f"orders: accepted is a non-empty list of positive engine orders (e.g. 1, 2, 2.5), got {orders!r}")
    if np.unique(arr).size != arr.size:
        raise InputError(f"orders must not repeat an order, got {arr.tolist()}")
    for q in range(1, MAX_ORDER_DENOMINATOR + 1):
        if np.all(np.abs(arr * q - np.round(arr * q)) < 1e-9):
            return arr, q
    raise InputError(f"orders {arr.tolist()}: accepted are whole orders and fractions with denominator up to "
                     f"{MAX_ORDER_DENOMINATOR} (half orders 0.5, 1.5, ...; quarter orders 0.25, ...)")


def track_orders(x, time, angle, orders=DEFAULT_ORDERS, revolutions: int | None = None,
                 channel: str = "angle", start: float | None = None) -> TrackedOrders:
    """Order amplitudes and phases of ``x`` sampled at ``time`` [s] with the shaft at ``angle``
    [rad] (same length; strictly increasing, from a speed channel through :func:`shaft_angle`
    or an angle channel unwrapped). See the module docstring for the method.

    orders: engine orders (whole, half or quarter orders); revolutions: the whole number of
    revolutions to analyse, default the most the record holds (a multiple of the orders'
    denominator); start: the angle [rad] where they begin, default centred in the record (pass
    another analysis's ``start`` and ``revolutions`` to read a second signal of the same record,
    e.g. a simulation driven by it, over exactly the same revolutions; that window may reach
    up to one sample beyond this signal's ends). channel names the angle's source in error
    messages.

    Raises InputError (naming ``channel``) for an angle that does not increase, a record too
    short to hold the revolutions the orders need (the larger of MIN_REVOLUTIONS and
    MIN_BINS_APART / smallest order spacing), an order at or above the Nyquist frequency at the
    record's highest speed.
    """
    x = _array(x, "signal", "samples")
    t = _time(time, x.size, "the signal")
    th = _array(angle, f"angle of {channel!r}", "shaft angles [rad]")
    if th.size != x.size:
        raise InputError(f"angle of {channel!r} has {th.size} samples but the signal has {x.size}; they must match")
    d = np.diff(th)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        raise InputError(f"angle of {channel!r} does not increase at index {bad[0] + 1}: accepted is a shaft turning "
                         "forwards at every sample (speed > 0)")
    orders, q = _orders(orders)
    spacing = float(np.min(np.diff(np.concatenate(([0.0], np.sort(orders))))))
    need = max(MIN_REVOLUTIONS, math.ceil(MIN_BINS_APART / spacing - 1e-9))
    need = q * math.ceil(need / q)
    held = (th[-1] - th[0]) / (2.0 * math.pi)
    mean_speed = (th[-1] - th[0]) / (t[-1] - t[0])
    if revolutions is None:
        n_rev = q * int(math.floor(held / q + 1e-9))
    else:
        n_rev = int(revolutions)
        if n_rev != revolutions or n_rev % q or (start is None and n_rev > held + 1e-9):
            raise InputError(f"revolutions = {revolutions!r}: accepted is a whole multiple of {q} of at most the "
                             f"{held:.3g} revolutions the record holds")
    if n_rev < need:
        raise InputError(
            f"{channel!r}: the record holds {held:.3g} revolutions ({t[-1] - t[0]:.3g} s at {_rpm(mean_speed)}); "
            f"order tracking of orders {', '.join(f'{k:g}' for k in orders)} needs at least {need} whole "
            f"revolutions: accepted is a record of at least {need} revolutions "
            f"({need * 2 * math.pi / mean_speed:.3g} s at that speed)")
    fs = (x.size - 1) / (t[-1] - t[0])
    w_max = float(np.max(d / np.diff(t)))
    k_max = float(np.max(orders))
    if k_max * w_max / (2.0 * math.pi) >= 0.5 * fs:
        raise InputError(f"order {k_max:g} reaches {k_max * w_max / (2 * math.pi):.1f} Hz at the record's highest "
                         f"speed ({_rpm(w_max)}), at or above the Nyquist frequency {0.5 * fs:.1f} Hz; drop that "
                         "order or sample faster")
    from scipy.fft import next_fast_len  # scipy loads only when an order track runs
    from scipy.interpolate import CubicSpline

    # samples per revolution: at least as dense as the time samples at the lowest speed
    per_rev = next_fast_len(max(int(math.ceil(2.0 * math.pi / float(np.min(d)))), int(4 * k_max)))
    if start is None:
        start = th[0] + 0.5 * (held - n_rev) * 2.0 * math.pi
    else:
        start, step = float(start), float(np.max(d))
        if not (th[0] - step <= start and start + 2.0 * math.pi * n_rev <= th[-1] + step):
            raise InputError(f"{channel!r}: revolutions {start / (2 * math.pi):.4g} to "
                             f"{start / (2 * math.pi) + n_rev:.4g} are not inside this signal's "
                             f"{th[0] / (2 * math.pi):.4g} to {th[-1] / (2 * math.pi):.4g}: accepted is a window "
                             "within the signal, give or take one sample")
    grid = start + (2.0 * math.pi / per_rev) * np.arange(n_rev * per_rev)
    xs = CubicSpline(th, x)(grid)
    xs -= xs.mean()
    win = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(xs.size) / xs.size)
    spec = np.fft.rfft(xs * win) * (2.0 / win.sum())
    c = spec[np.round(orders * n_rev).astype(int)] * np.exp(-1j * orders * start)
    t_a, t_b = np.interp([start, start + 2.0 * math.pi * n_rev], th, t)
    return TrackedOrders(orders=orders, amplitudes=np.abs(c), phases=np.angle(c), revolutions=n_rev, start=start,
                         mean_speed=2.0 * math.pi * n_rev / float(t_b - t_a))


def track_orders_by_speed(x, time, speed, orders=DEFAULT_ORDERS, speed_time=None, revolutions: int | None = None,
                          channel: str = "speed", start: float | None = None,
                          share: float | None = LOWPASS_SHARE) -> TrackedOrders:
    """:func:`track_orders` on :func:`tracking_angle` of a measured ``speed`` [rad/s]
    (low-passed at ``share`` of the lowest order's frequency; None: unfiltered).

    speed is sampled at ``speed_time`` [s] (default: ``time``, the signal's own stamps); a
    signal sampled on another time base (a simulation driven by the record) is analysed where
    the two overlap, its angle interpolated linearly from the speed channel's.
    """
    if speed_time is None:
        th = tracking_angle(time, speed, orders, share, channel)
        return track_orders(x, time, th, orders, revolutions, channel, start)
    ts = np.asarray(speed_time, dtype=float)
    th = tracking_angle(ts, speed, orders, share, channel)
    x = _array(x, "signal", "samples")
    t = _time(time, x.size, "the signal")
    inside = (t >= ts[0]) & (t <= ts[-1])
    if np.count_nonzero(inside) < MIN_SAMPLES:
        raise InputError(f"speed channel {channel!r} covers {ts[0]:.6g}-{ts[-1]:.6g} s, which holds fewer than "
                         f"{MIN_SAMPLES} of the signal's samples ({t[0]:.6g}-{t[-1]:.6g} s): accepted is a speed "
                         "channel spanning the signal's time")
    return track_orders(x[inside], t[inside], np.interp(t[inside], ts, th), orders, revolutions, channel, start)


__all__ = ["TrackedOrders", "MIN_REVOLUTIONS", "LOWPASS_SHARE", "LOWPASS_ORDER", "check_speed", "low_passed_speed",
           "shaft_angle", "lowpass_cutoff", "tracking_angle", "track_orders", "track_orders_by_speed"]
