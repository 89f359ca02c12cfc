"""Studies: run any chapter 7 study with progress, see its figures, its checks against the
thesis's findings and the thesis's numbers. Layout and callbacks only."""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html

from dampersim.incidents import public_message
from dampersim.views.studies import STUDY_NAMES, parse_studies_query, study_view
from pages._widgets import render_notices

dash.register_page(__name__, path="/studies", name="Studies", title="Studies · dampersim", order=8)


def layout(**query):
    """The page from its link: ``study`` (a study name) and ``quick`` (1/0); bad values get
    a notice and the default (never an error page)."""
    state, notices = parse_studies_query(query)
    return html.Div([
        html.H2("Studies (thesis chapter 7)"),
        html.Div(render_notices(notices, "The link contained values that could not be used:"), id="st-link-notices",
                 className="notices"),
        html.Div([
            dcc.Dropdown(id="st-name", options=[{"label": n, "value": n} for n in STUDY_NAMES], value=state["study"],
                         clearable=False),
            dcc.Checklist(id="st-quick", options=[{"label": " reduced grid", "value": "1"}],
                          value=["1"] if state["quick"] else [], inline=True),
            html.Button("Run study", id="st-run"),
            html.Button("Cancel", id="st-cancel"),
        ], className="controls"),
        html.Progress(id="st-progress", value="0", max="1"),
        html.Div(id="st-progress-text"),
        html.Div(id="st-checks"),
        html.Div(id="st-figures"),
        html.Details([html.Summary("Result document (JSON)"), html.Pre(id="st-json")]),
    ])


@callback(
    Output("st-figures", "children"), Output("st-checks", "children"), Output("st-json", "children"),
    Input("st-run", "n_clicks"), State("st-name", "value"), State("st-quick", "value"),
    background=True,
    progress=[Output("st-progress", "value"), Output("st-progress", "max"), Output("st-progress-text", "children")],
    running=[(Output("st-run", "disabled"), True, False)],
    cancel=[Input("st-cancel", "n_clicks")],
    prevent_initial_call=True,
)
def run(set_progress, _n, name, quick):
    def prog(done, total, cached):
        set_progress((str(done), str(max(total, 1)), f"{done} / {total} points ({cached} from cache)"))

    try:
        view = study_view(name, quick=bool(quick), progress=prog)
    except Exception as exc:  # DampersimError: its message; anything else: an incident id, never a traceback
        return [], html.Div(public_message(exc, "study run"), className="notice"), ""
    figs = [dcc.Graph(figure=f) for f in view["figures"]]
    checks = html.Ul([html.Li(f"{k}: {'agrees' if v else 'differs'}") for k, v in view["checks"]]
                     + [html.Li(f"thesis: {k} = {v}") for k, v in view["thesis"].items()]
                     + [html.Li(w) for w in view["warnings"]])
    return figs, checks, view["document"]
