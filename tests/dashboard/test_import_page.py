"""Importing a rig recording on the Discrepancy page: the preview of an uploaded recording
(mapping report, proposed cuts), the campaign created from reviewed cuts and selected in
the campaign dropdown, and the refusals (bad files, over-size uploads, invalid row edits,
forged upload ids), through the view functions, the page's callback functions and Dash's
HTTP endpoint (no browser).

The recording is the library's synthetic rig run (27 s: four torque plateaus and one
torque ramp; channels at 2000 and 500 Hz), written as MDF4 and as CSV once per module.
"""

from __future__ import annotations

import base64
import json
import os

import pandas as pd
import pytest
from dash import no_update

import app  # noqa: F401  (registers the pages)
from dampersim import views
from dampersim.discrepancy.campaign import read_campaign
from dampersim.errors import InputError
from dampersim.rigdata.examples import long_recording_channels, write_recording
from dampersim.views import rigdata as R
from pages import discrepancy as D
from tests.dashboard.test_callbacks import find
from tests.dashboard.test_discrepancy_page import EXAMPLE, as_json, background_call
from tests.dashboard.test_http import DashClient

OPTIONS = [{"label": f"example: {EXAMPLE}", "value": EXAMPLE}]


def data_url(data: bytes) -> str:
    """Bytes -> the data URL a dcc.Upload delivers."""
    return "data:application/octet-stream;base64," + base64.b64encode(data).decode()


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """The synthetic rig run as browser uploads: {"mdf4": data URL, "csv": data URL,
    "nospeed": a CSV without the input speed channel}."""
    root = tmp_path_factory.mktemp("recordings")
    channels = long_recording_channels()
    out = {}
    for fmt, name in (("mdf4", "rig-run.mf4"), ("csv", "rig-run.csv")):
        out[fmt] = data_url(open(write_recording(root / name, channels, fmt), "rb").read())
    nospeed = {k: v for k, v in channels.items() if k != "n_In"}
    out["nospeed"] = data_url(open(write_recording(root / "nospeed.csv", nospeed, "csv"), "rb").read())
    return out


def listed(cache) -> dict:
    """What the cache holds: staged recordings and campaign uploads (entries of each folder)."""
    out = {}
    for sub in (R.STAGING_SUBDIR, views.UPLOADS_SUBDIR):
        folder = cache / sub
        out[sub] = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    return out


def previewed(contents, filename, staged=None):
    """The page's preview callback, unpacked by output name."""
    staged, style, report, rows, dropped, disabled, create_notices, notices = D.preview_recording(contents, filename,
                                                                                                  staged)
    return {"staged": staged, "style": style, "report": report, "rows": rows, "dropped": dropped, "disabled": disabled,
            "create_notices": create_notices, "notices": notices}


def edited(rows):
    """The review of the tests: p003 deleted, p001 ends at 3.0 s instead of 3.992 s."""
    out = [dict(r) for r in rows if r["id"] != "p003"]
    out[0]["end_s"] = 3.0
    return out


# ----------------------------------------------------------------------------- layout
def test_layout_has_the_import_panel_hidden_until_a_preview():
    lay = D.layout()
    for cid in ("discrepancy-import-upload", "discrepancy-import-cuts", "discrepancy-import-create",
                "discrepancy-import-notices", "discrepancy-import-staged", "discrepancy-upload"):
        assert find(lay, cid) is not None, cid
    assert find(lay, "discrepancy-import-card").style == {"display": "none"}
    table = find(lay, "discrepancy-import-cuts")
    editable = {c["id"] for c in table.columns if c.get("editable")}
    assert editable == {"kind", "start_s", "end_s"} and table.row_deletable is True
    assert "python -m dampersim import FILE --out CAMPAIGN" in as_json(lay)  # larger files: the command line


