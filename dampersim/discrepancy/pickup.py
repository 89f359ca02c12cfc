"""Mains pick-up on the output torque channel, as an uncertainty of the order cells it falls on.

A rig's torque amplifiers pick up the mains (50 or 60 Hz and its harmonics) with a phase of
their own in every record. Where a mains line falls on an engine order (50 Hz is order 2 at
1500 rpm, 150 Hz order 5 at 1800 rpm) it adds to that order's coefficient a component the
model cannot produce and the split-half repeatability cannot see (it is the same in both
halves). Where it falls between the orders, the order tracking does not see it at all
(:mod:`dampersim.analysis.ordertrack`: a component a whole number of bins, or more than
one bin, away from an order bin does not leak into it through the Hann window).

So the pick-up is measured where it is harmless and carried where it is not:

1. for every line frequency F of MAINS_HZ and every torsional point whose record leaves
   F at least CLEAR_BINS frequency bins (1 / record length) from every engine order, half
   orders included (a four-stroke engine's cycle is two revolutions, and the damper's
   non-linearity carries its half orders up the spectrum), the
   output channel's line coefficient at F (Hann window over the whole record; the
   amplitude of a sinusoid at F). Its noise is taken as the point's median split-half
   variance over its orders (the same Hann estimate over the same record);
2. the line's power A^2 is the median over those points of |coefficient|^2 less the
   median noise variance, kept only when the median |coefficient|^2 exceeds SIGNIFICANT^2
   times that noise (a line that cannot be told from the noise is already in the noise
   term), and taken as 0 when fewer than MIN_CLEAR_POINTS points are clear;
3. a cell (point, order k) gets the variance A^2 |W(d)|^2, where d = (F / f_rot - k) N is
   the line's distance in bins from order k's bin over the point's N tracked revolutions
   and W the Hann window's response (1 at d = 0, 1/2 at d = +-1, 0 at other whole d).

The pick-up is a variance, not a fitted nuisance: its phase is random from record to record,
so one amplitude per line is all a campaign can know about it. The input channel's pick-up
is not carried: it drives the model, which answers with the damper's small transfer at the
line frequency (the 18/8 set at 1500 rpm, 0.13 N m of 50 Hz on its input: its orders moved
by at most 0.014 N m at 350 N m and 0.03 N m at 150 N m, at or below a record's order
uncertainty of 0.02-0.05 N m there).
Units: frequency [Hz], torque [N m].
"""

from __future__ import annotations

import numpy as np

from dampersim.discrepancy import tracking

#: mains line frequencies looked for [Hz]: 50 and 60 Hz grids, fundamentals and the second and
#: third harmonics (rectifiers, transformer saturation)
MAINS_HZ = (50.0, 100.0, 150.0, 60.0, 120.0, 180.0)
#: a point is clear of the engine orders at a line when the line is at least this many
#: frequency bins (1 / record length) from every whole and half order: the Hann window's
#: leakage there is below 1.3 % of that order's amplitude
CLEAR_BINS = 3.0
#: a line is carried only when its amplitude over the clear points exceeds this many times the
#: noise of a coefficient
SIGNIFICANT = 2.0
#: fewest clear points to estimate a line from
MIN_CLEAR_POINTS = 2
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


def line_coefficient(point, freq_hz: float) -> complex:
    """Complex amplitude [N m] of a sinusoid at ``freq_hz`` in the point's output torque,
    read with a periodic Hann window over the whole record (mean removed)."""
    x = np.asarray(point.output_torque, dtype=float)
    t = np.asarray(point.time, dtype=float)
    n = len(x)
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    return complex(2.0 * np.sum(w * (x - x.mean()) * np.exp(-2j * np.pi * freq_hz * (t - t[0]))) / np.sum(w))


def _clear(point, freq_hz: float) -> bool:
    f_rot = point.speed / (2.0 * np.pi)
    length = float(point.time[-1] - point.time[0])
    nyquist = 0.5 * point.sample_rate_hz
    k = np.arange(0.5, MAX_ORDER + 0.25, 0.5)  # whole and half orders
    return freq_hz < nyquist and bool(np.all(np.abs(freq_hz - k * f_rot) * length >= CLEAR_BINS))


def line_powers(points, repeat) -> dict:
    """{line frequency [Hz]: A^2 [N m^2]} of the campaign's output channel (module
    docstring, steps 1-2); repeat: the points' split-half standard deviations (points x
    orders) [N m]."""
    noise = np.median(np.asarray(repeat, dtype=float) ** 2, axis=1)
    out = {}
    for f in MAINS_HZ:
        rows = [i for i, p in enumerate(points) if _clear(p, f)]
        if len(rows) < MIN_CLEAR_POINTS:
            out[f] = 0.0
            continue
        power = float(np.median([abs(line_coefficient(points[i], f)) ** 2 for i in rows]))
        floor = float(np.median(noise[rows]))
        out[f] = power - floor if power > SIGNIFICANT ** 2 * floor else 0.0
    return out


def pickup_sigma(points, repeat, orders) -> np.ndarray:
    """Standard deviation [N m] (points x orders) the mains pick-up adds to every order cell
    (module docstring, step 3)."""
    powers = line_powers(points, repeat)
    orders = np.asarray(orders, dtype=float)
    var = np.zeros((len(points), len(orders)))
    for i, p in enumerate(points):
        f_rot = p.speed / (2.0 * np.pi)
        n_rev = _revolutions(p, orders)
        for f, a2 in powers.items():
            if a2 > 0.0:
                var[i] += a2 * hann_response((f / f_rot - orders) * n_rev) ** 2
    return np.sqrt(var)


def _revolutions(point, orders) -> float:
    """Revolutions the point's orders are read over (those of its tracked output; the
    record's length times the rotation frequency without a speed channel)."""
    if getattr(point, tracking.SPEED_CHANNEL, None) is None:
        return float(point.time[-1] - point.time[0]) * point.speed / (2.0 * np.pi)
    return float(tracking.tracked(point, point.output_torque, orders).revolutions)


__all__ = ["MAINS_HZ", "CLEAR_BINS", "SIGNIFICANT", "MIN_CLEAR_POINTS", "hann_response", "line_coefficient",
           "line_powers", "pickup_sigma"]
