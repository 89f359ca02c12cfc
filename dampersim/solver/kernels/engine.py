"""The pulsation generator (motored engine) chain: [thesis] chapter 4, docs/model.md §8.

One step of the chain is :func:`engine_step`; :func:`engine_integrate` marches it alone
on a stiff propshaft, :func:`dampersim.solver.kernels.integrate.integrate` marches it
coupled to the full damper. Array layouts in :mod:`dampersim.solver.engine_layout`.
"""

import math

import numpy as np
from numba import njit

from dampersim.solver.engine_layout import (
    E_AREA,
    E_BEAR,
    E_BLINK,
    E_DDYNO,
    E_DT,
    E_GAMMA,
    E_KI,
    E_KLINK,
    E_L,
    E_MREC,
    E_OMEGA0,
    E_PATM,
    E_PC,
    E_R,
    E_RBACK,
    E_RMU,
    E_RTENS,
    E_RVISC,
    E_VBDC,
    E_VC,
    E_VMAX,
    E_VREF,
    EO_P1,
    EO_PMAX,
    EO_SIZE,
    EO_TDYNO,
    EO_TFRIC,
    EO_TGAS,
    EO_THETA1,
    EO_TINER,
    EO_W_TRANS,
    ER_P1,
    ER_PMAX,
    ER_T,
    ER_TDYNO,
    ER_TFRIC,
    ER_TGAS,
    ER_THETA1,
    ER_TINER,
    ER_TLINK,
    ER_TOUT,
    ER_W_TRANS,
)
from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.fastmath import fast_tanh



@njit(inline="always", **JIT)
def crank_slider(th, r, L):
    """Piston displacement from TDC s(theta) [m] and its first two crank-angle
    derivatives ([thesis] Eq. 2 geometry, no pin offset)."""
    sn = math.sin(th)
    cs = math.cos(th)
    root = math.sqrt(L * L - r * r * sn * sn)
    s = r * (1.0 - cs) + L - root
    ds = r * sn + r * r * sn * cs / root
    dds = r * cs + r * r * (cs * cs - sn * sn) / root + (r * r * sn * cs) ** 2 / (root * root * root)
    return s, ds, dds


@njit(inline="always", **JIT)
def cylinder_pressure(s, PE):
    """Polytropic air-spring pressure P = P_c (V_BDC / V)^gamma [Pa] (docs/model.md §8: the
    physical form; the thesis's Eq. 1 and 3 are misprinted)."""
    vol = PE[E_VC] + PE[E_AREA] * s
    return PE[E_PC] * (PE[E_VBDC] / vol) ** PE[E_GAMMA]


@njit(**LEAF)
def engine_cylinder_torques(th, om, PE, gas_scale):
    """(gas, inertia-velocity, friction torque [N m], effective extra inertia [kg m^2],
    pressure [Pa]) of one cylinder at crank angle th [rad] and speed om [rad/s]."""
    s, ds, dds = crank_slider(th, PE[E_R], PE[E_L])
    p = cylinder_pressure(s, PE)
    pg = gas_scale * (p - PE[E_PATM])
    t_gas = pg * PE[E_AREA] * ds
    m = PE[E_MREC]
    t_in = -m * ds * dds * om * om
    vp = ds * om
    f_ring = PE[E_RVISC] * vp + PE[E_RMU] * (PE[E_RTENS] + max(pg, 0.0) * PE[E_RBACK]) * fast_tanh(vp / PE[E_VREF])
    t_fr = -f_ring * ds - PE[E_BEAR] * om
    return t_gas, t_in, t_fr, m * ds * ds, PE[E_PATM] + pg


