"""How far does the strict CI tests' model move with its time step, against the campaign's noise?

The strict identification tests (tests/discrepancy/test_identification.py) diagnose their
campaigns with the 18/8 model at TIME_STEP, three times the parameter set's 1/120 000 s. Their
truth is synthesised at 5e-6 s whatever the model's step, so the step only changes the model
the diagnosis compares with the data. This bench synthesises the clean CI campaign (no effect,
no acquisition chain, 3 % perturbation, seed 3, points of 0.8 s) and drives the diagnosed model
(drive.simulate_point on drive.diagnosis_system, as the compare step does) with every point's
measured input at each step. Printed per step: each point's largest change of a complex output
order against the 1/120 000 s run, in units of that cell's repeatability term as the diagnosis
forms it (likelihood.sigma_variances, the term bench_float_paths.py uses), its largest and RMS
over all cells, and the largest change relative to the point's largest order. A step below
1/120 000 s shows how much of the change is the runs' own sensitivity (chaotic points move with
any change of the arithmetic) rather than the step's error.

    python bench/bench_ci_step.py                    # 1/240000, 1/120000, 1/60000, 1/40000 s
    python bench/bench_ci_step.py --steps 1/40000 1/30000 --points 8
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_control_misfit as M  # noqa: E402 - the CI campaigns, their model and --points / step parsing

from dampersim.discrepancy import drive, synth  # noqa: E402
from dampersim.discrepancy.campaign import read_campaign  # noqa: E402
from dampersim.errors import AccuracyWarning  # noqa: E402
from dampersim.parameters import at_thesis_segments  # noqa: E402

#: [s] the parameter set's step (1/120 000 s), the strict tests' up to commit 0005f3a
REFERENCE = at_thesis_segments().solver.time_step
#: [s] the steps run by default: half and twice the reference, the reference, the strict tests'
DEFAULT_STEPS = (REFERENCE / 2, REFERENCE, 2 * REFERENCE, M.CI_TIME_STEP)


def changes(runs: dict, sigma: np.ndarray, reference: float = REFERENCE) -> dict:
    """Per step of ``runs`` ({step [s]: complex orders, points x orders}): the change against
    runs[reference] in units of ``sigma`` (same shape) per point (largest over its orders), the
    largest and RMS over all cells, and the largest |change| relative to its point's largest
    order."""
    ref = runs[reference]
    out = {}
    for step, y in runs.items():
        d = np.abs(y - ref)
        z = d / np.maximum(sigma, 1e-300)
        rel = d / np.abs(ref).max(axis=1, keepdims=True)
        out[step] = {"per_point": z.max(axis=1).tolist(), "largest": float(z.max()),
                     "rms": float(np.sqrt(np.mean(z ** 2))), "largest_relative": float(rel.max())}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=M.time_step, nargs="+", default=list(DEFAULT_STEPS),
                    help="model steps [s], numbers or 1/N (the parameter set's step, the reference, is always run)")
    M.add_ci_points(ap)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", AccuracyWarning)  # steps above the checked one are the subject
    steps = list(dict.fromkeys([REFERENCE, *args.steps]))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        camp = os.path.join(d, "campaign")
        synth.synthesize(camp, effects=[], perturb=0.03, seed=M.CI_SEED, points=M.CI_POINTS[:args.points], record=0.8,
                         workers=1, daq=None, base=M.ci_base())
        pts = read_campaign(camp).torsional
    _, sigma = M.ci_repeat_term(pts)
    runs = {}
    for step in steps:
        model = drive.diagnosis_system(M.ci_base(step))
        runs[step] = np.array([drive.simulate_point(model, p)["coefficients"] for p in pts])
    ids = [p.id for p in pts]
    for step, c in changes(runs, sigma).items():
        print(json.dumps({"time_step": step, "one_over": round(1 / step), "points": ids,
                          "per_point_sigma": [round(x, 3) for x in c["per_point"]],
                          "largest_sigma": round(c["largest"], 3), "rms_sigma": round(c["rms"], 3),
                          "largest_relative": round(c["largest_relative"], 4)}), flush=True)
    print(json.dumps({"wall_s": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    main()
