"""Maps: magnification ratio over excitation frequency x mean torque from a speed x torque
sweep, with the engine's full-load torque curve drawn for one order and the MR predicted
along it ([thesis] §6.3.1, §7.1.3).

URL keys: ``speeds`` [rpm], ``torques`` [N m] (value, list or START:STOP:STEP), ``orders``,
``duration`` [s], ``window`` [s], ``map_orders`` ("2,4"), ``fmin``/``fmax`` [Hz],
``curve_order``, plus dotted parameter names.
"""

from __future__ import annotations

import dash
from dash import Input, Output, dcc, html

from dampersim.views.notices import notice
from dampersim.views.params import resolve_system
from dampersim.views.state import PAGES, orders_text_from_rows, parse_query, state_from_controls
from dampersim.views.sweeps import maps_key, maps_points, maps_status, maps_view
from pages import _frame as F, _jobs as J, _widgets as W

PAGE = "maps"

dash.register_page(__name__, path="/maps", name="Maps", title="Maps · dampersim", order=4)

ORDER_OPTIONS = [{"label": f" {k}", "value": str(k)} for k in range(1, 9)]


def layout(**query):
    state, notices = parse_query(PAGE, query)
    # only a link whose every value was accepted starts by itself (within the autostart budget)
    autorun = any(f.key in query for f in PAGES[PAGE])  # refused values: the defaults run if cheap
    controls = [
        W.section("Test points", [
            W.control("Speeds", W.text("maps-speeds", state["speeds"], "1000:2800:200"), "rpm", cid="maps-speeds",
                      hint="START:STOP:STEP or a list."),
            W.control("Mean torques", W.text("maps-torques", state["torques"], "50:400:50"), "N m", cid="maps-torques",
                      hint="Every speed is run at every mean torque."),
        ]),
        W.section("Excitation orders", [W.order_rows(PAGE, state["orders"])]),
        W.section("Record", [
            W.control("Simulated time per point", W.number("maps-duration", state["duration"]), "s", cid="maps-duration"),
            W.control("Analysis window", W.number("maps-window", state["window"]), "s", cid="maps-window"),
        ], open_=False),
        W.section("Map", [
            W.control("Orders placed on the map", dcc.Checklist(id="maps-map-orders", options=ORDER_OPTIONS,
                                                                value=[k for k in state["map_orders"].split(",") if k in {o["value"] for o in ORDER_OPTIONS}],
                                                                inline=True, className="checks")),
            W.control("Frequency range", html.Div([W.number("maps-fmin", state["fmin"]), html.Span(" to "),
                                                   W.number("maps-fmax", state["fmax"])], className="pair"), "Hz",
                      hint="The thesis maps 30-200 Hz."),
            W.control("Torque-curve order", W.number("maps-curve-order", state["curve_order"], step=0.5), None, cid="maps-curve-order",
                      hint="Full-load curve drawn at the frequency of this engine order."),
        ]),
        W.run_panel(PAGE, "Run map"),
    ]
    content = [
        *J.background_header(PAGE),
        html.Div([
            W.card(None, W.graph("maps-map", 520, "No map shown yet: press Run map"), wide=True),
            W.card(None, W.graph("maps-curve", 340, "No map shown yet"), wide=True),
        ], className="cards"),
    ]
    return F.page_frame(PAGE, "Magnification maps", "Every test point and order placed at its excitation frequency and mean torque, "
                        "interpolated into a map of the magnification ratio; inside the black contour the damper amplifies.",
                        controls, content, notices, J.background_stores(PAGE, state["params"], autorun))


F.register_link_callbacks(PAGE)

CONTROL_INPUTS = [
    Input("maps-speeds", "value"),
    Input("maps-torques", "value"),
    *W.order_inputs(PAGE),
    Input("maps-duration", "value"),
    Input("maps-window", "value"),
    Input("maps-map-orders", "value"),
    Input("maps-fmin", "value"),
    Input("maps-fmax", "value"),
    Input("maps-curve-order", "value"),
]


def state_from_values(values, base_params):
    speeds, torques, ks, amps, phases, duration, window, map_orders, fmin, fmax, curve_order = values
    orders_text, notices = orders_text_from_rows(ks, amps, phases)
    mo = ",".join(sorted(map_orders or [], key=float)) or None
    if map_orders is not None and not map_orders:
        notices.append(notice("No order selected for the map; using order 2."))
        mo = "2"
    state, more = state_from_controls(PAGE, {"speeds": speeds, "torques": torques, "orders": orders_text, "duration": duration,
                                             "window": window, "map_orders": mo, "fmin": fmin, "fmax": fmax,
                                             "curve_order": curve_order}, base_params)
    system = resolve_system(state["params"], more)
    return state, system, notices + more


def request(run, initial, values, base_params, autorun):
    """Foreground part, as the Colourmap page's: validate, cache hit, budget refusal,
    autostart within the autostart budget, else the estimate and the Run button."""
    state, system, notices = state_from_values(values, base_params)
    return J.sweep_request(PAGE, state, system, notices, run, initial, autorun, view=maps_view, status=maps_status,
                           key=maps_key, noun="sweep", refused="This map cannot be built", button="Run map")


def job(job_data, progress):
    """Background part: validate the request again (state and budget), then run the map."""
    return J.sweep_job(PAGE, job_data, progress, points=maps_points, view=maps_view)


def render(view):
    s = view["summary"]
    cards = W.summary_cards([
        ("Largest MR on the map", W.fmt(s["max_mr"], 3), f"{100 * (s['share_above_one'] or 0):.0f} % of the map above 1"),
        ("Along the torque curve", f"MR ≤ {W.fmt(s['curve_max_mr'], 3)}", f"{100 * s['curve_covered']:.0f} % of the curve inside the map"),
        ("Sweep", f"{s['points']} points", f"{s['sweep_time_s']:.1f} s, {s['computed']} computed, {s['from_cache']} cached"),
    ])
    return view["figures"]["map"], view["figures"]["curve"], cards


SHOW_OUTPUTS = [Output("maps-map", "figure"), Output("maps-curve", "figure"), Output("maps-summary", "children")]


def show(data):
    return J.show_view(data, render, len(SHOW_OUTPUTS), "map")


callbacks = J.register_background(PAGE, control_inputs=CONTROL_INPUTS, request=request, job=job, show=show,
                                  show_outputs=SHOW_OUTPUTS)
