"""Torques on every DOF of the damper at a state, and its elastic energy.

Bodies J_pri, J_sec, J_ter ([thesis] Eq. 4-6) and the rig chain (Eq. 34-35); arc
springs as N massless segments between N-1 point masses (Eq. 14-15), free ends pushed
but never pulled by the stoppers (Eq. 16-18); radial force = centrifugal + redirection
+ preload (Eq. 19-24) as the normal force of each spring mass's friction; the hardstop
contacts' stiffness; the smooth optional effects; input torque and output motor.
:func:`forces` feeds the production step; :func:`rhs` is the explicit time derivative
(friction evaluated explicitly) for the reference comparison and the LSODA benchmark.
"""

import math

import numpy as np
from numba import njit

from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.contacts import hardstop_penetration
from dampersim.solver.kernels.effects import clutch_law, dead_zone, effect_energy, effect_forces, nested_radial_transfer
from dampersim.solver.kernels.fastmath import sin_poly
from dampersim.solver.kernels.friction import friction_torques
from dampersim.solver.kernels.springs import spring_nodes
from dampersim.solver.layout import (
    F_BLOCK,
    F_COUNT,
    F_KSEG,
    F_MASS,
    F_NW,
    F_PHISEG,
    F_PHIPS,
    F_PHISS,
    F_PITCH,
    F_PRELOAD,
    F_REFF,
    I_A,
    I_N,
    I_NODE,
    I_OFF,
    P_BL_HALF,
    P_CL_ON,
    P_HELD,
    P_HS_D,
    P_HS_K,
    P_HS_ON,
    P_INPUT,
    P_KI,
    P_KP,
    P_MOTOR,
    P_NRIG,
    P_NRT,
    P_OMEGA0,
    P_RIG0,
    P_TRANS,
    R_HS_I,
    R_HS_O,
    R_MOTOR_T,
    R_SET_I,
    R_SET_O,
    R_TIN,
    R_TOUT,
    R_W_MOTOR,
    R_W_PRI,
    R_W_SEC,
    R_W_TER,
    R_WIND_I,
    R_WIND_O,
    R_WIND_RIG,
)



