"""Discrepancy: run the discrepancy workflow of :mod:`dampersim.discrepancy` on a measured
campaign (a bundled example, an uploaded zip or an imported rig recording) and show what
the model misses: the verdict and the named effect, the ranking of candidate effects, the
posterior over the models with the fitted effects' 90 % intervals, what the campaign can
detect and the test points to measure next, the held-out gap at each stage against the
noise floor, where the error lies and the order amplitudes of the held-out points. Layout
and callbacks only; data and figures come from :mod:`dampersim.views`, the model
comparison's tables from :mod:`dampersim.discrepancy.report_tables`.

A rig recording (MDF4, TDMS, MAT, CSV) uploaded in "Import a rig recording" is previewed
(channel mapping, proposed cuts in an editable table) and, on "Create campaign", imported
with the reviewed cuts (:mod:`dampersim.views.rigdata`); the new campaign is then selected
like an uploaded zip.

Checking an uploaded zip, previewing a recording and the validation report of the chosen
campaign read files of up to 10 MB and run off the request thread: background callbacks
through the dashboard's job queue (:func:`pages._uploads.background_check`), with a
"checking" line while they run. The upload reaches the job only as the callback's
argument. A refused or failed check changes nothing that was uploaded before: the
campaign list, the chosen campaign and a recording under review stay.

URL keys: ``campaign`` (a bundled example's folder name) or ``upload`` (the id of a
campaign uploaded to this server).
"""

from __future__ import annotations

import time

import dash
from dash import Input, Output, State, callback, dash_table, dcc, html, no_update

from dampersim.discrepancy.upload import MAX_CAMPAIGN_ZIP_BYTES
from dampersim.errors import DampersimError, InputError
from dampersim.incidents import public_message
from dampersim.views.discrepancy import (
    CAMPAIGN_ACCEPTED,
    UPLOAD_PREFIX,
    campaign_summary,
    diagnosis_admission,
    discrepancy_choice,
    discrepancy_key,
    discrepancy_query,
    discrepancy_value,
    discrepancy_view,
    example_campaigns,
    not_ready_text,
    parse_discrepancy_query,
    unpack_campaign_zip,
    upload_in_use,
    upload_label,
)
from dampersim.views.notices import notice
from dampersim.views.rigdata import IMPORT_COMMAND, KINDS, MAX_RECORDING_BYTES, RECORDING_ACCEPTED, confirm_import, stage_recording
from dampersim.views.sweeps import SweepRegistry
from pages import _diagnosis_tables as T, _frame as F, _jobs as J, _uploads as U, _widgets as W
from pages._background import job_error_text
from pages._diagnosis_view import render

PAGE = "discrepancy"

dash.register_page(__name__, path="/discrepancy", name="Discrepancy", title="Discrepancy · dampersim", order=9)

# files above the page's limits are refused in the browser and never posted
CAMPAIGN_SIZE_CHECK = U.size_checked_upload(
    "discrepancy-upload", MAX_CAMPAIGN_ZIP_BYTES,
    "Diagnose a larger campaign folder on the server's command line: python -m dampersim diagnose CAMPAIGN.")
RECORDING_SIZE_CHECK = U.size_checked_upload(
    "discrepancy-import-upload", MAX_RECORDING_BYTES,
    f"Import a larger recording on the server's command line ({IMPORT_COMMAND}), then diagnose it with "
    "python -m dampersim diagnose CAMPAIGN.")

def _options(examples: dict, state: dict) -> list:
    opts = [{"label": f"example: {name}", "value": name} for name in examples]
    if state.get("upload"):
        opts.append({"label": upload_label(state["upload"]), "value": UPLOAD_PREFIX + state["upload"]})
    return opts


