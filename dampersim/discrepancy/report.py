"""The diagnosis report: a Diagnosis as a JSON document and back, and what it says in words
(verdict, ranking rows, effect parameters with their units)."""

from __future__ import annotations

from types import SimpleNamespace

from dampersim.discrepancy import diagnose as dg
from dampersim.discrepancy.effects import NAMES, describe, parameters_of
from dampersim.discrepancy.outcome import not_adopted_reason
from dampersim.errors import InputError
from dampersim.jsonsafe import jsonable


def diagnosis_document(diag) -> dict:
    """A Diagnosis -> JSON-ready document: :meth:`Diagnosis.to_json` plus the per-point
    data the figures need (``points``: measured and simulated order amplitudes per stage;
    ``residuals``: stage -> point id -> order errors [N m])."""
    doc = dict(diag.to_json())
    doc["points"] = diag.points
    doc["residuals"] = diag.residuals
    return jsonable(doc)


_DOC_FLOATS = ("noise_floor_nm", "gap_before_nm", "gap_calibrated_nm", "gap_after_nm")


def diagnosis_from_document(doc: dict) -> SimpleNamespace:
    """A diagnosis document (or the ``diagnose --json`` output) -> an object with the
    attributes the figure builders of :mod:`dampersim.plotting.discrepancy` read.
    Missing numbers become NaN; a document without ``points``/``residuals`` (the CLI's)
    gives empty ones, one without ``message``/``missing`` (from before they existed)
    "" and []."""
    if not isinstance(doc, dict) or "verdict" not in doc:
        raise InputError("a diagnosis document: accepted is the JSON of Diagnosis.to_json() (with a 'verdict')")
    d = dict(doc)
    for k in _DOC_FLOATS:
        d[k] = float("nan") if d.get(k) is None else float(d[k])
    d.setdefault("effect", None)
    d.setdefault("effect_parameters", {})
    d.setdefault("ranking", [])
    d.setdefault("held_out_points", [])
    d["points"] = list(d.get("points") or [])
    d["residuals"] = {k: dict(v) for k, v in (d.get("residuals") or {}).items()}
    d.setdefault("locate", {})
    d.setdefault("problems", [])
    d["message"] = d.get("message") or ""
    d["missing"] = list(d.get("missing") or [])
    return SimpleNamespace(**d)


def has_point_data(doc: dict) -> bool:
    """Whether a diagnosis document holds the per-point data of the residual figures."""
    res = (doc or {}).get("residuals") or {}
    return bool((doc or {}).get("points")) and all(s in res for s in ("before", "calibrated", "after"))


def effect_parameter_text(name, values: dict) -> str:
    """"capacity = 930 N m, drag = 0.4 N m s/rad" with the units of the effect registry."""
    units = {p["name"]: p["unit"] for p in parameters_of(name)} if name in NAMES else {}
    items = []
    for k, v in (values or {}).items():
        unit = units.get(k, "")
        val = f"{v:.4g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)
        items.append(f"{k} = {val}" + (f" {unit}" if unit and unit != "-" else ""))
    return ", ".join(items)


def ranking_rows(doc: dict) -> list:
    """Ranking of a diagnosis document as table rows: effect (or pair "a+b"), fitted
    parameters (with units), posterior probability, log evidence, held-out gap [N m] and
    reduced chi^2 on the held-out points, and the starting point the effect was fitted from
    ("calibrated" or "estimated" parameters; "refit": fitted again together with the
    calibration; "pair": on top of another effect). Documents from before the likelihood carry
    improvement, penalty, score, training and screen fits instead (None in newer ones).

    A candidate left unranked because its model runs failed has ``excluded`` (the
    reason, which also stands in its ``parameters`` text: it has no gap) and
    ``failed_points`` (ids of the points where a run with it failed); ``excluded`` is
    None for the others."""
    rows = []
    for i, r in enumerate(doc.get("ranking") or [], start=1):
        gap, score = r.get("gap_held_out_nm"), r.get("score")
        imp = r.get("improvement")
        excluded = r.get("excluded") or None
        fitted = effect_parameter_text(r.get("effect"), r.get("parameters") or {})
        rows.append({
            "rank": i,
            "effect": r.get("effect"),
            "parameters": excluded or fitted or "screened out",
            "excluded": excluded,
            "failed_points": list(r.get("failed_points") or []),
            "gap_held_out_nm": gap,
            "improvement_pct": None if imp is None else 100.0 * imp,
            "penalty_nm": None if gap is None or score is None else score - gap,
            "score_nm": score,
            "train_fit_nm": r.get("train_fit_nm"),
            "screen_fit_nm": r.get("screen_fit_nm"),
            "start": r.get("fitted_from"),
            "posterior": r.get("posterior"),
            "log_evidence": r.get("log_evidence"),
            "reduced_chi2_held_out": r.get("reduced_chi2_held_out"),
            "named": r.get("effect") == ((doc.get("likelihood") or {}).get("model") or doc.get("effect")),
        })
    return rows


