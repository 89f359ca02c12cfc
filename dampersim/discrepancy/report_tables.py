"""The diagnosis's model comparison as display rows: the posterior over the models, the
fitted effects of the most probable model with their 90 % intervals, what this campaign
can detect, the recommended next test points, the outliers and the likelihood summary.

Pure functions of a diagnosis document (:meth:`Diagnosis.to_json` or
:func:`dampersim.discrepancy.report.diagnosis_document`), shared by the Discrepancy page
and the HTML report (:func:`report_html`), so both show the same tables. The keys read
are ``posterior``, ``effects``, ``detectability``, ``recommended_points``, ``outliers``
and ``likelihood``. A document from before they existed gives no rows and the note of
:func:`not_computed_text`; a campaign that could not be diagnosed (``insufficient_data``:
empty lists and dicts) gives no rows either. Nothing here raises on a missing or
malformed value: it shows "—" instead.

Each row holds the values (numbers, None when missing) and their text (``*_text`` keys);
:func:`sections` gives the tables as columns of text, in the order the page and the
report show them.
"""

from __future__ import annotations

import math

from dampersim.discrepancy.diagnose import INSUFFICIENT
from dampersim.discrepancy.effects import NAMES, info, parameters_of
from dampersim.jsonsafe import jsonable
from dampersim.plotting import discrepancy as diagnosis_plots

#: Keys of the model comparison in a diagnosis document.
KEYS = ("posterior", "effects", "detectability", "recommended_points", "outliers", "likelihood")
#: Posterior key of the calibrated model without any effect.
NO_EFFECT = "none"
#: Probability content of the intervals in ``effects`` [%].
INTERVAL_PCT = 90
DASH = "—"


# --------------------------------------------------------------------------- small helpers
def _dict(v) -> dict:
    return v if isinstance(v, dict) else {}


def _list(v) -> list:
    return v if isinstance(v, list) else []


def _float(v):
    """A finite float, or None (missing, NaN, text, bool)."""
    if isinstance(v, bool) or v is None:
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def number_text(v, digits: int = 3, unit: str = "") -> str:
    """A number rounded to ``digits`` significant digits without exponent between 1e-4
    and 1e7 ("430", "0.0007", "12300"), with its unit ("-" is none); "—" when missing."""
    f = _float(v)
    if f is None:
        return DASH
    if f == 0:
        s = "0"
    else:
        r = round(f, digits - 1 - math.floor(math.log10(abs(f))))
        s = f"{r:f}".rstrip("0").rstrip(".") if 1e-4 <= abs(r) < 1e7 else f"{r:.{digits - 1}e}"
    return f"{s} {unit}" if unit and unit != "-" else s


def _percent(p) -> str:
    """A probability in per cent, 3 significant digits ("< 0.01 %" and "> 99.9 %" at the ends)."""
    f = _float(p)
    if f is None:
        return DASH
    if 0.0 < f < 1e-4:
        return "< 0.01 %"
    if 0.9995 <= f < 1.0:
        return "> 99.9 %"
    return number_text(100.0 * f, 3) + " %"


def _units(effect) -> dict:
    """{parameter: unit} of a registry effect ({} for an unknown name)."""
    return {p["name"]: p["unit"] for p in parameters_of(effect)} if effect in NAMES else {}


def document_of(diag) -> dict:
    """A Diagnosis (through :meth:`to_json`), the object of
    :func:`dampersim.discrepancy.report.diagnosis_from_document` or a document -> a plain
    document."""
    if isinstance(diag, dict):
        return diag
    to_json = getattr(diag, "to_json", None)
    return jsonable(to_json() if callable(to_json) else dict(vars(diag)))


def computed(doc) -> bool:
    """Whether a document holds the model comparison (not one from before it existed)."""
    return isinstance(doc, dict) and "posterior" in doc


def not_computed_text(doc) -> str:
    """Why a document has no model comparison to show, or "" when it has one."""
    if not isinstance(doc, dict):
        return "Not computed: no diagnosis."
    if doc.get("verdict") == INSUFFICIENT:
        return "Not computed: the campaign could not be diagnosed."
    if not computed(doc):
        return ("Not computed: this diagnosis was made by an earlier version, without the model posterior, intervals, "
                "detectability and recommended test points.")
    return ""


