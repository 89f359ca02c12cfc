"""Why a model wins a diagnosis: each fitted model's log evidence split into its terms.

For each named case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``;
the campaign is synthesised exactly as that benchmark does, 12 torsional points of 1 s and
one ramp) the whole diagnosis runs (no next-test design) and prints, per fitted model:

* ``laplace``: the Laplace evidence on the training points
  (:func:`dampersim.discrepancy.selection.log_evidence`), with ``cost`` (robust chi^2 plus
  prior terms that it starts from) and ``occam`` (laplace + cost / 2: with a learning rate
  of 1 the Occam factor, what the fitted parameters' prior and posterior widths add; below 1
  it also holds the tempering terms of selection.log_evidence);
* ``ramps``: the ramps' predictive log likelihood; ``penalty``: the held-out penalty;
  ``total``: the sum the posterior reads, with ``log_prior`` the model prior's log;
* ``x``: the fitted log calibration factors; ``start``: where the fit started;
  ``refactored`` ("none" only): the fitted effect whose calibration factors "none" took
  (:meth:`dampersim.discrepancy.naming.Namer.recalibrate`), or null;
  ``magnitude``: the fitted effect magnitude(s);
* ``train_point_chi2``: chi^2 per real residual of each training point at the model's fit;
* ``cost_without_effect`` (single effects): the same objective at the model's calibration
  factors without its effect or the effect's prior terms, from runs of the training points made for this bench
  (not counted in ``simulations``). Near a single effect's cost it says the fit gained by
  the calibration factors its fit reached, not by the effect;
* ``magnitude`` is the torsional fit's; ``sized_magnitude`` the one the diagnosis reports
  after the ramps sized the most probable effect (``ramp_models.size_by_ramps``), or null
  where they did not move it.

With ``--ramp-profile`` each single effect's ramps are also replayed along its magnitude
(``ramp_profile``, runs not counted in ``simulations``): at ``PROFILE_POINTS`` log
magnitudes spaced evenly over the torsional fit's log magnitude u0 ± max(RAMP_SEARCH,
4 sd) (sd the fit's Laplace standard deviation of log magnitude; kept inside the
effect's accepted range), the ramps' log likelihood with the magnitude held there and
the calibration factors' covariance carried as the diagnosis carries it
(``RampLikelihood.predictive``, scaled by the same effective share), less that of
"none". ``replayed`` integrates the same over the torsional fit's Gaussian on u0
(:func:`replayed_evidence`, a sum on the even grid, the Gaussian renormalised to it):
the ramps' evidence with the magnitude's effect replayed, against ``linearised``, the
term the posterior read (the magnitude carried through one sensitivity at u0).
``share`` is the ramps' effective share of independent samples: the replays' log
likelihoods carry it inside the sum, while the linearised term is a whole log
likelihood times it. Caveats: 21 points over at least ±1.5 in log magnitude can miss a
ramp likelihood narrower than the spacing; the calibration factors are held at the fit
with their marginal covariance (the magnitude's correlation with them is not carried).

Candidates that were only screened get their screen evidence relative to "none". A whole
diagnosis per case (777 s for control/none/1 on 2 cores).

    python bench/bench_evidence_terms.py control/none/1
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_sigma_terms as S  # noqa: E402 - the hard matrix's cases and campaigns, as that bench builds them

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import drive, ramp_models, ramps, selection  # noqa: E402
from dampersim.discrepancy.effects import info, with_effect  # noqa: E402
from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system  # noqa: E402

#: grid points of a ramp profile
PROFILE_POINTS = 21


def replayed_evidence(us, rel, u0: float, var0: float):
    """log of the sum over the even grid ``us`` of exp(rel) weighted by the Gaussian N(u0,
    var0) in u, the weights renormalised over the grid points whose replay worked (``rel``
    finite); None when none did. With a grid that holds the Gaussian it is the integral."""
    us, rel = np.asarray(us, dtype=float), np.asarray(rel, dtype=float)
    logw = -0.5 * (us - u0) ** 2 / var0
    ok = np.isfinite(rel)
    if not ok.any():
        return None
    return float(np.logaddexp.reduce(rel[ok] + logw[ok]) - np.logaddexp.reduce(logw[ok]))


def ramp_profile(fit, ramp_lik, points, ll_none: float, ll_lin: float, workers: int) -> dict:
    """The ramps' log likelihood of a single-effect fit along its log magnitude, against
    "none" (see the module's ``--ramp-profile``): grid rows and the replayed and linearised
    evidence, in nats relative to "none". ``fit`` holds the torsional fit as the ramp
    evidence read it (before any sizing)."""
    name = fit["effects"][0]
    n_cal = len(CALIBRATION)
    u0, var0 = math.log(fit["m"]), max(float(fit["cov"][n_cal, n_cal]), 1e-12)
    span = max(ramp_models.RAMP_SEARCH, 4.0 * math.sqrt(var0))
    lo, hi = ramp_models.log_range(name, u0, span)
    us = np.linspace(lo, hi, PROFILE_POINTS) if hi > lo else np.array([u0])
    systems = [with_effect(fit["system"], name, {info(name).magnitude: math.exp(u)}) for u in us]
    with drive.Runner(workers) as runner:
        out = runner.map([(drive.diagnosis_system(s), p) for s in systems for p in points])
    cols = np.column_stack(ramp_lik.cols_x)
    rel = []
    for k in range(len(us)):
        w = ramps.windups(points, out[k * len(points):(k + 1) * len(points)])
        rel.append(ramp_lik.predictive(w, cols, fit["cov"][:n_cal, :n_cal])[0] - ll_none)
    rel = np.array(rel)
    ok = np.isfinite(rel)
    replayed = replayed_evidence(us, rel, u0, var0)
    return {"u0": round(u0, 4), "sd": round(math.sqrt(var0), 4), "share": round(float(ramp_lik.fraction), 4),
            "rows": [[float(f"{math.exp(u):.4g}"), round(float(r), 3)] for u, r in zip(us, rel)],
            "best": float(f"{math.exp(us[int(np.nanargmax(np.where(ok, rel, -np.inf)))]):.4g}") if ok.any() else None,
            "replayed": None if replayed is None else round(replayed, 3), "linearised": round(ll_lin - ll_none, 3)}


def terms_of(camp, workers: int, profile: bool = False) -> dict:
    """Run the diagnosis of ``camp`` and return its verdict, posterior and every model's terms
    (with ``profile``, each single effect's ramp profile, see :func:`ramp_profile`)."""
    seen, held_namer, fits, ramp_seen = {}, {}, {}, {}
    real_penalty, real_log_z, real_namer = selection.held_out_penalty, selection.model_log_evidence, dg.Namer
    real_evidence = ramp_models.evidence

    def spy_evidence(runner, system, x, models, points):
        out = real_evidence(runner, system, x, models, points)
        ramp_seen.update(lik=out[0], points=points)
        return out

    class SpyNamer(real_namer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            held_namer["namer"] = self

    def without_effect(fit):
        """The objective of the fit's calibration factors with the effect taken out."""
        namer = held_namer["namer"]
        errs = {}
        with drive.Runner(workers) as runner:
            y = drive.coefficients_of(runner, calibrated_system(namer.starts["estimated"][0], fit["x"]), namer.points,
                                      errs)
        return None if errs else float(namer.cost(y, fit["x"]))

    def spy_penalty(lik, models, held, eta):
        rows = held_namer["namer"].train
        per = 2 * len(lik.orders)
        # the fits as the evidence reads them (the ramps' sizing later replaces m, system, cov)
        fits.update({label: {"fit": fit, "as_read": {k: fit[k] for k in ("m", "system", "cov", "effects") if k in fit}}
                     for label, fit in models.items()})
        seen["models"] = {
            label: {"cost": float(fit["cost"]), "start": fit.get("start"),
                    "x": [round(float(v), 4) for v in fit["x"]],
                    "magnitude": fit.get("m"), "refactored": fit.get("refactored"),
                    "train_point_chi2": [round(float(c) / per, 3)
                                         for c in lik.point_chi2(fit["y"], rows, fit["nuisance"])],
                    "cost_without_effect": without_effect(fit) if len(fit["effects"]) == 1 else None}
            for label, fit in models.items()}
        return real_penalty(lik, models, held, eta)

    def spy_log_z(models, candidates, pairs, screen_z, ramp_ll, penalty, unfitted):
        out = real_log_z(models, candidates, pairs, screen_z, ramp_ll, penalty, unfitted)
        for label, fit in models.items():
            m = seen["models"][label]
            m.update({"laplace": float(fit["log_z"]), "occam": float(fit["log_z"]) + 0.5 * m["cost"],
                      "ramps": float(ramp_ll.get(label, 0.0)), "penalty": float(penalty.get(label, 0.0)),
                      "total": float(out[label])})
        seen["screened"] = {k: round(float(v), 3) for k, v in screen_z.items()}
        return out

    selection.held_out_penalty, selection.model_log_evidence, dg.Namer = spy_penalty, spy_log_z, SpyNamer
    ramp_models.evidence = spy_evidence
    try:
        diag = dg.diagnose(camp, workers=workers, recommend=False)
        d = diag.to_json()
    finally:
        selection.held_out_penalty, selection.model_log_evidence, dg.Namer = real_penalty, real_log_z, real_namer
        ramp_models.evidence = real_evidence
    if "models" not in seen:  # not diagnosed: no model was fitted
        return {"verdict": d["verdict"], "message": d["message"], "simulations": d["simulations"]}
    priors = d["likelihood"]["model_prior"]
    for label, m in seen["models"].items():
        m["log_prior"] = math.log(priors[label]) if priors.get(label) else None
        f = fits[label]
        moved = f["fit"].get("m") is not None and f["fit"].get("m") != f["as_read"].get("m")
        m["sized_magnitude"] = f["fit"]["m"] if moved else None
        if profile and len(f["as_read"].get("effects", [])) == 1 and ramp_seen.get("lik") is not None:
            m["ramp_profile"] = ramp_profile(f["as_read"], ramp_seen["lik"], ramp_seen["points"],
                                             seen["models"]["none"]["ramps"], m["ramps"], workers)
    train = [p["id"] for p in diag.points if not p["held_out"]]
    return {"verdict": d["verdict"], "posterior": {k: round(v, 3) for k, v in d["posterior"].items() if v >= 0.001},
            "reduced_chi2_held_out": d["likelihood"]["reduced_chi2_held_out"],
            "reduced_chi2_train": d["likelihood"]["reduced_chi2_train"], "learning_rate": d["likelihood"]["learning_rate"],
            "training_points": train, "orders": list(drive.ORDERS), "simulations": d["simulations"], **seen}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", default=["control/none/1"], help="hard-matrix case ids (default control/none/1)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--ramp-profile", action="store_true",
                    help="replay each single effect's ramps along its magnitude (PROFILE_POINTS replays per ramp)")
    a = ap.parse_args(argv)
    matrix = S.named_cases(ap, a.cases)
    for cid in a.cases:
        with tempfile.TemporaryDirectory() as d:
            camp = S.campaign_of(matrix[cid], os.path.join(d, "campaign"), a.workers)
            print(json.dumps({"case": cid, **terms_of(camp, a.workers, a.ramp_profile)}, default=float), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
