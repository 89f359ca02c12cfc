"""Does the calibration reach the truth's own factors? One CI campaign, its truth known.

The diagnosis calibrates six log scale factors (``fitting.CALIBRATION``) on the training
points. For a synthetic campaign the truth's factors are known up to what the calibration
cannot follow (``fitting.UNCALIBRATED``): each group's factor is the mean log ratio of its
members' truth values to the diagnosed set's ("projected"). This bench diagnoses one of the
strict CI identification campaigns as they were up to commit a8d5936
(bench_control_misfit.py's ``ci-control`` or ``ci-absorber``: 18/8 model, 24/10 truth, nine
points of 0.8 s, 3 % perturbation, seed 3; ``--daq`` as there) and prints, as one JSON line:

* the calibrated factors (the calibration's own, before any effect is fitted with them) and
  the projected ones (log);
* the calibration's objective on the training points (the likelihood as the diagnosis left
  it: its last nuisance and robust weights, plus the factors' prior) at both;
* every point's reduced chi^2 with the calibrated model and with the projected one, each at
  the channel nuisance fitted to its training points;
* the diagnosis's verdict and held-out reduced chi^2;
* per order, the largest change between the truth's parameters (at the diagnosed
  discretisation) and the projected factors over the points (what the calibration cannot
  follow; with the absorber hidden, the absorber too), and the range over points of the cell
  uncertainty's term for it (``likelihood.sigma_variances``' ``uncalibrated``).

A projected objective well below the calibrated one means the calibration stopped short of a
better minimum it could have reached (the truth's remaining difference, the uncalibrated
directions, the finer discretisation and the DAQ chain are in both).

    python bench/bench_calibration_reach.py
    python bench/bench_calibration_reach.py --case ci-absorber --derivative-steps 0.05
    python bench/bench_calibration_reach.py --iterations 6
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

import bench_control_misfit as M  # noqa: E402 - the CI campaigns and their diagnosis options

from dampersim.discrepancy import diagnose as dg  # noqa: E402
from dampersim.discrepancy import drive, fitting, likelihood, synth  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.parameters import at_thesis_segments  # noqa: E402
from dampersim.parameters.io import flat_values  # noqa: E402


def projected_factors(base, applied: dict) -> np.ndarray:
    """Each calibration group's mean log ratio of the truth's values to ``base``'s."""
    flat = flat_values(base)
    return np.array([np.mean([math.log(float(applied.get(n, flat[n])) / float(flat[n])) for n in names])
                     for names in fitting.CALIBRATION.values()])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=("ci-control", "ci-absorber"), default="ci-control")
    ap.add_argument("--daq", default="random", help="none, random, or parts of the random chain")
    M.add_derivative_steps(ap)
    M.add_iterations(ap)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    M.use_derivative_steps(ap, a.derivative_steps)
    base = at_thesis_segments()
    effects = [("pendulum_absorber", {"inertia": 0.002})] if a.case == "ci-absorber" else []
    with tempfile.TemporaryDirectory() as d:
        doc = synth.synthesize(os.path.join(d, "c"), effects=effects, perturb=0.03, noise_db=0.0, seed=M.CI_SEED,
                               points=M.CI_POINTS, record=0.8, workers=a.workers, daq=M.ci_daq(a.daq), base=base)
        camp = read_campaign(os.path.join(d, "c"))
    applied = {k: v for k, v in doc["perturbed"].items() if not k.startswith("solver.")}
    seen, terms, starts = [], {}, []
    real, real_sigma, real_namer = dg.Likelihood, dg.cell_sigma, dg.Namer

    def keep(*args, **kwargs):
        seen.append(real(*args, **kwargs))
        return seen[-1]

    def keep_sigma(*args, **kwargs):
        terms.update(likelihood.sigma_variances(*args, **kwargs))
        return real_sigma(*args, **kwargs)

    def keep_namer(runner, lik, train, ptr, jac, start, *rest):
        starts.append(start)  # the calibration's result, before any effect is fitted with it
        return real_namer(runner, lik, train, ptr, jac, start, *rest)

    dg.Likelihood, dg.cell_sigma, dg.Namer = keep, keep_sigma, keep_namer
    try:
        res = dg.diagnose(camp, base, workers=a.workers, candidates=M.CI_CANDIDATES,
                          calibration_iterations=a.iterations,
                          shortlist=2, recommend=False).to_json()
    finally:
        dg.Likelihood, dg.cell_sigma, dg.Namer = real, real_sigma, real_namer
    lik, pts = seen[0], camp.torsional
    if lik.meas.shape[0] != len(pts) or not starts:
        raise SystemExit(f"the diagnosis left points out or stopped before naming ({res['verdict']}: "
                         f"{res.get('message', '')}); this bench compares whole campaigns only")
    every = list(range(len(pts)))
    train = [i for i in every if i % 3 != 1]
    x_cal = np.asarray(starts[0]["calibrated"][1], dtype=float)
    x_proj = projected_factors(base, applied)
    row = {"case": a.case, "daq": a.daq, "derivative_steps": list(fitting.CAL_DERIVATIVE_STEPS),
           "iterations": a.iterations,
           "simulations": res["simulations"],
           "verdict": res["verdict"], "reduced_chi2_held_out": res["likelihood"]["reduced_chi2_held_out"]}
    truth, _ = synth.truth_system(base, effects, 0.0, None, applied, fine=False)
    ys = {}
    with drive.Runner(a.workers) as r:
        ys["truth"] = drive.coefficients_of(r, truth, pts)
        for label, x in (("calibrated", x_cal), ("projected", x_proj)):
            y = ys[label] = drive.coefficients_of(r, fitting.calibrated_system(base, x), pts)
            row[f"factors_{label}"] = dict(zip(fitting.CALIBRATION, np.round(x, 4).tolist()))
            loss, nu = lik.profile(y[train], train)
            row[f"objective_{label}"] = round(loss + float(np.sum(x ** 2)) / fitting.PRIOR_LOG_SD ** 2, 2)
            chi = lik.point_chi2(y, every, nu) / (2 * len(drive.ORDERS))
            row[f"point_reduced_chi2_{label}"] = {p.id: round(float(c), 3) for p, c in zip(pts, chi)}
    # what the projection leaves (the uncalibrated directions, and the absorber where hidden,
    # which the projection leaves out) against the term that carries it, per order [N m]
    row["max_truth_minus_projected_by_order_nm"] = np.round(np.abs(ys["truth"] - ys["projected"]).max(axis=0), 3).tolist()
    unc = np.sqrt(terms["uncalibrated"]) if len(terms.get("uncalibrated", ())) == len(pts) else None
    row["uncalibrated_term_range_by_order_nm"] = (None if unc is None else
                                                  [[round(float(lo), 3), round(float(hi), 3)]
                                                   for lo, hi in zip(unc.min(axis=0), unc.max(axis=0))])
    print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
