"""The Studies page's data: one chapter 7 study run with progress, as figures, its checks
against the thesis's findings and its result document."""

from __future__ import annotations

import json

from dampersim.errors import InputError
from dampersim.plotting.studies import study_figures
from dampersim.studies import STUDIES, run_study
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


def study_view(name: str, quick: bool, progress=None) -> dict:
    """Run study ``name`` (``quick``: the reduced grid) on worker processes.

    ``progress(done, total, cached)`` follows the test points. Returns {"figures": Plotly
    figures, "checks": [(finding, agrees)], "thesis": {quantity: the thesis's value},
    "warnings": [...], "document": the result document as JSON text without the raw
    results}. Raises a DampersimError naming what is wrong.
    """
    if not isinstance(name, str) or name not in STUDY_NAMES:
        raise InputError(f"study {quoted(name)}: accepted is one of {', '.join(STUDY_NAMES)}")
    res = run_study(name, quick=bool(quick), executor="processes", progress=progress)
    return {
        "figures": study_figures(res),
        "checks": list(res["checks"].items()),
        "thesis": dict(res["thesis"]),
        "warnings": list(res["warnings"]),
        "document": json.dumps({k: v for k, v in res.items() if k != "results"}, indent=1),
    }


__all__ = ["STUDY_NAMES", "DEFAULT_STUDY", "DEFAULT_STATE", "parse_studies_query", "study_view"]
