"""Explorer: one test point (speed, mean torque, excitation orders, segments, key parameters).

URL keys: ``speed`` [rpm], ``torque`` [N m], ``orders`` ("2:300,4:100@90": order,
amplitude [N m], phase [deg]), ``duration`` [s], ``repeat`` (repeatability runs, 2-32, off
when absent), ``spread_check`` (true: with ``repeat``, the K runs again at half the step
label each order's spread physical or numerical) and any dotted parameter name (SI values),
e.g. ``/explorer?speed=2100&torque=260&solver.outer_segments=24``.
"""

from __future__ import annotations

import dash
from dash import ALL, Input, Output, State, callback, dcc, html, no_update

from dampersim.views.explorer import explorer_key, explorer_view
from dampersim.views.params import control_params, parameter_value, resolve_system
from dampersim.views.state import orders_text_from_rows, page_href, parse_query, state_from_controls, to_query
from pages import _frame as F, _jobs as J, _widgets as W

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
    state, notices = parse_query(PAGE, query)
    system = resolve_system(state["params"])
    on = [n for n in SWITCHES if parameter_value(system, n)]
    controls = [
        W.section("Test point", [
            W.control("Speed", W.slider("explorer-speed", state["speed"], 300, 6000, 10,
                                        {300: "300", 1500: "1500", 3000: "3000", 4500: "4500", 6000: "6000"}), "rpm", cid="explorer-speed"),
            W.control("Mean torque", W.slider("explorer-torque", state["torque"], -500, 1000, 5,
                                              {-500: "-500", 0: "0", 300: "300", 600: "600", 1000: "1000"}), "N m", cid="explorer-torque"),
            W.control("Simulated time", W.number("explorer-duration", state["duration"]), "s",
                      hint="Analysis window: the last 1.25 s (shorter records: after the 0.6 s start-up).", cid="explorer-duration"),
            W.control("Repeatability runs", W.number("explorer-repeat", state["repeat"], step=1, placeholder="off"), "runs",
                      hint="Off by default. K runs (2-32) with the input amplitudes scaled by 1 + i·1e-9: the magnification "
                           "gets the min-max of the K runs as a band and the table the spread per order. Costs K runs.",
                      cid="explorer-repeat"),
            dcc.Checklist(id="explorer-spread-check", options=[{"label": " Spread check at half the step", "value": "on"}],
                          value=["on"] if state["spread_check"] else [], className="checks"),
            W.run_button(PAGE),
        ]),
        W.section("Excitation orders", [W.order_rows(PAGE, state["orders"])]),
        W.section("Segments per spring", W.param_controls(PAGE, system, SEGMENT_PARAMS)),
        W.section("Inertias", W.param_controls(PAGE, system, INERTIA_PARAMS), open_=False),
        W.section("Springs and hardstop", W.param_controls(PAGE, system, SPRING_PARAMS), open_=False),
        W.section("Friction", W.param_controls(PAGE, system, FRICTION_PARAMS), open_=False),
        W.section("Model", [
            dcc.Checklist(id="explorer-switches", options=[{"label": " Friction", "value": "friction.enabled"},
                                                           {"label": " Hardstops", "value": "hardstops.enabled"}],
                          value=on, className="checks", inline=True),
            W.control("Output motor", dcc.RadioItems(id="explorer-motor", options=[{"label": " PI speed control", "value": "pi"},
                                                                                   {"label": " held speed", "value": "held"}],
                                                      value=system.motor.mode, className="radios", inline=True)),
        ], open_=False),
        html.Div([dcc.Link("Edit all parameters →", href=page_href("parameters", state["params"]), id="explorer-params-link")],
                 className="side-link"),
    ]
    content = [
        html.Div(id="explorer-run-notices", className="notices"),
        html.Div(W.summary_cards([("Magnification", "…", None), ("Output torque", "…", None), ("Outer windup", "…", None),
                                  ("Energy balance", "…", None), ("Run", "…", None)]), id="explorer-kpis"),
        html.Div([
            W.card(None, W.graph("explorer-traces", 340)),
            W.card(None, W.graph("explorer-spectrum", 340)),
            W.card(None, [W.graph("explorer-mr", 340), html.Div(id="explorer-orders-table")]),
            W.card(None, W.graph("explorer-windup", 380)),
            W.card(None, W.graph("explorer-energy", 420), wide=True),
        ], className="cards"),
    ]
    extra = [dcc.Store(id="explorer-base-params", data=state["params"]), dcc.Store(id="explorer-last-good")]
    return F.page_frame(PAGE, "Explorer", "One test point on the rig: time traces, spectra, magnification per order, "
                        "windup against the hardstops and the energy balance. Sliders update on release.",
                        controls, content, notices, extra)