IMPORT_COLUMNS = [
    {"id": "id", "name": "Point", "editable": False},
    {"id": "kind", "name": "Kind", "presentation": "dropdown", "editable": True},
    {"id": "speed_rpm", "name": "Speed [rpm]", "type": "numeric", "editable": False},
    {"id": "mean_torque_nm", "name": "Mean torque [N m]", "type": "numeric", "editable": False},
    {"id": "start_s", "name": "Start [s]", "type": "numeric", "editable": True},
    {"id": "end_s", "name": "End [s]", "type": "numeric", "editable": True},
]
HIDDEN = {"display": "none"}


def import_card():
    """The review of an uploaded rig recording: the mapping report, the cuts as an editable
    table and the "Create campaign" button (hidden until a recording was previewed)."""
    table = dash_table.DataTable(
        id="discrepancy-import-cuts", columns=IMPORT_COLUMNS, data=[], editable=True, row_deletable=True,
        dropdown={"kind": {"options": [{"label": k, "value": k} for k in KINDS], "clearable": False}},
        style_cell={"fontFamily": "inherit", "fontSize": "13px", "padding": "2px 6px"},
        style_header={"fontWeight": 600},
        style_data_conditional=[{"if": {"column_editable": False}, "backgroundColor": "#f5f6f8", "color": "#4b5563"}])
    return html.Div([
        html.Div("Import a rig recording: review the cuts", className="card-title"),
        html.Div([
            html.Div(id="discrepancy-import-report"),
            html.P("Edit kind, start and end [s from the start of the recording] in the table, or delete rows with ×; "
                   "speed and mean torque are those of the proposed cut. Create campaign imports the recording with "
                   "these cuts and selects the new campaign in the campaign list.", className="hint"),
            table,
            html.Div(id="discrepancy-import-dropped"),
            html.Div(html.Button("Create campaign", id="discrepancy-import-create", n_clicks=0, disabled=True,
                                 className="btn btn-primary"), className="buttons"),
            html.Div(id="discrepancy-import-create-notices", className="notices"),
        ], className="card-body"),
    ], id="discrepancy-import-card", className="card card-wide", style=HIDDEN)


