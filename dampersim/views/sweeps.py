"""The data of the pages built on sweeps of test points: the Colourmap page (FFT colourmaps
and order cuts over speed) and the Maps page (magnification map and the torque-curve
prediction), the sweep they run, and the registry of sweeps running on this server.
"""

from __future__ import annotations

import time
import uuid

import numpy as np

from dampersim.analysis.colourmap import colourmaps, order_cuts
from dampersim.analysis.maps import magnification_map, predict_along_curve, torque_curve_overlay
from dampersim.analysis.order_table import REPORT_ORDERS
from dampersim.analysis.repeatability import STEP, check_runs, sweep_spread
from dampersim.errors import InputError
from dampersim.excitation import default_torque_curve
from dampersim.plotting import (
    banded_colourmap_figure,
    curve_prediction_figure,
    magnification_map_figure,
    order_cut_figure,
)
from dampersim.units import number_text, rad_s_to_rpm
from dampersim import jobs
from dampersim.sweeps.cache import ResultCache, cache_key, kernel_source_hash
from dampersim.sweeps.executor import SweepCancelled, run_sweep
from dampersim.sweeps.grid import TestPoint, make_grid, parse_range, parse_torques
from dampersim.views.state import orders_si, parse_orders_deg
from dampersim.views.store import cached_view, view_key, view_store


# --------------------------------------------------------------------------- running sweeps
class SweepRegistry:
    """Which dashboard sweeps are running on this server (all processes), so a page can say
    that it shares the cores. Entries expire unless refreshed (a killed job disappears)."""

    TTL = 20.0

    def __init__(self):
        self.id = uuid.uuid4().hex
        self._last = 0.0

    @staticmethod
    def _store():
        return view_store()

    def start(self, label: str, n_points: int):
        self._info = {"label": label, "points": int(n_points), "started": time.time()}
        self.beat(force=True)

    def beat(self, force=False):
        now = time.monotonic()
        if force or now - self._last > 2.0:
            self._last = now
            try:
                self._store().set(f"running:{self.id}", self._info, expire=self.TTL, retry=True)
            except Exception:
                pass

    def stop(self):
        try:
            self._store().delete(f"running:{self.id}", retry=True)
        except Exception:
            pass

    def others(self) -> int:
        return max(0, running_sweeps() - 1)


def running_sweeps() -> int:
    """Number of dashboard sweeps currently running on this server."""
    try:
        store = view_store()
        n = 0
        for k in store.iterkeys():
            if isinstance(k, str) and k.startswith("running:") and store.get(k) is not None:
                n += 1
        return n
    except Exception:
        return 0


# --------------------------------------------------------------------------- test points
def sweep_points(speeds_text, torques, orders_text) -> list:
    """Test points of a speed range text (rpm), mean torques [N m] and page orders."""
    return make_grid(parse_range(speeds_text), list(torques), orders_si(parse_orders_deg(orders_text)))


def repeated_points(points, runs) -> list:
    """``points`` run ``runs`` (K) times, run i with every order amplitude scaled by
    (1 + i·1e-9) as :func:`dampersim.analysis.repeatability.repeatability` does, run after
    run: point p of the list is run p // len(points) of ``points[p % len(points)]``. Each
    run is a test point of its own, cached like any other. ``runs`` None or 1: ``points``."""
    points = list(points)
    if runs in (None, 1):
        return points
    out = list(points)
    for i in range(1, check_runs(runs, "repeat")):
        s = 1.0 + i * STEP
        out += [TestPoint(p.speed, p.mean_torque, tuple((k, a * s, ph) for k, a, ph in p.orders)) for p in points]
    return out


def colourmap_points(state) -> list:
    """Test points of a Colourmap page state: its speeds, K times with ``repeat`` = K
    (:func:`repeated_points`)."""
    return repeated_points(sweep_points(state["speeds"], [float(state["torque"])], state["orders"]), state.get("repeat"))


def maps_points(state) -> list:
    """Test points of a Maps page state."""
    return sweep_points(state["speeds"], parse_torques(state["torques"]), state["orders"])


def _table_orders(orders_text, extra=()):
    ks = set(REPORT_ORDERS)
    for k, a, _ in parse_orders_deg(orders_text):
        if k <= 8 and float(2 * k).is_integer():
            ks.add(float(k))
    for k in extra:
        ks.add(float(k))
    return tuple(sorted(ks))