F.register_link_callbacks(PAGE)


def _kpis(view):
    s = view["summary"]
    mr = s.get("main_mr")
    main = f"order {s['main_order']:g}" if s.get("main_order") is not None else "no excited order"
    hs = max(s["hardstop_outer_share"], s["hardstop_inner_share"])
    src = "from cache" if view.get("from_cache") else f"computed in {s['compute_time_s']:.2f} s"
    return W.summary_cards([
        ("Magnification", W.fmt(mr, 3), main),
        ("Output torque", W.fmt(s["mean_output_torque_nm"], 4, "N m"), "mean over the window"),
        ("Outer windup", f"{s['windup_outer_deg'][0]:.1f} to {s['windup_outer_deg'][1]:.1f} deg",
         f"hardstop contact {100 * hs:.0f} % of the window" if hs > 0 else "no hardstop contact"),
        ("Energy residual", f"{100 * s['residual_rel']:.1g} %", f"of the work; {W.fmt(s['dissipated_j'], 3, 'J')} dissipated"),
        ("Run", src, f"kernel {s['kernel_time_s']:.2f} s for {s['duration_s']:g} s simulated"),
    ])


def _spread_text(r) -> str:
    """"3.2" or, after a spread check, "3.2 (physical)" / "3.2, 0.01 at dt/2 (numerical)"."""
    text = W.fmt(r.get("spread_pct"), 3)
    if r.get("spread_half_pct") is not None and r.get("spread_origin") != "physical":
        text += f", {W.fmt(r['spread_half_pct'], 3)} at dt/2"
    return text + (f" ({r['spread_origin']})" if r.get("spread_origin") else "")


def _orders_table(rows, runs=None):
    data = [{"order": f"{r['order']:g}", "f": f"{r['frequency_hz']:.1f}", "in": W.fmt(r["input_nm"], 4), "out": W.fmt(r["output_nm"], 4),
             "mr": W.fmt(r["mr"], 4), "spread": _spread_text(r), "excited": r["excited"]} for r in rows]
    cols = [("order", "Order"), ("f", "Frequency [Hz]"), ("in", "Input [N m]"), ("out", "Output [N m]"), ("mr", "MR [-]")]
    if runs:
        cols.append(("spread", f"Spread of {runs} runs [%]"))
    return W.table(cols, data, cid="explorer-mr-table", highlight=lambda r: r["excited"])


