"""Mains pick-up on the output torque channel, as an uncertainty of the order cells it falls on.

A rig's torque amplifiers pick up the mains (50 or 60 Hz and its harmonics) with a phase of
their own in every record. Where a mains line falls on an engine order (50 Hz is order 2 at
1500 rpm, 150 Hz order 5 at 1800 rpm) it adds to that order's coefficient a component the
model cannot produce and the split-half repeatability cannot see (it is the same in both
halves). Where it falls between the orders, the order tracking hardly sees it
(:mod:`dampersim.analysis.ordertrack`: through its Hann window a component a whole number
of bins other than +-1 away from an order bin does not leak into it, and between whole
bins little does: 2.4 % at 2.5 bins, 0.84 % at most beyond 3 bins).

So the pick-up is measured where it is harmless and carried where it is not:

1. for every line frequency F of MAINS_HZ and every torsional point whose record leaves
   F at least CLEAR_BINS frequency bins (1 / record length) from every engine order (at
   the record's measured mean speed where it has a speed channel), half orders included
   (a four-stroke engine's cycle is two revolutions, and the damper's non-linearity
   carries its half orders up the spectrum), the output channel's line
   coefficient at F (Hann window over the whole record: the complex amplitude of a
   sinusoid at F) and its noise, from the record's two halves read at F on the whole
   record's time origin (a steady line gives both halves the same coefficient; half their
   difference has the variance of the whole record's estimate);
2. the line's power A^2 is the median over those points of |coefficient|^2 less the
   median noise variance, kept only when the median |coefficient|^2 exceeds SIGNIFICANT^2
   times that noise (a line that cannot be told from the noise is already in the noise
   term), and taken as 0 when fewer than MIN_CLEAR_POINTS points are clear;
3. a cell (point, order k) gets the variance A^2 |W(d)|^2, where d = (F / f_rot - k) N is
   the line's distance in bins from order k's bin over the point's N tracked revolutions
   at their mean speed f_rot, and W the Hann window's response (1 at d = 0, 1/2 at
   d = +-1, 0 at other whole d). A point without a speed channel has its orders read as
   band energies at the nominal speed (:func:`dampersim.signal.order_amplitudes`), which take
   in a line anywhere in the order's band: it gets the whole A^2 where |d| is within the
   band's half width (:func:`band_half_width`).

The pick-up is a variance, not a fitted nuisance: its phase is random from record to record,
so one amplitude per line is all a campaign can know about it. The input channel's pick-up
is not carried: it drives the model, which answers with the damper's small transfer at the
line frequency (tests/discrepancy/test_input_channel.py: 0.13 N m of 50 Hz on the input of
the 18/8 set at 1500 rpm and 350 N m moves its orders by 0.021 N m at most, at or below a
record's order uncertainty there).
Units: frequency [Hz], torque [N m].
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.discrepancy import tracking
from dampersim.signal import HANN_HALF_LOBE_BINS, SEARCH_HALF_WIDTH_BINS, SEARCH_HALF_WIDTH_REL

#: mains line frequencies looked for [Hz]: 50 and 60 Hz grids, fundamentals and the second and
#: third harmonics (rectifiers, transformer saturation)
MAINS_HZ = (50.0, 100.0, 150.0, 60.0, 120.0, 180.0)
#: a point is clear of the engine orders at a line when the line is at least this many
#: frequency bins (1 / record length) from every whole and half order: the Hann window's
#: leakage from an order there is at most 0.84 % of its amplitude
CLEAR_BINS = 3.0
#: a line is carried only when its amplitude over the clear points exceeds this many times the
#: noise of its coefficient
SIGNIFICANT = 2.0
#: fewest clear points to estimate a line from (the median of fewer is one point's word)
MIN_CLEAR_POINTS = 3
#: highest engine order considered when checking a point is clear of the orders
MAX_ORDER = 40.0


def hann_response(d) -> np.ndarray:
    """Magnitude of the periodic Hann window's response to a sinusoid ``d`` bins away from the
    bin read: |sinc(d) / (1 - d^2)|, which is 1 at d = 0, 1/2 at d = +-1 and 0 at other
    whole numbers."""
    d = np.abs(np.asarray(d, dtype=float))
    near_one = np.abs(d - 1.0) < 1e-9
    safe = np.where(near_one, 0.0, d)
    w = np.abs(np.sinc(safe) / (1.0 - safe * safe))
    return np.where(near_one, 0.5, w)


def band_half_width(orders, n_rev: float) -> np.ndarray:
    """Half width [bins] of the band :func:`dampersim.signal.order_amplitudes` reads around
    each of ``orders`` in a record of ``n_rev`` revolutions, with its peak on the order: the
    search half width (1.5 bins or 1 % of the order's frequency, whichever is wider) plus the
    Hann main lobe, never beyond half the spacing to the next order (counting DC as order 0)."""
    orders = np.asarray(orders, dtype=float)
    limit = 0.5 * float(np.min(np.diff(np.concatenate(([0.0], np.sort(orders)))))) * n_rev
    half = np.minimum(np.maximum(SEARCH_HALF_WIDTH_BINS, SEARCH_HALF_WIDTH_REL * orders * n_rev), limit)
    return np.minimum(half + HANN_HALF_LOBE_BINS, limit)


def line_coefficient(point, freq_hz: float, part: slice = slice(None)) -> complex:
    """Complex amplitude [N m] of a sinusoid at ``freq_hz`` in ``part`` of the point's output
    torque (mean removed), read with a periodic Hann window over that part and phased on the
    whole record's first sample."""
    x = np.asarray(point.output_torque, dtype=float)[part]
    t = np.asarray(point.time, dtype=float)
    t0, t = t[0], t[part]
    n = len(x)
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    return complex(2.0 * np.sum(w * (x - x.mean()) * np.exp(-2j * np.pi * freq_hz * (t - t0))) / np.sum(w))


def line_noise(point, freq_hz: float) -> float:
    """Standard deviation [N m] of :func:`line_coefficient` over the whole record: half the
    difference of the two halves' coefficients."""
    n = len(point.output_torque) // 2
    return 0.5 * abs(line_coefficient(point, freq_hz, slice(0, n)) - line_coefficient(point, freq_hz, slice(n, 2 * n)))


def _clear(point, freq_hz: float) -> bool:
    # the orders sit at the record's measured mean speed where it has a speed channel (the
    # rig's nominal speed can be off by more than a bin at the high orders)
    w = tracking.point_speed(point)
    f_rot = (float(np.mean(w)) if w is not None else point.speed) / (2.0 * np.pi)
    length = float(point.time[-1] - point.time[0])
    nyquist = 0.5 * point.sample_rate_hz
    k = np.arange(0.5, MAX_ORDER + 0.25, 0.5)  # whole and half orders
    return freq_hz < nyquist and bool(np.all(np.abs(freq_hz - k * f_rot) * length >= CLEAR_BINS))


def line_powers(points) -> dict:
    """{line frequency [Hz]: A^2 [N m^2]} of the campaign's output channel (module
    docstring, steps 1-2)."""
    out = {}
    for f in MAINS_HZ:
        rows = [p for p in points if _clear(p, f)]
        if len(rows) < MIN_CLEAR_POINTS:
            out[f] = 0.0
            continue
        power = float(np.median([abs(line_coefficient(p, f)) ** 2 for p in rows]))
        floor = float(np.median([line_noise(p, f) ** 2 for p in rows]))
        out[f] = power - floor if power > SIGNIFICANT ** 2 * floor else 0.0
    return out


def pickup_sigma(points, orders) -> np.ndarray:
    """Standard deviation [N m] (points x orders) the mains pick-up adds to every order cell
    (module docstring, step 3)."""
    powers = {f: a2 for f, a2 in line_powers(points).items() if a2 > 0.0}
    orders = np.asarray(orders, dtype=float)
    var = np.zeros((len(points), len(orders)))
    for i, p in enumerate(points):
        if not powers:
            break
        tracked = getattr(p, tracking.SPEED_CHANNEL, None) is not None
        if tracked:
            read = tracking.tracked(p, p.output_torque, orders)
            f_rot, n_rev = read.mean_speed / (2.0 * math.pi), float(read.revolutions)
        else:
            f_rot = p.speed / (2.0 * math.pi)
            n_rev = float(p.time[-1] - p.time[0]) * f_rot
        for f, a2 in powers.items():
            d = (f / f_rot - orders) * n_rev
            var[i] += a2 * (hann_response(d) ** 2 if tracked else (np.abs(d) <= band_half_width(orders, n_rev)))
    return np.sqrt(var)


__all__ = ["MAINS_HZ", "CLEAR_BINS", "SIGNIFICANT", "MIN_CLEAR_POINTS", "band_half_width", "hann_response",
           "line_coefficient", "line_noise", "line_powers", "pickup_sigma"]
