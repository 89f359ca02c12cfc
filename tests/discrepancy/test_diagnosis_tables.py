"""The model comparison of a diagnosis as display rows and in the HTML report: the posterior
sorted by probability, the effects of the most probable model with their 90 % intervals
and units, the detectability of each effect with the direction of its threshold in words,
the recommended next test points, the outliers and the likelihood summary.

Hand-written documents only, no model run: a full one, one from before these keys
existed, one of a campaign that could not be diagnosed and a malformed one."""

from __future__ import annotations

import copy
import html
import json
import re

import pytest

from dampersim.discrepancy import report_tables as T
from dampersim.discrepancy.report import diagnosis_from_document
from dampersim.plotting.discrepancy import report_html as plain_report_html

FULL = {
    "verdict": "missing_effect", "effect": "clutch_slip", "effect_parameters": {"capacity": 512.3},
    "noise_floor_nm": 0.4, "gap_before_nm": 3.1, "gap_calibrated_nm": 2.2, "gap_after_nm": 0.5,
    "held_out_points": ["p1", "p4"],
    "ranking": [{"effect": "clutch_slip", "parameters": {"capacity": 512.3}, "gap_held_out_nm": 0.5, "score": 0.52},
                {"effect": "turbine_drag", "parameters": {"coefficient": 2.0}, "gap_held_out_nm": 1.9, "score": 1.95}],
    "posterior": {"none": 0.04, "clutch_slip": 0.81, "turbine_drag": 0.1, "clutch_slip+turbine_drag": 0.05},
    "effects": [{"name": "clutch_slip", "parameters": {"capacity": 512.3, "viscous": 0.8},
                 "intervals": {"capacity": [480.2, 545.9], "viscous": [0.5, 1.1]}}],
    "detectability": {"pendulum_absorber": 0.0007, "clutch_slip": 430.0, "turbine_drag": None,
                      "transducer_bandwidth": 180.0, "nested_radial_transfer": 0.3},
    "recommended_points": [
        {"kind": "torsional", "speed_rpm": 2500.0, "mean_torque_nm": 450.0, "orders": "2:150", "protocol": None,
         "reason": "separate clutch_slip from clutch_slip+turbine_drag"},
        {"kind": "ramp", "speed_rpm": 1000.0, "mean_torque_nm": 0.0, "orders": None, "protocol": "pos-350-450",
         "reason": "clutch_slip shows in slow ramps"}],
    "outliers": ["map_900_50", "tc_1200"],
    "likelihood": {"reduced_chi2_held_out": 1.13, "reduced_chi2_train": 0.97, "cells": 96,
                   "nuisance": {"output_gain": 1.0021, "delay_ms": 0.153},
                   "log_evidence": {"none": -120.5, "clutch_slip": -100.25, "turbine_drag": -110.0,
                                    "clutch_slip+turbine_drag": -103.0},
                   "model_prior": {"none": 0.4, "clutch_slip": 0.2, "turbine_drag": 0.2,
                                   "clutch_slip+turbine_drag": 0.2}},
}
#: a document written before the model comparison existed
OLD = {k: v for k, v in FULL.items() if k not in T.KEYS}
#: a campaign that could not be diagnosed: every key present, all empty
INSUFFICIENT = {"verdict": "insufficient_data", "effect": None, "effect_parameters": {}, "ranking": [],
                "noise_floor_nm": None, "gap_before_nm": None, "gap_calibrated_nm": None, "gap_after_nm": None,
                "held_out_points": [], "message": "not diagnosed: only 2 valid torsional test point(s) (a, b).",
                "missing": ["torsional_points"], "posterior": {}, "effects": [], "detectability": {},
                "recommended_points": [], "outliers": [], "likelihood": {}}
NOT_COMPUTED = "Not computed: this diagnosis was made by an earlier version"


def plain(doc) -> dict:
    """As it comes back from the cache or the browser: plain JSON."""
    return json.loads(json.dumps(doc))


