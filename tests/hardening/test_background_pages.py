"""The background callbacks of the Pulsation and Studies pages through a real server and
its job queue: their jobs start from the fork server, find their callback and answer.

A page module registers a Dash page when it is imported, so a job process cannot load a
callback of it by reference alone; it must fall back to the callback's Dash key after
importing the app. Without that fallback both jobs end without a result. Each job here
takes a few seconds (a 9-speed generator sweep, the reduced order-rule study).
"""

from __future__ import annotations

import pytest

from tests.hardening.dashclient import DashSession
from tests.hardening.loadrun import start_server, stop_server


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    proc, base = start_server(tmp_path_factory.mktemp("bg") / "cache")
    yield base
    assert stop_server(proc) == [], "processes left after the server stopped"


@pytest.mark.slow
def test_pulsation_sweep_job_answers(server):
    s = DashSession(server)
    s.open("/pulsation")
    resp, _ = s.run_background("pg-dominant.figure", {"pg-sweep.n_clicks": 1}, deadline_s=120)
    assert resp.status == 200, resp.text[:300]
    figure = resp.json["response"]["pg-dominant"]["figure"]
    assert figure["data"] and "order" in figure["data"][0]["name"]


@pytest.mark.slow
def test_study_job_answers(server):
    s = DashSession(server)
    s.open("/studies?study=order-rule&quick=1")
    req = s.call_outputs("st-job.data", {"st-run.n_clicks": 1}, changed=["st-run.n_clicks"])
    job = req.json["response"]["st-job"]["data"]
    assert job["study"] == "order-rule"
    resp, _ = s.run_background("st-figures.children", {"st-job.data": job}, deadline_s=120)
    assert resp.status == 200, resp.text[:300]
    assert resp.json["response"]["st-figures"]["children"], resp.text[:300]
    assert "Traceback" not in resp.text
