"""Figures of the discrepancy benchmark, computed from its JSON lines.

``bench/bench_discrepancy.py`` writes one JSON object per finished case. Each row holds
``id``, ``kind`` (``effect``: one hidden effect; ``pair``: two; ``control``: none, at most
a change the calibration can absorb; ``out_of_library``: a change no library effect
describes), ``truth`` (at least ``effects``: [{name, parameters}]) and the diagnosis's
keys (``verdict``, ``effect``, ``effects``, ``posterior``, ``detectability``,
``likelihood``, ``noise_floor_nm``, ``gap_*_nm``, ...). A row with ``error`` is a case
whose run failed. Keys a diagnosis does not have are read as absent, so that rows written
before the diagnosis reported a posterior still count where they can.

:func:`summary` gives the figures; :func:`summary_table` prints them; :func:`case_table`
prints one Markdown row per case, in the manner of the case tables of docs/discrepancy.md.
"""

from __future__ import annotations

import math
import numbers
import statistics

from dampersim.discrepancy import selection
from dampersim.discrepancy.effects import EFFECTS

KINDS = ("effect", "pair", "control", "out_of_library")
#: posterior probability at which a named model counts as claimed
CLAIM_PROBABILITY = 0.9
#: range of a control's held-out reduced chi^2 that reads as uncertainties neither inflated
#: (below) nor optimistic (above): the one the diagnosis issue asks of the controls
CONTROL_CHI2_RANGE = (0.5, 1.5)


def latest(rows) -> tuple[list, int]:
    """(the last successful row of every case id in order of first appearance, number of
    ids that only failed)."""
    good, failed, order = {}, set(), []
    for r in rows:
        cid = r.get("id")
        if cid not in order:
            order.append(cid)
        if r.get("error"):
            failed.add(cid)
        else:
            good[cid] = r
    return [good[c] for c in order if c in good], len([c for c in order if c in failed and c not in good])


def true_effects(row) -> dict:
    """{name: parameters} of the effects hidden in a row's truth."""
    return {e["name"]: dict(e.get("parameters") or {}) for e in (row.get("truth") or {}).get("effects") or ()}


def named(row) -> list:
    """Names of the effects the diagnosis adopted (verdict ``missing_effect``): its
    ``effects`` list, else ``effect``. The ``effects`` list describes the most probable
    model whatever the verdict, so it alone does not count as naming."""
    if row.get("verdict") != "missing_effect":
        return []
    effs = row.get("effects")
    if isinstance(effs, list) and effs:
        return [e.get("name") for e in effs if isinstance(e, dict) and e.get("name")]
    return [row["effect"]] if row.get("effect") else []


def probability(row, name: str):
    """Posterior probability that effect ``name`` is present (the sum over the models that
    contain it); None without a posterior."""
    post = row.get("posterior")
    if not post:
        return None
    return sum(_number(v) or 0.0 for k, v in post.items() if name in k.split("+"))


def top_model(row) -> str:
    """The verdict's model (``likelihood.model``: the most probable of the models with a
    held-out run), else the model with the highest posterior (``none``, an effect, or
    ``a+b``); without a posterior the adopted effect(s) (``none`` for none)."""
    model = (row.get("likelihood") or {}).get("model")
    if isinstance(model, str):
        return model
    post = row.get("posterior") or {}
    vals = {k: _number(v) for k, v in post.items() if _number(v) is not None}
    if vals:
        return max(vals, key=vals.get)
    return "+".join(named(row)) or "none"


def claimed(row, p: float = CLAIM_PROBABILITY):
    """True when a model naming an effect has posterior >= ``p``; None without a posterior."""
    post = row.get("posterior")
    if not post:
        return None
    return any(k != "none" and _number(v) is not None and _number(v) >= p for k, v in post.items())


def interval(row, name: str, parameter: str):
    """[low, high] the diagnosis reports for ``parameter`` of effect ``name``, or None."""
    for e in row.get("effects") or ():
        if isinstance(e, dict) and e.get("name") == name:
            iv = (e.get("intervals") or {}).get(parameter)
            if isinstance(iv, (list, tuple)) and len(iv) == 2 and None not in map(_number, iv):
                return _number(iv[0]), _number(iv[1])
    return None


def side(name: str, magnitude: float, threshold) -> str:
    """``beyond`` when ``magnitude`` of effect ``name`` lies past the detectability
    ``threshold`` (above it for effects that grow with their value, below it for clutch
    capacity and transducer cut-off), ``below`` when not, ``unknown`` without a threshold."""
    threshold = _number(threshold)
    if threshold is None:
        return "unknown"
    past = magnitude > threshold if EFFECTS[name].grows else magnitude < threshold
    return "beyond" if past else "below"


