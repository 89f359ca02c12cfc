"""A run that blows up stops at once with the time and a hint; no garbage is returned."""

import pytest

from dampersim import OrderSum, SimulationDiverged, default_parameters, simulate
from dampersim.parameters import with_updates
from dampersim.solver.linear import check_time_step


def test_runaway_stops_with_time_and_hint():
    # a torque no damper survives: the bodies run away within milliseconds
    ex = OrderSum(speed=150.0, mean_torque=5.0e8, orders=(), mean_ramp=0.0)
    with pytest.raises(SimulationDiverged) as e:
        simulate(default_parameters(), ex, duration=1.0)
    assert 0.0 <= e.value.time < 0.1
    assert "smaller time step" in str(e.value) and "solver.time_step" in str(e.value)


def test_nan_input_is_rejected_before_running():
    with pytest.raises(ValueError):
        OrderSum(speed=150.0, mean_torque=float("nan"))


def test_unstable_step_is_refused_by_the_solver_check():
    from dampersim.errors import ParameterError

    with pytest.raises(ParameterError) as e:
        check_time_step(with_updates(default_parameters(), {"solver.time_step": 2e-4}))
    assert "stability bound" in str(e.value)


def test_simulate_refuses_an_unstable_step_before_running():
    from dampersim.errors import ParameterError

    unstable = with_updates(default_parameters(), {"solver.time_step": 2e-4})
    with pytest.raises(ParameterError) as e:
        simulate(unstable, OrderSum(speed=150.0, mean_torque=100.0), duration=0.01)
    assert "stability bound" in str(e.value)