def model_label(model) -> str:
    """A posterior key in words: "none" -> "none (calibrated model alone)", "a+b" -> "a + b"."""
    model = str(model)
    return "none (calibrated model alone)" if model == NO_EFFECT else " + ".join(model.split("+"))


# --------------------------------------------------------------------------- posterior
def posterior_rows(doc) -> list:
    """The posterior over the models, most probable first: {"model" (key), "label",
    "prior", "probability", "log_evidence" (numbers or None), their ``*_text`` and
    "most_probable" (the first row)}. Empty without a posterior."""
    if not isinstance(doc, dict):
        return []
    post = _dict(doc.get("posterior"))
    lik = _dict(doc.get("likelihood"))
    prior, evidence = _dict(lik.get("model_prior")), _dict(lik.get("log_evidence"))
    rows = []
    for model, p in post.items():
        p, pr, ev = _float(p), _float(prior.get(model)), _float(evidence.get(model))
        rows.append({"model": model, "label": model_label(model), "prior": pr, "probability": p, "log_evidence": ev,
                     "prior_text": _percent(pr), "probability_text": _percent(p),
                     "log_evidence_text": DASH if ev is None else f"{ev:.2f}", "most_probable": False})
    rows.sort(key=lambda r: -math.inf if r["probability"] is None else r["probability"], reverse=True)
    if rows and rows[0]["probability"] is not None:
        rows[0]["most_probable"] = True
    return rows


def most_probable(doc):
    """The key of the most probable model (the verdict's: ``likelihood.model``, the most
    probable of the models with a held-out run), or None."""
    model = (doc.get("likelihood") or {}).get("model") if isinstance(doc.get("likelihood"), dict) else None
    if isinstance(model, str):
        return model
    rows = posterior_rows(doc)
    return rows[0]["model"] if rows and rows[0]["most_probable"] else None


# --------------------------------------------------------------------------- effects with intervals
def _interval(v):
    """[low, high] -> (low, high) floats (None for what is missing)."""
    if isinstance(v, (list, tuple)) and len(v) == 2:
        return _float(v[0]), _float(v[1])
    return None, None


def _width_text(spread, noise, name: str, par: str, magnitude) -> str:
    """What set an interval's width, from ``likelihood.interval_spread`` and
    ``interval_spread_noise`` (None: a diagnosis from before them): the Laplace covariance,
    the points' jackknife (its standard deviation over the Laplace one, and the root of its
    expected variance with the noise alone over the Laplace one: a ratio well above that
    figure says the points disagree, a figure well above 1 that few points inform the
    parameter) or, for a magnitude the ramps sized, the ramps."""
    entry = spread.get(name) if spread is not None else None
    if not isinstance(entry, dict):
        return DASH
    if par not in entry:
        return "the ramps" if par == magnitude else DASH
    ratio = _float(entry[par])
    if ratio is None:
        return DASH
    if ratio <= 1.0:
        return "the Laplace covariance"
    alone = _float(_dict(_dict(noise).get(name)).get(par))
    return (f"the points' jackknife, {number_text(ratio, 3)}× the Laplace width" +
            ("" if alone is None else f" ({number_text(alone, 3)}× with the noise alone)"))