def _share(k: int, n: int) -> dict:
    return {"count": int(k), "of": int(n), "share": (k / n) if n else None}


def _number(x):
    """x as a finite float, else None (also for strings, lists and other non-numbers)."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        return None
    return float(x) if math.isfinite(float(x)) else None


def _finite(x) -> bool:
    return _number(x) is not None


def _spread(values) -> dict:
    v = [float(x) for x in values if _finite(x)]
    if not v:
        return {"median": None, "min": None, "max": None, "of": 0}
    return {"median": statistics.median(v), "min": min(v), "max": max(v), "of": len(v)}


def effect_case(row, p: float = CLAIM_PROBABILITY) -> dict:
    """Per single-effect row: true name and magnitude, threshold, side, top-1, adopted,
    detected (present with posterior >= ``p``, or adopted without a posterior), inside
    the interval."""
    (name, params), = true_effects(row).items()
    mag_par = EFFECTS[name].magnitude
    m = float(params[mag_par])
    thr = (row.get("detectability") or {}).get(name)
    iv = interval(row, name, mag_par)
    prob = probability(row, name)
    adopted = name in named(row)
    return {"name": name, "magnitude": m, "threshold": thr, "side": side(name, m, thr),
            "top1": top_model(row) == name, "named": adopted,
            "detected": adopted if prob is None else prob >= p,
            "inside": iv is not None and iv[0] <= m <= iv[1]}


def summary(rows, p: float = CLAIM_PROBABILITY) -> dict:
    """The benchmark's figures from its JSON lines (see the module doc):

    * effect cases beyond the tool's own detectability estimate: top-1 correct rate (the
      highest-posterior model is the true effect), the share adopted (verdict
      ``missing_effect`` naming it) and the share with the true magnitude inside the
      reported 90 % interval; below it: the detection rate (the true effect present with
      posterior >= ``p``; adopted, for rows without a posterior) and the share adopted;
      cases without an estimate are counted apart;
    * controls and out-of-library cases: the share where a named model has posterior >=
      ``p`` (false claims), and the share where any effect is adopted;
    * reduced chi^2 on controls (held out and training: median and range), and the share
      of controls whose held-out value lies within CONTROL_CHI2_RANGE, below it and above it;
    * two-effect cases: the share with both effects named (adopted, or the top model is
      their pair), and with at least one;
    * counts of every kind and of failed cases.
    """
    good, failed = latest(rows)
    by = {k: [r for r in good if r.get("kind") == k] for k in KINDS}
    cases = [effect_case(r, p) for r in by["effect"]]
    beyond = [c for c in cases if c["side"] == "beyond"]
    below = [c for c in cases if c["side"] == "below"]
    unknown = [c for c in cases if c["side"] == "unknown"]
    out = {"counts": {k: len(v) for k, v in by.items()}, "failed": failed, "rows": len(good)}
    out["effect_beyond"] = {"top1_correct": _share(sum(c["top1"] for c in beyond), len(beyond)),
                            "named_correct": _share(sum(c["named"] for c in beyond), len(beyond)),
                            "magnitude_in_90_interval": _share(sum(c["inside"] for c in beyond), len(beyond))}
    out["effect_below"] = {"detected": _share(sum(c["detected"] for c in below), len(below)),
                           "named_correct": _share(sum(c["named"] for c in below), len(below))}
    out["effect_no_estimate"] = {"top1_correct": _share(sum(c["top1"] for c in unknown), len(unknown)),
                                 "named_correct": _share(sum(c["named"] for c in unknown), len(unknown))}
    for kind in ("control", "out_of_library"):
        rs = by[kind]
        cl = [claimed(r, p) for r in rs]
        out[kind] = {"claimed_p90": _share(sum(bool(c) for c in cl if c is not None), sum(c is not None for c in cl)),
                     "named_any": _share(sum(bool(named(r)) for r in rs), len(rs))}
    like = [r.get("likelihood") or {} for r in by["control"]]
    out["control"]["reduced_chi2_held_out"] = _spread(x.get("reduced_chi2_held_out") for x in like)
    out["control"]["reduced_chi2_train"] = _spread(x.get("reduced_chi2_train") for x in like)
    held = [float(x["reduced_chi2_held_out"]) for x in like if _finite(x.get("reduced_chi2_held_out"))]
    lo, hi = CONTROL_CHI2_RANGE
    out["control"]["reduced_chi2_held_out_within"] = _share(sum(lo <= v <= hi for v in held), len(held))
    out["control"]["reduced_chi2_held_out_below"] = _share(sum(v < lo for v in held), len(held))
    out["control"]["reduced_chi2_held_out_above"] = _share(sum(v > hi for v in held), len(held))
    both = one = 0
    for r in by["pair"]:
        truth = set(true_effects(r))
        got = set(named(r)) | set(top_model(r).split("+"))
        both += truth <= set(named(r)) or set(top_model(r).split("+")) == truth
        one += bool(truth & got)
    out["pair"] = {"both_named": _share(both, len(by["pair"])), "one_named": _share(one, len(by["pair"]))}
    return out


def posterior_without_misfit(row):
    """{model: probability} without the unnamed smooth misfit beside "none"
    (:mod:`dampersim.discrepancy.unnamed`): the row's log evidences (``likelihood.log_evidence``
    [nats], which carry the misfit's gain on "none" alone) with that gain
    (``likelihood.unnamed_misfit.log_evidence`` [nats]) taken off "none", under the row's
    priors (``likelihood.model_prior``). A model without a finite evidence or with a zero prior
    gets 0. None when the row lacks the evidences, the priors, a finite gain or a finite
    evidence of "none" (rows from before the misfit, or from its first form, which kept one
    gain per model and no top-level ``log_evidence``)."""
    like = row.get("likelihood") or {}
    le, prior = like.get("log_evidence"), like.get("model_prior")
    misfit = like.get("unnamed_misfit")
    gain = _number(misfit.get("log_evidence")) if isinstance(misfit, dict) else None
    if not isinstance(le, dict) or not isinstance(prior, dict) or gain is None:
        return None
    log_z, priors = {}, {}
    for k, v in le.items():
        e, p = _number(v), _number(prior.get(k))
        usable = e is not None and p is not None and p > 0.0
        log_z[k] = e - (gain if k == "none" else 0.0) if usable else -math.inf
        priors[k] = p if usable else 1.0  # read only for models with a finite evidence
    if not math.isfinite(log_z.get("none", -math.inf)):
        return None
    return selection.posterior(log_z, priors)


def _leaders(post, n: int = 2) -> str:
    ranked = sorted(((_number(v), k) for k, v in (post or {}).items() if _number(v) is not None), reverse=True)
    return "; ".join(f"{k} {v:.3f}" for v, k in ranked[:n]) or "—"


def _num(x, fmt: str) -> str:
    x = _number(x)
    return "—" if x is None else format(x, fmt)


def _cell(text) -> str:
    return str(text).replace("|", "\\|") if text not in (None, "") else "—"


#: columns of :func:`case_row`
CASE_TABLE_HEADER = ("| Case | Truth | Verdict | Posterior (two most probable) | Without the misfit | "
                     "Misfit's gain on \"none\": torsional, ramps → total [nats] | "
                     "Held out: calibrated → verdict's model | Training | η | "
                     "Most probable model's fit [90 % interval] | Detectability of the truth (side) | Runs | "
                     "Diagnosis wall [s] |\n" + "|---" * 13 + "|")


def case_row(row) -> str:
    """One Markdown row of a finished case under CASE_TABLE_HEADER, in the manner of the case
    tables of docs/discrepancy.md: the truth's description; the verdict; the two most probable
    models with and without the unnamed misfit (:func:`posterior_without_misfit`, effect names
    as ``effects --json`` gives them); the misfit's gain on "none" [nats] from the torsional
    points and the ramps and in all; the held-out reduced chi^2 of the calibrated model and of
    the verdict's model; the training one; the learning rate η; the magnitudes of the most
    probable model's effects (fitted whatever the verdict; adopted only with
    ``missing_effect``) with their 90 % intervals, in each effect's unit (not printed); for a
    single hidden effect the diagnosis's detectability threshold of it and the side its true
    magnitude lies on (:func:`side`); the model runs; the diagnosis's own wall time
    (``wall_time_s`` [s], without the synthesis)."""
    like = row.get("likelihood") or {}
    fitted = []
    for e in row.get("effects") or ():
        if not isinstance(e, dict) or e.get("name") not in EFFECTS:
            continue
        mag = EFFECTS[e["name"]].magnitude
        iv = interval(row, e["name"], mag)
        span = f" [{iv[0]:.4g}, {iv[1]:.4g}]" if iv else ""
        fitted.append(f"{e['name']} {mag} {_num((e.get('parameters') or {}).get(mag), '.4g')}{span}")
    detect = "—"
    if row.get("kind") == "effect" and len(true_effects(row)) == 1:
        c = effect_case(row)
        detect = f"{_num(c['threshold'], '.4g')} ({c['side']})"
    misfit = like.get("unnamed_misfit")
    gain = "—"
    if isinstance(misfit, dict) and _number(misfit.get("log_evidence")) is not None:
        gain = (f"{_num(misfit.get('torsional'), '+.2f')}, {_num(misfit.get('ramps'), '+.2f')} → "
                f"{_num(misfit.get('log_evidence'), '+.2f')}")
    cells = [_cell(row.get("id")), _cell((row.get("truth") or {}).get("description")),
             f"`{row['verdict']}`" if row.get("verdict") else "—",
             _leaders(row.get("posterior")), _leaders(posterior_without_misfit(row)), gain,
             f"{_num(like.get('reduced_chi2_held_out_calibrated'), '.2f')} → "
             f"{_num(like.get('reduced_chi2_held_out'), '.2f')}",
             _num(like.get("reduced_chi2_train"), ".2f"), _num(like.get("learning_rate"), ".2f"),
             "; ".join(fitted) or "—", detect, _num(row.get("simulations"), ".0f"),
             _num(row.get("wall_time_s"), ".0f")]
    return "| " + " | ".join(cells) + " |"


def case_table(rows) -> str:
    """CASE_TABLE_HEADER and one :func:`case_row` per case (its last successful row, in
    order of first appearance)."""
    return "\n".join([CASE_TABLE_HEADER] + [case_row(r) for r in latest(rows)[0]])


def _fmt(fig: dict) -> str:
    if "share" in fig:
        s = "-" if fig["share"] is None else f"{100 * fig['share']:.0f} %"
        return f"{fig['count']}/{fig['of']}  ({s})"
    if fig.get("median") is None:
        return "-"
    return f"median {fig['median']:.3g}, range {fig['min']:.3g}-{fig['max']:.3g} (n={fig['of']})"


def summary_table(s: dict) -> str:
    """:func:`summary` as a text table, one figure a line."""
    lines = [f"{'figure':58s} value", "-" * 90]
    lo, hi = CONTROL_CHI2_RANGE
    c = s["counts"]
    lines.append(f"{'cases (effect / pair / control / out of library; failed)':58s} "
                 f"{c['effect']} / {c['pair']} / {c['control']} / {c['out_of_library']}; {s['failed']}")
    rows = [
        ("effect beyond detectability: top-1 correct", s["effect_beyond"]["top1_correct"]),
        ("effect beyond detectability: adopted (missing_effect)", s["effect_beyond"]["named_correct"]),
        ("effect beyond detectability: magnitude in 90 % interval", s["effect_beyond"]["magnitude_in_90_interval"]),
        ("effect below detectability: detected (posterior >= 0.9)", s["effect_below"]["detected"]),
        ("effect below detectability: adopted (missing_effect)", s["effect_below"]["named_correct"]),
        ("effect without detectability estimate: top-1 correct", s["effect_no_estimate"]["top1_correct"]),
        ("controls: a named model at posterior >= 0.9", s["control"]["claimed_p90"]),
        ("controls: an effect adopted (missing_effect)", s["control"]["named_any"]),
        ("controls: reduced chi2 held out", s["control"]["reduced_chi2_held_out"]),
        (f"controls: reduced chi2 held out within {lo:g}-{hi:g}", s["control"]["reduced_chi2_held_out_within"]),
        (f"controls: reduced chi2 held out below {lo:g}", s["control"]["reduced_chi2_held_out_below"]),
        (f"controls: reduced chi2 held out above {hi:g}", s["control"]["reduced_chi2_held_out_above"]),
        ("controls: reduced chi2 training", s["control"]["reduced_chi2_train"]),
        ("out of library: a named model at posterior >= 0.9", s["out_of_library"]["claimed_p90"]),
        ("out of library: an effect adopted (missing_effect)", s["out_of_library"]["named_any"]),
        ("two effects: both named (adopted or the top model)", s["pair"]["both_named"]),
        ("two effects: at least one named", s["pair"]["one_named"]),
    ]
    lines += [f"{name:58s} {_fmt(fig)}" for name, fig in rows]
    return "\n".join(lines)


__all__ = ["KINDS", "CLAIM_PROBABILITY", "CONTROL_CHI2_RANGE", "latest", "true_effects", "named", "probability", "top_model", "claimed", "interval",
           "side", "effect_case", "summary", "summary_table", "posterior_without_misfit", "CASE_TABLE_HEADER",
           "case_row", "case_table"]
