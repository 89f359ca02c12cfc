"""Shared helpers of the chapter 7 studies: cached MR sweeps and cached single runs."""

from __future__ import annotations

import json
import math
import time

import diskcache
import numpy as np

from dampersim.errors import InputError
from dampersim import keys
from dampersim.locations import cache_dir
from dampersim.sweeps.cache import key_parts
from dampersim.sweeps.backends import cpu_count, process_pool
from dampersim.sweeps.executor import SweepCancelled, run_sweep
from dampersim.sweeps.grid import TestPoint
from dampersim.units import rpm_to_rad_s

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


def mr_sweep(system, points, prog: Progress, executor, cancel=None, orders=None):
    """run_sweep over ``points`` (cached); returns its table."""
    kw = {}
    if orders is not None:
        kw["orders"] = orders
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
def _store():
    return diskcache.Cache(str(cache_dir() / "studies"))


def run_key(tag, fn, system, excitation, duration) -> str:
    """Key of one cached study run: ``tag``, the run's inputs as a sweep point keys them,
    and the source of the module that defines ``fn`` (with everything it imports)."""
    parts = {"tag": tag, "function": fn.__qualname__, "inputs": key_parts(system, excitation, duration)}
    return keys.make_key("dampersim.study-run", fn.__module__, parts)


def cached_runs(tag, fn, jobs, prog: Progress, parallel: bool, cancel=None):
    """Evaluate ``fn(system, excitation, duration)`` -> JSON-able dict for each job
    ``(system, excitation, duration)``, from the study cache when present; in a process
    pool when ``parallel``."""
    run_keys = [run_key(tag, fn, *j) for j in jobs]
    out = [None] * len(jobs)
    todo = []
    with _store() as store:
        for i, k in enumerate(run_keys):
            v = store.get(k)
            if v is not None:
                out[i] = json.loads(v)
            else:
                todo.append(i)
    prog.add(len(jobs) - len(todo), len(jobs) - len(todo))

    def save(i, value):
        with _store() as store:
            store.set(run_keys[i], json.dumps(value))
        out[i] = value
        prog.add(1)

    if todo and parallel and len(todo) > 1:
        with process_pool(min(cpu_count(), len(todo))) as pool:
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
