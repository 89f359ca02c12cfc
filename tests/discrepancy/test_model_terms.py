"""The model-based uncertainty terms (model_terms): their arithmetic, and the diagnosis's second
measurement of them at the calibrated factors (stand-in model, no simulation)."""

import numpy as np
import pytest

from dampersim.discrepancy import drive
from dampersim.discrepancy.model_terms import ModelTerms
from tests.discrepancy import fake_rig as F
from tests.discrepancy.test_input_channel import _campaign, _input_sensitive_model, _spy_on_cell_sigma

ORDERS = len(drive.ORDERS)


def _terms(y, up, down, unc=None):
    y = np.asarray(y, dtype=complex)
    unc = np.stack([y, y]) if unc is None else np.asarray(unc, dtype=complex)
    return ModelTerms(y, y + 0.1, np.asarray(up, dtype=complex), np.asarray(down, dtype=complex), unc,
                      [1.0] * len(y))


def test_the_input_term_is_half_the_change_for_a_linear_response_and_survives_a_bend():
    """Linear in the mean torque: the two one-sided changes are alike, and their RMS is half the
    change from down to up (the form used before). At an extremum of an order (a knee: both
    moves lower it by the same 0.8 N m) half that difference is zero, the RMS is 0.8."""
    y = np.full((2, ORDERS), 10.0 + 2.0j)
    d = np.full((2, ORDERS), 0.3 - 0.4j)
    linear = _terms(y, y + d, y - d)
    # rel 1e-12: the same numbers in another order
    assert linear.input_change == pytest.approx(0.5 * np.abs((y + d) - (y - d)), rel=1e-12)
    bent = _terms(y, y - 0.8, y - 0.8)
    assert 0.5 * np.abs(bent.input_up - bent.input_down) == pytest.approx(np.zeros((2, ORDERS)), abs=1e-12)
    assert bent.input_change == pytest.approx(np.full((2, ORDERS), 0.8), rel=1e-12)


def test_the_uncalibrated_term_sums_the_directions_mean_squares():
    y = np.full((1, ORDERS), 5.0 + 0j)
    unc = np.stack([y + 0.3, y - 0.3, y + 0.4j, y + 0.4j])  # direction 1 up, down; direction 2 up, down
    t = _terms(y, y, y, unc)
    # sqrt(0.5 (0.09 + 0.09 + 0.16 + 0.16)) = 0.5; rel 1e-12: exact arithmetic
    assert t.uncalibrated_change == pytest.approx(np.full((1, ORDERS), 0.5), rel=1e-12)
    assert t.model_change == pytest.approx(np.full((1, ORDERS), 0.1), rel=1e-12)


def test_failed_rows_are_filled_from_the_other_measurement_and_at_picks_rows():
    # first's rows differ: its input term is 0.5, 1.0 and 1.5 N m in rows 0, 1 and 2
    step = np.array([[0.5], [1.0], [1.5]]) * np.ones((3, ORDERS))
    first = _terms(np.full((3, ORDERS), 1.0), 1.0 + step, 1.0 - step)
    second = _terms(np.full((2, ORDERS), 2.0), np.full((2, ORDERS), 2.1), np.full((2, ORDERS), 1.9))
    second.y[1, 3] = np.nan  # its own run failed at row 1
    second.errors = {"coarse": {0: "diverged"}}
    assert second.failed_rows() == {0, 1}
    filled = second.filled_from(first, [2, 0])  # second's rows are first's rows 2 and 0
    assert filled.failed_rows() == set()
    # row 0 from first's row 2, row 1 from first's row 0
    assert filled.input_change == pytest.approx(np.array([[1.5], [0.5]]) * np.ones((2, ORDERS)), rel=1e-12)
    sub = first.at([2])
    assert sub.y.shape == (1, ORDERS) and sub.uncalibrated.shape == (2, 1, ORDERS)
    assert sub.input_change == pytest.approx(np.full((1, ORDERS), 1.5), rel=1e-12)
    sub.coarse[0, 2] = np.nan  # a failed check without a recorded error (at() drops them)
    assert sub.failed_rows() == {0}


def test_a_check_that_fails_only_at_the_calibrated_factors_keeps_the_first_and_is_reported(monkeypatch):
    """The stand-in's coarse check diverges at p3 once the calibration has moved the outer
    springs: p3 stays in the diagnosis with the checks of the set as given, and problems say so."""
    from dampersim.discrepancy import diagnose as dg

    def fail(system, p):
        coarse = system.solver.outer_segments < F.BASE.solver.outer_segments
        moved = system.outer.spring.stiffness != F.BASE.outer.spring.stiffness
        return "raise" if p.id == "p3" and coarse and moved else None

    seen = _spy_on_cell_sigma(monkeypatch, dg)
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(fail))
    d = dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False)
    assert d.verdict != dg.INSUFFICIENT and "p3" in {p["id"] for p in d.points}
    assert [(q["point"], q["field"]) for q in d.problems] == [("p3", "model")]
    message = d.problems[0]["message"]
    assert "calibrated parameter set" in message and "discretisation check" in message
    assert "keeps the uncertainty checks" in message
    assert len(seen["calls"]) == 2
    row = [p.id for p in _campaign().torsional].index("p3")
    # rel 1e-12: the same row copied
    assert np.asarray(seen["calls"][1]["model"])[row] == pytest.approx(np.asarray(seen["calls"][0]["model"])[row],
                                                                       rel=1e-12)


