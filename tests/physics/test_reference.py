"""The kernel's right-hand side equals the slow NumPy reference (tests/reference)."""

import numpy as np
import pytest

from dampersim import default_parameters
from dampersim.parameters import with_updates
from dampersim.solver.kernels import forces as kern
from dampersim.solver.layout import build_layout, initial_state
from dampersim.units import rpm_to_rad_s
from tests.reference.reference_model import accelerations

VARIANTS = {
    "default": {},
    "held motor, no hardstops": {"motor.mode": "held", "hardstops.enabled": False},
    "no friction": {"friction.enabled": False},
    "preload and clearance": {
        "outer.spring.arc": 1.86,  # longer than the 1.815 rad slot: preloaded
        "inner.nested.arc": 0.95,  # shorter than the 1.047 rad slot: clearance
        "friction.outer.preload": 12.0,
        "outer.secondary_stopper_half_width": 0.12,  # unequal stoppers
    },
    "other segment counts": {"solver.outer_segments": 7, "solver.inner_segments": 5, "friction.gamma5": 80.0},
    # effects of the discrepancy library
    "clutch slip": {"effects.clutch_slip.enabled": True, "effects.clutch_slip.capacity": 300.0},
    "clutch slip, held motor": {"effects.clutch_slip.enabled": True, "motor.mode": "held"},
    "output backlash": {"effects.output_backlash.enabled": True, "effects.output_backlash.free_play": 0.03},
    "inner short springs": {"effects.inner_short_springs.enabled": True, "effects.inner_short_springs.clearance": 0.02},
    # the second pair design with other counts, segments, unequal stoppers and the
    # radial transfer on both pairs
    "inner short springs, 3 of 5": {
        "effects.inner_short_springs.enabled": True, "effects.inner_short_springs.count": 3,
        "effects.inner_short_springs.clearance": 0.06, "effects.inner_short_springs.stiffness": 410.0,
        "effects.inner_short_springs.mass": 0.02, "effects.inner_short_springs.active_coils": 7.0,
        "solver.inner_segments": 5, "inner.secondary_stopper_half_width": 0.12,
        "effects.nested_radial_transfer.enabled": True, "friction.pair_inner.preload": 3.0,
    },
    "turbine drag": {"effects.turbine_drag.enabled": True, "effects.turbine_drag.coefficient": 5.0},
    "pendulum absorber": {"effects.pendulum_absorber.enabled": True, "effects.pendulum_absorber.order": 2.5},
    "nested radial transfer": {"effects.nested_radial_transfer.enabled": True},
    "spring preload": {"effects.spring_preload.enabled": True},
    "all effects": {f"effects.{e}.enabled": True for e in (
        "clutch_slip", "output_backlash", "inner_short_springs", "turbine_drag", "pendulum_absorber",
        "nested_radial_transfer", "spring_preload", "transducer_bandwidth")},
}


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_rhs_matches_reference_on_random_states(variant):
    system = with_updates(default_parameters(), VARIANTS[variant])
    omega0 = rpm_to_rad_s(1800)
    lay = build_layout(system, omega0)
    rng = np.random.default_rng(42)
    for trial in range(20):
        q, v = initial_state(lay)
        q = q + rng.normal(0.0, 0.02, q.size)
        # windups spread over, and beyond, both hardstop ranges of both sets
        q[1] = q[0] - rng.uniform(-0.3, 0.9)
        q[2] = q[1] - rng.uniform(-0.15, 0.3)
        v = rng.normal(0.0, 3.0, v.size)
        z = rng.normal(0.0, 0.05)
        tin = rng.uniform(-300.0, 600.0)
        _, acc, _ = kern.rhs(
            q, v, z, tin, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx, lay.contacts_f, lay.n_nodes
        )
        ref = accelerations(system, omega0, q, v, z, tin)
        scale = np.abs(ref) + 1e-12 * np.max(np.abs(ref))
        # 1e-9 relative: both evaluate the same equations in float64; only summation
        # order and tanh implementations differ (a few ulp)
        np.testing.assert_array_less(np.abs(acc - ref) / scale, 1e-9)
