"""Energy balance: external work = change of stored energy + dissipation."""

import numpy as np
import pytest

from dampersim import OrderSum, default_parameters, simulate
from dampersim.parameters import with_updates
from dampersim.units import rpm_to_rad_s


@pytest.mark.parametrize(
    "name, updates, mean, orders",
    [
        ("default point", {}, 200.0, ((2, 300.0, 0.0), (4, 100.0, 0.0))),
        # friction as the only loss: no viscous rig damping, held output motor
        (
            "friction only",
            {
                **{f"rig.elements.{e}.inertia_damping": 0.0 for e in
                   ("gearbox", "flange_group_1", "transducer", "flange_group_2", "roba_coupling", "output_motor")},
                **{f"rig.elements.{e}.shaft_damping": 0.0 for e in
                   ("gearbox", "flange_group_1", "transducer", "flange_group_2", "roba_coupling", "output_motor")},
                "hardstops.damping": 0.0,
                "motor.mode": "held",
            },
            150.0,
            ((2, 300.0, 0.0), (1, 40.0, 0.3)),
        ),
        ("on the hardstops", {}, 450.0, ((2, 250.0, 0.0),)),
        # mean torque at the outer knee: the hardstop closes and opens every cycle
        ("across the knee", {}, 320.0, ((2, 300.0, 0.0),)),
    ],
)
def test_energy_balance(name, updates, mean, orders):
    system = with_updates(default_parameters(), updates)
    res = simulate(system, OrderSum(speed=rpm_to_rad_s(1500), mean_torque=mean, orders=orders), record_segments=False)
    e = res.energy
    losses = e["friction"][-1] + e["damping"][-1] + e["stacking"][-1]
    assert losses > 0
    assert e["friction"][-1] >= 0 and e["damping"][-1] >= 0
    # 1 % of the dissipation a friction or contact error would corrupt (friction plus the
    # hardstop contacts), not of all losses: the rig's viscous losses (thousands of J)
    # would hide an error as large as the whole friction dissipation (25-300 J here)
    guarded = e["friction"][-1] + e["hardstop"][-1]
    assert 0.0 <= e["hardstop"][-1] <= e["damping"][-1]
    assert abs(res.energy_residual()[-1]) < 0.01 * guarded
    assert np.max(np.abs(res.energy_residual())) < 0.01 * guarded
