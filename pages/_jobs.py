"""Background work of the dashboard pages: the request / job / show / cancel callbacks of a
page whose results come from long work, with progress, status lines and time estimates.

The browser never carries a job's state: the request callback validates it, keeps it on
the server under an opaque ticket (:mod:`dampersim.views.tickets`) and sends only
``{"ticket", "work", "nonce"}`` (``work``: the key of the view the job produces). The
job queue shares identical requests on the work key stored with the ticket
(:func:`ticket_work`), never on the posted one. The job callback loads the state by
ticket and hands it to the page's ``job``, which validates it again and checks the budget
before any work; a result whose key is not the ticket's work is refused. Every error text shown comes from :func:`dampersim.incidents.public_message`.
"""

from __future__ import annotations

import time
import uuid

from dash import Input, Output, State, callback, ctx, dcc, html, no_update
from dash.exceptions import PreventUpdate

from dampersim import costs
from dampersim.errors import InputError
from dampersim.incidents import public_message
from dampersim.views import tickets
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
    def request_safe(run, initial, values, base_params, autorun):
        try:
            return request(run, initial, values, base_params, autorun)
        except Exception as exc:  # the page keeps working and says what happened, nothing more
            return {"notices": [notice(f"This request could not be handled: {public_message(exc, page + ' request')}", "error")],
                    "status": "Not started."}

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
        out = request_safe(run, initial, values, base_params, autorun)
        job_data = out.get("job")
        if job_data is not None:
            try:
                ticket = tickets.issue(page, job_data["state"], job_data.get("work"))
                job_data = {"ticket": ticket, "work": job_data.get("work"), "nonce": uuid.uuid4().hex}
            except Exception as exc:
                out["notices"] = list(out.get("notices") or []) + [
                    notice(f"The run cannot be started: {public_message(exc, page + ' ticket')}", "error")]
                out["status"] = "Not started."
                job_data = None
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
        return run_ticket(page, job, job_data, lambda done, total, text: set_progress((str(done), str(max(total, 1)), text)))

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


#: What the page says when a job's ticket is unknown or expired.
EXPIRED_TEXT = "this request has expired; press Run"
#: What the page says when a job produced another view than its ticket's work.
MISMATCH_TEXT = "the result does not match this request (its inputs changed meanwhile); press Run"


def ticket_work(args) -> str | None:
    """Work key of a background call, read on the server from the ticket it posts (for
    the job queue's ``work_of``): the ticket's page and stored work, or None (no ticket,
    unknown, expired, or no work stored: the job is not shared). A posted ``work`` is
    ignored."""
    from pages._background import first_argument

    first = first_argument(args)
    entry = tickets.peek(first.get("ticket") if isinstance(first, dict) else None)
    if entry is None or not entry["work"]:
        return None
    return f"{entry['page']}\0{entry['work']}"


def refused_result(message: str, args):
    """Result of a call the job queue refused (queue full), as the page shows it: a
    ticket job's ``{"error", "nonce"}``, else a background-callback error (shown by the
    callback's ``on_error``)."""
    from pages._background import first_argument, refused_error

    first = first_argument(args)
    if isinstance(first, dict) and "ticket" in first:
        nonce = first.get("nonce")
        return {"error": message, "nonce": nonce if isinstance(nonce, str) and len(nonce) <= 64 else None}
    return refused_error(message)


def run_ticket(page: str, job, job_data, progress) -> dict:
    """The body of a job callback: load the request of ``job_data["ticket"]`` (nothing
    else of the posted data is used) and run ``job({"state": ...}, progress)``, which
    validates the state again and checks the budget. Returns {"key"} or {"error"} with
    the posted nonce (a text, kept only when it is one); a key other than the ticket's
    stored work is refused (waiters sharing this job asked for that work)."""
    nonce = job_data.get("nonce") if isinstance(job_data, dict) else None
    nonce = nonce if isinstance(nonce, str) and len(nonce) <= 64 else None
    entry = tickets.redeem(job_data.get("ticket") if isinstance(job_data, dict) else None, page)
    if entry is None:
        return {"error": EXPIRED_TEXT, "nonce": nonce}
    try:
        out = job({"state": entry["state"]}, progress)
    except Exception as exc:
        out = {"error": public_message(exc, page + " job")}
    if entry["work"] and isinstance(out, dict) and "key" in out and out["key"] != entry["work"]:
        out = {"error": MISMATCH_TEXT}
    return {**out, "nonce": nonce}