# ----------------------------------------------------------------------------- rows
def test_posterior_is_sorted_by_probability_with_prior_and_evidence():
    rows = T.posterior_rows(plain(FULL))
    assert [r["model"] for r in rows] == ["clutch_slip", "turbine_drag", "clutch_slip+turbine_drag", "none"]
    assert [r["most_probable"] for r in rows] == [True, False, False, False]
    best = rows[0]
    assert (best["probability"], best["prior"], best["log_evidence"]) == (0.81, 0.2, -100.25)
    assert (best["probability_text"], best["prior_text"], best["log_evidence_text"]) == ("81 %", "20 %", "-100.25")
    assert rows[2]["label"] == "clutch_slip + turbine_drag" and rows[3]["label"] == "none (calibrated model alone)"
    assert T.most_probable(FULL) == "clutch_slip"
    # the ends of the scale stay readable
    tiny = T.posterior_rows({"posterior": {"none": 1e-9, "a": 0.9999999}})
    assert [r["probability_text"] for r in tiny] == ["> 99.9 %", "< 0.01 %"]


def test_effects_of_the_most_probable_model_with_intervals_and_units():
    rows = T.effect_rows(plain(FULL))
    cap, visc = rows
    assert (cap["effect"], cap["parameter"], cap["unit"], cap["magnitude"]) == ("clutch_slip", "capacity", "N m", True)
    assert (cap["value"], cap["low"], cap["high"]) == (512.3, 480.2, 545.9)
    assert cap["value_text"] == "512 N m" and cap["interval_text"] == "480 – 546 N m"
    assert visc["unit"] == "N m s/rad" and not visc["magnitude"] and visc["interval_text"] == "0.5 – 1.1 N m s/rad"
    assert "clutch_slip" in T.effects_note(FULL) and "90 % intervals" in T.effects_note(FULL)
    # what set each interval's width: not known for a diagnosis from before the jackknife
    assert cap["width_text"] == "—" and visc["width_text"] == "—"
    lk = {**FULL["likelihood"], "interval_spread": {"clutch_slip": {"viscous": 2.5}},
          "interval_spread_noise": {"clutch_slip": {"viscous": 2.4}}}
    cap, visc = T.effect_rows(plain({**FULL, "likelihood": lk}))
    assert cap["width_text"] == "the ramps"  # the magnitude left out: the ramps sized it
    assert visc["width_text"] == "the points' jackknife, 2.5× the Laplace width (2.4× with the noise alone)"
    lk["interval_spread"]["clutch_slip"] = {"capacity": 0.8, "viscous": 1.0}
    assert [r["width_text"] for r in T.effect_rows(plain({**FULL, "likelihood": lk}))] == [
        "the Laplace covariance", "the Laplace covariance"]
    # no jackknife (a null ratio), a malformed entry: a dash, never "the ramps"
    lk["interval_spread"]["clutch_slip"] = {"capacity": None, "viscous": 3.0}
    del lk["interval_spread_noise"]
    cap, visc = T.effect_rows(plain({**FULL, "likelihood": lk}))
    assert cap["width_text"] == "—" and visc["width_text"] == "the points' jackknife, 3× the Laplace width"
    lk["interval_spread"]["clutch_slip"] = "x"
    assert {r["width_text"] for r in T.effect_rows(plain({**FULL, "likelihood": lk}))} == {"—"}
    assert ("width_text", "Width set by") in T.EFFECT_COLUMNS
    # the most probable model is "none": no effect, said so
    none = {**FULL, "posterior": {"none": 0.9, "clutch_slip": 0.1}, "effects": []}
    assert T.effect_rows(none) == [] and "calibrated model alone" in T.effects_note(none)


def test_detectability_states_the_direction_of_each_threshold_in_words():
    rows = {r["effect"]: r for r in T.detectability_rows(plain(FULL))}
    # the registry's order, whatever the document's
    assert list(rows) == ["clutch_slip", "turbine_drag", "pendulum_absorber", "nested_radial_transfer",
                          "transducer_bandwidth"]
    clutch, drag, pendulum = rows["clutch_slip"], rows["turbine_drag"], rows["pendulum_absorber"]
    assert (clutch["parameter"], clutch["unit"], clutch["bound"]) == ("capacity", "N m", "upper")
    assert clutch["meaning"] == "detectable below 430 N m" and clutch["threshold_text"] == "430"
    assert rows["transducer_bandwidth"]["meaning"] == "detectable below 180 Hz"
    assert (pendulum["parameter"], pendulum["unit"], pendulum["bound"]) == ("inertia", "kg m^2", "lower")
    assert pendulum["meaning"] == "detectable above 0.0007 kg m^2"
    assert rows["nested_radial_transfer"]["meaning"] == "detectable above 0.3"  # dimensionless: no unit
    assert rows["nested_radial_transfer"]["unit"] == "—"
    assert drag["threshold"] is None and not drag["detectable"]
    assert drag["meaning"] == "not detectable with this campaign" and drag["threshold_text"] == "—"
    assert T.detects_below("clutch_slip") and not T.detects_below("spring_preload") and T.detects_below("x") is None


