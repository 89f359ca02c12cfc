"""Layout and callback helpers shared by the dashboard pages (no physics here).

URL state: each page parses its query string with :func:`dampersim.views.parse_query` in
its ``layout(**query)``, renders its controls from that state and mirrors every later
state back into the URL through a page-local ``dcc.Location(refresh=False)`` (writing
``search`` changes the address bar without re-rendering the page). The "Copy link" button
copies that address.
"""

from __future__ import annotations

import math

from dash import ALL, Input, Output, State, clientside_callback, dcc, html

from dampersim import views

GRAPH_CONFIG = {"displaylogo": False, "responsive": True, "toImageButtonOptions": {"format": "png", "scale": 2},
                "modeBarButtonsToRemove": ["lasso2d", "select2d"]}

#: Plotly figure shown before anything was computed (an explicit empty state).
def empty_figure(message: str = "Nothing to show yet", height: int = 320) -> dict:
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


# --------------------------------------------------------------------------- notices
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


# --------------------------------------------------------------------------- page frame
def page_frame(page: str, title: str, intro: str, controls, content, notices=(), extra=()):
    """Two-column page: a control panel (left) and the results (right).

    Holds the page-local Location that mirrors the state into the URL, the link notices
    (rendered once from the query string) and the copy-link bar.
    """
    return html.Div(
        [
            dcc.Location(id=f"{page}-url", refresh=False),
            html.Div(
                [
                    html.Div([html.H1(title, className="page-title"), html.P(intro, className="page-intro")], className="page-heading"),
                    copy_link(page),
                ],
                className="page-header",
            ),
            html.Div(render_notices(notices, "The link contained values that could not be used:"), id=f"{page}-link-notices",
                     className="notices"),
            html.Div(
                [
                    html.Aside(controls, className="panel controls", **{"aria-label": "controls"}),
                    html.Section(content, className="results"),
                ],
                className="page-grid",
            ),
            *extra,
        ],
        className=f"page page-{page}",
    )


def copy_link(page: str):
    """"Copy link" button plus the current link in a read-only field."""
    return html.Div(
        [
            dcc.Input(id=f"{page}-link-text", type="text", readOnly=True, value="", className="link-text", name="link"),
            html.Div([dcc.Clipboard(id=f"{page}-copy", content="", className="clipboard-icon", title="Copy link to this view"),
                      html.Span("Copy link", className="copy-label")],
                     className="copy-button", title="Copy a link that reproduces this view"),
            html.Span("", id=f"{page}-copied", className="copied"),
        ],
        className="link-bar",
    )


def register_link_callbacks(page: str):
    """Client-side: show the page's current link; copy it on click."""
    clientside_callback(
        """
        function(search, pathname) {
            return window.location.origin + (pathname || window.location.pathname) + (search || "");
        }
        """,
        Output(f"{page}-link-text", "value"),
        Input(f"{page}-url", "search"),
        State(f"{page}-url", "pathname"),
    )
    clientside_callback(
        """
        function(n, link) {
            if (!n) { return [window.dash_clientside.no_update, ""]; }
            return [link || window.location.href, "Link copied"];
        }
        """,
        Output(f"{page}-copy", "content"),
        Output(f"{page}-copied", "children"),
        Input(f"{page}-copy", "n_clicks"),
        State(f"{page}-link-text", "value"),
        prevent_initial_call=True,
    )


# --------------------------------------------------------------------------- controls
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


def order_rows(prefix: str, orders_text: str, rows: int = views.MAX_ORDERS):
    """Editable excitation orders: one row per order with amplitude [N m] and phase [deg]."""
    try:
        orders = views.parse_orders_deg(orders_text)
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


def orders_text_from_rows(ks, amps, phases):
    """Order rows -> ("2:300,4:100@90", notices). A row without an order is skipped; a row
    with an order but a missing amplitude is refused with a notice."""
    items, notes = [], []
    for i, (k, a, ph) in enumerate(zip(ks or [], amps or [], phases or [])):
        if k in (None, ""):
            continue
        if a in (None, ""):
            notes.append(views.notice(f"Order row {i + 1} (order {k}) has no amplitude; the row is ignored."))
            continue
        item = f"{_num(k)}:{_num(a)}"
        if ph not in (None, "") and float(ph) != 0.0:
            item += f"@{_num(ph)}"
        items.append(item)
    return ",".join(items), notes


def _num(v) -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isfinite(f) and f.is_integer():
        return str(int(f))
    return repr(f)


def display_value(v, factor: float = 1.0):
    """SI value -> display value rounded to 7 significant digits (None stays None)."""
    if v is None or isinstance(v, (bool, str)):
        return v
    x = float(v) * factor
    if x == 0:
        return 0
    x = float(f"{x:.7g}")
    return int(x) if x.is_integer() else x