def checked_job_state(page: str, job_data):
    """(state, system) of a job's request after validating it again like a link (the
    page's fields and parameter state, :func:`dampersim.views.state.reparse_state`), then
    the budget on its whole cost (:func:`dampersim.costs.admit`). Raises InputError naming
    what is refused, before any work."""
    from dampersim.views.params import resolve_system
    from dampersim.views.state import reparse_state, state_cost

    raw = job_data.get("state") if isinstance(job_data, dict) else None
    state, notices = reparse_state(page, raw)
    system = resolve_system(state["params"], notices)
    if notices:
        raise InputError("the request is not valid any more (" + "; ".join(n["text"] for n in notices)
                         + "); press Run to start it again")
    costs.admit(state_cost(page, system, state))
    return state, system


def sweep_request(page: str, state: dict, system, notices: list, run: bool, initial: bool, autorun: bool, *,
                  view, status, key, noun: str, refused: str, button: str) -> dict:
    """The foreground part of a sweep page (Colourmap, Maps): the whole sweep admitted
    before any look-up (refused above the budget), a cached view shown at once, else the
    missing points' cost: the job starts on Run, or from a link within the autostart
    budget, otherwise the estimate waits for ``button``. ``view(system, state,
    cache_only=True)``, ``status(system, state)`` -> {"total", "cached"} and ``key(system,
    state)`` are the page's; ``refused`` starts the message of a sweep that cannot run."""
    from dampersim.errors import DampersimError
    from dampersim.views.state import state_cost, to_query

    out = {"search": to_query(page, state), "params": state["params"], "notices": notices}
    try:
        costs.admit(state_cost(page, system, state))  # the whole sweep, before any look-up
        hit = view(system, state, cache_only=True)
        st = status(system, state)
    except costs.BudgetError as exc:
        out["notices"] = notices + [budget_refusal(exc)]
        out["status"] = "Not started."
        return out
    except DampersimError as exc:
        out["notices"] = notices + [notice(f"{refused}: {public_message(exc)}", "error")]
        out["status"] = "Not started."
        return out
    if hit is not None:
        out["hit"] = {"key": hit["key"], "from": "cache"}
        out["status"] = "Loading from the cache…"
        return out
    cost = state_cost(page, system, state, n_points=st["total"] - st["cached"])
    decision = costs.admit(cost)
    if run or (initial and autorun and decision == "run" and not notices):  # a control's value refused: wait for Run
        out["job"] = {"state": state, "work": key(system, state)}
        out["status"] = f"Starting the {noun}: {st['total']} test points, {st['cached']} already in the cache…"
        return out
    out["status"] = render_notices([cost_notice(cost, decision, button)])
    return out


def sweep_job(page: str, job_data, progress, *, points, view) -> dict:
    """The background part of a sweep page: the request validated again
    (:func:`checked_job_state`), then ``view(system, state, progress=...)`` with progress
    lines that say how many other jobs share the cores; {"key"} or {"error"}."""
    from dampersim.errors import DampersimError
    from dampersim.views.sweeps import SweepRegistry

    try:
        state, system = checked_job_state(page, job_data)
    except DampersimError as exc:
        return {"error": public_message(exc)}
    reg = SweepRegistry()
    t0 = time.monotonic()
    try:
        total = len(points(state))
        reg.start(page, total)
        progress(0, total, f"0 / {total} test points · starting worker processes…")

        def on_progress(done, total, cached):
            reg.beat()
            progress(done, total, progress_text(done, total, cached, time.monotonic() - t0, reg.others()))

        return {"key": view(system, state, progress=on_progress)["key"]}
    except Exception as exc:  # keep the server's page alive with a message that leaks nothing
        return {"error": public_message(exc, f"{page} job")}
    finally:
        reg.stop()


