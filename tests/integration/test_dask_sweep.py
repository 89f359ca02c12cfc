"""Sweeps on a Dask ``distributed`` scheduler started by the test on 127.0.0.1."""

import argparse
import math
import time

import numpy as np
import pandas as pd
import pytest

from dampersim import default_parameters
from dampersim.errors import InputError
from dampersim.sweeps import cache as sc
from dampersim.cli import sweeps as commands
from dampersim.sweeps.executor import run_sweep
from dampersim.sweeps.grid import make_grid

distributed = pytest.importorskip("distributed")

RPM = 2 * math.pi / 60
SHORT = dict(duration=1.0, window=0.4)  # 1.0 s simulated, last 0.4 s analysed
UNREACHABLE = "tcp://127.0.0.1:1"


@pytest.fixture(scope="module")
def cluster():
    # one in-process worker with two threads, tcp on loopback, no dashboard
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, protocol="tcp", host="127.0.0.1",
        dashboard_address=None,
    ) as c:
        yield c


@pytest.fixture(autouse=True)
def _no_scheduler_from_environment(monkeypatch):
    """A DAMPERSIM_SCHEDULER of the caller's shell must not redirect these tests."""
    monkeypatch.delenv("DAMPERSIM_SCHEDULER", raising=False)


def test_dask_gives_identical_numbers_to_serial(cluster, cache_dir):
    system = default_parameters()
    points = make_grid(np.array([1000.0, 1100.0, 1200.0]) * RPM, [150.0], "2:300,4:100")
    serial = run_sweep(system, points, executor="serial", cache=False, **SHORT)
    calls = []
    dask = run_sweep(system, points, scheduler=cluster.scheduler_address,
                     progress=lambda *a: calls.append(a), **SHORT)
    assert dask.executor == "dask"
    assert calls[-1] == (3, 3, 0)
    pd.testing.assert_frame_equal(serial.table, dask.table, check_exact=True)
    np.testing.assert_array_equal(serial.input_spectra, dask.input_spectra)
    # the parent stored what the workers computed
    again = run_sweep(system, points, executor="serial", **SHORT)
    assert again.from_cache == 3


def test_scheduler_from_environment(cluster, cache_dir, monkeypatch):
    monkeypatch.setenv("DAMPERSIM_SCHEDULER", cluster.scheduler_address)
    system = default_parameters()
    result = run_sweep(system, make_grid([1300 * RPM], [150.0], "2:300"), **SHORT)
    assert result.executor == "dask" and result.computed == 1


def test_worker_with_other_source_is_refused(cluster, cache_dir, monkeypatch):
    # the parent pretends to run other kernel source than the (in-process) worker
    system = default_parameters()
    points = make_grid([1400 * RPM], [150.0], "2:300")
    real = sc.kernel_source_hash()
    calls = {"n": 0}

    def parent_then_worker():
        calls["n"] += 1
        return "f" * 64 if calls["n"] == 1 else real

    monkeypatch.setattr(sc, "kernel_source_hash", parent_then_worker)
    with pytest.raises(InputError, match="would not match the cache key"):
        run_sweep(system, points, scheduler=cluster.scheduler_address, cache=False, **SHORT)


@pytest.mark.slow  # waits out the 5 s connection timeout
def test_unreachable_scheduler_fails_fast_with_its_address(cache_dir):
    system = default_parameters()
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"cannot reach the Dask scheduler at 'tcp://127\.0\.0\.1:1' within 5 s"):
        run_sweep(system, make_grid([1000 * RPM], [150.0], "2:300"), scheduler=UNREACHABLE, cache=False, **SHORT)
    assert time.perf_counter() - t0 < 15


@pytest.mark.slow  # waits out the 5 s connection timeout
def test_sweep_command_with_unreachable_scheduler_from_environment(cache_dir, tmp_path, monkeypatch):
    monkeypatch.setenv("DAMPERSIM_SCHEDULER", UNREACHABLE)
    parser = argparse.ArgumentParser(prog="dampersim")
    commands.add_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["sweep", "--speeds", "1000", "--duration", "1.0", "--window", "0.4",
                              "--no-progress", "--out", str(tmp_path / "out")])
    with pytest.raises(InputError, match="tcp://127.0.0.1:1"):
        args.func(args)
    assert not (tmp_path / "out" / "sweep.parquet").exists()
