"""Widgets shared by the dashboard pages: notices, labelled controls, order rows,
parameter boxes, cards, graphs, tables and the run panel (layout only, no physics)."""

from __future__ import annotations

import math

from dash import ALL, Input, dcc, html

from dampersim.views.params import KEY_PARAMETERS, display_value, parameter_value
from dampersim.views.state import MAX_ORDERS, parse_orders_deg

GRAPH_CONFIG = {"displaylogo": False, "responsive": True, "toImageButtonOptions": {"format": "png", "scale": 2},
                "modeBarButtonsToRemove": ["lasso2d", "select2d"]}

def empty_figure(message: str = "Nothing to show yet", height: int = 320) -> dict:
    """Plotly figure shown before anything was computed (an explicit empty state)."""
    return {
        "data": [],
        "layout": {
            "template": "dampersim",
            "height": height,
            "xaxis": {"visible": False},
            "yaxis": {"visible": False},
            "annotations": [{"text": message, "showarrow": False, "font": {"size": 14, "color": "#6B7280"},
                             "xref": "paper", "yref": "paper", "x": 0.5, "y": 0.5}],
            "margin": {"l": 20, "r": 20, "t": 20, "b": 20},
        },
    }


def render_notices(notices, heading: str | None = None):
    """Notice dicts ({"level", "text"}) -> visible alert boxes (an empty list: nothing)."""
    out = []
    for n in notices or ():
        level = n.get("level", "warning") if isinstance(n, dict) else "warning"
        text = n.get("text", "") if isinstance(n, dict) else str(n)
        icon = {"error": "⛔", "warning": "⚠", "info": "ℹ", "success": "✓"}.get(level, "⚠")
        out.append(html.Div([html.Span(icon, className="notice-icon"), html.Span(text, className="notice-text")],
                            className=f"notice notice-{level}", role="alert" if level in ("error", "warning") else "status"))
    if out and heading:
        out.insert(0, html.Div(heading, className="notice-heading"))
    return out


def control(label: str, component, unit: str | None = None, hint: str | None = None, cid: str | None = None):
    """A labelled control row."""
    lab = html.Label([label, html.Span(f" [{unit}]", className="unit") if unit else None], htmlFor=cid, className="control-label")
    return html.Div([lab, component, html.Div(hint, className="hint") if hint else None], className="control")


def section(title: str, children, open_: bool = True):
    return html.Details([html.Summary(title), html.Div(children, className="section-body")], open=open_, className="section")


def number(cid, value, step="any", width=None, placeholder=None):
    """A debounced number box (commits on Enter or blur, so typing runs nothing)."""
    return dcc.Input(id=cid, type="number", value=value, step=step, debounce=True, className="num",
                     placeholder=placeholder, style={"width": width} if width else None)


def text(cid, value, placeholder=None):
    return dcc.Input(id=cid, type="text", value=value, debounce=True, className="txt", placeholder=placeholder)


def slider(cid, value, lo, hi, step, marks=None):
    """Slider that updates on release (a drag never queues runs); typed values commit on blur."""
    if marks is None:
        span = hi - lo
        n = 5
        marks = {float(lo + i * span / n) if not float(lo + i * span / n).is_integer() else int(lo + i * span / n): f"{lo + i * span / n:g}" for i in range(n + 1)}
    return dcc.Slider(id=cid, min=lo, max=hi, step=step, value=value, marks=marks, updatemode="mouseup",
                      tooltip={"placement": "bottom", "always_visible": False}, className="slider")


def order_rows(prefix: str, orders_text: str, rows: int = MAX_ORDERS):
    """Editable excitation orders: one row per order with amplitude [N m] and phase [deg]."""
    try:
        orders = parse_orders_deg(orders_text)
    except ValueError:
        orders = []
    head = html.Div([html.Span("Order"), html.Span("Amplitude [N m]"), html.Span("Phase [deg]")], className="order-row order-head")
    body = []
    for i in range(rows):
        k, a, ph = orders[i] if i < len(orders) else (None, None, None)
        body.append(html.Div(
            [
                dcc.Input(id={"type": f"{prefix}-order", "field": "k", "row": i}, type="number", value=k, step=0.5, debounce=True,
                          className="num", placeholder="—", name=f"order-{i + 1}"),
                dcc.Input(id={"type": f"{prefix}-order", "field": "a", "row": i}, type="number", value=a, step="any", debounce=True,
                          className="num", placeholder="N m", name=f"amplitude-{i + 1}"),
                dcc.Input(id={"type": f"{prefix}-order", "field": "ph", "row": i}, type="number", value=ph, step="any", debounce=True,
                          className="num", placeholder="0", name=f"phase-{i + 1}"),
            ],
            className="order-row",
        ))
    return html.Div([head, *body, html.Div("Leave the order empty to drop a row.", className="hint")], className="order-rows")


