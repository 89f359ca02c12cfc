"""Explorer: one test point (speed, mean torque, excitation orders, segments, key parameters).

URL keys: ``speed`` [rpm], ``torque`` [N m], ``orders`` ("2:300,4:100@90": order,
amplitude [N m], phase [deg]), ``duration`` [s] and any dotted parameter name (SI values),
e.g. ``/explorer?speed=2100&torque=260&solver.outer_segments=24``.
"""

from __future__ import annotations

import dash
from dash import ALL, Input, Output, State, callback, dcc, html, no_update

from dampersim import views
from dampersim.errors import DampersimError
from pages import _common as C

PAGE = "explorer"
TITLE = "Explorer"

dash.register_page(__name__, path="/explorer", name=TITLE, title="Explorer · dampersim", order=0)

SEGMENT_PARAMS = ("solver.outer_segments", "solver.inner_segments")
INERTIA_PARAMS = ("inertias.primary", "inertias.secondary", "inertias.tertiary")
SPRING_PARAMS = ("outer.spring.stiffness", "inner.spring.stiffness", "inner.nested.stiffness", "outer.hardstop_positive")
FRICTION_PARAMS = ("friction.outer.alpha", "friction.pair_outer.alpha", "friction.pair_inner.alpha")
SWITCHES = ("friction.enabled", "hardstops.enabled")
FIGURES = ("traces", "spectrum", "mr", "windup", "energy")


def layout(**query):
    state, notices = views.parse_query(PAGE, query)
    system = views.resolve_system(state["params"])
    on = [n for n in SWITCHES if views.parameter_value(system, n)]
    controls = [
        C.section("Test point", [
            C.control("Speed", C.slider("explorer-speed", state["speed"], 300, 6000, 10,
                                        {300: "300", 1500: "1500", 3000: "3000", 4500: "4500", 6000: "6000"}), "rpm", cid="explorer-speed"),
            C.control("Mean torque", C.slider("explorer-torque", state["torque"], -500, 1000, 5,
                                              {-500: "-500", 0: "0", 300: "300", 600: "600", 1000: "1000"}), "N m", cid="explorer-torque"),
            C.control("Simulated time", C.number("explorer-duration", state["duration"]), "s",
                      hint="Analysis window: the last 1.25 s (shorter records: after the 0.6 s start-up).", cid="explorer-duration"),
        ]),
        C.section("Excitation orders", [C.order_rows(PAGE, state["orders"])]),
        C.section("Segments per spring", C.param_controls(PAGE, system, SEGMENT_PARAMS)),
        C.section("Inertias", C.param_controls(PAGE, system, INERTIA_PARAMS), open_=False),
        C.section("Springs and hardstop", C.param_controls(PAGE, system, SPRING_PARAMS), open_=False),
        C.section("Friction", C.param_controls(PAGE, system, FRICTION_PARAMS), open_=False),
        C.section("Model", [
            dcc.Checklist(id="explorer-switches", options=[{"label": " Friction", "value": "friction.enabled"},
                                                           {"label": " Hardstops", "value": "hardstops.enabled"}],
                          value=on, className="checks", inline=True),
            C.control("Output motor", dcc.RadioItems(id="explorer-motor", options=[{"label": " PI speed control", "value": "pi"},
                                                                                   {"label": " held speed", "value": "held"}],
                                                      value=system.motor.mode, className="radios", inline=True)),
        ], open_=False),
        html.Div([dcc.Link("Edit all parameters →", href=views.page_href("parameters", state["params"]), id="explorer-params-link")],
                 className="side-link"),
    ]
    content = [
        html.Div(id="explorer-run-notices", className="notices"),
        html.Div(C.summary_cards([("Magnification", "…", None), ("Output torque", "…", None), ("Outer windup", "…", None),
                                  ("Energy balance", "…", None), ("Run", "…", None)]), id="explorer-kpis"),
        html.Div([
            C.card(None, C.graph("explorer-traces", 340)),
            C.card(None, C.graph("explorer-spectrum", 340)),
            C.card(None, [C.graph("explorer-mr", 340), html.Div(id="explorer-orders-table")]),
            C.card(None, C.graph("explorer-windup", 380)),
            C.card(None, C.graph("explorer-energy", 420), wide=True),
        ], className="cards"),
    ]
    extra = [dcc.Store(id="explorer-base-params", data=state["params"]), dcc.Store(id="explorer-last-good")]
    return C.page_frame(PAGE, "Explorer", "One test point on the rig: time traces, spectra, magnification per order, "
                        "windup against the hardstops and the energy balance. Sliders update on release.",
                        controls, content, notices, extra)


C.register_link_callbacks(PAGE)


