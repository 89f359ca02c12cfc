"""The magnitude grid of an effect's fit continued beyond its ends (fitting.grid_bracket): a fit
whose best grid value is the grid's floor or top can leave it, inside the parameter's accepted
range, in the runs the cost model counts. Objectives here are functions of the magnitude, and
the fit on the toy of tests/discrepancy/test_refit.py stands in for the simulations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampersim import costs
from dampersim.discrepancy import drive, naming
from dampersim.discrepancy.effects import NAMES, info, parameters_of
from dampersim.discrepancy.fitting import GRID_EXTENSION, _effect_grid, grid_bracket
from dampersim.discrepancy.likelihood import Likelihood

from tests.discrepancy.test_refit import NAME, POINTS, _toy
from tests.discrepancy.toy_namer import BASE, patch_runs


def _counted(fun):
    """(objective, list of the magnitudes it was asked for)."""
    asked = []

    def objective(m):
        asked.append(m)
        return fun(m)
    return objective, asked


def _bowl(centre):
    return lambda m: (math.log(m) - math.log(centre)) ** 2


def _ratio(name):
    grid = _effect_grid(name)
    return grid[1] / grid[0]


@pytest.mark.parametrize("name", NAMES)
def test_an_inner_minimum_is_bracketed_by_its_neighbours_without_continuation(name):
    grid = _effect_grid(name)
    objective, asked = _counted(_bowl(grid[2] * 1.1))
    lo, hi = grid_bracket(name, objective)
    assert (lo, hi) == pytest.approx((math.log(grid[1]), math.log(grid[3])), abs=1e-12)
    assert len(asked) == len(grid)


def test_a_minimum_below_the_floor_is_reached_by_continuing_the_grid():
    # the preload's floor is 8 N / 1.8 = 4.44 N; a truth of 2 N lies 1.4 grid ratios below it
    grid = _effect_grid("spring_preload")
    objective, asked = _counted(_bowl(2.0))
    lo, hi = grid_bracket("spring_preload", objective)
    assert lo < math.log(2.0) < hi
    assert hi - lo == pytest.approx(2 * math.log(_ratio("spring_preload")), abs=1e-9)  # two grid steps, as inside
    assert len(asked) == len(grid) + 2  # 2.50 N is lower than 4.44 N, 1.40 N not lower than 2.50 N: it stops
    assert min(asked) < grid[0]


def test_a_minimum_above_the_top_is_reached_and_the_continuation_stops_at_its_count():
    # a drag coefficient 100 times the typical one: the continuation ends after GRID_EXTENSION values
    grid = _effect_grid("turbine_drag")
    objective, asked = _counted(_bowl(300.0))
    lo, hi = grid_bracket("turbine_drag", objective)
    assert len(asked) == len(grid) + GRID_EXTENSION
    assert hi == pytest.approx(math.log(grid[-1] * _ratio("turbine_drag") ** GRID_EXTENSION), abs=1e-9)
    assert lo == pytest.approx(math.log(grid[-1] * _ratio("turbine_drag") ** (GRID_EXTENSION - 1)), abs=1e-9)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("side", [-1, 1])
def test_the_continuation_stays_inside_the_accepted_range(name, side):
    # an objective that falls without end toward one side: every value asked for is one the
    # parameter set accepts, and the count is at most the grid plus its continuation
    meta = next(p for p in parameters_of(name) if p["name"] == info(name).magnitude)
    objective, asked = _counted(lambda m: side * -math.log(m))
    lo, hi = grid_bracket(name, objective)
    assert len(asked) <= len(_effect_grid(name)) + GRID_EXTENSION
    assert len(set(asked)) == len(asked)  # no magnitude is run twice
    assert min(asked) > 0 and (meta["min"] is None or min(asked) >= meta["min"])
    assert meta["max"] is None or max(asked) <= meta["max"]
    assert lo < hi


def test_a_flat_objective_keeps_the_value_tried_first():
    # equal objectives: one value beyond the floor is tried, is not lower, and the continuation
    # stops; the best stays the floor tried first (as Namer.fit takes the first of equal costs)
    grid = _effect_grid("spring_preload")
    objective, asked = _counted(lambda m: 1.0)
    lo, hi = grid_bracket("spring_preload", objective)
    assert len(asked) == len(grid) + 1
    assert lo < math.log(grid[0]) < hi


def test_a_positive_lower_bound_ends_the_continuation_at_the_grids_floor(monkeypatch):
    # a cut-off accepted from 100 Hz only: the grid's floor is the bound (kept just above it, as the
    # set accepts it), nothing is tried below or at it again, and the bracket stays ordered
    from dampersim.discrepancy import effects

    real = effects.parameters_of

    def bounded(name):
        return [dict(p, min=100.0) if name == "transducer_bandwidth" and p["name"] == "cutoff" else p
                for p in real(name)]

    monkeypatch.setattr(effects, "parameters_of", bounded)
    objective, asked = _counted(lambda m: math.log(m))  # falls toward the bound
    lo, hi = grid_bracket("transducer_bandwidth", objective)
    assert min(asked) == pytest.approx(100.0, rel=1e-3) and min(asked) > 100.0
    assert len(asked) == len(set(asked)) == 5
    assert lo == pytest.approx(math.log(min(asked))) and lo < hi


def test_a_grid_whose_runs_all_failed_is_not_continued():
    objective, asked = _counted(lambda m: math.inf)
    grid_bracket("spring_preload", objective)
    assert len(asked) == len(_effect_grid("spring_preload"))


@pytest.fixture()
def namer(monkeypatch):
    calls = []
    patch_runs(monkeypatch, _toy, lambda runner, s: False, calls)
    zeros = np.zeros(6)
    jac = np.zeros((2 * len(POINTS) * len(drive.ORDERS), 6))
    starts = {"calibrated": (BASE, zeros, None), "estimated": (BASE, zeros, None)}
    out = naming.Namer(None, None, list(range(len(POINTS))), POINTS, jac, starts, {NAME: {}})
    out.calls = calls
    return out


def _measure(namer, inertia):
    meas = _toy(naming.with_effect(BASE, NAME, {"inertia": inertia}))
    namer.lik = Likelihood(meas, np.full(meas.shape, 0.05), [100.0] * len(POINTS), drive.ORDERS)


@pytest.mark.parametrize("inertia", [0.0002, 0.00015])
def test_a_fit_below_the_grids_floor_reaches_the_truth_in_the_counted_runs(namer, inertia):
    # the absorber's grid starts at 0.0005 / 1.8 = 0.00028 kg m^2; before the continuation the fit
    # stopped there, 0.33 and 0.62 in log magnitude from these truths. On noise-free toy data the
    # magnitude prior (sd 1 around 0.001) moves the fit by about 4e-5 in log and the fit ends
    # about 2e-4 from the truth; 0.02 leaves room for the bounded search's tolerance (0.01 in log)
    _measure(namer, inertia)
    fit = namer.fit(NAME, "calibrated")
    assert abs(math.log(fit["m"] / inertia)) < 0.02
    # the counted runs less two: with a zero Jacobian the re-calibrated, the start's and the
    # estimated factors are all zero here, so one verification run stands for three
    assert len(namer.calls) <= (costs.DIAGNOSIS_FIT_RUNS - 2) * len(POINTS)
