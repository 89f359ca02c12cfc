"""One point of the accuracy grid (docs/model.md §12, bench/accuracy_grid.py) as a test:
at the default time step every output order carrying at least 2 % of the largest agrees
with a 1e-6 s run of the same model within 1 %.

The point, 2500 rpm with 100 +- 300 N m (the fluctuation swings the windup through the
negative knee), is one the previous default step of 1/60 000 s failed with the thesis's
18/8 segments (its 6th order 3 % off) and whose reference has a single steady state (a 100x tighter friction
tolerance moves it by 0.01 %), so a difference here is truncation error, not scatter.
"""

import warnings

import numpy as np
import pytest

import dampersim as ds
from dampersim.errors import AccuracyWarning
from dampersim.parameters import at_thesis_segments, with_updates
from dampersim.units import rpm_to_rad_s

POINT = ds.OrderSum(speed=rpm_to_rad_s(2500), mean_torque=100.0, orders=((2, 300.0, 0.0),))
ORDERS = tuple(range(1, 9))


def outputs(system):
    return np.asarray(ds.simulate(system, POINT, record_segments=False).order_amplitudes(orders=ORDERS)[1])


@pytest.fixture(scope="module")
def reference():
    return outputs(with_updates(ds.default_parameters(), {"solver.time_step": 1e-6}))


def test_default_step_meets_the_grid_criterion(reference):
    judged = reference >= 0.02 * reference.max()
    assert judged.sum() >= 2  # the 2nd and the generated 6th order at least
    err = outputs(ds.default_parameters())[judged] / reference[judged] - 1.0
    # 1 %: the accuracy criterion of issue 14 for an order without spread (this point's
    # repeatability over runs 1e-9 apart is below 0.01 %)
    assert np.max(np.abs(err)) < 0.01, dict(zip(np.array(ORDERS)[judged], np.round(100 * err, 3)))


def test_previous_default_step_fails_it():
    # the criterion has teeth here: with the thesis's 18/8 segments, on which the step was
    # chosen, the 6th order misses it at 1/60 000 s (3 %) and meets it at the default step.
    # With the default 48/16 segments both steps meet it at this point (docs/model.md §12)
    thesis = at_thesis_segments()
    ref = outputs(with_updates(thesis, {"solver.time_step": 1e-6}))
    assert abs(outputs(thesis)[5] / ref[5] - 1.0) < 0.01
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # a step above the tested default
        coarse = outputs(with_updates(thesis, {"solver.time_step": 1.0 / 60000.0}))
    assert abs(coarse[5] / ref[5] - 1.0) > 0.01