def test_the_model_terms_bench_summarises_rms_and_largest_per_point():
    """bench/bench_model_terms.py's printed figures (docs/discrepancy.md quotes them)."""
    from tests.discrepancy.benches import load_bench

    bench = load_bench("bench_model_terms")
    y = np.zeros((2, ORDERS), dtype=complex)
    up = y.copy()
    up[0, 0] = 3.0  # one order of one point moves by 3 N m when the input moves up, none when down
    t = _terms(y, up, y)
    meas = y + 0.5j
    got = bench.summary(t, meas)
    # input: sqrt(9 / 2) in one cell of eight -> RMS sqrt(9 / 16) = 0.75, largest 2.1213
    assert got["input"] == [0.75, 0.0] and got["input_max"] == [pytest.approx(2.12132, abs=1e-5), 0.0]
    assert got["model"] == [0.1, 0.1] and got["misfit"] == [0.5, 0.5]


def _spied_diagnosis(monkeypatch, uphill_recheck=False):
    """Diagnose the stand-in campaign, recording the uncertainty() returns, the Gauss-Newton
    solves (the last one is step 2b's; with ``uphill_recheck`` its direction is turned uphill)
    and what the naming starts from: (diagnosis, record)."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy import naming

    rec = {"sigmas": [], "solves": []}
    real_unc, real_solve, real_init = dg.uncertainty, dg._lstsq_bounded, naming.Namer.__init__

    def spy_unc(*args, **kwargs):
        out = real_unc(*args, **kwargs)
        rec["sigmas"].append(np.array(out[0]))
        return out

    def spy_solve(J, r, x0):
        dx = real_solve(J, r, x0)
        rec["solves"].append((np.array(x0), np.array(dx)))
        return -dx if uphill_recheck and len(rec["sigmas"]) == 2 else dx

    def spy_init(self, runner, lik, train, points, jac, starts, *args, **kwargs):
        rec["sigma"], rec["x"] = np.array(lik.sigma), np.array(starts["calibrated"][1])
        real_init(self, runner, lik, train, points, jac, starts, *args, **kwargs)

    monkeypatch.setattr(dg, "uncertainty", spy_unc)
    monkeypatch.setattr(dg, "_lstsq_bounded", spy_solve)
    monkeypatch.setattr(naming.Namer, "__init__", spy_init)
    # the stand-in whose orders follow the record's mean input torque: its input term moves with
    # the calibrated factors
    monkeypatch.setattr(drive, "simulate_point", _input_sensitive_model())
    return dg.diagnose(_campaign(), workers=1, candidates=["turbine_drag"], recommend=False), rec


def test_the_naming_reads_the_recheck_and_the_factors_its_step_reached(monkeypatch):
    """After step 2b the naming's likelihood carries the uncertainty measured at the calibrated
    factors, and (the stand-in's step is kept) the factors one Gauss-Newton step further, with
    the held-out points run at them."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy.fitting import CAL_STEP_FRACTIONS, calibrated_system

    d, rec = _spied_diagnosis(monkeypatch)
    assert len(rec["sigmas"]) == 2 and not np.array_equal(rec["sigmas"][0], rec["sigmas"][1])
    np.testing.assert_array_equal(rec["sigma"], rec["sigmas"][1])
    x0, dx = rec["solves"][-1]
    assert any(np.allclose(rec["x"], x0 + f * dx, rtol=0.0, atol=1e-15) for f in CAL_STEP_FRACTIONS), (rec["x"], x0)
    assert not np.array_equal(rec["x"], x0)  # kept: the check below then sees the rerun
    assert d.likelihood["calibration_taken_from"] is None  # "none" kept these factors
    cal = drive.diagnosis_system(calibrated_system(dg.default_parameters(), rec["x"]))
    camp = _campaign()
    for p, row in zip(camp.torsional, d.points):
        if row["held_out"]:
            # rel 1e-9: the same stand-in arithmetic (no simulation)
            assert row["calibrated"] == pytest.approx(np.abs(_input_sensitive_model()(cal, p)["coefficients"]),
                                                      rel=1e-9)


def test_an_uphill_recheck_step_is_not_kept(monkeypatch):
    _d, rec = _spied_diagnosis(monkeypatch, uphill_recheck=True)
    np.testing.assert_array_equal(rec["x"], rec["solves"][-1][0])


def test_measure_makes_the_runs_it_declares(monkeypatch):
    """model_terms.RUNS_PER_POINT (costs.DIAGNOSIS_RECHECK_RUNS copies it) against a counting runner."""
    from dampersim.discrepancy import model_terms

    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    pts = _campaign().torsional
    runner = drive.Runner(1)
    t = model_terms.measure(runner, F.BASE, pts, drive.coefficients_of(drive.Runner(1), F.BASE, pts))
    assert runner.count == model_terms.RUNS_PER_POINT * len(pts) and t.failed_rows() == set()
