"""Resampling: channels recorded on different time bases brought onto one uniform time base.

A rig file keeps each channel group on its own clock: torque at 20 kHz, speed at 1 kHz,
flange angles at 10 kHz, each starting and ending at its own time. The campaign wants one
``time_s`` column. :func:`common_time_base` builds a uniform base over the overlap of all
channels and brings each channel onto it:

* **down-sampling** (channel rate above the new rate): a zero-phase Butterworth low pass
  of order :data:`FILTER_ORDER` (``scipy.signal.sosfiltfilt``, so magnitude squared:
  effectively order 24, no phase shift between channels) at :data:`CUTOFF_FRACTION` x the
  new rate removes what would alias, then the filtered signal is interpolated. Every tone
  at or above the new Nyquist frequency (0.5 x the new rate, 1.25 x the cut-off) is
  suppressed by at least 46 dB, from 0.6 x the new rate by 84 dB; up to 0.25 x the new rate
  the gain is within 0.001 % of 1, up to 0.3 x within 0.1 % (4 % off at 0.35 x): choose a
  rate of at least 3.3 x the highest frequency of interest.
* **up-sampling or the same rate**: interpolation only. A channel up-sampled from rate fs
  holds nothing above fs / 2; the note says so, for the reader to check against the
  highest order of interest (order 8 at the highest speed).

Interpolation is cubic convolution (Keys, a = -1/2) on the channel's own uniform grid: four
neighbouring samples, third-order accurate (Keys' boundary condition at the ends). Linear interpolation would do for channels
sampled far above the highest order of interest, but loses up to 0.8 % of a tone at 4 % of
the channel's rate (order 8 at 6000 rpm sampled at 20 kHz); cubic convolution loses 0.01 %
there. Where the new instants coincide with the channel's samples (same rate,
same start) the samples are copied unchanged.

NaN samples (drop-outs) are kept as NaN, never bridged: each output sample that depends on a
NaN input is NaN (the two neighbours either side for interpolation; for a filtered channel
also :data:`GUARD_PERIODS` periods of the cut-off either side of a NaN burst, where the
filter's response to the burst's edge has not yet decayed below 1e-4). The importer drops
the test points NaN reaches.
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.errors import InputError
from dampersim.signal import sample_rate_from_time

#: Butterworth order of the anti-aliasing low pass (run forwards and backwards): the
#: lowest order that keeps 40 dB (46.6 dB) at the new Nyquist frequency with the cut-off at
#: 0.4 x the new rate.
FILTER_ORDER = 12
#: Cut-off of the anti-aliasing low pass as a fraction of the new sample rate: 0.4 leaves
#: 0.1 x the rate of transition band below the new Nyquist frequency.
CUTOFF_FRACTION = 0.4
#: NaN is widened by this many periods of the cut-off around a NaN burst in a filtered
#: channel: the order-12 filter's impulse response is below 1e-4 of its peak after 12.
GUARD_PERIODS = 12.0
#: Relative difference of two rates treated as the same rate (no anti-aliasing filter):
#: the default rate is rounded to 4 significant digits, at most 0.05 % off the channel's.
SAME_RATE_TOLERANCE = 1e-3
#: Significant digits of the default rate (19999.7 Hz -> 20000 Hz, 10240 Hz stays).
RATE_DIGITS = 4
#: Output samples interpolated per block (bounds the memory of long recordings).
BLOCK = 1 << 20


def nice_rate(rate_hz: float) -> float:
    """``rate_hz`` [Hz] rounded to :data:`RATE_DIGITS` significant digits."""
    return float(f"{float(rate_hz):.{RATE_DIGITS}g}")


def _channel(target, pair):
    """(t0 [s], rate [Hz], values, t_end [s]) of one series, checked."""
    try:
        t, x = pair
    except (TypeError, ValueError):
        raise InputError(f"{target}: accepted is a pair (time stamps [s], values)") from None
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or x.ndim != 1 or t.size != x.size:
        raise InputError(f"{target}: {t.size} time stamps and {x.size} values (shapes {t.shape}, {x.shape}); "
                         "accepted are two 1-D arrays of the same length")
    if t.size < 2:
        raise InputError(f"{target}: {t.size} samples; accepted are at least 2")
    try:
        rate = sample_rate_from_time(t)
    except InputError as exc:
        raise InputError(f"{target}: {exc}") from None
    return float(t[0]), rate, x, float(t[-1])


def _finite_runs(mask):
    """(start, stop) index pairs of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def lowpass(x, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Butterworth low pass (order :data:`FILTER_ORDER`, run forwards and
    backwards) of ``x`` sampled at ``rate_hz`` [Hz], cut-off ``cutoff_hz`` [Hz] (-6 dB
    there, the magnitude being squared). Values in x's unit.

    NaN bursts stay NaN and are widened by :data:`GUARD_PERIODS` periods of the cut-off on
    each side; each finite stretch between them is filtered on its own, and one too short
    to filter (fewer samples than scipy's edge padding needs) becomes NaN as well. Ends are
    padded by odd extension over :data:`GUARD_PERIODS` periods of the cut-off."""
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(x, dtype=float)
    if not 0 < cutoff_hz < rate_hz / 2:
        raise InputError(f"cut-off {cutoff_hz!r} Hz: accepted is 0 < cut-off < rate / 2 = {rate_hz / 2:g} Hz")
    sos = butter(FILTER_ORDER, cutoff_hz, fs=rate_hz, output="sos")
    guard = int(math.ceil(GUARD_PERIODS * rate_hz / cutoff_hz))
    shortest = 3 * (2 * len(sos) + 1)  # scipy's default edge padding

    def zero_phase(y):  # odd extension over the filter's response length: clean ends
        return sosfiltfilt(sos, y, padlen=min(guard, y.size - 1))

    finite = np.isfinite(x)
    if finite.all():
        return zero_phase(x)
    out = np.full_like(x, np.nan)
    for a, b in _finite_runs(finite):
        if b - a > shortest:
            out[a:b] = zero_phase(x[a:b])
    for a, b in _finite_runs(~finite):
        out[max(a - guard, 0):b + guard] = np.nan
    return out


def cubic_at(x, t0: float, rate_hz: float, t_new) -> np.ndarray:
    """Cubic-convolution interpolation (Keys, a = -1/2) of ``x`` sampled at
    ``t0 + i / rate_hz`` [s] onto times ``t_new`` [s] inside that span. Output in x's unit.

    A NaN among the four samples an output depends on makes it NaN; instants that fall on
    a sample (to 1e-9 of a step) copy it. Beyond the ends Keys' boundary condition adds one
    sample each side (3 x0 - 3 x1 + x2), which keeps the third-order accuracy there."""
    x = np.asarray(x, dtype=float)
    t_new = np.asarray(t_new, dtype=float)
    n = x.size
    if n >= 3:
        xp = np.concatenate(([3 * x[0] - 3 * x[1] + x[2]], x, [3 * x[-1] - 3 * x[-2] + x[-3]]))
    else:
        xp = np.concatenate((x[:1], x, x[-1:]))
    out = np.empty(t_new.size)
    for lo in range(0, t_new.size, BLOCK):
        u = np.clip((t_new[lo:lo + BLOCK] - t0) * rate_hz, 0.0, n - 1.0)
        i = np.minimum(np.floor(u).astype(np.int64), max(n - 2, 0))
        s = u - i
        near = np.rint(u)
        on_sample = np.abs(u - near) < 1e-9
        s2, s3 = s * s, s * s * s
        w = ((-s3 + 2 * s2 - s) / 2, (3 * s3 - 5 * s2 + 2) / 2, (-3 * s3 + 4 * s2 + s) / 2, (s3 - s2) / 2)
        y = np.zeros(u.size)
        for k, wk in zip((0, 1, 2, 3), w):  # xp[i + k] is x[i + k - 1]
            y += wk * xp[np.minimum(i + k, n + 1)]
        y[on_sample] = x[near[on_sample].astype(np.int64)]
        out[lo:lo + BLOCK] = y
    return out


def common_time_base(series, rate_hz: float | None = None):
    """Bring channels of different time bases onto one uniform time base.

    Args:
        series: ``{target: (t, x)}``: per channel its time stamps ``t`` [s] (uniform,
            strictly increasing; any start) and values ``x`` (any unit, NaN allowed).
        rate_hz: rate of the common base [Hz]; None takes the highest channel rate
            rounded to 4 significant digits (:func:`nice_rate`).

    Returns:
        ``(t, {target: x}, note)``: the uniform time stamps [s] over the overlap of all
        channels (from the latest start to the earliest end), each channel on them (its
        own unit; NaN where a NaN burst reaches), and one human-readable line saying what
        was done to each channel, for the import report.

    Raises:
        InputError: no channels; a channel with mismatched or too few samples; time stamps
            not finite, not strictly increasing or not uniform (a step more than 0.1 % off
            the mean step); channels that do not overlap in time; a bad ``rate_hz``.
    """
    if not series:
        raise InputError("no channels to resample; accepted is {target: (t [s], values)} with at least one channel")
    chans = {target: _channel(target, pair) for target, pair in series.items()}
    start = max(c[0] for c in chans.values())
    end = min(c[3] for c in chans.values())
    if not end > start:
        spans = ", ".join(f"{k} {c[0]:.6g}-{c[3]:.6g} s" for k, c in chans.items())
        raise InputError(f"the channels do not overlap in time ({spans}); accepted are channels recorded together")
    if rate_hz is None:
        rate = nice_rate(max(c[1] for c in chans.values()))
        how = "the highest channel rate"
    else:
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            rate = math.nan
        if not (math.isfinite(rate) and rate > 0):
            raise InputError(f"rate_hz = {rate_hz!r}: accepted is a positive sample rate in Hz")
        how = "as asked"
    n = int(math.floor((end - start) * rate * (1 + 1e-12))) + 1
    if n < 2:
        raise InputError(f"the channels overlap for only {end - start:.6g} s, less than one step at {rate:g} Hz; "
                         "accepted is an overlap of at least two samples")
    t = start + np.arange(n) / rate
    out, parts = {}, []
    for target, (t0, fs, x, _t1) in chans.items():
        if fs > rate * (1 + SAME_RATE_TOLERANCE):
            fc = CUTOFF_FRACTION * rate
            y = cubic_at(lowpass(x, fs, fc), t0, fs, t)
            what = (f"{fs:.6g} Hz, low-pass (zero-phase Butterworth order {FILTER_ORDER}, cut-off {fc:.6g} Hz) "
                    "then cubic interpolation")
        elif fs < rate * (1 - SAME_RATE_TOLERANCE):
            y = cubic_at(x, t0, fs, t)
            what = f"{fs:.6g} Hz, up-sampled by cubic interpolation (holds nothing above {fs / 2:.6g} Hz)"
        else:
            y = cubic_at(x, t0, fs, t)
            what = f"{fs:.6g} Hz, same rate" + (", copied" if abs((start - t0) * fs - round((start - t0) * fs)) < 1e-9
                                                  else ", cubic interpolation onto the common instants")
        nan = int(np.count_nonzero(~np.isfinite(y)))
        if nan:
            what += f"; {nan} samples NaN (drop-outs kept)"
        out[target] = y
        parts.append(f"{target} {what}")
    note = (f"common time base {rate:.6g} Hz ({how}) over {start:.6g}-{t[-1]:.6g} s, the overlap of "
            f"{len(chans)} channels, {n} samples: " + "; ".join(parts))
    return t, out, note


__all__ = ["FILTER_ORDER", "CUTOFF_FRACTION", "GUARD_PERIODS", "SAME_RATE_TOLERANCE", "nice_rate", "lowpass",
           "cubic_at", "common_time_base"]
