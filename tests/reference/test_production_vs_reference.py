"""The production integrator against an independent stiff integration of the reference
equations over a short window (issue 14, item 4; the order analysis over a full window at
three points is ``bench/bench_reference.py``).

The production step (implicit linearised friction, implicit hardstop contact, speed
extrapolation) runs to a steady snapshot at 1.5 s; from that state the compiled reference
(:mod:`tests.reference.compiled_reference`) is integrated by scipy's BDF at rtol 1e-8 over
0.1 s and both trajectories are compared sample by sample (10 kHz).

Point: 1500 rpm, 450 +- 250 N m (2nd order): the outer set sits on its hardstop for the
whole window and the spring masses stick and slide (bench: 45 % of contact-samples
stuck). There the two integrations agree and the trajectory is not chaotic: two
reference runs from snapshots 1e-9 apart differ by 2e-7 of the output torque's
peak-to-peak. (Below the knee, at 1500 rpm / 200 N m, the stick-slip pattern is chaotic
and only the order statistics of the bench compare; at 2500 rpm / 200 +- 300 N m the
production output torque is 1.2 % of its peak-to-peak off the reference within 0.1 s,
a step-size finding for the accuracy grid of the issue, not a test here.)
"""

from __future__ import annotations

import numpy as np
import pytest

from dampersim import OrderSum, default_parameters
from dampersim.parameters import with_updates
from dampersim.solver.layout import build_layout, initial_state
from dampersim.units import rpm_to_rad_s
from tests.reference.compiled_reference import build
from tests.reference.reference_model import accelerations
from tests.reference.windows import production, reference

P = default_parameters()
EX = OrderSum(speed=rpm_to_rad_s(1500), mean_torque=450.0, orders=((2, 250.0, 0.0),))


@pytest.mark.parametrize("updates", [{}, {"motor.mode": "held"}, {"friction.outer.preload": 12.0}])
def test_compiled_reference_equals_numpy_reference(updates):
    system = with_updates(P, updates)
    R = build(system, EX.speed, EX)
    lay = build_layout(system, EX.speed)
    n = R.ndof
    rng = np.random.default_rng(7)
    for _ in range(20):
        q, v = initial_state(lay)
        q = q + rng.normal(0.0, 0.02, n)
        q[1] = q[0] - rng.uniform(-0.3, 0.9)  # windups over and beyond both hardstop ranges
        q[2] = q[1] - rng.uniform(-0.15, 0.3)
        v = rng.normal(0.0, 3.0, n)
        z = rng.normal(0.0, 0.05)
        t = rng.uniform(1.0, 2.0)
        d = R.rhs(t, np.concatenate([q, v, [z]]))
        ref = accelerations(system, EX.speed, q, v, z, R.input_torque(t))
        scale = np.abs(ref) + 1e-12 * np.max(np.abs(ref))
        # 1e-9 relative: the same equations in float64, summation order aside
        np.testing.assert_array_less(np.abs(d[n:2 * n] - ref) / scale, 1e-9)
        np.testing.assert_array_equal(d[:n], v)
        assert d[2 * n] == -v[n - 1]


def test_production_follows_reference_on_the_hardstop():
    snap, pw = production(P, EX, 1.5, 0.1, max(1, round(1e-4 / P.solver.time_step)))  # 10 kHz records
    # the reference has no coil stacking: the production run must have none either
    assert pw.stacking == 0.0
    rw = reference(P, EX, snap, pw.t, method="BDF")
    # output torque: an order amplitude of the Hann-windowed record changes by at most
    # 2 max|difference|, so 0.2 % of the peak-to-peak (0.4 % of the fluctuation's half
    # peak-to-peak, 27 N m) keeps every order within 0.8 % of that half peak-to-peak,
    # the dominant 2nd order (21.5 N m) within 1 %, the criterion. Measured
    # 0.038 % at the default step; the same check at 2500 rpm / 200 +- 300 N m gives
    # 1.8 % and fails: its stick-slip pattern diverges from any start (docs/model.md §14).
    tout = np.ptp(rw.output_torque)
    assert np.max(np.abs(pw.output_torque - rw.output_torque)) < 0.002 * tout
    # inner windup (springs working, 0.015 rad peak-to-peak): the same 0.2 % for the
    # same reason (measured 0.0026 %)
    assert np.max(np.abs(pw.windup_inner - rw.windup_inner)) < 0.002 * np.ptp(rw.windup_inner)
    # outer windup, on its stop for the whole window: the penetration beyond the stop
    # (~7.6e-5 rad, the contact torque over its 2e6 N m/rad stiffness) within 1 %
    # (measured 0.2 %)
    pen = rw.windup_outer - P.outer.hardstop_positive
    assert np.min(pen) > 0.0
    assert np.max(np.abs(pw.windup_outer - rw.windup_outer)) < 0.01 * np.mean(pen)