def effect_rows(doc) -> list:
    """The effects of the most probable model, one row per fitted parameter: {"effect",
    "parameter", "unit", "value", "low", "high", "magnitude" (the parameter that sets the
    effect's size), "value_text", "interval_text" ("880 – 990 N m", the 90 % interval),
    "width_text" (what set the interval's width: the Laplace covariance, the points' jackknife
    or the ramps; dampersim.discrepancy.intervals)}. Empty for the model without effects and without a
    model comparison."""
    rows = []
    if not isinstance(doc, dict):
        return rows
    lk = _dict(doc.get("likelihood"))
    spread = lk.get("interval_spread") if isinstance(lk.get("interval_spread"), dict) else None
    noise = lk.get("interval_spread_noise")
    for e in _list(doc.get("effects")):
        if not isinstance(e, dict):
            continue
        name = str(e.get("name"))
        units = _units(name)
        magnitude = info(name).magnitude if name in NAMES else None
        values, intervals = _dict(e.get("parameters")), _dict(e.get("intervals"))
        for par in [*values, *(k for k in intervals if k not in values)]:
            unit = units.get(par, "")
            value, (low, high) = values.get(par), _interval(intervals.get(par))
            if _float(value) is not None or value is None:
                value_text = number_text(value, 3, unit)
            else:  # a setting that is no number: shown as it is
                value_text = str(value)
            rows.append({
                "effect": name, "parameter": par, "unit": unit, "value": _float(value), "low": low, "high": high,
                "magnitude": par == magnitude, "value_text": value_text,
                "interval_text": DASH if low is None or high is None else
                f"{number_text(low, 3)} – {number_text(high, 3, unit)}",
                "width_text": DASH if low is None or high is None else _width_text(spread, noise, name, par, magnitude),
            })
    return rows


def effects_note(doc) -> str:
    """What the effects table shows, or why it is empty."""
    if not computed(doc) or doc.get("verdict") == INSUFFICIENT:
        return not_computed_text(doc)
    best = most_probable(doc)
    if best is None:
        return "No model posterior in this diagnosis."
    if not effect_rows(doc):
        return ("The most probable model is the calibrated model alone: no effect parameters." if best == NO_EFFECT
                else f"The most probable model is {model_label(best)}; its fitted parameters are not in this diagnosis.")
    return (f"Fitted parameters of the most probable model, {model_label(best)}, with their {INTERVAL_PCT} % "
            "intervals; the magnitude parameter (the one that sets the effect's size) is highlighted.")


# --------------------------------------------------------------------------- detectability
def detects_below(effect) -> bool | None:
    """True when a smaller magnitude value is the larger effect (the threshold is an upper
    value: clutch_slip's capacity, transducer_bandwidth's cutoff), False when a larger
    one is (a lower value), None for an unknown effect."""
    return (not info(effect).grows) if effect in NAMES else None


def _upper_names() -> str:
    """"clutch_slip (capacity) and transducer_bandwidth (cutoff)": the effects whose
    threshold is an upper value."""
    names = [f"{n} ({info(n).magnitude})" for n in NAMES if detects_below(n)]
    return ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else "".join(names)


def detectability_rows(doc) -> list:
    """What this campaign can detect, in the registry's order: {"effect", "parameter"
    (the magnitude parameter), "unit", "threshold" (its value at the detection threshold,
    None when undetectable), "bound" ("upper", "lower" or None), "detectable" (bool),
    "threshold_text", "meaning" ("detectable below 430 N m", "detectable above 0.0007
    kg m^2" or "not detectable with this campaign")}."""
    det = _dict(doc.get("detectability")) if isinstance(doc, dict) else {}
    order = [n for n in NAMES if n in det] + sorted(str(n) for n in det if n not in NAMES)
    # the candidates the diagnosis considered carry a log evidence; the others were not asked
    evidence = _dict((_dict(doc.get("likelihood")) if isinstance(doc, dict) else {}).get("log_evidence"))
    rows = []
    for name in order:
        par = info(name).magnitude if name in NAMES else None
        unit = _units(name).get(par, "")
        value = _float(det.get(name))
        below = detects_below(name)
        bound = None if below is None else ("upper" if below else "lower")
        if value is None and evidence and name not in evidence:
            meaning = "not considered in this diagnosis"
        elif value is None:
            meaning = "not detectable with this campaign"
        elif below is None:
            meaning = f"threshold {number_text(value, 3, unit)}"
        else:
            meaning = f"detectable {'below' if below else 'above'} {number_text(value, 3, unit)}"
        rows.append({"effect": name, "parameter": par or DASH, "unit": unit if unit and unit != "-" else DASH,
                     "threshold": value, "bound": bound, "detectable": value is not None,
                     "threshold_text": number_text(value, 3), "meaning": meaning})
    return rows


