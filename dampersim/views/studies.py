"""The Studies page's data: one chapter 7 study run with progress, as figures, its checks
against the thesis's findings and its result document."""

from __future__ import annotations

import json

from dampersim.plotting.studies import study_figures
from dampersim.studies import STUDIES, run_study

#: Names of the studies, in the order the page lists them.
STUDY_NAMES = tuple(STUDIES)
#: The study a page shows first.
DEFAULT_STUDY = "order-rule"


def study_view(name: str, quick: bool, progress=None) -> dict:
    """Run study ``name`` (``quick``: the reduced grid) on worker processes.

    ``progress(done, total, cached)`` follows the test points. Returns {"figures": Plotly
    figures, "checks": [(finding, agrees)], "thesis": {quantity: the thesis's value},
    "warnings": [...], "document": the result document as JSON text without the raw
    results}. Raises a DampersimError naming what is wrong.
    """
    res = run_study(name, quick=bool(quick), executor="processes", progress=progress)
    return {
        "figures": study_figures(res),
        "checks": list(res["checks"].items()),
        "thesis": dict(res["thesis"]),
        "warnings": list(res["warnings"]),
        "document": json.dumps({k: v for k, v in res.items() if k != "results"}, indent=1),
    }


__all__ = ["STUDY_NAMES", "DEFAULT_STUDY", "study_view"]
