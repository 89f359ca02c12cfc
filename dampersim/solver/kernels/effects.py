"""The optional effects of the discrepancy library (:mod:`dampersim.discrepancy.effects`).

Each is off when its P slot is zero; see :mod:`dampersim.solver.layout` for the slots.
Smooth effects add torques in :func:`dampersim.solver.kernels.forces.forces`; the lock-up
clutch's slip is solved implicitly after the friction step. Effect inner_short_springs
has no kernel of its own: the layout adds its pair as spring rows and friction contacts.
"""

from numba import njit

from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.fastmath import fast_tanh
from dampersim.solver.layout import (
    I_N,
    I_OFF,
    P_CL_CAP,
    P_CL_VISC,
    P_CL_WS,
    P_INPUT,
    P_NRT,
    P_PA_C,
    P_PA_DOF,
    P_PA_K,
    P_TD_C,
)



@njit(inline="always", **JIT)
def dead_zone(x, half):
    """x with a band of +-half removed (free play): 0 inside, x -+ half outside."""
    if x > half:
        return x - half
    if x < -half:
        return x + half
    return 0.0


@njit(**LEAF)
def nested_radial_transfer(P, SI, FN):
    """Effect nested_radial_transfer ([thesis] §5.3.2): the inner spring of each nested
    pair presses on its outer spring, so a share P[P_NRT] of the inner mass's normal force
    adds to the normal force of the outer spring's mass of the same index. Spring rows 1
    and 2 are the normal pair (outer, inner), rows 3 and 4 the short pair of effect
    inner_short_springs when present; both springs of a pair represent the same number
    of pairs, so the count-scaled forces add directly."""
    f = P[P_NRT]
    for r in range(1, SI.shape[0] - 1, 2):
        n = SI[r, I_N]
        o1 = SI[r, I_OFF]
        o2 = SI[r + 1, I_OFF]
        for i in range(n - 1):
            FN[o1 + i] += f * FN[o2 + i]


@njit(**LEAF)
def effect_forces(q, v, P, FC, FD):
    """Conservative (FC) and dissipative (FD) torques of the smooth effects; returns their
    elastic energy [J].

    - turbine_drag: T = c (v_housing - v_sec) on J_sec, the reaction on the housing
      (J_pri, or the clutch drive side when the clutch can slip);
    - pendulum_absorber: linearised pendulum DOF on J_sec with restoring stiffness
      J_a (n Omega0)^2 and damping c_a.
    """
    energy = 0.0
    c = P[P_TD_C]
    if c > 0.0:
        h = int(P[P_INPUT])
        t = c * (v[h] - v[1])
        FD[1] += t
        FD[h] -= t
    pa = int(P[P_PA_DOF])
    if pa >= 0:
        dq = q[1] - q[pa]
        tk = P[P_PA_K] * dq
        td = P[P_PA_C] * (v[1] - v[pa])
        FC[1] -= tk
        FC[pa] += tk
        FD[1] -= td
        FD[pa] += td
        energy += 0.5 * P[P_PA_K] * dq * dq
    return energy


@njit(**LEAF)
def effect_energy(q, P):
    """Elastic energy [J] stored by the effects' springs (see effect_forces)."""
    energy = 0.0
    pa = int(P[P_PA_DOF])
    if pa >= 0:
        dq = q[1] - q[pa]
        energy += 0.5 * P[P_PA_K] * dq * dq
    return energy


@njit(inline="always", **JIT)
def clutch_law(s, P):
    """Lock-up clutch torque [N m] passed from the drive side to J_pri at slip speed s
    [rad/s] (effect clutch_slip) and its slope: capacity * tanh(s / s_slip) + c_oil * s."""
    cap = P[P_CL_CAP]
    ws = P[P_CL_WS]
    th = fast_tanh(s / ws)
    return cap * th + P[P_CL_VISC] * s, cap * (1.0 - th * th) / ws + P[P_CL_VISC]


@njit(**LEAF)
def clutch_step(v, v0, P, J, dt):
    """Clutch impulse for one step, backward Euler in the slip speed linearised about the
    current slip (the locked clutch is very stiff); applied to v in place. Returns the
    dissipation [J]: the clutch torque times the mean of the start-of-step (v0) and
    end-of-step slips, the same speeds the kinetic energy and input work are taken on."""
    d = int(P[P_INPUT])
    s = v[d] - v[0]
    t0, k0 = clutch_law(s, P)
    mu = 1.0 / J[d] + 1.0 / J[0]
    s1 = s - dt * mu * t0 / (1.0 + dt * mu * k0)
    t = t0 + k0 * (s1 - s)
    v[d] -= dt * t / J[d]
    v[0] += dt * t / J[0]
    return dt * t * 0.5 * (v0[d] - v0[0] + v[d] - v[0])