def layout(**query):
    examples = example_campaigns()
    state, notices = parse_discrepancy_query(query, examples)
    # a shared link to a campaign starts its diagnosis (as on the other pages), unless a
    # value of the link was refused and replaced
    autorun = any(k in query for k in ("campaign", "upload")) and not any(n["level"] == "warning" for n in notices)
    controls = [
        W.section("Campaign", [
            W.control("Campaign", dcc.Dropdown(id="discrepancy-campaign", options=_options(examples, state),
                                               value=discrepancy_value(state), clearable=False, className="dropdown",
                                               placeholder="upload a campaign"),
                      cid="discrepancy-campaign", hint="A bundled example, or a campaign uploaded below."),
            W.control("Upload a campaign", dcc.Upload(
                id="discrepancy-upload", children=html.Div(["Drop a campaign .zip here or ", html.A("choose one")]),
                className="upload", multiple=False, accept=".zip,application/zip"),
                hint=f"Accepted: {CAMPAIGN_ACCEPTED}."),
            *U.components("discrepancy-upload"),
            U.checking("discrepancy-upload", "Checking the zip on the server: its entries, the manifest and the size "
                                             "of every test point (nothing is loaded before that)."),
            html.Div(id="discrepancy-upload-notices", className="notices"),
        ]),
        W.section("Import a rig recording", [
            W.control("Rig recording", dcc.Upload(
                id="discrepancy-import-upload", children=html.Div(["Drop one recording here or ", html.A("choose one")]),
                className="upload", multiple=False, accept=".mf4,.mdf,.tdms,.mat,.csv,.txt"),
                hint=f"Accepted: {RECORDING_ACCEPTED}. The channel mapping and the proposed cuts are shown on the "
                     "right for review before anything is created."),
            *U.components("discrepancy-import-upload"),
            U.checking("discrepancy-import-upload", "Reading the recording on the server: its channels, their mapping "
                                                    "and the cuts it proposes."),
            html.Div(id="discrepancy-import-notices", className="notices"),
        ]),
        W.run_panel(PAGE, "Run diagnosis"),
        W.section("How it works", [html.P(
            "Every measured input torque drives the model (default parameter set); the estimated parameters are "
            "calibrated on two thirds of the torsional points; each candidate effect is screened, the best few are "
            "fitted, and all are judged on the held-out third, which no fit ever sees. Gaps are RMS errors of the "
            "output order amplitudes 1-8.", className="hint")], open_=False),
    ]
    content = [
        *J.background_header(PAGE),
        html.Div([
            import_card(),
            W.card("Campaign validation", html.Div([
                U.checking("discrepancy-report", "Checking the campaign: every manifest row and every file."),
                html.Div(id="discrepancy-report")]), wide=True),
            W.card("Verdict", html.Div(html.P("No diagnosis shown yet: press Run diagnosis.", className="hint"),
                                       id="discrepancy-verdict"), wide=True),
            W.card("Held-out gap at each stage", W.graph("discrepancy-gap", 360, "No diagnosis shown yet")),
            W.card("Candidate effects: held-out gap", W.graph("discrepancy-ranking-fig", 360, "No diagnosis shown yet")),
            W.card("Ranking of the candidate effects", html.Div(id="discrepancy-ranking"), wide=True),
            *T.cards(),
            W.card("Where the model disagrees (diamonds: held-out points)",
                   W.graph("discrepancy-map", 380, "No diagnosis shown yet"), wide=True),
            W.card(None, W.graph("discrepancy-profile", 360, "No diagnosis shown yet"), wide=True),
            W.card("Held-out points: measured against the model as given and the final model",
                   W.graph("discrepancy-overlays", None, "No diagnosis shown yet"), wide=True),
            W.card(None, html.Details([html.Summary("Diagnosis document (JSON)"), html.Pre(id="discrepancy-json")]), wide=True),
        ], className="cards"),
    ]
    return F.page_frame(PAGE, "Discrepancy", "Where model and measurement disagree, which physical effect the model is "
                        "missing, and how much of the gap adding it closes on test points that no fit has seen.",
                        controls, content, notices,
                        [*J.background_stores(PAGE, None, autorun), dcc.Store(id="discrepancy-import-staged", data=None)])


F.register_link_callbacks(PAGE)


# --------------------------------------------------------------------------- upload and validation
def upload(contents, filename, options):
    """An uploaded zip -> (dropdown options, dropdown value, notices). A refused upload
    changes nothing and says what was wrong and what is accepted."""
    if not contents:
        return no_update, no_update, []
    try:
        upload_id = unpack_campaign_zip(contents, filename)
    except DampersimError as exc:
        return no_update, no_update, W.render_notices([notice(f"The upload was refused: {public_message(exc)}", "error")])
    except Exception as exc:  # never let a strange file take the page down
        return no_update, no_update, W.render_notices([notice(
            f"The upload was refused: {filename or 'the file'} could not be read ({public_message(exc, 'campaign upload')}); "
            f"accepted is {CAMPAIGN_ACCEPTED}", "error")])
    value = UPLOAD_PREFIX + upload_id
    options = [o for o in (options or []) if o.get("value") != value] + [{"label": upload_label(upload_id), "value": value}]
    text = f"{filename or 'The zip'} was unpacked; its validation report is shown on the right."
    return options, value, W.render_notices([notice(text, "success")])


# --------------------------------------------------------------------------- rig recording import
def report_list(lines):
    """Import report lines as a nested list: a file's line, its indented lines under it."""
    items, sub = [], None
    for line in lines or ():
        if line.startswith("  ") and sub is not None:
            sub.append(html.Li(line.strip()))
            continue
        sub = []
        items.append(html.Li([line, html.Ul(sub)]))
    return html.Ul(items, className="import-report")


