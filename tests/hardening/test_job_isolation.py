"""A job process must not inherit the server's SQLite state.

The server is threaded: while one request thread is inside a cache transaction, another
starts a job. A process forked at that moment inherits SQLite's record of a lock it does
not hold; its own cache writes then hang or fail with "disk I/O error" (before the fork
server, 4 of 8 sessions of a load run failed this way). Job processes are therefore forked
by a clean fork server. The second test runs the same scenario with plain fork, to show the
first test can fail.
"""

from __future__ import annotations

import threading
import time

import diskcache
import pytest

from pages._background import make_manager
from tests.hardening.test_background_manager import FUNCTIONS, POLL_S, Caller
from tests.hardening.test_background_manager import warm_fork_server  # noqa: F401  (module fixture: fork server warm)


def write_to_shared_cache(job):
    cache = diskcache.Cache(job["dir"], timeout=2)  # a lock that never clears fails after 2 s
    cache.set("from-the-job", 3)
    out = cache.get("from-the-job")
    cache.close()
    return {"value": out}


FUNCTIONS[write_to_shared_cache.__name__] = write_to_shared_cache


def _run_while_a_thread_holds_a_transaction(tmp_path, start_method, budget_s):
    shared = diskcache.Cache(str(tmp_path / "shared"))
    shared.set("a", 1)
    holding, release = threading.Event(), threading.Event()

    def request_thread():
        with shared.transact():
            shared.set("b", 2)
            holding.set()
            release.wait(10)

    t = threading.Thread(target=request_thread)
    t.start()
    holding.wait(5)
    manager = make_manager(tmp_path / "callbacks", registry_dir=tmp_path / "jobs", max_jobs=2,
                           start_method=start_method, idle_timeout_s=30.0)
    try:
        caller = Caller(manager, "write_to_shared_cache", {"dir": str(tmp_path / "shared")})
        time.sleep(0.3)  # the job starts while the transaction is still open
        release.set()
        t.join()
        deadline = time.monotonic() + budget_s
        while caller.poll() and time.monotonic() < deadline:
            time.sleep(POLL_S)
        return caller.result
    finally:
        release.set()
        manager.close()
        shared.close()


def test_a_job_started_during_a_transaction_writes_the_cache(tmp_path):
    # budget: a trivial job forked by the warm fork server, on two busy cores
    result = _run_while_a_thread_holds_a_transaction(tmp_path, "forkserver", budget_s=10.0)
    assert result == {"value": 3}, result


def test_plain_fork_in_the_same_scenario_does_not_write(tmp_path):
    result = _run_while_a_thread_holds_a_transaction(tmp_path, "fork", budget_s=8.0)
    assert result != {"value": 3}, "plain fork wrote the cache: the scenario no longer shows the hazard"


def report_cache_dir(job):
    import os

    return {"cache": os.environ.get("DAMPERSIM_CACHE_DIR")}


FUNCTIONS[report_cache_dir.__name__] = report_cache_dir


def test_a_job_sees_the_servers_settings_of_now_not_the_fork_servers(tmp_path, monkeypatch):
    # the fork server keeps the environment it started with; a job must take the server's
    # current DAMPERSIM_* settings (here: a cache folder changed after the first job)
    manager = make_manager(tmp_path / "callbacks", registry_dir=tmp_path / "jobs", max_jobs=2, idle_timeout_s=30.0)
    try:
        results = []
        for name in ("first", "second"):
            monkeypatch.setenv("DAMPERSIM_CACHE_DIR", str(tmp_path / name))
            caller = Caller(manager, "report_cache_dir", {"n": name})
            deadline = time.monotonic() + 10.0  # a trivial job forked by the warm fork server
            while caller.poll() and time.monotonic() < deadline:
                time.sleep(POLL_S)
            results.append(caller.result)
        assert results == [{"cache": str(tmp_path / "first")}, {"cache": str(tmp_path / "second")}], results
    finally:
        manager.close()