def sweep_status(system, points, duration, window) -> dict:
    """How many of ``points`` are in the result cache: {"total", "cached"}."""
    src = kernel_source_hash()
    keys = {cache_key(system, p, duration, window, source_hash=src) for p in points}
    cached = 0
    with ResultCache() as store:
        for k in keys:
            if store.diskcache.get(k, default=None) is not None:
                cached += 1
    return {"total": len(keys), "cached": cached}


def colourmap_status(system, state) -> dict:
    """{"total", "cached"} test points of a colourmap state in the result cache."""
    return sweep_status(system, colourmap_points(state), float(state["duration"]), float(state["window"]))


def maps_status(system, state) -> dict:
    """{"total", "cached"} test points of a maps state in the result cache."""
    return sweep_status(system, maps_points(state), float(state["duration"]), float(state["window"]))


def _run_points(system, points, duration, window, orders, progress=None, cancel=None, cache_only=False, workers=None,
                executor=None):
    """run_sweep with the dashboard's executor choice; ``cache_only`` assembles from the
    result cache without simulating (raises SweepCancelled when points are missing)."""
    if cache_only:
        return run_sweep(system, points, executor="serial", duration=duration, window=window,
                         orders=orders, cancel=lambda: True)
    if executor is None:
        status = sweep_status(system, points, duration, window)
        missing = status["total"] - status["cached"]
        executor = "serial" if missing <= 2 else "processes"
    if executor == "processes" and workers is None:
        # the cores are shared with the other jobs running on this server
        workers = jobs.sweep_workers()
    try:
        return run_sweep(system, points, executor=executor, workers=workers, progress=progress, cancel=cancel,
                         duration=duration, window=window, orders=orders)
    except InputError as exc:
        if executor == "processes" and "source files changed" in str(exc):
            # new worker processes would run newer code than this process: compute here
            return run_sweep(system, points, executor="serial", progress=progress, cancel=cancel,
                             duration=duration, window=window, orders=orders)
        raise


def _sweep_summary(result) -> dict:
    return {
        "points": int(result.n_points),
        "computed": int(result.computed),
        "from_cache": int(result.from_cache),
        "sweep_time_s": float(result.wall_time),
        # a full disk: the points were computed but not stored (the page says so)
        "cache_notice": getattr(result, "cache_notice", None),
        "executor": result.executor,
    }


# --------------------------------------------------------------------------- colourmap
def _colourmap_key(system, state, **_):
    return view_key("colourmap", system, state, module=__name__)


def colourmap_key(system, state) -> str:
    """The view-cache key of the Colourmap view of ``state`` with ``system``."""
    return _colourmap_key(system, state)


@cached_view(_colourmap_key)
def colourmap_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False, workers=None, executor=None):
    """Speed sweep -> FFT colourmaps of input and output with order lines, and order cuts
    with the input for context ([thesis] §6.3.1).

    state: from :func:`dampersim.views.state.parse_query` ("colourmap").
    ``progress(done, total, from_cache)`` and ``cancel`` go to
    :func:`dampersim.sweeps.run_sweep` (SweepCancelled when cancelled; finished points stay
    cached). ``cache_only``: return None unless every point is cached (nothing is
    simulated). ``executor``: "serial" or "processes" (default: processes when more than
    two points are missing). With ``repeat`` = K every speed runs K times
    (:func:`repeated_points`): the colourmaps and cuts show run 0, the cuts get the
    min-max of the K runs as a band and each cut row its largest spread
    (:func:`dampersim.analysis.repeatability.sweep_spread`).
    """
    t0 = time.perf_counter()
    cuts = [float(k) for k in str(state["cuts"]).split(",") if k]
    table_orders = _table_orders(state["orders"], cuts)
    runs = state.get("repeat")
    points = colourmap_points(state)
    n = len(points) // (runs or 1)  # the speeds; run 0 is the first n points
    try:
        result = _run_points(system, points, float(state["duration"]), float(state["window"]), table_orders,
                             progress, cancel, cache_only, workers, executor)
    except SweepCancelled:
        if cache_only:
            return None
        raise
    fmax = float(state["fmax"])
    maps = colourmaps(result.spectra("input")[:n], result.spectra("output")[:n], f_max_hz=fmax)
    fig = banded_colourmap_figure(maps, orders=REPORT_ORDERS, f_max_hz=fmax, db=bool(state["db"]),
                                  title=f"FFT colourmaps at {number_text(state['torque'])} N m mean torque")
    cut_table = order_cuts(result.table[result.table["point"] < n], orders=cuts)
    band = None
    if runs:
        band = sweep_spread(result.table, n)
        band = band[np.isclose(band["order"].to_numpy()[:, None], np.asarray(cuts)[None, :]).any(axis=1)]
    cut_fig = order_cut_figure(cut_table, orders=cuts, band=band, runs=runs,
                               title="Order cuts: output (solid, left) and input (dashed, right)")
    rows = []
    for k in cuts:
        sub = cut_table[np.isclose(cut_table["order"], k)]
        mr = sub["magnification"].to_numpy(float)
        ok = np.isfinite(mr)
        if ok.any():
            i = int(np.nanargmax(np.where(ok, mr, -np.inf)))
            rows.append({"order": k, "max_mr": float(mr[i]), "at_rpm": float(sub["speed_rpm"].iloc[i]),
                         "mean_mr": float(np.nanmean(mr))})
        else:
            rows.append({"order": k, "max_mr": None, "at_rpm": None, "mean_mr": None})
        if band is not None:
            rows[-1].update(_largest_spread(band[np.isclose(band["order"], k)]))
    summary = {**_sweep_summary(result), "speeds": n, "repeat": runs, "compute_time_s": time.perf_counter() - t0}
    return {"kind": "colourmap", "figures": {"colourmap": fig.to_dict(), "cuts": cut_fig.to_dict()}, "cuts": rows,
            "summary": summary}


