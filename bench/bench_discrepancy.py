"""Benchmark of the discrepancy workflow on synthetic campaigns with hidden effects.

Cases: every effect x magnitudes x seeds (with noise and parameter perturbation),
no-effect controls and pure mis-calibration controls. For each case: synth -> diagnose,
then top-1 identification, gap reduction, recovered magnitude and wall time.

    python bench/bench_discrepancy.py --out bench-results.json            # full matrix (hours)
    python bench/bench_discrepancy.py --reduced --out bench-results.json  # one magnitude, one seed

The full matrix is 8 x 3 x 3 hidden-effect cases plus controls; each case diagnoses a
campaign of --points torsional test points.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time

import numpy as np

from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.diagnose import diagnose
from dampersim.discrepancy.effects import EFFECTS, NAMES
from dampersim.discrepancy.synth import plan, synthesize

MISCAL = (
    {"outer.spring.stiffness": 127.0 * 1.15},
    {"inner.spring.stiffness": 240.0 * 0.85, "inner.nested.stiffness": 240.0 * 0.85},
    {"friction.outer.alpha": 0.6, "friction.pair_outer.alpha": 0.3},
    {"friction.outer.alpha": 0.15},
    {"inertias.primary": 0.22, "inertias.secondary": 0.054},
)


def cases(reduced: bool, seeds: int, mags=None):
    mags = mags if mags is not None else ((1,) if reduced else (0, 1, 2))
    for name in NAMES:
        e = EFFECTS[name]
        for mi in mags:
            for seed in range(1 if reduced else seeds):
                yield {"kind": "effect", "effect": name, "values": {e.magnitude: e.magnitudes[mi]}, "seed": seed}
    for seed in range(2 if reduced else 5):
        yield {"kind": "no_effect", "effect": None, "values": {}, "seed": 100 + seed}
    for i, upd in enumerate(MISCAL[:2] if reduced else MISCAL):
        yield {"kind": "miscalibration", "effect": None, "values": {}, "updates": upd, "seed": 200 + i}


def run_case(case, n_points: int, record: float, workers: int) -> dict:
    ids = [p[0] for p in plan("all") if p[1] == "torsional"]
    step = max(1, len(ids) // n_points)
    ids = ids[::step][:n_points]
    with tempfile.TemporaryDirectory() as d:
        eff = [(case["effect"], case["values"])] if case["effect"] else []
        synthesize(d, effects=eff, perturb=0.0 if case["kind"] == "miscalibration" else 0.05, noise_db=0.0,
                   seed=case["seed"], updates=case.get("updates"), points=ids, record=record, workers=workers)
        t0 = time.perf_counter()
        diag = diagnose(read_campaign(d), workers=workers)
        wall = time.perf_counter() - t0
    out = dict(case)
    out.update({k: v for k, v in diag.to_json().items() if k in (
        "verdict", "effect_parameters", "noise_floor_nm", "gap_before_nm", "gap_calibrated_nm", "gap_after_nm")})
    out["named"] = diag.effect
    out["top"] = diag.ranking[0]["effect"] if diag.ranking else None
    out["wall_s"] = wall
    out["simulations"] = diag.simulations
    if case["effect"]:
        mag = EFFECTS[case["effect"]].magnitude
        got = diag.effect_parameters.get(mag) if diag.effect == case["effect"] else None
        out["magnitude_error"] = None if got is None else abs(got / case["values"][mag] - 1.0)
    return out


def summary(rows) -> dict:
    eff = [r for r in rows if r["kind"] == "effect"]
    ctrl = [r for r in rows if r["kind"] != "effect"]
    strong = [r for r in eff if r["gap_calibrated_nm"] >= 3 * r["noise_floor_nm"]]
    return {
        "cases": len(rows),
        "effect_cases": len(eff),
        "effect_cases_above_3x_floor": len(strong),
        "top1_identified_above_3x_floor": sum(r["named"] == r["effect"] for r in strong),
        "augmented_gap_le_1p5_floor": sum(r["gap_after_nm"] <= 1.5 * r["noise_floor_nm"] for r in strong if r["named"] == r["effect"]),
        "augmented_gap_70pct_below_calibrated": sum(r["gap_after_nm"] <= 0.3 * r["gap_calibrated_nm"] for r in strong if r["named"] == r["effect"]),
        "controls": len(ctrl),
        "controls_no_missing_effect": sum(r["verdict"] == "no_missing_effect" for r in ctrl),
        "magnitude_within_20pct": sum((r.get("magnitude_error") is not None and r["magnitude_error"] <= 0.2) for r in eff),
        "max_wall_s": max((r["wall_s"] for r in rows), default=0.0),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="bench-discrepancy.json")
    ap.add_argument("--reduced", action="store_true", help="one magnitude and one seed per effect, fewer controls")
    ap.add_argument("--only", nargs="*", help="effect names (and/or 'no_effect', 'miscalibration') to run")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--mags", help="magnitude indices to run, e.g. '2' (0 weak, 1 typical, 2 strong)")
    ap.add_argument("--points", type=int, default=12, help="torsional test points per campaign")
    ap.add_argument("--record", type=float, default=1.0, help="record length [s]")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    rows = []
    mags = tuple(int(x) for x in a.mags.split(",")) if a.mags else None
    for case in cases(a.reduced, a.seeds, mags):
        if a.only and case["kind"] not in a.only and case["effect"] not in a.only:
            continue
        r = run_case(case, a.points, a.record, a.workers)
        rows.append(r)
        print(json.dumps({k: r[k] for k in ("kind", "effect", "verdict", "named", "gap_calibrated_nm", "gap_after_nm",
                                            "noise_floor_nm", "wall_s")}), flush=True)
        with open(a.out, "w") as fh:
            json.dump({"rows": rows, "summary": summary(rows), "args": vars(a)}, fh, indent=1, default=float)
    print(json.dumps(summary(rows), indent=1))


if __name__ == "__main__":
    main()

_ = np
