"""Parameters: view and edit the parameter set, validate it, download or upload TOML.

URL keys: dotted parameter names with SI values (only those that differ from the base
set), and ``set=<id>`` for an uploaded set whose structure differs from the default one
(stored on this server). The same keys travel to every other page through the navbar, so
the edited set is used everywhere and every link reproduces it.
"""

from __future__ import annotations

import dash
from dash import ALL, Input, Output, State, callback, ctx, dcc, html, no_update
from dash.exceptions import PreventUpdate

from dampersim.errors import DampersimError
from dampersim.incidents import public_message
from dampersim.views.notices import notice
from dampersim.views.params import (
    MAX_UPLOAD_BYTES,
    accuracy_notices,
    apply_table_edits,
    parameters_toml,
    parameters_view,
    params_for_system,
    parse_uploaded_parameters,
    resolve_system,
)
from dampersim.views.state import parse_query, to_query
from pages import _frame as F, _jobs as J, _uploads as U, _widgets as W

PAGE = "parameters"

dash.register_page(__name__, path="/parameters", name="Parameters", title="Parameters · dampersim", order=5)

# a file above the page's limit is refused in the browser and never posted
UPLOAD_SIZE_CHECK = U.size_checked_upload(
    "parameters-upload", MAX_UPLOAD_BYTES,
    "Check a larger parameter file on the server's command line with python -m dampersim params validate FILE "
    "and use it there with --params FILE.")

def table_rows(system):
    """Editable rows: every dotted parameter except labels and rig-element names."""
    return [r for r in parameters_view(system) if r["name"] not in ("name", "source") and not r["name"].endswith(".name")]


GROUPS = {
    "inertias": "Inertias", "outer": "Outer spring set", "inner": "Inner set (nested pairs)", "friction": "Friction",
    "hardstops": "Hardstops", "rig": "Rig output chain", "motor": "Output motor", "solver": "Solver",
}


def render_table(rows):
    """Parameter rows grouped in collapsible sections, each value an editable text box."""
    groups = {}
    for r in rows:
        groups.setdefault(r["name"].split(".", 1)[0], []).append(r)
    out = []
    for g, items in groups.items():
        n_changed = sum(r["changed"] for r in items)
        head = html.Tr([html.Th("Parameter"), html.Th("Value"), html.Th("Unit"), html.Th("Accepted"), html.Th("Meaning")])
        body = [html.Tr([
            html.Td(r["name"].split(".", 1)[1] if "." in r["name"] else r["name"], className="pname", title=r["name"]),
            html.Td(dcc.Input(id={"type": "param-value", "name": r["name"]}, type="text", value=r["value"], className="txt pvalue",
                              debounce=True)),
            html.Td(r["unit"], className="punit"),
            html.Td(r["accepted"], className="paccepted"),
            html.Td(r["doc"], className="pdoc"),
        ], className="changed" if r["changed"] else None) for r in items]
        title = GROUPS.get(g, g) + (f"  ·  {n_changed} changed" if n_changed else "")
        out.append(html.Details([html.Summary(title), html.Table([html.Thead(head), html.Tbody(body)], className="param-table")],
                                open=g in ("inertias", "outer", "inner", "friction", "solver") or n_changed > 0, className="section"))
    return out


def _set_info(system, params):
    n = len((params or {}).get("overrides") or {})
    base = "uploaded set " + params["set"] if (params or {}).get("set") else "default set"
    return W.summary_cards([
        ("Parameter set", system.name, (system.source[:90] + "…") if len(system.source) > 90 else system.source),
        ("Changes", f"{n} value{'s' if n != 1 else ''}", f"relative to the {base}"),
    ])


def layout(**query):
    state, notices = parse_query(PAGE, query)
    system = resolve_system(state["params"])
    controls = [
        W.section("This parameter set", [html.Div(_set_info(system, state["params"]), id="parameters-info")]),
        W.section("File", [
            dcc.Upload(id="parameters-upload", children=html.Div(["Drop a TOML parameter file here or ", html.A("choose one")]),
                       className="upload", multiple=False, accept=".toml,text/plain"),
            *U.components("parameters-upload"),
            html.Div([html.Button("Download TOML", id="parameters-download-btn", n_clicks=0, className="btn btn-primary"),
                      html.Button("Reset to default", id="parameters-reset", n_clicks=0, className="btn btn-secondary")],
                     className="buttons", style={"marginTop": "10px"}),
            dcc.Download(id="parameters-download"),
        ]),
        W.section("Edit", [
            html.P("Edit values in the tables (SI units: kg, m, rad, s, N m), then validate or apply. Applied changes go into "
                   "the link and to every page. Highlighted rows differ from the default set.",
                   className="hint"),
            html.Div([html.Button("Validate", id="parameters-validate", n_clicks=0, className="btn btn-secondary"),
                      html.Button("Apply", id="parameters-apply", n_clicks=0, className="btn btn-primary"),
                      html.Button("Undo edits", id="parameters-undo", n_clicks=0, className="btn btn-secondary")],
                     className="buttons"),
        ]),
        html.Div(id="parameters-status", className="status", **{"aria-live": "polite"}),
    ]
    content = [
        html.Div(id="parameters-run-notices", className="notices"),
        W.card(None, html.Div(render_table(table_rows(system)), id="parameters-table", className="param-table-wrap"), wide=True),
        dcc.Store(id="parameters-params", data=state["params"]),
    ]
    return F.page_frame(PAGE, "Parameters", "The complete parameter set of the damper, the rig and the solver, with units and accepted "
                        "ranges.", controls, content, notices)


