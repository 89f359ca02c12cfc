"""Contacts between bodies and spring masses: hardstops and coil stacking.

- hardstops as a stiff, damped, one-sided contact on each set's windup (we differ from
  the thesis's inertia merge, [thesis] Eq. 30-33, see docs/model.md §6); the stiffness acts
  explicitly, the damping implicitly inside the friction solve
  (:func:`dampersim.solver.kernels.friction.friction_step`);
- coil stacking as a momentum-conserving contact (position projection + inelastic
  impulse) instead of the thesis's position clamp (Eq. 29), which breaks momentum.
"""

from numba import njit

from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.springs import spring_nodes
from dampersim.solver.layout import (
    F_BLOCK,
    F_PHIPS,
    F_PHISS,
    F_PITCH,
    I_A,
    I_N,
    I_NODE,
    I_OFF,
    P_HS_D,
    P_HS_K,
    P_HSN_I,
    P_HSN_O,
    P_HSP_I,
    P_HSP_O,
)



@njit(inline="always", **JIT)
def hardstop_penetration(q, P, st):
    """Windup of set ``st`` (0 outer, 1 inner) beyond its hardstop [rad]: positive past
    the positive stop, negative past the negative stop, 0 in between."""
    w = q[st] - q[st + 1]
    lim_p = P[P_HSP_O] if st == 0 else P[P_HSP_I]
    lim_n = P[P_HSN_O] if st == 0 else P[P_HSN_I]
    if w > lim_p:
        return w - lim_p
    if w < lim_n:
        return w - lim_n
    return 0.0


@njit(**LEAF)
def hardstop_coefficients(q, P, dt, HS):
    """Implicit hardstop contact coefficients for :func:`.friction.friction_step` into
    HS.

    The contact stiffness acts explicitly through FC (:func:`.forces.forces`, positions
    at the start of the step); what the implicit solve adds on the end-of-step windup speed w is
    c w with c = (damping + stiffness dt) (damping, plus the stiffness on the penetration
    the step adds), so a stiff, near-inelastic contact (restitution ~0, like the inertia
    merge of [thesis] Eq. 30-33) needs no step limit. Returns True if a contact is
    closed.
    """
    HS[0] = 0.0
    HS[1] = 0.0
    HS[2] = 0.0
    HS[3] = 0.0
    ce = P[P_HS_D] + P[P_HS_K] * dt
    closed = False
    if hardstop_penetration(q, P, 0) != 0.0:
        HS[0] = ce
        closed = True
    if hardstop_penetration(q, P, 1) != 0.0:
        HS[2] = ce
        closed = True
    return closed


@njit(**LEAF)
def hardstop_release(q, v, P, HS):
    """After a solve with closed hardstop contacts: a contact whose total torque
    k pen + c w would pull is opened instead (its implicit part cancels the stiffness
    torque, HS = (0, -k pen)). Returns True if HS changed (the step must be re-solved)."""
    k = P[P_HS_K]
    changed = False
    for st in range(2):
        c = HS[2 * st]
        if c != 0.0:
            pen = hardstop_penetration(q, P, st)
            t = c * (v[st] - v[st + 1]) + HS[2 * st + 1]
            if (k * pen + t) * pen < 0.0:
                HS[2 * st] = 0.0
                HS[2 * st + 1] = -k * pen
                changed = True
    return changed


@njit(**LEAF)
def hardstop_dissipation(dt, HS, v_before, v):
    """Energy [J] the hardstop contacts removed in the step: the torque of the implicit
    solve, c w_end with c = damping + k dt for a closed contact (or the cancelling torque
    of an opened one), times the mid-step windup speed, which is the kinetic energy it
    takes out. The elastic energy records only the contact's explicit stiffness torque
    on the start-of-step penetration; the k dt share acts on the step's added
    penetration and is dissipated, so it is booked here with the damping. Measured at
    1500 rpm, 320 +- 300 N m (the contact closes every cycle) at the default step: with
    only the damping share booked the balance missed 5.2 J of 307 J friction and contact
    dissipation; with the whole implicit torque 0.18 J (tests/physics/test_energy.py,
    case 'across the knee')."""
    e = 0.0
    for st in range(2):
        c = HS[2 * st]
        w1 = v[st] - v[st + 1]
        w0 = v_before[st] - v_before[st + 1]
        t = c * w1 if c != 0.0 else HS[2 * st + 1]
        e += dt * t * 0.5 * (w0 + w1)
    return e


@njit(**LEAF)
def _stack_pair(q, v, J, da, db, delta, stats):
    """Separate two masses (x_b - x_a must grow by delta; x = q_A - q) keeping their
    momentum, and remove their approach speed with an inelastic impulse."""
    ja = J[da]
    jb = J[db]
    tot = ja + jb
    # x_a down by delta*jb/tot -> q_a up; x_b up by delta*ja/tot -> q_b down
    q[da] += delta * jb / tot
    q[db] -= delta * ja / tot
    # approach in x: d/dt(x_b - x_a) = v_a - v_b < 0  <=>  v_b > v_a
    if v[db] > v[da]:
        vm = (ja * v[da] + jb * v[db]) / tot
        ke0 = 0.5 * ja * v[da] ** 2 + 0.5 * jb * v[db] ** 2
        v[da] = vm
        v[db] = vm
        stats[0] += ke0 - 0.5 * tot * vm * vm


@njit(**LEAF)
def stacking(q, v, P, SF, SI, J, X, stats):
    """Coil-stacking contact ([thesis] Eq. 29, made momentum-conserving): no segment may
    be shorter than its block arc. Gauss-Seidel sweeps over the segments until no
    segment is short by more than 1e-6 of its block arc (at most 4 N sweeps).

    stats[0] accumulates kinetic energy removed by impulses [J].
    """
    for s in range(SF.shape[0]):
        a = SI[s, I_A]
        b = a + 1
        n = SI[s, I_N]
        off = SI[s, I_OFF]
        base = SI[s, I_NODE]
        block = SF[s, F_BLOCK]
        tol = 1e-6 * block
        for sweep in range(4 * n):
            moved = False
            spring_nodes(q, P, SF, SI, X)
            # end segment 0: node 0 rests on a stopper (or is free, then it is relaxed)
            seg = X[base + 1] - X[base]
            if seg < block - tol:
                fa = SF[s, F_PHIPS]
                fb = q[a] - q[b] + SF[s, F_PHISS]
                body = b if fb >= fa else a
                _stack_pair(q, v, J, body, off, block - seg, stats)
                moved = True
            for j in range(1, n - 1):
                seg = q[off + j - 1] - q[off + j]
                if seg < block - tol:
                    _stack_pair(q, v, J, off + j - 1, off + j, block - seg, stats)
                    moved = True
            spring_nodes(q, P, SF, SI, X)
            seg = X[base + n] - X[base + n - 1]
            if seg < block - tol:
                fa = SF[s, F_PITCH] - SF[s, F_PHIPS]
                fb = q[a] - q[b] + SF[s, F_PITCH] - SF[s, F_PHISS]
                body = b if fb <= fa else a
                _stack_pair(q, v, J, off + n - 2, body, block - seg, stats)
                moved = True
            if not moved:
                break
