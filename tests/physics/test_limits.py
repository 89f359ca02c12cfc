"""Hardstops, coil stacking and the knee: nothing passes a limit, nothing blows up."""

import numpy as np
import pytest

from dampersim import OrderSum, default_parameters, simulate
from dampersim.excitation import TorqueRamp
from dampersim.parameters import with_updates
from dampersim.solver.layout import F_BLOCK
from dampersim.units import rpm_to_rad_s

P = default_parameters()
TOL = np.radians(0.1)  # the limit: 0.1 deg beyond a hardstop


def test_positive_hardstops_hold_under_heavy_load():
    res = simulate(P, OrderSum(speed=rpm_to_rad_s(1500), mean_torque=550.0, orders=((2, 300.0, 0.0),)))
    assert res.hardstop_outer.max() > 100.0  # the outer stop carries load
    assert res.windup_outer.max() < P.outer.hardstop_positive + TOL
    assert res.windup_inner.max() < P.inner.hardstop_positive + TOL


def test_negative_hardstops_hold_on_a_negative_ramp():
    system = with_updates(P, {"solver.output_sample_rate": 2000})
    ex = TorqueRamp(speed=rpm_to_rad_s(1000), points=(0.0, -400.0, 0.0), rate=400.0, hold=0.3, lead=0.1)
    res = simulate(system, ex, record_segments=False)
    assert res.hardstop_outer.min() < -50.0 and res.hardstop_inner.min() < -10.0
    assert res.windup_outer.min() > P.outer.hardstop_negative - TOL
    assert res.windup_inner.min() > P.inner.hardstop_negative - TOL
    # contact releases: back at zero torque no stop is touched
    assert res.hardstop_outer[-1] == 0.0 and res.hardstop_inner[-1] == 0.0


def test_coil_stacking_without_hardstops_keeps_block_length():
    system = with_updates(P, {"hardstops.enabled": False})
    # 0.8 s: the mean and amplitude ramps (0.3 s each), then ten cycles of the 2nd order
    # (50 Hz) at full amplitude; the natural 2.6 s takes four times as long and gave the same
    # smallest segment (0.99925 of its block arc)
    res = simulate(system, OrderSum(speed=rpm_to_rad_s(1500), mean_torque=450.0, orders=((2, 150.0, 0.0),)),
                   duration=0.8)
    assert res.energy["stacking"][-1] > 0  # the outer springs did go coil-bound
    for k, sp in enumerate(res.springs):
        seg = np.diff(res.spring_nodes(sp.name), axis=1)
        block = res.spring_rows[k, F_BLOCK]
        # 0.2 % of a segment's block arc (~1e-4 rad): the contact sweeps stop at 1e-6
        # relative, but a fully coil-bound chain needs more sweeps than the cap allows
        assert seg.min() > block * (1 - 2e-3), sp.name
    losses = res.energy["friction"][-1] + res.energy["damping"][-1] + res.energy["stacking"][-1]
    assert abs(res.energy_residual()[-1]) < 0.01 * losses


@pytest.mark.parametrize("offset", [0.0, 5.0])
def test_mean_torque_at_the_knee_with_ripple_is_stable(offset):
    knee = P.outer.count * P.outer.spring.stiffness * P.outer.hardstop_positive
    res = simulate(P, OrderSum(speed=rpm_to_rad_s(1500), mean_torque=knee + offset, orders=((2, 15.0, 0.0),)))
    w = res.window()
    assert np.all(np.isfinite(res.output_torque))
    assert res.windup_outer.max() < P.outer.hardstop_positive + TOL
    # the mean torque reaches the output, less the rig's viscous losses (~1 %)
    assert res.output_torque[w].mean() == pytest.approx(knee + offset, rel=0.03)
    assert res.output_torque[w].std() < 20.0


def test_knee_crossing_point_has_no_subharmonics():
    # 350 +- 300 N m at 2000 rpm drives the outer set into its stop every cycle. A
    # bouncing contact (restitution ~0.6) once made this point period-doubled, with
    # odd-order output near 6 N m from a 2nd-order-only input; the near-inelastic
    # contact (like the thesis's inertia merge) keeps the response at the input's
    # period. 1 % of the 2nd order: odd orders are rounding-level (< 0.01 N m) when periodic.
    res = simulate(P, OrderSum(speed=rpm_to_rad_s(2000), mean_torque=350.0, orders=((2, 300.0, 0.0),)),
                   record_segments=False)
    _, a = res.order_amplitudes()
    assert res.hardstop_outer.max() > 100.0  # the stop is hit
    assert max(a[0], a[2], a[4], a[6]) < 0.01 * a[1]

