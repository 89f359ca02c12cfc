"""How much do the strict CI campaigns move with the machine's floating-point path?

The campaigns of tests/discrepancy/test_identification.py (bench_control_misfit.py's
``ci-control`` with no acquisition chain, the clean test's, and ``ci-absorber`` with the
random chain of seed 3, the absorber test's: 18/8 model, 24/10 truth, points of 0.8 s, 3 %
perturbation, seed 3; ``--points 8`` the strict clean test's eight, the default all nine;
``--time-step 1/40000`` the strict tests' model step after commit 0005f3a, the default the
parameter set's 1/120000 s, theirs up to then)
are synthesised and diagnosed once per variant, each in a process of its own whose
environment changes only how the same arithmetic is compiled or dispatched:

    host            as installed (numba compiles for this CPU, numpy and OpenBLAS pick theirs)
    numba-generic   NUMBA_CPU_NAME=generic: the kernel compiled for a generic x86-64
    numpy-v2        NPY_DISABLE_CPU_FEATURES=X86_V3: numpy's AVX2/FMA3 loops off
    openblas-sb     OPENBLAS_CORETYPE=Sandybridge: another BLAS kernel

None of them changes a parameter, a seed or an equation. Printed per variant: verdict, the
float-path settings and what the process saw (numba's target CPU, numpy's features,
OpenBLAS's kernels), posterior of "none" and of the absorber, the absorber's fitted inertia
[kg m^2] and its 90 % interval, held-out reduced chi^2 (calibrated and most probable) and
training reduced chi^2, model runs, wall time, and how far its synthesised measured output
orders lie from the host's, per point as the largest |difference| over the orders in units
of the host's repeatability term of that cell as the diagnosis forms it
(likelihood.sigma_variances; 0 where the syntheses agree). Only the kernel's code moves the
synthesised data: where the truth run is chaotic by up to 1.44 (control) and 0.81 (absorber)
of that term on the nine points, 0.80 on the control's eight, elsewhere by less than 0.03.
The other variants leave the data unchanged to
the printed digits and move the diagnosis's path. docs/discrepancy.md (Known limits) quotes
the figures.

    python bench/bench_float_paths.py                       # all four, one after another
    python bench/bench_float_paths.py --variants host numba-generic
    python bench/bench_float_paths.py --case ci-absorber
    python bench/bench_float_paths.py --points 8            # the strict clean test's campaign up to 0005f3a
    python bench/bench_float_paths.py --points 8 --time-step 1/40000   # ... and since (its model's step)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_control_misfit as M  # noqa: E402 - the CI campaigns and their diagnosis options
import bench_discrepancy as B  # noqa: E402 - machine(): what a result line's figures depend on

VARIANTS = {
    "host": {},
    "numba-generic": {"NUMBA_CPU_NAME": "generic"},
    "numpy-v2": {"NPY_DISABLE_CPU_FEATURES": "X86_V3"},
    "openblas-sb": {"OPENBLAS_CORETYPE": "Sandybridge"},
}


def variant_env(name: str, environ) -> dict:
    """The environment of variant ``name``: ``environ`` without any float-path setting of the
    caller's (bench_discrepancy.FLOAT_PATH_ENV), plus the variant's own."""
    return {**{k: v for k, v in environ.items() if k not in B.FLOAT_PATH_ENV}, **VARIANTS[name]}


def worker(out: str, case: str, workers: int, points: int = len(M.CI_POINTS), step: float | None = None) -> None:
    """Synthesise and diagnose a CI campaign in this process, the model at ``step`` [s] (None: the
    parameter set's); write the measured coefficients, the diagnosis's repeatability term per cell
    and the diagnosis's figures to ``out`` (JSON)."""
    import warnings

    from dampersim.discrepancy import synth
    from dampersim.discrepancy.campaign import read_campaign
    from dampersim.discrepancy.diagnose import diagnose
    from dampersim.errors import AccuracyWarning

    warnings.simplefilter("ignore", AccuracyWarning)  # a step above the checked one is the point of --time-step
    base = M.ci_base(step)
    t0 = time.perf_counter()
    effects, daq = M.CI_CASES[case]
    with tempfile.TemporaryDirectory() as d:
        camp = os.path.join(d, "campaign")
        synth.synthesize(camp, effects=effects, perturb=0.03, seed=M.CI_SEED, points=M.CI_POINTS[:points],
                         record=0.8, workers=workers, daq=M.ci_daq(daq), base=base)
        c = read_campaign(camp)
        coef, sig = M.ci_repeat_term(c.points)
        g = diagnose(c, base, workers=workers, recommend=False, **M.CI_DIAGNOSIS)
    lk = g.likelihood
    fitted = next((e for e in g.effects if e["name"] == "pendulum_absorber"), None)
    ids = [p.id for p in c.points]
    doc = {"verdict": g.verdict, "none": g.posterior.get("none"), "absorber": g.posterior.get("pendulum_absorber"),
           "inertia": fitted and fitted["parameters"]["inertia"], "interval": fitted and fitted["intervals"]["inertia"],
           "held_out_calibrated": lk["reduced_chi2_held_out_calibrated"], "held_out": lk["reduced_chi2_held_out"],
           "train": lk["reduced_chi2_train"], "noise_level": lk["noise_level"], "runs": g.simulations,
           "wall_s": time.perf_counter() - t0, "machine": B.machine(), "time_step": base.solver.time_step,
           "coef": {k: [np.real(v).tolist(), np.imag(v).tolist()] for k, v in zip(ids, coef)},
           "sigma": {k: v.tolist() for k, v in zip(ids, sig)}}
    with open(out, "w") as f:
        json.dump(doc, f)


def spread(ref: dict, other: dict) -> dict:
    """Per point, the largest |measured difference| over the orders in units of the reference's
    repeatability term (0 where the two syntheses agree)."""
    out = {}
    for pid, (re, im) in ref["coef"].items():
        a = np.asarray(re) + 1j * np.asarray(im)
        b = np.asarray(other["coef"][pid][0]) + 1j * np.asarray(other["coef"][pid][1])
        out[pid] = float(np.max(np.abs(a - b) / np.maximum(np.asarray(ref["sigma"][pid]), 1e-300)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=("ci-control", "ci-absorber"), default="ci-control")
    ap.add_argument("--variants", nargs="+", choices=tuple(VARIANTS), default=list(VARIANTS))
    ap.add_argument("--workers", type=int, default=2)
    M.add_ci_points(ap)
    M.add_ci_time_step(ap)
    ap.add_argument("--worker", metavar="OUT", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.worker, args.case, args.workers, args.points, args.time_step)
        return
    step = [] if args.time_step is None else ["--time-step", repr(args.time_step)]
    variants = ["host"] + [v for v in dict.fromkeys(args.variants) if v != "host"]  # the reference runs first
    docs = {}
    with tempfile.TemporaryDirectory() as d:
        for name in variants:
            env = variant_env(name, os.environ)
            out = os.path.join(d, f"{name}.json")
            subprocess.run([sys.executable, os.path.abspath(__file__), "--worker", out, "--case", args.case,
                            "--workers", str(args.workers), "--points", str(args.points), *step], env=env, check=True)
            with open(out) as f:
                docs[name] = json.load(f)
            r = docs[name]
            moved = spread(docs["host"], r)
            print(json.dumps({"case": args.case, "points": args.points, "time_step": r["time_step"], "variant": name,
                              "env": r["machine"]["env"], "verdict": r["verdict"],
                              "none": r["none"], "pendulum_absorber": r["absorber"], "inertia": r["inertia"],
                              "interval": r["interval"], "reduced_chi2_held_out_calibrated": r["held_out_calibrated"],
                              "reduced_chi2_held_out": r["held_out"], "reduced_chi2_train": r["train"],
                              "noise_level": r["noise_level"], "runs": r["runs"], "wall_s": round(r["wall_s"], 1),
                              "numba_cpu": r["machine"]["cpu"].get("name"), "numpy_cpu": r["machine"]["numpy_cpu"],
                              "blas": r["machine"]["blas"],
                              "measured_moved_sigma": {k: round(v, 3) for k, v in moved.items()}}), flush=True)


if __name__ == "__main__":
    main()
