"""What makes up the cell uncertainty of a diagnosis, and what the floor term does to it.

For each named case of the hard benchmark matrix (``bench/bench_discrepancy.py --list``
shows the ids; the campaign is synthesised exactly as that benchmark does, 12 torsional
points of 1 s), the diagnosis's own compare step runs (ten model runs per point) and is
stopped there; printed per case:

* each term's share of the cell variance summed over all cells, and the median over cells
  of its share of the cell's variance (repeatability, discretisation, input channel, uncalibrated
  parameters, mains pick-up, floor;
  :func:`dampersim.discrepancy.likelihood.sigma_variances`);
* per point the RMS of each term [N m].

``--floor F [F ...]`` then runs the whole diagnosis (no next-test design) once per
floor share F (``likelihood.SIGMA_FLOOR_SHARE``) and prints its verdict, posterior and
reduced chi^2 (held out and training): a whole diagnosis each (697 s for control/none/0
on 2 cores shared with other work, the hard benchmark's run of it).

    python bench/bench_sigma_terms.py control/none/0
    python bench/bench_sigma_terms.py control/none/0 control/calibration/0 --floor 1e-3 1e-4
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

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import likelihood  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.discrepancy.synth import synthesize  # noqa: E402


class _Stop(Exception):
    """Raised by the spy of :func:`diagnose_until` once the diagnosis has made the call watched."""


def campaign_of(case, folder, workers: int):
    spec = case["spec"]
    synthesize(folder, effects=[(n, dict(v)) for n, v in spec["effects"]], perturb=case["perturb"],
               noise_db=case["noise_db"], seed=case["seed"], updates=dict(spec["updates"]) or None,
               points=B.point_ids(12, 1), record=1.0, workers=workers, daq=case["daq"])
    return read_campaign(folder)


def named_cases(ap, ids) -> dict:
    """{id: case} of the hard matrix for the case ids asked for; an unknown id is the parser's error."""
    matrix = {c["id"]: c for c in B.hard_cases()}
    unknown = [c for c in ids if c not in matrix]
    if unknown:
        ap.error(f"unknown case(s) {', '.join(unknown)}: see python bench/bench_discrepancy.py --list")
    return matrix


def diagnose_until(camp, workers: int, name: str, capture) -> None:
    """Run the diagnosis of ``camp`` (no next-test design) until it calls ``name`` of
    :mod:`dampersim.discrepancy.diagnose`: ``capture`` gets that call's arguments, then the
    diagnosis stops (it returns normally when it ends before that call, e.g. not diagnosed)."""
    real = getattr(dg, name)

    def spy(*args, **kwargs):
        capture(*args, **kwargs)
        raise _Stop

    setattr(dg, name, spy)
    try:
        dg.diagnose(camp, workers=workers, recommend=False)
    except _Stop:
        pass
    finally:
        setattr(dg, name, real)


def terms_of(camp, workers: int) -> dict:
    """The variances diagnose's compare step passes to cell_sigma, by term."""
    seen = {}
    diagnose_until(camp, workers, "cell_sigma", lambda *a, **k: seen.update(likelihood.sigma_variances(*a, **k)))
    return seen


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", default=["control/none/0"], help="hard-matrix case ids (default control/none/0)")
    ap.add_argument("--floor", nargs="*", type=float, default=[], help="floor shares to run the whole diagnosis with")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    bad = [f for f in a.floor if not 0.0 < f < 1.0]
    if bad:
        ap.error(f"--floor {bad[0]}: accepted is a share between 0 and 1, both excluded")
    matrix = named_cases(ap, a.cases)
    for cid in a.cases:
        with tempfile.TemporaryDirectory() as d:
            camp = campaign_of(matrix[cid], os.path.join(d, "campaign"), a.workers)
            var = terms_of(camp, a.workers)
            if not var:
                print(json.dumps({"case": cid, "error": "the diagnosis stopped before its cell uncertainty"}))
                continue
            total = sum(var.values())
            ids = [p.id for p in camp.torsional]
            if len(ids) != len(total):  # points whose runs failed were left out: rows by index
                ids = [f"kept point {i}" for i in range(len(total))]
            print(json.dumps({
                "case": cid, "floor_share": likelihood.SIGMA_FLOOR_SHARE,
                "share_of_summed_variance": {k: round(float(v.sum() / total.sum()), 3) for k, v in var.items()},
                "median_share_per_cell": {k: round(float(np.median(v / total)), 3) for k, v in var.items()},
                "rms_per_point_nm": {pid: {k: round(float(np.sqrt(v[i].mean())), 4) for k, v in var.items()}
                                     for i, pid in enumerate(ids)}}), flush=True)
            default = likelihood.SIGMA_FLOOR_SHARE
            for share in a.floor:
                likelihood.SIGMA_FLOOR_SHARE = share
                try:
                    d_ = dg.diagnose(camp, workers=a.workers, recommend=False).to_json()
                finally:
                    likelihood.SIGMA_FLOOR_SHARE = default
                lk = d_["likelihood"]
                print(json.dumps({"case": cid, "floor_share": share, "verdict": d_["verdict"],
                                  "posterior": {k: round(v, 3) for k, v in d_["posterior"].items() if v >= 0.001},
                                  "reduced_chi2_held_out": lk["reduced_chi2_held_out"],
                                  "reduced_chi2_train": lk["reduced_chi2_train"],
                                  "simulations": d_["simulations"]}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
