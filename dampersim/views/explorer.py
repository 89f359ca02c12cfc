"""The Explorer page's data: one simulated test point as time traces, spectra with order
markers, magnification per order, windup per set against the hardstops and the energy
balance, cached as one view.
"""

from __future__ import annotations

import time

import numpy as np

from dampersim.analysis.order_table import order_table
from dampersim.analysis.repeatability import repeatability, spread_check
from dampersim.plotting import (
    energy_balance_figure,
    mr_figure,
    recent_traces_figure,
    windowed_spectrum_figure,
    windup_figure,
)
from dampersim.units import number_text
from dampersim.results import ANALYSIS_WINDOW
from dampersim.simulation import simulate
from dampersim.units import rad_to_deg
from dampersim.views.state import point_excitation
from dampersim.views.store import cached_view, view_key

#: Display thinning of long time series (points per trace).
TRACE_POINTS = 4000
ENERGY_POINTS = 2000


def analysis_seconds(duration: float, steady_start: float = 0.6) -> float:
    """Analysis window [s]: the thesis's 1.25 s, shortened to fit after the start-up."""
    return float(min(ANALYSIS_WINDOW, max(duration - steady_start, 0.2)))


def _energy_summary(result) -> dict:
    e = result.energy
    resid = result.energy_residual()
    work = float(abs(e["input_work"][-1]) + abs(e["motor_work"][-1]))
    return {
        "input_work_j": float(e["input_work"][-1]),
        "dissipated_j": float(e["friction"][-1] + e["damping"][-1] + e["stacking"][-1]),
        "friction_j": float(e["friction"][-1]),
        "residual_j": float(resid[-1]),
        "residual_rel": float(abs(resid[-1]) / work) if work > 0 else 0.0,
    }


def with_spread(rows, rep) -> list:
    """Order rows of :func:`order_table` with the spread of a
    :class:`~dampersim.analysis.repeatability.Repeatability` over the same orders:
    ``spread_pct`` [%] (None where the order's output is below 0.1 % of the largest),
    ``output_range_nm`` [min, max] [N m] and ``mr_range`` [min, max] [-] (None without a
    ratio) over the K runs."""
    lo, hi = rep.output_range_nm()
    out = []
    for j, r in enumerate(rows):
        r = dict(r)
        r["spread_pct"] = rep.spread_pct[j]
        r["output_range_nm"] = [float(lo[j]), float(hi[j])]
        mr = r.get("mr")
        ok = mr is not None and r["output_nm"] > 0 and rep.spread_pct[j] is not None
        r["mr_range"] = [mr * float(lo[j]) / r["output_nm"], mr * float(hi[j]) / r["output_nm"]] if ok else None
        out.append(r)
    return out


def with_origin(rows, check) -> list:
    """Rows of :func:`with_spread` with a
    :class:`~dampersim.analysis.repeatability.SpreadCheck` of the same orders:
    ``spread_half_pct`` [%] (the spread at half the step, None as ``spread_pct``) and
    ``spread_origin`` ("physical", "numerical" or None,
    :func:`dampersim.analysis.repeatability.spread_origin`)."""
    return [{**r, "spread_half_pct": check.spread_pct[j], "spread_origin": check.origin[j]} for j, r in enumerate(rows)]


def _explorer_key(system, state, **_):
    return view_key("explorer", system, state, module=__name__)


def explorer_key(system, state) -> str:
    """The view-cache key of the Explorer view of ``state`` with ``system``."""
    return _explorer_key(system, state)


@cached_view(_explorer_key)
def explorer_view(system, state: dict, use_cache: bool = True) -> dict:
    """One test point: traces, spectra with order markers, MR per order, windup per set
    with hardstop limits and the energy balance.

    state: from :func:`dampersim.views.state.parse_query` ("explorer"): speed [rpm], torque
    [N m], orders ("2:300,4:100@90", phase in deg), duration [s], repeat (None or K runs:
    the point runs K times with the input amplitudes scaled by 1 + i·1e-9 and each order
    row gets ``spread_pct`` [%], ``output_range_nm`` and ``mr_range`` over the K runs,
    :func:`with_spread`; the figures and the rest show run 0), spread_check (True: with
    repeat, the K runs again at half ``solver.time_step``, each row labelled by
    :func:`with_origin`). Returns a dict with
    ``figures`` (traces, spectrum, mr, windup, energy), ``orders`` (rows of
    :func:`dampersim.analysis.order_table.order_table`), ``summary`` and ``key``;
    ``from_cache`` tells whether it came from the view cache.
    Raises ParameterError / InputError / SimulationDiverged with a clear message.
    """
    t0 = time.perf_counter()
    ex = point_excitation(state)
    duration = float(state["duration"])
    res = simulate(system, ex, duration=duration, record_segments=False)
    seconds = analysis_seconds(duration, ex.steady_start)
    excited = [k for k, a, _ in ex.orders if a > 0]
    rows = order_table(res, excited, seconds)
    runs = state.get("repeat")
    if runs:
        rep = repeatability(system, ex, int(runs), [r["order"] for r in rows], seconds, duration=duration, run0=res)
        rows = with_spread(rows, rep)
        if state.get("spread_check"):
            rows = with_origin(rows, spread_check(system, ex, rep, seconds, duration=duration))
    speed_rpm = float(state["speed"])
    traces = recent_traces_figure(res, duration, max_points=TRACE_POINTS,
                                  title=f"Torque at {number_text(round(speed_rpm, 1))} rpm, {number_text(state['torque'])} N m mean")
    figures = {
        "traces": traces.to_dict(),
        "spectrum": windowed_spectrum_figure(res, seconds).to_dict(),
        "mr": mr_figure(rows, runs=int(runs) if runs else None).to_dict(),
        "windup": windup_figure(res, system, max_points=TRACE_POINTS).to_dict(),
        "energy": energy_balance_figure(res, max_points=ENERGY_POINTS).to_dict(),
    }
    w = res.window(seconds)
    main = max((r for r in rows if r["excited"] and r["mr"] is not None), key=lambda r: r["input_nm"], default=None)
    summary = {
        "speed_rpm": speed_rpm,
        "mean_torque_nm": float(state["torque"]),
        "duration_s": duration,
        "analysis_window_s": seconds,
        "main_order": main["order"] if main else None,
        "main_mr": main["mr"] if main else None,
        "mean_output_torque_nm": float(np.mean(res.output_torque[w])),
        "windup_outer_deg": [float(rad_to_deg(np.min(res.windup_outer[w]))), float(rad_to_deg(np.max(res.windup_outer[w])))],
        "windup_inner_deg": [float(rad_to_deg(np.min(res.windup_inner[w]))), float(rad_to_deg(np.max(res.windup_inner[w])))],
        "hardstop_outer_share": float(np.mean(res.hardstop_outer[w] != 0.0)),
        "hardstop_inner_share": float(np.mean(res.hardstop_inner[w] != 0.0)),
        "kernel_time_s": float(res.wall_time),
        "repeat": int(runs) if runs else None,
        "spread_check": bool(runs and state.get("spread_check")),
        **_energy_summary(res),
    }
    summary["compute_time_s"] = time.perf_counter() - t0
    return {"kind": "explorer", "figures": figures, "orders": rows, "summary": summary}


__all__ = ["TRACE_POINTS", "ENERGY_POINTS", "analysis_seconds", "explorer_key", "explorer_view", "with_spread", "with_origin"]