class SimpleCallbacks:
    def __init__(self, request, job, show, cancel):
        self.request, self.job, self.show, self.cancel = request, job, show, cancel


def show_view(data, render, n_outputs, what="results"):
    """Common part of ``show``: load the view a hit/job refers to and render it; errors
    keep the previous results (no_update) and say what went wrong."""
    if not isinstance(data, dict):
        data = {}
    if data.get("error"):
        err = data["error"]
        err = err if isinstance(err, str) and len(err) <= 2000 else "unexpected error"
        msg = f"The run failed: {err}. The previous {what} are kept."
        return (*([no_update] * n_outputs), "Failed (see the message above).", render_notices([notice(msg, "error")]))
    key = data.get("key")
    try:
        view = load_view(key) if isinstance(key, str) and 0 < len(key) <= 128 else None
        if view is not None:
            shown = render(view)
    except Exception as exc:
        msg = f"The result cannot be shown: {public_message(exc, 'show')}. The previous {what} are kept."
        return (*([no_update] * n_outputs), "Failed (see the message above).", render_notices([notice(msg, "error")]))
    if view is None:
        msg = "The result is no longer in the cache (it was cleared meanwhile); press Run to compute it again."
        return (*([no_update] * n_outputs), render_notices([notice(msg, "warning")]), [])
    status = data.get("status") if isinstance(data.get("status"), str) else None
    return (*shown, status or status_line(view, data), [])


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
    notes = [notice(text, "success")]
    if s.get("cache_notice"):  # e.g. a full disk: the results are shown but were not stored
        notes.append(notice(s["cache_notice"], "warning"))
    return render_notices(notes)


def cost_notice(cost, decision: str, button: str) -> dict:
    """The notice of a request that waits for its Run button: the estimate, and why it
    did not start by itself."""
    text = f"Not computed yet: {cost.what}, {cost.text()} (about {cost.duration()} of one core)."
    if decision == "ask":
        b = costs.budgets()
        text += (f" That is above the {costs.work_duration(b.autostart)} of computing that "
                 f"start by themselves on this server ({costs.AUTOSTART_ENV}).")
    text += f" Press {button} to start it."
    return notice(text, "info")


def foreground_run(page: str, key: str, system, state: dict, run: bool, compute) -> dict:
    """The one computation of a page that answers while the browser waits (Explorer,
    Segments): a cached view under ``key`` at once (no slot); otherwise the cost is
    admitted as a foreground request (:func:`dampersim.costs.admit`), a point above the
    autostart budget waits for Run, and ``compute(system, state)`` runs in one of the
    server's foreground slots. Returns {"view"}, {"pending", "notice"} or {"error",
    "notice"} (with "busy" when no slot was free); nothing here raises."""
    try:
        hit = load_view(key)
        if hit is not None:
            return {"view": hit}
        from dampersim.views.state import state_cost

        cost = state_cost(page, system, state)
        decision = costs.admit(cost, foreground=True)  # BudgetError above the limit: nothing runs
        if not run and decision == "ask":
            return {"pending": True, "notice": cost_notice(cost, decision, "Run")}
        with costs.foreground_slot():  # ServerBusy at once when every slot computes
            return {"view": compute(system, state)}
    except costs.ServerBusy as exc:
        return {"error": str(exc), "busy": True,
                "notice": notice(f"Not computed: {exc}. The previous results are kept.", "warning")}
    except costs.BudgetError as exc:
        return {"error": public_message(exc), "notice": budget_refusal(exc)}
    except Exception as exc:
        msg = public_message(exc, page)
        return {"error": msg,
                "notice": notice(f"The test point could not be simulated: {msg}. The previous results are kept.", "error")}


def budget_refusal(exc) -> dict:
    """The notice of a request above the server's budget (nothing runs)."""
    return notice(f"Refused: {public_message(exc)}. Use fewer points, a shorter record or a coarser step, or run it "
                  f"from the command line.", "error")
