"""Segmentation: a long rig recording cut into test points, torsional plateaus and torque-ramp protocols.

A run on the rig steps speed and mean torque through plateaus (torsional test points: a
steady speed and mean torque with an order excitation of large amplitude on top) and, at a
steady speed, through hysteresis protocols (the torque ramped slowly, e.g. 0 -> +450 ->
-180 -> 0 N m at 50 N m/s with 2 s holds at the peaks; :mod:`dampersim.excitation.ramps`).
:func:`find_segments` finds both on the speed [rpm] and input torque [N m] traces:

1. **Mean over revolutions.** Speed and torque are averaged twice over a centred window
   of :data:`MEAN_REVOLUTIONS` revolutions at the local speed. At a steady speed each
   pass cancels every integer and half order, however large (the order excitation, the
   speed's own ripple); the second pass removes what the first leaves when the window is
   a whole number of samples only approximately (up to 7 % of an order on a 200 Hz trace,
   0.5 % after both), and both average noise and 50 Hz hum down. A step is smeared by one
   window either side (0.12 s at 1000 rpm). The detection runs on these means at about
   :data:`DETECTION_RATE_HZ`.
2. **Rates of change** of mean speed and torque: slope of a straight line fitted over
   :data:`SLOPE_WINDOW_S`. Each instant is *flat* (speed steady, torque changing slower
   than :data:`FLAT_TORQUE_RATE`), *ramping* (speed steady, torque rate between that and
   :data:`MAX_RAMP_RATE`) or *changing* (a step).
3. **Plateaus.** From every flat stretch the plateau is grown while mean speed and mean
   torque stay within tolerance (:data:`SPEED_TOLERANCE`, :data:`TORQUE_TOLERANCE`) of the
   plateau's median (excursions shorter than :data:`PERSIST_WINDOWS` mean windows are
   noise on the mean): its start is the settled start (the transient after the step
   removed), its end the last instant before the next change. Half a mean window is
   dropped after the settled start, since the mean there still averages samples before it.
   A NaN drop-out ends a plateau (a new one may start after it): no test point holds NaN.
4. **Ramp protocols.** Ramping stretches of at least :data:`MIN_RAMP_PIECE_S` that are
   straight lines (R² >= :data:`MIN_RAMP_LINEARITY`) are ramps; consecutive ramps at the
   same speed with only holds (at most ``max_hold_s``) between them form one protocol,
   from the corner where the first ramp leaves its start level to the corner where the
   last one arrives. The protocol's holds, and a lead-in or lead-out level without order
   excitation next to it, belong to the protocol and are not plateaus.
5. **Checks.** A plateau shorter than the order analysis needs (campaign.MIN_TORSIONAL_S
   and MIN_REVOLUTIONS at its speed), one without order excitation (torque ripple below
   ``min_ripple_nm`` RMS, judged where the trace's rate shows :data:`EXCITATION_ORDER`)
   or below :data:`MIN_SPEED_RPM`, and a protocol shorter than
   campaign.MIN_RAMP_S are returned as rejected candidates with the reason.

Thresholds are module constants, each with its unit and reason. Units at the edges: time
[s], speed [rpm], torque [N m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.discrepancy.campaign import KINDS, MIN_RAMP_S, MIN_REVOLUTIONS, MIN_TORSIONAL_S
from dampersim.errors import InputError
from dampersim.signal import sample_rate_from_time

#: Window of the mean [revolutions]: an integer number cancels every integer order and,
#: being even, every half order; two keep the smear of a step short (0.12 s at 1000 rpm).
MEAN_REVOLUTIONS = 2
#: Longest mean window [s]: below 600 rpm the window stops growing, so that a step is never
#: smeared by more than 0.2 s either side (the settled start is wanted to within 0.2 s).
MAX_MEAN_WINDOW_S = 0.2
#: Rate the detection works at [Hz]: 5 ms resolution, far finer than the 0.2 s asked of
#: the boundaries, and cheap on recordings of hours.
DETECTION_RATE_HZ = 200.0
#: Window of the line fitted for rates of change [s]: long enough to average the residue
#: of the mean (slope noise about 1 N m/s), short against a 0.5 s settling transient.
SLOPE_WINDOW_S = 0.2
#: Torque rate [N m/s] below which the mean torque holds: 5x the slope noise, half the
#: slowest hysteresis ramp rate (tens of N m/s).
FLAT_TORQUE_RATE = 5.0
#: Fastest torque ramp rate [N m/s] of a hysteresis protocol: 3x the thesis's 50 N m/s;
#: faster is a step between test points.
MAX_RAMP_RATE = 150.0
#: Speed steady while its rate stays below (relative [1/s], absolute [rpm/s]): a speed step
#: between test points runs at hundreds of rpm/s, slow drift at a few.
SPEED_RATE_TOLERANCE = (0.05, 20.0)
#: Plateau tolerance of the mean speed (relative, absolute [rpm]): the order read-out
#: absorbs up to about +-0.5 % (dampersim.signal); 3 rpm is far above the mean's noise.
SPEED_TOLERANCE = (0.005, 3.0)
#: Plateau tolerance of the mean torque (relative, absolute [N m]): 2 % keeps the spring
#: curve's operating point; 5 N m is far above the residue of the mean (< 1 N m).
TORQUE_TOLERANCE = (0.02, 5.0)
#: A plateau ends where mean speed or torque stays out of tolerance for this many mean
#: windows [-]; shorter excursions are noise on the mean (one window is its correlation time).
PERSIST_WINDOWS = 1.0
#: Steady stretches shorter than this [s] are turning points of a settling transient (its
#: overshoot peaks) or of a ramp reversal, not plateaus; they are not reported.
MIN_PLATEAU_S = 0.25
#: Shortest ramp piece [s]: shorter ramping stretches are the flanks of a step.
MIN_RAMP_PIECE_S = 0.5
#: Least R² of a straight line through a ramp piece's mean torque: a ramp is straight, the
#: flank of a settling step is curved.
MIN_RAMP_LINEARITY = 0.98
#: Longest hold inside a protocol [s] (the thesis holds 2 s); a longer pause ends it.
MAX_HOLD_S = 5.0
#: Least torque ripple [N m RMS] of a torsional test point: a fifth of the smallest order
#: excitation the thesis applies (100 N m amplitude, 71 N m RMS), several times rig noise.
MIN_RIPPLE_NM = 20.0
#: Order whose presence marks a torsional test point, when the trace's rate shows it (the
#: rig excites order 2 and up; at 200 Hz order 2 is visible up to 2400 rpm): a plateau
#: with less ripple than ``min_ripple_nm`` is rejected only then.
EXCITATION_ORDER = 2
#: A level without order excitation this close [s] (plus a slope window) to a ramp protocol
#: at its speed is the protocol's lead-in or lead-out (ramps.TorqueRamp leads 0.5 s).
LEAD_GAP_S = 0.5
#: Slowest trace accepted [Hz]: the slope fit needs 10 samples per SLOPE_WINDOW_S.
MIN_RATE_HZ = 50.0
#: Slowest speed of a test point [rpm]: the campaign accepts 100-10000 rpm.
MIN_SPEED_RPM = 100.0
#: Decimals of the review table (time [s], speed [rpm], torque [N m]).
TABLE_DECIMALS = {"start_s": 3, "end_s": 3, "speed_rpm": 1, "mean_torque_nm": 1}
TABLE_COLUMNS = ("id", "kind", "speed_rpm", "mean_torque_nm", "start_s", "end_s")


@dataclass(frozen=True)
class Segment:
    """One test point of a recording: ``kind`` "torsional" or "ramp", the usable window
    ``start_s``-``end_s`` [s, the recording's time], its mean ``speed_rpm`` [rpm] and
    ``mean_torque_nm`` [N m], and a ``note`` on how it was found."""

    kind: str
    start_s: float
    end_s: float
    speed_rpm: float
    mean_torque_nm: float
    note: str = ""


@dataclass(frozen=True)
class Rejected:
    """A candidate that is not a test point, and why (``reason``); fields as :class:`Segment`."""

    kind: str
    start_s: float
    end_s: float
    speed_rpm: float
    mean_torque_nm: float
    reason: str


class SegmentList(list):
    """The segments found (a list of :class:`Segment`, in time order) with the
    ``rejected`` candidates (list of :class:`Rejected`) and the recording's ``span_s``
    (first, last time [s]); ``segments`` is the list itself."""

    def __init__(self, segments=(), rejected=(), span_s=(math.nan, math.nan)):
        super().__init__(segments)
        self.rejected = list(rejected)
        self.span_s = (float(span_s[0]), float(span_s[1]))

    @property
    def segments(self) -> list:
        return list(self)


def _tolerance(value, tol):
    """The tolerance (relative, absolute) at ``value``: the larger of the two."""
    return max(tol[0] * abs(value), tol[1])


def _needed_s(speed_rpm: float) -> float:
    """Shortest torsional window [s] the order analysis takes at ``speed_rpm``."""
    return max(MIN_TORSIONAL_S, MIN_REVOLUTIONS * 60.0 / max(speed_rpm, MIN_SPEED_RPM))


def _runs(mask):
    """(start, stop) index pairs of the runs of True in a boolean array."""
    edges = np.diff(np.concatenate(([0], np.asarray(mask, dtype=np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _filled(x, name):
    """``x`` with NaN/inf bridged linearly (for the detection only) and the NaN mask."""
    x = np.asarray(x, dtype=float)
    bad = ~np.isfinite(x)
    if bad.all():
        raise InputError(f"{name}: no finite samples; accepted is a trace with values")
    if bad.any():
        idx = np.arange(x.size)
        x = x.copy()
        x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return x, bad


class _Traces:
    """Revolution means and rates of change of speed and torque on the detection grid."""

    def __init__(self, t, speed, torque, nan):
        from scipy.signal import savgol_filter

        n = t.size
        self.fs = sample_rate_from_time(t)
        # the first mean runs on a grid of about 1 kHz, the second on the detection grid
        k1 = max(1, int(self.fs // 1000.0))
        fine = np.arange(0, n, k1)
        every = max(1, int((self.fs / k1) // DETECTION_RATE_HZ))
        self.idx = fine[::every]
        self.t = t[self.idx]
        self.t_full = t
        self.fd = self.fs / (k1 * every)
        rough = _box(speed, fine, np.full(fine.size, max(1, int(round(0.1 * self.fs)))))
        window = np.minimum(MEAN_REVOLUTIONS * 60.0 / np.maximum(rough, MIN_SPEED_RPM), MAX_MEAN_WINDOW_S)
        width = np.maximum(1, np.rint(window * self.fs).astype(np.int64))
        sub = np.arange(0, fine.size, every)
        width2 = np.maximum(1, np.rint(window[sub] * self.fs / k1).astype(np.int64))
        self.window_s = window[sub]
        self.speed = _box(_box(speed, fine, width), sub, width2)
        self.torque = _box(_box(torque, fine, width), sub, width2)
        # instants whose means reach a NaN drop-out: a plateau never spans one
        self.dropout = _box(_box(nan.astype(float), fine, width), sub, width2) > 0
        w = max(5, int(round(SLOPE_WINDOW_S * self.fd)) | 1)  # <= 0.4 s x 50 Hz samples: see MIN_RATE_HZ
        self.dspeed = savgol_filter(self.speed, w, 1, deriv=1, delta=1.0 / self.fd)
        self.dtorque = savgol_filter(self.torque, w, 1, deriv=1, delta=1.0 / self.fd)
        steady = np.abs(self.dspeed) <= np.maximum(SPEED_RATE_TOLERANCE[0] * np.abs(self.speed),
                                                    SPEED_RATE_TOLERANCE[1])
        rate = np.abs(self.dtorque)
        self.flat = steady & (rate <= FLAT_TORQUE_RATE)
        self.ramping = steady & (rate > FLAT_TORQUE_RATE) & (rate <= MAX_RAMP_RATE)


def _box(x, at, width):
    """Centred moving mean of ``x`` over ``width`` samples at the indices ``at`` (each its
    own width), from the cumulative sum; shorter where it would run off the ends."""
    n = x.size
    csum = np.concatenate(([0.0], np.cumsum(x)))
    lo = np.clip(at - width // 2, 0, n - 1)
    hi = np.minimum(lo + width, n)
    lo = np.maximum(hi - width, 0)
    return (csum[hi] - csum[lo]) / (hi - lo)


def _grow(tr: _Traces, a: int, b: int, speed_tol, torque_tol):
    """Extent (start, stop) of the plateau seeded by flat stretch [a, b): where mean speed
    and torque stay within tolerance of the plateau's medians, up to a drop-out, excursions
    shorter than :data:`PERSIST_WINDOWS` mean windows (noise on the mean) ignored; None
    when the seed's centre is not within tolerance itself."""
    lo, hi, c, n = a, b, (a + b) // 2, tr.t.size
    persist = max(2, int(round(PERSIST_WINDOWS * tr.window_s[c] * tr.fd)))
    for _ in range(3):
        s0, m0 = float(np.median(tr.speed[lo:hi])), float(np.median(tr.torque[lo:hi]))
        ts, tm = _tolerance(s0, speed_tol), _tolerance(m0, torque_tol)

        def fails(i0, i1):
            return (np.abs(tr.speed[i0:i1] - s0) > ts) | (np.abs(tr.torque[i0:i1] - m0) > tm)

        if fails(c, c + 1)[0] or tr.dropout[c]:
            return None
        back = _reach(lambda k: (fails(c + 1 - k, c + 1)[::-1], tr.dropout[c + 1 - k:c + 1][::-1]), c + 1, persist)
        ahead = _reach(lambda k: (fails(c, c + k), tr.dropout[c:c + k]), n - c, persist)
        if (c + 1 - back, c + ahead) == (lo, hi):
            break
        lo, hi = c + 1 - back, c + ahead
    return lo, hi


def _reach(look, room: int, persist: int) -> int:
    """How many instants from a seed's centre outwards (centre included) a plateau reaches:
    up to the first run of ``persist`` or more failing instants, or the first drop-out.
    ``look(k)`` gives (failing, drop-out) masks of the first k instants outwards, ``room``
    how many there are. Looks in doubling steps: a plateau is short against a recording."""
    k = 256
    while True:
        k = min(k, room)
        fail, hard = look(k)
        h = np.flatnonzero(hard)
        final = bool(h.size) or k == room
        limit = int(h[0]) if h.size else k
        for x, y in _runs(fail[:limit]):
            if y - x >= persist or (y == limit and final):
                return x
            if y == limit:
                break  # the run may go on beyond this look
        else:
            if final:
                return limit
        k *= 2


@dataclass
class _Ramp:
    """A ramp piece: detection-grid indices [lo, hi), its line (slope [N m/s], intercept
    [N m] at the grid's first instant) and its speed [rpm]."""

    lo: int
    hi: int
    slope: float
    intercept: float
    speed: float


def _ramp_pieces(tr: _Traces, speed_tol):
    """The ramping stretches that are ramps: long and straight enough, at a steady speed."""
    pieces = []
    trim = int(round(0.5 * SLOPE_WINDOW_S * tr.fd))
    for a, b in _runs(tr.ramping):
        if (b - a) / tr.fd < MIN_RAMP_PIECE_S:
            continue
        lo, hi = a + trim, b - trim
        if hi - lo < 3:
            continue
        tt, mm = tr.t[lo:hi] - tr.t[0], tr.torque[lo:hi]
        slope, intercept = np.polyfit(tt, mm, 1)
        r2 = 1.0 - float(np.var(mm - (slope * tt + intercept))) / max(float(np.var(mm)), 1e-300)
        speed = float(np.median(tr.speed[a:b]))
        steady = float(np.ptp(tr.speed[a:b])) <= 2 * _tolerance(speed, speed_tol)
        if r2 >= MIN_RAMP_LINEARITY and steady and FLAT_TORQUE_RATE < abs(slope) <= MAX_RAMP_RATE:
            pieces.append(_Ramp(a, b, float(slope), float(intercept), speed))
    return pieces


def _protocols(tr: _Traces, pieces, speed_tol, max_hold_s):
    """Ramp pieces grouped into protocols: consecutive pieces at one speed, with holds of
    at most ``max_hold_s`` and no step or speed change between them."""
    groups = []
    for p in pieces:
        if groups:
            q = groups[-1][-1]
            gap = slice(q.hi, p.lo)
            tol = _tolerance(q.speed, speed_tol)
            gap_ok = ((tr.t[p.lo] - tr.t[q.hi - 1]) <= max_hold_s
                      and not (np.abs(tr.dtorque[gap]) > MAX_RAMP_RATE).any()
                      and not (np.abs(tr.speed[gap] - q.speed) > tol).any())
            if gap_ok and abs(p.speed - q.speed) <= tol:
                groups[-1].append(p)
                continue
        groups.append([p])
    return groups


def _level(tr: _Traces, lo: int, hi: int):
    """Median mean torque over the flat instants of [lo, hi), or None without any."""
    lo, hi = max(lo, 0), min(hi, tr.t.size)
    if hi <= lo:
        return None
    sel = tr.flat[lo:hi]
    return float(np.median(tr.torque[lo:hi][sel])) if sel.any() else None


def _corner(tr: _Traces, piece: _Ramp, level, at_start: bool) -> float:
    """Time [s] where a ramp piece's line meets the level before (after) it, kept within a
    slope window of the piece's labelled edge; that edge when there is no level."""
    edge = tr.t[piece.lo] if at_start else tr.t[piece.hi - 1]
    if level is None:
        return float(edge)
    tc = (level - piece.intercept) / piece.slope + tr.t[0]
    return float(np.clip(tc, edge - SLOPE_WINDOW_S, edge + SLOPE_WINDOW_S))


def _mean_over(tr: _Traces, t0: float, t1: float):
    """Mean speed [rpm] and torque [N m] (revolution means) over [t0, t1] [s]."""
    sel = (tr.t >= t0) & (tr.t <= t1)
    if not sel.any():
        sel = np.abs(tr.t - 0.5 * (t0 + t1)) == np.min(np.abs(tr.t - 0.5 * (t0 + t1)))
    return float(np.mean(tr.speed[sel])), float(np.mean(tr.torque[sel]))


def _check_options(t, speed_rpm, torque_nm, settle_s, speed_tolerance, torque_tolerance, min_ripple_nm, max_hold_s):
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or np.ndim(speed_rpm) != 1 or np.ndim(torque_nm) != 1 or not (
            t.size == np.size(speed_rpm) == np.size(torque_nm)):
        raise InputError(f"t, speed_rpm, torque_nm: sizes {t.size}, {np.size(speed_rpm)}, {np.size(torque_nm)}; "
                         "accepted are three 1-D arrays of the same length")
    fs = sample_rate_from_time(t)
    if fs < MIN_RATE_HZ or (t[-1] - t[0]) < 2 * SLOPE_WINDOW_S:
        raise InputError(f"recording of {t[-1] - t[0]:.3g} s at {fs:.3g} Hz: accepted is at least "
                         f"{2 * SLOPE_WINDOW_S:g} s at {MIN_RATE_HZ:g} Hz or more")
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0

    for name, value in (("settle_s", settle_s), ("max_hold_s", max_hold_s), ("min_ripple_nm", min_ripple_nm)):
        if not number(value):
            raise InputError(f"{name} = {value!r}: accepted is a finite number >= 0")
    for name, tol in (("speed_tolerance", speed_tolerance), ("torque_tolerance", torque_tolerance)):
        if not (isinstance(tol, (tuple, list)) and len(tol) == 2 and all(map(number, tol)) and max(tol) > 0):
            raise InputError(f"{name} = {tol!r}: accepted is (relative, absolute [unit]), both finite and >= 0, "
                             "one > 0")
    return t, fs


def _protocol(tr: _Traces, group, nans) -> Segment | Rejected:
    """The segment (or rejected candidate) of one group of ramp pieces."""
    first, last = group[0], group[-1]
    half_s = int(tr.fd * 0.5)
    t0 = _corner(tr, first, _level(tr, first.lo - half_s, first.lo), True)
    t1 = _corner(tr, last, _level(tr, last.hi, last.hi + half_s), False)
    spd, mean_tq = _mean_over(tr, t0, t1)
    if t1 - t0 < MIN_RAMP_S:
        return Rejected("ramp", t0, t1, spd, mean_tq,
                        f"ramp of {t1 - t0:.2f} s is shorter than {MIN_RAMP_S:g} s (campaign.MIN_RAMP_S)")
    ends = [t0] + [tr.t[p.hi - 1] for p in group[:-1]] + [t1]
    path = [first.slope * (ends[0] - tr.t[0]) + first.intercept]
    path += [p.slope * (e - tr.t[0]) + p.intercept for p, e in zip(group, ends[1:])]
    rates = "/".join(str(r) for r in sorted({round(abs(p.slope)) for p in group}))
    note = (f"ramp protocol {' -> '.join(f'{v:.0f}' for v in path)} N m at {rates} N m/s: {len(group)} ramps "
            f"with {len(group) - 1} holds or turns between them")
    inside = int(np.count_nonzero(nans[np.searchsorted(tr.t_full, t0):np.searchsorted(tr.t_full, t1, "right")]))
    if inside:
        note += f"; {inside} NaN samples inside"
    return Segment("ramp", t0, t1, spd, mean_tq, note)


def _extents(tr: _Traces, speed_tolerance, torque_tolerance):
    """Index extents of the plateaus, each grown from a flat stretch (longest first)."""
    extents = []
    for a, b in sorted(_runs(tr.flat), key=lambda r: r[0] - r[1]):
        c = (a + b) // 2
        if any(lo <= c < hi for lo, hi in extents):
            continue
        ext = _grow(tr, a, b, speed_tolerance, torque_tolerance)
        if ext is not None and (tr.t[ext[1] - 1] - tr.t[ext[0]]) >= MIN_PLATEAU_S:
            extents.append(ext)
    kept = []  # overlapping extents: one grew from a settling transient; the longer wins
    for lo, hi in sorted(set(extents), key=lambda e: e[0] - e[1]):
        if all(min(hi, h) - max(lo, l) <= 0.1 * min(hi - lo, h - l) for l, h in kept):
            kept.append((lo, hi))
    return sorted(kept)


def _plateau(tr: _Traces, lo, hi, torque, spans, opts) -> Segment | Rejected | None:
    """The segment (or rejected candidate) of one plateau extent; None for a hold, lead-in
    or lead-out of a ramp protocol, or a stretch too short to be a plateau at all."""
    settle_s, speed_tolerance, torque_tolerance, min_ripple_nm = opts
    a_s, b_s = float(tr.t[lo]), float(tr.t[hi - 1])
    if any(min(b_s, s1) - max(a_s, s0) > 0.5 * (b_s - a_s) for s0, s1, _ in spans):
        return None  # a hold of a protocol
    start = a_s + (0.5 * float(np.median(tr.window_s[lo:hi])) if lo > 0 else 0.0) + settle_s
    end = b_s
    for s0, s1, _ in spans:  # never reach into a protocol
        if s0 < end and s1 > start:
            end, start = (min(end, s0), start) if s0 >= a_s else (end, max(start, s1))
    if end - start < MIN_PLATEAU_S:
        return None
    spd, mean_tq = _mean_over(tr, start, end)
    i0, i1 = np.searchsorted(tr.t_full, start), np.searchsorted(tr.t_full, end, "right")
    rms = float(np.std(torque[i0:i1]))
    visible = EXCITATION_ORDER * spd / 60.0 <= 0.4 * tr.fs  # resample keeps 0.4 x the rate
    margin = SLOPE_WINDOW_S + LEAD_GAP_S
    if (rms < min_ripple_nm or not visible) and any(
            abs(sp - spd) <= _tolerance(sp, speed_tolerance) and (abs(s0 - end) <= margin or abs(start - s1) <= margin)
            for s0, s1, sp in spans):
        return None  # lead-in or lead-out level of a protocol
    need = _needed_s(spd)
    if spd < MIN_SPEED_RPM:
        return Rejected("torsional", start, end, spd, mean_tq, f"speed {spd:.0f} rpm is below {MIN_SPEED_RPM:g} rpm")
    if visible and rms < min_ripple_nm:
        return Rejected("torsional", start, end, spd, mean_tq, f"no order excitation: torque ripple {rms:.1f} N m "
                        f"RMS is below {min_ripple_nm:g} N m RMS")
    if end - start < need:
        return Rejected("torsional", start, end, spd, mean_tq, (
            f"plateau of {end - start:.2f} s is shorter than the {need:.2f} s the order analysis needs "
            f"(campaign.MIN_TORSIONAL_S {MIN_TORSIONAL_S:g} s, MIN_REVOLUTIONS {MIN_REVOLUTIONS} at {spd:.0f} rpm)"))
    since = "the recording start" if lo == 0 else "a drop-out" if tr.dropout[lo - 1] else "a change"
    until = "the recording end" if hi == tr.t.size else "a drop-out" if tr.dropout[hi] else "the next change"
    note = (f"steady within {_tolerance(spd, speed_tolerance):.1f} rpm and {_tolerance(mean_tq, torque_tolerance):.1f}"
            f" N m for {end - start:.2f} s, from {since} to {until}; torque ripple {rms:.0f} N m RMS")
    if not visible:
        note += (f" (order {EXCITATION_ORDER} at {EXCITATION_ORDER * spd / 60:.0f} Hz is beyond this {tr.fs:.0f} Hz "
                 "trace: excitation not checked)")
    return Segment("torsional", start, end, spd, mean_tq, note)


def find_segments(t, speed_rpm, torque_nm, *, settle_s: float = 0.0, speed_tolerance=SPEED_TOLERANCE,
                  torque_tolerance=TORQUE_TOLERANCE, min_ripple_nm: float = MIN_RIPPLE_NM,
                  max_hold_s: float = MAX_HOLD_S) -> SegmentList:
    """Torsional plateaus and torque-ramp protocols of a long recording (method: module
    docstring).

    Args:
        t: uniform time stamps [s] (any start), e.g. from
            :func:`dampersim.rigdata.resample.common_time_base`; at least 50 Hz, 200 Hz or
            more recommended (the order excitation is checked only where the trace's
            rate shows order 2: up to 0.4 x rate x 30 rpm).
        speed_rpm: input speed [rpm] at ``t``. NaN drop-outs are bridged for the
            detection; no plateau spans one (a ramp protocol may: its note says so).
        torque_nm: input torque [N m] at ``t``, order excitation included; NaN as speed.
        settle_s: extra time [s] dropped after each plateau's settled start, on top of the
            detection (0: none), for rigs whose response settles later than its means.
        speed_tolerance: plateau tolerance of the mean speed (relative, absolute [rpm]).
        torque_tolerance: plateau tolerance of the mean torque (relative, absolute [N m]).
        min_ripple_nm: least torque ripple [N m RMS] of a torsional test point.
        max_hold_s: longest hold [s] inside a ramp protocol.

    Returns:
        :class:`SegmentList`: the segments in time order, ``.rejected`` the candidates
        that are not test points with the reason, ``.span_s`` the recording's first and
        last time [s].

    Raises:
        InputError: arrays of different lengths or too short, time not uniform, a trace
            without finite samples, bad options.
    """
    t, _fs = _check_options(t, speed_rpm, torque_nm, settle_s, speed_tolerance, torque_tolerance, min_ripple_nm,
                            max_hold_s)
    speed, nan_s = _filled(speed_rpm, "speed_rpm")
    torque, nan_m = _filled(torque_nm, "torque_nm")
    nans = nan_s | nan_m
    tr = _Traces(t, speed, torque, nans)
    found = [_protocol(tr, group, nans)
             for group in _protocols(tr, _ramp_pieces(tr, speed_tolerance), speed_tolerance, max_hold_s)]
    spans = [(f.start_s, f.end_s, f.speed_rpm) for f in found]
    opts = (settle_s, speed_tolerance, torque_tolerance, min_ripple_nm)
    found += [_plateau(tr, lo, hi, torque, spans, opts) for lo, hi in _extents(tr, speed_tolerance, torque_tolerance)]
    segments = sorted((f for f in found if isinstance(f, Segment)), key=lambda s: s.start_s)
    rejected = sorted((f for f in found if isinstance(f, Rejected)), key=lambda r: r.start_s)
    return SegmentList(segments, rejected, (t[0], t[-1]))


def segment_table(segments) -> list:
    """Review rows, one per segment in the given order: ``id`` ("seg001", ... by position),
    ``kind``, ``speed_rpm`` [rpm], ``mean_torque_nm`` [N m], ``start_s``, ``end_s`` [s],
    rounded to :data:`TABLE_DECIMALS`."""
    rows = [{"id": f"seg{i + 1:03d}", "kind": s.kind, **{k: round(float(getattr(s, k)), d)
                                                          for k, d in TABLE_DECIMALS.items()}}
            for i, s in enumerate(segments)]
    return [{k: r[k] for k in TABLE_COLUMNS} for r in rows]


def _number(row_name, field, value):
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x):
        raise InputError(f"{row_name}: {field} = {value!r}: accepted is a finite number")
    return x


