"""Repeatability of one test point: the same point run K times with every input order
amplitude scaled by (1 + i·1e-9), i = 0…K−1, and the spread of each output order amplitude
over the K runs.

A change of 1e-9 relative is far below anything a rig or an engine reproduces, so in a
well-behaved (non-chaotic) regime every output order moves by about 1e-9 relative too and
the spread is about 1e-7 %. Where the springs' stick-slip pattern is chaotic (docs/model.md,
"Accuracy and its limits") the same change moves an order by per cent: the spread says how
far one run's value of that order can be trusted. Whether it is numerical or physical is
seen by repeating it at a smaller ``solver.time_step``: a numerical spread shrinks with the
step, a physical one does not. :func:`spread_check` runs the K runs again at half the step
and :func:`spread_origin` labels each order by the rule stated there (and in
docs/model.md §14).
"""

from __future__ import annotations

import dataclasses
import math
import operator
from dataclasses import dataclass

import numpy as np
import pandas as pd

from dampersim import costs
from dampersim.errors import InputError
from dampersim.parameters import with_updates
from dampersim.results import ANALYSIS_WINDOW
from dampersim.signal import order_amplitudes
from dampersim.simulation import simulate

#: Relative amplitude step between runs [-]: run i scales every input order by (1 + i·STEP).
STEP = 1e-9
#: Accepted numbers of runs K [-].
MIN_RUNS, MAX_RUNS = 2, 32
#: An order whose median output is below this share of the largest order's median output
#: [-] gets no spread (a ratio of near-zero amplitudes says nothing).
MIN_OUTPUT_REL = 1e-3
#: Spread floor of the origin labels [%]: a spread below it at both steps is not labelled
#: (the 1e-9 input change alone spreads a well-behaved order by about (K - 1)·1e-7 %, and
#: 0.01 % is a hundredth of the 1 % an order must agree with a fine reference, so a spread
#: under it changes no reading of an amplitude); ``physical`` needs it at both steps.
SPREAD_FLOOR_PCT = 0.01
#: Labels of :func:`spread_origin`.
PHYSICAL, NUMERICAL = "physical", "numerical"


@dataclass(frozen=True)
class Repeatability:
    """K runs of one test point.

    result: run 0 (the unscaled input, the same result a single run gives);
    orders: the analysed engine orders [-]; scales: the input amplitude factor of each run
    [-]; output_nm: output order amplitudes [N m], shape (K, len(orders));
    spread_pct: per order 100·(max − min)/median of the K output amplitudes [%], or None
    where the median is below :data:`MIN_OUTPUT_REL` of the largest median.
    """

    result: object
    orders: tuple
    scales: tuple
    output_nm: np.ndarray
    spread_pct: tuple

    @property
    def runs(self) -> int:
        return len(self.scales)

    def output_range_nm(self):
        """(min, max) over the K runs of each order's output amplitude [N m]."""
        return self.output_nm.min(axis=0), self.output_nm.max(axis=0)


def check_runs(runs, name: str = "K") -> int:
    """``runs`` as an int from :data:`MIN_RUNS` to :data:`MAX_RUNS`; otherwise InputError
    naming ``name``, the value and what is accepted."""
    try:
        k = operator.index(runs) if not isinstance(runs, bool) else None
    except TypeError:
        k = None
    if k is None and isinstance(runs, float) and math.isfinite(runs) and runs.is_integer():
        k = int(runs)
    if k is None or not (MIN_RUNS <= k <= MAX_RUNS):
        raise InputError(f"{name} = {runs!r}: accepted is a whole number of runs from {MIN_RUNS} to {MAX_RUNS}")
    return k


def scaled_excitation(excitation, scale: float):
    """``excitation`` (an OrderSum) with every order amplitude multiplied by ``scale`` [-];
    the mean torque, phases and start-up are unchanged."""
    orders = getattr(excitation, "orders", None)
    if orders is None or not dataclasses.is_dataclass(excitation):
        raise InputError(f"excitation {type(excitation).__name__}: accepted is an order sum (OrderSum)")
    return dataclasses.replace(excitation, orders=tuple((k, a * scale, ph) for k, a, ph in orders))


