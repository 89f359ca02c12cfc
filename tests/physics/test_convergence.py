"""Convergence in time step and segment count ([thesis] §6.2.2)."""

import pytest

from dampersim import OrderSum, default_parameters, simulate
from dampersim.parameters import with_updates
from dampersim.units import rpm_to_rad_s

P = default_parameters()
DT = P.solver.time_step


def _orders(system, rpm):
    # the dominant engine order of a four-cylinder engine ([thesis] §3.4)
    ex = OrderSum(speed=rpm_to_rad_s(rpm), mean_torque=200.0, orders=((2, 300.0, 0.0),))
    return simulate(system, ex, record_segments=False).order_amplitudes()[1]


@pytest.mark.slow
@pytest.mark.parametrize("rpm", [1500, 2500])
def test_halving_the_time_step(rpm):
    a = _orders(P, rpm)
    b = _orders(with_updates(P, {"solver.time_step": DT / 2}), rpm)
    # 1 %: the criterion, on the excited order (2nd) and the strongest
    # friction-generated harmonic (6th, several N m). Orders whose output is a few
    # hundredths of a N m are set by stick-slip details and are not a step-size measure.
    assert b[1] == pytest.approx(a[1], rel=0.01)
    if rpm == 1500:
        assert b[5] == pytest.approx(a[5], rel=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("rpm", [1500, 2500])
def test_default_segments_against_fine_discretisation(rpm):
    a = _orders(P, rpm)
    b = _orders(with_updates(P, {"solver.outer_segments": 32, "solver.inner_segments": 12}), rpm)
    # 2 %: the criterion ([thesis] §6.2.2 found 18/8 on the accuracy plateau)
    assert b[1] == pytest.approx(a[1], rel=0.02)
    assert b[5] == pytest.approx(a[5], rel=0.02)
