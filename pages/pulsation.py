"""Pulsation generator: charge pressure, speed and coupling -> output torque trace, order
content and the dominant order over speed ([thesis] chapter 4). Layout and callbacks only."""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html

from dampersim.errors import DampersimError
from dampersim.incidents import public_message
from dampersim.views.pulsation import dominant_order_view, parse_pulsation_query, pulsation_view
from pages._background import job_error_text
from pages._widgets import render_notices

dash.register_page(__name__, path="/pulsation", name="Pulsation generator", title="Pulsation generator · dampersim", order=7)


def _num(id_, value, step):
    return dcc.Input(id=id_, type="number", value=value, step=step, debounce=True)


def layout(**query):
    """The page from its link: ``pressure`` [bar abs], ``speed`` [rpm], ``coupled`` (1/0);
    bad values get a notice and the default (never an error page)."""
    state, notices = parse_pulsation_query(query)
    return html.Div([
        html.H2("Pulsation generator"),
        html.Div(render_notices(notices, "The link contained values that could not be used:"), id="pg-link-notices",
                 className="notices"),
        html.Div([
            html.Label(["Charge pressure [bar abs] ", _num("pg-pressure", state["pressure"], 0.1)]),
            html.Label([" Speed [rpm] ", _num("pg-speed", state["speed"], 50)]),
            dcc.Checklist(id="pg-coupled", options=[{"label": " coupled to the damper and rig", "value": "1"}],
                          value=["1"] if state["coupled"] else [], inline=True),
            html.Button("Run", id="pg-run"),
            html.Button("Dominant order over speed", id="pg-sweep"),
        ], className="controls"),
        html.Div(id="pg-message", className="notices"),
        html.Pre(id="pg-summary"),
        dcc.Graph(id="pg-trace"),
        dcc.Graph(id="pg-pressure-fig"),
        dcc.Graph(id="pg-orders"),
        html.Progress(id="pg-progress", value="0", max="1"),
        html.Div(id="pg-sweep-message", className="notices"),
        dcc.Graph(id="pg-dominant"),
    ])


@callback(
    Output("pg-trace", "figure"), Output("pg-pressure-fig", "figure"), Output("pg-orders", "figure"),
    Output("pg-summary", "children"), Output("pg-message", "children"),
    Input("pg-run", "n_clicks"), State("pg-pressure", "value"), State("pg-speed", "value"), State("pg-coupled", "value"),
    prevent_initial_call=True,
)
def run(_n, pressure, speed, coupled):
    try:
        view = pulsation_view(pressure, speed, coupled)
    except DampersimError as exc:
        return dash.no_update, dash.no_update, dash.no_update, "", public_message(exc)
    except Exception as exc:  # a defect: logged with an incident id, never a traceback on the page
        return dash.no_update, dash.no_update, dash.no_update, "", public_message(exc, "pulsation run")
    f1, f2, f3 = view["figures"]
    return f1, f2, f3, view["summary"], " ".join(view["warnings"])


@callback(
    Output("pg-dominant", "figure"), Output("pg-sweep-message", "children"),
    Input("pg-sweep", "n_clicks"), State("pg-pressure", "value"), State("pg-coupled", "value"),
    background=True, progress=[Output("pg-progress", "value"), Output("pg-progress", "max")],
    prevent_initial_call=True,
    on_error=lambda exc: (dash.no_update, f"The sweep did not run: {job_error_text(exc)}."),
)
def sweep(set_progress, _n, pressure, coupled):
    """Dominant order over speed; the posted values are validated again here."""
    try:
        fig = dominant_order_view(pressure, coupled, progress=lambda done, total: set_progress((str(done), str(total))))
    except Exception as exc:  # DampersimError: its message; anything else: an incident id
        return dash.no_update, public_message(exc, "pulsation sweep")
    return fig, ""