def test_recommended_points_outliers_and_likelihood_summary():
    torsional, ramp = T.recommended_rows(plain(FULL))
    assert (torsional["kind"], torsional["speed_text"], torsional["torque_text"]) == ("torsional", "2500", "450")
    assert torsional["test"] == "orders 2:150" and torsional["reason"].startswith("separate clutch_slip")
    assert (ramp["kind"], ramp["test"], ramp["protocol"], ramp["orders"]) == ("ramp", "protocol pos-350-450",
                                                                            "pos-350-450", None)
    assert T.outliers(FULL) == ["map_900_50", "tc_1200"]
    assert T.outlier_text(FULL) == "Outliers (down-weighted by the robust loss): map_900_50, tc_1200."
    assert "No outliers" in T.outlier_text({**FULL, "outliers": []})
    assert T.likelihood_text(FULL) == ("Reduced χ² 1.13 on the held-out points, 0.97 on the training points "
                                       "(96 cells). Fitted output gain 1.002, delay 0.153 ms.")
    # which model and the noise level the verdict compares with, when the document says
    named = {**FULL, "likelihood": {**FULL["likelihood"], "model": "clutch_slip", "noise_level": 1.5}}
    assert T.likelihood_text(named).startswith("Reduced χ² of clutch_slip: 1.13 on the held-out points, 0.97 on the "
                                               "training points (96 cells); up to 1.5 is the noise level.")
    # a learning rate below 1 is said with the widening it means (1/sqrt(0.25) = 2); 1 is not said
    tempered = {**FULL, "likelihood": {**FULL["likelihood"], "learning_rate": 0.25}}
    assert T.likelihood_text(tempered).endswith("torsional evidence is read with every uncertainty widened 2× "
                                                "(learning rate 0.25).")
    assert "learning rate" not in T.likelihood_text({**FULL, "likelihood": {**FULL["likelihood"], "learning_rate": 1.0}})


def test_number_text_rounds_without_exponents_in_the_usual_range():
    assert [T.number_text(v) for v in (430.4, 0.0007, 12345.0, 0.0, -2.25, 1.234e-5)] == \
        ["430", "0.0007", "12300", "0", "-2.25", "1.23e-05"]
    assert T.number_text(0.0007, 3, "kg m^2") == "0.0007 kg m^2" and T.number_text(0.3, 3, "-") == "0.3"
    assert [T.number_text(v) for v in (None, float("nan"), float("inf"), "x", True)] == ["—"] * 5


# ----------------------------------------------------------------------------- documents without a model comparison
@pytest.mark.parametrize("doc, why", [
    (OLD, NOT_COMPUTED),
    (INSUFFICIENT, "Not computed: the campaign could not be diagnosed."),
], ids=["older-document", "insufficient-data"])
def test_documents_without_a_model_comparison_give_no_rows_and_say_why(doc, why):
    doc = plain(doc)
    assert T.posterior_rows(doc) == [] and T.effect_rows(doc) == [] and T.detectability_rows(doc) == []
    assert T.recommended_rows(doc) == [] and T.outliers(doc) == [] and T.most_probable(doc) is None
    assert T.outlier_text(doc) == "" and T.likelihood_text(doc) == ""
    assert T.not_computed_text(doc).startswith(why)
    secs = T.sections(doc)
    assert [s["id"] for s in secs] == ["posterior", "effects", "detectability", "next-points"]
    for s in secs:
        assert s["rows"] == [] and s["hint"] == "" and s["after"] == []
        assert len(s["notes"]) == 1 and s["notes"][0].startswith(why)


