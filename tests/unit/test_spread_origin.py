"""Where a repeatability spread comes from (issue 14, item 2): the K runs again at half the
time step label each order's spread physical (it does not shrink with the step) or
numerical; the rule on synthetic amplitudes, the half-step runs, the command line
(``simulate --repeatability K --spread-check``) and the Explorer state and cost."""

import json

import numpy as np
import pytest

import dampersim
from dampersim.analysis import repeatability as R
from dampersim.cli import main
from dampersim.errors import InputError
from dampersim.excitation import OrderSum
from dampersim.parameters import with_updates
from dampersim.units import rpm_to_rad_s

# A frictionless linear point (no friction, no hardstops), 1.5 s: about 0.05 s a run.
LINEAR = ["simulate", "--speed", "1500", "--torque", "200", "--orders", "2:300", "--no-friction", "--no-hardstops",
          "--duration", "1.5", "--json"]


def _runs(centre, spread_pct, k=4):
    """K synthetic amplitudes [N m] around ``centre`` spanning ``spread_pct`` of it."""
    return centre * (1.0 + 0.01 * spread_pct * (np.linspace(0.0, 1.0, k) - 0.5))


def _labels(dt_cols, half_cols):
    a = R.spread_pct(np.column_stack(dt_cols))
    b = R.spread_pct(np.column_stack(half_cols))
    return a, b, R.spread_origin(a, b)


# ------------------------------------------------------------------------ the rule
def test_labelling_rule_on_synthetic_amplitudes():
    floor = R.SPREAD_FLOOR_PCT
    dt = [_runs(10.0, 0.2), _runs(1.0, 5.0), _runs(1.0, 5.0), _runs(0.001, 50.0), _runs(1.0, 1e-7),
          _runs(1.0, 0.5 * floor), _runs(1.0, 4.0)]
    half = [_runs(10.0, 0.3), _runs(1.0, 1.0), _runs(1.0, 2.6), _runs(1.0, 50.0) * 0.001, _runs(1.0, 1e-7),
            _runs(1.0, 2 * floor), _runs(1.0, 0.5 * floor)]
    a, b, origin = _labels(dt, half)
    # the synthetic spreads come out as built (a straight span of K values: max - min over the median)
    assert a[0] == pytest.approx(0.2) and b[1] == pytest.approx(1.0)
    assert origin[0] == R.PHYSICAL  # grows with the finer step: it does not shrink
    assert origin[1] == R.NUMERICAL  # 5 % -> 1 %: it shrinks with the step
    assert origin[2] == R.PHYSICAL  # 5 % -> 2.6 %: above half, not shrinking (the exact half: below)
    assert origin[3] is None and a[3] is None  # 0.001 N m: below 0.1 % of the largest order (10 N m)
    assert origin[4] is None  # a linear order's 1e-7 %: below the floor at both steps, nothing to label
    assert origin[5] == R.NUMERICAL  # above the floor at the finer step only: it depends on the step
    assert origin[6] == R.NUMERICAL  # 4 % -> below the floor: gone at the finer step


def test_rule_boundaries_and_refusals():
    floor = R.SPREAD_FLOOR_PCT
    assert R.spread_origin([2.0], [1.0]) == (R.PHYSICAL,)  # exactly half: not shrinking
    assert R.spread_origin([2.0], [np.nextafter(1.0, 0.0)]) == (R.NUMERICAL,)
    assert R.spread_origin([floor], [floor]) == (R.PHYSICAL,)  # at the floor counts as above it
    assert R.spread_origin([None, 3.0], [3.0, None]) == (None, None)
    with pytest.raises(InputError, match="same orders"):
        R.spread_origin([1.0, 2.0], [1.0])


def test_spread_check_runs_the_same_inputs_at_half_the_step():
    system = with_updates(dampersim.default_parameters(), {"friction.enabled": False, "hardstops.enabled": False})
    ex = OrderSum(speed=rpm_to_rad_s(1500.0), mean_torque=200.0, orders=((2.0, 300.0, 0.0),))
    seen = []

    def spy(system, ex, **kw):
        seen.append((system.solver.time_step, ex.orders[0][1]))
        return dampersim.simulate(system, ex, **kw)

    rep = R.repeatability(system, ex, 3, orders=(2.0, 3.0), duration=1.2, simulate_fn=spy)
    check = R.spread_check(system, ex, rep, duration=1.2, simulate_fn=spy)
    dt = system.solver.time_step
    assert seen[:3] == [(dt, 300.0), (dt, 300.0 * (1 + 1e-9)), (dt, 300.0 * (1 + 2e-9))]
    assert seen[3:] == [(dt / 2, 300.0), (dt / 2, 300.0 * (1 + 1e-9)), (dt / 2, 300.0 * (1 + 2e-9))]
    assert check.time_step == dt / 2 and check.output_nm.shape == (3, 2)
    # a linear damper spreads by the input's 2e-9 at any step (2e-7 %, 5 % for the FFT's
    # rounding as in test_repeatability): far below the floor, so no label
    assert check.spread_pct[0] == pytest.approx(2e-7, rel=0.05) and check.origin == (None, None)


