"""Does the records' split-half repeatability measure the noise a driven model is judged against?

Among the terms of a cell's uncertainty, the diagnosis takes the repeatability of the
measured order coefficient from the record's two halves
(:func:`dampersim.discrepancy.likelihood.split_half_sigma`; for the orders the input
carries, half the difference of the halves' ratios output/input). The model it is compared
with is driven by the same record, so what matters is the uncertainty of the residual:
what the model cannot reproduce from the record. This bench measures both on synthetic
campaigns whose truth is known and whose only noise is white sensor noise (no acquisition
chain, exact channel gains):

* ``measured``: ``split_half_sigma``, as the diagnosis uses it;
* ``residual``: half the difference of the halves' residuals against the truth's parameters
  at the diagnosed discretisation, driven by the record
  (:func:`~dampersim.discrepancy.likelihood.residual_half_sigma`; the run's output is
  interpolated onto the record's time base and read like the record: same angle, same
  halves; the interpolation's small attenuation is the same in both halves and cancels in
  their difference).

Printed per campaign: the noise-only reduced chi^2, the mean over cells of |measured - the
fine truth driven by the record|^2 over each estimate's variance, pooled per order as the
diagnosis pools it (likelihood.sigma_variances): 1 for an honest estimate, below 1 for an
inflated one; and per order the RMS of that misfit and of each estimate [N m].

Campaigns: ``ci-control`` and ``ci-absorber`` (bench_control_misfit.py's, on nine points:
the strict CI identification tests' campaigns up to commit a8d5936; the clean test now
diagnoses eight) and ``benchmark`` (its 12-point no-effect campaign, 10 % perturbation,
-2 dB noise).

``--diagnose`` then diagnoses the CI control campaign with ``--daq`` (default ``random``)
twice, with each estimate as the repeatability term (the diagnosis's ``repeatability``
``"split_half"`` and ``"residual"``, the latter against the parameter set as given), and
prints verdict, reduced chi^2 and every point's reduced chi^2; ``--perturb`` sets the truth's perturbation of the
estimated parameters (default the CI test's 3 %; 0 leaves only the finer discretisation
and the acquisition chain between truth and model).

    python bench/bench_repeatability.py
    python bench/bench_repeatability.py --campaigns ci-control --diagnose
    python bench/bench_repeatability.py --campaigns --diagnose --perturb 0
    python bench/bench_repeatability.py --campaigns --diagnose --iterations 6
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_control_misfit as M  # noqa: E402 - the CI campaigns and their diagnosis options

from dampersim.discrepancy import drive, synth  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.discrepancy.likelihood import (measured_coefficients, residual_half_sigma,  # noqa: E402
                                              sigma_variances, split_half_sigma)
from dampersim.parameters import at_thesis_segments, default_parameters  # noqa: E402

CAMPAIGNS = {
    "ci-control": dict(base=at_thesis_segments, points=M.CI_POINTS, record=0.8, noise_db=0.0, perturb=0.03,
                       seed=M.CI_SEED, effects=[]),
    "ci-absorber": dict(base=at_thesis_segments, points=M.CI_POINTS, record=0.8, noise_db=0.0, perturb=0.03,
                        seed=M.CI_SEED, effects=[("pendulum_absorber", {"inertia": 0.002})]),
    "benchmark": dict(base=default_parameters, points=M.BENCH_POINTS, record=1.0, noise_db=-2.0, perturb=0.1,
                      seed=4242, effects=[]),
}


def residual_half_sigma_of(system, point) -> np.ndarray:
    """Half the difference of the halves' residuals against ``system`` driven by the record [N m]."""
    run = drive.simulate_point(drive.diagnosis_system(system), point, halves=True)
    return residual_half_sigma(point, run["halves"], drive.ORDERS)


def pooled_variance(repeat) -> np.ndarray:
    """The diagnosis's repeatability variance [N m^2] for ``repeat`` (the term of sigma_variances)."""
    return sigma_variances(repeat, np.zeros(repeat.shape), np.ones(1))["repeat"]


def noise_check(name: str, workers: int) -> dict:
    c = CAMPAIGNS[name]
    base = c["base"]()
    with tempfile.TemporaryDirectory() as d:
        doc = synth.synthesize(os.path.join(d, "c"), effects=c["effects"], perturb=c["perturb"],
                               noise_db=c["noise_db"], seed=c["seed"], points=c["points"], record=c["record"],
                               workers=workers, base=base, gain_error=0.0)
        pts = read_campaign(os.path.join(d, "c")).torsional
    applied = {k: v for k, v in doc["perturbed"].items() if not k.startswith("solver.")}
    truth, _ = synth.truth_system(base, c["effects"], 0.0, None, applied, fine=False)
    fine, _ = synth.truth_system(base, c["effects"], 0.0, None, applied, fine=True)
    with drive.Runner(workers) as r:
        y_fine = drive.coefficients_of(r, fine, pts)
    resid2 = np.abs(np.array([measured_coefficients(p, drive.ORDERS) for p in pts]) - y_fine) ** 2
    est = {"measured": np.array([split_half_sigma(p, drive.ORDERS) for p in pts]),
           "residual": np.array([residual_half_sigma_of(truth, p) for p in pts])}
    def rms(a):
        return np.round(np.sqrt(np.mean(a, axis=0)), 3).tolist()

    return {"campaign": name,
            "noise_only_reduced_chi2": {k: round(float(np.mean(resid2 / pooled_variance(v))), 3)
                                        for k, v in est.items()},
            "rms_misfit_by_order_nm": rms(resid2),
            **{f"rms_{k}_estimate_by_order_nm": rms(v ** 2) for k, v in est.items()}}


def diagnose_control(daq: str, workers: int, perturb: float, iterations: int = 3) -> list:
    rows = []
    for est, term in (("measured", "split_half"), ("residual", "residual")):
        rows.append(M.run(f"ci-control daq={daq} perturb={perturb:g} repeatability={est} iterations={iterations}", [],
                          perturb, M.CI_SEED, M.CI_POINTS, 0.8, M.ci_daq(daq), True, at_thesis_segments(),
                          {"candidates": M.CI_CANDIDATES, "calibration_iterations": iterations, "shortlist": 2,
                           "repeatability": term}, workers))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaigns", nargs="*", choices=tuple(CAMPAIGNS), default=list(CAMPAIGNS))
    ap.add_argument("--diagnose", action="store_true", help="also diagnose the CI control with each estimate")
    ap.add_argument("--daq", default="random", help="--diagnose: none, random, or parts of the random chain")
    ap.add_argument("--perturb", type=float, default=0.03,
                    help="--diagnose: the truth's relative perturbation of the estimated parameters (CI test: 0.03)")
    M.add_iterations(ap, "--diagnose: ")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    for name in args.campaigns:
        print(json.dumps(noise_check(name, args.workers)), flush=True)
    if args.diagnose:
        if not 0.0 <= args.perturb < 1.0:
            ap.error(f"--perturb {args.perturb}: accepted is a share from 0 (included) to 1 (excluded)")
        for row in diagnose_control(args.daq, args.workers, args.perturb, args.iterations):
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
