"""The Studies page's data: one chapter 7 study run with progress, as figures, its checks
against the thesis's findings and its result document; and the study's cost, estimated
from its plan before anything runs and judged by the server's budget
(:func:`dampersim.costs.admit`)."""

from __future__ import annotations

import json

from dampersim import costs
from dampersim.errors import InputError
from dampersim.plotting.studies import study_figures
from dampersim.studies import STUDIES, run_study, study_cost
from dampersim.views.notices import notice, query_value
from dampersim.views.pulsation import parse_bool, quoted

#: Names of the studies, in the order the page lists them.
STUDY_NAMES = tuple(STUDIES)
#: The study a page shows first.
DEFAULT_STUDY = "order-rule"
#: Page state defaults.
DEFAULT_STATE = {"study": DEFAULT_STUDY, "quick": True}


def parse_studies_query(query: dict | None) -> tuple:
    """The Studies page's query -> ``(state, notices)``: ``study`` (one of
    :data:`STUDY_NAMES`) and ``quick`` (the reduced grid, true/false). A bad value gives a
    notice naming the key, the value, what is accepted and the default used. Never raises.
    """
    query = dict(query or {})
    state, notices = dict(DEFAULT_STATE), []
    if query.get("study") is not None:
        raw = query_value(query, "study", notices, "Study")
        if isinstance(raw, str) and raw.strip() in STUDY_NAMES:
            state["study"] = raw.strip()
        else:
            notices.append(notice(f"Study (study={quoted(raw)}) is not a known study: accepted is one of "
                                  f"{', '.join(STUDY_NAMES)}. Using {DEFAULT_STUDY}."))
    if query.get("quick") is not None:
        raw = query_value(query, "quick", notices, "Reduced grid")
        try:
            state["quick"] = parse_bool(raw)
        except ValueError as exc:
            notices.append(notice(f"Reduced grid (quick={quoted(raw)}) {exc}: accepted is true or false (1/0). Using 1."))
    return state, notices


def _check_name(name):
    if not isinstance(name, str) or name not in STUDY_NAMES:
        raise InputError(f"study {quoted(name)}: accepted is one of {', '.join(STUDY_NAMES)}")


def study_request_cost(name, quick) -> costs.Cost:
    """Cost of study ``name`` (``quick``: the reduced grid) on the default parameter set:
    work [step·DOF] and bytes [B] (:func:`dampersim.studies.study_cost`, from the study's
    own grid, every run counted as computed). Raises InputError for an unknown study."""
    _check_name(name)
    return study_cost(name, bool(quick))


def estimate_text(cost: costs.Cost) -> str:
    """The estimate shown next to the Run button: "about 6.3e9 step·DOF, ~7 min of one core"."""
    work = f"{cost.work:.1e}".replace("e+0", "e").replace("e+", "e")
    return f"about {work} step·DOF, ~{cost.duration()} of one core"


def admit_study(name, quick) -> costs.Cost:
    """The study's cost when this server's budget admits it (a study never starts by itself,
    so within the limit it runs on its Run button whatever the autostart budget). Raises
    :class:`dampersim.costs.BudgetError` (the estimate and the limit) above the budget,
    InputError for an unknown study; nothing is simulated either way."""
    cost = study_request_cost(name, quick)
    costs.admit(cost)
    return cost


def study_view(name: str, quick: bool, progress=None) -> dict:
    """Run study ``name`` (``quick``: the reduced grid) on worker processes, after checking
    its cost against the server's budget again (:func:`admit_study`: nothing runs above it).

    ``progress(done, total, cached)`` follows the test points. Returns {"figures": Plotly
    figures, "checks": [(finding, agrees)], "thesis": {quantity: the thesis's value},
    "warnings": [...], "document": the result document as JSON text without the raw
    results}. Raises a DampersimError naming what is wrong (a BudgetError above the budget).
    """
    admit_study(name, quick)
    res = run_study(name, quick=bool(quick), executor="processes", progress=progress)
    return {
        "figures": study_figures(res),
        "checks": list(res["checks"].items()),
        "thesis": dict(res["thesis"]),
        "warnings": list(res["warnings"]),
        "document": json.dumps({k: v for k, v in res.items() if k != "results"}, indent=1),
    }


__all__ = ["STUDY_NAMES", "DEFAULT_STUDY", "DEFAULT_STATE", "parse_studies_query", "study_request_cost", "estimate_text",
           "admit_study", "study_view"]