# --------------------------------------------------------------------------- recommended points
def recommended_rows(doc) -> list:
    """The recommended next test points: {"kind", "speed_rpm", "mean_torque_nm", "orders"
    (``--orders`` syntax or None), "protocol" (hysteresis protocol or None), "reason",
    "speed_text", "torque_text", "test" ("orders 2:150", "protocol full-450" or "—")}."""
    rows = []
    for p in _list(doc.get("recommended_points")) if isinstance(doc, dict) else []:
        if not isinstance(p, dict):
            continue
        orders, protocol = p.get("orders"), p.get("protocol")
        test = "; ".join([*([f"orders {orders}"] if orders else []), *([f"protocol {protocol}"] if protocol else [])])
        speed, torque = _float(p.get("speed_rpm")), _float(p.get("mean_torque_nm"))
        rows.append({"kind": str(p.get("kind") or DASH), "speed_rpm": speed, "mean_torque_nm": torque,
                     "orders": orders, "protocol": protocol, "reason": str(p.get("reason") or ""),
                     "speed_text": number_text(speed, 4), "torque_text": number_text(torque, 4),
                     "test": test or DASH})
    return rows


# --------------------------------------------------------------------------- outliers and likelihood
def outliers(doc) -> list:
    """Ids of the test points the robust loss flagged as outliers ([] when none or not computed)."""
    return [str(x) for x in _list(doc.get("outliers"))] if isinstance(doc, dict) else []


def outlier_text(doc) -> str:
    """The outliers in one sentence ("" without a model comparison)."""
    if not computed(doc) or doc.get("verdict") == INSUFFICIENT:
        return ""
    ids = outliers(doc)
    if not ids:
        return "No outliers: the robust loss down-weighted no test point."
    return f"Outliers (down-weighted by the robust loss): {', '.join(ids)}."


def likelihood_text(doc) -> str:
    """The likelihood summary in one line: reduced χ² on the held-out and the training
    points (of the model named by ``likelihood.model`` when the document says which), the
    number of cells, the noise level the verdict compares with (``noise_level``, when
    present), the fitted output gain and delay, and the learning rate when it tempers the
    evidence (below 1) ("" when not computed)."""
    lik = _dict(doc.get("likelihood")) if isinstance(doc, dict) else {}
    if not lik:
        return ""
    held, train = _float(lik.get("reduced_chi2_held_out")), _float(lik.get("reduced_chi2_train"))
    cells, level = _float(lik.get("cells")), _float(lik.get("noise_level"))
    model = lik.get("model")
    nuis = _dict(lik.get("nuisance"))
    gain, delay = _float(nuis.get("output_gain")), _float(nuis.get("delay_ms"))
    parts = []
    if held is not None or train is not None:
        parts.append("Reduced χ²" + (f" of {model_label(model)}:" if isinstance(model, str) and model else "")
                     + f" {number_text(held, 3)} on the held-out points, {number_text(train, 3)} on the training points"
                     + (f" ({cells:.0f} cells)" if cells is not None else "")
                     + (f"; up to {number_text(level, 3)} is the noise level." if level is not None else "."))
    if gain is not None or delay is not None:
        parts.append(f"Fitted output gain {number_text(gain, 4)}, delay {number_text(delay, 3, 'ms')}.")
    eta = _float(lik.get("learning_rate"))
    if eta is not None and eta < 1.0:
        parts.append(f"Even the best model leaves a training misfit above the stated uncertainties: the torsional "
                     f"evidence is read with every uncertainty widened {number_text(1.0 / math.sqrt(eta), 3)}× "
                     f"(learning rate {number_text(eta, 3)}).")
    return " ".join(parts)


# --------------------------------------------------------------------------- tables for the page and the report
POSTERIOR_COLUMNS = [("label", "Model"), ("prior_text", "Prior"), ("probability_text", "Posterior probability"),
                     ("log_evidence_text", "Log evidence")]
EFFECT_COLUMNS = [("effect", "Effect"), ("parameter", "Parameter"), ("value_text", "Fitted value"),
                  ("interval_text", f"{INTERVAL_PCT} % interval"), ("width_text", "Width set by")]
