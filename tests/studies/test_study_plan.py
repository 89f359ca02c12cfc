"""Each study's plan against the study itself: the plan (built from the study's own grid,
before anything is simulated, the source of :func:`dampersim.studies.study_cost`) counts
exactly the simulations the study then makes on an empty cache, and their step·DOF.

Counting: every simulation ends in one call of the integrator kernel
(``dampersim.simulation.damper.run_damper``), whatever asked for it (a sweep point or a
cached study run); a wrapper counts the calls and their work, ``len(torque)`` steps x the
layout's DOF, as the kernel sees them (not through the cost model's formulas). The
studies run with ``executor="serial"`` so every call happens in this process, on a fresh
cache so nothing is served from an earlier run.
"""

from __future__ import annotations

import time

import pytest

import dampersim.simulation.damper as damper
from dampersim.parameters import at_thesis_segments
from dampersim.studies import STUDIES, run_study, study_cost, study_plan

THESIS_SEGMENTS = at_thesis_segments()


class KernelCounter:
    """Stands in for ``run_damper``: records (steps, DOF) of each call, then runs it."""

    def __init__(self, real):
        self.real = real
        self.calls = []

    def __call__(self, lay, torque, *args, **kwargs):
        self.calls.append((len(torque), lay.ndof))
        return self.real(lay, torque, *args, **kwargs)

    @property
    def work(self) -> float:
        return float(sum(steps * dof for steps, dof in self.calls))


@pytest.fixture
def counter(cache_dir, monkeypatch):
    c = KernelCounter(damper.run_damper)
    monkeypatch.setattr(damper, "run_damper", c)
    return c


def check_plan_is_the_run(name, counter, system=None):
    plan = study_plan(name, quick=True, system=system)
    cost = study_cost(name, quick=True, system=system)
    t0 = time.perf_counter()
    res = run_study(name, system, quick=True, executor="serial")
    wall = time.perf_counter() - t0
    # the plan's simulations are the study's: none missing, none extra
    assert len(counter.calls) == plan.simulations(), (name, len(counter.calls), plan.simulations())
    assert res["computed"] == plan.total and res["from_cache"] == 0  # a fresh cache: every progress unit computed
    # steps and DOF are whole numbers on both sides: the estimate is exact, up to the
    # rounding of a float sum of a few dozen products below 1e8 (far under 1e-12 relative)
    assert cost.work == pytest.approx(counter.work, rel=1e-12), (name, cost.work, counter.work)
    print(f"{name}: {plan.simulations()} simulations planned, {len(counter.calls)} run; "
          f"{cost.work:.3e} step·DOF estimated, {counter.work:.3e} run; ~{cost.seconds():.1f} s of one core "
          f"estimated, {wall:.1f} s wall (serial, including the analysis)")
    return plan


# The two cheapest studies on their reduced grids (5 simulations each, about 4 s of one
# core); additional-orders repeats its dominant-only point (progress 6, simulations 5),
# so it also checks that a repeated point is counted once, as the sweep computes it once.
@pytest.mark.parametrize("name", ["order-rule", "additional-orders"])
def test_plan_counts_the_cheapest_studies(name, counter):
    plan = check_plan_is_the_run(name, counter)
    if name == "additional-orders":
        assert plan.total > plan.simulations()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(STUDIES))
def test_plan_counts_every_study(name, counter):
    # the thesis's 18/8 segments: the counting does not depend on them, and they halve the
    # run time against the default 48/16 (the cheapest studies above run the default set)
    check_plan_is_the_run(name, counter, THESIS_SEGMENTS)
