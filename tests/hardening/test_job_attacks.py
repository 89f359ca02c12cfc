"""Attacks on the job queue through what a browser can post: a work key of another
session, made-up session cookies, a flood of submissions; and a restarted server that
finds the jobs of a dead one.

The managers here use the dashboard's own resolver of the work key
(:func:`pages._jobs.ticket_work`: the key stored with the ticket on the server) and its
answer to a refused submission (:func:`pages._jobs.refused_result`), with small job
functions from test_background_manager.py instead of sweeps.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from flask import Flask, request

from dampersim.jobs import FAILED, JobRegistry
from dampersim.views import tickets
from pages import _jobs, _sessions
from pages._background import ANONYMOUS, SESSION_COOKIE, current_session, install_sessions, make_manager, sign_session
from tests.hardening.test_background_manager import Caller, poll_all
from tests.hardening.test_background_manager import warm_fork_server  # noqa: F401  (module fixture: fork server warm)


@pytest.fixture
def dashboard_manager(tmp_path, cache_dir):
    made = []

    def make(**limits):
        limits.setdefault("idle_timeout_s", 10.0)
        m = make_manager(tmp_path / "callbacks", registry_dir=tmp_path / "jobs", work_of=_jobs.ticket_work,
                         refused_result=_jobs.refused_result, **limits)
        made.append(m)
        return m

    yield make
    for m in made:
        m.close()


def _job_id(manager, caller):
    return manager.registry.waiter(caller.job).job_id


# ----------------------------------------------------------------------- the work key
def test_a_posted_work_key_of_another_session_does_not_attach_its_requests(dashboard_manager):
    manager = dashboard_manager(max_jobs=4, per_session=4)
    victim_work, attacker_work = "v" * 64, "a" * 64
    # the attacker's own (valid) request, posted with the victim's work key
    attacker_ticket = tickets.issue("colourmap", {"speeds": "1000"}, attacker_work)
    attacker = Caller(manager, "sleep_and_return", {"ticket": attacker_ticket, "work": victim_work, "sleep": 1.0},
                      session="a" * 32)
    # then two sessions ask for the victim's state: the server stored its work key with their tickets
    victims = [Caller(manager, "sleep_and_return",
                      {"ticket": tickets.issue("colourmap", {"speeds": "2000"}, victim_work), "work": victim_work,
                       "sleep": 0.3}, session=s * 32) for s in "bc"]
    assert _job_id(manager, victims[0]) != _job_id(manager, attacker)  # the victim's request has its own job
    assert _job_id(manager, victims[1]) == _job_id(manager, victims[0])  # identical requests still share
    poll_all([attacker, *victims], budget_s=10)  # budget: a 1 s and a 0.3 s job, forked by the warm fork server
    assert victims[0].result == victims[1].result and victims[0].result["pid"] != attacker.result["pid"]


def test_a_job_whose_key_is_not_its_tickets_work_is_refused(cache_dir):
    ticket = tickets.issue("colourmap", {"speeds": "1000"}, "k-stored")
    assert tickets.peek(ticket) == {"page": "colourmap", "state": {"speeds": "1000"}, "work": "k-stored"}
    assert tickets.peek(ticket, "maps") is None
    same = _jobs.run_ticket("colourmap", lambda data, progress: {"key": "k-stored"}, {"ticket": ticket, "nonce": "n"},
                            None)
    assert same == {"key": "k-stored", "nonce": "n"}
    other = _jobs.run_ticket("colourmap", lambda data, progress: {"key": "k-other"}, {"ticket": ticket, "nonce": "n"},
                             None)
    assert other == {"error": _jobs.MISMATCH_TEXT, "nonce": "n"}


# ----------------------------------------------------------------------- sessions
def test_only_a_cookie_signed_by_the_server_names_a_session(tmp_path):
    folder = tmp_path / "jobs"
    app = Flask("signed_sessions")
    install_sessions(app, folder)
    app.add_url_rule("/", "index", lambda: current_session(folder))
    client = app.test_client()
    signed = sign_session("a" * 32, folder)
    forged = {"unsigned": "a" * 32, "bad signature": "a" * 32 + "." + "0" * 64,
              "another session's signature": "b" * 32 + "." + signed.split(".")[1]}
    for what, value in forged.items():
        client.set_cookie(SESSION_COOKIE, value)
        resp = client.get("/")
        assert resp.get_data(as_text=True) == ANONYMOUS, what
        new = resp.headers["Set-Cookie"].split(";")[0].split("=", 1)[1]  # a new signed cookie instead
        assert new != value and _sessions.verified_session(new, folder), what
    client.set_cookie(SESSION_COOKIE, signed)
    resp = client.get("/")
    assert resp.get_data(as_text=True) == "a" * 32 and "Set-Cookie" not in resp.headers
    assert (folder / _sessions.SECRET_FILE).stat().st_mode & 0o777 == 0o600
    with app.test_request_context("/", headers={"Cookie": f"{SESSION_COOKIE}={signed}"}):
        assert request.cookies[SESSION_COOKIE] == signed and current_session(tmp_path / "other") == ANONYMOUS


def test_made_up_session_cookies_share_one_session_limit(dashboard_manager):
    manager = dashboard_manager(max_jobs=4, per_session=1)
    callers = [Caller(manager, "sleep_and_return", {"sleep": 0.3}, cookie=c * 32) for c in "abc"]
    rows = [manager.registry.job(_job_id(manager, c)) for c in callers]
    assert {r["session"] for r in rows} == {ANONYMOUS}
    assert manager.registry.running_count() == 1  # one slot for all made-up sessions together
    poll_all(callers, budget_s=10)  # budget: three 0.3 s jobs one after the other, forked by the warm fork server


# ----------------------------------------------------------------------- queue caps
def test_a_submission_above_the_queue_cap_is_answered_at_once_without_a_process(dashboard_manager):
    manager = dashboard_manager(max_jobs=1, per_session=1, queued_per_session=1)
    running, queued = (Caller(manager, "sleep_and_return", {"ticket": None, "nonce": f"n{i}", "sleep": 0.5},
                              session="a" * 32) for i in range(2))
    t0 = time.monotonic()
    refused = Caller(manager, "sleep_and_return", {"ticket": None, "nonce": "n3", "sleep": 0.5}, session="a" * 32)
    assert refused.poll() is False  # the answer is there on the first poll
    assert time.monotonic() - t0 < 2.0  # budget: two registry transactions and a cache write, no process
    assert refused.result["nonce"] == "n3"
    error = refused.result["error"]
    assert error.startswith("the server's queue is full") and "try again later" in error
    job = manager.registry.job(_job_id(manager, refused))
    assert job["state"] == FAILED and job["pid"] is None
    other = Caller(manager, "sleep_and_return", {"sleep": 0.5}, session="b" * 32)  # other sessions still queue
    assert manager.registry.job(_job_id(manager, other))["state"] == "queued"
    poll_all([running, queued, other], budget_s=10)  # budget: three 0.5 s jobs on one slot, warm fork server
    assert manager.registry.job(_job_id(manager, refused))["pid"] is None


# ----------------------------------------------------------------------- a restarted server
def test_a_restarted_server_does_not_count_a_dead_servers_jobs(cache_dir, monkeypatch):
    import app

    monkeypatch.setenv("DAMPERSIM_MAX_JOBS", "2")
    reg = JobRegistry()
    jobs = [reg.submit("A").job_id for _ in range(2)]
    ended = subprocess.Popen([sys.executable, "-c", "pass"])  # stands for a job process and its server
    ended.wait()
    assert reg.dispatch(lambda job, payload: ended.pid) == jobs  # recorded as running (dead pid, no ctime)
    with reg._tx() as con:
        con.execute("UPDATE jobs SET owner = ?", (ended.pid,))
    assert reg.running_count() == 2  # the new server's limit would be used up
    app.cleanup_at_start(cache_dir)
    assert reg.running_count() == 0 and [reg.job_state(j) for j in jobs] == [FAILED, FAILED]
    assert os.path.exists(reg.path)
