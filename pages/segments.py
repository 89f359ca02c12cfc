"""Segments: how the arc-spring segments move -- compression of each segment over time and
an animated drawing of the damper from the simulated states ([thesis] §7.3, Fig. 7.24-7.25).

URL keys: ``speed`` [rpm], ``torque`` [N m], ``orders``, ``duration`` [s], ``spring``
(outer / pair_outer / pair_inner), ``span`` [s] (animated end of the record), ``gain``
(motion exaggeration about the mean), plus dotted parameter names.
"""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html, no_update

from dampersim.views.params import resolve_system
from dampersim.views.segments import segments_key, segments_view
from dampersim.views.state import orders_text_from_rows, page_href, parse_query, state_from_controls, to_query
from pages import _frame as F, _jobs as J, _widgets as W

PAGE = "segments"

dash.register_page(__name__, path="/segments", name="Segments", title="Segments · dampersim", order=3)

SPRINGS = [{"label": " outer arc spring", "value": "outer"}, {"label": " nested pair, outer", "value": "pair_outer"},
           {"label": " nested pair, inner", "value": "pair_inner"}]


def layout(**query):
    state, notices = parse_query(PAGE, query)
    controls = [
        W.section("Test point", [
            W.control("Speed", W.slider("segments-speed", state["speed"], 300, 6000, 10,
                                        {300: "300", 1500: "1500", 3000: "3000", 4500: "4500", 6000: "6000"}), "rpm", cid="segments-speed"),
            W.control("Mean torque", W.slider("segments-torque", state["torque"], -500, 1000, 5,
                                              {-500: "-500", 0: "0", 300: "300", 600: "600", 1000: "1000"}), "N m", cid="segments-torque"),
            W.control("Simulated time", W.number("segments-duration", state["duration"]), "s", cid="segments-duration"),
            W.run_button(PAGE),
        ]),
        W.section("Excitation orders", [W.order_rows(PAGE, state["orders"])]),
        W.section("Display", [
            W.control("Spring in the heatmap", dcc.RadioItems(id="segments-spring", options=SPRINGS, value=state["spring"], className="radios")),
            W.control("Heatmap window", W.number("segments-window", state["window"]), "s", cid="segments-window",
                      hint="The end of the record shown in the heatmap; the simulated time shows it all."),
            W.control("Animated span", W.number("segments-span", state["span"]), "s", cid="segments-span",
                      hint="The end of the record, drawn at the 1 kHz segment sample rate."),
            W.control("Motion exaggeration", W.number("segments-gain", state["gain"]), "×", cid="segments-gain",
                      hint="Oscillation about the mean position drawn enlarged; 1 = true angles."),
        ]),
        html.Div(dcc.Link("Segment counts and parameters: Explorer / Parameters", href=page_href("parameters", state["params"]),
                          id="segments-params-link"), className="side-link"),
    ]
    content = [
        html.Div(id="segments-run-notices", className="notices"),
        html.Div(id="segments-kpis"),
        html.Div([
            W.card(None, W.graph("segments-animation", 600, "Computing…"), wide=True),
            W.card(None, W.graph("segments-heatmap", 440, "Computing…")),
            W.card("Compression per segment (steady part of the record)", html.Div(id="segments-table")),
        ], className="cards"),
        dcc.Store(id="segments-base-params", data=state["params"]),
        dcc.Store(id="segments-last-good"),
    ]
    return F.page_frame(PAGE, "Segment motion", "Compression of every segment over time, and the damper drawn from the simulated "
                        "node positions: the springs' end segments move first, the middle ones late.", controls, content, notices)


F.register_link_callbacks(PAGE)