def control_params(base_params, names, values, notices):
    """Parameter state from parameter controls on top of the link's parameter state.

    ``values`` are display values (see :data:`dampersim.views.KEY_PARAMETERS`); a control
    that still shows the (rounded) current value keeps the exact current value, so a link's
    values survive the round trip through the controls unchanged. Returns (params, system).
    """
    base_params = base_params or {"set": None, "overrides": {}}
    set_id = base_params.get("set")
    base = views.base_system(set_id if set_id and views.load_parameter_set(set_id) else None)
    current = views.resolve_system(base_params)
    overrides = dict(base_params.get("overrides") or {})
    for name, shown in zip(names, values):
        if name not in views.KEY_PARAMETERS:
            continue
        label, unit, factor = views.KEY_PARAMETERS[name]
        now = views.parameter_value(current, name)
        if shown is None or shown == "":
            notices.append(views.notice(f"{label} is empty; using {display_value(now, factor)}{' ' + unit if unit and unit != '-' else ''}."))
            continue
        if isinstance(now, (bool, str)):
            if shown != now:
                overrides[name] = shown
            continue
        if display_value(now, factor) == display_value(shown):
            continue
        try:
            si = float(shown) / factor
        except (TypeError, ValueError):
            notices.append(views.notice(f"{label} = {shown!r} is not a number; using {display_value(now, factor)}."))
            continue
        if isinstance(now, int) and not isinstance(now, bool):
            if not float(shown).is_integer():
                notices.append(views.notice(f"{label} = {shown} is not a whole number; using {now}."))
                continue
            si = int(round(si))
        overrides[name] = si
    system, accepted = views.apply_overrides(base, overrides, notices, source="controls")
    return {"set": base_params.get("set"), "overrides": accepted}, system


def param_controls(prefix: str, system, names):
    """Number boxes for the dotted parameters ``names`` (display units of KEY_PARAMETERS)."""
    rows = []
    for name in names:
        label, unit, factor = views.KEY_PARAMETERS[name]
        value = views.parameter_value(system, name)
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


def progress_text(done, total, cached, elapsed, others=0):
    """"12 / 39 test points (3 from cache) · 4 s · about 9 s left"."""
    parts = [f"{done} / {total} test points"]
    if cached:
        parts[0] += f" ({cached} from the cache)"
    parts.append(f"{elapsed:.0f} s")
    computed = done - cached
    if 0 < computed < total - cached:
        left = elapsed / computed * (total - done)
        parts.append(f"about {left:.0f} s left")
    return " · ".join(parts) + others_text(others, "sweep", "running on this server: sharing the cores, this takes longer")


def others_text(others: int, noun: str, tail: str) -> str:
    """" · 2 other sweeps running on this server: …" when ``others`` other runs share the
    server's cores, else "" (appended to a progress text)."""
    return f" · {others} other {noun}{'s' if others > 1 else ''} {tail}" if others else ""


# --------------------------------------------------------------------------- background work
def background_header(page: str) -> list:
    """The notices (from the request and from the job) and summary line above a
    background page's results; the job callbacks below write into them."""
    return [
        html.Div(id=f"{page}-run-notices", className="notices"),
        html.Div(id=f"{page}-job-notices", className="notices"),
        html.Div(id=f"{page}-summary"),
    ]


def background_stores(page: str, params: dict, autorun: bool):
    """Stores of a page with background work: link parameters, autorun flag, the request
    of a job, its outcome and cache hits."""
    from dash import dcc

    return [
        dcc.Store(id=f"{page}-base-params", data=params),
        dcc.Store(id=f"{page}-autorun", data=bool(autorun)),
        dcc.Store(id=f"{page}-job"),
        dcc.Store(id=f"{page}-done"),
        dcc.Store(id=f"{page}-hit"),
    ]


CANCEL_TEXT = ("Cancelled. The test points finished so far stay in the cache and the results shown are the previous ones; "
               "press Run to continue where the sweep stopped.")


def trigger_kind(run_prop: str | None = None):
    """(initial, run) of the current callback: a page's first call lists every input as
    triggered (the page layout was just inserted); a user action triggers one input."""
    from dash import ctx

    fired = list(ctx.triggered_prop_ids) if ctx.triggered_prop_ids else []
    initial = len(fired) != 1
    run = (not initial) and run_prop is not None and fired[0] == run_prop
    return initial, run


