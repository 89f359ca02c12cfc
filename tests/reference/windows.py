"""The production integrator and the compiled reference over the same window, from the
same state (issue 14, item 4). Used by ``bench/bench_reference.py`` (three points,
order analysis) and ``tests/reference/test_production_vs_reference.py`` (a short window).

How the window is set up:

1. the production integrator (:func:`dampersim.solver.kernels.integrate.march`, the loop
   of ``integrate``, which repeats the production ``step``) runs from the unloaded start
   to ``t_snap`` [s], in the steady part of the excitation;
2. its full state there is the snapshot: angles q at t_snap, speeds v half a step
   behind, the speeds of the step before (vprev) and the PI state and energy ledger S.
   The reference starts from q, the speed at q's time 1.5 v - 0.5 vprev (the production
   step's own second-order extrapolation) and the same PI state;
3. both integrate ``duration`` [s] more: production with its fixed step, recording every
   ``rec_every`` steps (the record holds the start-of-step state), the reference with
   scipy's implicit Radau (or BDF) at tight tolerances on the same instants.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dampersim.solver.driver import ensure_compiled, input_torque, no_generator
from dampersim.solver.engine_layout import EO_SIZE
from dampersim.solver.kernels.integrate import march, workspace
from dampersim.solver.layout import NREC, R_T, R_TOUT, R_WIND_I, R_WIND_O, S_E_STACK, S_SIZE, S_Z, build_layout, \
    initial_state
from tests.reference.compiled_reference import build

#: Radau tolerances. rtol 1e-8 is five orders below the 1 % the comparison asks of an
#: order amplitude. atol per state scale: angles [rad] (windups 0.1-0.6 rad, spring
#: segments ~0.1 rad) 1e-10 rad; speeds [rad/s] (slip and fluctuation speeds 0.01-10 rad/s)
#: 1e-7 rad/s; the PI state [rad] (~0.1 rad) 1e-10 rad.
RTOL = 1e-8
ATOL_ANGLE = 1e-10
ATOL_SPEED = 1e-7


@dataclass
class Window:
    """One run over the window: t [s] at the recorded instants, output torque [N m],
    outer and inner windup [rad], wall time [s]; ``stacking`` [J] is the production
    run's coil-stacking energy over the window (0 when stacking never occurred), ``states``
    the reference's full states (2 ndof + 1, samples) or None, ``nfev`` its right-hand-side
    evaluations (0 for production)."""

    t: np.ndarray
    output_torque: np.ndarray
    windup_outer: np.ndarray
    windup_inner: np.ndarray
    wall_time: float
    stacking: float = 0.0
    states: np.ndarray | None = None
    nfev: int = 0


@dataclass
class Snapshot:
    """The production state at t [s] (see the module docstring)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    vprev: np.ndarray
    S: np.ndarray


def _march(lay, state, torque, rec_every, rec):
    q, v, vprev, S, W = state
    G = (np.zeros(0), np.zeros(0), np.zeros(EO_SIZE))
    status, done = march(q, v, vprev, S, torque, lay.P, lay.SF, lay.SI, lay.J, lay.rig, lay.contacts_idx,
                         lay.contacts_f, lay.singles, lay.pairs, rec_every, 1, rec, np.zeros((0, lay.n_nodes)),
                         np.zeros(NREC), np.zeros(lay.n_nodes), np.zeros(0), W, *no_generator(), G)
    if status != 0:
        raise RuntimeError(f"production run diverged (status {status}) at step {done}")


def production(system, excitation, t_snap: float, duration: float, rec_every: int) -> tuple[Snapshot, Window]:
    """Production run to ``t_snap`` [s], its snapshot there, then ``duration`` [s] more,
    recorded every ``rec_every`` steps."""
    lay = build_layout(system, float(excitation.speed))
    ensure_compiled(lay)
    dt = system.solver.time_step
    n0 = int(round(t_snap / dt))
    n1 = int(round(duration / dt))
    torque = input_torque(excitation, n0 + n1, dt)
    q, v = initial_state(lay)
    state = (q, v, v.copy(), np.zeros(S_SIZE),
             workspace(lay.J, lay.n_nodes, len(lay.contacts_idx), len(lay.singles), len(lay.pairs)))
    _march(lay, state, torque[:n0], n0 + 1, np.zeros((0, NREC)))
    snap = Snapshot(n0 * dt, q.copy(), v.copy(), state[2].copy(), state[3].copy())
    rec = np.zeros(((n1 + rec_every - 1) // rec_every, NREC))
    stack0 = state[3][S_E_STACK]
    t0 = time.perf_counter()
    _march(lay, state, torque[n0:], rec_every, rec)
    wall = time.perf_counter() - t0
    t = snap.t + rec[:, R_T]  # the march counts time from its own first step
    return snap, Window(t, rec[:, R_TOUT], rec[:, R_WIND_O], rec[:, R_WIND_I], wall,
                        stacking=float(state[3][S_E_STACK] - stack0))


def reference(system, excitation, snap: Snapshot, t_eval: np.ndarray, method: str = "Radau",
              rtol: float = RTOL) -> Window:
    """The compiled reference integrated by scipy from the snapshot to t_eval[-1] [s],
    sampled at t_eval."""
    R = build(system, float(excitation.speed), excitation)
    if snap.t < R.steady_start:
        raise ValueError("the snapshot must lie in the steady part of the excitation")
    n = R.ndof
    y0 = np.concatenate([snap.q, 1.5 * snap.v - 0.5 * snap.vprev, [snap.S[S_Z]]])
    atol = np.concatenate([np.full(n, ATOL_ANGLE), np.full(n, ATOL_SPEED), [ATOL_ANGLE]])
    R.rhs(snap.t, y0)  # compile (or load) before timing
    t0 = time.perf_counter()
    sol = solve_ivp(R.rhs, (snap.t, t_eval[-1]), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval)
    wall = time.perf_counter() - t0
    if sol.status != 0:
        raise RuntimeError(f"scipy {method} failed: {sol.message}")
    wo, wi = R.windups(sol.y)
    return Window(sol.t, R.output_torque(sol.y), wo, wi, wall, states=sol.y, nfev=sol.nfev)
