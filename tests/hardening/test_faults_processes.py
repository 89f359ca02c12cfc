"""Faults of processes: a pool worker killed in the middle of a sweep, and a process killed
while it writes the sweep cache.

What must hold: the test points finished before the fault stay in the cache, the point
that was lost is reported by speed and torque (never silently dropped, never a hang), a
rerun completes, and a cache that a killed writer left behind is still readable.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time

import psutil
import pytest

from dampersim.parameters import default_parameters
from dampersim.errors import DampersimError
from dampersim.sweeps.cache import ResultCache
from dampersim.sweeps.executor import run_sweep
from dampersim.sweeps.grid import make_grid
from dampersim.units import rpm_to_rad_s

DURATION = 1.0  # [s] short records: the faults, not the physics, are under test
WINDOW = 0.3


def _points(n, start=1000.0):
    return make_grid([rpm_to_rad_s(start + 37.0 * i) for i in range(n)], [150.0], orders=((2.0, 200.0, 0.0),))


def _pool_children(before=frozenset()):
    """Live children of this process started after ``before`` (pids) was taken, without
    multiprocessing's helpers (resource tracker, fork server) that earlier tests started."""
    out = []
    for p in psutil.Process().children(recursive=True):
        try:
            if p.pid in before or p.status() == psutil.STATUS_ZOMBIE:
                continue
            cmd = " ".join(p.cmdline())
        except psutil.Error:
            continue
        if "resource_tracker" in cmd or "forkserver" in cmd:
            continue
        out.append(p)
    return out


@pytest.mark.slow
def test_killed_pool_worker_keeps_finished_points_and_names_the_lost_one(cache_dir):
    system = default_parameters()
    points = _points(8)
    cache = ResultCache()
    done = []
    killed = threading.Event()
    before = frozenset(p.pid for p in psutil.Process().children(recursive=True))

    def progress(n, total, from_cache):
        done.append(n)
        if n >= 2 and not killed.is_set():
            kids = _pool_children(before)
            if kids:
                os.kill(kids[0].pid, signal.SIGKILL)
                killed.set()

    t0 = time.perf_counter()
    with pytest.raises(DampersimError) as info:
        run_sweep(system, points, executor="processes", workers=2, progress=progress,
                  duration=DURATION, window=WINDOW, cache=cache)
    elapsed = time.perf_counter() - t0
    assert killed.is_set(), "the test never reached a running pool worker"
    msg = str(info.value)
    # the lost point is named by speed and torque, and the message says the rest is kept
    assert "rpm" in msg and "N m" in msg and "cached" in msg, msg
    # a dead worker is noticed at once: 8 points of 1 s take ~1 s; 60 s means a hang
    assert elapsed < 60.0, elapsed
    # every point finished before the fault is in the cache, and a rerun completes
    finished = max(done)
    rerun = run_sweep(system, points, executor="serial", duration=DURATION, window=WINDOW, cache=cache)
    assert rerun.from_cache >= finished - 1  # the progress count includes the point being written
    assert rerun.from_cache + rerun.computed == len(points)
    assert len(_pool_children(before)) == 0, "a pool worker outlived its sweep"


def _writer(cache_root, started):
    os.environ["DAMPERSIM_CACHE_DIR"] = cache_root
    from dampersim.sweeps.cache import ResultCache as RC  # after the variable is set

    system = default_parameters()
    cache = RC()
    started.set()
    # write forever: the parent kills this process in the middle of some write
    i = 0
    while True:
        run_sweep(system, _points(1, start=900.0 + i), executor="serial", duration=0.9, window=0.3, cache=cache)
        i += 1


@pytest.mark.slow
def test_process_killed_during_cache_writes_leaves_a_readable_cache(cache_dir):
    ctx = mp.get_context("spawn")
    started = ctx.Event()
    proc = ctx.Process(target=_writer, args=(str(cache_dir), started))
    proc.start()
    try:
        assert started.wait(120), "the writer never started"
        time.sleep(4.0)  # several points written, one in flight
        os.kill(proc.pid, signal.SIGKILL)
        proc.join(10)
    finally:
        if proc.is_alive():
            proc.kill()
    system = default_parameters()
    cache = ResultCache()
    # every entry the killed writer left is either whole or absent: a sweep over the
    # points it was writing reads what is whole and recomputes the rest
    points = _points(1, start=900.0)
    out = run_sweep(system, points, executor="serial", duration=0.9, window=0.3, cache=cache)
    assert out.from_cache + out.computed == 1
    assert out.from_cache == 1, "the first point was written long before the kill"
    more = [p for i in range(12) for p in _points(1, start=900.0 + i)]
    again = run_sweep(system, more, executor="serial", duration=0.9, window=0.3, cache=cache)
    assert again.from_cache + again.computed == len(more)
    assert again.from_cache >= 1
