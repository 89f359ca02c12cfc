"""Hysteresis loops from torque ramps: windup, dynamic stiffness, knee and loop energy.

On the rig a hysteresis loop is the windup across the damper while the input torque is
ramped slowly through a protocol of [thesis] §3.3.1, Table 3.1 (e.g. 0 -> +450 -> -180 -> 0
N m at 50 N m/s, 2 s holds at the peaks). Measured loops are smoothed with a first-order
10 Hz low pass ([thesis] §3.4). From a loop the thesis reads ([thesis] §6.3.2, §7.3.1):

* the stiffness of each stage and the knee where the outer set reaches its hardstop and
  the curve stiffens;
* the dynamic stiffness dT/dtheta along the loading curve (Fig. 7.26), which shows how the
  springs' end segments join in late at high speed;
* the energy dissipated per cycle = the loop area, the closed integral of T dtheta [J].

:func:`run_loops` simulates the protocol at several speeds (the only function here that
runs the model); everything else works on plain (torque, windup) arrays, so measured loops
are analysed the same way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from dampersim.errors import InputError
from dampersim.signal import LOWPASS_CUTOFF_HZ, lowpass_first_order
from dampersim.units import rad_s_to_rpm, rad_to_deg
from dampersim.excitation.ramps import TorqueRamp, ramp_protocol
from dampersim.parameters import with_updates
from dampersim.simulation import simulate

#: Sample rate [Hz] used by run_loops unless the parameter set asks for another one:
#: a 50 N m/s ramp has no content near 500 Hz, and 1 kHz keeps 30 s loops small.
LOOP_SAMPLE_RATE_HZ = 1000.0
#: A sample belongs to a ramp (not a hold) when |dT/dt| exceeds this fraction of the
#: loop's typical ramp rate (95th percentile of |dT/dt|).
RAMP_RATE_FRACTION = 0.05
#: Fewest samples of a ramp branch, of each side of a knee fit, and of a stiffness window.
MIN_BRANCH_SAMPLES = 5
#: Default knee criterion: compliance below the knee / compliance above >= this.
DEFAULT_KNEE_RATIO = 1.5
#: Above-knee compliance below this fraction of the one below counts as "windup stopped".
STOP_RATIO = 1e-6
#: The knee fit ignores the first 2 % of a branch's windup travel (the stuck start).
START_TRIM = 0.02


# --- loops -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class HysteresisLoop:
    """One torque-ramp record.

    speed_rad_s: shaft speed [rad/s] (NaN if unknown); time_s [s]; torque_nm: input torque
    [N m]; windup_rad: total windup [rad] (input flange minus output transducer, the rig's
    measurement, [thesis] §3.3.1); windup_outer_rad, windup_inner_rad: per-set windup [rad]
    (simulation only, else None); output_torque_nm [N m] or None; protocol: name;
    lowpass_hz: break frequency applied [Hz] or None; result: the SimulationResult it came
    from (None for measured data).
    """

    speed_rad_s: float
    time_s: np.ndarray
    torque_nm: np.ndarray
    windup_rad: np.ndarray
    windup_outer_rad: np.ndarray | None = None
    windup_inner_rad: np.ndarray | None = None
    output_torque_nm: np.ndarray | None = None
    protocol: str = ""
    lowpass_hz: float | None = None
    label: str = ""
    result: object = field(default=None, repr=False)

    @property
    def speed_rpm(self) -> float:
        """Shaft speed [rpm]."""
        return float(rad_s_to_rpm(self.speed_rad_s))

    @property
    def sample_rate_hz(self) -> float:
        """Mean sample rate [Hz] of ``time_s``."""
        return (self.time_s.size - 1) / float(self.time_s[-1] - self.time_s[0])

    def windup(self, which: str = "total") -> np.ndarray:
        """Windup [rad] of ``which``: "total", "outer" or "inner"."""
        arr = {"total": self.windup_rad, "outer": self.windup_outer_rad, "inner": self.windup_inner_rad}
        if which not in arr:
            raise InputError(f"windup {which!r}: accepted is 'total', 'outer' or 'inner'")
        if arr[which] is None:
            raise InputError(f"this loop has no {which!r} windup (measured loops only have the total)")
        return arr[which]

    @classmethod
    def from_arrays(cls, torque_nm, windup_rad, time_s=None, sample_rate_hz=None, speed_rad_s=float("nan"), **kwargs):
        """A loop from measured arrays: torque [N m], total windup [rad], and either time
        stamps [s] or a sample rate [Hz] (one of them is needed for filtering)."""
        t, w = _pair(torque_nm, windup_rad)
        if time_s is None:
            if sample_rate_hz is None:
                raise InputError("give time_s [s] or sample_rate_hz [Hz] with the loop's samples")
            time_s = np.arange(t.size) / float(sample_rate_hz)
        time_s = np.asarray(time_s, dtype=float)
        if time_s.shape != t.shape or np.any(np.diff(time_s) <= 0):
            raise InputError("time_s must be strictly increasing and have one stamp per sample")
        return cls(float(speed_rad_s), time_s, t, w, **kwargs)

    @classmethod
    def from_result(cls, result, protocol: str = "", label: str = "") -> "HysteresisLoop":
        """The loop of an existing :class:`dampersim.SimulationResult` (no simulation)."""
        return cls(
            speed_rad_s=float(result.speed),
            time_s=result.t,
            torque_nm=result.input_torque,
            windup_rad=result.windup_total,
            windup_outer_rad=result.windup_outer,
            windup_inner_rad=result.windup_inner,
            output_torque_nm=result.output_torque,
            protocol=protocol,
            label=label or f"{rad_s_to_rpm(result.speed):.0f} rpm",
            result=result,
        )

    def filtered(self, cutoff_hz: float = LOWPASS_CUTOFF_HZ, zero_phase: bool = False) -> "HysteresisLoop":
        """The loop with every channel low-passed alike (:func:`lowpass_first_order`)."""
        fs = self.sample_rate_hz

        def f(x):
            return None if x is None else lowpass_first_order(x, fs, cutoff_hz, zero_phase)

        return replace(
            self,
            torque_nm=f(self.torque_nm),
            windup_rad=f(self.windup_rad),
            windup_outer_rad=f(self.windup_outer_rad),
            windup_inner_rad=f(self.windup_inner_rad),
            output_torque_nm=f(self.output_torque_nm),
            lowpass_hz=float(cutoff_hz),
        )


def _ramp(protocol, speed_rad_s, rate, hold):
    if isinstance(protocol, str):
        return protocol, ramp_protocol(protocol, speed_rad_s, rate=rate, hold=hold)
    try:
        points = tuple(float(p) for p in protocol)
    except (TypeError, ValueError):
        raise InputError(f"protocol {protocol!r}: accepted is a Table 3.1 name or a list of torque points [N m]") from None
    return "custom", TorqueRamp(speed=speed_rad_s, points=points, rate=rate, hold=hold)


def run_loops(
    system,
    protocol="full-450",
    speeds_rad_s=(),
    rate: float = 50.0,
    hold: float = 2.0,
    lowpass: bool = False,
    cutoff_hz: float = LOWPASS_CUTOFF_HZ,
    zero_phase: bool = False,
    record_segments: bool = False,
) -> list:
    """Simulate a torque-ramp protocol at each speed and return the loops.

    Args:
        system: :class:`dampersim.DamperSystem`. Its ``solver.output_sample_rate`` is
            lowered to 1 kHz if it is the 10 kHz default (ample for ramps of a few hundred
            N m/s, and 10x less memory); set it explicitly to keep another rate.
        protocol: a Table 3.1 name (see :data:`dampersim.excitation.ramps.PROTOCOLS`, e.g.
            "full-450") or a sequence of torque points [N m] ([thesis] §3.3.1).
        speeds_rad_s: shaft speeds [rad/s] (the thesis uses 1000-2000 rpm).
        rate: ramp rate [N m/s] (thesis: 50); hold: hold at each peak [s] (thesis: 2).
        lowpass: apply the first-order ``cutoff_hz`` [Hz] low pass to every channel, as
            the thesis did to its measured loops ([thesis] §3.4); ``zero_phase`` see
            :func:`lowpass_first_order`.
        record_segments: keep per-segment states in ``loop.result`` (for segment plots).

    Returns:
        List of :class:`HysteresisLoop`, one per speed, in the given order.
    """

    speeds = np.atleast_1d(np.asarray(speeds_rad_s, dtype=float))
    if speeds.size == 0 or not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
        raise InputError(f"speeds_rad_s {speeds_rad_s!r}: accepted is one or more positive speeds [rad/s]")
    if system.solver.output_sample_rate == 10000.0:
        system = with_updates(system, {"solver.output_sample_rate": LOOP_SAMPLE_RATE_HZ})
    loops = []
    for w in speeds:
        name, ramp = _ramp(protocol, float(w), rate, hold)
        res = simulate(system, ramp, record_segments=record_segments)
        loop = HysteresisLoop.from_result(res, protocol=name)
        if lowpass:
            loop = loop.filtered(cutoff_hz, zero_phase)
        loops.append(loop)
    return loops


# --- branches and stiffness -----------------------------------------------------------------
def _pair(torque, windup):
    try:
        t = np.asarray(torque, dtype=float)
        w = np.asarray(windup, dtype=float)
    except (TypeError, ValueError):
        raise InputError("torque [N m] and windup [rad] must be numeric arrays") from None
    if t.ndim != 1 or t.shape != w.shape or t.size < 2 * MIN_BRANCH_SAMPLES:
        raise InputError(
            f"torque and windup must be 1-D arrays of equal length >= {2 * MIN_BRANCH_SAMPLES}, "
            f"got shapes {t.shape} and {w.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(w))):
        raise InputError("torque/windup contain NaN or inf samples: clean or drop them")
    return t, w


def branch_directions(torque, rate_fraction: float = RAMP_RATE_FRACTION) -> np.ndarray:
    """Per-sample direction of the torque ramp: +1 loading, -1 unloading, 0 hold/turn.

    A sample is on a ramp when |dT/dn| exceeds ``rate_fraction`` times the 95th percentile
    of |dT/dn| over the record; runs shorter than 5 samples are treated as holds. Noisy
    measured torque should be low-passed first (:func:`lowpass_first_order`).
    """
    t = np.asarray(torque, dtype=float)
    d = np.gradient(t)
    ref = float(np.percentile(np.abs(d), 95))
    if ref <= 0:
        return np.zeros(t.size, dtype=int)
    s = np.where(np.abs(d) > rate_fraction * ref, np.sign(d), 0).astype(int)
    # drop short runs
    edges = np.flatnonzero(np.diff(s)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [s.size]))
    for a, b in zip(starts, ends):
        if s[a] != 0 and b - a < MIN_BRANCH_SAMPLES:
            s[a:b] = 0
    return s


def branch_labels(directions) -> np.ndarray:
    """Label each ramp run of ``directions`` 0, 1, 2, ... in time order; holds get -1."""
    s = np.asarray(directions)
    new = np.concatenate(([s[0] != 0], (np.diff(s) != 0) & (s[1:] != 0)))
    lab = np.cumsum(new) - 1
    return np.where(s != 0, lab, -1)


def dynamic_stiffness(torque, windup, window_nm: float | None = None, directions=None, min_span_rad: float | None = None) -> np.ndarray:
    """Local stiffness dT/dtheta [N m/rad] along a loop ([thesis] §7.3.1, Fig. 7.26).

    On each loading or unloading ramp (:func:`branch_directions`) the slope at a sample is
    the least-squares line T = a + k theta through the ramp's samples whose torque lies
    within +-``window_nm``/2 of the sample's torque. Windowing by torque (the controlled
    quantity of a ramp) gives the same resolution all along the ramp, averages noise, and
    never mixes the loading and unloading branches.

    Args:
        torque: torque [N m]; windup: windup [rad]; same length, in time order.
        window_nm: fitting window in torque [N m]; default 2 % of the loop's torque range.
        directions: precomputed :func:`branch_directions` (optional).
        min_span_rad: windows whose windup spans less than this [rad] give NaN (the windup
            has stopped, e.g. a set on its hardstop, and the slope is unbounded); default
            1e-4 of the loop's windup range.

    Returns:
        Array [N m/rad] aligned with the input; NaN on holds and turning points, where a
        window holds fewer than 5 samples, and where the windup stopped.
    """
    t, w = _pair(torque, windup)
    if window_nm is None:
        window_nm = 0.02 * float(np.ptp(t))
    if not (np.isfinite(window_nm) and window_nm > 0):
        raise InputError(f"window_nm {window_nm!r}: accepted is a positive torque window [N m]")
    if min_span_rad is None:
        min_span_rad = 1e-4 * float(np.ptp(w))
    s = branch_directions(t) if directions is None else np.asarray(directions)
    labels = branch_labels(s)
    out = np.full(t.size, np.nan)
    half = 0.5 * window_nm
    for lab in np.unique(labels[labels >= 0]):
        idx = np.flatnonzero(labels == lab)
        if idx.size < MIN_BRANCH_SAMPLES:
            continue
        order = np.argsort(t[idx], kind="stable")
        y = t[idx][order]
        x = w[idx][order]
        x0, y0 = x.mean(), y.mean()
        xc, yc = x - x0, y - y0
        c = [np.concatenate(([0.0], np.cumsum(v))) for v in (xc, yc, xc * xc, xc * yc)]
        lo = np.searchsorted(y, y - half, side="left")
        hi = np.searchsorted(y, y + half, side="right")
        n = (hi - lo).astype(float)
        sx, sy, sxx, sxy = (ci[hi] - ci[lo] for ci in c)
        den = n * sxx - sx * sx
        # windup travelled across the window (windup is near-monotone in torque on a ramp)
        span = np.abs(x[hi - 1] - x[lo])
        ok = (n >= MIN_BRANCH_SAMPLES) & (span > min_span_rad) & (den > 0)
        slope = np.full(x.size, np.nan)
        slope[ok] = (n[ok] * sxy[ok] - sx[ok] * sy[ok]) / den[ok]
        out[idx[order]] = slope
    return out


# --- knee ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Knee:
    """Knee of a loading curve from a two-slope fit.

    found: the curve stiffens by at least the asked ratio; windup_rad [rad], torque_nm
    [N m]: the knee; stiffness_below, stiffness_above [N m/rad] (inf: windup stops, e.g. a
    set on its hardstop); without a knee only stiffness_below is set (straight-line fit of
    the branch); rms_residual_rad [rad]: fit quality; branch: "positive" or "negative".
    """

    found: bool
    windup_rad: float
    torque_nm: float
    stiffness_below: float
    stiffness_above: float
    rms_residual_rad: float
    branch: str = "positive"

    def to_dict(self, angle_unit: str = "deg") -> dict:
        """Plain dict in display units (angles in ``angle_unit``, stiffness in N m/unit)."""
        conv = rad_to_deg if angle_unit == "deg" else (lambda x: x)
        inv = (lambda k: k / rad_to_deg(1.0)) if angle_unit == "deg" else (lambda k: k)
        fin = lambda v: v if math.isfinite(v) else None  # noqa: E731 (JSON has no inf/nan)
        return {
            "found": self.found,
            f"windup_{angle_unit}": fin(float(conv(self.windup_rad))),
            "torque_nm": fin(self.torque_nm),
            f"stiffness_below_nm_per_{angle_unit}": fin(float(inv(self.stiffness_below))),
            f"stiffness_above_nm_per_{angle_unit}": fin(float(inv(self.stiffness_above))),
            "branch": self.branch,
        }


_NO_KNEE = dict(found=False, windup_rad=math.nan, torque_nm=math.nan, stiffness_below=math.nan, stiffness_above=math.nan, rms_residual_rad=math.nan)


def _two_slope_fit(tq, th, tk):
    """Continuous two-slope least squares theta = a + c1 T + dc * max(T - tk, 0)."""
    A = np.column_stack((np.ones_like(tq), tq, np.maximum(tq - tk, 0.0)))
    coef, *_ = np.linalg.lstsq(A, th, rcond=None)
    r = th - A @ coef
    return coef, float(r @ r)


def find_knee(torque, windup, branch: str = "positive", min_ratio: float = DEFAULT_KNEE_RATIO, directions=None, max_points: int = 4000) -> Knee:
    """Find where a loading curve stiffens (the knee, [thesis] §6.3.2, §7.3.1).

    Takes the loading samples of the branch (``"positive"``: rising torque above 0;
    ``"negative"``: falling torque below 0, mirrored), drops the first 2 % of their windup
    travel (where friction still holds the springs after a reversal) and fits windup as a continuous
    two-slope function of torque, theta = a + c1 T + (c2 - c1) max(T - T_k, 0): compliance
    c1 below the knee torque T_k and c2 above. Fitting windup against torque (the
    controlled quantity) stays well-posed when the windup stops altogether above the knee
    (c2 = 0, infinite stiffness, a set on its hardstop). T_k is chosen on a grid of torque
    quantiles and refined with a bounded scalar search; the fit is exact for exactly
    bilinear data.

    Args:
        torque [N m], windup [rad]: loop samples in time order.
        branch: "positive" or "negative".
        min_ratio: a knee is reported (``found``) when c1 / c2 >= this (stiffness jumps by
            at least this factor) or the windup stops (c2 below 1e-6 c1; the stiffness
            above is then reported as inf).
        directions: precomputed :func:`branch_directions`.
        max_points: thin the branch to about this many samples (speed only).

    Returns:
        :class:`Knee` (windup and torque of the knee, stiffness below/above [N m/rad]).
        Without a knee (``found`` False) the windup, torque and stiffness above are NaN and
        ``stiffness_below`` is the straight-line stiffness of the whole branch (NaN too if
        the branch has too few samples).
    """
    from scipy.optimize import minimize_scalar

    t, w = _pair(torque, windup)
    if branch not in ("positive", "negative"):
        raise InputError(f"branch {branch!r}: accepted is 'positive' or 'negative'")
    s = branch_directions(t) if directions is None else np.asarray(directions)
    sign = 1.0 if branch == "positive" else -1.0
    sel = (s == sign) & (sign * t > 0)
    tq, th = sign * t[sel], sign * w[sel]
    if tq.size:
        # drop the start of the branch where the windup has not moved yet (friction holds
        # the springs until the torque change exceeds it): a vertical piece, not the knee
        travel = float(th.max() - th.min())
        keep = th > th.min() + START_TRIM * travel
        tq, th = tq[keep], th[keep]
    if tq.size < 4 * MIN_BRANCH_SAMPLES:
        return Knee(branch=branch, **_NO_KNEE)
    if tq.size > max_points:
        keep = np.unique(np.linspace(0, tq.size - 1, max_points).round().astype(int))
        tq, th = tq[keep], th[keep]
    srt = np.sort(tq)
    lo_i, hi_i = 2 * MIN_BRANCH_SAMPLES, srt.size - 2 * MIN_BRANCH_SAMPLES - 1
    if hi_i <= lo_i or srt[hi_i] <= srt[lo_i]:
        return Knee(branch=branch, **_NO_KNEE)
    cand = np.unique(np.quantile(srt[lo_i:hi_i + 1], np.linspace(0, 1, 101)))
    sse = np.array([_two_slope_fit(tq, th, c)[1] for c in cand])
    j = int(np.argmin(sse))
    a, b = cand[max(j - 1, 0)], cand[min(j + 1, cand.size - 1)]
    tk = cand[j]
    if b > a:
        res = minimize_scalar(lambda x: _two_slope_fit(tq, th, x)[1], bounds=(a, b), method="bounded", options={"xatol": 1e-10 * max(abs(b), 1.0)})
        if res.fun <= sse[j]:
            tk = float(res.x)
    coef, err = _two_slope_fit(tq, th, tk)
    c1, c2 = float(coef[1]), float(coef[1] + coef[2])
    # a compliance below 1e-6 of the one below the knee means the windup has stopped (the
    # fit's round-off leaves such a residue; real contact stiffnesses stay well below 1e6 x)
    tiny = STOP_RATIO * max(abs(c1), 1e-30)
    k1 = 1.0 / c1 if c1 > 0 else math.inf
    k2 = 1.0 / c2 if c2 > tiny else math.inf
    found = c1 > 0 and (c2 <= tiny or c1 / c2 >= min_ratio)
    if not found:
        # no stiffening: report the straight-line stiffness of the whole branch
        A = np.column_stack((np.ones_like(tq), tq))
        (a0, c), *_ = np.linalg.lstsq(A, th, rcond=None)
        r = th - A @ np.array([a0, c])
        return Knee(
            found=False,
            windup_rad=math.nan,
            torque_nm=math.nan,
            stiffness_below=1.0 / c if c > 0 else math.inf,
            stiffness_above=math.nan,
            rms_residual_rad=math.sqrt(float(r @ r) / tq.size),
            branch=branch,
        )
    theta_k = float(coef[0] + c1 * tk)
    return Knee(
        found=bool(found),
        windup_rad=sign * theta_k,
        torque_nm=sign * float(tk),
        stiffness_below=k1,
        stiffness_above=k2,
        rms_residual_rad=math.sqrt(err / tq.size),
        branch=branch,
    )


# --- energy ----------------------------------------------------------------------------------
def closed_part(torque, windup) -> tuple:
    """(start, stop) sample indices of the closed part of a ramp loop.

    Start: the last sample before the torque first leaves its starting value (drops the
    constant lead-in). Stop: among the samples after the last turning point, the one
    closest to the start point (windup and torque each scaled by the loop's range). For a
    loop that returns to its start this is the whole loop; when the windup has crept (e.g.
    slip during the holds, [thesis] §6.3.2) it is where the path comes back nearest.
    """
    t, w = _pair(torque, windup)
    moved = np.flatnonzero(np.abs(t - t[0]) > 1e-9 * max(float(np.ptp(t)), 1e-300))
    if moved.size == 0:
        raise InputError("torque never changes: not a loop")
    i0 = max(int(moved[0]) - 1, 0)
    s = branch_directions(t)
    ramps = np.flatnonzero(s != 0)
    # the last ramp run starts after the last direction change
    last_start = i0
    if ramps.size:
        lab = branch_labels(s)
        last_start = int(np.flatnonzero(lab == lab[ramps[-1]])[0])
    tail = np.arange(max(last_start, i0 + 1), t.size)
    if tail.size == 0:
        return i0, t.size - 1
    sw = max(float(np.ptp(w)), 1e-300)
    st = max(float(np.ptp(t)), 1e-300)
    dist = ((w[tail] - w[i0]) / sw) ** 2 + ((t[tail] - t[i0]) / st) ** 2
    return i0, int(tail[np.argmin(dist)])


def loop_energy(torque, windup, closed: bool = True) -> float:
    """Energy dissipated in one loop: the closed integral of T dtheta [J] ([thesis] §6.3.2).

    Args:
        torque [N m], windup [rad]: the loop in time order.
        closed: first cut the record to :func:`closed_part`; False integrates all samples
            given (use this when they already form exactly one cycle).

    The path is integrated with the trapezoidal rule and closed with a straight segment
    from the last sample back to the first. Clockwise loops in the (windup, torque) plane
    (loading above unloading, as friction makes them) give a positive energy.
    """
    t, w = _pair(torque, windup)
    if closed:
        i0, i1 = closed_part(t, w)
        t, w = t[i0:i1 + 1], w[i0:i1 + 1]
    tt = np.append(t, t[0])
    ww = np.append(w, w[0])
    return float(np.sum(0.5 * (tt[1:] + tt[:-1]) * np.diff(ww)))


# --- one-stop analysis -----------------------------------------------------------------------
@dataclass(frozen=True)
class LoopAnalysis:
    """Figures of one loop: speed [rad/s]; knee of the total windup; knee of the outer set
    (simulation only) and the outer positive hardstop [rad] to compare it with; energy per
    loop [J]; closure gap [rad] (windup difference between the closed part's ends); windup
    range [rad]."""

    speed_rad_s: float
    knee: Knee
    energy_j: float
    closure_gap_rad: float
    max_windup_rad: float
    min_windup_rad: float
    outer_knee: Knee | None = None
    outer_hardstop_positive_rad: float | None = None
    label: str = ""

    def to_dict(self, angle_unit: str = "deg") -> dict:
        """JSON-ready dict in display units (rpm, ``angle_unit``, N m, J)."""
        conv = rad_to_deg if angle_unit == "deg" else (lambda x: x)
        fin = lambda v: None if v is None or not math.isfinite(v) else float(v)  # noqa: E731
        return {
            "label": self.label,
            "speed_rpm": fin(rad_s_to_rpm(self.speed_rad_s)),
            "knee": self.knee.to_dict(angle_unit),
            "energy_per_loop_j": fin(self.energy_j),
            f"closure_gap_{angle_unit}": fin(conv(self.closure_gap_rad)),
            f"max_windup_{angle_unit}": fin(conv(self.max_windup_rad)),
            f"min_windup_{angle_unit}": fin(conv(self.min_windup_rad)),
            "outer_knee": None if self.outer_knee is None else self.outer_knee.to_dict(angle_unit),
            f"outer_hardstop_positive_{angle_unit}": fin(None if self.outer_hardstop_positive_rad is None else conv(self.outer_hardstop_positive_rad)),
        }


def analyse_loop(loop: HysteresisLoop, system=None, min_ratio: float = DEFAULT_KNEE_RATIO) -> LoopAnalysis:
    """Knee, stiffness below/above it and energy per loop of one :class:`HysteresisLoop`.

    ``system`` (default: the loop's result's parameters, if any) supplies the outer set's
    positive hardstop windup [rad] for comparison with the outer-set knee.
    """
    t, w = loop.torque_nm, loop.windup_rad
    s = branch_directions(t)
    knee = find_knee(t, w, "positive", min_ratio, directions=s)
    i0, i1 = closed_part(t, w)
    energy = loop_energy(t[i0:i1 + 1], w[i0:i1 + 1], closed=False)
    outer_knee = None
    if loop.windup_outer_rad is not None:
        outer_knee = find_knee(t, loop.windup_outer_rad, "positive", min_ratio, directions=s)
    if system is None and loop.result is not None:
        system = getattr(loop.result, "parameters", None)
    hs = None if system is None else float(system.outer.hardstop_positive)
    return LoopAnalysis(
        speed_rad_s=loop.speed_rad_s,
        knee=knee,
        energy_j=energy,
        closure_gap_rad=float(w[i1] - w[i0]),
        max_windup_rad=float(np.max(w)),
        min_windup_rad=float(np.min(w)),
        outer_knee=outer_knee,
        outer_hardstop_positive_rad=hs,
        label=loop.label,
    )


__all__ = [
    "HysteresisLoop",
    "Knee",
    "LoopAnalysis",
    "run_loops",
    "branch_directions",
    "branch_labels",
    "dynamic_stiffness",
    "find_knee",
    "closed_part",
    "loop_energy",
    "analyse_loop",
]
