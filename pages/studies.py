"""Studies: run any chapter 7 study with progress, see its figures, its checks against the
thesis's findings and the thesis's numbers. Layout and callbacks only.

A study never starts from a link: it runs on the Run button. Its cost (from the study's
own grid, :func:`dampersim.views.studies.study_request_cost`) is shown next to the button;
a press first checks it against the server's budget (above it: a notice with the estimate
and the limit, and nothing starts), and the background job checks it again before it
simulates anything (it never trusts the posted request).
"""

from __future__ import annotations

import dash
from dash import Input, Output, State, callback, dcc, html, no_update

from dampersim import costs
from dampersim.errors import DampersimError
from dampersim.incidents import public_message
from dampersim.views.notices import notice
from dampersim.views.studies import STUDY_NAMES, admit_study, estimate_text, parse_studies_query, study_request_cost, study_view
from pages._background import job_error_text
from pages._widgets import render_notices

dash.register_page(__name__, path="/studies", name="Studies", title="Studies · dampersim", order=8)


def layout(**query):
    """The page from its link: ``study`` (a study name) and ``quick`` (1/0); bad values get
    a notice and the default (never an error page). Nothing runs before the Run button."""
    state, notices = parse_studies_query(query)
    return html.Div([
        html.H2("Studies (thesis chapter 7)"),
        html.Div(render_notices(notices, "The link contained values that could not be used:"), id="st-link-notices",
                 className="notices"),
        html.Div([
            dcc.Dropdown(id="st-name", options=[{"label": n, "value": n} for n in STUDY_NAMES], value=state["study"],
                         clearable=False),
            dcc.Checklist(id="st-quick", options=[{"label": " reduced grid", "value": "1"}],
                          value=["1"] if state["quick"] else [], inline=True),
            html.Button("Run study", id="st-run"),
            html.Span(id="st-estimate", className="estimate"),
            html.Button("Cancel", id="st-cancel"),
        ], className="controls"),
        html.Div(id="st-request-notices", className="notices"),
        dcc.Store(id="st-job"),
        html.Progress(id="st-progress", value="0", max="1"),
        html.Div(id="st-progress-text"),
        html.Div(id="st-checks"),
        html.Div(id="st-figures"),
        html.Details([html.Summary("Result document (JSON)"), html.Pre(id="st-json")]),
    ])


def refusal(exc, name) -> dict:
    """The notice of a study above the server's budget: the estimate and the limit."""
    cli = f"dampersim study {name}" if isinstance(name, str) and name in STUDY_NAMES else "dampersim study NAME"
    return notice(f"Refused: {public_message(exc)}. Nothing was started. Use the reduced grid, or run it from the "
                  f"command line ({cli}).", "error")


@callback(Output("st-estimate", "children"), Input("st-name", "value"), Input("st-quick", "value"))
def estimate(name, quick):
    """The selected study's estimate next to the Run button, and whether it exceeds the
    server's budget (computed from the study's plan; nothing runs)."""
    try:
        cost = study_request_cost(name, bool(quick))
    except DampersimError as exc:
        return public_message(exc)
    text = estimate_text(cost)
    try:
        costs.admit(cost)
    except costs.BudgetError as exc:
        b = exc.budget
        if cost.work > b.limit:
            limit = f"{b.limit:.1e}".replace("e+0", "e").replace("e+", "e") + f" step·DOF, {costs.BUDGET_ENV}"
        else:
            limit = f"{costs.bytes_text(b.bytes_limit)} of memory, {costs.BYTES_ENV}"
        return f"{text}: above this server's limit ({limit}), it will not run"
    except DampersimError as exc:  # a malformed budget setting: its message
        return f"{text} ({public_message(exc)})"
    return text


@callback(
    Output("st-request-notices", "children"), Output("st-job", "data"),
    Input("st-run", "n_clicks"), State("st-name", "value"), State("st-quick", "value"),
    prevent_initial_call=True,
)
def request(n_clicks, name, quick):
    """The Run button: admit the study's cost before a job starts. Above the budget: a
    notice naming the estimate and the limit, and no job. Else the job's request."""
    if not n_clicks:
        return no_update, no_update
    try:
        admit_study(name, bool(quick))
    except costs.BudgetError as exc:
        return render_notices([refusal(exc, name)]), no_update
    except Exception as exc:  # DampersimError: its message; anything else: an incident id
        return render_notices([notice(public_message(exc, "study request"), "error")]), no_update
    return [], {"study": name, "quick": bool(quick), "n": int(n_clicks)}


@callback(
    Output("st-figures", "children"), Output("st-checks", "children"), Output("st-json", "children"),
    Input("st-job", "data"),
    background=True,
    progress=[Output("st-progress", "value"), Output("st-progress", "max"), Output("st-progress-text", "children")],
    running=[(Output("st-run", "disabled"), True, False)],
    cancel=[Input("st-cancel", "n_clicks")],
    prevent_initial_call=True,
    on_error=lambda exc: ([], html.Div(f"The study did not run: {job_error_text(exc)}.", className="notice"), ""),
)
def run_job(set_progress, job):
    """The background job of a request that :func:`request` admitted; :func:`run` checks
    the posted values and the budget again."""
    job = job if isinstance(job, dict) else {}
    return run(set_progress, None, job.get("study"), job.get("quick"))


def run(set_progress, _n, name, quick):
    """Run study ``name`` (``quick``: the reduced grid) -> (figures, checks, document).
    The cost is admitted again first (:func:`study_view`): above the budget, a refusal
    notice and nothing is simulated."""
    def prog(done, total, cached):
        set_progress((str(done), str(max(total, 1)), f"{done} / {total} points ({cached} from cache)"))

    try:
        view = study_view(name, quick=bool(quick), progress=prog)
    except costs.BudgetError as exc:
        return [], html.Div(render_notices([refusal(exc, name)])), ""
    except Exception as exc:  # DampersimError: its message; anything else: an incident id, never a traceback
        return [], html.Div(public_message(exc, "study run"), className="notice"), ""
    figs = [dcc.Graph(figure=f) for f in view["figures"]]
    checks = html.Ul([html.Li(f"{k}: {'agrees' if v else 'differs'}") for k, v in view["checks"]]
                     + [html.Li(f"thesis: {k} = {v}") for k, v in view["thesis"].items()]
                     + [html.Li(w) for w in view["warnings"]])
    return figs, checks, view["document"]