def test_cost_counts_k_runs_and_k_runs_at_half_the_step():
    system = dampersim.default_parameters()
    one = R.costs.point_cost(system, 1.5, record_segments=False)
    plain = R.repeatability_cost(system, 1.5, 4)
    checked = R.repeatability_cost(system, 1.5, 4, spread=True)
    assert plain.work == pytest.approx(4 * one.work)
    # half the step: twice the steps per run (1e-9 for rounding the step count)
    assert checked.work == pytest.approx(4 * one.work + 4 * 2 * one.work, rel=1e-9)
    assert checked.bytes > plain.bytes / 2 and "half the step" in checked.what
    with pytest.raises(InputError, match="2 to 32"):
        R.repeatability_cost(system, 1.5, 33)


# ------------------------------------------------------------------------ command line
def test_cli_spread_origin_only_with_the_flag_and_aligned_with_orders(capsys, monkeypatch):
    import dampersim.simulation.damper as damper

    steps = []
    real = damper.run_damper

    def spy(lay, torque, *a, **k):
        steps.append(len(torque))
        return real(lay, torque, *a, **k)

    monkeypatch.setattr(damper, "run_damper", spy)
    assert main([*LINEAR, "--repeatability", "3"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert "spread_origin" not in plain and len(steps) == 3
    steps.clear()
    assert main([*LINEAR, "--repeatability", "3", "--spread-check"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert set(rep) == set(plain) | {"spread_origin"}
    assert rep["repeatability_pct"] == plain["repeatability_pct"] and rep["output_amplitude_nm"] == plain["output_amplitude_nm"]
    assert len(rep["spread_origin"]) == len(rep["orders"])
    assert all(o in (None, "physical", "numerical") for o in rep["spread_origin"])
    assert all(o is None for o, s in zip(rep["spread_origin"], rep["repeatability_pct"]) if s is None)
    # three runs at the step, three more of twice the steps (half the step)
    assert len(steps) == 6 and all(abs(h - 2 * steps[0]) <= 1 for h in steps[3:]) and steps[:3] == [steps[0]] * 3


def test_cli_text_shows_both_spreads_and_the_label(capsys):
    assert main([*LINEAR[:-1], "--repeatability", "2", "--spread-check"]) == 0
    text = capsys.readouterr().out
    assert "at dt/2 [%]" in text and "origin" in text and "half the step" in text


def test_cli_refuses_the_check_without_repeatability_before_simulating(capsys, monkeypatch):
    import dampersim.simulation.damper as damper

    monkeypatch.setattr(damper, "run_damper", lambda *a, **k: pytest.fail("simulated before checking the flags"))
    assert main([*LINEAR, "--spread-check"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--spread-check needs --repeatability K" in err


# ------------------------------------------------------------------------ Explorer state
def test_explorer_state_spread_check_needs_repeat_and_counts_in_the_cost():
    from dampersim.views.state import parse_query, state_cost, to_query

    state, notices = parse_query("explorer", {"repeat": "4", "spread_check": "true"})
    assert notices == [] and state["spread_check"] is True and "spread_check=true" in to_query("explorer", state)
    off, notices = parse_query("explorer", {"spread_check": "true"})
    assert off["spread_check"] is None and len(notices) == 1
    assert "spread_check=true" in notices[0]["text"] and "repeat from 2 to 32" in notices[0]["text"]
    assert "spread_check" not in to_query("explorer", off)
    bad, notices = parse_query("explorer", {"repeat": "4", "spread_check": "maybe"})
    assert bad["spread_check"] is None and "spread_check='maybe'" in notices[0]["text"] and "Using off" in notices[0]["text"]
    system = dampersim.default_parameters()
    one = state_cost("explorer", system, {**off, "repeat": None})
    # K runs at the step plus K at half of it (twice the steps each); 1e-9 for rounding the step count
    assert state_cost("explorer", system, state).work == pytest.approx(4 * one.work + 8 * one.work, rel=1e-9)
