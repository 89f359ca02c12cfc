"""Colourmap: a speed sweep -> FFT colourmaps of input and output torque with order lines,
and order cuts with the input for context ([thesis] §6.3.1).

URL keys: ``speeds`` (rpm, "900:2800:50" or "1200,1500"), ``torque`` [N m], ``orders``,
``duration`` [s], ``window`` [s], ``fmax`` [Hz], ``db`` (true/false), ``cuts`` ("2,4"),
``repeat`` (repeatability runs per speed, 2-32, off when absent: the order cuts get the
min-max of the K runs as a band), plus dotted parameter names. The sweep runs in the
background with progress and cancel; finished test points are cached, so a repeated or
continued sweep is fast.
"""

from __future__ import annotations

import dash
from dash import Input, Output, dcc, html

from dampersim.views.notices import notice
from dampersim.views.params import resolve_system
from dampersim.views.state import (
    PAGES,
    orders_text_from_rows,
    parse_orders_deg,
    parse_query,
    state_from_controls,
)
from dampersim.views.sweeps import colourmap_key, colourmap_points, colourmap_status, colourmap_view
from pages import _frame as F, _jobs as J, _widgets as W

PAGE = "colourmap"

dash.register_page(__name__, path="/colourmap", name="Colourmap", title="Colourmap · dampersim", order=1)

CUT_OPTIONS = [{"label": f" {k}", "value": str(k)} for k in range(1, 9)]


def layout(**query):
    state, notices = parse_query(PAGE, query)
    # a link starts its sweep by itself only when every value in it was accepted (and the
    # request callback checks the autostart budget)
    autorun = any(f.key in query for f in PAGES[PAGE])  # refused values: the defaults run if cheap
    controls = [
        W.section("Speed sweep", [
            W.control("Speeds", W.text("colourmap-speeds", state["speeds"], "900:2800:50"), "rpm",
                      hint="START:STOP:STEP (inclusive) or a list. The thesis steps 10 rpm (191 points); 50 rpm gives a quick overview.",
                      cid="colourmap-speeds"),
            W.control("Mean torque", W.number("colourmap-torque", state["torque"]), "N m", cid="colourmap-torque"),
        ]),
        W.section("Excitation orders", [W.order_rows(PAGE, state["orders"])]),
        W.section("Record", [
            W.control("Simulated time per point", W.number("colourmap-duration", state["duration"]), "s", cid="colourmap-duration",
                      hint="2.6 s as the thesis. A quick sweep: 1.2 s with a 0.6 s window, about half the time, "
                           "but less time to settle and 1.7 Hz frequency resolution."),
            W.control("Analysis window", W.number("colourmap-window", state["window"]), "s", cid="colourmap-window",
                      hint="The end of each record; 1.25 s as the thesis (0.8 Hz resolution)."),
        ], open_=False),
        W.section("Display", [
            W.control("Top frequency", W.number("colourmap-fmax", state["fmax"]), "Hz", cid="colourmap-fmax"),
            dcc.Checklist(id="colourmap-db", options=[{"label": " colour in dB re 1 N m", "value": "db"}],
                          value=["db"] if state["db"] else [], className="checks"),
            W.control("Order cuts", dcc.Checklist(id="colourmap-cuts", options=CUT_OPTIONS,
                                                  value=[c for c in state["cuts"].split(",") if c in {o["value"] for o in CUT_OPTIONS}],
                                                  inline=True, className="checks")),
            W.control("Repeatability runs", W.number("colourmap-repeat", state["repeat"], step=1, placeholder="off"), "runs",
                      hint="Off, or 2-32: every speed runs K times with the input amplitudes scaled by 1 + i·1e-9 and "
                           "the order cuts show the spread of the K runs as a band. The sweep costs K times as much.",
                      cid="colourmap-repeat"),
        ]),
        W.run_panel(PAGE, "Run sweep"),
    ]
    content = [
        *J.background_header(PAGE),
        html.Div([
            W.card(None, W.graph("colourmap-graph", 480, "No sweep shown yet: press Run sweep"), wide=True),
            W.card(None, [W.graph("colourmap-cuts-graph", 650, "No sweep shown yet"),
                                                             html.Div(id="colourmap-cuts-table")], wide=True),
        ], className="cards"),
    ]
    return F.page_frame(PAGE, "Colourmap", "Speed sweep at one mean torque: amplitude over speed and frequency of the input and "
                        "output torque, engine orders as lines, and the order amplitudes along them.",
                        controls, content, notices, J.background_stores(PAGE, state["params"], autorun))