def dropped_table(dropped):
    """Cuts the import could not use, with the reason (nothing when none was dropped)."""
    if not dropped:
        return []
    return [html.P(f"{len(dropped)} proposed cut(s) could not be used:", className="hint"),
            W.table([("kind", "Kind"), ("start_s", "Start [s]"), ("end_s", "End [s]"), ("reason", "Reason")], dropped,
                    cid="discrepancy-import-dropped-table")]


IMPORT_PREVIEW_OUTPUTS = 8


def _review_kept(staged) -> str:
    """" The review of X on the right stays as it was." when a recording is under review."""
    if isinstance(staged, dict) and isinstance(staged.get("file"), str) and staged.get("id"):
        return f" The review of {staged['file'][:200]} on the right stays as it was."
    return ""


def preview_recording(contents, filename, staged=None):
    """An uploaded recording -> (staged upload {"id", "file"}, card style, report, cut rows,
    dropped cuts, Create button disabled, Create notices (cleared), notices). A refused
    recording says what was wrong and what is accepted and keeps nothing of that file; the
    recording already under review (``staged``) and its edited cuts stay as they were."""
    if not contents:
        return (no_update,) * IMPORT_PREVIEW_OUTPUTS
    name = filename or "the file"
    kept = (no_update,) * (IMPORT_PREVIEW_OUTPUTS - 1)
    try:
        preview = stage_recording(contents, filename)
    except DampersimError as exc:
        return (*kept, W.render_notices([notice(
            f"The recording was refused: {public_message(exc)}.{_review_kept(staged)}", "error")]))
    except Exception as exc:  # a file the readers did not foresee: say so, keep serving
        return (*kept, W.render_notices([notice(
            f"The recording was refused: {name} could not be read ({public_message(exc, 'recording upload')}); "
            f"accepted is {RECORDING_ACCEPTED}.{_review_kept(staged)}", "error")]))
    text = (f"{name} was read: {len(preview['cuts'])} proposed cut(s). Review them on the right, then press "
            "Create campaign.")
    level = "success" if preview["cuts"] else "warning"
    return ({"id": preview["id"], "file": preview["file"]}, {}, report_list(preview["report"]), preview["cuts"],
            dropped_table(preview["dropped"]), not preview["cuts"], [], W.render_notices([notice(text, level)]))


def create_campaign(n_clicks, staged, rows, options):
    """"Create campaign" -> (dropdown options, dropdown value, notices): the reviewed cuts
    imported as a new campaign, which is added to the dropdown and selected. A refused
    row, an unknown upload or a failed import changes nothing and says why."""
    if not n_clicks:
        return no_update, no_update, no_update
    if not isinstance(staged, dict) or not staged.get("id"):
        return no_update, no_update, W.render_notices([notice("Upload a rig recording first.", "info")])
    try:
        out = confirm_import(staged["id"], rows)
    except DampersimError as exc:
        return no_update, no_update, W.render_notices([notice(f"The campaign was not created: {public_message(exc)}",
                                                              "error")])
    except Exception as exc:  # reported on the page, never raised into Dash
        return no_update, no_update, W.render_notices([notice(
            f"The campaign was not created: {public_message(exc, 'campaign import')}", "error")])
    value = out["value"]
    options = [o for o in (options or []) if o.get("value") != value] + [{"label": out["label"], "value": value}]
    return options, value, W.render_notices(out["notices"])


@callback(
    Output("discrepancy-campaign", "options", allow_duplicate=True),
    Output("discrepancy-campaign", "value", allow_duplicate=True),
    Output("discrepancy-import-create-notices", "children"),
    Input("discrepancy-import-create", "n_clicks"),
    State("discrepancy-import-staged", "data"),
    State("discrepancy-import-cuts", "data"),
    State("discrepancy-campaign", "options"),
    prevent_initial_call=True,
)
def create_campaign_cb(n_clicks, staged, rows, options):
    return create_campaign(n_clicks, staged, rows, options)