def apply_edits(segments, rows, *, t=None, speed_rpm=None, torque_nm=None) -> SegmentList:
    """Segments after a review: ``rows`` are :func:`segment_table`'s rows of ``segments``,
    edited (``kind``, ``start_s``, ``end_s`` [s] changed; rows deleted to drop segments).
    Values may be text (a CSV table); ``speed_rpm`` and ``mean_torque_nm`` are measured and
    must be left as they are (or left out).

    ``segments`` is the list the table was made of; a plain list (not a
    :class:`SegmentList`) needs ``t``, the recording's time stamps [s]. With ``t``,
    ``speed_rpm`` [rpm] and ``torque_nm`` [N m], a changed window's speed and mean torque
    are measured again. Returns a :class:`SegmentList` of the kept segments in the rows'
    order (``rejected`` and ``span_s`` carried over); an unchanged row gives back its
    segment as it was, the table's rounding notwithstanding.

    Raises InputError naming the row (1-based, with its id) and the field: an id not in the
    table or given twice, a kind not torsional/ramp, start/end not numbers, start >= end, a
    window outside the recording or too short for its kind, an edited speed or torque.
    """
    table = {r["id"]: (r, s) for r, s in zip(segment_table(segments), segments)}
    if t is not None:
        span = (float(np.asarray(t, dtype=float)[0]), float(np.asarray(t, dtype=float)[-1]))
    elif isinstance(segments, SegmentList) and math.isfinite(segments.span_s[0]):
        span = segments.span_s
    else:
        raise InputError("apply_edits needs the recording's time stamps t [s] (or the SegmentList of find_segments)")
    out, seen = [], set()
    for i, row in enumerate(rows, start=1):
        rid = str(row.get("id", "")).strip() if hasattr(row, "get") else ""
        name = f"row {i} (id {rid!r})"
        if rid not in table or rid in seen:
            raise InputError(f"{name}: id: {'given twice' if rid in seen else 'not a segment of this table'}; "
                             f"accepted is each of {', '.join(table)} at most once")
        seen.add(rid)
        orig, seg = table[rid]
        kind = str(row.get("kind", "")).strip().lower()
        if kind not in KINDS:
            raise InputError(f"{name}: kind = {row.get('kind')!r}: accepted is {' or '.join(KINDS)}")
        values = {}
        for field in TABLE_DECIMALS:
            if field not in row or (field not in ("start_s", "end_s") and row[field] in ("", None)):
                if field in ("start_s", "end_s"):
                    raise InputError(f"{name}: {field}: missing; accepted is a time in s")
                continue
            x = _number(name, field, row[field])
            same = abs(x - orig[field]) <= 0.5 * 10 ** -TABLE_DECIMALS[field] + 1e-9
            if not same and field not in ("start_s", "end_s"):
                raise InputError(f"{name}: {field} = {row[field]!r}: a measured value; accepted is {orig[field]!r} "
                                 "(change start_s and end_s instead)")
            values[field] = getattr(seg, field) if same else x
        start, end = values["start_s"], values["end_s"]
        if not start < end:
            raise InputError(f"{name}: end_s = {row['end_s']!r}: accepted is a time after start_s = {start!r}")
        if start < span[0] - 1e-9 or end > span[1] + 1e-9:
            field = "start_s" if start < span[0] - 1e-9 else "end_s"
            raise InputError(f"{name}: {field} = {row[field]!r}: accepted is a time inside the recording, "
                             f"{span[0]:.6g}-{span[1]:.6g} s")
        if (start, end, kind) == (seg.start_s, seg.end_s, seg.kind):
            out.append(seg)
            continue
        spd, mean_tq, how = seg.speed_rpm, seg.mean_torque_nm, "of the detected window"
        if t is not None and speed_rpm is not None and torque_nm is not None:
            sel = (np.asarray(t, dtype=float) >= start) & (np.asarray(t, dtype=float) <= end)
            spd = float(np.nanmean(np.asarray(speed_rpm, dtype=float)[sel]))
            mean_tq, how = float(np.nanmean(np.asarray(torque_nm, dtype=float)[sel])), "measured over the new window"
        need = _needed_s(spd) if kind == "torsional" else MIN_RAMP_S
        if end - start < need:
            raise InputError(f"{name}: end_s = {row['end_s']!r}: a {kind} window of {end - start:.3g} s is too "
                             f"short; accepted is at least {need:.3g} s")
        out.append(Segment(kind, start, end, spd, mean_tq, f"edited in review; speed and mean torque {how}"))
    return SegmentList(out, getattr(segments, "rejected", ()), span)


__all__ = ["Segment", "Rejected", "SegmentList", "find_segments", "segment_table", "apply_edits", "TABLE_COLUMNS"]
