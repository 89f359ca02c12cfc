"""bench/bench_fit_trace.py's wrapping of the naming's steps, on the re-calibration toy of
test_refit.py (smooth stand-in runs with known answers): the traced steps return what the
plain ones return, and the events carry the figures the docs read from them."""

import json
import math
import sys

import numpy as np
import pytest

from dampersim.discrepancy import fitting, naming, selection

from tests.discrepancy.benches import load_bench
from tests.discrepancy.test_refit import NAME, _first_fit, namer  # noqa: F401  (namer: the fixture)

trace = load_bench("bench_fit_trace")


@pytest.fixture()
def events(monkeypatch):
    # the wrapping replaces Namer's methods: registered here so that the test restores them
    for attr in trace.WRAPPED:
        monkeypatch.setattr(naming.Namer, attr, getattr(naming.Namer, attr))
    return []


def test_the_traced_refit_returns_the_plain_one_and_logs_the_side_refits(namer, events):  # noqa: F811
    first = _first_fit(namer, 0.0016)
    plain = naming.Namer.refit(namer, NAME, first)
    runs_plain = len(namer.calls)
    side_shape = {"order": 2.1, "damping": 0.03}
    trace.install(events.append, {NAME: {"other": side_shape}})
    traced = naming.Namer.refit(namer, NAME, first)
    assert traced["cost"] == plain["cost"] and np.array_equal(traced["x"], plain["x"])
    (event,) = events
    assert event["event"] == "refit" and event["name"] == NAME
    assert event["first_fit"]["cost"] == first["cost"] and event["refit"]["cost"] == plain["cost"]
    (side,) = event["side"]
    assert side["from"] == "other" and side["refit"]["shape"]["order"] == 2.1
    # the side refit started from the given shape, so it is another fit, and its runs are real
    assert side["refit"]["cost"] != plain["cost"]
    assert len(namer.calls) > 2 * runs_plain
    assert side["after_shape_step"] is not None  # the side refit's shape step is in its entry
    json.dumps(events)  # every event serialises


def _failing_at_order(namer, order):
    """Make every run at the absorber's ``order`` record a failure at its first point (as a side
    shape whose runs fail would)."""
    runs = namer.runs

    def failing_side(system, name, points=None):
        y, failed = runs(system, name, points)
        if system.effects.pendulum_absorber.order == order:
            namer._record(name, {0: "side run failed"}, namer.points if points is None else points)
        return y, failed

    namer.runs = failing_side


def test_a_side_refits_failed_points_are_not_recorded_against_the_effect(namer, events):  # noqa: F811
    first = _first_fit(namer, 0.0016)
    _failing_at_order(namer, 2.1)
    naming.Namer.refit(namer, NAME, first)
    before = dict(namer.failures.get(NAME, {}))
    trace.install(events.append, {NAME: {"other": {"order": 2.1, "damping": 0.03}}})
    naming.Namer.refit(namer, NAME, first)
    assert before == {} and namer.failures[NAME] == before


def test_a_side_refit_the_set_refuses_goes_to_its_event_and_leaves_the_fit_alone(namer, events):  # noqa: F811
    first = _first_fit(namer, 0.0016)
    plain = naming.Namer.refit(namer, NAME, first)
    trace.install(events.append, {NAME: {"bad": {"order": -1.0}}})
    traced = naming.Namer.refit(namer, NAME, first)
    assert traced["cost"] == plain["cost"]
    (bad,) = events[0]["side"]
    assert "error" in bad and "order" in bad["error"] and "refit" not in bad


def test_the_shape_step_is_traced_with_the_objective_before_it(namer, events):  # noqa: F811
    fit = naming.Namer.refit(namer, NAME, _first_fit(namer, 0.0016))
    before = fit["cost"]
    trace.install(events.append, {})
    out = naming.Namer.fit_shapes(namer, NAME, fit)
    (event,) = events
    assert event["event"] == "shape_step" and event["cost_before"] == before
    assert event["fit"]["cost"] == out["cost"] <= before