F.register_link_callbacks(PAGE)

CONTROL_INPUTS = [
    Input("colourmap-speeds", "value"),
    Input("colourmap-torque", "value"),
    *W.order_inputs(PAGE),
    Input("colourmap-duration", "value"),
    Input("colourmap-window", "value"),
    Input("colourmap-fmax", "value"),
    Input("colourmap-db", "value"),
    Input("colourmap-cuts", "value"),
    Input("colourmap-repeat", "value"),
]


def state_from_values(values, base_params):
    """Controls -> (state, system, notices)."""
    speeds, torque, ks, amps, phases, duration, window, fmax, db, cuts, *rest = values
    repeat = rest[0] if rest else None  # the Repeatability runs box (None: off)
    orders_text, notices = orders_text_from_rows(ks, amps, phases)
    cuts_text = ",".join(sorted(cuts or [], key=float)) or None
    if cuts is not None and not cuts:
        notices.append(notice("No order cut selected; showing the excited orders."))
        cuts_text = ",".join(f"{k:g}" for k, a, _ in parse_orders_deg(orders_text or "2:300") if k <= 8 and (2 * k).is_integer()) or "2"
    state, more = state_from_controls(PAGE, {"speeds": speeds, "torque": torque, "orders": orders_text, "duration": duration,
                                             "window": window, "fmax": fmax, "db": bool(db), "cuts": cuts_text,
                                             "repeat": repeat}, base_params)
    system = resolve_system(state["params"], more)
    return state, system, notices + more


def request(run, initial, values, base_params, autorun):
    """Foreground part: validate, mirror into the URL, show a cached view at once, refuse a
    sweep above the server's budget, start one within the autostart budget from a link
    (any size within the limit on Run), else show its estimate and wait for Run."""
    state, system, notices = state_from_values(values, base_params)
    return J.sweep_request(PAGE, state, system, notices, run, initial, autorun, view=colourmap_view, status=colourmap_status,
                           key=colourmap_key, noun="sweep", refused="This sweep cannot run", button="Run sweep")


def job(job_data, progress):
    """Background part: validate the request again (state and budget), then run the sweep
    with progress; a cancelled job is killed by Dash (the finished points are in the
    cache already)."""
    return J.sweep_job(PAGE, job_data, progress, points=colourmap_points, view=colourmap_view)


def render(view):
    s = view["summary"]
    runs = s.get("repeat")
    points = f"{s['speeds']} speeds x {runs} runs" if runs else f"{s['points']} points"
    cards = W.summary_cards(
        [(f"Order {r['order']:g}", f"MR ≤ {W.fmt(r['max_mr'], 3)}", f"max at {W.fmt(r['at_rpm'], 4, 'rpm')}") for r in view["cuts"]]
        + [("Sweep", points, f"{s['sweep_time_s']:.1f} s, {s['computed']} computed, {s['from_cache']} cached")]
    )
    rows = [{"order": f"{r['order']:g}", "max": W.fmt(r["max_mr"], 4), "at": W.fmt(r["at_rpm"], 5), "mean": W.fmt(r["mean_mr"], 4),
             "spread": W.fmt(r.get("max_spread_pct"), 3), "spread_at": W.fmt(r.get("spread_at_rpm"), 5)} for r in view["cuts"]]
    cols = [("order", "Order"), ("max", "Largest MR [-]"), ("at", "at speed [rpm]"), ("mean", "Mean MR [-]")]
    if runs:
        cols += [("spread", f"Largest spread of {runs} runs [%]"), ("spread_at", "at speed [rpm]")]
    tab = W.table(cols, rows, cid="colourmap-mr-table")
    return view["figures"]["colourmap"], view["figures"]["cuts"], tab, cards


SHOW_OUTPUTS = [Output("colourmap-graph", "figure"), Output("colourmap-cuts-graph", "figure"),
                Output("colourmap-cuts-table", "children"), Output("colourmap-summary", "children")]


def show(data):
    return J.show_view(data, render, len(SHOW_OUTPUTS), "colourmaps")


callbacks = J.register_background(PAGE, control_inputs=CONTROL_INPUTS, request=request, job=job, show=show,
                                  show_outputs=SHOW_OUTPUTS)