def spread_pct(output_nm, min_rel: float = MIN_OUTPUT_REL) -> tuple:
    """Per column of ``output_nm`` (runs x orders, [N m]): 100·(max − min)/median [%], or
    None where the median is zero or below ``min_rel`` of the largest median."""
    a = np.asarray(output_nm, dtype=float)
    med = np.median(a, axis=0)
    top = float(np.nanmax(med)) if np.isfinite(med).any() else 0.0  # an order above Nyquist is NaN
    out = []
    for j, m in enumerate(med):
        if not (m > 0 and m >= min_rel * top):
            out.append(None)
        else:
            out.append(float(100.0 * (np.max(a[:, j]) - np.min(a[:, j])) / m))
    return tuple(out)


def repeatability(system, excitation, runs: int, orders=tuple(range(1, 9)), seconds: float = ANALYSIS_WINDOW,
                  duration: float | None = None, record_segments: bool = False, run0=None,
                  simulate_fn=simulate) -> Repeatability:
    """Run one test point ``runs`` (K, 2-32) times, run i with every input order amplitude
    scaled by (1 + i·1e-9), and return run 0 with the spread of each output order.

    excitation: an OrderSum (mean torque [N m], orders with amplitude [N m]); orders: the
    engine orders [-] analysed over the last ``seconds`` [s] of each record; duration [s]
    as :func:`dampersim.simulation.simulate`. The runs go one after the other (the cost is
    K single runs); each run's excitation differs, so no cache can hand one run's result to
    another. ``run0``: run 0's result when the caller has it already (the unscaled point
    with the same system and duration); it is analysed, not run again. Raises InputError for K outside 2-32 or not a whole number, and whatever
    :func:`simulate` raises.
    """
    k_runs = check_runs(runs)
    orders = tuple(float(k) for k in orders)
    scales = tuple(1.0 + i * STEP for i in range(k_runs))
    kept = []
    out = _output_rows(system, excitation, scales, orders, seconds, duration, simulate_fn, run0=run0,
                       record_segments=record_segments, keep=kept.append)
    return Repeatability(result=kept[0], orders=orders, scales=scales, output_nm=out, spread_pct=spread_pct(out))


def _output_rows(system, excitation, scales, orders, seconds, duration, simulate_fn, run0=None, record_segments=False,
                 keep=None) -> np.ndarray:
    """Output order amplitudes [N m] (runs x orders) of one run per scale; run 0's result
    goes to ``keep`` (when given), the others are dropped as soon as they are analysed."""
    rows = []
    for i, s in enumerate(scales):
        ex = excitation if s == 1.0 else scaled_excitation(excitation, s)
        if s == 1.0 and run0 is not None:
            res = run0
        else:
            res = simulate_fn(system, ex, duration=duration, record_segments=record_segments and i == 0)
        w = res.window(seconds)
        rows.append(np.asarray(order_amplitudes(res.output_torque[w], res.sample_rate, res.speed, orders), dtype=float))
        if i == 0 and keep is not None:
            keep(res)
    return np.vstack(rows)


def spread_origin(spread_dt, spread_half, floor_pct: float = SPREAD_FLOOR_PCT) -> tuple:
    """Label each order's spread by how it changes when the step halves.

    spread_dt, spread_half: per order the spread [%] at the step and at half of it (None
    where the order's median output is below 0.1 % of the largest, :func:`spread_pct`).
    Per order: None where either spread is None, or where both are below ``floor_pct``
    [%] (nothing to label); ``"physical"`` where both are at or above the floor and the
    spread at half the step is at least half the spread at the step (it does not shrink
    with the step); ``"numerical"`` otherwise (it falls below half, or it is above the
    floor at one step only: it depends on the step).
    """
    if len(spread_dt) != len(spread_half):
        raise InputError(f"spreads of {len(spread_dt)} and {len(spread_half)} orders: accepted are spreads of the same orders")
    out = []
    for a, b in zip(spread_dt, spread_half):
        if a is None or b is None or (a < floor_pct and b < floor_pct):
            out.append(None)
        elif a >= floor_pct and b >= floor_pct and b >= 0.5 * a:
            out.append(PHYSICAL)
        else:
            out.append(NUMERICAL)
    return tuple(out)


def half_step(system):
    """``system`` with ``solver.time_step`` halved (everything else unchanged)."""
    return with_updates(system, {"solver.time_step": float(system.solver.time_step) / 2.0})


@dataclass(frozen=True)
class SpreadCheck:
    """The K runs of a :class:`Repeatability` again at half the step.

    time_step: the half step [s]; output_nm: output order amplitudes [N m] at it, shape
    (K, len(orders)); spread_pct: their spread per order [%] (None as in
    :func:`spread_pct`); origin: :func:`spread_origin` of the two spreads per order.
    """

    time_step: float
    output_nm: np.ndarray
    spread_pct: tuple
    origin: tuple