def test_a_first_fits_shape_step_is_followed_by_the_side_fits_from_the_given_shapes(namer, events):  # noqa: F811
    first = namer.fit(NAME, "calibrated")
    plain = naming.Namer.fit_shapes(namer, NAME, dict(first))
    runs_plain = len(namer.calls)
    trace.install(events.append, {}, {NAME: {"low": {"order": 1.92}, "bad": {"order": -1.0}}})
    traced = naming.Namer.fit_shapes(namer, NAME, dict(first))
    assert traced["cost"] == plain["cost"] and np.array_equal(traced["x"], plain["x"])  # the fit is left alone
    step, low, bad = events
    assert step["event"] == "shape_step" and low["event"] == bad["event"] == "side_fit"
    assert low["from"] == "low" and low["start"] == "calibrated"
    # the side fit held the given order through its magnitude search, then took its own shape step (the toy
    # ignores the order, so the step goes to the prior's centre, the set's 2.0)
    assert low["fit"]["shape"]["order"] == 1.92 and low["after_shape_step"]["shape"]["order"] != 1.92
    assert len(namer.calls) > 2 * runs_plain  # its runs are real
    assert "error" in bad and "order" in bad["error"] and "fit" not in bad
    json.dumps(events)


def test_no_side_fit_runs_after_a_refits_or_a_pairs_shape_step(namer, events):  # noqa: F811
    trace.install(events.append, {}, {NAME: {"low": {"order": 1.92}}})
    first = namer.fit(NAME, "calibrated")
    naming.Namer.fit_shapes(namer, NAME, dict(first, start="refit"))
    naming.Namer.fit_shapes(namer, NAME, dict(first, base=first["system"]))  # on top of another effect
    assert [e["event"] for e in events] == ["shape_step", "shape_step"]


def _order_dependent(namer, slope=3.0):
    """Make the toy's coefficients depend on the absorber's order too (the toy alone ignores the
    shapes), so that a shape column has a value to check."""
    runs = namer.runs

    def with_order(system, name, points=None):
        y, failed = runs(system, name, points)
        return y + slope * math.log(system.effects.pendulum_absorber.order / 2.0), failed

    namer.runs = with_order


def _stepped_fit(namer):
    fit = naming.Namer.fit_shapes(namer, NAME, namer.fit(NAME, "calibrated"))
    assert fit["shapes"]  # the step moved the fit
    fit.update({"effects": [NAME], "columns": [fit["column"], *fit["shape_columns"]],
                "nuisance": namer.lik.profile(fit["y"], namer.train)[1]})
    return fit


def test_fresh_columns_read_the_evidence_with_derivatives_at_the_fits_final_point(namer, events):  # noqa: F811
    _order_dependent(namer)
    fit = _stepped_fit(namer)
    plain = naming.Namer.evidence(namer, fit, [NAME])
    untraced = trace.install(events.append, {}, {}, fresh_columns=True)
    runs = len(namer.calls)
    log_z, cov = naming.Namer.evidence(namer, fit, [NAME])
    assert log_z == plain[0] and np.array_equal(cov, plain[1])  # the diagnosis reads what it read
    per_run = len(namer.points)  # the toy counts a call per point
    assert len(namer.calls) == runs + per_run * (1 + len(fit["shape_start"]))  # one run per derivative
    naming.Namer.evidence(namer, fit, [NAME], eta=0.5)
    assert len(namer.calls) == runs + per_run * (1 + len(fit["shape_start"]))  # read again without runs
    fresh = events[0]["fresh_columns"]
    # independently: each column by its finite difference at the final point
    moved, step = fitting.fd_magnitude(NAME, fit["m"])
    y_m, _ = namer.runs(naming.with_effect(fit["system"], NAME, {"inertia": moved}), NAME)
    cols = [namer.w((y_m - fit["y"]) / step)]
    eff = fit["system"].effects.pendulum_absorber
    for q in fit["shape_start"]:
        v = getattr(eff, q)
        y_q, _ = namer.runs(naming.with_effect(fit["system"], NAME, {q: v * math.exp(naming.SHAPE_FD_STEP)}), NAME)
        cols.append(namer.w((y_q - fit["y"]) / naming.SHAPE_FD_STEP))
    assert np.linalg.norm(cols[1]) > 0  # the order's column is not trivially zero
    expected = untraced["evidence"](namer, dict(fit, columns=cols), [NAME])
    assert fresh["log_evidence"] == pytest.approx(expected[0], rel=1e-12)
    assert fresh["log_evidence_as_run"] == plain[0] and fresh["log_evidence"] != plain[0]
    n = namer.jac.shape[1]  # the calibration factors come first, then the magnitude, then the shapes
    values = {"inertia": fit["m"], **{q: getattr(eff, q) for q in fit["shape_start"]}}
    assert list(fresh["laplace"]) == list(values) and fresh["zeroed"] == []
    for i, (q, v) in enumerate(values.items()):
        want = selection.interval90(math.log(v), math.sqrt(expected[1][n + i, n + i]))
        assert fresh["laplace"][q][1:3] == pytest.approx(want, rel=1e-9), q
        as_run = selection.interval90(math.log(v), math.sqrt(plain[1][n + i, n + i]))
        assert fresh["laplace_as_run"][q][1:3] == pytest.approx(as_run, rel=1e-9), q
    json.dumps(events)


