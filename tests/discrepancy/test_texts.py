"""What the diagnosis says in words: the verdict summary and ranking rows of a diagnosis
document, the HTML report, and the effect registry's signature texts.

Diagnoses here drive the stand-in model of :mod:`tests.discrepancy.fake_rig` (about a
second each) or need no model run at all (a campaign the diagnosis cannot take).
"""

import html
import json
import re

import pytest

from dampersim.discrepancy import drive
from dampersim.discrepancy.diagnose import INSUFFICIENT, diagnose
from dampersim.discrepancy.effects import describe
from dampersim.discrepancy.report import diagnosis_document, diagnosis_from_document, ranking_rows, verdict_summary
from dampersim.parameters import default_parameters
from dampersim.plotting.discrepancy import report_html
from tests.discrepancy import fake_rig as F

#: four torsional points at one set point speed (1510 rpm is 1500 rpm, measured)
ONE_SPEED = [("a", 1500.0, 100.0), ("b", 1500.0, 300.0), ("c", 1510.0, 200.0), ("d", 1500.0, 400.0)]


def refuse(system, point):
    raise AssertionError(f"simulated {point.id}")


@pytest.fixture
def one_speed(monkeypatch):
    """The Diagnosis of a one-speed campaign (no model run: the campaign's shape decides)."""
    monkeypatch.setattr(drive, "simulate_point", refuse)
    d = diagnose(F.campaign([F.point(*p) for p in ONE_SPEED]), workers=1)
    assert d.verdict == INSUFFICIENT and d.missing == ["speeds"]
    return d


@pytest.fixture
def crashing_clutch(monkeypatch):
    """A diagnosis where clutch_slip fits the training points but the model diverges with it
    at the held-out points p1, p4: the candidate is not ranked, turbine_drag is named."""
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(
        lambda s, p: "raise" if s.effects.clutch_slip.enabled and p.id in ("p1", "p4") else None))
    d = diagnose(F.campaign([F.point(*p) for p in F.POINTS]), workers=1, candidates=["clutch_slip", "turbine_drag"])
    assert d.verdict == "missing_effect" and d.effect == "turbine_drag"
    return d


def as_document(diag) -> dict:
    """The diagnosis document as it comes back from a cache or a browser: plain JSON."""
    return json.loads(json.dumps(diagnosis_document(diag)))


# ----------------------------------------------------------------------------- verdict and ranking in words
def test_insufficient_data_says_what_is_missing_not_unexplained(one_speed):
    doc = as_document(one_speed)
    v = verdict_summary(doc)
    assert v["verdict"] == INSUFFICIENT and v["headline"] == "Insufficient data" and v["level"] == "error"
    assert "Unexplained" not in v["headline"] and "noise floor" not in v["reason"]
    # the diagnosis's own message, as a sentence
    assert v["reason"] == "N" + doc["message"][1:]
    assert "all 4 torsional test points are at one speed (1500 rpm)" in v["reason"] and "Accepted:" in v["reason"]
    assert v["missing"] == ["speeds"] and v["effect"] is None and v["parameters"] == ""
    assert ranking_rows(doc) == []


def test_an_excluded_candidate_shows_why_in_the_ranking_and_the_verdict(crashing_clutch):
    doc = as_document(crashing_clutch)
    rows = {r["effect"]: r for r in ranking_rows(doc)}
    clutch, drag = rows["clutch_slip"], rows["turbine_drag"]
    assert clutch["gap_held_out_nm"] is None and clutch["score_nm"] is None
    assert clutch["excluded"].startswith("not ranked: with clutch_slip fitted")
    assert "held-out point(s) p1, p4" in clutch["excluded"] and clutch["failed_points"] == ["p1", "p4"]
    assert clutch["parameters"] == clutch["excluded"]  # the table's parameters column says why, not "screened out"
    assert drag["excluded"] is None and drag["failed_points"] == [] and drag["parameters"].startswith("coefficient = ")
    reason = verdict_summary(doc)["reason"]
    # the pair tried with it fails there too
    assert reason.endswith("Not ranked because their model runs failed: clutch_slip, clutch_slip+turbine_drag (see the "
                           "ranking).")
    assert doc["posterior"]["clutch_slip"] == 0.0 and doc["posterior"]["turbine_drag"] > 0.9


def test_documents_from_before_the_new_fields_still_read():
    old = {"verdict": "unexplained", "gap_calibrated_nm": 2.0, "noise_floor_nm": 0.5,
           "ranking": [{"effect": "turbine_drag", "parameters": {}, "gap_held_out_nm": None, "score": None}]}
    assert ranking_rows(old)[0]["parameters"] == "screened out" and ranking_rows(old)[0]["excluded"] is None
    v = verdict_summary(old)
    assert v["headline"] == "Unexplained discrepancy" and "Not ranked" not in v["reason"]
    d = diagnosis_from_document(old)
    assert d.message == "" and d.missing == []


# ----------------------------------------------------------------------------- the HTML report
def test_the_html_report_of_a_campaign_without_a_diagnosis_states_what_is_missing(one_speed):
    for diag in (one_speed, diagnosis_from_document(as_document(one_speed))):
        page = report_html(diag, "one-speed")
        assert "<b>Verdict:</b> insufficient_data" in page
        assert html.escape(one_speed.message) in page and "<b>Missing:</b> speeds" in page
        assert not re.search(r"\bnan\b", page, re.IGNORECASE)  # no empty numbers, no figures of nothing
        assert "plotly" not in page


def test_the_html_report_of_a_diagnosis_lists_the_candidates_not_ranked(crashing_clutch):
    page = report_html(crashing_clutch, "fake")
    assert "<b>Verdict:</b> missing_effect" in page and html.escape(crashing_clutch.message) in page
    assert "Candidates not ranked" in page and "clutch_slip: not ranked: with clutch_slip fitted" in page
    assert page.count("plotly-graph-div") == 5  # gap, map, order errors, ranking, worst point


# ----------------------------------------------------------------------------- effect signatures
def test_inner_short_springs_signature_states_the_softer_first_stage():
    base = default_parameters()
    inner, short = base.inner, base.effects.inner_short_springs
    k_o, k_i, n_s, n = inner.spring.stiffness, inner.nested.stiffness, inner.count, short.count
    full = n_s * (k_o + k_i)  # every pair full length
    first = (n_s - n) * (k_o + k_i) + n * k_o  # below the clearance: the short pairs' outer spring alone
    third = first + n * short.stiffness  # beyond it
    sig = describe("inner_short_springs")["signature"]
    assert "no change at low torque" not in sig
    assert f"{n} of {n_s} pairs short: {first:.0f} instead of {full:.0f} N m/rad" in sig
    assert f"back to {third:.0f} N m/rad with the default {short.stiffness:.0f} N m/rad" in sig