def spread_check(system, excitation, rep: Repeatability, seconds: float = ANALYSIS_WINDOW, duration: float | None = None,
                 simulate_fn=simulate) -> SpreadCheck:
    """Run the K runs of ``rep`` (same input scales and orders) again with
    ``solver.time_step`` halved and label each order's spread (:func:`spread_origin`).

    Costs K runs at half the step (twice the steps of a run each, :func:`repeatability_cost`);
    no result is kept. Raises what :func:`simulate` raises (e.g. ParameterError when half the
    step is below the accepted range).
    """
    half = half_step(system)
    out = _output_rows(half, excitation, rep.scales, rep.orders, seconds, duration, simulate_fn)
    spread = spread_pct(out)
    return SpreadCheck(time_step=float(half.solver.time_step), output_nm=out, spread_pct=spread,
                       origin=spread_origin(rep.spread_pct, spread))


def sweep_spread(table, n_points: int) -> pd.DataFrame:
    """Spread of a sweep whose ``n_points`` test points were each run K times, run i with
    the input amplitudes scaled by (1 + i·1e-9): in ``table`` (a sweep table with a
    ``point`` column, :class:`dampersim.sweeps.SweepResult`), point p is run p // n_points
    of test point p % n_points.

    Returns one row per test point and order: ``point`` (0 to n_points - 1),
    ``speed_rad_s`` [rad/s], ``order`` [-], ``output_min_nm`` and ``output_max_nm`` [N m]
    and ``mr_min`` and ``mr_max`` [-] over the K runs (NaN where an order has no ratio),
    and ``spread_pct`` [%] (:func:`spread_pct` over that point's orders; NaN where None).
    Raises InputError for a table without those columns or whose points are not K runs of
    ``n_points`` with K from 2 to 32.
    """
    need = ("point", "speed_rad_s", "order", "output_amplitude_nm", "magnification")
    if not isinstance(table, pd.DataFrame) or any(c not in table.columns for c in need):
        raise InputError(f"sweep table: accepted is a DataFrame with columns {list(need)}")
    n = int(n_points)
    total = int(table["point"].max()) + 1 if len(table) else 0
    if n < 1 or total % n:
        raise InputError(f"{total} sweep points are not whole runs of {n} test points: accepted is K runs of each point")
    check_runs(total // n, "runs of the sweep")
    t = table.assign(base=table["point"].to_numpy() % n, run=table["point"].to_numpy() // n)
    out = t.groupby(["base", "order"], sort=True).agg(
        speed_rad_s=("speed_rad_s", "first"), output_min_nm=("output_amplitude_nm", "min"),
        output_max_nm=("output_amplitude_nm", "max"), mr_min=("magnification", "min"), mr_max=("magnification", "max"))
    spreads = {}
    for base, grp in t.groupby("base"):
        amps = grp.pivot(index="run", columns="order", values="output_amplitude_nm")
        for k, v in zip(amps.columns, spread_pct(amps.to_numpy(float))):
            spreads[(base, k)] = np.nan if v is None else v
    out["spread_pct"] = [spreads[i] for i in out.index]
    return out.reset_index().rename(columns={"base": "point"})


def repeatability_cost(system, duration: float, runs: int, spread: bool = False, record_segments: bool = False):
    """The :class:`dampersim.costs.Cost` of :func:`repeatability` (K runs of ``duration``
    [s] one after the other, run 0 kept while the others run) and, with ``spread``, of
    :func:`spread_check` (K more runs at half the step, each of twice the steps)."""
    k = check_runs(runs)
    one = costs.point_cost(system, duration, record_segments)
    work, peak = k * one.work, 2 * one.bytes
    if spread:
        half = costs.point_cost(half_step(system), duration, record_segments=False)
        work, peak = work + k * half.work, max(peak, one.bytes + half.bytes)
    what = f"this test point run {k} times (repeatability)" + (f" and {k} times at half the step" if spread else "")
    return costs.Cost(float(work), float(peak), what)


__all__ = ["STEP", "MIN_RUNS", "MAX_RUNS", "MIN_OUTPUT_REL", "SPREAD_FLOOR_PCT", "PHYSICAL", "NUMERICAL", "Repeatability",
           "SpreadCheck", "check_runs", "scaled_excitation", "spread_pct", "repeatability", "spread_origin", "half_step",
           "spread_check", "sweep_spread", "repeatability_cost"]
