"""The Discrepancy page's model comparison, drawn: the posterior over the models (with the
likelihood summary and the outliers), the effects of the most probable model with their
90 % intervals, the detectability of each effect with this campaign and the recommended
next test points. One card per table; rows and texts come from
:mod:`dampersim.discrepancy.report_tables` (the same tables as the HTML report)."""

from __future__ import annotations

from dash import Output, html

from dampersim.discrepancy.report_tables import TABLES, sections
from pages import _widgets as W

#: Table id -> id of its card body (the callback's output).
CARD_IDS = {tid: f"discrepancy-{tid}" for tid in TABLES}
OUTPUTS = [Output(cid, "children") for cid in CARD_IDS.values()]


def cards():
    """The cards of the tables, empty until a diagnosis is shown."""
    return [W.card(title, html.Div(html.P("No diagnosis shown yet.", className="hint"), id=CARD_IDS[tid]),
                   wide=tid in ("posterior", "effects", "next-points"))  # effects: five columns
            for tid, (title, _columns, _hl) in TABLES.items()]


def _section(sec):
    out = [html.P(n) for n in sec["notes"]]
    if sec["rows"]:
        hl = sec["highlight"]
        out.append(W.table(sec["columns"], sec["rows"], cid=f"{CARD_IDS[sec['id']]}-table",
                           highlight=(lambda r: bool(r.get(hl))) if hl else None))
    out += [html.P(t) for t in sec["after"]]
    if sec["hint"]:
        out.append(html.P(sec["hint"], className="hint"))
    return out


def render_tables(doc: dict) -> tuple:
    """The children of every card (in the order of :data:`OUTPUTS`) for a diagnosis document;
    a document without a model comparison says so in each card."""
    return tuple(_section(sec) for sec in sections(doc))


__all__ = ["CARD_IDS", "OUTPUTS", "cards", "render_tables"]
