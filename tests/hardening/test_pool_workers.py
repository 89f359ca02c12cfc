"""Process pools started inside a job share the cores with the other running jobs:
studies (MR sweeps and cached single runs) and the diagnosis runner ask
:func:`dampersim.jobs.sweep_workers`, which gives all cores when no job runs (the command
line). Unit level: the running count and the cores are monkeypatched, no process starts.

Budget: 5 s per case (a registry database opened; nothing simulated).
"""

from __future__ import annotations

import time
from concurrent.futures import Future
from types import SimpleNamespace

import pytest

from dampersim import default_parameters, jobs
from dampersim.discrepancy import drive
from dampersim.studies import _common as C

CASE_BUDGET_S = 5.0
CORES = 8


@pytest.fixture(autouse=True)
def budget(cache_dir):
    t0 = time.perf_counter()
    yield
    assert time.perf_counter() - t0 < CASE_BUDGET_S


@pytest.fixture
def running(monkeypatch):
    """Set the number of running jobs on an 8-core machine."""
    monkeypatch.setattr(jobs, "usable_cores", lambda: CORES)

    def set_running(n):
        monkeypatch.setattr(jobs.JobRegistry, "running_count", lambda self: n)
    return set_running


class FakePool:
    """A process pool that records its size and runs each task at once in this process."""

    sizes = []

    def __init__(self, workers):
        FakePool.sizes.append(workers)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args):
        fut = Future()
        fut.set_result(fn(*args))
        return fut


def run_fn(system, excitation, duration):
    return {"duration": duration}


@pytest.mark.parametrize("n_running, expected", [(0, CORES), (1, CORES), (2, 4), (3, 2), (8, 1), (20, 1)])
def test_study_pools_share_the_cores(running, monkeypatch, n_running, expected):
    running(n_running)
    assert jobs.sweep_workers() == expected
    seen = {}

    def fake_run_sweep(system, points, **kw):
        seen.update(kw)
        return SimpleNamespace(n_points=len(points), from_cache=0, table=None)

    monkeypatch.setattr(C, "run_sweep", fake_run_sweep)
    C.mr_sweep(default_parameters(), [C.point(1500, 200, ((2.0, 300.0),))], C.Progress(None, 1), "processes")
    assert seen["workers"] == expected
    FakePool.sizes = []
    monkeypatch.setattr(C, "process_pool", FakePool)
    system = default_parameters()
    ex = C.point(1500, 200, ((2.0, 300.0),)).excitation()
    js = [(system, ex, 1.2 + 0.01 * i) for i in range(CORES + 4)]
    out = C.cached_runs("pool-probe", run_fn, js, C.Progress(None, len(js)), parallel=True)
    assert [o["duration"] for o in out] == [j[2] for j in js]
    assert FakePool.sizes == ([expected] if expected > 1 else [])  # one process: no pool at all


@pytest.mark.parametrize("n_running, expected", [(0, 2), (4, 2), (5, 1), (8, 1)])
def test_diagnosis_runner_shares_the_cores(running, n_running, expected):
    running(n_running)
    assert drive.Runner().workers == expected  # up to 2 processes, fewer when the cores are shared
    assert drive.Runner(3).workers == 3  # an explicit count (the command line's --workers) is kept