# ----------------------------------------------------------------------------- preview
@pytest.mark.parametrize("fmt, filename", [("mdf4", "rig-run.mf4"), ("csv", "rig-run.csv")])
def test_preview_lists_the_mapping_and_five_cuts(cache_dir, recordings, fmt, filename):
    out = previewed(recordings[fmt], filename)
    assert out["style"] == {} and out["disabled"] is False and out["create_notices"] == []
    assert "notice-success" in as_json(out["notices"]) and filename in as_json(out["notices"])
    rows = out["rows"]
    assert [r["kind"] for r in rows] == ["torsional"] * 3 + ["ramp", "torsional"]  # 4 plateaus, 1 torque ramp
    assert [r["id"] for r in rows] == ["p001", "p002", "p003", "p004", "p005"]
    assert set(rows[0]) == set(R.CUT_FIELDS) and all(r["start_s"] < r["end_s"] for r in rows)
    assert [round(r["speed_rpm"], -2) for r in rows] == [1000, 1500, 2000, 1200, 1800]
    report = as_json(out["report"])
    for line in ("input_torque_nm <- 'Trq_In'", "kN m -> N m x 1000", "output_speed_rpm <- 'Speed_Out'",
                 "windup_deg <- 'Windup_Angle'", "5 test points found", "proposed: 5 test points (4 torsional, 1 ramp)"):
        assert line in report, line
    assert str(cache_dir) not in report + as_json(out["notices"])  # the server's folders are not shown
    # the view: the same preview, the file kept under a safe name in its own staging folder
    preview = R.stage_recording(recordings[fmt], "../../" + filename)
    assert preview["id"] == out["staged"]["id"] and preview["cuts"] == rows and preview["file"] == filename
    assert (cache_dir / R.STAGING_SUBDIR / preview["id"] / filename).is_file()
    assert listed(cache_dir)[R.STAGING_SUBDIR] == [preview["id"]] and listed(cache_dir)[views.UPLOADS_SUBDIR] == []


def test_file_names_are_reduced_to_a_safe_base_name():
    assert R.safe_file_name("../../etc/passwd") == "passwd"
    assert R.safe_file_name("C:\\data\\run 7 (final).mf4") == "run_7__final_.mf4"
    assert R.safe_file_name(".hidden.csv") == "hidden.csv"
    assert R.safe_file_name("..") == "recording" and R.safe_file_name(None) == "recording"
    assert len(R.safe_file_name("x" * 300 + ".mf4")) == 100 and R.safe_file_name("x" * 300 + ".mf4").endswith(".mf4")


# ----------------------------------------------------------------------------- confirm
def test_reviewed_cuts_create_a_campaign_selected_in_the_dropdown(cache_dir, recordings):
    out = previewed(recordings["mdf4"], "rig-run.mf4")
    options, value, notices = D.create_campaign(1, out["staged"], edited(out["rows"]), OPTIONS)
    assert value.startswith(views.UPLOAD_PREFIX) and options[0] == OPTIONS[0] and options[-1]["value"] == value
    assert "rig-run" in options[-1]["label"] and "rig-run.mf4" in options[-1]["label"]
    text = as_json(notices)
    assert "notice-success" in text and "4 test points (3 torsional, 1 ramp)" in text
    upload_id = value[len(views.UPLOAD_PREFIX):]
    folder = views.upload_folder(upload_id)
    camp = read_campaign(folder, strict=True)  # a complete, valid campaign
    assert [p.id for p in camp.points] == ["p001", "p002", "p004", "p005"]
    assert [p.kind for p in camp.points] == ["torsional", "torsional", "ramp", "torsional"]
    man = pd.read_csv(folder / "manifest.csv").set_index("id")
    assert man.loc["p001", "end_s"] == 3.0 and man.loc["p002", "end_s"] == out["rows"][1]["end_s"]
    assert set(man["source_file"]) == {"rig-run.mf4"}
    assert abs(camp.points[0].duration - 3.0) < 0.01
    # the page treats it like an uploaded zip: validation report, link, run request
    assert "4 of 4 test points valid" in as_json(D.report_for(value))
    state, link_notices = views.parse_discrepancy_query({"upload": upload_id}, views.example_campaigns())
    assert state["upload"] == upload_id and link_notices == []
    assert D.request(False, False, [value], None, False)["search"] == f"?upload={upload_id}"
    lay = D.layout(upload=upload_id)
    assert find(lay, "discrepancy-campaign").value == value
    assert any(o["value"] == value for o in find(lay, "discrepancy-campaign").options)
    # the same cuts again: the same campaign, selected, nothing new written
    before = listed(cache_dir)
    again = D.create_campaign(2, out["staged"], edited(out["rows"]), options)
    assert again[1] == value and "imported before" in as_json(again[2]) and listed(cache_dir) == before
    assert before[views.UPLOADS_SUBDIR] == [upload_id, f"{upload_id}.json"]  # no scratch folders left behind


