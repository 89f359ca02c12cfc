"""Independent check of the production integrator (issue 14, item 4).

At three test points, each exercising one hard part of the production step: stick-slip of
the spring masses, hardstop contact, and a mean torque on the knee:

1. the production integrator runs from the unloaded start to T_SNAP = 1.5 s (steady
   operation); its full state there is the snapshot (tests/reference/windows.py);
2. from that snapshot, the production integrator and an independently written
   right-hand side (tests/reference/compiled_reference.py: the NumPy reference's
   equations, friction explicit, compiled) integrated by scipy's BDF at rtol 1e-8 both
   run the same window (default 1.0 s);
3. over the window: output-torque order amplitudes (orders 1-8 that carry >= 2 % of the
   largest) and mean outer and inner windups are compared. Criterion of the issue: within
   1 %, or within the production run's own spread for chaotic orders. The spread: K
   production runs from the start whose input amplitudes are scaled by 1 + i 1e-9,
   100 (max - min) / median over the same window (docs/model.md §14).

The reference has no coil stacking: the production run's stacking energy over the window
is printed and must be 0 J for the comparison to hold. Also printed: the share of
contact-samples whose slip lies below 1 mm/s (stuck, well below the Makkar law's peak near
2 cm/s) and of contacts that both stick and slide (> 5 cm/s) in the window; the share of
samples with a set beyond its hardstop.

    python bench/bench_reference.py                  # three points, 1.0 s window (~minutes)
    python bench/bench_reference.py --window 0.5 --method Radau
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import dampersim as ds  # noqa: E402
from dampersim.signal import order_amplitudes  # noqa: E402
from dampersim.units import rpm_to_rad_s  # noqa: E402
from tests.reference.compiled_reference import build  # noqa: E402
from tests.reference.windows import RTOL, production, reference  # noqa: E402

T_SNAP = 1.5  # s: steady operation (the excitation is steady from 0.6 s)
RECORD_RATE = 1.0e4  # [Hz] records of both runs: the default output rate
POINTS = {
    # name: (speed [rpm], mean torque [N m], ((order, amplitude [N m], phase [rad]), ...))
    "stick-slip 1500/200, 2:300": (1500.0, 200.0, ((2, 300.0, 0.0),)),
    "hardstop 1500/450, 2:250": (1500.0, 450.0, ((2, 250.0, 0.0),)),
    "knee 1500/300, 2:150": (1500.0, 300.0, ((2, 150.0, 0.0),)),
}


def spread(system, ex, t0, t1, k_runs):
    """Per order 100 (max - min) / median [%] of the output amplitudes over [t0, t1] [s] of
    k_runs production runs with input amplitudes scaled by 1 + i 1e-9."""
    amps = []
    for i in range(k_runs):
        exi = ds.OrderSum(speed=ex.speed, mean_torque=ex.mean_torque,
                          orders=tuple((k, a * (1 + i * 1e-9), ph) for k, a, ph in ex.orders))
        res = ds.simulate(system, exi, duration=t1, record_segments=False)
        sel = (res.t >= t0 - 1e-9) & (res.t < t1 - 1e-9)
        amps.append(order_amplitudes(res.output_torque[sel], res.sample_rate, ex.speed))
    amps = np.array(amps)
    return 100 * (amps.max(0) - amps.min(0)) / np.median(amps, 0)


def contact_shares(system, ex, states):
    """(stuck share, share of contacts that both stick and slide) of the reference run."""
    R = build(system, ex.speed, ex)
    n = R.ndof
    slips = np.array([(states[n + int(m)] - states[n + int(h)]) * r for m, h, _, r in R.FR])
    stuck = np.abs(slips) < 1e-3
    both = stuck.any(1) & (np.abs(slips) > 5e-2).any(1)
    return stuck.mean(), both.mean()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--window", type=float, default=1.0, help="window length [s]")
    ap.add_argument("--method", default="BDF", choices=("BDF", "Radau"))
    ap.add_argument("--rtol", type=float, default=RTOL)
    ap.add_argument("--spread-runs", type=int, default=8)
    ap.add_argument("--points", nargs="*", default=list(POINTS), help="names of POINTS (default: all)")
    args = ap.parse_args()
    system = ds.default_parameters()
    rec_every = max(1, round(1.0 / (RECORD_RATE * system.solver.time_step)))
    hs = (system.outer.hardstop_positive, system.outer.hardstop_negative,
          system.inner.hardstop_positive, system.inner.hardstop_negative)
    print(f"window {T_SNAP}-{T_SNAP + args.window} s after a production run from the start; reference: scipy "
          f"{args.method}, rtol {args.rtol:g}; production dt = {system.solver.time_step:g} s; records at "
          f"{1 / (rec_every * system.solver.time_step):g} Hz")
    rows = []
    for name in args.points:
        rpm, mean, orders = POINTS[name]
        ex = ds.OrderSum(speed=rpm_to_rad_s(rpm), mean_torque=mean, orders=orders)
        snap, pw = production(system, ex, T_SNAP, args.window, rec_every)
        rw = reference(system, ex, snap, pw.t, method=args.method, rtol=args.rtol)
        fs = 1.0 / (rec_every * system.solver.time_step)  # the record rate, as simulate() computes it
        a_p = order_amplitudes(pw.output_torque, fs, ex.speed)
        a_r = order_amplitudes(rw.output_torque, fs, ex.speed)
        t0 = time.perf_counter()
        sp = spread(system, ex, T_SNAP, T_SNAP + args.window, args.spread_runs)
        sp_wall = time.perf_counter() - t0
        stuck, both = contact_shares(system, ex, rw.states)
        beyond = ((pw.windup_outer > hs[0]) | (pw.windup_outer < hs[1]) | (pw.windup_inner > hs[2])
                  | (pw.windup_inner < hs[3])).mean()
        print(f"\n== {name}")
        print(f"wall time: production {pw.wall_time:.3f} s, reference {rw.wall_time:.1f} s ({rw.nfev} RHS calls), "
              f"spread runs {sp_wall:.1f} s for {args.spread_runs} whole runs")
        print(f"production coil-stacking energy in the window: {pw.stacking:.3g} J; contact-samples stuck "
              f"(|slip| < 1 mm/s): {100 * stuck:.1f} %; contacts that stick and slide: {100 * both:.0f} %; "
              f"samples beyond a hardstop: {100 * beyond:.1f} %")
        print("order  production [N m]  reference [N m]  error %   spread %  verdict")
        big = 0.02 * a_r.max()
        for k in range(8):
            if a_r[k] < big and a_p[k] < big:
                continue
            err = 100 * (a_p[k] / a_r[k] - 1)
            ok = abs(err) <= max(1.0, sp[k])
            verdict = "ok" if abs(err) <= 1.0 else ("within spread" if ok else "DISAGREES")
            print(f"{k + 1:5d}  {a_p[k]:16.4f}  {a_r[k]:15.4f}  {err:+7.2f}  {sp[k]:8.2f}  {verdict}")
            rows.append((name, k + 1, a_p[k], a_r[k], err, sp[k], verdict))
        for label, p_, r_ in (("outer", pw.windup_outer, rw.windup_outer), ("inner", pw.windup_inner,
                                                                               rw.windup_inner)):
            mp, mr = p_.mean(), r_.mean()
            err = 100 * (mp / mr - 1)
            print(f"mean {label} windup: production {mp:.6f} rad, reference {mr:.6f} rad, error {err:+.3f} %"
                  f"  {'ok' if abs(err) <= 1.0 else 'DISAGREES'}")
    bad = [r for r in rows if r[-1] == "DISAGREES"]
    print(f"\norders beyond 1 % and beyond their spread: {len(bad)}")


if __name__ == "__main__":
    main()
