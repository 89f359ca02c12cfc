"""With the fast stand-in model patched in (fake_rig.fake_model), the next-test design's
candidate runs use the stand-in too: without it every fake diagnosis would make 75 real
simulations for its recommendations."""

import pytest

from dampersim.discrepancy import design, drive
from tests.discrepancy import fake_rig


@pytest.fixture(autouse=True)
def _design_follows_the_stand_in(monkeypatch):
    real = design.design_task

    def task(args):
        if getattr(drive.simulate_point, "fake", False):
            return fake_rig.fake_design_task(args)
        return real(args)

    monkeypatch.setattr(design, "design_task", task)
