"""The Hysteresis page's data: torque-ramp protocols at each speed as hysteresis loops,
dynamic stiffness along the loading branch and energy per loop, with each speed's loop
cached on its own so display options and added speeds reuse the loops simulated.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from dampersim.analysis.hysteresis import HysteresisLoop, analyse_loop, run_loops
from dampersim.errors import InputError
from dampersim.excitation import PROTOCOLS, ramp_protocol
from dampersim.plotting import hysteresis_figure, loop_energy_figure, stiffness_figure
from dampersim.units import number_text
from dampersim.sweeps.grid import parse_values
from dampersim.units import rpm_to_rad_s
from dampersim.views.store import cached_view, load_view, save_view, view_key

#: Angle unit of the loop table (the page shows degrees).
ANGLE_UNIT = "deg"
#: The ramp protocols a page offers.
PROTOCOL_NAMES = tuple(PROTOCOLS)
#: Arrays of a loop kept in the cache.
_LOOP_ARRAYS = ("time_s", "torque_nm", "windup_rad", "windup_outer_rad", "windup_inner_rad", "output_torque_nm")


def protocol_label(name: str) -> str:
    """A protocol with its torque points: "full-450  (0 → 450 → -450 → 0 N m)"."""
    start, pos, neg, end = PROTOCOLS[name]
    pts = [p for p in (start, pos, neg, end) if p is not None]
    return f"{name}  ({' → '.join(f'{p:g}' for p in pts)} N m)"


def simulated_seconds(state) -> float:
    """Simulated time [s] of one loop of a Hysteresis page state (protocol, rate, hold)."""
    return ramp_protocol(state["protocol"], 100.0, rate=float(state["rate"]), hold=float(state["hold"])).duration


def _loop_key(system, state, rpm) -> str:
    """Key of one simulated loop: only what the simulation depends on (display options such
    as the windup shown or the low pass are applied afterwards)."""
    return view_key("hysteresis-loop", system, {"protocol": state["protocol"], "speed_rpm": float(rpm),
                                                "rate": float(state["rate"]), "hold": float(state["hold"])}, module=__name__)


def _load_loop(key):
    data = load_view(key)
    if data is None or "loop" not in data:
        return None
    d = data["loop"]
    return HysteresisLoop(speed_rad_s=d["speed_rad_s"], protocol=d["protocol"], label=d["label"],
                          **{k: (np.asarray(d[k]) if d[k] is not None else None) for k in _LOOP_ARRAYS})


def _save_loop(key, loop):
    d = {k: getattr(loop, k) for k in _LOOP_ARRAYS}
    d.update(speed_rad_s=float(loop.speed_rad_s), protocol=loop.protocol, label=loop.label)
    save_view(key, {"kind": "hysteresis-loop", "loop": d})


def _hysteresis_key(system, state, **_):
    return view_key("hysteresis", system, state, module=__name__)


def hysteresis_key(system, state) -> str:
    """The view-cache key of the Hysteresis view of ``state`` with ``system``."""
    return _hysteresis_key(system, state)


@cached_view(_hysteresis_key)
def hysteresis_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False):
    """Torque-ramp protocol at each speed -> hysteresis loops, dynamic stiffness along the
    loading branch and energy per loop ([thesis] §6.3.2, §7.3.1).

    state: from :func:`dampersim.views.state.parse_query` ("hysteresis"). Each speed's loop
    is cached on its own (protocol, speed, rate, hold), so display options (windup shown,
    low pass) and added speeds reuse the loops already simulated. ``progress(done, total, from_cache)`` after
    each speed; ``cancel()`` returning True stops between speeds (InputError);
    ``cache_only``: return None unless every loop is cached.
    """
    t0 = time.perf_counter()
    speeds_rpm = parse_values(state["speeds"], option="speeds", unit="rpm")
    keys = [_loop_key(system, state, rpm) for rpm in speeds_rpm]
    cached = {k: _load_loop(k) for k in keys}
    cached = {k: v for k, v in cached.items() if v is not None}
    if cache_only and len(cached) < len(set(keys)):
        return None
    loops, analyses = [], []
    n_cached = sum(k in cached for k in keys)
    if progress:
        progress(n_cached, len(speeds_rpm), n_cached)
    done = n_cached
    for i, (rpm, k) in enumerate(zip(speeds_rpm, keys)):
        lp = cached.get(k)
        if lp is None:
            if cancel is not None and (cancel() if callable(cancel) else cancel.is_set()):
                raise InputError(f"hysteresis run cancelled after {done} of {len(speeds_rpm)} speeds; the finished loops are cached")
            lp, = run_loops(system, state["protocol"], [rpm_to_rad_s(rpm)], rate=float(state["rate"]), hold=float(state["hold"]))
            lp = dataclasses.replace(lp, result=None)
            _save_loop(k, lp)
            cached[k] = lp
            done += 1
            if progress:
                progress(done, len(speeds_rpm), n_cached)
        if state["lowpass"]:
            lp = lp.filtered()
        loops.append(lp)
        analyses.append(analyse_loop(lp, system))
    which = state["windup"]
    knees = [a.knee for a in analyses] if which == "total" else None
    loops_fig = hysteresis_figure(loops, windup=which, knees=knees,
                                  title=f"Hysteresis loops, protocol {state['protocol']} ({number_text(state['rate'])} N m/s)")
    stiff_fig = stiffness_figure(loops, windup=which, log_y=True)
    efig = loop_energy_figure(speeds_rpm, [a.energy_j for a in analyses])
    rows = []
    for rpm, a in zip(speeds_rpm, analyses):
        d = a.to_dict(ANGLE_UNIT)
        rows.append({
            "speed_rpm": float(rpm),
            "knee_torque_nm": d["knee"]["torque_nm"] if d["knee"]["found"] else None,
            "knee_windup_deg": d["knee"]["windup_deg"] if d["knee"]["found"] else None,
            "stiffness_below_nm_per_deg": d["knee"]["stiffness_below_nm_per_deg"],
            "energy_j": d["energy_per_loop_j"],
            "max_windup_deg": d["max_windup_deg"],
            "min_windup_deg": d["min_windup_deg"],
            "closure_gap_deg": d["closure_gap_deg"],
        })
    summary = {"speeds": len(speeds_rpm), "protocol": state["protocol"], "compute_time_s": time.perf_counter() - t0,
               "simulated_s": float(loops[0].time_s[-1]) if loops else 0.0}
    figures = {"loops": loops_fig.to_dict(), "stiffness": stiff_fig.to_dict(), "energy": efig.to_dict()}
    return {"kind": "hysteresis", "figures": figures, "loops": rows, "summary": summary}


__all__ = ["ANGLE_UNIT", "PROTOCOL_NAMES", "protocol_label", "simulated_seconds", "hysteresis_key", "hysteresis_view"]
