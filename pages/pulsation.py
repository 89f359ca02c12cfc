"""Pulsation generator: charge pressure, speed and coupling -> output torque trace, order
content and the dominant order over speed ([thesis] chapter 4). Layout and callbacks only."""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html

from dampersim.errors import DampersimError

dash.register_page(__name__, path="/pulsation", name="Pulsation generator", title="Pulsation generator · dampersim", order=7)


def _num(id_, value, step):
    return dcc.Input(id=id_, type="number", value=value, step=step, debounce=True)


def layout(pressure="2.5", speed="1500", coupled="0", **kwargs):
    return html.Div([
        html.H2("Pulsation generator"),
        html.Div([
            html.Label(["Charge pressure [bar abs] ", _num("pg-pressure", float(pressure or 2.5), 0.1)]),
            html.Label([" Speed [rpm] ", _num("pg-speed", float(speed or 1500), 50)]),
            dcc.Checklist(id="pg-coupled", options=[{"label": " coupled to the damper and rig", "value": "1"}],
                          value=["1"] if str(coupled) == "1" else [], inline=True),
            html.Button("Run", id="pg-run"),
            html.Button("Dominant order over speed", id="pg-sweep"),
        ], className="controls"),
        html.Div(id="pg-message", className="notices"),
        html.Pre(id="pg-summary"),
        dcc.Graph(id="pg-trace"),
        dcc.Graph(id="pg-pressure-fig"),
        dcc.Graph(id="pg-orders"),
        html.Progress(id="pg-progress", value="0", max="1"),
        dcc.Graph(id="pg-dominant"),
    ])


@callback(
    Output("pg-trace", "figure"), Output("pg-pressure-fig", "figure"), Output("pg-orders", "figure"),
    Output("pg-summary", "children"), Output("pg-message", "children"),
    Input("pg-run", "n_clicks"), State("pg-pressure", "value"), State("pg-speed", "value"), State("pg-coupled", "value"),
    prevent_initial_call=True,
)
def run(_n, pressure, speed, coupled):
    from dampersim.excitation.pulsation import check_speed_rpm, pressure_warnings, simulate_pulsation
    from dampersim.parameters.engine import check_pressure_bar
    from dampersim.plotting.studies import pulsation_figures
    from dampersim.units import rpm_to_rad_s

    try:
        p = check_pressure_bar(pressure)
        warns = check_speed_rpm(speed, warn=False) + pressure_warnings(p)
        res = simulate_pulsation(rpm_to_rad_s(float(speed)), p, 200.0, coupled=bool(coupled))
    except DampersimError as exc:
        return dash.no_update, dash.no_update, dash.no_update, "", str(exc)
    f1, f2, f3 = pulsation_figures(res)
    s = res.summary()
    text = (f"dominant order {s['dominant_order']:g}; peak cylinder pressure {s['peak_cylinder_pressure_bar']:.1f} bar; "
            f"mean torque {s['mean_torque_nm']:.1f} N m")
    return f1, f2, f3, text, " ".join(warns)


@callback(
    Output("pg-dominant", "figure"),
    Input("pg-sweep", "n_clicks"), State("pg-pressure", "value"), State("pg-coupled", "value"),
    background=True, progress=[Output("pg-progress", "value"), Output("pg-progress", "max")],
    prevent_initial_call=True,
)
def sweep(set_progress, _n, pressure, coupled):
    import numpy as np

    from dampersim.excitation.pulsation import simulate_pulsation
    from dampersim.parameters.engine import check_pressure_bar
    from dampersim.plotting.studies import dominant_order_figure
    from dampersim.units import rpm_to_rad_s

    p = check_pressure_bar(pressure)
    speeds = list(range(1000, 3001, 250))
    rows = []
    for i, rpm in enumerate(speeds):
        r = simulate_pulsation(rpm_to_rad_s(rpm), p, 200.0, coupled=bool(coupled))
        a = r.order_amplitudes((2.0, 4.0, 6.0))
        rows.append((rpm, (2, 4, 6)[int(np.argmax(a))], [float(x) for x in a]))
        set_progress((str(i + 1), str(len(speeds))))
    return dominant_order_figure(rows)