def test_a_cut_too_short_is_left_out_with_a_warning(cache_dir, recordings):
    preview = R.stage_recording(recordings["csv"], "rig-run.csv")
    rows = [dict(r) for r in preview["cuts"]]
    rows[2]["end_s"] = rows[2]["start_s"] + 0.1  # shorter than the order analysis needs
    out = R.confirm_import(preview["id"], rows)
    assert len(out["points"]) == 4 and "p003" not in [p["id"] for p in out["points"]]
    warn = [n["text"] for n in out["notices"] if n["level"] == "warning"]
    assert len(warn) == 1 and warn[0].startswith("Cut p003 (torsional") and "shorter" in warn[0]
    assert str(cache_dir) not in json.dumps(out)
    read_campaign(views.upload_folder(out["upload"]), strict=True)


# ----------------------------------------------------------------------------- refusals
BAD_UPLOADS = [
    ("garbage", "garbage.mf4", ["unknown format", "accepted is ASAM MDF 4.x"]),
    ("not-base64", "run.mf4", ["not valid base64", "accepted is one rig recording"]),
    ("empty", "empty.tdms", ["is empty", "accepted is one rig recording"]),
    ("oversize", "huge.mf4", ["is 10.0 MB; accepted is a recording of up to 10 MB", "python -m dampersim import FILE --out CAMPAIGN"]),
    ("nospeed", "nospeed.csv", ["input_speed_rpm", "python -m dampersim import FILE --map MAP.toml"]),
    ("no-content", "weird.mf4", ["arrived without content"]),
]


def _bad_contents(kind, recordings):
    if kind == "garbage":
        return data_url(os.urandom(4096))
    if kind == "not-base64":
        return "data:application/octet-stream;base64,@@not-base64@@"
    if kind == "empty":
        return "data:application/octet-stream;base64,"
    if kind == "oversize":
        return data_url(b"\0" * (R.MAX_RECORDING_BYTES + 1))
    if kind == "nospeed":
        return recordings["nospeed"]
    return "no data url"


@pytest.mark.parametrize("kind, filename, expect", BAD_UPLOADS, ids=[b[0] for b in BAD_UPLOADS])
def test_bad_uploads_are_refused_with_a_notice(cache_dir, recordings, kind, filename, expect):
    out = previewed(_bad_contents(kind, recordings), filename)
    text = as_json(out["notices"])
    assert "notice-error" in text and "The recording was refused" in text and filename in text, text
    assert "accepted" in text
    for e in expect:
        assert e in text, e
    # nothing on the page changes but the notice: a recording under review stays under review
    assert all(out[k] is no_update for k in ("staged", "style", "report", "rows", "dropped", "disabled",
                                             "create_notices"))
    assert str(cache_dir) not in text
    assert listed(cache_dir) == {R.STAGING_SUBDIR: [], views.UPLOADS_SUBDIR: []}  # nothing kept, nothing listed


def test_a_refused_recording_keeps_the_review_of_the_one_before(cache_dir, recordings):
    good = previewed(recordings["mdf4"], "rig-run.mf4")
    bad = previewed(recordings["nospeed"], "nospeed.csv", good["staged"])
    assert bad["staged"] is no_update and bad["rows"] is no_update and bad["style"] is no_update
    text = as_json(bad["notices"])
    assert "The recording was refused" in text and "The review of rig-run.mf4 on the right stays as it was" in text
    options, value, _ = D.create_campaign(1, good["staged"], good["rows"], OPTIONS)  # still importable
    assert value.startswith(views.UPLOAD_PREFIX)


def test_the_preview_callback_gives_the_same_outcome_as_the_plain_function(cache_dir, recordings):
    progress = []
    data = {"contents": recordings["csv"], "filename": "rig-run.csv"}
    out = D.preview_recording_cb(progress.append, data, None)
    assert as_json(out) == as_json(D.preview_recording(recordings["csv"], "rig-run.csv"))
    assert out[0]["file"] == "rig-run.csv" and len(out[3]) == 5
    assert progress == [(None, None, "reading rig-run.csv and proposing cuts…")]
    assert D.preview_recording_cb(progress.append, None, out[0]) == (no_update,) * D.IMPORT_PREVIEW_OUTPUTS