def _largest_spread(rows) -> dict:
    """{"max_spread_pct" [%], "spread_at_rpm" [rpm]} of one order's band rows (None where
    no speed has a spread)."""
    sp = rows["spread_pct"].to_numpy(float)
    if not np.isfinite(sp).any():
        return {"max_spread_pct": None, "spread_at_rpm": None}
    i = int(np.nanargmax(sp))
    return {"max_spread_pct": float(sp[i]), "spread_at_rpm": float(rad_s_to_rpm(rows["speed_rad_s"].iloc[i]))}


# --------------------------------------------------------------------------- maps
def _maps_key(system, state, **_):
    return view_key("maps", system, state, module=__name__)


def maps_key(system, state) -> str:
    """The view-cache key of the Maps view of ``state`` with ``system``."""
    return _maps_key(system, state)


@cached_view(_maps_key)
def maps_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False, workers=None, executor=None):
    """Magnification map over (excitation frequency, mean torque) from a speed x torque
    sweep, with the engine torque curve drawn for one order and the MR predicted along it
    ([thesis] §6.3.1, §7.1.3). Arguments as :func:`colourmap_view`."""
    t0 = time.perf_counter()
    map_orders = [float(k) for k in str(state["map_orders"]).split(",") if k]
    try:
        result = _run_points(system, maps_points(state), float(state["duration"]), float(state["window"]),
                             _table_orders(state["orders"], map_orders), progress, cancel, cache_only, workers, executor)
    except SweepCancelled:
        if cache_only:
            return None
        raise
    frange = (float(state["fmin"]), float(state["fmax"]))
    mmap = magnification_map(result.table, frequency_range_hz=frange, orders=map_orders)
    curve = default_torque_curve()
    k = float(state["curve_order"])
    overlay = torque_curve_overlay(curve, k, frequency_range_hz=frange)
    finite_mr = mmap.magnification[np.isfinite(mmap.magnification)]
    zmax = max(1.25, float(finite_mr.max()) * 1.05) if finite_mr.size else None  # resolve MR < 1 as well
    fig = magnification_map_figure(mmap, overlays=overlay if len(overlay) else None, show_points=True, zmax=zmax,
                                   title=f"Magnification map, orders {state['map_orders']}", height=520)
    pred = predict_along_curve(mmap, curve, k)
    pfig = curve_prediction_figure(pred, k, curve.name)
    finite = pred["magnification"].to_numpy(float)
    finite = finite[np.isfinite(finite)]
    mr = mmap.magnification[np.isfinite(mmap.magnification)]
    summary = {
        **_sweep_summary(result),
        "map_points": int(len(mmap.points)),
        "share_above_one": float(np.mean(mr > 1.0)) if mr.size else None,
        "max_mr": float(mr.max()) if mr.size else None,
        "curve_max_mr": float(finite.max()) if finite.size else None,
        "curve_covered": float(np.isfinite(pred["magnification"].to_numpy(float)).mean()),
        "compute_time_s": time.perf_counter() - t0,
    }
    return {"kind": "maps", "figures": {"map": fig.to_dict(), "curve": pfig.to_dict()}, "summary": summary}


__all__ = [
    "SweepRegistry",
    "running_sweeps",
    "sweep_points",
    "repeated_points",
    "colourmap_points",
    "maps_points",
    "sweep_status",
    "colourmap_status",
    "maps_status",
    "colourmap_key",
    "colourmap_view",
    "maps_key",
    "maps_view",
]