F.register_link_callbacks(PAGE)


def parameters_action(action, rows, params, contents=None, filename=None):
    """One user action on the parameter set (plain function, testable).

    action: "validate", "apply", "undo", "reset" or "upload". Returns a dict with
    ``params`` (new parameter state or None when unchanged), ``rows`` (table rows or None),
    ``notices`` and ``status``. A refused edit or upload changes nothing.
    """
    params = params or {"set": None, "overrides": {}}
    if action == "reset":
        system = resolve_system(None)
        return {"params": {"set": None, "overrides": {}}, "rows": table_rows(system), "notices": [],
                "status": notice("Reset to the default parameter set.", "success"), "system": system}
    if action == "undo":
        system = resolve_system(params)
        return {"params": None, "rows": table_rows(system), "notices": [], "status": notice("Edits undone.", "info"), "system": system}
    if action == "upload":
        try:
            system = parse_uploaded_parameters(contents, filename)
        except Exception as exc:  # noqa: BLE001 - a refused file changes nothing; no traceback reaches the page
            return {"params": None, "rows": None, "system": None, "status": notice("Upload refused.", "error"),
                    "notices": [notice(f"The file was not loaded: {public_message(exc, 'parameter upload')}. "
                                       "The current parameter set is unchanged.", "error")]}
        new = params_for_system(system)
        n = len(new["overrides"])
        what = f"{n} value{'s' if n != 1 else ''} differ from the default set" if not new["set"] else \
            "its structure differs from the default set, so it is stored on this server and the link refers to it"
        return {"params": new, "rows": table_rows(system), "notices": accuracy_notices(system), "system": system,
                "status": notice(f"Loaded {filename or 'the file'} ({system.name}): {what}.", "success")}
    if action in ("validate", "apply"):
        try:
            new, system = apply_table_edits(params, rows or [])
        except DampersimError as exc:
            return {"params": None, "rows": None, "system": None, "status": notice("Not valid.", "error"),
                    "notices": [notice(f"Not accepted: {exc}. The applied parameter set is unchanged; fix the value or undo the edits.",
                                       "error")]}
        n = len(new.get("overrides") or {})
        if action == "validate":
            return {"params": None, "rows": None, "notices": accuracy_notices(system), "system": system,
                    "status": notice(f"Valid: the edited set passes every check ({n} value{'s' if n != 1 else ''} differ from the base set). "
                                     "Press Apply to use it.", "success")}
        return {"params": new, "rows": table_rows(system), "notices": accuracy_notices(system), "system": system,
                "status": notice(f"Applied: {n} value{'s' if n != 1 else ''} differ from the base set; every page now uses this set.",
                                 "success")}
    raise PreventUpdate


@callback(
    Output("parameters-params", "data"),
    Output("parameters-table", "children"),
    Output("parameters-status", "children"),
    Output("parameters-run-notices", "children"),
    Output("parameters-url", "search"),
    Output("shared-params", "data", allow_duplicate=True),
    Output("parameters-info", "children"),
    Input("parameters-validate", "n_clicks"),
    Input("parameters-apply", "n_clicks"),
    Input("parameters-undo", "n_clicks"),
    Input("parameters-reset", "n_clicks"),
    Input("parameters-upload-data", "data"),
    State({"type": "param-value", "name": ALL}, "value"),
    State({"type": "param-value", "name": ALL}, "id"),
    State("parameters-params", "data"),
    prevent_initial_call="initial_duplicate",
)
def on_action(_v, _a, _u, _r, upload_data, values, ids, params):
    contents, filename = U.store_contents(upload_data)  # passed on by the browser's size check
    rows = [{"name": i["name"], "value": v} for i, v in zip(ids or [], values or [])]
    initial, _ = J.trigger_kind()
    trig = ctx.triggered_id
    if initial:  # page load: mirror the (validated) link state
        system = resolve_system(params)
        return (no_update, no_update, "", [], to_query(PAGE, {"params": params}), params, _set_info(system, params))
    action = {"parameters-validate": "validate", "parameters-apply": "apply", "parameters-undo": "undo",
              "parameters-reset": "reset", "parameters-upload-data": "upload"}.get(trig)
    if action == "upload" and not contents:
        raise PreventUpdate
    out = parameters_action(action, rows, params, contents, filename)
    new = out["params"]
    status = W.render_notices([out["status"]]) if out.get("status") else ""
    if new is None:
        return (no_update, render_table(out["rows"]) if out["rows"] is not None else no_update, status,
                W.render_notices(out["notices"]), no_update, no_update, no_update)
    return (new, render_table(out["rows"]), status, W.render_notices(out["notices"]), to_query(PAGE, {"params": new}), new,
            _set_info(out["system"], new))


@callback(
    Output("parameters-download", "data"),
    Input("parameters-download-btn", "n_clicks"),
    State("parameters-params", "data"),
    prevent_initial_call=True,
)
def download(n_clicks, params):
    if not n_clicks:
        raise PreventUpdate
    system = resolve_system(params)
    return dcc.send_string(parameters_toml(system), filename=f"{system.name}.toml", type="application/toml")