def test_malformed_values_show_a_dash_never_raise():
    bad = {"verdict": "unexplained", "posterior": {"none": "x", "turbine_drag": None, "clutch_slip": 0.5},
           "effects": [None, {"name": "not_an_effect", "parameters": {"a": "text"}, "intervals": {"a": [1]}},
                       {"name": "turbine_drag", "parameters": None, "intervals": {"coefficient": [1.0, None]}}],
           "detectability": {"not_an_effect": 3.0, "turbine_drag": "x"},
           "recommended_points": [None, {"kind": None, "speed_rpm": "fast"}], "outliers": "p1",
           "likelihood": {"nuisance": None, "log_evidence": [], "reduced_chi2_train": 2.0,
                          "interval_spread": {"turbine_drag": "x", "not_an_effect": {"a": "y"}}}}
    post = T.posterior_rows(bad)
    assert post[0]["model"] == "clutch_slip" and post[0]["most_probable"]
    assert post[0]["prior_text"] == "—" and post[0]["log_evidence_text"] == "—"
    assert {r["probability_text"] for r in post[1:]} == {"—"}
    eff = T.effect_rows(bad)
    assert [(r["effect"], r["parameter"], r["value_text"], r["interval_text"]) for r in eff] == [
        ("not_an_effect", "a", "text", "—"), ("turbine_drag", "coefficient", "—", "—")]
    assert [r["width_text"] for r in eff] == ["—", "—"]
    det = {r["effect"]: r for r in T.detectability_rows(bad)}
    assert det["turbine_drag"]["meaning"] == "not detectable with this campaign"
    assert det["not_an_effect"]["meaning"] == "threshold 3" and det["not_an_effect"]["bound"] is None
    rec = T.recommended_rows(bad)
    assert len(rec) == 1 and rec[0]["kind"] == "—" and rec[0]["speed_text"] == "—" and rec[0]["test"] == "—"
    assert T.outliers(bad) == [] and "— on the held-out points, 2 on the training points." in T.likelihood_text(bad)
    for doc in (None, [], "text", {}):
        assert all(s["rows"] == [] for s in T.sections(doc))


# ----------------------------------------------------------------------------- the HTML report
class _Diagnosis:
    """What the CLI passes: an object with ``to_json`` and the attributes the figures read."""

    def __init__(self, doc):
        self._doc = doc
        vars(self).update(vars(diagnosis_from_document(doc)))

    def to_json(self):
        return copy.deepcopy(self._doc)


def _table_after(page: str, heading: str) -> str:
    """The HTML from ``<h2>heading</h2>`` to the end of the table that follows it."""
    start = page.index(f"<h2>{heading}</h2>")
    return page[start:page.index("</table>", start)]


def test_the_html_report_holds_the_posterior_and_the_detectability_table():
    for diag in (diagnosis_from_document(plain(FULL)), _Diagnosis(plain(FULL))):
        page = T.report_html(diag, "fake")
        posterior = _table_after(page, "Model posterior")
        assert "<th>Posterior probability</th>" in posterior and "<th>Log evidence</th>" in posterior
        assert posterior.index("<td>clutch_slip</td>") < posterior.index("<td>turbine_drag</td>")
        assert "<td>81 %</td>" in posterior and "<td>-100.25</td>" in posterior
        assert "<td>none (calibrated model alone)</td>" in posterior
        assert html.escape(T.likelihood_text(FULL)) in page and "map_900_50, tc_1200" in page
        detect = _table_after(page, "Detectability with this campaign")
        assert "<td>detectable below 430 N m</td>" in detect and "<td>detectable above 0.0007 kg m^2</td>" in detect
        assert "<td>not detectable with this campaign</td>" in detect
        effects = _table_after(page, "Effects of the most probable model (90 % intervals)")
        assert "<td>480 – 546 N m</td>" in effects
        assert "<td>orders 2:150</td>" in _table_after(page, "Recommended next test points")
        assert page.count("plotly-graph-div") == 2  # gap and ranking; no per-point data in this document


@pytest.mark.parametrize("doc", [OLD, INSUFFICIENT], ids=["older-document", "insufficient-data"])
def test_the_html_report_of_a_document_without_a_model_comparison_still_renders(doc):
    page = T.report_html(diagnosis_from_document(plain(doc)), "old")
    assert "<h2>Model comparison</h2>" in page and page.count("Not computed") == 1
    assert "<table" not in page and not re.search(r"\bnan\b", page, re.IGNORECASE)
    assert "<b>Verdict:</b> " + doc["verdict"] in page
    # the rest is the report as before: the gap and ranking figures when there are gaps
    figures = 0 if doc["verdict"] == "insufficient_data" else 2
    assert page.count("plotly-graph-div") == figures
    assert plain_report_html(diagnosis_from_document(plain(doc)), "old").count("plotly-graph-div") == figures
    assert "Model comparison" not in plain_report_html(diagnosis_from_document(plain(doc)), "old")