def order_inputs(prefix: str):
    """The three pattern-matching inputs of :func:`order_rows` (k, amplitude, phase)."""
    return [Input({"type": f"{prefix}-order", "field": f, "row": ALL}, "value") for f in ("k", "a", "ph")]


def param_controls(prefix: str, system, names):
    """Number boxes for the dotted parameters ``names`` (display units of KEY_PARAMETERS)."""
    rows = []
    for name in names:
        label, unit, factor = KEY_PARAMETERS[name]
        value = parameter_value(system, name)
        cid = {"type": f"{prefix}-param", "name": name}
        step = 1 if isinstance(value, int) and not isinstance(value, bool) else "any"
        rows.append(control(label, dcc.Input(id=cid, type="number", value=display_value(value, factor), step=step, debounce=True,
                                             className="num"), unit if unit != "-" else None, hint=None))
    return rows


def summary_cards(items):
    """Key figures as small cards: [(label, value text, hint or None), ...]."""
    return html.Div([html.Div([html.Div(lab, className="kpi-label"), html.Div(val, className="kpi-value"),
                               html.Div(hint, className="kpi-hint") if hint else None], className="kpi") for lab, val, hint in items],
                    className="kpis")


def graph(cid, height=None, message="Computing…"):
    """A graph with an explicit empty state and a loading overlay."""
    fig = empty_figure(message, height or 320)
    return dcc.Loading(dcc.Graph(id=cid, figure=fig, config=GRAPH_CONFIG, className="graph", style={"height": f"{height}px"} if height else None),
                       type="dot", delay_show=250, overlay_style={"visibility": "visible", "opacity": 0.55}, className="loading")


def card(title, children, cid=None, wide=False):
    return html.Div([html.Div(title, className="card-title") if title else None, html.Div(children, className="card-body")],
                    className="card card-wide" if wide else "card", **({"id": cid} if cid else {}))


def run_panel(page: str, label: str = "Run"):
    """Run / Cancel buttons, a progress bar and a status line for background work."""
    return html.Div(
        [
            html.Div([
                html.Button(label, id=f"{page}-run", n_clicks=0, className="btn btn-primary"),
                html.Button("Cancel", id=f"{page}-cancel", n_clicks=0, disabled=True, className="btn btn-secondary"),
            ], className="buttons"),
            html.Div([
                html.Progress(id=f"{page}-progress", value="0", max="1", className="progress"),
                html.Div("", id=f"{page}-progress-text", className="progress-text"),
            ], id=f"{page}-progress-wrap", className="progress-wrap", style={"display": "none"}),
            html.Div(id=f"{page}-status", className="status", **{"aria-live": "polite"}),
        ],
        className="run-panel",
    )


def run_button(page: str, label: str = "Run"):
    """A Run button for a page that computes in the foreground, hidden until a state
    needs it (above the autostart budget, or a link with refused values)."""
    return html.Div([html.Button(label, id=f"{page}-run", n_clicks=0, className="btn btn-primary")],
                    id=f"{page}-run-wrap", className="buttons", style={"display": "none"})


def triggers(run_prop: str):
    """(initial, run) of a foreground callback: its first call lists every input as
    triggered (or runs outside Dash, e.g. called as a plain function); a user action
    triggers one input, ``run_prop`` when it is the Run button."""
    from dash import ctx

    try:
        fired = list(ctx.triggered_prop_ids) if ctx.triggered_prop_ids else []
    except Exception:  # no callback context: a direct call
        fired = []
    initial = len(fired) != 1
    return initial, (not initial) and fired[0] == run_prop


def fmt(v, digits=3, unit=""):
    """Number -> short text for cards and tables ("—" for None/NaN)."""
    if v is None:
        return "—"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(f):
        return "—"
    s = f"{f:.{digits}g}" if abs(f) < 10 ** digits else f"{f:.0f}"
    return f"{s} {unit}".strip()


def table(columns, rows, cid=None, highlight=None):
    """A plain HTML table; ``columns`` = [(key, title)], ``highlight(row) -> bool``."""
    head = html.Thead(html.Tr([html.Th(t) for _, t in columns]))
    body = html.Tbody([html.Tr([html.Td(r.get(k) if not isinstance(r.get(k), float) else fmt(r.get(k), 4)) for k, _ in columns],
                               className="hl" if highlight and highlight(r) else None) for r in rows])
    return html.Table([head, body], className="data-table", **({"id": cid} if cid else {}))
