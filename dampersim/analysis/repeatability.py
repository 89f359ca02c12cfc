"""Repeatability of one test point: the same point run K times with every input order
amplitude scaled by (1 + i·1e-9), i = 0…K−1, and the spread of each output order amplitude
over the K runs.

A change of 1e-9 relative is far below anything a rig or an engine reproduces, so in a
well-behaved (non-chaotic) regime every output order moves by about 1e-9 relative too and
the spread is about 1e-7 %. Where the springs' stick-slip pattern is chaotic (docs/model.md,
"Accuracy and its limits") the same change moves an order by per cent: the spread says how
far one run's value of that order can be trusted. Whether it is numerical or physical is
seen by repeating it at a smaller ``solver.time_step``: a numerical spread shrinks with the
step, a physical one does not.
"""

from __future__ import annotations

import dataclasses
import math
import operator
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError
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
    top = float(np.max(med)) if med.size else 0.0
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
    first = None
    rows = []
    for s in scales:
        ex = excitation if s == 1.0 else scaled_excitation(excitation, s)
        if s == 1.0 and run0 is not None:
            res = run0
        else:
            res = simulate_fn(system, ex, duration=duration, record_segments=record_segments and first is None)
        w = res.window(seconds)
        rows.append(np.asarray(order_amplitudes(res.output_torque[w], res.sample_rate, res.speed, orders), dtype=float))
        if first is None:
            first = res
    out = np.vstack(rows)
    return Repeatability(result=first, orders=orders, scales=scales, output_nm=out, spread_pct=spread_pct(out))


__all__ = ["STEP", "MIN_RUNS", "MAX_RUNS", "MIN_OUTPUT_REL", "Repeatability", "check_runs", "scaled_excitation",
           "spread_pct", "repeatability"]
