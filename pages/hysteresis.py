"""Hysteresis: a torque-ramp protocol at several speeds -> loops, dynamic stiffness and the
energy dissipated per loop ([thesis] §3.3.1, §6.3.2, §7.3.1).

URL keys: ``protocol`` (Table 3.1 name), ``speeds`` (rpm list, e.g. "1000,2000"), ``rate``
[N m/s], ``hold`` [s], ``windup`` (total/outer/inner), ``lowpass`` (true/false), plus
dotted parameter names. A protocol at 50 N m/s simulates about 30 s per speed, so it runs
in the background with progress and cancel; results are cached.
"""

from __future__ import annotations

import time

import dash
from dash import Input, Output, dcc, html

from dampersim import costs
from dampersim.errors import DampersimError
from dampersim.incidents import public_message
from dampersim.views.hysteresis import PROTOCOL_NAMES, hysteresis_key, hysteresis_view, protocol_label, simulated_seconds
from dampersim.views.notices import notice
from dampersim.views.params import resolve_system
from dampersim.views.state import (MAX_LOOP_SPEEDS, PAGES, parse_query, state_cost, state_from_controls,
                                   to_query)
from pages import _frame as F, _jobs as J, _widgets as W

PAGE = "hysteresis"

dash.register_page(__name__, path="/hysteresis", name="Hysteresis", title="Hysteresis · dampersim", order=2)


def layout(**query):
    state, notices = parse_query(PAGE, query)
    # only a link whose every value was accepted starts by itself (within the autostart budget)
    autorun = any(f.key in query for f in PAGES[PAGE])  # refused values: the defaults run if cheap
    controls = [
        W.section("Protocol ([thesis] Table 3.1)", [
            W.control("Ramp protocol", dcc.Dropdown(id="hysteresis-protocol", options=[{"label": protocol_label(p), "value": p} for p in PROTOCOL_NAMES],
                                                    value=state["protocol"], clearable=False, className="dropdown")),
            W.control("Speeds", W.text("hysteresis-speeds", state["speeds"], "1000,2000"), "rpm",
                      hint=f"One loop per speed, at most {MAX_LOOP_SPEEDS}; the thesis tests 1000-2000 rpm.", cid="hysteresis-speeds"),
            W.control("Ramp rate", W.number("hysteresis-rate", state["rate"]), "N m/s", hint="The rig ramps at 50 N m/s.", cid="hysteresis-rate"),
            W.control("Hold at the peaks", W.number("hysteresis-hold", state["hold"]), "s", cid="hysteresis-hold"),
        ]),
        W.section("Display", [
            W.control("Windup", dcc.RadioItems(id="hysteresis-windup", options=[{"label": " total (as measured)", "value": "total"},
                                                                            {"label": " outer set", "value": "outer"},
                                                                            {"label": " inner set", "value": "inner"}],
                                               value=state["windup"], className="radios")),
            dcc.Checklist(id="hysteresis-lowpass", options=[{"label": " 10 Hz first-order low pass (as the rig data)", "value": "on"}],
                          value=["on"] if state["lowpass"] else [], className="checks"),
        ]),
        W.run_panel(PAGE, "Run ramps"),
    ]
    content = [
        *J.background_header(PAGE),
        html.Div([
            W.card(None, W.graph("hysteresis-loops", 460, "No loops shown yet: press Run ramps"), wide=True),
            W.card(None, W.graph("hysteresis-stiffness", 380, "No loops shown yet")),
            W.card(None, [W.graph("hysteresis-energy", 380, "No loops shown yet")]),
            W.card("Loop figures", html.Div(id="hysteresis-table"), wide=True),
        ], className="cards"),
    ]
    return F.page_frame(PAGE, "Hysteresis", "Quasi-static torque ramps at constant speed: input torque over windup, the knee where "
                        "the outer set meets its hardstop, dynamic stiffness along the loading branch and the energy per loop.",
                        controls, content, notices, J.background_stores(PAGE, state["params"], autorun))


F.register_link_callbacks(PAGE)

CONTROL_INPUTS = [
    Input("hysteresis-protocol", "value"),
    Input("hysteresis-speeds", "value"),
    Input("hysteresis-rate", "value"),
    Input("hysteresis-hold", "value"),
    Input("hysteresis-windup", "value"),
    Input("hysteresis-lowpass", "value"),
]


def state_from_values(values, base_params):
    protocol, speeds, rate, hold, windup, lowpass = values
    state, notices = state_from_controls(PAGE, {"protocol": protocol, "speeds": speeds, "rate": rate, "hold": hold,
                                                "windup": windup, "lowpass": bool(lowpass)}, base_params)
    system = resolve_system(state["params"], notices)
    return state, system, notices


