"""Job registry (dampersim.jobs): limits, sharing, cancelling, reaping and settings, with
stand-in processes (``sleep``) instead of dashboard jobs.

Every test runs in well under a second except the ones that wait for a real process to be
terminated; budgets are stated where a time is asserted.
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import time

import psutil
import pytest

from dampersim.errors import InputError
from dampersim.jobs import (CANCELLED, DONE, FAILED, QUEUED, RUNNING, JobRegistry, Limits, process_alive,
                            process_ctime, terminate_tree)


@pytest.fixture
def registry_dir(tmp_path):
    path = tmp_path / "jobs"
    path.mkdir(mode=0o700)
    return path


def _sleeper(seconds=30):
    """A stand-in job process in its own session (like a real job, which calls setsid)."""
    return subprocess.Popen([sys.executable, "-c", f"import time; time.sleep({seconds})"], start_new_session=True)


def _fake_start(job_id, payload):
    return os.getpid()  # a live process that is not signalled by these tests


def test_settings_come_from_the_environment_and_bad_values_name_variable_value_and_range(monkeypatch):
    monkeypatch.setenv("DAMPERSIM_MAX_JOBS", "3")
    monkeypatch.setenv("DAMPERSIM_JOBS_PER_SESSION", "1")
    assert Limits.resolve() == Limits(3, 1, 30.0)
    assert Limits.resolve(max_jobs=5).max_jobs == 5  # an explicit value wins
    for bad in ("0", "two", "-1", "1.5", "100000"):
        monkeypatch.setenv("DAMPERSIM_MAX_JOBS", bad)
        with pytest.raises(InputError) as err:
            Limits.resolve()
        assert "DAMPERSIM_MAX_JOBS" in str(err.value) and repr(bad) in str(err.value)
        assert "whole number from 1 to 1024" in str(err.value)
    monkeypatch.delenv("DAMPERSIM_MAX_JOBS")
    monkeypatch.setenv("DAMPERSIM_JOBS_PER_SESSION", "x")
    with pytest.raises(InputError, match="DAMPERSIM_JOBS_PER_SESSION = 'x'"):
        Limits.resolve()
    monkeypatch.delenv("DAMPERSIM_JOBS_PER_SESSION")
    with pytest.raises(InputError, match="idle_timeout_s"):
        Limits.resolve(idle_timeout_s=0)
    assert Limits.resolve().max_jobs == len(os.sched_getaffinity(0))


def test_registry_lives_in_a_private_folder(cache_dir):
    reg = JobRegistry()
    assert reg.path.parent == cache_dir / "jobs"
    assert reg.path.parent.stat().st_mode & 0o777 == 0o700


def test_dispatch_honours_global_and_per_session_limits(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=3, per_session=2)
    a = [reg.submit("A").job_id for _ in range(4)]
    b = [reg.submit("B").job_id for _ in range(2)]
    started = reg.dispatch(_fake_start)
    # oldest first, but A may run only 2: the third slot goes to B's first job
    assert started == [a[0], a[1], b[0]]
    assert reg.running_count() == 3
    assert reg.dispatch(_fake_start) == []  # full: nothing more starts
    assert [reg.job_state(j) for j in a[2:] + b[1:]] == [QUEUED] * 3
    assert reg.queue_position(b[1]) == (2, 3)  # A's two queued jobs are older
    reg.finish(a[0])
    assert reg.dispatch(_fake_start) == [a[2]]  # A runs one job now: its next one is the oldest eligible
    assert reg.job_state(a[0]) == DONE


def test_per_session_queue_moves_when_the_session_frees_a_slot(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=4, per_session=1)
    a = [reg.submit("A").job_id for _ in range(3)]
    assert reg.dispatch(_fake_start) == [a[0]]  # free slots, but A may run one at a time
    reg.finish(a[0])
    assert reg.dispatch(_fake_start) == [a[1]]


def test_identical_work_keys_share_one_job_until_it_is_finished(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=2)
    first = reg.submit("A", "sweep-1")
    second = reg.submit("B", "sweep-1")
    other = reg.submit("B", "sweep-2")
    plain = [reg.submit("A"), reg.submit("A")]  # no work key: never shared
    assert second.shared and second.job_id == first.job_id and second.waiter_id != first.waiter_id
    assert not other.shared and other.job_id != first.job_id
    assert plain[0].job_id != plain[1].job_id
    reg.dispatch(_fake_start)
    assert reg.submit("C", "sweep-1").job_id == first.job_id  # running: still shared
    reg.finish(first.job_id)
    assert reg.submit("C", "sweep-1").job_id != first.job_id  # finished: a new job


def test_cancel_ends_a_job_only_when_no_other_waiter_polls(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=2)
    first = reg.submit("A", "w")
    second = reg.submit("B", "w")
    proc = _sleeper()
    try:
        reg.dispatch(lambda job, payload: proc.pid)
        assert reg.cancel(first.waiter_id) is False
        assert reg.job_state(first.job_id) == RUNNING and proc.poll() is None
        assert reg.waiter(first.waiter_id).detached
        assert reg.cancel(second.waiter_id) is True
        assert reg.job_state(first.job_id) == CANCELLED
        assert proc.wait(timeout=5) != 0  # terminated, not finished (it would sleep 30 s)
        queued = reg.submit("A")
        assert reg.cancel(queued.waiter_id) and reg.job_state(queued.job_id) == CANCELLED
        assert reg.cancel("w-unknown") is False  # a forged handle does nothing
    finally:
        proc.kill()


def test_reap_cancels_unpolled_jobs_and_fails_dead_ones(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=3, per_session=4, idle_timeout_s=0.3)
    idle, polled, dead, waiting = (reg.submit("S") for _ in range(4))
    procs = {idle.job_id: _sleeper(), polled.job_id: _sleeper(), dead.job_id: _sleeper()}
    try:
        reg.dispatch(lambda job, payload: procs[job].pid)
        assert reg.job_state(waiting.job_id) == QUEUED
        procs[dead.job_id].kill()
        procs[dead.job_id].wait()
        time.sleep(0.4)  # past the idle timeout (0.3 s)
        for sub in (polled, dead):
            reg.heartbeat(sub.waiter_id)
        report = reg.reap()
        assert report.idle == (idle.job_id,) and report.dropped == (waiting.job_id,)
        assert report.failed == (dead.job_id,)
        assert reg.job_state(dead.job_id) == FAILED and reg.job_state(polled.job_id) == RUNNING
        assert procs[idle.job_id].wait(timeout=5) != 0
        assert procs[polled.job_id].poll() is None
    finally:
        for p in procs.values():
            p.kill()


def test_terminate_tree_kills_the_process_group_but_never_a_reused_pid():
    leader = subprocess.Popen([sys.executable, "-c",
                               "import subprocess, sys, time; subprocess.Popen(['sleep', '30']); time.sleep(30)"],
                              start_new_session=True)
    try:
        deadline = time.monotonic() + 10
        while not psutil.Process(leader.pid).children() and time.monotonic() < deadline:
            time.sleep(0.02)
        child = psutil.Process(leader.pid).children()[0]
        ctime = process_ctime(leader.pid)
        terminate_tree(leader.pid, ctime + 1.0)  # a different creation time: another process
        assert leader.poll() is None and child.is_running()
        terminate_tree(leader.pid, ctime)
        assert leader.wait(timeout=5) != 0
        child_gone = not child.is_running() or child.status() == psutil.STATUS_ZOMBIE
        assert child_gone
        assert not process_alive(leader.pid, ctime)
    finally:
        leader.kill()


def test_shutdown_terminates_only_this_owners_jobs(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=2)
    mine, theirs = reg.submit("A"), reg.submit("B")
    procs = {mine.job_id: _sleeper(), theirs.job_id: _sleeper()}
    try:
        reg.dispatch(lambda job, payload: procs[job].pid)
        with reg._tx() as con:  # the second job was started by another server process
            con.execute("UPDATE jobs SET owner = 1 WHERE id = ?", (theirs.job_id,))
        assert reg.shutdown() == [mine.job_id]
        assert procs[mine.job_id].wait(timeout=5) != 0
        assert procs[theirs.job_id].poll() is None and reg.job_state(theirs.job_id) == RUNNING
    finally:
        for p in procs.values():
            p.kill()


def test_sweep_workers_share_the_cores_among_running_jobs(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=8, per_session=8)
    assert reg.sweep_workers(8) == 8
    for _ in range(3):
        reg.submit("A")
    reg.dispatch(_fake_start)
    assert reg.sweep_workers(8) == 2 and reg.sweep_workers(2) == 1


# ----------------------------------------------------------------------- races and failed starts
def test_cancel_between_claim_and_start_terminates_the_new_process(registry_dir):
    # dispatch claims the job (RUNNING, no pid yet), then starts its process; a cancel in
    # between finds no process to end: the start record must end it, or it runs uncounted
    reg = JobRegistry(registry_dir, max_jobs=2)
    sub = reg.submit("A")
    procs = []

    def start_with_a_cancel(job, payload):
        assert reg.cancel(sub.waiter_id) is True  # the tab is closed while the process starts
        procs.append(_sleeper())
        return procs[0].pid

    try:
        assert reg.dispatch(start_with_a_cancel) == []  # nothing counts as started
        assert reg.job_state(sub.job_id) == CANCELLED and reg.running_count() == 0
        assert procs[0].wait(timeout=5) != 0  # budget: SIGTERM now (the 30 s sleep never ends by itself)
        assert reg.job(sub.job_id)["pid"] is None
    finally:
        for p in procs:
            p.kill()


def test_a_failed_start_leaves_the_other_claimed_jobs_running(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=3, per_session=3)
    broken, fine = reg.submit("A"), reg.submit("A")
    proc = _sleeper()

    def start(job, payload):
        if job == broken.job_id:
            raise OSError("no more processes")
        return proc.pid

    try:
        assert reg.dispatch(start) == [fine.job_id]  # no exception: the second claim still started
        assert reg.job_state(broken.job_id) == FAILED
        assert reg.job_state(fine.job_id) == RUNNING and reg.job(fine.job_id)["pid"] == proc.pid
        assert reg.running_count() == 1
    finally:
        proc.kill()


def test_a_claim_without_a_process_is_failed_after_the_start_grace(registry_dir):
    from dampersim import jobs

    reg = JobRegistry(registry_dir, max_jobs=4, per_session=4)
    stale, fresh, orphan = reg.submit("A"), reg.submit("A"), reg.submit("A")
    with reg._tx() as con:  # claimed by a live server process (this one) that never recorded a process
        con.execute("UPDATE jobs SET state = 'running', owner = ?, started = ? WHERE id = ?",
                    (os.getpid(), time.time() - jobs.START_GRACE_S - 1, stale.job_id))
        con.execute("UPDATE jobs SET state = 'running', owner = ?, started = ? WHERE id = ?",
                    (os.getpid(), time.time(), fresh.job_id))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    with reg._tx() as con:  # claimed a moment ago by a server process that has ended since
        con.execute("UPDATE jobs SET state = 'running', owner = ?, started = ? WHERE id = ?",
                    (dead.pid, time.time(), orphan.job_id))
    report = reg.reap()
    assert set(report.failed) == {stale.job_id, orphan.job_id}
    assert reg.job_state(fresh.job_id) == RUNNING  # still within the grace of a live server
    assert reg.running_count() == 1


# ----------------------------------------------------------------------- queue caps
def test_queue_is_capped_per_session_and_in_total(registry_dir):
    reg = JobRegistry(registry_dir, max_jobs=1, per_session=1, queued_per_session=2, max_queued=3)
    a = [reg.submit("A", f"a{i}") for i in range(3)]
    assert [s.refused for s in a[:2]] == [None, None]
    assert "this session already has 2 jobs waiting (at most 2)" in a[2].refused and "try again later" in a[2].refused
    assert reg.job_state(a[2].job_id) == FAILED and reg.job(a[2].job_id)["pid"] is None
    assert reg.submit("B", "a0").shared  # attaching to a queued job adds no job: never refused
    b = [reg.submit("B") for _ in range(2)]
    assert b[0].refused is None
    assert "the server's queue is full (3 jobs waiting, at most 3)" in b[1].refused
    assert reg.queued_count() == 3
    assert not reg.submit("C", "a2").shared  # a refused job is never shared (it has no work key)
    with pytest.raises(InputError, match="queued_per_session"):
        JobRegistry(registry_dir, queued_per_session=0)


def _open_registry(folder, barrier, out):
    barrier.wait()  # every process opens the new registry at the same moment
    try:
        JobRegistry(folder)
        out.put(None)
    except Exception as exc:  # reported to the test, which names it
        out.put(repr(exc))


def test_processes_opening_a_new_registry_together_all_succeed(tmp_path):
    # switching a new database to WAL needs it exclusively, and SQLite says "locked" at once
    # rather than waiting when another process does the same: without _enable_wal's retry, 2 of
    # 240 openers failed in 30 rounds like these (8 processes each), and this test failed in 2
    # of 3 runs with the retry taken out: it catches the race often, not always
    ctx = multiprocessing.get_context("fork")
    errors = []
    for k in range(30):
        barrier, out = ctx.Barrier(8), ctx.Queue()
        procs = [ctx.Process(target=_open_registry, args=(tmp_path / str(k), barrier, out)) for _ in range(8)]
        for p in procs:
            p.start()
        errors += [e for e in (out.get(timeout=60) for _ in procs) if e is not None]
        for p in procs:
            p.join(timeout=60)
    assert errors == []
