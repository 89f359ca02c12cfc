"""Background work of the dashboard pages: the request / job / show / cancel callbacks of a
page whose results come from long work, with progress, status lines and time estimates."""

from __future__ import annotations

import os
import uuid

from dash import Input, Output, State, callback, ctx, dcc, html, no_update
from dash.exceptions import PreventUpdate

from dampersim.views.notices import notice
from dampersim.views.store import load_view
from pages._widgets import render_notices


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
        return render_notices([notice(cancel_text, "info")])

    return SimpleCallbacks(request_cb, job_cb, show_cb, cancel_cb)


class SimpleCallbacks:
    def __init__(self, request, job, show, cancel):
        self.request, self.job, self.show, self.cancel = request, job, show, cancel


def show_view(data, render, n_outputs, what="results"):
    """Common part of ``show``: load the view a hit/job refers to and render it; errors
    keep the previous results (no_update) and say what went wrong."""
    if data.get("error"):
        msg = f"The run failed: {data['error']}. The previous {what} are kept."
        return (*([no_update] * n_outputs), "Failed (see the message above).", render_notices([notice(msg, "error")]))
    view = load_view(data.get("key", ""))
    if view is None:
        msg = "The result is no longer in the cache (it was cleared meanwhile); press Run to compute it again."
        return (*([no_update] * n_outputs), render_notices([notice(msg, "warning")]), [])
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
    return render_notices([notice(text, "success")])


def estimate_seconds(n_missing: int, duration: float, cores: int | None = None) -> float:
    """Rough wall time [s] of computing ``n_missing`` test points of ``duration`` [s]."""
    cores = cores or max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))
    per_point = 0.05 + 0.19 * duration  # kernel ~0.13 s per simulated second plus analysis, this class of machine
    if n_missing <= 2:
        return n_missing * per_point
    return 2.0 + n_missing * per_point / min(cores, n_missing)
