"""A model run that fails is never a match: the point is left out and reported by id, a
calibration trial is rejected, a candidate effect is not ranked.

The diagnoses here drive the stand-in model of :mod:`tests.discrepancy.fake_rig` (whole
diagnoses in about a second each); the campaign has six points, p1 and p4 held out.
"""

import json

import numpy as np
import pytest

from dampersim.cli import main
from dampersim.discrepancy import drive, unnamed
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.discrepancy.diagnose import INSUFFICIENT, _resid, diagnose
from dampersim.discrepancy.likelihood import Likelihood
from dampersim.jsonsafe import jsonable
from tests.discrepancy import fake_rig as F

#: the JSON fields of ``diagnose --json`` before the failed-run and bad-input work; they stay
EXISTING_KEYS = {"verdict", "effect", "effect_parameters", "ranking", "noise_floor_nm", "gap_before_nm",
                 "gap_calibrated_nm", "gap_after_nm", "held_out_points", "calibration", "locate",
                 "ramp_windup_error_deg", "problems", "simulations", "wall_time_s"}


def six_points():
    return F.campaign([F.point(*p) for p in F.POINTS])


def run(monkeypatch, fail, **kw):
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(fail))
    return diagnose(six_points(), workers=1, **kw)


def test_a_failed_run_stays_a_failure_in_the_residual_and_the_cost():
    # read as 0, a failed run would be a perfect match
    assert np.isnan(_resid(np.array([np.nan, 2.0]), np.array([1.0, 1.0]))[0])
    lik = Likelihood(np.ones((1, 2), complex), np.ones((1, 2)), [100.0], [1.0, 2.0])
    assert lik.loss(np.array([[np.nan, 1.0]]), [0]) == float("inf")
    assert lik.loss(np.array([[np.inf + 0j, 1.0]]), [0]) == float("inf")
    assert lik.loss(np.ones((1, 2), complex), [0]) == 0.0


def test_run_task_turns_exceptions_and_non_finite_results_into_errors(monkeypatch):
    monkeypatch.setattr(drive, "simulate_point", lambda s, p: {"orders": np.array([1.0, np.nan])})
    assert "non-finite orders" in drive.run_task((None, None))["error"]
    monkeypatch.setattr(drive, "simulate_point", lambda s, p: {"windup": np.array([np.inf])})
    assert "non-finite windup" in drive.run_task((None, None))["error"]
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(lambda s, p: "raise"))
    assert drive.run_task((F.BASE, F.point(*F.POINTS[0])))["error"].startswith("SimulationDiverged")


def test_a_point_whose_run_diverges_is_left_out_and_reported_by_id(monkeypatch):
    d = run(monkeypatch, lambda s, p: "nan" if p.id == "p4" else None, candidates=["turbine_drag"])
    assert [(q["point"], q["field"]) for q in d.problems] == [("p4", "model")]
    assert "non-finite orders" in d.problems[0]["message"] and "left out" in d.problems[0]["message"]
    # out of the fit and the verdict: the split is made on the five points that ran
    assert "p4" not in d.held_out_points and d.held_out_points == ["p1", "p5"]
    assert "p4" not in {p["id"] for p in d.points}
    assert all("p4" not in stage for stage in d.residuals.values())
    assert "p4" in d.message
    # the gaps are those of the points shown (same arithmetic, so to rounding: 1e-12)
    held = [p for p in d.points if p["held_out"]]
    rms = np.sqrt(np.mean([(np.array(p["before"]) - p["measured"]) ** 2 for p in held]))
    assert d.gap_before_nm == pytest.approx(rms, rel=1e-12)
    assert d.verdict == "missing_effect" and d.effect == "turbine_drag"


@pytest.mark.parametrize("candidates, verdict, effect", [
    (["clutch_slip", "turbine_drag"], "missing_effect", "turbine_drag"),
    (["clutch_slip"], "unexplained", None),
])
def test_a_candidate_that_crashes_the_model_at_held_out_points_cannot_win(monkeypatch, candidates, verdict, effect):
    # clutch slip fits the training points as well as turbine drag (same signature) but
    # the model diverges with it at the held-out points: read as zero residuals, that was
    # a held-out gap of 0 and the win
    d = run(monkeypatch, lambda s, p: "raise" if s.effects.clutch_slip.enabled and p.id in ("p1", "p4") else None,
            candidates=candidates)
    assert (d.verdict, d.effect) == (verdict, effect)
    clutch = next(r for r in d.ranking if r["effect"] == "clutch_slip")
    assert clutch["gap_held_out_nm"] is None and clutch["posterior"] == 0.0  # never a match, never probable
    assert clutch["failed_points"] == ["p1", "p4"]
    assert "p1, p4" in clutch["excluded"] and "SimulationDiverged" in clutch["excluded"]
    assert "clutch_slip" in d.message and "not ranked" in d.message
    assert d.problems == []  # the points themselves run with the parameter set as given
    if effect:
        assert d.ranking[0]["effect"] == effect and d.ranking[0]["excluded"] is None


def test_a_calibration_trial_that_fails_is_rejected(monkeypatch):
    # the data ask for a 17 % stiffer outer set (see fake_rig: calibrated without failures
    # to x1.17); the model fails at training point p0 above x1.05, so the calibration
    # must stay at or below that (read as a zero residual, a failing trial looked better)
    limit = 1.05 * F.BASE.outer.spring.stiffness
    d = run(monkeypatch, lambda s, p: "raise" if p.id == "p0" and s.outer.spring.stiffness > limit else None,
            candidates=["turbine_drag"])
    assert d.calibration["outer_stiffness"] <= 1.05
    assert d.problems == [] and d.verdict != INSUFFICIENT