def excluded_text(doc: dict) -> str:
    """" Not ranked because their model runs failed: a, b (see the ranking)." for the
    candidates of a diagnosis document that were left unranked, or ""."""
    names = [r.get("effect") for r in doc.get("ranking") or [] if r.get("excluded")]
    return f" Not ranked because their model runs failed: {', '.join(names)} (see the ranking)." if names else ""


def _sentence(text: str) -> str:
    """``text`` with its first letter in upper case."""
    return text[:1].upper() + text[1:]


def verdict_summary(doc: dict) -> dict:
    """What a diagnosis document concludes, in words: {"verdict", "level" (notice level),
    "headline", "reason", "effect" (registry description or None), "parameters" (text with
    units), "collapses_on", "collapse_eta2", "missing"}. The thresholds are those of
    :mod:`dampersim.discrepancy.diagnose`. For a campaign that could not be diagnosed
    (verdict ``insufficient_data``) the reason is the document's ``message`` (what the
    campaign lacks and what is accepted) and ``missing`` lists what it lacks."""
    def nm(v):
        return "—" if v is None else f"{float(v):.3g} N m"

    verdict, effect = doc.get("verdict"), doc.get("effect")
    if verdict == dg.INSUFFICIENT:
        missing = list(doc.get("missing") or [])
        return {
            "verdict": verdict,
            "level": "error",
            "headline": "Insufficient data",
            "reason": _sentence(doc.get("message") or "not diagnosed: the campaign lacks "
                                + (", ".join(missing) or "data") + "."),
            "effect": None,
            "parameters": "",
            "collapses_on": None,
            "collapse_eta2": None,
            "missing": missing,
        }
    floor, cal, after = doc.get("noise_floor_nm"), doc.get("gap_calibrated_nm"), doc.get("gap_after_nm")
    lk = doc.get("likelihood") or {}
    post = doc.get("posterior") or {}
    top = lk.get("model") or (max(post, key=post.get) if post else None)  # the verdict's model
    level_chi = lk.get("noise_level")

    def chi(v):
        return "—" if v is None else f"{float(v):.3g}"

    if not lk:  # a document from before the likelihood: the gap figures only
        reason = f"Held-out gap {nm(cal)} calibrated, {nm(after)} after; noise floor {nm(floor)}."
        level, headline = {"missing_effect": ("success", f"Missing effect: {effect}"),
                           "no_missing_effect": ("info", "No missing effect")}.get(
                               verdict, ("warning", "Unexplained discrepancy"))
    elif verdict == "missing_effect":
        level, headline = "success", f"Missing effect: {top.replace('+', ' and ') if top else effect}"
        reason = (f"Most probable model: {top} (posterior {post.get(top, 0.0):.2f}). With it the held-out misfit falls "
                  f"from reduced chi^2 {chi(lk.get('reduced_chi2_held_out_calibrated'))} (calibrated) to "
                  f"{chi(lk.get('reduced_chi2_held_out'))}, within the noise level {chi(level_chi)}; the held-out gap "
                  f"from {nm(cal)} to {nm(after)}.")
    elif why := not_adopted_reason(verdict, top, post.get(top, 0.0), lk.get("reduced_chi2_held_out"),
                                   lk.get("reduced_chi2_held_out_calibrated"), level_chi):
        level, headline = (("info", "No missing effect") if verdict == "no_missing_effect"
                           else ("warning", "Unexplained discrepancy"))
        reason = _sentence(f"{why} (held-out gap {nm(cal)} calibrated).")
    elif verdict == "no_missing_effect":
        level, headline = "info", "No missing effect"
        reason = (f"The calibrated model is the most probable (posterior {post.get('none', 0.0):.2f}) and its held-out "
                  f"misfit, reduced chi^2 {chi(lk.get('reduced_chi2_held_out_calibrated'))}, is within the noise level "
                  f"{chi(level_chi)} (held-out gap {nm(cal)}): the model explains this campaign.")
    else:
        level, headline = "warning", "Unexplained discrepancy"
        reason = (f"The most probable model, {top} (posterior {post.get(top, 0.0):.2f}), leaves a held-out misfit of "
                  f"reduced chi^2 {chi(lk.get('reduced_chi2_held_out'))}, above the noise level {chi(level_chi)} "
                  f"(held-out gap {nm(cal)} calibrated): no candidate explains the data.")
    reason += excluded_text(doc)
    axes = (doc.get("locate") or {}).get("axes") or {}
    where = (doc.get("locate") or {}).get("collapses_on")
    return {
        "verdict": verdict,
        "level": level,
        "headline": headline,
        "reason": reason,
        "effect": describe(effect) if effect in NAMES else None,
        "parameters": effect_parameter_text(effect, doc.get("effect_parameters") or {}) if effect else "",
        "collapses_on": where,
        "collapse_eta2": (axes.get(where) or {}).get("eta2") if where else None,
        "missing": [],
    }


__all__ = [
    "diagnosis_document",
    "diagnosis_from_document",
    "has_point_data",
    "effect_parameter_text",
    "ranking_rows",
    "excluded_text",
    "verdict_summary",
]