def request(run, initial, values, base_params, autorun):
    """Foreground part: validate, cache hit, budget refusal, autostart within the
    autostart budget, else the estimate and the Run button."""
    state, system, notices = state_from_values(values, base_params)
    out = {"search": to_query(PAGE, state), "params": state["params"], "notices": notices}
    try:
        cost = state_cost(PAGE, system, state)
        decision = costs.admit(cost)
        view = hysteresis_view(system, state, cache_only=True)
    except costs.BudgetError as exc:
        out["notices"] = notices + [J.budget_refusal(exc)]
        out["status"] = "Not started."
        return out
    except DampersimError as exc:
        out["notices"] = notices + [notice(f"These loops cannot run: {public_message(exc)}", "error")]
        out["status"] = "Not started."
        return out
    if view is not None:
        out["hit"] = {"key": view["key"], "from": "cache"}
        out["status"] = "Loading from the cache…"
        return out
    n = len(state["speeds"].split(","))
    sim = simulated_seconds(state)
    if run or (initial and autorun and decision == "run" and not notices):  # a control's value refused: wait for Run
        out["job"] = {"state": state, "work": hysteresis_key(system, state)}
        out["status"] = f"Starting: {n} speed{'s' if n > 1 else ''}, {sim:.0f} s simulated each…"
        return out
    out["status"] = W.render_notices([J.cost_notice(cost, decision, "Run ramps")])
    return out


def job(job_data, progress):
    """Background part: validate the request again (state and budget), then run the ramps."""
    try:
        state, system = J.checked_job_state(PAGE, job_data)
    except DampersimError as exc:
        return {"error": public_message(exc)}
    t0 = time.monotonic()
    n = len(state["speeds"].split(","))
    sim = simulated_seconds(state)

    def on_progress(done, total, _cached):
        el = time.monotonic() - t0
        text = f"{done} / {total} speeds · {el:.0f} s"
        if done < total:
            text += f" · simulating speed {done + 1} ({sim:.0f} s of ramp)"
            if done:
                text += f", about {el / done * (total - done):.0f} s left"
        progress(done, total, text)

    try:
        on_progress(0, n, 0)
        view = hysteresis_view(system, state, progress=on_progress)
        return {"key": view["key"]}
    except Exception as exc:
        return {"error": public_message(exc, "hysteresis job")}


def render(view):
    rows = view["loops"]
    data = [{"speed": W.fmt(r["speed_rpm"], 5), "knee_t": W.fmt(r["knee_torque_nm"], 4), "knee_w": W.fmt(r["knee_windup_deg"], 3),
             "k": W.fmt(r["stiffness_below_nm_per_deg"], 3), "e": W.fmt(r["energy_j"], 3), "wmax": W.fmt(r["max_windup_deg"], 3),
             "wmin": W.fmt(r["min_windup_deg"], 3)} for r in rows]
    tab = W.table([("speed", "Speed [rpm]"), ("knee_t", "Knee torque [N m]"), ("knee_w", "Knee windup [deg]"),
                   ("k", "Stiffness below knee [N m/deg]"), ("e", "Energy per loop [J]"), ("wmax", "Max windup [deg]"),
                   ("wmin", "Min windup [deg]")], data, cid="hysteresis-loop-table")
    first = rows[0] if rows else {}
    s = view["summary"]
    cards = W.summary_cards([
        ("Knee", W.fmt(first.get("knee_torque_nm"), 4, "N m"), f"at {W.fmt(first.get('speed_rpm'), 5, 'rpm')}"),
        ("Energy per loop", W.fmt(first.get("energy_j"), 3, "J"), f"at {W.fmt(first.get('speed_rpm'), 5, 'rpm')}"),
        ("Loops", f"{s['speeds']} × {s['protocol']}", f"{s['simulated_s']:.0f} s simulated each"),
    ])
    f = view["figures"]
    return f["loops"], f["stiffness"], f["energy"], tab, cards


SHOW_OUTPUTS = [Output("hysteresis-loops", "figure"), Output("hysteresis-stiffness", "figure"), Output("hysteresis-energy", "figure"),
                Output("hysteresis-table", "children"), Output("hysteresis-summary", "children")]


def show(data):
    return J.show_view(data, render, len(SHOW_OUTPUTS), "loops")


callbacks = J.register_background(PAGE, control_inputs=CONTROL_INPUTS, request=request, job=job, show=show,
                                  show_outputs=SHOW_OUTPUTS,
                                  cancel_text="Cancelled. The loops shown are the previous ones; press Run ramps to start again.")
