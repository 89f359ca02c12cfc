"""Pulsation page: its foreground run and its background sweep are estimated and admitted
like every other request, so a server with a small budget refuses them with the estimate
and the limit, before anything is simulated.

Budget: 5 s per case: a refusal computes nothing (the generator's kernel is replaced by one
that fails), a parse and an estimate take milliseconds.
"""

from __future__ import annotations

import inspect
import sys
import time

import pytest

from dampersim import costs, default_parameters
from dampersim.parameters.engine import default_pulsation_generator
from dampersim.simulation.pulsation import simulate_pulsation
from dampersim.views import pulsation as V

CASE_BUDGET_S = 5.0


@pytest.fixture(autouse=True)
def budget(monkeypatch):
    for name in (costs.BUDGET_ENV, costs.AUTOSTART_ENV, costs.BYTES_ENV):
        monkeypatch.delenv(name, raising=False)
    t0 = time.perf_counter()
    yield
    assert time.perf_counter() - t0 < CASE_BUDGET_S


def no_simulation(monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("the generator must not run")
    monkeypatch.setattr(V, "simulate_pulsation", refuse)
    monkeypatch.setattr(V, "dominant_order_over_speed", refuse)


def test_cost_of_a_generator_run():
    d = inspect.signature(simulate_pulsation).parameters
    steps = round(d["duration"].default / d["time_step"].default)  # 2.6 s at 1e-5 s: 260 000 steps
    gen = len(default_pulsation_generator().chain)
    alone = costs.pulsation_cost()
    assert alone.work == pytest.approx(steps * costs.GENERATOR_DOF_WEIGHT * gen)
    coupled = costs.pulsation_cost(coupled=True)
    assert coupled.work == pytest.approx(steps * (costs.GENERATOR_DOF_WEIGHT * gen
                                                  + costs.degrees_of_freedom(default_parameters())))
    assert 3 * steps * 8 < alone.bytes < coupled.bytes < 50e6  # step-grid arrays and records: tens of MB
    sweep = costs.pulsation_cost(runs=len(V.SWEEP_SPEEDS_RPM))
    assert sweep.work == pytest.approx(len(V.SWEEP_SPEEDS_RPM) * alone.work) and sweep.bytes == alone.bytes
    longer = costs.pulsation_cost(duration=26.0, time_step=1e-6)
    assert longer.work == pytest.approx(100 * alone.work)
    # the page's own runs start on the default budgets
    assert costs.admit(coupled, foreground=True) == "run" and costs.admit(costs.pulsation_cost(True, runs=9)) == "run"


def test_small_budget_refuses_the_run_with_estimate_and_limit(monkeypatch):
    no_simulation(monkeypatch)
    monkeypatch.setenv(costs.BUDGET_ENV, "1e5")
    with pytest.raises(costs.BudgetError) as exc:
        V.pulsation_view(2.5, 1500, ["1"])
    text = str(exc.value)
    assert "pulsation generator run coupled to the damper" in text and "step·DOF" in text
    assert "1.0e5 step·DOF" in text and costs.BUDGET_ENV in text
    with pytest.raises(costs.BudgetError, match="dominant order over 9 speeds"):
        V.dominant_order_view(2.5, [])


def test_page_shows_the_refusal(monkeypatch):
    import app  # noqa: F401  (Dash loads the page modules)

    page = sys.modules["pages.pulsation"]
    no_simulation(monkeypatch)
    monkeypatch.setenv(costs.BUDGET_ENV, "1e5")
    out = page.run(1, 2.5, 1500, [])
    assert out[0] is page.dash.no_update and "1.0e5 step·DOF" in out[-1] and costs.BUDGET_ENV in out[-1]
    fig, msg = page.sweep(lambda progress: None, 1, 2.5, [])  # the background callback's function
    assert fig is page.dash.no_update and "1.0e5 step·DOF" in msg and "dominant order over 9 speeds" in msg


def test_foreground_limit_holds_for_the_run(monkeypatch):
    no_simulation(monkeypatch)
    monkeypatch.setenv(costs.BUDGET_ENV, "1e12")
    monkeypatch.setattr(costs, "pulsation_cost", lambda *a, **k: costs.Cost(2 * costs.FOREGROUND_WORK, 1e6, "a long run"))
    with pytest.raises(costs.BudgetError, match="dampersim simulate"):
        V.pulsation_view(2.5, 1500, [])
