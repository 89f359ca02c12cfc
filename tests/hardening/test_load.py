"""Load: 16 sessions open sweep links at once on a real server (loopback, fixed count,
stops by itself).

Four distinct sweeps, each asked for by four sessions. The server runs with a global
limit of 2 jobs. What must hold while the sweeps run: never more job processes than the
limit; the server's process tree and memory stay bounded; a light page request is
answered within 1 s at p95; identical sweeps are computed once (one job per distinct
link); every session gets its result; stopping the server leaves no process behind.
"""

from __future__ import annotations

import pytest

from tests.hardening.loadrun import run_load, start_server, stop_server

MAX_JOBS = 2
SESSIONS = 16
DISTINCT = 4


@pytest.mark.slow
def test_sixteen_sessions_starting_sweeps(tmp_path):
    proc, base = start_server(tmp_path / "cache", "--max-jobs", str(MAX_JOBS), "--jobs-per-session", "2")
    try:
        out = run_load(base, proc.pid, SESSIONS, distinct=DISTINCT, points=4, duration=6.0, deadline_s=240.0)
    finally:
        orphans = stop_server(proc)
    assert out["failed"] == [], out["failed"][:3]
    assert out["finished"] == SESSIONS
    assert out["max_jobs"] <= MAX_JOBS, out
    # identical requests share one job: at most one job process per distinct link
    assert out["jobs_started"] <= DISTINCT, out
    # bounded tree: the server, its job processes, each with at most one pool worker per
    # core (2 here) and a resource tracker, plus slack for a job being replaced
    assert out["max_processes"] <= 1 + MAX_JOBS * 4 + 2, out
    # bounded memory: measured ~0.3 GB per busy process here; unbounded (before the job
    # limit) 8 sessions reached 3.7 GB
    assert out["peak_rss_mb"] < 2500, out
    # a light request stays interactive while every core computes
    assert out["latency_p95_s"] < 1.0, out
    assert out["probe_count"] > 20, out
    assert orphans == [], f"processes left after the server stopped: {orphans}"
