"""Accuracy figures of the simulation core, printed (the physics tests only assert them).

Energy balance at the default point, frictionless forced response against the exported
M, C, K, the static curve, convergence in time step and segment count, and speed
stiffening of the outer set.

    python bench/bench_accuracy.py      # about 1 min on 2 cores

The accuracy grid (bench/accuracy_grid.py: 32 test points, each order against a 1e-6 s
or 64/24-segment reference (``--reference`` chooses another), tolerance 1 % / 2 % or twice the order's physical spread):

    python bench/bench_accuracy.py --grid step                  # default step (~15 min first time)
    python bench/bench_accuracy.py --grid step --steps 2e-5,1/60000
    python bench/bench_accuracy.py --grid segments --segments 18/8,24/10,32/12,40/14,48/16
    python bench/bench_accuracy.py --grid step --set solver.friction_scheme=trapezoidal
    python bench/bench_accuracy.py --grid newton   # friction re-solves per point (~30 s)
    python bench/bench_accuracy.py --energy        # energy balance across the knee only
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

import dampersim as ds
from dampersim.excitation import TorqueRamp
from dampersim.parameters import with_updates
from dampersim.solver.linear import linearise
from dampersim.studies.studies import secondary_end_share
from dampersim.units import rpm_to_rad_s

P = ds.default_parameters()


def order2(system, rpm):
    ex = ds.OrderSum(speed=rpm_to_rad_s(rpm), mean_torque=200.0, orders=((2, 300.0, 0.0),))
    return ds.simulate(system, ex, record_segments=False).order_amplitudes()[1][1]


def knee_energy():
    """Energy balance at a point whose outer hardstop closes every cycle (1500 rpm,
    320 +- 300 N m): residual against friction plus contact dissipation [J]."""
    ex = ds.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=320.0, orders=((2, 300.0, 0.0),))
    res = ds.simulate(P, ex, record_segments=False)
    e = res.energy
    print(f"energy across the knee: residual {res.energy_residual()[-1]:.3f} J against "
          f"{e['friction'][-1] + e['hardstop'][-1]:.1f} J of friction ({e['friction'][-1]:.1f} J) and hardstop "
          f"contact ({e['hardstop'][-1]:.1f} J) dissipation")


def grid(kind, candidates, workers, overrides=None, reference=None):
    """Print the accuracy grid for each candidate (a time step [s] or 'outer/inner' segment
    counts, with the parameter ``overrides`` {dotted name: value}) against the default
    set's reference (``reference``: its step [s] or segment pair, None for the grid's
    default), and a summary line per candidate."""
    import accuracy_grid as ag

    ref_out, spread, sens = ag.references(P, kind, workers, reference)
    if kind == "step":
        ref_label = f"a {reference or ag.REFERENCE_STEP:.6g} s"
    else:
        ref_label = "a {}/{}-segment".format(*(reference or ag.REFERENCE_SEGMENTS))
    limit = 1.0 if kind == "step" else 2.0
    base = with_updates(P, overrides or {})
    for cand in candidates:
        if kind == "step":
            system = with_updates(base, {"solver.time_step": cand})
            label = f"time step {cand:.6g} s"
        else:
            no, ni = cand
            system = with_updates(base, {"solver.outer_segments": no, "solver.inner_segments": ni})
            label = f"segments {no}/{ni}"
        if overrides:
            label += " with " + ", ".join(f"{k}={v}" for k, v in overrides.items())
        err, ok, allowed = ag.errors(system, ref_out, spread, limit, workers)
        print(f"--- {label} against {ref_label} reference")
        for row in ag.table(err, spread, sens, ok, allowed):
            print(row)
        judged = ~np.isnan(err)
        fails = judged & ~ok
        multi = fails & (np.abs(err) <= 2 * np.nan_to_num(sens))
        worst = np.nanmax(np.abs(err) - allowed)
        bad_points = sorted({ag.POINTS[i] for i in np.nonzero(fails.any(axis=1))[0]})
        print(f"=== {label}: {int(ok[judged].sum())}/{int(judged.sum())} judged orders pass, "
              f"{int(multi.sum())} of the {int(fails.sum())} failures within twice the reference's tolerance "
              f"sensitivity; largest excess over the allowed error {worst:+.2f} points; "
              f"points with a failure: {len(bad_points)}/{len(ag.POINTS)}", flush=True)


def main():
    ex = ds.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=200.0, orders=((2, 300.0, 0.0), (4, 100.0, 0.0)))
    res = ds.simulate(P, ex, record_segments=False)
    e = res.energy
    losses = e["friction"][-1] + e["damping"][-1] + e["stacking"][-1]
    print(f"energy: residual {res.energy_residual()[-1]:.4f} J against {losses:.1f} J of losses "
          f"({e['friction'][-1]:.1f} J friction), input work {e['input_work'][-1]:.0f} J")

    lin_sys = with_updates(P, {"friction.enabled": False, "hardstops.enabled": False, "motor.mode": "held"})
    lm = linearise(lin_sys, motor="held")
    errs = []
    for f in (15.0, 40.0, 80.0, 150.0, 220.0, 330.0):
        k = f / 25.0
        r = ds.simulate(lin_sys, ds.OrderSum(speed=rpm_to_rad_s(1500), mean_torque=100.0, orders=((k, 10.0, 0.0),)),
                        record_segments=False)
        a_in, a_out = r.order_amplitudes(orders=(k,))
        errs.append((f, 100 * (a_out[0] / a_in[0] / abs(lm.output_torque_response(2 * np.pi * f)) - 1)))
    print("linear limit, MR error vs M/C/K [%]: " + ", ".join(f"{f:g} Hz {x:+.3f}" for f, x in errs))

    st = with_updates(P, {"friction.enabled": False, "motor.mode": "held", "solver.output_sample_rate": 2000})
    r = ds.simulate(st, TorqueRamp(speed=rpm_to_rad_s(500), points=(0.0, 600.0), rate=50.0, hold=0.0, lead=0.2),
                    record_segments=False)
    t, w = r.input_torque, r.windup_outer + r.windup_inner
    k_o = P.outer.count * P.outer.spring.stiffness
    k_i = P.inner.count * (P.inner.spring.stiffness + P.inner.nested.stiffness)
    m = (t > 50) & (t < 250)
    m2 = (t > 350) & (t < 580)
    print(f"static curve: series {1 / np.polyfit(t[m], w[m], 1)[0]:.2f} (expected {1 / (1 / k_o + 1 / k_i):.2f}) N m/rad, "
          f"knee {t[np.argmax(r.hardstop_outer > 0)]:.2f} (expected {k_o * P.outer.hardstop_positive:.2f}) N m, "
          f"above knee {1 / np.polyfit(t[m2], w[m2], 1)[0]:.1f} (expected {k_i:.1f}) N m/rad")

    dt = P.solver.time_step
    for rpm in (1500, 2500):
        a = order2(P, rpm)
        b = order2(with_updates(P, {"solver.time_step": dt / 2}), rpm)
        c = order2(with_updates(P, {"solver.outer_segments": 64, "solver.inner_segments": 24}), rpm)
        print(f"convergence at {rpm} rpm, 2nd order {a:.4f} N m: halved step {100 * (b / a - 1):+.2f} %, "
              f"64/24 segments {100 * (c / a - 1):+.2f} %")

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # the stiffness probe of the tests
    from tests.physics.test_speed_stiffening import _run

    k5a, ang5a, comp_a = _run(500, 20.0)
    k5b, ang5b, comp_b = _run(3000, 50.0)
    k30a, ang30a, _ = _run(500, 100.0)
    k30b, ang30b, _ = _run(3000, 100.0)
    print(f"speed stiffening 500 -> 3000 rpm: x{k5b / k5a:.2f} at {ang5a:.1f}/{ang5b:.1f} deg, "
          f"x{k30b / k30a:.2f} at {ang30a:.1f}/{ang30b:.1f} deg; compression share of the secondary end "
          f"(5/18 of the length) {secondary_end_share(comp_a):.3f} -> {secondary_end_share(comp_b):.3f}")


def _step(text):
    """A time step [s] written as a number or a quotient 'a/b'."""
    num, _, den = text.partition("/")
    return float(num) / float(den) if den else float(num)


def _cli():
    import argparse

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--energy", action="store_true", help="only the energy balance across the knee")
    ap.add_argument("--grid", choices=("step", "segments", "newton"),
                    help="run the accuracy grid instead ('newton': friction re-solve counts at the grid's points)")
    ap.add_argument("--steps", default=None, help="candidate steps [s], comma-separated (a/b allowed)")
    ap.add_argument("--segments", default=None, help="candidate 'outer/inner' segment counts, comma-separated")
    ap.add_argument("--reference", default=None,
                    help="the reference: a step [s] for --grid step, 'outer/inner' for --grid segments")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="parameter override of the candidates (not of the reference), repeatable")
    a = ap.parse_args()
    if a.energy:
        knee_energy()
        return
    if a.grid is None:
        main()
        knee_energy()
        return
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    if a.grid == "newton":
        import accuracy_grid as ag

        rows = ag.newton_statistics(P)
        for point, share, last in rows:
            print(f"{point[0]:5d} rpm {point[1]:5.0f} +- {point[2]:3.0f} N m  re-solved steps {100 * share:6.2f} %  "
                  f"last resort {last}")
        shares = [r[1] for r in rows]
        print(f"=== time step {P.solver.time_step:.6g} s: re-solved steps median {100 * np.median(shares):.2f} % "
              f"(min {100 * min(shares):.2f} %, max {100 * max(shares):.2f} %), last-resort steps {sum(r[2] for r in rows)}")
        return
    if a.grid == "step":
        cands = [P.solver.time_step] if a.steps is None else [_step(x) for x in a.steps.split(",")]
    else:
        raw = a.segments or f"{P.solver.outer_segments}/{P.solver.inner_segments}"
        cands = [tuple(int(n) for n in x.split("/")) for x in raw.split(",")]
    overrides = {}
    for item in a.set:
        name, _, value = item.partition("=")
        overrides[name] = _value(value)
    if a.reference is None:
        reference = None
    elif a.grid == "step":
        reference = _step(a.reference)
    else:
        reference = tuple(int(n) for n in a.reference.split("/"))
    grid(a.grid, cands, a.workers, overrides, reference)


def _value(text):
    """A --set value: a number where it reads as one, else the text."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


if __name__ == "__main__":
    _cli()
