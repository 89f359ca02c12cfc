"""Where a model sits on its characteristic decides its uncertainty terms: the three model-based
terms of the diagnosis's cell uncertainty measured at several parameter sets.

For a case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``; its campaign
synthesised as that benchmark does, 12 torsional points of 1 s, or the ``--points`` given) the
discretisation check, the input channel and what the calibration cannot follow
(:mod:`dampersim.discrepancy.model_terms`, nine runs per point and set) are measured, each
point driven by its own record as the diagnosis drives it, at:

* ``estimate``: the parameter set the diagnosis is given (the default set);
* ``truth``: the truth's estimated parameters, at the diagnosis's segments and step (the
  truth itself runs finer: what that costs shows in the discretisation term);
* ``calibrated``: with ``--x``, the default set with the six calibration factors exp(x)
  (:data:`dampersim.discrepancy.fitting.CALIBRATION` order; a diagnosis reports them, e.g.
  ``bench/bench_evidence_terms.py``'s ``x``).

Printed per set and point: each term's RMS and largest value over orders 1-8 [N m], and the
set's own misfit against the measured coefficients (RMS over the orders, [N m]). A set near
a knee of the characteristic has input and split terms many times those of a set away from
it; a diagnosis that measured its terms at the estimate alone read such points as exact.
The campaign's records are synthesised as the benchmark's (its 12 points, in its order), so
they are the records its diagnosis of the case saw.

    python bench/bench_model_terms.py control/calibration/3 --points tc_2000 tc_2400 \\
        --x 0.2843 0.0341 0.0725 0.1145 -0.0425 -0.1521
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_discrepancy as B  # noqa: E402 - the benchmark's matrix and campaign layout
import bench_sigma_terms as S  # noqa: E402 - the benchmark's synthesis of a case

from dampersim.discrepancy import drive, model_terms  # noqa: E402
from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system  # noqa: E402
from dampersim.discrepancy.likelihood import measured_coefficients  # noqa: E402
from dampersim.parameters import default_parameters  # noqa: E402
from dampersim.parameters.io import with_updates  # noqa: E402


def truth_estimate(perturbed: dict, base):
    """``base`` with the truth's values (``perturbed``: dotted name -> value, as synthesize
    reports them) of everything but the solver's segments and step."""
    return with_updates(base, {k: v for k, v in perturbed.items() if not k.startswith("solver.")}, check=False)


def summary(terms, meas) -> dict:
    """{term: [RMS per point], ..., "<term>_max": [largest per point], "misfit": [RMS of the
    set's own coefficients against ``meas`` per point]} [N m], rounded to 0.01 mN m."""
    out = {}
    for name, v in (("model", terms.model_change), ("input", terms.input_change),
                    ("uncalibrated", terms.uncalibrated_change), ("misfit", np.abs(terms.y - meas))):
        out[name] = np.round(np.sqrt(np.mean(v ** 2, axis=1)), 5).tolist()
        if name != "misfit":
            out[f"{name}_max"] = np.round(np.max(v, axis=1), 5).tolist()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", nargs="?", default="control/calibration/3",
                    help="a hard-matrix case id (default control/calibration/3)")
    ap.add_argument("--points", nargs="+", help="torsional point ids (default the benchmark's 12)")
    ap.add_argument("--x", nargs=len(CALIBRATION), type=float, metavar="X",
                    help=f"log calibration factors ({', '.join(CALIBRATION)}) of a calibrated set")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    matrix = {c["id"]: c for c in B.hard_cases()}
    if a.case not in matrix:
        ap.error(f"unknown case {a.case}: see python bench/bench_discrepancy.py --list")
    if a.x is not None and not all(abs(v) <= 1.0 for v in a.x):
        ap.error("--x: accepted are log factors between -1 and 1")
    case, base = matrix[a.case], default_parameters()
    # the benchmark's 12 points are always synthesised, in its order: a record's noise, engine
    # harmonics and acquisition stream follow its place in the campaign, so that the records
    # are the ones the benchmark's diagnosis of the case saw; other ids asked for come after them
    bench_ids = B.point_ids(12, 0)
    points = a.points or bench_ids
    with tempfile.TemporaryDirectory() as d:
        truth = {}
        camp = S.campaign_of(case, os.path.join(d, "campaign"), a.workers, truth,
                             points=bench_ids + [p for p in points if p not in bench_ids])
        by_id = {p.id: p for p in camp.torsional}
    pts = [by_id[p] for p in points if p in by_id]
    meas = np.array([measured_coefficients(p, drive.ORDERS) for p in pts])
    sets = {"estimate": base, "truth": truth_estimate(truth["perturbed"], base)}
    if a.x is not None:
        sets["calibrated"] = calibrated_system(base, np.array(a.x))
    with drive.Runner(a.workers) as runner:
        for name, system in sets.items():
            y = drive.coefficients_of(runner, system, pts)
            t = model_terms.measure(runner, system, pts, y)
            print(json.dumps({"case": a.case, "set": name, "points": [p.id for p in pts],
                              "failed_rows": sorted(t.failed_rows()), **summary(t, meas)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