DETECTABILITY_COLUMNS = [("effect", "Effect"), ("parameter", "Magnitude parameter"), ("unit", "Unit"),
                         ("threshold_text", "Threshold"), ("meaning", "With this campaign")]
RECOMMENDED_COLUMNS = [("kind", "Kind"), ("speed_text", "Speed [rpm]"), ("torque_text", "Mean torque [N m]"),
                       ("test", "Excitation orders / protocol"), ("reason", "Why")]

#: Table id -> (title, columns, key of the highlighted rows or None).
TABLES = {
    "posterior": ("Model posterior", POSTERIOR_COLUMNS, "most_probable"),
    "effects": (f"Effects of the most probable model ({INTERVAL_PCT} % intervals)", EFFECT_COLUMNS, "magnitude"),
    "detectability": ("Detectability with this campaign", DETECTABILITY_COLUMNS, None),
    "next-points": ("Recommended next test points", RECOMMENDED_COLUMNS, None),
}


def sections(doc) -> list:
    """The tables of a diagnosis document in the order they are shown: [{"id", "title",
    "columns" ([(key, title)]), "rows" (see the row builders), "highlight" (key of a
    row's bool, or None), "notes" (what the diagnosis found, before the table), "hint"
    (how to read the table, "" without rows), "after" (sentences after it)}].
    Without a model comparison every table is empty and its notes say why."""
    missing = not_computed_text(doc)
    rows = {"posterior": posterior_rows(doc), "effects": effect_rows(doc), "detectability": detectability_rows(doc),
            "next-points": recommended_rows(doc)}
    notes = {
        "posterior": [missing or likelihood_text(doc)] if missing or rows["posterior"] else
        ["No model posterior in this diagnosis."],
        "effects": [effects_note(doc)],
        "detectability": [missing or "No detectability in this diagnosis."] if missing or not rows["detectability"]
        else [],
        "next-points": [missing or "No further test point recommended."] if missing or not rows["next-points"] else [],
    }
    hints = {
        "posterior": "Probability of each model given the campaign, from its evidence (log marginal likelihood) and its "
                     "prior; none is the calibrated model without any effect, a + b two effects together.",
        "effects": "",
        "detectability": "The smallest effect this campaign would detect, as the value of its magnitude parameter: an "
                         f"upper value for {_upper_names()}, where a smaller value is the larger effect, a lower value "
                         "for the others.",
        "next-points": "Test points to measure next, best first: where the most probable models differ most, or where "
                       "an effect this campaign cannot detect would show; with the excitation orders (ORDER:AMPLITUDE "
                       "in N m, as --orders) or the ramp protocol (as hysteresis --protocol).",
    }
    out = []
    for tid, (title, columns, highlight) in TABLES.items():
        out.append({"id": tid, "title": title, "columns": columns, "rows": rows[tid], "highlight": highlight,
                    "notes": [n for n in notes[tid] if n], "hint": hints[tid] if rows[tid] else "",
                    "after": [t for t in ([outlier_text(doc)] if tid == "posterior" else []) if t]})
    return out


def report_html(diag, campaign_name: str = "") -> str:
    """The HTML report of :func:`dampersim.plotting.discrepancy.report_html` with the
    tables of :func:`sections` (the ``diagnose --report`` file); a diagnosis without a
    model comparison (an earlier version's, or ``insufficient_data``) says so once."""
    doc = document_of(diag)
    missing = not_computed_text(doc)
    secs = [{"title": "Model comparison", "notes": [missing]}] if missing else sections(doc)
    return diagnosis_plots.report_html(diag, campaign_name, sections=secs)


__all__ = ["KEYS", "NO_EFFECT", "INTERVAL_PCT", "number_text", "document_of", "computed", "not_computed_text",
           "model_label", "posterior_rows", "most_probable", "effect_rows", "effects_note", "detects_below",
           "detectability_rows", "recommended_rows", "outliers", "outlier_text", "likelihood_text",
           "POSTERIOR_COLUMNS", "EFFECT_COLUMNS", "DETECTABILITY_COLUMNS", "RECOMMENDED_COLUMNS", "TABLES",
           "sections", "report_html"]
