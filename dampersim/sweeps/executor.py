"""Run a sweep of test points: cache look-up, then serial, process-pool or Dask execution.

:func:`run_sweep` takes every point it can from the result cache
(:mod:`dampersim.sweeps.cache`) and computes only the misses:

* ``"serial"``: one after the other in this process;
* ``"processes"`` (default): a process pool over all cores, forked where that is safe
  (:mod:`dampersim.sweeps.backends`); the parent loads or compiles the kernel once first;
* ``"dask"``: a ``distributed`` scheduler at ``scheduler=`` or ``$DAMPERSIM_SCHEDULER``
  (a local cluster on this machine when neither is set). Workers must run the same
  dampersim version, source and platform; a worker that does not is refused.

Only the parent writes the cache, one transaction per point, as results arrive: a
cancelled or failed sweep keeps every finished point and never leaves a partial entry.
When the disk is full the sweep goes on without storing; the result says so
(:attr:`SweepResult.uncached`, :attr:`SweepResult.cache_notice`).
The table follows the thesis's analysis ([thesis] §3.4): order amplitudes of input and
output torque and their magnification ratio per test point and engine order.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from dampersim.analysis.colourmap import SWEEP_COLUMNS
from dampersim.errors import DampersimError, InputError
from dampersim.fileio import write_parquet_atomic
from dampersim.parameters import validate
from dampersim.results import ANALYSIS_WINDOW
from dampersim.solver.linear import check_time_step
from dampersim.sweeps import cache as _cache
from dampersim.sweeps.backends import (SCHEDULER_ENV, DaskBackend, PoolBackend, check_scheduler_address, compute_task,
                                       cpu_count, environment)
from dampersim.sweeps.grid import TestPoint
from dampersim.analysis.metrics import magnification_ratio
from dampersim.units import rad_s_to_rpm

#: Accepted values of ``executor``.
EXECUTORS = ("processes", "serial", "dask")
#: Orders in the table by default: the first eight engine orders ([thesis] §3.4).
DEFAULT_ORDERS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)
#: Magnification is NaN where the input amplitude is below this share of the point's
#: largest input amplitude (an order that is not excited has no meaningful ratio).
MIN_INPUT_REL = 1e-3

#: Columns of the sweep table: a point index, then the analysis package's sweep columns.
TABLE_COLUMNS = ("point", *SWEEP_COLUMNS)


class SweepCancelled(DampersimError):
    """The sweep was cancelled; finished points are in the cache.

    completed: points finished (computed now or taken from the cache); total: points in
    the sweep; computed / from_cache: how ``completed`` splits up.
    """

    def __init__(self, completed, total, computed=0, from_cache=0):
        self.completed = int(completed)
        self.total = int(total)
        self.computed = int(computed)
        self.from_cache = int(from_cache)
        super().__init__(
            f"sweep cancelled after {self.completed} of {self.total} test points "
            f"({self.computed} computed, {self.from_cache} from the cache); the finished points "
            "are kept in the cache, run the same sweep again to continue"
        )

    def __reduce__(self):
        return (type(self), (self.completed, self.total, self.computed, self.from_cache))


class SweepPointFailed(DampersimError):
    """One test point could not be computed (e.g. the simulation diverged).

    speed_rpm [rpm], mean_torque [N m]: the point; reason: the original message;
    error_type: the original exception's class name.
    """

    def __init__(self, speed_rpm, mean_torque, error_type, reason):
        self.speed_rpm = float(speed_rpm)
        self.mean_torque = float(mean_torque)
        self.error_type = str(error_type)
        self.reason = str(reason)
        super().__init__(
            f"test point {self.speed_rpm:g} rpm, {self.mean_torque:g} N m failed "
            f"({self.error_type}): {self.reason}; the points finished so far are cached"
        )

    def __reduce__(self):
        return (type(self), (self.speed_rpm, self.mean_torque, self.error_type, self.reason))


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class SweepResult:
    """Outcome of :func:`run_sweep`.

    table: one row per test point and order, columns ``point`` (index into
    ``test_points``), ``speed_rpm``, ``speed_rad_s``, ``mean_torque_nm``, ``order``,
    ``frequency_hz`` (order x speed / 2 pi), ``input_amplitude_nm``,
    ``output_amplitude_nm`` and ``magnification`` (output / input, NaN where the input is
    below 1e-3 of the point's largest input amplitude) -- [thesis] §3.4.
    points: one row per test point (speeds, mean torque [N m], mean input/output torque
    over the window [N m], kernel wall time and compute time [s], from_cache).
    frequency_hz: bins [Hz] of the spectra; input_spectra, output_spectra: float32 arrays
    [n_points, n_bins] of amplitude spectra [N m] up to 1000 Hz (FFT colourmaps, [thesis]
    §6.2.1). wall_time: seconds the whole sweep took; computed / from_cache: how many of
    the test points were simulated now / read from the cache (a point listed twice is
    simulated once and counted twice). uncached: computed test points that could not be
    stored (full disk); cache_notice: one line for the page saying so, or None.
    """

    table: pd.DataFrame
    points: pd.DataFrame
    test_points: tuple
    frequency_hz: np.ndarray
    input_spectra: np.ndarray
    output_spectra: np.ndarray
    wall_time: float
    computed: int
    from_cache: int
    executor: str
    keys: tuple
    uncached: int = 0
    cache_notice: str | None = None

    @property
    def n_points(self) -> int:
        return len(self.test_points)

    def colourmap(self, which="output", mean_torque=None):
        """FFT colourmap data of a speed sweep ([thesis] §6.2.1, Fig. 6.12).

        which: "input" or "output" torque; mean_torque [N m]: select that torque level
        (needed when the sweep has several). Returns ``(speed_rpm, frequency_hz, amp)``
        with ``amp[i, j]`` the amplitude [N m] at speed i (ascending) and frequency j.
        """
        if which not in ("input", "output"):
            raise InputError(f"which = {which!r}: accepted is 'input' or 'output'")
        spectra = self.input_spectra if which == "input" else self.output_spectra
        torques = self.points["mean_torque_nm"].to_numpy()
        levels = np.unique(torques)
        if mean_torque is None:
            if levels.size > 1:
                raise InputError(
                    f"the sweep has {levels.size} mean torque levels; pass mean_torque= one of "
                    f"{', '.join(f'{v:g}' for v in levels)} N m"
                )
            mean_torque = levels[0]
        sel = np.flatnonzero(np.isclose(torques, float(mean_torque), rtol=0, atol=1e-9))
        if sel.size == 0:
            raise InputError(
                f"mean_torque = {mean_torque!r} N m is not in the sweep; accepted is one of "
                f"{', '.join(f'{v:g}' for v in levels)} N m"
            )
        speeds = self.points["speed_rpm"].to_numpy()[sel]
        order = np.argsort(speeds, kind="stable")
        return speeds[order], self.frequency_hz, spectra[sel[order]]

    def spectra(self, which="output") -> list:
        """Per-point spectra as ``[(speed [rad/s], frequency [Hz], amplitude [N m]), ...]``,
        the form :func:`dampersim.analysis.colourmap.colourmap` accepts; which: "input" or
        "output" torque."""
        if which not in ("input", "output"):
            raise InputError(f"which = {which!r}: accepted is 'input' or 'output'")
        spectra = self.input_spectra if which == "input" else self.output_spectra
        return [(p.speed, self.frequency_hz, spectra[i].astype(float)) for i, p in enumerate(self.test_points)]

    def to_parquet(self, path) -> str:
        """Write :attr:`table` to ``path`` atomically (temporary file + rename); returns
        the absolute path."""
        return write_parquet_atomic(self.table, path)


def _cancel_check(cancel):
    if cancel is None:
        return lambda: False
    if hasattr(cancel, "is_set"):
        return cancel.is_set
    if callable(cancel):
        return lambda: bool(cancel())
    raise InputError(f"cancel = {cancel!r}: accepted is a threading.Event or a function returning True to cancel")


def _resolve_executor(executor, scheduler):
    env_sched = os.environ.get(SCHEDULER_ENV, "").strip() or None
    if executor is None:
        executor = "dask" if (scheduler or env_sched) else "processes"
    if executor not in EXECUTORS:
        raise InputError(f"executor = {executor!r}: accepted is one of {', '.join(EXECUTORS)}")
    if scheduler is not None and executor != "dask":
        raise InputError(
            f"a Dask scheduler ({scheduler!r}) was given with executor = {executor!r}; "
            "accepted is executor 'dask' (or no executor) together with a scheduler"
        )
    address = (scheduler or env_sched) if executor == "dask" else None
    if address is not None and not isinstance(address, str):
        raise InputError(f"scheduler = {address!r}: accepted is an address such as tls://host:8786")
    if address is not None:
        check_scheduler_address(address)
    return executor, address


def _check_window(system, point, duration, window):
    exc = point.excitation()
    dur = _cache.resolved_duration(system, exc, duration)
    steady = float(getattr(exc, "steady_start", 0.0))
    if window > dur - steady + 1e-9:
        raise InputError(
            f"analysis window {window:g} s does not fit after the start-up ({steady:g} s) of a "
            f"{dur:g} s simulation; accepted is a window up to {max(dur - steady, 0):g} s or a "
            f"duration of at least {steady + window:g} s"
        )
    f1 = point.speed / (2.0 * math.pi)
    need = 4.0 / f1  # half orders 0.5 f1 apart need a resolution finer than 0.25 f1
    if window <= 1.01 * need:  # 1 % margin for rounding the window to whole samples
        raise InputError(
            f"analysis window {window:g} s is too short to separate half orders at "
            f"{point.speed_rpm:g} rpm; accepted is a window longer than {1.01 * need:.3g} s"
        )


# --------------------------------------------------------------------------- run_sweep
def run_sweep(
    system,
    points,
    executor=None,
    workers=None,
    scheduler=None,
    progress=None,
    cancel=None,
    *,
    duration=None,
    window=None,
    orders=DEFAULT_ORDERS,
    cache=None,
) -> SweepResult:
    """Simulate every test point (or take it from the cache) and tabulate the orders.

    Args:
        system: :class:`dampersim.DamperSystem` (validated here).
        points: sequence of :class:`TestPoint` (speed [rad/s], mean torque [N m],
            orders), e.g. from :func:`dampersim.sweeps.grid.make_grid`; the thesis steps
            speed sweeps by 10 rpm ([thesis] §3.3.2).
        executor: "processes" (all cores), "serial" or "dask"; default "dask" when a
            scheduler is given or ``$DAMPERSIM_SCHEDULER`` is set, else "processes".
        workers: number of processes (default: all cores) or of local Dask workers.
        scheduler: Dask scheduler address (default ``$DAMPERSIM_SCHEDULER``); it must
            answer within 5 s.
        progress: ``progress(done, total, from_cache)`` called after the cache look-up
            and after every computed point; ``done`` and ``from_cache`` count test points.
        cancel: ``threading.Event`` or function returning True: stop submitting, finish
            or cancel what is running, keep finished points cached, raise SweepCancelled.
        duration: simulated time per point [s] (default: ``system.solver.duration``).
        window: analysis window at the end of each record [s] (default 1.25 s,
            [thesis] §3.4); it must fit after the start-up ramps.
        orders: engine orders in the table (any of 0.5, 1, ..., 8).
        cache: None for the default :class:`ResultCache` (``$DAMPERSIM_CACHE_DIR``), a
            ResultCache, or False to neither read nor write a cache.

    Returns:
        :class:`SweepResult`.

    Raises:
        InputError: bad arguments, window not fitting, unreachable scheduler.
        ParameterError: invalid parameters.
        SweepCancelled: cancelled (``completed`` says how many points are done).
        SweepPointFailed: a point failed (e.g. diverged); finished points stay cached.
    """
    t_start = time.perf_counter()
    check_time_step(validate(system))
    points = tuple(points) if points is not None else ()
    if not points:
        raise InputError("a sweep needs at least one test point")
    for p in points:
        if not isinstance(p, TestPoint):
            raise InputError(f"test point {p!r}: accepted are dampersim.sweeps.TestPoint objects")
    window = ANALYSIS_WINDOW if window is None else float(window)
    if not (math.isfinite(window) and window > 0):
        raise InputError(f"window = {window!r} s: accepted is a positive analysis window")
    if duration is not None:
        duration = float(duration)
        if not (math.isfinite(duration) and duration > 0):
            raise InputError(f"duration = {duration!r} s: accepted is a positive duration")
    try:
        orders = tuple(float(k) for k in np.atleast_1d(np.asarray(orders, dtype=float)).ravel())
    except (TypeError, ValueError):
        raise InputError(f"orders = {orders!r}: accepted are engine orders among 0.5, 1, ..., 8") from None
    if not orders:
        raise InputError("orders: accepted is at least one engine order")
    for k in orders:
        _cache._order_index(_cache.STORED_ORDERS, k)
    if workers is not None:
        if isinstance(workers, bool) or int(workers) != workers or int(workers) < 1:
            raise InputError(f"workers = {workers!r}: accepted is a whole number >= 1")
        workers = int(workers)
    executor, address = _resolve_executor(executor, scheduler)
    is_cancelled = _cancel_check(cancel)
    for p in points:
        _check_window(system, p, duration, window)

    own_cache = cache is None
    if cache is not None and cache is not False and not isinstance(cache, _cache.ResultCache):
        raise InputError(f"cache = {cache!r}: accepted is None (default cache), False or a ResultCache")
    # (an empty ResultCache is falsy through __len__: compare with False explicitly)
    store = _cache.ResultCache() if own_cache else (None if cache is False else cache)
    try:
        return _run(system, points, executor, address, workers, progress, is_cancelled,
                    duration, window, orders, store, t_start)
    finally:
        if own_cache:
            store.close()


def _run(system, points, executor, address, workers, progress, is_cancelled,
         duration, window, orders, store, t_start):
    source = _cache.kernel_source_hash()
    env = environment(source)
    keys = tuple(_cache.cache_key(system, p, duration, window, source_hash=source) for p in points)
    slots_of: dict[str, list[int]] = {}
    for i, k in enumerate(keys):
        slots_of.setdefault(k, []).append(i)
    total = len(points)

    records: dict[str, _cache.PointRecord] = {}
    cached_keys = set()
    if store is not None:
        for k in slots_of:
            rec = store.get(k)
            if rec is not None:
                records[k] = rec
                cached_keys.add(k)
    state = {"done": sum(len(slots_of[k]) for k in cached_keys), "computed": 0, "uncached": 0}
    n_from_cache = state["done"]
    if progress is not None:
        progress(state["done"], total, n_from_cache)

    missing = [k for k in slots_of if k not in records]
    first_point = {k: points[slots_of[k][0]] for k in missing}

    def finish(k, outcome):
        status = outcome[0]
        p = first_point[k]
        if status == "ok":
            try:
                rec = _cache.PointRecord.from_bytes(outcome[1], key=k)
            except ValueError as exc:
                return SweepPointFailed(p.speed_rpm, p.mean_torque, "ValueError", f"result damaged in transfer: {exc}")
            if store is not None and not store.put(k, outcome[1]):  # full disk: go on uncached
                state["uncached"] += len(slots_of[k])
            records[k] = rec
            state["done"] += len(slots_of[k])
            state["computed"] += len(slots_of[k])
            if progress is not None:
                progress(state["done"], total, n_from_cache)
            return None
        if status == "mismatch":
            theirs = outcome[1]
            if tuple(theirs[:2]) == tuple(env[:2]):
                return InputError(
                    "a worker runs the same dampersim on another platform (numpy/scipy/numba/llvmlite "
                    "version, numba's CPU target, numpy's CPU features or the OpenBLAS kernel, e.g. set by "
                    "OPENBLAS_CORETYPE; results are keyed by the platform, since rounding differs between "
                    "them): run the sweep on workers of this machine's kind and environment, or "
                    "with executor='processes'"
                )
            return InputError(
                f"a worker runs dampersim {theirs[0]} with kernel source {theirs[1][:12]}, "
                f"this process {env[0]} with {env[1][:12]}; its results would not match the cache "
                "key: run the same dampersim on every worker (and restart processes that loaded "
                "dampersim before its source changed)"
            )
        return SweepPointFailed(p.speed_rpm, p.mean_torque, outcome[1], outcome[2])

    failure = None
    cancelled = bool(missing) and is_cancelled()
    if missing and not cancelled:
        if executor == "serial":
            for k in missing:
                if is_cancelled():
                    cancelled = True
                    break
                failure = finish(k, compute_task(system, first_point[k], duration, window, k, env))
                if failure is not None:
                    break
        else:
            if executor == "processes":
                if _cache.current_source_hash() != source:
                    raise InputError(
                        "dampersim's source files changed on disk after this process loaded them: "
                        "new worker processes would run other code than the cache keys describe; "
                        "restart this process (or use executor='serial')"
                    )

                backend = PoolBackend(min(workers or cpu_count(), len(missing)))
            else:
                backend = DaskBackend(address, workers)
            queue = list(missing)
            inflight = {}
            abort = True
            try:
                while queue or inflight:
                    if not cancelled and failure is None and is_cancelled():
                        cancelled = True
                    if cancelled or failure is not None:
                        queue.clear()
                        for f in list(inflight):
                            if backend.cancel(f):
                                inflight.pop(f)
                    while queue and len(inflight) < backend.slots:
                        k = queue.pop(0)
                        inflight[backend.submit(system, first_point[k], duration, window, k, env)] = k
                    if not inflight:
                        break
                    for f in backend.wait(inflight, 0.1):
                        k = inflight.pop(f)
                        try:
                            outcome = backend.result(f)
                        except Exception as exc:  # worker died, lost connection, ...
                            outcome = ("error", type(exc).__name__, str(exc) or repr(exc))
                        err = finish(k, outcome)
                        if err is not None and failure is None:
                            failure = err
                abort = False
            finally:
                backend.close(abort=abort)
    if failure is not None:
        raise failure
    if cancelled and len(records) < len(slots_of):
        raise SweepCancelled(state["done"], total, state["computed"], n_from_cache)

    notice = None
    if state["uncached"]:
        notice = (f"{state['uncached']} of {total} test points were computed but not cached: "
                  f"{getattr(store, 'write_error', None) or 'the cache could not be written'}. "
                  "Free disk space to keep results for the next run.")
    return _assemble(points, keys, records, cached_keys, orders, executor, time.perf_counter() - t_start,
                     uncached=state["uncached"], cache_notice=notice)


def _assemble(points, keys, records, cached_keys, orders, executor, wall, uncached=0, cache_notice=None):
    orders_arr = np.asarray(orders, dtype=float)
    n_o = orders_arr.size
    cols = {c: [] for c in TABLE_COLUMNS}
    prow = {c: [] for c in ("point", "speed_rpm", "speed_rad_s", "mean_torque_nm",
                            "mean_input_torque_nm", "mean_output_torque_nm", "wall_time_s",
                            "compute_time_s", "from_cache")}
    spectra_in, spectra_out = [], []
    freq = None
    for i, (p, k) in enumerate(zip(points, keys)):
        rec = records[k]
        a_in, a_out = rec.amplitudes(orders_arr)
        largest = np.nanmax(a_in) if np.isfinite(a_in).any() else 0.0
        mr = magnification_ratio(a_in, a_out, min_input=max(MIN_INPUT_REL * largest, 1e-12))
        rpm = round(float(rad_s_to_rpm(p.speed)), 9)
        cols["point"].extend([i] * n_o)
        cols["speed_rpm"].extend([rpm] * n_o)
        cols["speed_rad_s"].extend([p.speed] * n_o)
        cols["mean_torque_nm"].extend([p.mean_torque] * n_o)
        cols["order"].extend(orders_arr)
        cols["frequency_hz"].extend(orders_arr * p.speed / (2.0 * np.pi))
        cols["input_amplitude_nm"].extend(a_in)
        cols["output_amplitude_nm"].extend(a_out)
        cols["magnification"].extend(mr)
        prow["point"].append(i)
        prow["speed_rpm"].append(rpm)
        prow["speed_rad_s"].append(p.speed)
        prow["mean_torque_nm"].append(p.mean_torque)
        prow["mean_input_torque_nm"].append(rec.mean_input_torque)
        prow["mean_output_torque_nm"].append(rec.mean_output_torque)
        prow["wall_time_s"].append(rec.wall_time)
        prow["compute_time_s"].append(rec.compute_time)
        prow["from_cache"].append(k in cached_keys)
        f = rec.frequency_hz
        if freq is None or f.size < freq.size:
            freq = f
        spectra_in.append(rec.input_spectrum)
        spectra_out.append(rec.output_spectrum)
    # points of one sweep share sample rate and window, hence bins; trim defensively
    n_f = freq.size
    table = pd.DataFrame(cols)
    table["point"] = table["point"].astype("int64")
    for c in TABLE_COLUMNS[1:]:
        table[c] = table[c].astype("float64")
    return SweepResult(
        table=table,
        points=pd.DataFrame(prow),
        test_points=tuple(points),
        frequency_hz=freq,
        input_spectra=np.vstack([s[:n_f] for s in spectra_in]),
        output_spectra=np.vstack([s[:n_f] for s in spectra_out]),
        wall_time=wall,
        computed=sum(k not in cached_keys for k in keys),
        from_cache=sum(k in cached_keys for k in keys),
        executor=executor,
        keys=tuple(keys),
        uncached=int(uncached),
        cache_notice=cache_notice,
    )


__all__ = [
    "run_sweep",
    "SweepResult",
    "SweepCancelled",
    "SweepPointFailed",
    "write_parquet_atomic",
    "EXECUTORS",
    "SCHEDULER_ENV",
    "DEFAULT_ORDERS",
]
