"""Unit checks of the diagnosis's fitting helpers and the synth point selection."""

import numpy as np
import pytest

from dampersim.discrepancy.diagnose import PRIOR_LOG_SD, _effect_grid, _lstsq_bounded
from dampersim.discrepancy.selection import linear_screen_evidence
from dampersim.discrepancy.effects import NAMES, info, parameters_of
from dampersim.discrepancy.synth import synthesize
from dampersim.errors import InputError


@pytest.mark.parametrize("name", NAMES)
def test_effect_grid_stays_inside_the_accepted_range(name):
    # a grid value outside the bounds used to abort the whole diagnosis
    meta = next(p for p in parameters_of(name) if p["name"] == info(name).magnitude)
    grid = _effect_grid(name)
    assert np.all(np.diff(grid) > 0)
    if meta["min"] is not None:
        assert grid[0] >= meta["min"]
    if meta["max"] is not None:
        assert grid[-1] <= meta["max"]


def test_calibration_step_without_information_returns_to_the_prior():
    # no sensitivity at all: the regularised step takes the factors back to 0 exactly
    x0 = np.array([0.3, -0.2])
    dx = _lstsq_bounded(np.zeros((5, 2)), np.ones(5), x0)
    np.testing.assert_allclose(x0 + dx, 0.0, atol=1e-12)


def test_calibration_step_follows_strong_data():
    # one well-measured factor: 100 residuals of weight 1 each ask for +0.1; the prior
    # (spread PRIOR_LOG_SD) pulls by 1/(1 + 1/(100 sd^2)) only
    J = np.ones((100, 1))
    dx = _lstsq_bounded(J, 0.1 * np.ones(100), np.zeros(1))
    assert dx[0] == pytest.approx(0.1 / (1.0 + 1.0 / (100 * PRIOR_LOG_SD ** 2)), rel=1e-12)


def test_joint_screen_lets_an_effect_take_back_imitating_calibration():
    # linear model: the calibrated start x0 imitated part of an effect; the residual left
    # from there is what undoing x0 plus the effect at scale 2 explains (plus noise of 0.3).
    # The joint fit finds both (the prior acts on x0 + dx, which it can bring back to 0) and
    # its evidence is far above that of the calibration directions alone
    rng = np.random.default_rng(7)
    J = 3.0 * rng.normal(size=(40, 3))
    d = 3.0 * rng.normal(size=40)
    x0 = np.array([0.4, -0.1, 0.0])
    r = -J @ x0 + 2.0 * d + 0.3 * rng.normal(size=40)
    z, s, dx, cost = linear_screen_evidence(r, J, d, x0, PRIOR_LOG_SD)
    assert s == pytest.approx(2.0, abs=0.1)
    np.testing.assert_allclose(x0 + dx, 0.0, atol=0.05)
    z0, s0, _, cost0 = linear_screen_evidence(r, J, None, x0, PRIOR_LOG_SD)
    assert s0 == 0.0 and cost0 > 10 * cost and z > z0 + 50
    # an effect cannot act backwards: asked for a negative scale it is held at the minimum
    z_neg, s_neg, _, _ = linear_screen_evidence(-J @ x0 - 2.0 * d, J, d, x0, PRIOR_LOG_SD, min_scale=0.05)
    assert s_neg == 0.05


def test_synth_refuses_unknown_point_ids(tmp_path):
    with pytest.raises(InputError, match="map_9999_1"):
        synthesize(tmp_path / "c", points=["tc_1200", "map_9999_1"], record=0.5)


def test_uncalibrated_directions_move_only_what_the_calibration_cannot_follow():
    import math

    from dampersim.discrepancy.fitting import CALIBRATION, ESTIMATE_LOG_SD, UNCALIBRATED, uncalibrated_systems
    from dampersim.discrepancy.synth import ESTIMATED
    from dampersim.parameters import default_parameters
    from dampersim.parameters.io import flat_values

    # every estimated parameter is either calibrated or carried as an uncertainty direction
    covered = {n for names in CALIBRATION.values() for n in names} | {n for d in UNCALIBRATED.values() for n in d}
    assert set(ESTIMATED) <= covered
    base = default_parameters()
    flat = flat_values(base)
    moved = uncalibrated_systems(base)
    assert [name for name, _ in moved] == list(UNCALIBRATED)
    for name, (up, down) in moved:
        direction = UNCALIBRATED[name]
        step = ESTIMATE_LOG_SD / math.sqrt(len(direction))
        for s, sign in ((up, 1.0), (down, -1.0)):
            f = flat_values(s)
            changed = {n for n in flat if f[n] != flat[n]}
            assert changed == set(direction)
            for n, w in direction.items():  # rel 1e-12: exp then log of the same float, to rounding
                assert math.log(f[n] / flat[n]) == pytest.approx(sign * w * step, rel=1e-12)
            # a split keeps the group's log mean, the level a calibration factor scales
            group = [g for g in CALIBRATION.values() if set(direction) <= set(g)]
            if len(direction) > 1:
                assert group and sum(math.log(f[n] / flat[n]) for n in group[0]) == pytest.approx(0.0, abs=1e-12)


def test_uncalibrated_systems_moves_given_directions_by_a_given_uncertainty():
    # other directions (here a rig shaft and the motor's inertia) at another standard
    # uncertainty: each set differs from the base in its direction's parameters only, by
    # exactly +-log_sd (rel 1e-12: exp then log of the same float, to rounding)
    import math

    from dampersim.discrepancy.fitting import uncalibrated_systems
    from dampersim.parameters import default_parameters
    from dampersim.parameters.io import named_values

    base = default_parameters()
    flat = named_values(base)
    dirs = {"transducer": {"rig.elements.transducer.shaft_stiffness": 1.0},
            "motor": {"rig.elements.output_motor.inertia": 1.0}}
    moved = uncalibrated_systems(base, dirs, log_sd=0.1)
    assert [name for name, _ in moved] == ["transducer", "motor"]
    for name, pair in moved:
        (param,) = dirs[name]
        for s, sign in zip(pair, (1.0, -1.0)):
            f = named_values(s)
            assert {n for n in flat if f[n] != flat[n]} == {param}
            assert math.log(f[param] / flat[param]) == pytest.approx(sign * 0.1, rel=1e-12)
