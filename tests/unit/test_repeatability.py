"""Repeatability as a result (issue 14, item 2): K runs of one test point with the input
amplitudes scaled by (1 + i·1e-9), the spread of each output order, on the command line
(``simulate --repeatability K``), in the library and on the Explorer (``repeat=K``)."""

import json
import math

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


def _linear_system():
    return with_updates(dampersim.default_parameters(), {"friction.enabled": False, "hardstops.enabled": False})


def _excitation():
    return OrderSum(speed=rpm_to_rad_s(1500.0), mean_torque=200.0, orders=((2.0, 300.0, 0.0),))


def test_cli_key_only_with_the_flag_aligned_with_orders_and_null_where_tiny(capsys):
    assert main(LINEAR) == 0
    plain = json.loads(capsys.readouterr().out)
    assert "repeatability_pct" not in plain
    assert main([*LINEAR, "--repeatability", "3"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert set(rep) == set(plain) | {"repeatability_pct"}
    assert len(rep["repeatability_pct"]) == len(rep["orders"]) == 8
    # run 0 is the unscaled input: the same numbers as a single run
    assert rep["output_amplitude_nm"] == plain["output_amplitude_nm"]
    out = rep["output_amplitude_nm"]
    for a, s in zip(out, rep["repeatability_pct"]):
        # null exactly where the order's output is below 0.1 % of the largest order (here
        # the linear damper makes orders 3-8 from a pure 2nd order 1e3-1e5 times weaker)
        assert (s is None) == (a < 1e-3 * max(out)), (a, s)
    assert rep["repeatability_pct"][1] is not None and any(s is None for s in rep["repeatability_pct"])


def test_cli_text_table_has_the_spread_column(capsys):
    assert main([*LINEAR[:-1], "--repeatability", "2"]) == 0
    text = capsys.readouterr().out
    assert "spread of 2 runs [%]" in text and "max - min" in text


@pytest.mark.parametrize("value", ["1", "33", "2.5", "x", "-3", "²"])
def test_cli_refuses_k_outside_2_to_32_with_one_line(value, capsys, monkeypatch):
    import dampersim.simulation.damper as damper

    monkeypatch.setattr(damper, "run_damper", lambda *a, **k: pytest.fail("simulated before checking K"))
    assert main([*LINEAR, "--repeatability", value]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"--repeatability {value!r}" in err and "2 to 32" in err


def test_linear_case_spread_is_the_input_change_and_inputs_really_differ(monkeypatch):
    seen = []
    real = R.simulate

    def spy(system, ex, **kw):
        seen.append(ex)
        return real(system, ex, **kw)

    ex = _excitation()
    rep = R.repeatability(_linear_system(), ex, 3, orders=(2.0, 3.0), duration=1.5, simulate_fn=spy)
    # run i's input amplitudes are the given ones x (1 + i·1e-9), nothing else changes
    assert [e.orders[0][1] for e in seen] == [300.0, 300.0 * (1 + 1e-9), 300.0 * (1 + 2e-9)]
    assert seen[0] is ex and all(e.mean_torque == 200.0 and e.speed == ex.speed for e in seen)
    assert rep.result is not None and rep.runs == 3 and rep.output_nm.shape == (3, 2)
    # A linear damper's output scales with its input, so the 2nd order spreads by exactly
    # the input's 2e-9 (2e-7 %); 5 % allows the FFT's rounding (1e-16 of 10 N m). This
    # fails both when the runs are not different (spread 0, e.g. one run served from a
    # cache) and when the result is not repeatable (anything near the 1e-5 % ceiling).
    assert rep.spread_pct[0] == pytest.approx(2e-7, rel=0.05)
    assert rep.spread_pct[0] < 1e-5
    assert rep.spread_pct[1] is None  # the 3rd order's output is below 0.1 % of the 2nd's


def test_run0_given_is_not_run_again(monkeypatch):
    calls = []
    real = R.simulate

    def spy(system, ex, **kw):
        calls.append(ex.orders[0][1])
        return real(system, ex, **kw)

    system, ex = _linear_system(), _excitation()
    first = real(system, ex, duration=1.2, record_segments=False)
    rep = R.repeatability(system, ex, 2, orders=(2.0,), duration=1.2, run0=first, simulate_fn=spy)
    assert rep.result is first and calls == [300.0 * (1 + 1e-9)]


@pytest.mark.parametrize("k", [1, 33, 2.5, "x", True, None, float("nan")])
def test_library_refuses_k_outside_2_to_32(k):
    with pytest.raises(InputError) as exc:
        R.repeatability(_linear_system(), _excitation(), k, simulate_fn=lambda *a, **kw: pytest.fail("ran"))
    assert f"K = {k!r}" in str(exc.value) and "2 to 32" in str(exc.value)


def test_spread_rule():
    # two orders: 10 and 12 N m in the 1st, 0.001 (below 0.1 % of 11) in the 2nd
    s = R.spread_pct([[10.0, 0.001], [12.0, 0.002], [11.0, 0.001]])
    assert s[0] == pytest.approx(100 * 2 / 11) and s[1] is None
    assert R.spread_pct([[0.0], [0.0]]) == (None,)


# ------------------------------------------------------------------------ Explorer
def test_explorer_state_round_trips_repeat_and_refuses_bad_values():
    from dampersim.views.state import parse_query, state_cost, to_query

    state, notices = parse_query("explorer", {"repeat": "8"})
    assert notices == [] and state["repeat"] == 8
    assert "repeat=8" in to_query("explorer", state)
    assert parse_query("explorer", dict(p.split("=") for p in to_query("explorer", state)[1:].split("&")))[0] == state
    off, notices = parse_query("explorer", {})
    assert off["repeat"] is None and notices == [] and "repeat" not in to_query("explorer", off)
    assert parse_query("explorer", {"repeat": "off"}) == (off, [])
    for bad in ("1", "33", "2.5", "x"):
        state, notices = parse_query("explorer", {"repeat": bad})
        assert state["repeat"] is None and len(notices) == 1
        text = notices[0]["text"]
        assert f"repeat={bad!r}" in text and "2 to 32" in text and "Using off" in text
    # the cost the page checks is K runs
    system = dampersim.default_parameters()
    one = state_cost("explorer", system, off)
    assert state_cost("explorer", system, {**off, "repeat": 8}).work == pytest.approx(8 * one.work)


def test_explorer_view_draws_the_band(cache_dir):
    from dampersim.views.explorer import explorer_view
    from dampersim.views.state import parse_query

    state, _ = parse_query("explorer", {"duration": "1", "repeat": "2", "friction.enabled": "false",
                                        "hardstops.enabled": "false"})
    from dampersim.views.params import resolve_system

    view = explorer_view(resolve_system(state["params"]), state)
    main_row = [r for r in view["orders"] if r["order"] == 2.0][0]
    assert main_row["spread_pct"] == pytest.approx(1e-7, rel=0.05)  # linear: the 1e-9 input change
    lo, hi = main_row["mr_range"]
    assert lo <= main_row["mr"] <= hi and lo < hi
    bar = view["figures"]["mr"]["data"][0]
    assert "error_y" in bar and any(v > 0 for v in bar["error_y"]["array"])
    assert view["summary"]["repeat"] == 2
    # without the flag: no band, no spread
    plain = explorer_view(resolve_system(state["params"]), {**state, "repeat": None})
    assert "error_y" not in plain["figures"]["mr"]["data"][0] and "spread_pct" not in plain["orders"][0]
    assert all(math.isfinite(r["output_nm"]) for r in plain["orders"])