def report(summary: dict):
    """The validation report of a campaign (see campaign_summary) as page content; a
    campaign the diagnosis cannot take says what it lacks and what is accepted."""
    if summary.get("error"):
        return W.render_notices([notice(f"This campaign cannot be read: {public_message(InputError(summary['error']))}. "
                                        f"Accepted is {CAMPAIGN_ACCEPTED}.", "error")])
    head = html.P([html.B(summary["name"]), f": {summary['valid']} of {summary['rows']} test points valid "
                   f"({summary['torsional']} torsional, {summary['ramps']} ramps)."
                   + (f" {summary['description']}" if summary.get("description") else "")])
    notes = []
    if summary["problems"]:
        notes.append(notice(f"{len(summary['problems'])} problem(s) found: the test points concerned are left out "
                            "of the diagnosis.", "warning"))
    else:
        notes.append(notice("No problems found.", "success"))
    if not summary["ready"]:
        notes.append(notice(f"This campaign cannot be diagnosed: {not_ready_text(summary)}", "error"))
    out = [head, *W.render_notices(notes)]
    if summary["problems"]:
        out.append(W.table([("file", "File"), ("field", "Field"), ("point", "Point"), ("message", "Problem")],
                           summary["problems"], cid="discrepancy-problems"))
    return out


def report_for(value):
    examples = example_campaigns()
    _state, _notices, folder = discrepancy_choice(value, examples)  # refused values: notices come from the request
    if folder is None:
        return W.render_notices([notice("No campaign chosen: pick an example or upload a campaign.", "info")])
    try:
        return report(campaign_summary(folder))
    except Exception as exc:  # a campaign the reader did not foresee: say so, keep serving
        return W.render_notices([notice(f"This campaign cannot be read ({job_error_text(exc)}); "
                                        f"accepted is {CAMPAIGN_ACCEPTED}.", "error")])


# --------------------------------------------------------------------------- checks off the request thread
def upload_failed(exc):
    """A campaign upload whose check did not finish (its job died, was stopped or failed
    unexpectedly): the campaign list and the chosen campaign stay; the page says so."""
    return no_update, no_update, W.render_notices([notice(
        f"The upload was not checked: {job_error_text(exc)}. Nothing was changed; upload "
        f"the zip again. Accepted is {CAMPAIGN_ACCEPTED}.", "error")])


def preview_failed(exc):
    """A recording whose preview did not finish: the review on the right stays."""
    return (*(no_update,) * (IMPORT_PREVIEW_OUTPUTS - 1), W.render_notices([notice(
        f"The recording was not read: {job_error_text(exc)}. Nothing was changed; upload it "
        f"again. Accepted is {RECORDING_ACCEPTED}.", "error")]))


def report_failed(exc):
    """A validation report that did not finish."""
    return W.render_notices([notice(f"The campaign could not be checked ({job_error_text(exc)}); "
                                    "choose it again to retry.", "error")])


