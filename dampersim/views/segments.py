"""The Segments page's data: the compression of every segment over time and the animated
damper drawing of one test point, cached as one view; the simulation behind it is cached
on its own, so display options reuse it.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from dampersim.plotting import damper_animation_figure, segment_compression_figure
from dampersim.units import number_text
from dampersim.simulation import simulate
from dampersim.units import rad_to_deg
from dampersim.views.state import point_excitation
from dampersim.views.store import cached_view, load_entry, save_entry, view_key

#: State keys the simulation depends on (the others are display options).
SIMULATION_KEYS = ("speed", "torque", "orders", "duration")


def _segments_key(system, state, **_):
    return view_key("segments", system, state, module=__name__)


def segments_key(system, state) -> str:
    """The view-cache key of the Segments view of ``state`` with ``system``."""
    return _segments_key(system, state)


@cached_view(_segments_key)
def segments_view(system, state: dict, use_cache: bool = True) -> dict:
    """Segment motion of one test point: compression of each segment over time (heatmap)
    and the animated damper drawing ([thesis] §7.3, Fig. 7.24-7.25)."""
    t0 = time.perf_counter()
    ex = point_excitation(state)
    # the simulation is cached apart from the display options (spring, windows, gain)
    sim_key = view_key("segments-simulation", system, {k: state[k] for k in SIMULATION_KEYS}, module=__name__)
    res = load_entry(sim_key) if use_cache else None
    if res is None or not hasattr(res, "nodes"):
        res = simulate(system, ex, duration=float(state["duration"]), record_segments=True)
        save_entry(sim_key, res)
    names = [s.name for s in res.springs]
    spring = state["spring"] if state["spring"] in names else names[0]
    k0 = int(np.searchsorted(res.segment_t, res.segment_t[-1] - float(state["window"]) - 1e-12))
    k0 = min(k0, max(res.segment_t.size - 2, 0))
    tail = dataclasses.replace(res, nodes=res.nodes[k0:], segment_t=res.segment_t[k0:])
    heat = segment_compression_figure(tail, spring=spring, max_frames=1500, dtype=np.float32,
                                      title=f"Segment compression, {spring.replace('_', ' ')} spring, last {number_text(float(state['window']))} s")
    anim = damper_animation_figure(res, system, span=float(state["span"]), gain=float(state["gain"]))
    comp = rad_to_deg(res.segment_compression(spring))
    steady = res.segment_t >= ex.steady_start
    c = comp[steady] if steady.any() else comp
    amp = (c.max(axis=0) - c.min(axis=0)) / 2
    rows = [{"segment": i + 1, "mean_deg": float(c[:, i].mean()), "amplitude_deg": float(amp[i]),
             "max_deg": float(c[:, i].max())} for i in range(c.shape[1])]
    summary = {
        "spring": spring,
        "segments": int(c.shape[1]),
        "frames": int(res.nodes.shape[0]),
        "end_to_middle_amplitude": float(max(amp[0], amp[-1]) / max(np.median(amp), 1e-12)),
        "compute_time_s": time.perf_counter() - t0,
    }
    return {"kind": "segments", "figures": {"heatmap": heat.to_dict(), "animation": anim.to_dict()}, "segments": rows,
            "summary": summary}


__all__ = ["SIMULATION_KEYS", "segments_key", "segments_view"]
