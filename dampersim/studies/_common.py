"""Shared helpers of the chapter 7 studies: cached MR sweeps and cached single runs."""

from __future__ import annotations

import logging
import math
import time

import diskcache
import numpy as np

from dampersim.errors import InputError
from dampersim import jobs, keys
from dampersim.locations import private_dir
from dampersim.safestore import JsonDisk
from dampersim.sweeps.cache import key_parts
from dampersim.sweeps.backends import process_pool
from dampersim.sweeps.executor import SweepCancelled, run_sweep
from dampersim.sweeps.grid import TestPoint
from dampersim.units import rpm_to_rad_s

LOGGER = logging.getLogger("dampersim.studies")

#: Speeds [rpm] over which the thesis validated the model (rig limit 3000 rpm, §7.1.3).
VALIDATED_RPM = (500.0, 3000.0)


class Progress:
    """Counts work across the several sweeps of one study and reports it as
    ``progress(done, total, from_cache)`` to the caller's callback."""

    def __init__(self, callback, total):
        self.callback = callback
        self.total = int(total)
        self.done = 0
        self.cached = 0
        self.computed = 0
        self.warnings = []

    def sweep_callback(self):
        base_done, base_cached = self.done, self.cached

        def cb(done, total, from_cache):
            self._report(base_done + done, base_cached + from_cache)

        return cb

    def _report(self, done, cached):
        if self.callback is not None:
            self.callback(min(done, self.total), self.total, cached)

    def add(self, n, from_cache=0):
        self.done += n
        self.cached += from_cache
        self.computed += n - from_cache
        self._report(self.done, self.cached)


def point(rpm, mean_torque, orders) -> TestPoint:
    return TestPoint(rpm_to_rad_s(rpm), float(mean_torque), tuple(orders))


def warn_speeds(rpms, prog: Progress):
    hi = [r for r in rpms if r > VALIDATED_RPM[1] + 1e-9]
    if hi:
        prog.warnings.append(
            f"{len(hi)} test points above {VALIDATED_RPM[1]:g} rpm (up to {max(hi):g} rpm): the thesis never "
            "validated the model there (its rig stopped at 3000 rpm)"
        )


def pool_workers() -> int:
    """Processes a study's pool may use: the cores shared with the other running jobs
    (:func:`dampersim.jobs.sweep_workers`; all cores when no job runs, as on the command line)."""
    return jobs.sweep_workers()


def mr_sweep(system, points, prog: Progress, executor, cancel=None, orders=None):
    """run_sweep over ``points`` (cached); returns its table. A process pool gets
    :func:`pool_workers` processes."""
    kw = {}
    if orders is not None:
        kw["orders"] = orders
    if executor == "processes":
        kw["workers"] = pool_workers()
    res = run_sweep(system, points, executor=executor, progress=prog.sweep_callback(), cancel=cancel, **kw)
    prog.add(res.n_points, res.from_cache)
    return res.table


def mr_of(table, idx, order) -> float:
    """Magnification of ``order`` at test point ``idx`` of a sweep table (NaN if absent)."""
    sel = table[(table["point"] == idx) & np.isclose(table["order"], order)]
    return float(sel["magnification"].iloc[0]) if len(sel) else float("nan")


def amp_of(table, idx, order, which="output") -> float:
    sel = table[(table["point"] == idx) & np.isclose(table["order"], order)]
    return float(sel[f"{which}_amplitude_nm"].iloc[0]) if len(sel) else float("nan")


def pct(a, b) -> float:
    """100 (a - b) / b."""
    return float(100.0 * (a - b) / b) if (b and math.isfinite(a) and math.isfinite(b)) else float("nan")


# ----------------------------------------------------------------- cached single runs
#: Folder of the study cache under :func:`dampersim.locations.cache_dir`.
STUDIES_SUBDIR = "studies"


def _store():
    """The study cache: a private folder (0700, refused when others may write it) and JSON
    rows (:class:`dampersim.safestore.JsonDisk`), never pickle."""
    return diskcache.Cache(str(private_dir(STUDIES_SUBDIR)), disk=JsonDisk)


def _lookup(store, key):
    """The stored run under ``key``, or None when missing or refused (a pickled or foreign
    row, or one of an older format, is never read: the run is computed again)."""
    try:
        return store.get(key, default=None, retry=True)
    except (ValueError, TypeError, UnicodeDecodeError) as exc:
        LOGGER.warning("study cache entry %s refused (%s); computing it again", key[:12], exc)
        return None


def run_key(tag, fn, system, excitation, duration) -> str:
    """Key of one cached study run: ``tag``, the run's inputs as a sweep point keys them,
    and the source of the module that defines ``fn`` (with everything it imports)."""
    parts = {"tag": tag, "function": fn.__qualname__, "inputs": key_parts(system, excitation, duration)}
    return keys.make_key("dampersim.study-run", fn.__module__, parts)


def cached_runs(tag, fn, jobs, prog: Progress, parallel: bool, cancel=None):
    """Evaluate ``fn(system, excitation, duration)`` -> JSON-able dict (see
    :mod:`dampersim.safestore`; tuples and numpy arrays come back as such) for each job
    ``(system, excitation, duration)``, from the study cache when present; in a process
    pool of :func:`pool_workers` processes when ``parallel``."""
    run_keys = [run_key(tag, fn, *j) for j in jobs]
    out = [None] * len(jobs)
    todo = []
    with _store() as store:
        for i, k in enumerate(run_keys):
            v = _lookup(store, k)
            if v is not None:
                out[i] = v
            else:
                todo.append(i)
    prog.add(len(jobs) - len(todo), len(jobs) - len(todo))

    def save(i, value):
        with _store() as store:
            store.set(run_keys[i], value, retry=True)
        out[i] = value
        prog.add(1)

    workers = min(pool_workers(), len(todo)) if (todo and parallel) else 1
    if workers > 1:
        with process_pool(workers) as pool:
            futs = {pool.submit(fn, *jobs[i]): i for i in todo}
            for f in futs:
                if _cancelled(cancel):
                    for g in futs:
                        g.cancel()
                    raise SweepCancelled(prog.done, prog.total)
                save(futs[f], f.result())
    else:
        for i in todo:
            if _cancelled(cancel):
                raise SweepCancelled(prog.done, prog.total)
            save(i, fn(*jobs[i]))
    return out


def _cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if hasattr(cancel, "is_set"):
        return cancel.is_set()
    return bool(cancel())


def finish(name, params, results, checks, thesis, prog: Progress, t0, quick):
    return {
        "study": name,
        "quick": bool(quick),
        "params": params,
        "results": results,
        "checks": checks,
        "thesis": thesis,
        "warnings": prog.warnings,
        "points": prog.total,
        "computed": prog.computed,
        "from_cache": prog.cached,
        "wall_time_s": time.perf_counter() - t0,
    }


def check_executor(executor):
    if executor not in ("processes", "serial"):
        raise InputError(f"executor {executor!r}: accepted is 'processes' or 'serial'")