def register_background(page: str, *, control_inputs, request, job, show, show_outputs, interval: int = 300,
                        cancel_text: str = CANCEL_TEXT):
    """Wire a page whose results come from long work (sweeps, ramps) run as a background
    callback, and return the callback functions (plain functions, for tests).

    request(run, initial, values, base_params, autorun) -> dict with search, params,
        notices, status, hit (a cached view's {"key"}) and job (state to compute) -- the
        foreground callback: a cache hit returns at once, a miss starts the job on Run;
    job(job_data, progress) -> {"key"} or {"error"} -- runs in the background process;
        progress(done, total, text) updates the progress bar;
    show(data) -> tuple of values for ``show_outputs`` followed by status and notices.
    """
    import uuid

    from dash import callback, ctx, no_update
    from dash.exceptions import PreventUpdate

    @callback(
        Output(f"{page}-url", "search"),
        Output("shared-params", "data", allow_duplicate=True),
        Output(f"{page}-run-notices", "children"),
        Output(f"{page}-status", "children"),
        Output(f"{page}-hit", "data"),
        Output(f"{page}-job", "data"),
        Input(f"{page}-run", "n_clicks"),
        *control_inputs,
        State(f"{page}-base-params", "data"),
        State(f"{page}-autorun", "data"),
        prevent_initial_call="initial_duplicate",
    )
    def request_cb(n_clicks, *args):
        values, base_params, autorun = list(args[:-2]), args[-2], args[-1]
        initial, run = trigger_kind(f"{page}-run.n_clicks")
        out = request(run, initial, values, base_params, autorun)
        job_data = out.get("job")
        if job_data is not None:
            job_data = {**job_data, "nonce": uuid.uuid4().hex}
        hit = out.get("hit")
        if hit is not None:
            hit = {**hit, "nonce": uuid.uuid4().hex}
        return (
            out["search"] if out.get("search") is not None else no_update,
            out["params"] if out.get("params") is not None else no_update,
            render_notices(out.get("notices")),
            out.get("status", ""),
            hit if hit is not None else no_update,
            job_data if job_data is not None else no_update,
        )

    @callback(
        Output(f"{page}-done", "data"),
        Input(f"{page}-job", "data"),
        background=True,
        progress=[Output(f"{page}-progress", "value"), Output(f"{page}-progress", "max"), Output(f"{page}-progress-text", "children")],
        running=[
            (Output(f"{page}-run", "disabled"), True, False),
            (Output(f"{page}-cancel", "disabled"), False, True),
            (Output(f"{page}-progress-wrap", "style"), {"display": "block"}, {"display": "none"}),
        ],
        cancel=[Input(f"{page}-cancel", "n_clicks")],
        interval=interval,
        prevent_initial_call=True,
    )
    def job_cb(set_progress, job_data):
        if not job_data:
            raise PreventUpdate
        out = job(job_data, lambda done, total, text: set_progress((str(done), str(max(total, 1)), text)))
        return {**out, "nonce": job_data.get("nonce")}

    @callback(
        *show_outputs,
        Output(f"{page}-status", "children", allow_duplicate=True),
        Output(f"{page}-job-notices", "children"),
        Input(f"{page}-hit", "data"),
        Input(f"{page}-done", "data"),
        prevent_initial_call=True,
    )
    def show_cb(hit, done):
        fired = set(ctx.triggered_prop_ids.values()) if ctx.triggered_prop_ids else set()
        data = hit if (f"{page}-hit" in fired and hit) else (done or hit)
        if not data:
            raise PreventUpdate
        return show(data)

    @callback(
        Output(f"{page}-status", "children", allow_duplicate=True),
        Input(f"{page}-cancel", "n_clicks"),
        prevent_initial_call=True,
    )
    def cancel_cb(n_clicks):
        if not n_clicks:
            raise PreventUpdate
        return render_notices([views.notice(cancel_text, "info")])

    return SimpleCallbacks(request_cb, job_cb, show_cb, cancel_cb)


class SimpleCallbacks:
    def __init__(self, request, job, show, cancel):
        self.request, self.job, self.show, self.cancel = request, job, show, cancel


def show_view(data, render, n_outputs, what="results"):
    """Common part of ``show``: load the view a hit/job refers to and render it; errors
    keep the previous results (no_update) and say what went wrong."""
    from dash import no_update

    if data.get("error"):
        msg = f"The run failed: {data['error']}. The previous {what} are kept."
        return (*([no_update] * n_outputs), "Failed (see the message above).", render_notices([views.notice(msg, "error")]))
    view = views.load_view(data.get("key", ""))
    if view is None:
        msg = "The result is no longer in the cache (it was cleared meanwhile); press Run to compute it again."
        return (*([no_update] * n_outputs), render_notices([views.notice(msg, "warning")]), [])
    return (*render(view), data.get("status") or status_line(view, data), [])


def status_line(view, data):
    s = view.get("summary", {})
    if data.get("from") == "cache":
        text = "Shown from the cache"
        if "points" in s:
            text += f" ({s['points']} test points, computed earlier in {s.get('sweep_time_s', 0):.1f} s)"
        text += "."
    else:
        text = f"Done in {s.get('compute_time_s', 0):.1f} s."
        if "points" in s:
            text += f" {s['points']} test points: {s.get('computed', 0)} computed now, {s.get('from_cache', 0)} from the cache."
    return render_notices([views.notice(text, "success")])


def estimate_seconds(n_missing: int, duration: float, cores: int | None = None) -> float:
    """Rough wall time [s] of computing ``n_missing`` test points of ``duration`` [s]."""
    import os

    cores = cores or max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))
    per_point = 0.05 + 0.19 * duration  # kernel ~0.13 s per simulated second plus analysis, this class of machine
    if n_missing <= 2:
        return n_missing * per_point
    return 2.0 + n_missing * per_point / min(cores, n_missing)
