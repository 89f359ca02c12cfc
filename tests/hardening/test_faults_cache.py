"""Faults around the sweep cache: a full disk (ENOSPC injected into the write, or SQLite's
"database or disk is full") lets the sweep finish uncached and say so; an unencrypted Dask
scheduler on another machine is refused before any connection.

Budgets: the sweep is two short test points in this process (1.0 s simulated each, about
0.3 s of kernel time each plus the first compile from numba's cache); 30 s allows a cold
cache on a loaded 2-core machine. The address checks make no connection: 1 s.
"""

from __future__ import annotations

import errno
import math
import sqlite3
import time

import diskcache
import numpy as np
import pytest

from dampersim import default_parameters
from dampersim.errors import InputError
from dampersim.sweeps import cache as sc
from dampersim.sweeps import run_sweep
from dampersim.sweeps.backends import check_scheduler_address
from dampersim.sweeps.grid import make_grid

RPM = 2 * math.pi / 60
SWEEP_BUDGET_S = 30.0
CHECK_BUDGET_S = 1.0


def full_disk(exc):
    def write(self, *args, **kwargs):
        raise exc
    return write


@pytest.mark.parametrize("exc", [OSError(errno.ENOSPC, "No space left on device"),
                                 sqlite3.OperationalError("database or disk is full")])
def test_full_disk_sweep_completes_uncached(cache_dir, monkeypatch, exc):
    points = make_grid(np.array([1000.0, 1100.0]) * RPM, [200.0], "2:300")
    # only the write is patched, and only here (undoing the whole monkeypatch would also
    # take back the cache folder of the fixture)
    with monkeypatch.context() as patch:
        patch.setattr(diskcache.Cache, "set", full_disk(exc))
        t0 = time.perf_counter()
        res = run_sweep(default_parameters(), points, executor="serial", duration=1.0, window=0.4)
        assert time.perf_counter() - t0 < SWEEP_BUDGET_S
    assert res.computed == 2 and res.uncached == 2 and len(res.table) == 2 * 8
    assert np.isfinite(res.table["output_amplitude_nm"]).all()
    assert "2 of 2 test points were computed but not cached" in res.cache_notice
    assert "out of disk space" in res.cache_notice and "Free disk space" in res.cache_notice
    with sc.ResultCache() as store:
        assert store.directory == sc.results_dir() and str(cache_dir) in str(store.directory)
        assert len(store) == 0  # nothing half-written


def test_other_write_errors_still_raise(cache_dir, monkeypatch):
    monkeypatch.setattr(diskcache.Cache, "set", full_disk(OSError(errno.EACCES, "Permission denied")))
    with sc.ResultCache() as store, pytest.raises(OSError):
        store.put("k", b"x")


def test_a_full_cache_stops_writing(cache_dir, monkeypatch):
    calls = []

    def write(self, *args, **kwargs):
        calls.append(1)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(diskcache.Cache, "set", write)
    with sc.ResultCache() as store:
        assert store.put("a", b"x") is False and store.put("b", b"y") is False
        assert len(calls) == 1 and store.unstored == 2 and not store.writable


@pytest.mark.parametrize("address", ["tcp://10.0.0.5:8786", "10.0.0.5:8786", "tcp://scheduler.example:8786",
                                     "ws://10.0.0.5:8786", "TCP://192.168.1.2:8786", "tcp://[fd00::1]:8786"])
def test_insecure_remote_scheduler_refused(monkeypatch, address):
    monkeypatch.delenv("DAMPERSIM_ALLOW_INSECURE_DASK", raising=False)
    t0 = time.perf_counter()
    with pytest.raises(InputError) as exc:
        check_scheduler_address(address)
    message = str(exc.value)
    assert repr(address) in message and "tls://" in message and "DAMPERSIM_ALLOW_INSECURE_DASK=1" in message
    assert time.perf_counter() - t0 < CHECK_BUDGET_S


def test_run_sweep_refuses_before_connecting(cache_dir, monkeypatch):
    monkeypatch.delenv("DAMPERSIM_ALLOW_INSECURE_DASK", raising=False)
    monkeypatch.setenv("DAMPERSIM_SCHEDULER", "tcp://10.0.0.5:8786")
    points = make_grid(np.array([1000.0]) * RPM, [200.0], "2:300")
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="tls://"):
        run_sweep(default_parameters(), points, duration=1.0, window=0.4)
    assert time.perf_counter() - t0 < 5 * CHECK_BUDGET_S  # no 5 s connection attempt


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:8786", "tcp://localhost:8786", "127.0.0.1:8786",
                                     "tcp://[::1]:8786", "tls://10.0.0.5:8786", "tls://scheduler.example:8786",
                                     "inproc://10.0.0.5/1/1"])
def test_secure_or_local_scheduler_accepted(monkeypatch, address):
    monkeypatch.delenv("DAMPERSIM_ALLOW_INSECURE_DASK", raising=False)
    assert check_scheduler_address(address) == address


def test_explicit_opt_in_accepts_tcp(monkeypatch):
    monkeypatch.setenv("DAMPERSIM_ALLOW_INSECURE_DASK", "1")
    assert check_scheduler_address("tcp://10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    monkeypatch.setenv("DAMPERSIM_ALLOW_INSECURE_DASK", "yes please")  # only "1" counts
    with pytest.raises(InputError):
        check_scheduler_address("tcp://10.0.0.5:8786")