def explorer_outputs(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params,
                     run=False, initial=False, repeat=None, spread_check=None):
    """Everything the Explorer shows for the current controls (plain function, testable).

    Returns a dict: figures {name: figure}, table, kpis, notices, search, params, error,
    pending. On a refused state (above the server's budget) or a failed simulation
    ``error`` is set and the previous results stay (``figures`` is None); the Explorer
    computes in the request thread, so it also refuses points above
    :data:`dampersim.costs.FOREGROUND_WORK`. A point above the autostart budget computes
    only on ``run``: ``pending`` is True and a notice gives the estimate. A link's refused
    values have already fallen back to their defaults (the URL contract), which run.
    ``repeat`` (the "Repeatability runs" box; None = off) runs the point K times, so the
    cost checked is K runs; ``spread_check`` (the "Spread check" box: a list holding "on",
    or True) runs them again at half the step and labels each order's spread
    (:func:`dampersim.analysis.repeatability.spread_check`), K more runs of twice the steps
    in the cost. A point to compute takes one of the server's foreground slots
    (:func:`dampersim.costs.foreground_slot`); when none is free nothing runs, ``error``
    and ``busy`` are set and a notice says the server is busy (a cache hit needs no slot).
    """
    notices = []
    orders_text, notes = orders_text_from_rows(ks, amps, phases)
    notices += notes
    names = [i["name"] for i in (param_ids or [])]
    values = list(param_values or [])
    sw = set(switches or [])
    names += list(SWITCHES) + ["motor.mode"]
    values += [n in sw for n in SWITCHES] + [motor or "pi"]
    params, system = control_params(base_params, names, values, notices)
    state, more = state_from_controls(PAGE, {"speed": speed, "torque": torque, "orders": orders_text, "duration": duration,
                                             "repeat": repeat, "spread_check": True if spread_check else None}, params)
    notices += more
    out = J.foreground_run(PAGE, explorer_key(system, state), system, state, run, explorer_view)
    if "notice" in out:
        notices.append(out["notice"])
    if out.get("pending"):
        return {"figures": None, "table": None, "kpis": None, "notices": notices, "search": to_query(PAGE, state),
                "params": state["params"], "error": None, "pending": True, "state": state}
    if "error" in out:
        return {"figures": None, "table": None, "kpis": None, "notices": notices, "search": None, "params": None,
                "error": out["error"], "state": state, "pending": False, **({"busy": True} if out.get("busy") else {})}
    view = out["view"]
    return {"figures": view["figures"], "table": _orders_table(view["orders"], state.get("repeat")), "kpis": _kpis(view), "notices": notices,
            "search": to_query(PAGE, state), "params": state["params"], "error": None, "state": state, "view": view,
            "pending": False}


@callback(
    *[Output(f"explorer-{f}", "figure") for f in FIGURES],
    Output("explorer-orders-table", "children"),
    Output("explorer-kpis", "children"),
    Output("explorer-run-notices", "children"),
    Output("explorer-url", "search"),
    Output("shared-params", "data", allow_duplicate=True),
    Output("explorer-last-good", "data"),
    Output("explorer-params-link", "href"),
    Output("explorer-run-wrap", "style"),
    Input("explorer-speed", "value"),
    Input("explorer-torque", "value"),
    *W.order_inputs(PAGE),
    Input("explorer-duration", "value"),
    Input({"type": "explorer-param", "name": ALL}, "value"),
    Input("explorer-switches", "value"),
    Input("explorer-motor", "value"),
    State({"type": "explorer-param", "name": ALL}, "id"),
    State("explorer-base-params", "data"),
    State("explorer-last-good", "data"),
    Input("explorer-run", "n_clicks"),
    Input("explorer-repeat", "value"),
    Input("explorer-spread-check", "value"),
    prevent_initial_call="initial_duplicate",
)
def update_explorer(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params, last_good,
                    run_clicks=None, repeat=None, spread_check=None):
    initial, run = W.triggers("explorer-run.n_clicks")
    out = explorer_outputs(speed, torque, ks, amps, phases, duration, param_values, switches, motor, param_ids, base_params,
                           run=run, initial=initial, repeat=repeat, spread_check=spread_check)
    notices = W.render_notices(out["notices"])
    hidden, shown = {"display": "none"}, {"display": "block"}
    if out.get("pending"):
        figs = [no_update] * len(FIGURES) if last_good else [W.empty_figure("Not computed yet: press Run")] * len(FIGURES)
        return (*figs, no_update, no_update, notices, out["search"], out["params"], no_update,
                page_href("parameters", out["params"]), shown)
    if out["error"]:
        figs = [no_update] * len(FIGURES) if last_good else [W.empty_figure("No result: see the message above")] * len(FIGURES)
        return (*figs, no_update, no_update, notices, no_update, no_update, no_update, no_update, hidden)
    figs = [out["figures"][f] for f in FIGURES]
    return (*figs, out["table"], out["kpis"], notices, out["search"], out["params"], out["view"]["key"],
            page_href("parameters", out["params"]), hidden)


# The home page "/" is the Explorer too (same layout, same query keys).
dash.register_page("pages.explorer_home", path="/", name="Explorer (home)", title="Explorer · dampersim", layout=layout, order=99)
