"""Studies: run any chapter 7 study with progress, see its figures, its checks against the
thesis's findings and the thesis's numbers. Layout and callbacks only."""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html

from dampersim.errors import DampersimError
from dampersim.views.studies import DEFAULT_STUDY, STUDY_NAMES, study_view

dash.register_page(__name__, path="/studies", name="Studies", title="Studies · dampersim", order=8)


def layout(study=DEFAULT_STUDY, quick="1", **kwargs):
    study = study if study in STUDY_NAMES else DEFAULT_STUDY
    return html.Div([
        html.H2("Studies (thesis chapter 7)"),
        html.Div([
            dcc.Dropdown(id="st-name", options=[{"label": n, "value": n} for n in STUDY_NAMES], value=study, clearable=False),
            dcc.Checklist(id="st-quick", options=[{"label": " reduced grid", "value": "1"}],
                          value=["1"] if str(quick) == "1" else [], inline=True),
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
    except DampersimError as exc:
        return [], html.Div(str(exc), className="notice"), ""
    figs = [dcc.Graph(figure=f) for f in view["figures"]]
    checks = html.Ul([html.Li(f"{k}: {'agrees' if v else 'differs'}") for k, v in view["checks"]]
                     + [html.Li(f"thesis: {k} = {v}") for k, v in view["thesis"].items()]
                     + [html.Li(w) for w in view["warnings"]])
    return figs, checks, view["document"]