def _register_checks():
    """Register the three checks as background callbacks and return them (plain functions
    too: ``fn(set_progress, *callback arguments)``).

    They are defined inside this function on purpose: a job process cannot import this
    page module by itself (``dash.register_page`` needs the app), so the job queue finds a
    local function by its Dash key after importing ``app``."""

    @callback(
        Output("discrepancy-campaign", "options"),
        Output("discrepancy-campaign", "value"),
        Output("discrepancy-upload-notices", "children"),
        Input("discrepancy-upload-data", "data"),
        State("discrepancy-campaign", "options"),
        prevent_initial_call=True,
        on_error=upload_failed,
        **U.background_check("discrepancy-upload", running=[
            (Output("discrepancy-upload", "disabled"), True, False),
            (Output("discrepancy-upload-notices", "style"), HIDDEN, {})]),
    )
    def upload_cb(set_progress, data, options):
        contents, filename = U.store_contents(data)  # passed on by the browser's size check
        if contents:
            U.check_started(set_progress, f"unpacking {(filename or 'the zip')[:200]} and reading the size of its test points…")
        return upload(contents, filename, options)

    @callback(
        Output("discrepancy-import-staged", "data"),
        Output("discrepancy-import-card", "style"),
        Output("discrepancy-import-report", "children"),
        Output("discrepancy-import-cuts", "data"),
        Output("discrepancy-import-dropped", "children"),
        Output("discrepancy-import-create", "disabled"),
        Output("discrepancy-import-create-notices", "children", allow_duplicate=True),
        Output("discrepancy-import-notices", "children"),
        Input("discrepancy-import-upload-data", "data"),
        State("discrepancy-import-staged", "data"),
        prevent_initial_call=True,
        on_error=preview_failed,
        **U.background_check("discrepancy-import-upload", running=[
            (Output("discrepancy-import-upload", "disabled"), True, False),
            (Output("discrepancy-import-notices", "style"), HIDDEN, {})]),
    )
    def preview_recording_cb(set_progress, data, staged):
        contents, filename = U.store_contents(data)  # passed on by the browser's size check
        if contents:
            U.check_started(set_progress, f"reading {(filename or 'the recording')[:200]} and proposing cuts…")
        return preview_recording(contents, filename, staged)

    @callback(
        Output("discrepancy-report", "children"),
        Input("discrepancy-campaign", "value"),
        on_error=report_failed,
        **U.background_check("discrepancy-report", running=[(Output("discrepancy-report", "style"), {"opacity": 0.4}, {})]),
    )
    def report_cb(set_progress, value):
        U.check_started(set_progress, "reading every manifest row and file…")
        return report_for(value)

    return upload_cb, preview_recording_cb, report_cb


upload_cb, preview_recording_cb, report_cb = _register_checks()


# --------------------------------------------------------------------------- diagnosis (background)
CONTROL_INPUTS = [Input("discrepancy-campaign", "value")]


def request(run, initial, values, base_params, autorun):
    examples = example_campaigns()
    state, notices, folder = discrepancy_choice(values[0], examples)
    out = {"search": discrepancy_query(state), "notices": notices}
    if folder is None:
        out["status"] = W.render_notices([notice("Pick an example campaign or upload one.", "info")])
        return out
    try:
        view = discrepancy_view(folder, cache_only=True)
        if view is not None:
            out["hit"] = {"key": view["key"], "from": "cache"}
            out["status"] = "Loading from the cache…"
            return out
        summary = campaign_summary(folder)
    except DampersimError as exc:
        out["notices"] = notices + [notice(f"This campaign cannot be diagnosed: {public_message(exc)}", "error")]
        out["status"] = "Not started."
        return out
    if not summary["ready"]:  # the diagnosis's own rule: it would end in insufficient_data
        out["status"] = W.render_notices([notice(
            f"This campaign cannot be diagnosed: {not_ready_text(summary)} Nothing was run (see the validation report).",
            "error")])
        return out
    by_link = bool(initial and autorun and not run)
    rule, text = diagnosis_admission(summary, started_by_link=by_link)
    if rule == "refuse":
        out["status"] = W.render_notices([notice(text, "error")])
        return out
    if run or (by_link and rule == "run"):
        # work: the key of the diagnosis view (campaign files, options, parameters, code):
        # identical diagnoses asked for by several tabs are computed once by the job queue
        out["job"] = {"state": state, "work": discrepancy_key(folder)}
        out["status"] = f"Starting the diagnosis of {summary['torsional']} torsional test points…"
        return out
    if by_link:  # a link asked for more than it may start by itself
        out["status"] = W.render_notices([notice(text, "info")])
        return out
    out["status"] = W.render_notices([notice(f"Not diagnosed yet: {text}. Press Run diagnosis.", "info")])
    return out