@njit(**LEAF)
def forces(q, v, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, rec, flags, hs_damp, ST):
    """Torques on every DOF at state (q, v): conservative FC, dissipative FD, external FE
    (input and motor), and the normal force FN [N] on every spring mass (count springs).

    hs_damp: 1.0 puts the hardstop contact damping into FD (explicit right-hand side);
    0.0 leaves it out for the integrator, which applies it implicitly
    (:func:`.contacts.hardstop_coefficients`, solved in :func:`.friction.friction_step`).
    The recorded hardstop torque includes it either way.

    Fills ``rec`` (if its length is > 0) with the measured quantities of this state, and
    sets flags[0] to 1 if a segment is shorter than its block arc (coil stacking).
    ST: scratch of length 2 n_nodes (segment torques, redirection forces).
    Returns the elastic energy [J] if ``rec`` has a length, else 0.
    """
    ndof = q.shape[0]
    n_nodes = X.shape[0]
    om0 = P[P_OMEGA0]
    for i in range(ndof):
        FC[i] = 0.0
        FD[i] = 0.0
        FE[i] = 0.0
        FN[i] = 0.0
    flags[0] = 0.0
    energy = 0.0
    sb0 = 0.0  # spring torque the outer set passes to J_sec
    sb1 = 0.0  # spring torque the inner set passes to J_ter
    spring_nodes(q, P, SF, SI, X)
    for s in range(SF.shape[0]):
        a = SI[s, I_A]
        b = a + 1
        n = SI[s, I_N]
        off = SI[s, I_OFF]
        base = SI[s, I_NODE]
        kseg = SF[s, F_KSEG]
        phiseg = SF[s, F_PHISEG]
        count = SF[s, F_COUNT]
        reff = SF[s, F_REFF]
        nw = SF[s, F_NW]
        m = SF[s, F_MASS]
        pitch = SF[s, F_PITCH]
        w = q[a] - q[b]
        short = SF[s, F_BLOCK] * (1.0 - 1e-6)
        cfd = 2.0 * nw / reff  # Eq. 21: F = T / r_eff * 2 n_w sin(seg / (2 n_w))
        carg = 0.5 / nw
        # The loops below index views of this spring's nodes, segment torques (ST_t),
        # redirection forces (ST_r) and masses by the loop counter alone: numba then needs
        # no negative-index wraparound per access, which kept these loops scalar (the
        # views halved the cost of this function).
        # 1) torque T_j and redirection force of every segment (Eq. 21; only compression
        #    pushes outwards) into ST; written without branches so that it vectorises
        Xs = X[base:base + n + 1]
        ST_t = ST[base:base + n]
        ST_r = ST[n_nodes + base:n_nodes + base + n]
        nshort = 0
        nwide = 0
        for j in range(n):
            seg = Xs[j + 1] - Xs[j]
            t = kseg * (phiseg - seg)
            xs = seg * carg
            nshort += seg < short
            nwide += abs(xs) > 0.5
            ST_t[j] = t
            ST_r[j] = max(t, 0.0) * cfd * sin_poly(xs)
        if nshort > 0:
            flags[0] = 1.0
        if nwide > 0:  # a segment wider than sin_poly's range: exact sine (rare)
            for j in range(n):
                seg = Xs[j + 1] - Xs[j]
                ST_r[j] = max(ST_t[j], 0.0) * cfd * math.sin(seg * carg)
        if rec.shape[0] > 0:  # elastic energy, only where it is recorded
            for j in range(n):
                c = phiseg - (Xs[j + 1] - Xs[j])
                energy += 0.5 * count * kseg * c * c
        # 2) each mass j = 1 .. n-1 (DOF off + j - 1) between segments j-1 and j: theta
        #    torque T_j - T_{j-1} (Eq. 14); normal force = centrifugal + half of each
        #    neighbour's redirection force + preload (Eq. 19-24) ...
        cen = m * reff
        pre = SF[s, F_PRELOAD]
        FCm = FC[off:off + n - 1]
        FNm = FN[off:off + n - 1]
        vm = v[off:off + n - 1]
        for i in range(n - 1):  # mass j = i + 1
            FCm[i] += count * (ST_t[i + 1] - ST_t[i])
            om = om0 + vm[i]
            FNm[i] = count * (cen * om * om + 0.5 * (ST_r[i] + ST_r[i + 1]) + pre)
        # ... and the end segments' redirection goes fully to their one mass
        FN[off] += count * 0.5 * ST[n_nodes + base]
        FN[off + n - 2] += count * 0.5 * ST[n_nodes + base + n - 1]
        # 3) the end nodes are pushed (theta direction) onto the stopper they rest on
        t = ST[base]
        fa = SF[s, F_PHIPS]
        fb = w + SF[s, F_PHISS]
        tb = 0.0
        if fb > fa:
            tb = count * t
        elif fa > fb:
            FC[a] += count * t
        else:
            FC[a] += 0.5 * count * t
            tb = 0.5 * count * t
        FC[b] += tb
        if a == 0:
            sb0 += tb
        else:
            sb1 += tb
        t = ST[base + n - 1]
        fa = pitch - SF[s, F_PHIPS]
        fb = w + pitch - SF[s, F_PHISS]
        tb = 0.0
        if fb < fa:
            tb = count * t
        elif fa < fb:
            FC[a] -= count * t
        else:
            FC[a] -= 0.5 * count * t
            tb = 0.5 * count * t
        FC[b] -= tb
        if a == 0:
            sb0 -= tb
        else:
            sb1 -= tb
    if P[P_NRT] > 0.0:
        nested_radial_transfer(P, SI, FN)
    # hardstops: stiff, damped, one-sided contact on the windup of each set
    hs0 = 0.0
    hs1 = 0.0
    if P[P_HS_ON] > 0.0:
        k = P[P_HS_K]
        dmp = P[P_HS_D]
        for st in range(2):
            a = st
            b = st + 1
            dw = v[a] - v[b]
            pen = hardstop_penetration(q, P, st)
            if pen != 0.0:
                tk = k * pen
                tt = tk + dmp * dw
                if tt * pen < 0.0:  # never pulls
                    tt = 0.0
                energy += 0.5 * k * pen * pen
                FC[a] -= tk
                FC[b] += tk
                if hs_damp > 0.0:
                    FD[a] -= tt - tk
                    FD[b] += tt - tk
                if st == 0:
                    hs0 = tt
                else:
                    hs1 = tt
    energy += effect_forces(q, v, P, FC, FD)
    # rig chain (Eq. 34-35)
    nrig = int(P[P_NRIG])
    rig0 = int(P[P_RIG0])
    trans = int(P[P_TRANS])
    tout = 0.0
    for e in range(nrig):
        d = rig0 + e
        prev = 2 if e == 0 else d - 1
        dq = q[prev] - q[d]
        ds = RIG[e, 1] * (v[prev] - v[d])
        if e == 0 and P[P_BL_HALF] > 0.0:
            dq = dead_zone(dq, P[P_BL_HALF])
            if dq == 0.0:  # inside the free play: no shaft torque, no damping
                ds = 0.0
        ks = RIG[e, 0] * dq
        FC[prev] -= ks
        FC[d] += ks
        FD[prev] -= ds
        FD[d] += ds
        energy += 0.5 * RIG[e, 0] * dq * dq
        FD[d] -= RIG[e, 2] * (om0 + v[d])
        if d == trans:
            tout = ks + ds
    motor = int(P[P_MOTOR])
    FE[int(P[P_INPUT])] = tin
    tm = 0.0
    if P[P_HELD] > 0.0:
        tm = -(FC[motor] + FD[motor])
    else:
        tm = -P[P_KP] * v[motor] + P[P_KI] * z
    FE[motor] = tm
    if rec.shape[0] > 0:
        rec[R_TIN] = tin
        rec[R_TOUT] = tout
        rec[R_W_PRI] = om0 + v[0]
        rec[R_W_SEC] = om0 + v[1]
        rec[R_W_TER] = om0 + v[2]
        rec[R_W_MOTOR] = om0 + v[motor]
        rec[R_WIND_O] = q[0] - q[1]
        rec[R_WIND_I] = q[1] - q[2]
        rec[R_WIND_RIG] = q[int(P[P_INPUT])] - q[trans]
        rec[R_HS_O] = hs0
        rec[R_HS_I] = hs1
        rec[R_MOTOR_T] = tm
        rec[R_SET_O] = sb0
        rec[R_SET_I] = sb1
    return energy