def _kpis(view):
    s = view["summary"]
    mr = s.get("main_mr")
    main = f"order {s['main_order']:g}" if s.get("main_order") is not None else "no excited order"
    hs = max(s["hardstop_outer_share"], s["hardstop_inner_share"])
    src = "from cache" if view.get("from_cache") else f"computed in {s['compute_time_s']:.2f} s"
    return C.summary_cards([
        ("Magnification", C.fmt(mr, 3), main),
        ("Output torque", C.fmt(s["mean_output_torque_nm"], 4, "N m"), "mean over the window"),
        ("Outer windup", f"{s['windup_outer_deg'][0]:.1f} to {s['windup_outer_deg'][1]:.1f} deg",
         f"hardstop contact {100 * hs:.0f} % of the window" if hs > 0 else "no hardstop contact"),
        ("Energy residual", f"{100 * s['residual_rel']:.1g} %", f"of the work; {C.fmt(s['dissipated_j'], 3, 'J')} dissipated"),
        ("Run", src, f"kernel {s['kernel_time_s']:.2f} s for {s['duration_s']:g} s simulated"),
    ])


def _orders_table(rows):
    data = [{"order": f"{r['order']:g}", "f": f"{r['frequency_hz']:.1f}", "in": C.fmt(r["input_nm"], 4), "out": C.fmt(r["output_nm"], 4),
             "mr": C.fmt(r["mr"], 4), "excited": r["excited"]} for r in rows]
    return C.table([("order", "Order"), ("f", "Frequency [Hz]"), ("in", "Input [N m]"), ("out", "Output [N m]"), ("mr", "MR [-]")],
                   data, cid="explorer-mr-table", highlight=lambda r: r["excited"])


def explorer_outputs(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params):
    """Everything the Explorer shows for the current controls (plain function, testable).

    Returns a dict: figures {name: figure}, table, kpis, notices, search, params, error.
    On a refused state or a failed simulation ``error`` is set and the previous results
    stay (``figures`` is None).
    """
    notices = []
    orders_text, notes = C.orders_text_from_rows(ks, amps, phases)
    notices += notes
    names = [i["name"] for i in (param_ids or [])]
    values = list(param_values or [])
    sw = set(switches or [])
    names += list(SWITCHES) + ["motor.mode"]
    values += [n in sw for n in SWITCHES] + [motor or "pi"]
    params, system = C.control_params(base_params, names, values, notices)
    state, more = views.state_from_controls(PAGE, {"speed": speed, "torque": torque, "orders": orders_text, "duration": duration}, params)
    notices += more
    try:
        view = views.explorer_view(system, state)
    except DampersimError as exc:
        notices.append(views.notice(f"The test point could not be simulated: {exc}. The previous results are kept.", "error"))
        return {"figures": None, "table": None, "kpis": None, "notices": notices, "search": None, "params": None,
                "error": str(exc), "state": state}
    return {"figures": view["figures"], "table": _orders_table(view["orders"]), "kpis": _kpis(view), "notices": notices,
            "search": views.to_query(PAGE, state), "params": state["params"], "error": None, "state": state, "view": view}


@callback(
    *[Output(f"explorer-{f}", "figure") for f in FIGURES],
    Output("explorer-orders-table", "children"),
    Output("explorer-kpis", "children"),
    Output("explorer-run-notices", "children"),
    Output("explorer-url", "search"),
    Output("shared-params", "data", allow_duplicate=True),
    Output("explorer-last-good", "data"),
    Output("explorer-params-link", "href"),
    Input("explorer-speed", "value"),
    Input("explorer-torque", "value"),
    *C.order_inputs(PAGE),
    Input("explorer-duration", "value"),
    Input({"type": "explorer-param", "name": ALL}, "value"),
    Input("explorer-switches", "value"),
    Input("explorer-motor", "value"),
    State({"type": "explorer-param", "name": ALL}, "id"),
    State("explorer-base-params", "data"),
    State("explorer-last-good", "data"),
    prevent_initial_call="initial_duplicate",
)
def update_explorer(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params, last_good):
    out = explorer_outputs(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params)
    notices = C.render_notices(out["notices"])
    if out["error"]:
        figs = [no_update] * len(FIGURES) if last_good else [C.empty_figure("No result: see the message above")] * len(FIGURES)
        return (*figs, no_update, no_update, notices, no_update, no_update, no_update, no_update)
    figs = [out["figures"][f] for f in FIGURES]
    return (*figs, out["table"], out["kpis"], notices, out["search"], out["params"], out["view"]["key"],
            views.page_href("parameters", out["params"]))


# The home page "/" is the Explorer too (same layout, same query keys).
dash.register_page("pages.explorer_home", path="/", name="Explorer (home)", title="Explorer · dampersim", layout=layout, order=99)