def test_a_failed_fresh_derivative_is_a_zero_column_and_not_the_effects_failure(namer, events):  # noqa: F811
    fit = _stepped_fit(namer)
    trace.install(events.append, {}, {}, fresh_columns=True)
    namer.runner.fail_above = fit["m"] * 1.01  # the magnitude's derivative run fails, nothing else
    before = dict(namer.failures.get(NAME, {}))
    naming.Namer.evidence(namer, fit, [NAME])
    fresh = events[0]["fresh_columns"]
    assert fresh["zeroed"] == ["inertia"] and fresh["column_norms"][0] == 0.0
    assert namer.failures.get(NAME, {}) == before


def test_a_side_fits_failed_points_are_not_recorded_against_the_effect(namer, events):  # noqa: F811
    first = namer.fit(NAME, "calibrated")
    _failing_at_order(namer, 1.92)
    trace.install(events.append, {}, {NAME: {"low": {"order": 1.92}}})
    before = dict(namer.failures.get(NAME, {}))
    naming.Namer.fit_shapes(namer, NAME, first)
    assert events[-1]["event"] == "side_fit" and namer.failures[NAME] == before == {}


def test_the_traced_evidence_logs_each_training_points_reduced_chi2(namer, events):  # noqa: F811
    first = _first_fit(namer, 0.0016)
    fit = naming.Namer.refit(namer, NAME, first)
    fit.update({"effects": [NAME], "columns": [fit["column"]], "nuisance": namer.lik.profile(fit["y"], namer.train)[1]})
    plain = naming.Namer.evidence(namer, fit, [NAME])
    trace.install(events.append, {})
    log_z, cov = naming.Namer.evidence(namer, fit, [NAME])
    assert log_z == plain[0] and np.array_equal(cov, plain[1])
    (event,) = events
    assert list(event["point_reduced_chi2"]) == [p.id for p in namer.points]
    per_point = namer.lik.point_chi2(fit["y"], namer.train, fit["nuisance"]) / (2 * len(namer.lik.orders))
    assert list(event["point_reduced_chi2"].values()) == [float(c) for c in per_point]  # each to its own point
    # independently: the points' mean is the model's plain reduced chi^2 (equal point sizes);
    # the tolerance covers the summation order only
    mean = np.mean(list(event["point_reduced_chi2"].values()))
    assert mean == pytest.approx(namer.lik.reduced_chi2(fit["y"], namer.train, fit["nuisance"]), rel=1e-12)
    assert event["effects"] == [NAME] and event["log_evidence"] == plain[0]


def test_main_hands_the_arguments_to_the_benchmark_and_puts_the_methods_back(tmp_path, capsys):
    plain = {attr: getattr(naming.Namer, attr) for attr in trace.WRAPPED}
    argv = list(sys.argv)
    assert trace.main(["--trace", str(tmp_path / "t.jsonl"), "--", "--list", "--only", "control/none/1"]) == 0
    assert "control/none/1" in capsys.readouterr().out
    assert {attr: getattr(naming.Namer, attr) for attr in trace.WRAPPED} == plain and sys.argv == argv
    with pytest.raises(SystemExit):  # no benchmark arguments would run the whole matrix
        trace.main(["--trace", str(tmp_path / "t.jsonl")])
    assert "no benchmark arguments" in capsys.readouterr().err


def test_bad_side_shapes_are_refused_with_what_is_accepted(capsys, tmp_path):
    with pytest.raises(SystemExit):
        trace.main(["--trace", str(tmp_path / "t.jsonl"), "--refit-shapes", "{not json", "--", "--list"])
    assert "accepted is an object" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        trace.main(["--trace", str(tmp_path / "t.jsonl"), "--refit-shapes", '{"a": 1}', "--", "--list"])
    assert "accepted is an object of effect name" in capsys.readouterr().err
    for shapes, said in (('{"nope": {}}', "not an effect"),
                         ('{"inner_short_springs": {"clearnce": 0.05}}', "clearance"),
                         ('{"inner_short_springs": {"clearance": -1}}', "accepted is a value")):
        with pytest.raises(SystemExit):
            trace.main(["--trace", str(tmp_path / "t.jsonl"), "--refit-shapes", shapes, "--", "--list"])
        assert said in capsys.readouterr().err
