"""The chapter 7 studies under the server's budget: each study's cost comes from its own
grid before anything runs (the reduced grid costs less than the full one), and the
Studies page refuses a study above the budget with a notice naming the estimate and the
limit, both when the Run button is pressed and again in the background job, without
simulating anything.

Budgets used below, and why:
* WALL = 2 s per call: an estimate builds the study's test points (the largest, the full
  mapping grid of about a thousand points, in about 0.1 s) and runs nothing; 2 s leaves
  room for a loaded 2-core machine, while the cheapest study takes about a second of
  simulation and the full ones minutes.
* MEM = 20 MB of Python allocations (tracemalloc peak): a plan of at most about a
  thousand test points and a notice; a study that ran would allocate tens of MB per run.
"""

from __future__ import annotations

import json
import re
import sys
import time
import tracemalloc

import pytest

from dampersim import costs
from dampersim.studies import STUDIES, study_cost, study_plan

WALL = 2.0
MEM = 20e6
PATH = re.compile(r"(?<![\w.])/(?:work|tmp|home|root|usr|var|opt)/")


def text_of(obj) -> str:
    return json.dumps(obj, ensure_ascii=False,
                      default=lambda c: c.to_plotly_json() if hasattr(c, "to_plotly_json") else str(c))


def bounded(fn, *args, **kwargs):
    """Run ``fn`` within the wall-time and memory budgets; returns its result and its text
    (checked for tracebacks and server paths). The time is taken on a call without
    tracemalloc, which slows the engine-signal arithmetic of a plan about twentyfold; the
    memory on a second call with it (every call here is repeatable: it runs nothing)."""
    t0 = time.perf_counter()
    fn(*args, **kwargs)
    wall = time.perf_counter() - t0
    tracemalloc.start()
    try:
        out = fn(*args, **kwargs)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert wall < WALL, f"{getattr(fn, '__name__', fn)} took {wall:.2f} s"
    assert peak < MEM, f"{getattr(fn, '__name__', fn)} allocated {peak / 1e6:.0f} MB"
    text = text_of(out)
    assert "Traceback" not in text and not PATH.search(text), text[:500]
    return out, text


def _plain(f):
    return getattr(f, "__wrapped__", f)


@pytest.fixture(autouse=True)
def _fresh(cache_dir, monkeypatch):
    for name in (costs.BUDGET_ENV, costs.AUTOSTART_ENV, costs.BYTES_ENV):
        monkeypatch.delenv(name, raising=False)


@pytest.fixture(scope="module")
def page():
    import app  # noqa: F401  (Dash loads the page modules)

    return sys.modules["pages.studies"]


@pytest.fixture
def nothing_runs(monkeypatch):
    """Make every way a study computes fail the test if it is reached: the study runner the
    view calls and the integrator kernel under every simulation."""
    import dampersim.simulation.damper as damper
    import dampersim.views.studies as view

    calls = []

    def refuse(*a, **k):
        calls.append(a)
        raise AssertionError("a study above the budget must not run")
    monkeypatch.setattr(view, "run_study", refuse)
    monkeypatch.setattr(damper, "run_damper", refuse)
    return calls


# --------------------------------------------------------------------------- the estimates
@pytest.mark.parametrize("name", list(STUDIES))
def test_reduced_grid_costs_less_than_the_full_one(name):
    (quick, full), _ = bounded(lambda: (study_cost(name, True), study_cost(name, False)))
    assert 0 < quick.work < full.work
    assert 0 < quick.bytes <= full.bytes
    assert study_plan(name, True).simulations() < study_plan(name, False).simulations()
    assert name in quick.what and "reduced grid" in quick.what and "full grid" in full.what


def test_estimate_follows_the_parameter_set():
    # the cost is built from the study's runs on the given set, not a fixed figure: halving
    # the time step doubles every run's steps (the runs' durations are the set's or the
    # study's, not the step's), so the work doubles exactly, up to float rounding
    from dampersim.parameters import default_parameters, with_updates

    base = default_parameters()
    fine = with_updates(base, {"solver.time_step": base.solver.time_step / 2})
    for name in STUDIES:
        assert study_cost(name, True, fine).work == pytest.approx(2 * study_cost(name, True, base).work, rel=1e-9)


# --------------------------------------------------------------------------- the page
def test_estimate_is_shown_next_to_the_run_button(page):
    layout, _ = bounded(page.layout)
    ids = [getattr(c, "id", None) for c in layout.children[2].children]
    assert ids.index("st-estimate") == ids.index("st-run") + 1
    text, _ = bounded(_plain(page.estimate), "mapping", [])
    cost = study_cost("mapping", False)
    mantissa, exponent = f"{cost.work:.1e}".split("e")
    assert text.startswith(f"about {mantissa}e{int(exponent)}") and "step·DOF" in text
    assert f"~{costs.duration_text(cost.seconds())} of one core" in text and "will not run" not in text


def test_lowered_budget_refuses_on_run_and_in_the_job(page, monkeypatch, nothing_runs):
    from dash import no_update

    cost = study_cost("order-rule", True)  # the cheapest study, on its reduced grid
    monkeypatch.setenv(costs.BUDGET_ENV, f"{cost.work / 2:g}")
    limit = costs.budgets().limit
    estimate = cost.text()  # "about 3.1e7 step·DOF and 20 MB"
    limit_text = f"{limit:.1e}".replace("e+0", "e").replace("e+", "e") + " step·DOF"

    # next to the Run button: the estimate and that it will not run
    shown, _ = bounded(_plain(page.estimate), "order-rule", ["1"])
    assert "will not run" in shown and limit_text in shown

    # the Run button: a notice with the estimate and the limit, and no job
    (notices, job), text = bounded(_plain(page.request), 1, "order-rule", ["1"])
    assert job is no_update
    assert "Refused" in text and estimate in text and limit_text in text and costs.BUDGET_ENV in text

    # a job posted anyway (a crafted request): the job checks again and runs nothing
    (figs, checks, doc), text = bounded(_plain(page.run_job), lambda p: None, {"study": "order-rule", "quick": True, "n": 1})
    assert figs == [] and doc == ""
    assert "Refused" in text and estimate in text and limit_text in text
    assert nothing_runs == []


def test_within_the_budget_the_run_button_starts_the_job(page, nothing_runs):
    (notices, job), _ = bounded(_plain(page.request), 3, "speed-stiffness", [])
    assert notices == [] and job == {"study": "speed-stiffness", "quick": False, "n": 3}
    assert nothing_runs == []  # the request only admits; the background job computes


@pytest.mark.parametrize("name", ["nope", None, ["order-rule"], {"a": 1}])
def test_posted_nonsense_is_named_not_run(page, nothing_runs, name):
    (notices, job), text = bounded(_plain(page.request), 1, name, ["1"])
    assert "accepted is one of" in text
    (figs, checks, doc), text = bounded(_plain(page.run_job), lambda p: None, {"study": name})
    assert figs == [] and "accepted is one of" in text
    (_f, _c, _d), text = bounded(_plain(page.run_job), lambda p: None, "not a request")
    assert "accepted is one of" in text
    assert nothing_runs == []