@njit(**LEAF)
def elastic_energy(q, P, SF, SI, RIG, X):
    """Elastic energy [J] of springs (all count copies), hardstop contacts and rig shafts."""
    spring_nodes(q, P, SF, SI, X)
    e = 0.0
    for s in range(SF.shape[0]):
        n = SI[s, I_N]
        base = SI[s, I_NODE]
        for j in range(n):
            c = SF[s, F_PHISEG] - (X[base + j + 1] - X[base + j])
            e += 0.5 * SF[s, F_COUNT] * SF[s, F_KSEG] * c * c
    if P[P_HS_ON] > 0.0:
        for st in range(2):
            pen = hardstop_penetration(q, P, st)
            e += 0.5 * P[P_HS_K] * pen * pen
    rig0 = int(P[P_RIG0])
    for e_ in range(int(P[P_NRIG])):
        d = rig0 + e_
        prev = 2 if e_ == 0 else d - 1
        dq = q[prev] - q[d]
        if e_ == 0 and P[P_BL_HALF] > 0.0:
            dq = dead_zone(dq, P[P_BL_HALF])
        e += 0.5 * RIG[e_, 0] * dq * dq
    e += effect_energy(q, P)
    return e


@njit(**JIT)
def rhs(q, v, z, tin, P, SF, SI, J, RIG, CI, CF, n_nodes):
    """Time derivative of (q, v, z) with friction evaluated explicitly.

    Used by the reference comparison and by the scipy (LSODA) benchmark; the production
    integrator :func:`.integrate.integrate` uses the same forces with implicit friction.
    """
    ndof = q.shape[0]
    X = np.zeros(n_nodes)
    FC = np.zeros(ndof)
    FD = np.zeros(ndof)
    FE = np.zeros(ndof)
    FN = np.zeros(ndof)
    TF = np.zeros(CI.shape[0])
    rec = np.zeros(0)
    forces(q, v, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, rec, np.zeros(1), 1.0, np.zeros(2 * n_nodes))
    friction_torques(v, P, J, CI, CF, FN, TF)
    acc = np.zeros(ndof)
    for i in range(ndof):
        acc[i] = FC[i] + FD[i] + FE[i]
    for c in range(CI.shape[0]):
        acc[CI[c, 0]] -= TF[c]
        acc[CI[c, 1]] += TF[c]
    if P[P_CL_ON] > 0.0:
        d = int(P[P_INPUT])
        tc, _ = clutch_law(v[d] - v[0], P)
        acc[d] -= tc
        acc[0] += tc
    for i in range(ndof):
        acc[i] /= J[i]
    motor = int(P[P_MOTOR])
    if P[P_HELD] > 0.0:
        acc[motor] = 0.0
    return v.copy(), acc, -v[motor]
