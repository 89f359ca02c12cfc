"""The calibration's two derivative steps (fitting.CAL_DERIVATIVE_STEPS): when no step length
along the longer step's Gauss-Newton direction lowers the cost, the iteration retries with
the shorter step; each later iteration starts with the step that last moved the factors and
falls back on the other; the naming gets the longer step's sensitivities, taken again at the
calibrated factors only when the last iteration moved them with the shorter step alone, so
that no diagnosis takes more than two sets per iteration (costs.diagnosis_runs); the one
Gauss-Newton step after the uncertainties are measured again at the calibrated factors takes
no set of its own (stand-in model, no simulation)."""

import numpy as np
import pytest

from dampersim.discrepancy import drive, fitting
from tests.discrepancy import fake_rig as F
from tests.discrepancy.test_input_channel import _campaign

LONG, SHORT = fitting.CAL_DERIVATIVE_STEPS
N = len(fitting.CALIBRATION)


def _step_of(runs, x0):
    """LONG or SHORT if ``runs`` are x0 offset by it in each factor in turn, else None (to 1e-12:
    x0 + h - x0 rounds h)."""
    d = np.array(runs) - x0
    return next((h for h in (LONG, SHORT) if np.allclose(d, h * np.eye(N), rtol=0.0, atol=1e-12)), None)


def _diagnose(monkeypatch, uphill=(), iterations=3):
    """Diagnose the stand-in campaign, recording every factor vector the calibration runs and,
    per Gauss-Newton solve, (runs so far, the factors it starts from). The solves numbered in
    ``uphill`` (from 1) return their direction turned uphill, along which no step length
    lowers the cost."""
    from dampersim.discrepancy import diagnose as dg

    xs, solves = [], []
    real_cs, real_solve = dg.calibrated_system, dg._lstsq_bounded

    def spy_cs(system, x):
        xs.append(np.array(x, dtype=float))
        return real_cs(system, x)

    def spy_solve(J, r, x0):
        solves.append((len(xs), np.array(x0, dtype=float)))
        dx = real_solve(J, r, x0)
        return -dx if len(solves) in uphill else dx

    monkeypatch.setattr(dg, "calibrated_system", spy_cs)
    monkeypatch.setattr(dg, "_lstsq_bounded", spy_solve)
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    d = dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False,
                    calibration_iterations=iterations)
    # the derivative step of each solve: the N runs just before it
    steps = [_step_of(xs[k - N:k], x0) for k, x0 in solves]
    if iterations:
        # the last solve is diagnose's step 2b: one Gauss-Newton step under the uncertainties
        # measured again at the calibrated factors, from the sensitivities the naming gets (no
        # derivative runs of its own), starting where the calibration ended
        assert steps[-1] is None and len(solves) >= 2, steps
        assert solves[-1][0] > solves[-2][0]
        solves, steps = solves[:-1], steps[:-1]
    return d, xs, solves, steps


def test_a_failed_long_step_retries_short_and_later_iterations_keep_it(monkeypatch):
    d, xs, solves, steps = _diagnose(monkeypatch, uphill={1})
    assert d.verdict != "insufficient_data"
    # iteration 1: the long step, its direction fails, the retry with the short one moves the
    # factors; iterations 2 and 3 start (and here end) with the short step
    assert steps == [LONG, SHORT, SHORT, SHORT]
    np.testing.assert_array_equal(solves[1][1], solves[0][1])  # the retry starts where the first solve did
    # after the last solve's trials: the long step's sensitivities at the factors the last
    # accepted trial reached (the calibrated ones), for the naming
    start = solves[-1][0]
    trials = []
    for i in range(start, len(xs) - N + 1):
        found = [t for t in trials if _step_of(xs[i:i + N], t) == LONG]
        if found:
            break
        trials.append(xs[i])
    assert found, "the long step's sensitivities were not taken again after the short ones"
    assert not np.array_equal(found[0], solves[-1][1])  # at the moved factors, not where the last solve began
    assert len(steps) + 1 <= 2 * 3  # with it, still the sets costs.diagnosis_runs counts


def test_when_the_short_step_fails_later_the_long_one_is_its_fallback(monkeypatch):
    _d, _xs, solves, steps = _diagnose(monkeypatch, uphill={1, 3})
    # iteration 1: long fails, short moves; iteration 2: short fails, long moves (the same
    # factors for both solves of an iteration); iteration 3 starts with the long step again
    assert steps == [LONG, SHORT, SHORT, LONG, LONG]
    np.testing.assert_array_equal(solves[3][1], solves[2][1])


def _retaken(xs, solves) -> bool:
    """Whether the long step's sensitivities were taken after the last solve, around any factor
    vector run after it."""
    start = solves[-1][0]
    return any(_step_of(xs[i:i + N], xs[j]) == LONG for i in range(start, len(xs) - N + 1) for j in range(start, i))


@pytest.mark.parametrize("uphill,iterations,expect", [
    ({1, 3, 4}, 3, [LONG, SHORT, SHORT, LONG]),  # iteration 2: both fail, the calibration stops
    ({1}, 1, [LONG, SHORT]),  # one iteration that took both sets
    ({1, 3, 5}, 3, [LONG, SHORT, SHORT, LONG, LONG, SHORT]),  # the last iteration took both sets
])
def test_the_long_sensitivities_are_not_taken_again_when_the_last_iteration_took_them(monkeypatch, uphill,
                                                                                       iterations, expect):
    _d, xs, solves, steps = _diagnose(monkeypatch, uphill=uphill, iterations=iterations)
    assert steps == expect
    assert not _retaken(xs, solves)
    assert len(steps) <= 2 * iterations  # the sets costs.diagnosis_runs counts


def test_without_a_retry_the_long_step_is_used_throughout(monkeypatch):
    d, xs, solves, steps = _diagnose(monkeypatch)
    assert steps and set(steps) == {LONG}
    # no second taking of the sensitivities: the naming gets the last iteration's
    assert not _retaken(xs, solves)


def test_without_iterations_the_naming_gets_sensitivities_at_the_estimate(monkeypatch):
    """calibration_iterations=0 skips the scan and Gauss-Newton; the naming must still get the
    longer step's sensitivities, taken at the estimate (once), not the zeros of a set never run."""
    from dampersim.discrepancy import naming

    seen = {}
    real_init = naming.Namer.__init__

    def spy_init(self, runner, lik, train, points, jac, *args, **kwargs):
        seen["jac"] = np.array(jac)
        real_init(self, runner, lik, train, points, jac, *args, **kwargs)

    monkeypatch.setattr(naming.Namer, "__init__", spy_init)
    d, xs, solves, steps = _diagnose(monkeypatch, iterations=0)
    assert not solves  # no Gauss-Newton step
    assert d.verdict != "insufficient_data"
    taken = [k for k in range(N, len(xs) + 1) if _step_of(xs[k - N:k], np.zeros(N)) == LONG]
    assert len(taken) == 1  # one set of sensitivities, at the estimate
    # the stand-in's orders follow the outer stiffness and the secondary inertia (fake_rig): their columns move
    moving = np.abs(seen["jac"]).max(axis=0) > 0
    assert seen["jac"].shape[1] == N and moving.sum() == 2, moving