GONE_TEXT = "the campaign is no longer on this server (upload it again)"


def checked_job_state(job_data) -> tuple:
    """(state, folder, summary) of a diagnosis job's request, validated again like a link
    (the page's equivalent of :func:`pages._jobs.checked_job_state`): the state must name
    a bundled example or an upload still on this server, resolve to itself, and be
    ready for the diagnosis (enough valid torsional points, at more than one speed: the
    ``ready`` of :func:`dampersim.views.discrepancy.campaign_summary`). Raises InputError
    naming what is refused, before any work; the budget is checked by :func:`job` on the
    campaign read here."""
    raw = job_data.get("state") if isinstance(job_data, dict) else None
    if not isinstance(raw, dict):
        raise InputError(f"the request names no campaign (state = {type(raw).__name__}); accepted is a state with "
                         "campaign or upload; press Run diagnosis to start again")
    value = discrepancy_value(raw)
    if not isinstance(value, str):
        raise InputError(GONE_TEXT)
    state, _notices, folder = discrepancy_choice(value, example_campaigns())
    if folder is None or discrepancy_value(state) != value:  # refused or gone: the fallback is not what was asked
        raise InputError(GONE_TEXT)
    summary = campaign_summary(folder)
    if not summary["ready"]:
        raise InputError(f"this campaign cannot be diagnosed: {not_ready_text(summary)} See the validation report.")
    return state, folder, summary


def job(job_data, progress):
    """Background part: validate the request again (state and budget), then diagnose."""
    try:
        state, folder, summary = checked_job_state(job_data)
    except DampersimError as exc:
        return {"error": public_message(exc)}
    except Exception as exc:  # reported on the page (no traceback, no server path), never raised into Dash
        return {"error": public_message(exc, "discrepancy request")}
    reg = SweepRegistry()
    t0 = time.monotonic()
    try:
        rule, text = diagnosis_admission(summary, started_by_link=False)  # the budget, on the campaign as it is now
        if rule == "refuse":
            return {"error": text}
        reg.start(PAGE, 0)
        progress(0, 100, "reading the campaign…")

        def on_progress(fraction, text):
            reg.beat()
            extra = J.others_text(reg.others(), "run", "on this server share the cores")
            progress(int(round(100 * fraction)), 100, f"{text} · {time.monotonic() - t0:.0f} s{extra}")

        with upload_in_use(state):  # not evicted by the uploads quota while it is diagnosed
            view = discrepancy_view(folder, progress=on_progress)
        return {"key": view["key"]}
    except Exception as exc:  # reported on the page (no traceback, no server path), never raised into Dash
        return {"error": public_message(exc, "discrepancy diagnosis")}
    finally:
        reg.stop()


SHOW_OUTPUTS = [
    Output("discrepancy-summary", "children"),
    Output("discrepancy-verdict", "children"),
    Output("discrepancy-ranking", "children"),
    Output("discrepancy-gap", "figure"),
    Output("discrepancy-ranking-fig", "figure"),
    Output("discrepancy-map", "figure"),
    Output("discrepancy-profile", "figure"),
    Output("discrepancy-overlays", "figure"),
    Output("discrepancy-json", "children"),
    *T.OUTPUTS,
]


def render_all(view):
    """Everything :func:`show` writes: the verdict, ranking and figures of
    :func:`pages._diagnosis_view.render`, then the model comparison's tables."""
    return (*render(view), *T.render_tables(view["diagnosis"]))


def show(data):
    return J.show_view(data, render_all, len(SHOW_OUTPUTS), "results")


callbacks = J.register_background(PAGE, control_inputs=CONTROL_INPUTS, request=request, job=job, show=show,
                                  show_outputs=SHOW_OUTPUTS,
                                  cancel_text="Cancelled. The results shown are the previous ones; press Run diagnosis to "
                                              "start again (a diagnosis is cached only once it has finished).")