def segments_outputs(speed, torque, ks, amps, phases, duration, spring, window, span, gain, base_params,
                     run=False, initial=False):
    """State, view and notices for the current controls (plain function, testable).

    As the Explorer's: above the server's budget (or the foreground limit) ``error`` is set
    and nothing runs; above the autostart budget ``pending`` is True, a notice gives the
    estimate and the point computes only on ``run``; with every foreground slot taken
    ``busy`` is set and nothing runs."""
    orders_text, notices = orders_text_from_rows(ks, amps, phases)
    state, more = state_from_controls(PAGE, {"speed": speed, "torque": torque, "orders": orders_text, "duration": duration,
                                             "spring": spring, "window": window, "span": span, "gain": gain}, base_params)
    notices += more
    system = resolve_system(state["params"], notices)
    out = J.foreground_run(PAGE, segments_key(system, state), system, state, run, segments_view)
    if "notice" in out:
        notices.append(out["notice"])
    if out.get("pending"):
        return {"view": None, "state": state, "notices": notices, "error": None, "pending": True}
    if "error" in out:
        return {"view": None, "state": state, "notices": notices, "error": out["error"], "pending": False,
                **({"busy": True} if out.get("busy") else {})}
    view = out["view"]
    return {"view": view, "state": state, "notices": notices, "error": None, "pending": False}


def _table(rows):
    data = [{"seg": r["segment"], "mean": W.fmt(r["mean_deg"], 3), "amp": W.fmt(r["amplitude_deg"], 3), "max": W.fmt(r["max_deg"], 3)}
            for r in rows]
    return W.table([("seg", "Segment"), ("mean", "Mean compression [deg]"), ("amp", "Oscillation amplitude [deg]"),
                    ("max", "Largest compression [deg]")], data, cid="segments-seg-table")


@callback(
    Output("segments-animation", "figure"),
    Output("segments-heatmap", "figure"),
    Output("segments-table", "children"),
    Output("segments-kpis", "children"),
    Output("segments-run-notices", "children"),
    Output("segments-url", "search"),
    Output("shared-params", "data", allow_duplicate=True),
    Output("segments-last-good", "data"),
    Output("segments-run-wrap", "style"),
    Input("segments-speed", "value"),
    Input("segments-torque", "value"),
    *W.order_inputs(PAGE),
    Input("segments-duration", "value"),
    Input("segments-spring", "value"),
    Input("segments-window", "value"),
    Input("segments-span", "value"),
    Input("segments-gain", "value"),
    State("segments-base-params", "data"),
    State("segments-last-good", "data"),
    Input("segments-run", "n_clicks"),
    prevent_initial_call="initial_duplicate",
)
def update_segments(speed, torque, ks, amps, phases, duration, spring, window, span, gain, base_params, last_good,
                    run_clicks=None):
    initial, run = W.triggers("segments-run.n_clicks")
    out = segments_outputs(speed, torque, ks, amps, phases, duration, spring, window, span, gain, base_params,
                           run=run, initial=initial)
    notices = W.render_notices(out["notices"])
    hidden, shown = {"display": "none"}, {"display": "block"}
    if out.get("pending"):
        figs = [no_update, no_update] if last_good else [W.empty_figure("Not computed yet: press Run")] * 2
        state = out["state"]
        return (*figs, no_update, no_update, notices, to_query(PAGE, state), state["params"], no_update, shown)
    if out["error"]:
        figs = [no_update, no_update] if last_good else [W.empty_figure("No result: see the message above")] * 2
        return (*figs, no_update, no_update, notices, no_update, no_update, no_update, hidden)
    view = out["view"]
    s = view["summary"]
    kpis = W.summary_cards([
        ("Spring", s["spring"].replace("_", " "), f"{s['segments']} segments"),
        ("End vs middle", f"{s['end_to_middle_amplitude']:.2g} ×", "oscillation of the end segments / median segment"),
        ("Frames", f"{s['frames']}", "segment states at 1 kHz"),
        ("Run", "from cache" if view.get("from_cache") else f"computed in {s['compute_time_s']:.2f} s", None),
    ])
    state = out["state"]
    return (view["figures"]["animation"], view["figures"]["heatmap"], _table(view["segments"]), kpis, notices,
            to_query(PAGE, state), state["params"], view["key"], hidden)
