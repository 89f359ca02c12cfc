"""The Discrepancy page's diagnosis, drawn: summary cards, the verdict with the named
effect, the ranking table and the figures of a diagnosis view."""

from __future__ import annotations

import json

from dash import html

from dampersim.views.discrepancy import discrepancy_figures, ranking_rows, verdict_summary
from dampersim.views.notices import notice
from pages import _widgets as W

#: Names of the calibration factors in the verdict.
CALIBRATION_LABELS = {
    "outer_stiffness": "outer spring rate",
    "inner_stiffness": "inner spring rates",
    "primary_inertia": "J_pri",
    "secondary_inertia": "J_sec",
    "outer_friction": "outer friction factor",
    "inner_friction": "inner friction factors",
}


def _nm(v):
    return W.fmt(v, 3, "N m")


def verdict_block(doc: dict):
    v = verdict_summary(doc)
    parts = [*W.render_notices([notice(f"{v['headline']}. {v['reason']}", v["level"])])]
    if v["effect"]:
        e = v["effect"]
        parts.append(html.P([html.B(e["name"]), f": {e['description']}. Fitted: {v['parameters']}."]))
        parts.append(html.Details([html.Summary("Cause and signature"), html.P(e["cause"]),
                                   html.P(f"Signature: {e['signature']}")]))
    if v["collapses_on"]:
        eta = v["collapse_eta2"]
        parts.append(html.P(f"The calibrated residual varies most with {v['collapses_on'].replace('_', ' ')}"
                            + (f" (η² = {eta:.2f})." if eta is not None else ".")))
    cal = doc.get("calibration") or {}
    if cal:
        parts.append(html.P("Calibration (scale factors on the estimated parameters): " + ", ".join(
            f"{CALIBRATION_LABELS.get(k, k)} ×{W.fmt(x, 3)}" for k, x in cal.items()) + ".", className="hint"))
    return parts


def ranking_table(doc: dict):
    rows = []
    ranked = ranking_rows(doc)
    if any(r["posterior"] is not None for r in ranked):  # a diagnosis with the likelihood
        for r in ranked:
            rows.append({
                "rank": str(r["rank"]), "effect": r["effect"], "parameters": r["parameters"],
                "posterior": W.fmt(r["posterior"], 3), "evidence": W.fmt(r["log_evidence"], 4),
                "gap": _nm(r["gap_held_out_nm"]), "chi2": W.fmt(r["reduced_chi2_held_out"], 3),
                "start": r["start"] or "—", "named": r["named"],
            })
        cols = [("rank", "#"), ("effect", "Effect"), ("parameters", "Fitted parameters"), ("posterior", "Posterior"),
                ("evidence", "Log evidence"), ("gap", "Held-out gap"), ("chi2", "Held-out reduced χ²"),
                ("start", "Fitted from")]
        note = html.P("Ranked by posterior probability: the Laplace evidence of each model fitted on the training points "
                      "(calibration, channel gain and delay, the effect's magnitude and shape) times its prior. "
                      "Candidates without a held-out figure were screened (linearised) but not fitted. Each candidate "
                      "is fitted from the calibrated or the estimated parameters, whichever fits better: from the "
                      "estimated ones when the calibration had imitated the effect. \"refit\": the leading effect "
                      "fitted again together with the calibration factors, from the estimated ones, because its "
                      "first fit left the training points above the noise level.", className="hint")
        return [W.table(cols, rows, cid="discrepancy-ranking-table", highlight=lambda r: r["named"]), note]
    for r in ranked:  # a document from before the likelihood
        rows.append({
            "rank": str(r["rank"]), "effect": r["effect"], "parameters": r["parameters"],
            "gap": _nm(r["gap_held_out_nm"]),
            "improvement": "—" if r["improvement_pct"] is None else f"{r['improvement_pct']:+.0f} %",
            "penalty": _nm(r["penalty_nm"]), "score": _nm(r["score_nm"]),
            "train": _nm(r["train_fit_nm"]), "screen": _nm(r["screen_fit_nm"]), "named": r["named"],
            "start": r["start"] or "—",
        })
    cols = [("rank", "#"), ("effect", "Effect"), ("parameters", "Fitted parameters"), ("gap", "Held-out gap"),
            ("improvement", "Improvement on held-out points"), ("penalty", "Complexity penalty"), ("score", "Score"),
            ("train", "Training fit"), ("screen", "Screen fit"), ("start", "Fitted from")]
    note = html.P("Ranked by score = held-out gap plus a complexity penalty per fitted parameter (a diagnosis made "
                  "before the likelihood).", className="hint")
    return [W.table(cols, rows, cid="discrepancy-ranking-table", highlight=lambda r: r["named"]), note]


def render(view):
    doc = view["diagnosis"]
    figs = discrepancy_figures(doc)
    missing = "This diagnosis document holds no per-point data"

    def fig(name):
        return figs[name] if figs.get(name) is not None else W.empty_figure(missing)

    camp = view.get("campaign") or {}
    s = view.get("summary") or {}
    sims = s.get("simulations", doc.get("simulations"))
    took = W.fmt(s.get("compute_time_s", doc.get("wall_time_s")), 3, "s")
    cards = W.summary_cards([
        ("Verdict", doc["verdict"].replace("_", " "), doc.get("effect") or None),
        ("Held-out gap", f"{_nm(doc.get('gap_before_nm'))} → {_nm(doc.get('gap_after_nm'))}",
         f"noise floor {_nm(doc.get('noise_floor_nm'))}; {len(doc.get('held_out_points') or [])} held-out points"),
        ("Campaign", camp.get("name", "—"), f"{camp.get('torsional', '?')} torsional points, {sims} simulations in {took}"),
    ])
    return (cards, verdict_block(doc), ranking_table(doc), fig("gap"), fig("ranking"), fig("map"), fig("profile"),
            fig("overlays"), json.dumps({k: v for k, v in doc.items() if k not in ("points", "residuals")}, indent=1))


__all__ = ["verdict_block", "ranking_table", "render"]