@njit(**LEAF)
def engine_step(q, v, t, setpoint, gas_scale, z, qd, vd, PE, CH, CYL, F, extra, OUT):
    """Advance the pulsation generator chain one step of PE[E_DT] (symplectic Euler)
    from time t [s]; returns the torque [N m] of the shaft leaving the transducer.

    Chain DOFs (CH rows [J, B_j, K to previous, B_k to previous]): input dyno, coupling,
    crank sections (CYL rows [dof, phase offset rad]), flange, transducer. Each crank
    section carries one cylinder: gas torque, reciprocating inertia (effective inertia
    J + m s'^2 and velocity term -m s' s'' omega^2) and ring + bearing friction. The
    input dyno applies setpoint [N m] + PE[E_KI] z (z: integral of the set point minus
    the link torque [N m s], kept by the caller) - PE[E_DDYNO] v_dyno.

    The link shaft (PE[E_KLINK], PE[E_BLINK]) runs from the transducer to a body at
    angle qd [rad] and speed vd [rad/s] (both relative to the nominal-speed frame): the
    held output dyno of the stiff-shaft test (qd = vd = 0) or the damper's input DOF.
    The torque is taken at the start of the step, so the caller applies the same value
    to that body. gas_scale: factor on the gas pressure above atmosphere [-] (start-up
    ramp). F, extra: scratch of the chain's length; OUT: scratch of EO_SIZE receiving the
    channels of the start-of-step state (EO_*).
    """
    n = q.shape[0]
    dt = PE[E_DT]
    om0 = PE[E_OMEGA0]
    last = n - 1
    for i in range(n):
        F[i] = -CH[i, 1] * (om0 + v[i])
        extra[i] = 0.0
    for i in range(1, n):
        ts = CH[i, 2] * (q[i - 1] - q[i]) + CH[i, 3] * (v[i - 1] - v[i])
        F[i - 1] -= ts
        F[i] += ts
    tg = 0.0
    ti = 0.0
    tf = 0.0
    p1 = 0.0
    pmax = 0.0
    for c in range(CYL.shape[0]):
        d = int(CYL[c, 0])
        th = om0 * t + q[d] + CYL[c, 1]
        om = om0 + v[d]
        a, b, fr, jx, p = engine_cylinder_torques(th, om, PE, gas_scale)
        F[d] += a + b + fr
        extra[d] += jx
        tg += a
        ti += b
        tf += fr
        if c == 0:
            p1 = p
        if p > pmax:
            pmax = p
    tl = PE[E_KLINK] * (q[last] - qd) + PE[E_BLINK] * (v[last] - vd)
    F[last] -= tl
    tdyno = setpoint + PE[E_KI] * z - PE[E_DDYNO] * v[0]
    F[0] += tdyno
    OUT[EO_TDYNO] = tdyno
    OUT[EO_W_TRANS] = om0 + v[last]
    OUT[EO_THETA1] = om0 * t + q[int(CYL[0, 0])] + CYL[0, 1]
    OUT[EO_P1] = p1
    OUT[EO_TGAS] = tg
    OUT[EO_TINER] = ti
    OUT[EO_TFRIC] = tf
    OUT[EO_PMAX] = pmax
    for i in range(n):
        v[i] += dt * F[i] / (CH[i, 0] + extra[i])
    for i in range(n):
        q[i] += dt * v[i]
    return tl


@njit(inline="always", **JIT)
def engine_record(rec, irec, t, tl, tout, pmax, OUT):
    """Row ``irec`` of the generator record (columns ER_*)."""
    rec[irec, ER_T] = t
    rec[irec, ER_TLINK] = tl
    rec[irec, ER_TDYNO] = OUT[EO_TDYNO]
    rec[irec, ER_W_TRANS] = OUT[EO_W_TRANS]
    rec[irec, ER_THETA1] = OUT[EO_THETA1]
    rec[irec, ER_P1] = OUT[EO_P1]
    rec[irec, ER_TGAS] = OUT[EO_TGAS]
    rec[irec, ER_TINER] = OUT[EO_TINER]
    rec[irec, ER_TFRIC] = OUT[EO_TFRIC]
    rec[irec, ER_TOUT] = tout
    rec[irec, ER_PMAX] = pmax


@njit(inline="always", **JIT)
def engine_diverged(v, PE):
    """0 if the chain's speeds are finite and below PE[E_VMAX], else 1 (NaN) or 2 (runaway)."""
    for i in range(v.shape[0]):
        if not (v[i] == v[i]):
            return 1
        if abs(v[i]) > PE[E_VMAX]:
            return 2
    return 0


@njit(**JIT)
def engine_integrate(q, v, setpoint, gas_scale, PE, CH, CYL, rec_every, rec):
    """March the pulsation generator alone ``len(setpoint)`` steps: the transducer drives
    a torsionally stiff propshaft to a held output dyno (PE[E_KLINK], PE[E_BLINK]),
    the "pulsation generator only" tests of [thesis] §4.3.1. Coupled to the damper the
    chain is marched by :func:`.integrate.integrate` instead.

    setpoint[n]: mean torque set point [N m], gas_scale[n]: gas ramp [-] at t = n dt; the
    input dyno adds integral control of the measured output torque (the rig controlled
    the mean on the generator's output, [thesis] §4.3.1). Every ``rec_every`` steps a row
    of ``rec`` (columns ER_*) is written. Returns (status, step): 0 ok, 1 NaN, 2 runaway
    speed.
    """
    n = q.shape[0]
    nsteps = setpoint.shape[0]
    dt = PE[E_DT]
    F = np.zeros(n)
    extra = np.zeros(n)
    OUT = np.zeros(EO_SIZE)
    z = 0.0
    irec = 0
    pmax = 0.0
    for step in range(nsteps):
        t = step * dt
        tl = engine_step(q, v, t, setpoint[step], gas_scale[step], z, 0.0, 0.0, PE, CH, CYL, F, extra, OUT)
        if OUT[EO_PMAX] > pmax:
            pmax = OUT[EO_PMAX]
        if step % rec_every == 0 and irec < rec.shape[0]:
            engine_record(rec, irec, t, tl, tl, pmax, OUT)
            pmax = 0.0
            irec += 1
        z += dt * (setpoint[step] - tl)
        if step % 256 == 0:
            st = engine_diverged(v, PE)
            if st != 0:
                return st, step
    return 0, nsteps
