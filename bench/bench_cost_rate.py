"""How fast this machine runs the work :mod:`dampersim.costs` estimates, request by request.

For each kind of whole run the server admits by estimate, the run is made several times
on one core (warm kernels), and its estimated work [step·DOF] is divided by the measured
wall time: the step·DOF per second this machine achieves on it, against
``costs.STEP_DOF_PER_SECOND``, the rate every time estimate (``Cost.seconds``, the pages'
"about N min of one core", ``FOREGROUND_WORK``) divides by. A ratio below 1 means the
estimates read short.

    python bench/bench_cost_rate.py              # seven kinds, best and median of 3 runs
    python bench/bench_cost_rate.py --repeats 5

The last lines compare a pulsation-generator DOF-step with a damper one (the weight
``costs.GENERATOR_DOF_WEIGHT`` a generator DOF carries in the work).

Kinds: a test point as the Explorer computes it (bench_core.py's point, orders 2 and 4 at
1500 rpm; 48/16 segments, 2.6 s at 1/120 000 s, with its segment record), the same point at
the thesis's 18/8 segments, a sweep point (the same run without the segment record, as
sweeps make them), the full-450 hysteresis ramp protocol at 1500 rpm (30 s), the pulsation
generator alone and coupled to the damper and rig (default settings, 1500 rpm, as the
Pulsation page computes them) and one diagnosis model run (a 1 s recorded point after the
drive's lead-in, 48/16, as the Discrepancy page runs them). The process is pinned to one
core where the system allows it (Linux), so no library spreads a run over two.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import dampersim as ds
from dampersim import costs
from dampersim.discrepancy import drive
from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.synth import synthesize
from dampersim.excitation import ramp_protocol
from dampersim.parameters import at_thesis_segments, default_parameters
from dampersim.simulation import simulate_pulsation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_core import EXCITATION, SPEED  # noqa: E402 - bench_core.py's test point (orders 2 and 4, 1500 rpm)

DURATION = 2.6  # [s] a test point's simulated time ([thesis] §6.2.1)


def _kinds(tmp: Path):
    """(name, estimated Cost, callable making the whole run) for each kind."""
    base = default_parameters()
    thesis = at_thesis_segments()
    ramp = ramp_protocol("full-450", SPEED)
    d = tmp / "campaign"
    synthesize(d, effects=[], perturb=0.0, seed=0, points=["map_1500_150"], record=1.0, base=base, workers=1)
    point = next(p for p in read_campaign(d).points if p.kind == "torsional")
    sysd = drive.diagnosis_system(base)
    return [
        ("explorer point 48/16", costs.point_cost(base, DURATION), lambda: ds.simulate(base, EXCITATION)),
        ("explorer point 18/8", costs.point_cost(thesis, DURATION), lambda: ds.simulate(thesis, EXCITATION)),
        ("sweep point 48/16", costs.point_cost(base, DURATION, record_segments=False),
         lambda: ds.simulate(base, EXCITATION, record_segments=False)),
        ("ramp full-450 48/16", costs.ramp_cost(base, ramp.duration), lambda: ds.simulate(base, ramp,
                                                                                       record_segments=False)),
        ("pulsation alone", costs.pulsation_cost(), lambda: simulate_pulsation(SPEED)),
        ("pulsation coupled", costs.pulsation_cost(coupled=True), lambda: simulate_pulsation(SPEED, coupled=True)),
        ("diagnosis run 48/16, 1 s", costs.point_cost(sysd, costs.DIAGNOSIS_LEAD_IN_S + 1.0, record_segments=False),
         lambda: drive.simulate_point(sysd, point)),
    ]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per kind (after one warm-up run)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    print(f"costs.STEP_DOF_PER_SECOND = {costs.STEP_DOF_PER_SECOND:.2e}")
    print(f"{'kind':28s} {'work':>9s} {'best s':>8s} {'median s':>9s} {'rate (median)':>14s} {'rate / constant':>15s}")
    medians = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, cost, run in _kinds(Path(tmp)):
            run()  # compile or load the kernels, warm the caches
            times = []
            for _ in range(max(1, args.repeats)):
                t0 = time.perf_counter()
                run()
                times.append(time.perf_counter() - t0)
            med = statistics.median(times)
            medians[name] = (cost.work, med)
            rate = cost.work / med
            print(f"{name:28s} {cost.work:9.2e} {min(times):8.3f} {med:9.3f} {rate:14.2e} "
                  f"{rate / costs.STEP_DOF_PER_SECOND:15.2f}")

    # costs.GENERATOR_DOF_WEIGHT: a generator DOF-step's time against a damper DOF-step's
    work, med = medians["pulsation alone"]
    gen_ns = med / (work / costs.GENERATOR_DOF_WEIGHT) * 1e9
    for name in ("sweep point 48/16", "diagnosis run 48/16, 1 s"):
        dw, dm = medians[name]
        print(f"generator DOF-step {gen_ns:.0f} ns against {dm / dw * 1e9:.0f} ns of the {name}: ratio "
              f"{gen_ns / (dm / dw * 1e9):.2f} (costs.GENERATOR_DOF_WEIGHT = {costs.GENERATOR_DOF_WEIGHT})")


if __name__ == "__main__":
    main()
