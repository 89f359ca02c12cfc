"""Discrepancy page: a campaign the diagnosis cannot take (too few valid torsional points,
all at one speed) is refused before anything runs, with what it lacks and what is
accepted, by the diagnosis's own rule (:func:`dampersim.discrepancy.diagnose.shortfall`);
a diagnosis with the verdict insufficient_data is shown with its message. Through the
callback functions, no browser; nothing here simulates."""

from __future__ import annotations

import json

import pytest

import app  # noqa: F401  (registers the pages)
from dampersim import views
from dampersim.discrepancy import drive
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.discrepancy.diagnose import diagnose
from dampersim.discrepancy.report import diagnosis_document
from pages import discrepancy as D
from tests.dashboard.test_discrepancy_page import as_json, folder_files, zip_upload
from tests.discrepancy import fake_rig as F

#: four valid torsional points at one set point speed (1510 rpm is 1500 rpm, measured):
#: enough points, which was all the page checked
ONE_SPEED = [("a", 1500.0, 100.0), ("b", 1500.0, 300.0), ("c", 1510.0, 200.0), ("d", 1500.0, 400.0)]
SPEED_TEXT = "all 4 torsional test points are at one speed (1500 rpm)"


@pytest.fixture
def no_diagnosis(monkeypatch):
    """Any model run or diagnosis is a test failure; a cache lookup finds nothing."""
    def refuse(*args, **kwargs):
        raise AssertionError("a campaign the diagnosis cannot take was run")

    monkeypatch.setattr(drive, "simulate_point", refuse)
    monkeypatch.setattr(views.discrepancy, "diagnose", refuse)
    monkeypatch.setattr(D, "discrepancy_view", lambda *a, cache_only=False, **k: None if cache_only else refuse())


def uploaded(tmp_path, points, name="one-speed") -> str:
    """The dropdown value of ``points`` written as a campaign, zipped and uploaded."""
    folder = tmp_path / name
    write_campaign(folder, [F.point(*p) for p in points], name=name)
    _options, value, notices = D.upload(zip_upload(folder_files(folder, f"{name}/")), f"{name}.zip", [])
    assert value.startswith(views.UPLOAD_PREFIX), as_json(notices)
    return value


def test_a_one_speed_campaign_is_refused_before_anything_runs(cache_dir, tmp_path, no_diagnosis):
    value = uploaded(tmp_path, ONE_SPEED)
    upload_id = value[len(views.UPLOAD_PREFIX):]
    summary = views.campaign_summary(views.upload_folder(upload_id))
    assert summary["torsional"] == 4 and not summary["ready"] and summary["missing"] == ["speeds"]
    assert SPEED_TEXT in summary["message"]
    # the validation report says what is missing and what is accepted
    report = as_json(D.report_for(value))
    assert "notice-error" in report and f"This campaign cannot be diagnosed: {SPEED_TEXT}" in report
    assert "at 2 or more speeds" in report
    # neither Run nor a link starts it; the status says why
    for run, initial, autorun in ((True, False, False), (False, True, True)):
        out = D.request(run, initial, [value], None, autorun)
        status = as_json(out["status"])
        assert "job" not in out and "hit" not in out
        assert SPEED_TEXT in status and "Accepted: at least 3" in status and "Nothing was run" in status
    # a job sent anyway is refused by the same rule, before any work
    done = D.job({"state": {"campaign": None, "upload": upload_id}}, lambda *a: None)
    assert SPEED_TEXT in done["error"]


def test_too_few_points_are_refused_with_the_diagnosis_message(cache_dir, tmp_path, no_diagnosis):
    value = uploaded(tmp_path, [("a", 1000.0, 100.0), ("b", 1600.0, 200.0)], name="two-points")
    out = D.request(True, False, [value], None, False)
    status = as_json(out["status"])
    assert "job" not in out and "only 2 valid torsional test point(s) (a, b)" in status
    assert "only 2 valid torsional test point(s)" in as_json(D.report_for(value))


def test_a_diagnosis_of_insufficient_data_is_shown_with_its_message(monkeypatch):
    # failed model runs can leave too few points after the page's check: the verdict says so
    monkeypatch.setattr(drive, "simulate_point", F.fake_model(lambda s, p: "raise" if p.id != "p0" else None))
    diag = diagnose(F.campaign([F.point(*p) for p in F.POINTS]), workers=1, recommend=False)
    doc = json.loads(json.dumps(diagnosis_document(diag)))  # plain JSON, as from the cache
    assert doc["verdict"] == "insufficient_data" and doc["missing"] == ["torsional_points"]
    cards, verdict, ranking, *figs, doc_text = D.render({"diagnosis": doc, "campaign": {"name": "fake"}, "summary": {}})
    text = as_json(verdict)
    assert "Insufficient data" in text and "Unexplained" not in text
    assert "only 1 valid torsional test point(s) (p0)" in text and "left out because the model run failed" in text
    assert "insufficient data" in as_json(cards)
    assert all(not f["data"] for f in figs)  # no numbers to draw: empty figures with a note