@pytest.mark.parametrize("edit, expect", [
    (lambda rows: rows[0].update(end_s=rows[0]["start_s"]), ["cut row 1 (p001) [end_s]", "0 <= start_s < end_s"]),
    (lambda rows: rows[1].update(kind="sideways"), ["cut row 2 (p002) [kind]", "accepted is torsional or ramp"]),
    (lambda rows: rows[2].update(start_s="abc"), ["cut row 3 (p003) [start_s]", "'abc' is not a number"]),
    (lambda rows: rows[3].update(end_s=None), ["cut row 4 (p004) [end_s]", "is empty"]),
    (lambda rows: rows[0].update(start_s=-1), ["cut row 1 (p001) [start_s]", "negative"]),
    (lambda rows: rows[4].update(id="../../evil"), ["cut row 5 (../../evil) [id]", "accepted is a point id"]),
    (lambda rows: rows[4].update(id="p001"), ["cut row 5 (p001) [id]", "given twice"]),
    (lambda rows: rows.clear(), ["no cuts left"]),
    (lambda rows: [r.update(end_s=r["start_s"] + 0.05) for r in rows],
     ["no test point could be cut with these cuts", "dropped ramp 15.37-15.42 s", "shorter than the order analysis"]),
])
def test_invalid_row_edits_are_refused_naming_row_and_field(cache_dir, recordings, edit, expect):
    out = previewed(recordings["mdf4"], "rig-run.mf4")
    rows = [dict(r) for r in out["rows"]]
    edit(rows)
    options, value, notices = D.create_campaign(1, out["staged"], rows, OPTIONS)
    text = as_json(notices)
    assert options is no_update and value is no_update  # the chosen campaign stays
    assert "notice-error" in text and "The campaign was not created" in text
    for e in expect:
        assert e in text, e
    assert listed(cache_dir)[views.UPLOADS_SUBDIR] == []


def test_forged_or_unknown_upload_ids_are_refused(cache_dir, recordings):
    rows = R.stage_recording(recordings["mdf4"], "rig-run.mf4")["cuts"]
    for forged in ("../../etc", "DB607A86DE489DD5", "zz", None, 12):
        with pytest.raises(InputError, match="is not an upload id"):
            R.confirm_import(forged, rows)
    with pytest.raises(InputError, match="is not on this server"):
        R.confirm_import("0123456789abcdef", rows)
    options, value, notices = D.create_campaign(1, {"id": "../../x"}, rows, OPTIONS)
    assert value is no_update and "is not an upload id" in as_json(notices)
    assert D.create_campaign(1, None, rows, OPTIONS)[2] and D.create_campaign(0, None, rows, OPTIONS)[2] is no_update
    assert listed(cache_dir)[views.UPLOADS_SUBDIR] == []


# ----------------------------------------------------------------------------- over HTTP
def test_preview_and_create_over_http(cache_dir, recordings):
    """The preview runs as a job of the job queue (fork server, job process importing app),
    the campaign is created in the request thread from what the job staged."""
    dc = DashClient(app.app)
    resp, _progress = background_call(dc, "discrepancy-import-staged.data", {"discrepancy-import-upload-data.data": {
        "contents": recordings["mdf4"], "filename": "rig-run.mf4"}}, ["discrepancy-import-upload-data.data"])
    staged, rows = resp["discrepancy-import-staged"]["data"], resp["discrepancy-import-cuts"]["data"]
    assert len(rows) == 5 and staged["file"] == "rig-run.mf4"
    values = {"discrepancy-import-create.n_clicks": 1, "discrepancy-import-staged.data": staged,
              "discrepancy-import-cuts.data": edited(rows), "discrepancy-campaign.options": OPTIONS}
    r = dc.call("discrepancy-campaign.value@", values, changed=["discrepancy-import-create.n_clicks"])
    assert r.status_code == 200, r.data[:500]
    resp = r.get_json()["response"]
    value = resp["discrepancy-campaign"]["value"]
    assert value.startswith(views.UPLOAD_PREFIX) and resp["discrepancy-campaign"]["options"][-1]["value"] == value
    assert "4 test points" in json.dumps(resp["discrepancy-import-create-notices"])
    read_campaign(views.upload_folder(value[len(views.UPLOAD_PREFIX):]), strict=True)
