"""Benchmark of the simulation core (one default test point).

Prints: kernel compile/load time, wall time per default test point (2.6 s simulated,
1500 rpm, 18/8 segments, default time step) and ns per DOF-step; the accuracy against a
1e-6 s reference run; and the same equations integrated by scipy's solve_ivp (LSODA)
over a short interval for comparison.

    python bench/bench_core.py            # full run (~1 min)
    python bench/bench_core.py --quick    # skip the 1e-6 s reference and LSODA
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import dampersim as ds
from dampersim.parameters import with_updates
from dampersim.simulation import ensure_compiled
from dampersim.solver.kernels.forces import rhs
from dampersim.solver.layout import build_layout, initial_state
from dampersim.units import rpm_to_rad_s

SPEED = rpm_to_rad_s(1500)
EXCITATION = ds.OrderSum(speed=SPEED, mean_torque=200.0, orders=((2, 300.0, 0.0), (4, 100.0, 0.0)))


def timed_point(system, repeats=5):
    times = []
    res = None
    for _ in range(repeats):
        res = ds.simulate(system, EXCITATION, record_segments=False)
        times.append(res.wall_time)
    return min(times), float(np.median(times)), res


def lsoda(system, t_end):
    from scipy.integrate import solve_ivp

    lay = build_layout(system, SPEED)
    q0, v0 = initial_state(lay)
    n = lay.ndof

    def f(t, y):
        q, v, z = y[:n], y[n:2 * n], y[2 * n]
        tin = float(EXCITATION.torque(np.array([t]))[0])
        dq, dv, dz = rhs(q, v, z, tin, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx,
                              lay.contacts_f, lay.n_nodes)
        return np.concatenate([dq, dv, [dz]])

    y0 = np.concatenate([q0, v0, [0.0]])
    f(0.0, y0)
    t0 = time.perf_counter()
    sol = solve_ivp(f, (0.0, t_end), y0, method="LSODA", rtol=1e-6, atol=1e-9)
    return time.perf_counter() - t0, sol.nfev, sol.status


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    system = ds.default_parameters()
    compile_s = ensure_compiled()
    lay = build_layout(system, SPEED)
    steps = int(round(system.solver.duration / system.solver.time_step))
    best, median, res = timed_point(system)
    print(f"kernel compile/cache load: {compile_s:.2f} s (once per process)")
    print(f"default test point: {system.solver.duration} s simulated, dt = {system.solver.time_step:g} s, "
          f"{lay.ndof} DOFs, {len(lay.contacts_idx)} friction contacts, {steps} steps")
    print(f"wall time per test point: best {best:.3f} s, median {median:.3f} s")
    print(f"ns per DOF-step: {best / (steps * lay.ndof) * 1e9:.1f}")
    a_in, a_out = res.order_amplitudes()
    print("output order amplitudes [N m]:", np.round(a_out, 4).tolist())
    if args.quick:
        return
    ref_sys = with_updates(system, {"solver.time_step": 1e-6})
    t0 = time.perf_counter()
    ref = ds.simulate(ref_sys, EXCITATION, record_segments=False)
    ref_wall = time.perf_counter() - t0
    r_in, r_out = ref.order_amplitudes()
    for k in (2, 4, 6):
        print(f"order {k}: default {a_out[k - 1]:.4f} N m, 1e-6 s reference {r_out[k - 1]:.4f} N m, "
              f"difference {100 * (a_out[k - 1] / r_out[k - 1] - 1):+.2f} %")
    print(f"1e-6 s reference wall time: {ref_wall:.1f} s")
    t_end = 0.05
    wall, nfev, status = lsoda(system, t_end)
    ours = best * t_end / system.solver.duration
    print(f"scipy solve_ivp LSODA over {t_end} s: {wall:.2f} s wall ({nfev} RHS calls, status {status}); "
          f"dampersim for the same interval: {ours:.4f} s -> {wall / ours:.0f}x faster")
    print(f"extrapolated LSODA per 2.6 s test point: {wall * system.solver.duration / t_end:.0f} s")


if __name__ == "__main__":
    main()
