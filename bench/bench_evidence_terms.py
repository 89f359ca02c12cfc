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
  the calibration factors its fit reached, not by the effect.

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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_sigma_terms as S  # noqa: E402 - the hard matrix's cases and campaigns, as that bench builds them

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import drive, selection  # noqa: E402
from dampersim.discrepancy.fitting import calibrated_system  # noqa: E402


def terms_of(camp, workers: int) -> dict:
    """Run the diagnosis of ``camp`` and return its verdict, posterior and every model's terms."""
    seen, held_namer = {}, {}
    real_penalty, real_log_z, real_namer = selection.held_out_penalty, selection.model_log_evidence, dg.Namer

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
    try:
        diag = dg.diagnose(camp, workers=workers, recommend=False)
        d = diag.to_json()
    finally:
        selection.held_out_penalty, selection.model_log_evidence, dg.Namer = real_penalty, real_log_z, real_namer
    if "models" not in seen:  # not diagnosed: no model was fitted
        return {"verdict": d["verdict"], "message": d["message"], "simulations": d["simulations"]}
    priors = d["likelihood"]["model_prior"]
    for label, m in seen["models"].items():
        m["log_prior"] = math.log(priors[label]) if priors.get(label) else None
    train = [p["id"] for p in diag.points if not p["held_out"]]
    return {"verdict": d["verdict"], "posterior": {k: round(v, 3) for k, v in d["posterior"].items() if v >= 0.001},
            "reduced_chi2_held_out": d["likelihood"]["reduced_chi2_held_out"],
            "reduced_chi2_train": d["likelihood"]["reduced_chi2_train"], "learning_rate": d["likelihood"]["learning_rate"],
            "training_points": train, "orders": list(drive.ORDERS), "simulations": d["simulations"], **seen}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", default=["control/none/1"], help="hard-matrix case ids (default control/none/1)")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    matrix = S.named_cases(ap, a.cases)
    for cid in a.cases:
        with tempfile.TemporaryDirectory() as d:
            camp = S.campaign_of(matrix[cid], os.path.join(d, "campaign"), a.workers)
            print(json.dumps({"case": cid, **terms_of(camp, a.workers)}, default=float), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
