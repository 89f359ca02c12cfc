"""The kernel counter of the studies' plan check (see test_studies.py)."""

from __future__ import annotations

import pytest

import dampersim.simulation.damper as damper


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
    """Counts every kernel call of the test, on a fresh, empty cache."""
    c = KernelCounter(damper.run_damper)
    monkeypatch.setattr(damper, "run_damper", c)
    return c
