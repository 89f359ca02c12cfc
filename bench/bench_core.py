"""Benchmark of the simulation core (one default test point).

Prints: kernel compile/load time, wall time per default test point (2.6 s simulated,
1500 rpm, default 48/16 segments and time step) and ns per DOF-step, and the same point
with the thesis's 18/8 segments (the point of the speed target); the accuracy against a
1e-6 s reference run; and the same equations (the kernel's explicit right-hand side
``rhs``) integrated by scipy's solve_ivp (LSODA) over the whole 2.6 s test point, once:
its measured wall time (not scaled from a shorter interval) and its output order
amplitudes against dampersim's over the same analysis window.

    python bench/bench_core.py            # full run (several minutes: LSODA dominates)
    python bench/bench_core.py --quick    # skip the 1e-6 s reference and LSODA
    python bench/bench_core.py --no-lsoda # skip LSODA only
    python bench/bench_core.py --segments 18/8,48/16   # only the point's time at these counts
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import dampersim as ds
from dampersim.errors import AccuracyWarning
from dampersim.parameters import at_thesis_segments, with_updates
from dampersim.simulation import ensure_compiled
from dampersim.solver.kernels.forces import rhs
from dampersim.signal import order_amplitudes
from dampersim.solver.layout import P_RIG0, P_TRANS, build_layout, initial_state
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


def lsoda(system, t_rec):
    """The whole test point integrated once by scipy's LSODA from the unloaded start.

    Right-hand side: the kernel's explicit ``rhs`` (friction explicit; the regularised
    Makkar law is smooth), input torque from the excitation at each evaluation.
    Tolerances: rtol 1e-6, atol 1e-9 on every state (angles [rad], speeds [rad/s], PI
    state [rad]). Sampled at t_rec [s] (dampersim's record instants). Returns the measured
    wall time [s], the number of right-hand-side calls, the solver status and the output
    torque [N m] (transducer shaft, docs/model.md §2) at t_rec.
    """
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
    f(0.0, y0)  # compile outside the timing
    t0 = time.perf_counter()
    sol = solve_ivp(f, (0.0, float(t_rec[-1])), y0, method="LSODA", rtol=1e-6, atol=1e-9, t_eval=t_rec)
    wall = time.perf_counter() - t0
    # output transducer shaft torque: K (theta_before - theta) + B_k (omega_before - omega)
    d = int(lay.P[P_TRANS])
    e = d - int(lay.P[P_RIG0])
    prev = 2 if e == 0 else d - 1
    k, bk = lay.rig[e, 0], lay.rig[e, 1]
    tout = k * (sol.y[prev] - sol.y[d]) + bk * (sol.y[n + prev] - sol.y[n + d])
    return wall, sol.nfev, sol.status, tout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-lsoda", action="store_true")
    ap.add_argument("--segments", default=None,
                    help="only time the point at these 'outer/inner' segment counts, comma-separated")
    args = ap.parse_args()
    system = ds.default_parameters()
    compile_s = ensure_compiled()
    if args.segments:
        for item in args.segments.split(","):
            no, ni = (int(x) for x in item.split("/"))
            best, median, _ = timed_point(with_updates(system, {"solver.outer_segments": no,
                                                                "solver.inner_segments": ni}))
            print(f"segments {no}/{ni}: wall time per test point best {best:.3f} s, median {median:.3f} s", flush=True)
        return
    lay = build_layout(system, SPEED)
    steps = int(round(system.solver.duration / system.solver.time_step))
    best, median, res = timed_point(system)
    print(f"kernel compile/cache load: {compile_s:.2f} s (once per process)")
    print(f"default test point: {system.solver.duration} s simulated, dt = {system.solver.time_step:g} s, "
          f"{lay.ndof} DOFs, {len(lay.contacts_idx)} friction contacts, {steps} steps")
    print(f"wall time per test point: best {best:.3f} s, median {median:.3f} s")
    print(f"ns per DOF-step: {best / (steps * lay.ndof) * 1e9:.1f}")
    thesis = at_thesis_segments(system)
    best18, median18, _ = timed_point(thesis)
    steps_dof18 = steps * build_layout(thesis, SPEED).ndof
    print(f"the same point with the thesis's 18/8 segments (the default until the segment grid; the speed "
          f"target's point): best {best18:.3f} s, median {median18:.3f} s, {best18 / steps_dof18 * 1e9:.1f} ns per DOF-step")
    with warnings.catch_warnings():  # the coarser step is above the accuracy-tested default
        warnings.simplefilter("ignore", AccuracyWarning)
        coarse = with_updates(thesis, {"solver.time_step": 1.0 / 60000.0})
        best60, median60, _ = timed_point(coarse)
    print(f"the same 18/8 point at 1/60 000 s (the default step until the accuracy grid): best {best60:.3f} s, "
          f"median {median60:.3f} s")
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
    if args.no_lsoda:
        return
    wall, nfev, status, tout = lsoda(system, res.t)
    w = res.window()
    l_out = order_amplitudes(tout[w], res.sample_rate, SPEED)
    print(f"scipy solve_ivp LSODA, whole {system.solver.duration} s test point, run once: {wall:.1f} s wall "
          f"(measured; {nfev} RHS calls, status {status}); dampersim {best:.3f} s -> {wall / best:.0f}x")
    print("order  dampersim [N m]  LSODA [N m]  difference")
    for k in range(1, 9):
        a, b = a_out[k - 1], l_out[k - 1]
        rel = f"{100 * (a / b - 1):+.2f} %" if b > 0.02 * max(l_out) else "(below 2 % of the largest order)"
        print(f"{k:5d}  {a:15.4f}  {b:11.4f}  {rel}")


if __name__ == "__main__":
    main()