def test_every_point_failing_gives_insufficient_data(monkeypatch):
    d = run(monkeypatch, lambda s, p: "raise", candidates=["turbine_drag"])
    assert d.verdict == INSUFFICIENT and d.missing == ["torsional_points"]
    assert sorted(q["point"] for q in d.problems) == [p[0] for p in F.POINTS]
    assert "6 torsional point(s) were left out" in d.message and "Accepted: at least 3" in d.message
    assert d.effect is None and d.ranking == [] and d.held_out_points == []


def test_cli_json_lists_the_failed_point_under_problems(monkeypatch, tmp_path, capsys):
    folder = tmp_path / "camp"
    write_campaign(folder, six_points().points)
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(lambda s, p: "raise" if p.id == "p4" else None))
    assert main(["diagnose", str(folder), "--json", "--workers", "1"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert set(doc) >= EXISTING_KEYS | {"message", "missing"}
    assert [(q["point"], q["field"]) for q in doc["problems"]] == [("p4", "model")]
    assert "p4" not in doc["held_out_points"] and "p4 [model]" in captured.err
    assert all({"excluded", "failed_points"} <= set(r) for r in doc["ranking"])
    assert doc == jsonable(doc)  # strict JSON: no NaN or inf slipped through


def test_a_held_out_point_where_the_calibrated_model_fails_is_left_out_of_the_verdict(monkeypatch):
    # the calibration asks for a 17 % stiffer outer set (fake_rig); with it the model fails at
    # held-out point p1: p1 leaves the verdict, which is judged on p4 alone, with numbers
    def fail(s, p):
        return "raise" if p.id == "p1" and s.outer.spring.stiffness > 1.1 * F.BASE.outer.spring.stiffness else None

    d = run(monkeypatch, fail, candidates=["turbine_drag"])
    assert d.verdict in ("missing_effect", "no_missing_effect", "unexplained")
    assert d.held_out_points == ["p4"]
    assert ("p1", "model") in [(q["point"], q["field"]) for q in d.problems]
    assert np.isfinite(d.likelihood["reduced_chi2_held_out_calibrated"])
    assert np.isfinite(d.likelihood["reduced_chi2_held_out"])


def test_the_next_points_separate_the_two_most_probable_models(monkeypatch):
    # the stand-in's design runs (tests/discrepancy/conftest.py): turbine drag against none
    d = run(monkeypatch, None, candidates=["turbine_drag"])
    recs = d.recommended_points
    assert recs and all(set(r) == {"kind", "speed_rpm", "mean_torque_nm", "orders", "protocol", "reason"} for r in recs)
    first = recs[0]
    assert first["kind"] == "torsional" and first["orders"].startswith("2:") and first["protocol"] is None
    assert "separates the two most probable models" in first["reason"] and "turbine_drag" in first["reason"]


def test_the_posterior_is_built_from_the_penalised_evidences(monkeypatch):
    """The diagnosis's posterior is the one selection.model_log_evidence gives from the
    held-out penalties the diagnosis reports: if diagnose stopped passing the penalty (or
    computed log evidences elsewhere), the reported posterior would differ from this one."""
    from dampersim.discrepancy import selection

    seen = {}
    real = selection.model_log_evidence

    def spy(models, candidates, pairs, screen_z, ramp_ll, penalty, unfitted, unnamed):
        seen["penalty"], seen["pairs"], seen["ramp_ll"] = dict(penalty), list(pairs), dict(ramp_ll)
        seen["unnamed"] = unnamed
        seen["log_z"] = real(models, candidates, pairs, screen_z, ramp_ll, penalty, unfitted, unnamed)
        return seen["log_z"]

    monkeypatch.setattr(selection, "model_log_evidence", spy)
    d = run(monkeypatch, None, candidates=["clutch_slip", "turbine_drag"])
    assert seen["penalty"] == d.likelihood["held_out_penalty"] and seen["penalty"]  # every fitted model has one
    # the leading effect predicts the held-out points at the noise here: no pair, no partner screen
    assert seen["pairs"] == [] and d.likelihood["pair_partners"] is None
    assert seen["log_z"] == d.likelihood["log_evidence"]
    # the ramps' term as the posterior read it (this stand-in campaign has none: {})
    assert seen["ramp_ll"] == d.likelihood["ramp_log_likelihood"]
    # the unnamed misfit's term of "none" as the posterior read it, from its two parts
    reported = d.likelihood["unnamed_misfit"]
    assert seen["unnamed"] == reported["log_evidence"] == unnamed.combined(reported["torsional"], reported["ramps"])
    assert reported["ramps"] == 0.0  # no ramp in this campaign
    # what that term was computed from comes with the diagnosis and gives it back (the same
    # arithmetic on the same arrays: exact), so a reader can recompute it under other settings
    assert unnamed.torsion_gain(**d.misfit_inputs["torsion"]) == reported["torsional"]
    assert d.misfit_inputs["ramps"] is None
    expect = selection.posterior(seen["log_z"], selection.model_priors(["clutch_slip", "turbine_drag"], seen["pairs"]))
    assert {k: d.posterior[k] for k in expect} == pytest.approx(expect)
