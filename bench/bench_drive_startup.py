"""How well does the diagnosis's drive reproduce a record of the model itself?

The truth is the diagnosed model itself (default set, same segments and step, no
perturbation, no effect, sensor noise -60 dB re 1 N m, no channel gain error), run by the
synthetic engine drive of ``dampersim.discrepancy.synth``; the model is then driven by the
record's input torque exactly as a diagnosis drives it (``drive.simulate_point``) and its
complex output order coefficients are compared with the record's. The difference is the
drive's own error, up to what the synthetic record adds: the truth's 10 kHz output sampling
and 0.5 rpm of speed-channel noise. For scale, the record's split-half repeatability (the
likelihood's data term) is printed too. Each point's engine amplitudes are drawn from the
seed and the set of points, so a point's figures change with ``--points``.

    python bench/bench_drive_startup.py                               # four points
    python bench/bench_drive_startup.py --points map_900_150 tc_2800
    python bench/bench_drive_startup.py --settle 0          # the model without its settling
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from dampersim.discrepancy import drive, synth
from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.likelihood import measured_coefficients, split_half_sigma
from dampersim.parameters import default_parameters


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", nargs="+", default=["map_900_150", "tc_1600", "tc_2800", "map_1500_350"],
                    help="ids of the synthetic plan (dampersim.discrepancy.synth.plan)")
    ap.add_argument("--record", type=float, default=1.0, help="record length [s]")
    ap.add_argument("--seed", type=int, default=4242)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--settle", type=float, default=None,
                    help="time [s] the model runs on the looped record before it (default drive.DRIVE_SETTLE)")
    args = ap.parse_args(argv)
    settle = drive.DRIVE_SETTLE
    if args.settle is not None:
        if not args.settle >= 0:
            raise SystemExit(f"--settle {args.settle}: accepted is a time >= 0 s")
        drive.DRIVE_SETTLE = args.settle
    same = synth.truth_system
    synth.truth_system = lambda *a, **k: same(*a, **{**k, "fine": False})  # the truth is the model itself
    system = drive.diagnosis_system(default_parameters())
    t0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "campaign")
            synth.synthesize(out, effects=[], perturb=0.0, noise_db=-60.0, seed=args.seed, points=args.points,
                             record=args.record, gain_error=0.0, workers=args.workers)
            points = read_campaign(out).torsional
    finally:
        synth.truth_system = same
    print(f"model settling {drive.DRIVE_SETTLE:g} s; orders {', '.join(f'{k:g}' for k in drive.ORDERS)}; "
          "|model - record| and split-half sigma [N m]")
    try:
        for p in points:
            meas = measured_coefficients(p, drive.ORDERS)
            model = drive.simulate_point(system, p)["coefficients"]
            err = np.abs(model - meas)
            k = int(np.argmax(err))
            print(f"{p.id:14s} largest {err[k]:.3f} N m at order {drive.ORDERS[k]:g} (|record| {abs(meas[k]):.2f} N m)")
            print(f"{'':14s} |record|   {np.array2string(np.abs(meas), precision=3)}")
            print(f"{'':14s} error      {np.array2string(err, precision=3)}")
            print(f"{'':14s} split-half {np.array2string(split_half_sigma(p, drive.ORDERS), precision=3)}")
    finally:
        drive.DRIVE_SETTLE = settle
    print(f"wall {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
