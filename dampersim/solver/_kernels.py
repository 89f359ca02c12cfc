"""All hot code of dampersim: numba kernels on flat float64/int64 arrays.

Equations ([thesis] chapter 5, as corrected in model-spec §2-6):

- bodies J_pri, J_sec, J_ter ([thesis] Eq. 4-6) and the rig chain (Eq. 34-35);
- arc springs as N massless segments between N-1 point masses (Eq. 14-15), free ends
  pushed but never pulled by the stoppers (Eq. 16-18);
- radial force = centrifugal + redirection + preload (Eq. 19-24) and Makkar friction
  (Eq. 27-28) against the housing or, for the inner spring of a nested pair, against
  the outer spring's mass (Eq. 25-26);
- hardstops as a stiff, damped, one-sided contact (we differ from the thesis's inertia
  merge, Eq. 30-33, see model-spec §6);
- coil stacking as a momentum-conserving contact (position projection + inelastic
  impulse) instead of the thesis's position clamp (Eq. 29), which breaks momentum.

Integrator: symplectic (semi-implicit) Euler for the smooth forces, and a linearly
implicit (Rosenbrock-type) update of each friction contact in turn, so the stiff
friction slope at small slip speed (about 38 per m/s) needs no tiny step.
Array layouts are defined in :mod:`dampersim.solver.layout`.

The pulsation generator's chain ([thesis] chapter 4, model-spec §8; end of this module)
is stepped by :func:`engine_step`: alone on a stiff propshaft by
:func:`engine_integrate`, or as the torque source of the damper inside
:func:`integrate` (the rig mode of [thesis] §4.2), where its transducer shaft drives the
damper's input DOF with the same step.
"""

import math

import numpy as np
from numba import njit

from dampersim.solver.layout import (
    F_BLOCK,
    F_COUNT,
    F_KSEG,
    F_MASS,
    F_NW,
    F_PHIPS,
    F_PHISEG,
    F_PHISS,
    F_PITCH,
    F_PRELOAD,
    F_REFF,
    I_A,
    I_N,
    I_NODE,
    I_OFF,
    P_DT,
    P_G1,
    P_G2,
    P_G3,
    P_G4,
    P_G5,
    P_G6,
    P_HELD,
    P_HS_D,
    P_HS_K,
    P_HS_ON,
    P_HSN_I,
    P_HSN_O,
    P_HSP_I,
    P_HSP_O,
    P_KI,
    P_KP,
    P_NRIG,
    P_OMEGA0,
    P_RIG0,
    P_TRANS,
    P_VMAX,
)
from dampersim.solver.layout import (  # optional effects (dampersim.discrepancy.effects)
    P_BL_HALF,
    P_CL_CAP,
    P_CL_ON,
    P_CL_VISC,
    P_CL_WS,
    P_INPUT,
    P_MOTOR,
    P_NRT,
    P_PA_C,
    P_PA_DOF,
    P_PA_K,
    P_SS_GAP,
    P_SS_K,
    P_TD_C,
)

# record columns (one row per stored sample)
R_T = 0
R_TIN = 1
R_TOUT = 2
R_W_PRI = 3  # absolute speeds [rad/s]
R_W_SEC = 4
R_W_TER = 5
R_W_MOTOR = 6
R_WIND_O = 7  # windup of the outer set [rad]
R_WIND_I = 8  # windup of the inner set [rad]
R_WIND_RIG = 9  # J_pri angle - output transducer angle [rad]
R_HS_O = 10  # hardstop torque of the outer set [N m] (+ positive stop, - negative stop)
R_HS_I = 11
R_MOTOR_T = 12  # output motor torque [N m]
R_E_IN = 13  # work of the input torque [J]
R_E_MOTOR = 14  # work of the output motor [J]
R_E_KIN = 15  # kinetic energy [J]
R_E_SPRING = 16  # elastic energy (springs, shafts, hardstops) [J]
R_E_FRIC = 17  # friction dissipation [J]
R_E_DAMP = 18  # viscous dissipation (shafts, inertia damping, hardstop damping) [J]
R_E_STACK = 19  # energy removed by coil-stacking contacts [J]
R_SET_O = 20  # torque the outer set's springs pass to J_sec [N m]
R_SET_I = 21  # torque the inner set's springs pass to J_ter [N m]
NREC = 22
THETA = 0.5

# Compile options of every kernel: Python's division-by-zero checks are off (a check per
# division blocks SIMD code; a non-finite state is caught by the divergence check).
# Floating-point options: multiply-adds may fuse, sums may be reassociated (reductions
# over DOFs and contacts become SIMD code), the sign of a zero is not kept and a division
# may become a multiplication by the reciprocal. Each changes results only at rounding
# level; no NaN/inf assumption is made, so the divergence check still sees NaN. Measured
# 7 % off the step time against contraction alone (interleaved A/B runs in one process).
# The polynomial friction law keeps its accuracy under these options
# (tests/unit/test_friction_law.py).
JIT = dict(cache=True, error_model="numpy", fastmath={"contract", "reassoc", "nsz", "arcp"})
# Kernels that allocate nothing are compiled without numba's reference counting: the
# hot loop calls them every step, and each call would otherwise pay atomic
# increments and decrements on every array argument.
LEAF = dict(JIT, _nrt=False)


# Taylor coefficients 1/k! of expm1, k = 1..12
_C2, _C3, _C4, _C5, _C6, _C7 = 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040
_C8, _C9, _C10, _C11, _C12 = 1.0 / 40320, 1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600


@njit(inline="always", **JIT)
def expm1_neg(y):
    """exp(-y) - 1 for y >= 0, accurate to a few ulp relative, branch-free.

    y is clamped at 40 (exp(-40) is below float64's resolution next to 1), scaled by
    2^-7 into [0, 0.3125], where a degree-12 Taylor polynomial has truncation error
    < 2e-16 relative; seven doublings e^(2h) - 1 = u (2 + u) bring it back. A doubling
    never amplifies the relative error for u in (-1, 0], and no step cancels, so the
    result stays accurate near y = 0 (unlike 1 - exp(-y)). Only multiplications and
    additions: loops over many contacts vectorise (libm's exp is an opaque call)."""
    h = -min(y, 40.0) * (1.0 / 128.0)
    u = h * (1.0 + h * (_C2 + h * (_C3 + h * (_C4 + h * (_C5 + h * (_C6 + h * (_C7 + h * (
        _C8 + h * (_C9 + h * (_C10 + h * (_C11 + h * _C12)))))))))))
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    u = u * (2.0 + u)
    return u


@njit(inline="always", **JIT)
def fast_tanh(x):
    """tanh(x) = -u / (2 + u) with u = expm1(-2|x|): relative error of a few ulp for
    every x (no cancellation near 0), exactly +-1 where tanh rounds to +-1."""
    u = expm1_neg(2.0 * abs(x))
    return math.copysign(-u / (2.0 + u), x)


@njit(inline="always", **JIT)
def sin_poly(x):
    """sin(x) for |x| <= 0.5 (error < 1e-12 relative) as a short odd polynomial, without
    branches; callers check the range. The redirection angle of a segment per coil is a
    few hundredths of a radian."""
    x2 = x * x
    # Taylor series in nested form, divisions by constants written as products
    return x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0) * (
        1.0 - x2 * (1.0 / 72.0) * (1.0 - x2 * (1.0 / 110.0))))))


@njit(inline="always", **JIT)
def makkar_fast(v, g1, g2, g3, g4, g6):
    """:func:`makkar` for the thesis's coefficient pattern gamma2 = gamma5 = 10 gamma3:
    all three tanh terms from one expm1, u = exp(-2 gamma3 |v|) - 1, with
    exp(-20 gamma3 |v|) - 1 = (1 + u)^10 - 1 built from products (relative accuracy
    kept). Branch-free."""
    xb = g3 * v
    ub = expm1_neg(2.0 * abs(xb))
    u2 = ub * (2.0 + ub)
    u4 = u2 * (2.0 + u2)
    u5 = u4 + ub + u4 * ub
    u10 = u5 * (2.0 + u5)
    # tanh(|xb|) = -ub / (2 + ub), tanh(10 |xb|) = -u10 / (2 + u10): one division
    r = 1.0 / ((2.0 + ub) * (2.0 + u10))
    b = math.copysign(-ub * (2.0 + u10) * r, xb)
    a = math.copysign(-u10 * (2.0 + ub) * r, xb)
    mu = g1 * (a - b) + g4 * a + g6 * v
    dmu = g1 * (g2 * (1.0 - a * a) - g3 * (1.0 - b * b)) + g4 * g2 * (1.0 - a * a) + g6
    return mu, dmu


@njit(inline="always", **JIT)
def makkar(v, g1, g2, g3, g4, g5, g6):
    """Friction coefficient and its slope d(mu)/dv at slip speed v [m/s] ([thesis] Eq. 27):
    mu = g1 (tanh(g2 v) - tanh(g3 v)) + g4 tanh(g5 v) + g6 v."""
    if g2 == 10.0 * g3 and g5 == g2:
        return makkar_fast(v, g1, g2, g3, g4, g6)
    return makkar_general(v, g1, g2, g3, g4, g5, g6)


@njit(inline="always", **JIT)
def makkar_general(v, g1, g2, g3, g4, g5, g6):
    """:func:`makkar` for any coefficients: three tanh terms."""
    a = fast_tanh(g2 * v)
    b = fast_tanh(g3 * v)
    c = fast_tanh(g5 * v)
    mu = g1 * (a - b) + g4 * c + g6 * v
    dmu = g1 * (g2 * (1.0 - a * a) - g3 * (1.0 - b * b)) + g4 * g5 * (1.0 - c * c) + g6
    return mu, dmu


@njit(**LEAF)
def spring_nodes(q, P, SF, SI, X):
    """Slot coordinates of every node of every spring into X (Eq. 16-18)."""
    for s in range(SF.shape[0]):
        a = SI[s, I_A]
        n = SI[s, I_N]
        off = SI[s, I_OFF]
        base = SI[s, I_NODE]
        w = q[a] - q[a + 1]
        phiseg = SF[s, F_PHISEG]
        pitch = SF[s, F_PITCH]
        qa = q[a]
        Xs = X[base:base + n + 1]  # views offset by the counter only (see forces)
        qm = q[off:off + n - 1]
        for i in range(n - 1):
            Xs[i + 1] = qa - qm[i]
        x0 = SF[s, F_PHIPS]
        xb = w + SF[s, F_PHISS]
        if xb > x0:
            x0 = xb
        xf = X[base + 1] - phiseg
        if xf > x0:
            x0 = xf
        X[base] = x0
        xn = pitch - SF[s, F_PHIPS]
        xb = w + pitch - SF[s, F_PHISS]
        if xb < xn:
            xn = xb
        xf = X[base + n - 1] + phiseg
        if xf < xn:
            xn = xf
        X[base + n] = xn


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
def forces(q, v, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, rec, flags, hs_damp, ST):
    """Torques on every DOF at state (q, v): conservative FC, dissipative FD, external FE
    (input and motor), and the normal force FN [N] on every spring mass (count springs).

    hs_damp: 1.0 puts the hardstop contact damping into FD (explicit right-hand side);
    0.0 leaves it out for the integrator, which applies it implicitly
    (:func:`hardstop_coefficients`, solved in :func:`friction_step`). The recorded
    hardstop torque includes it either way.

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
def friction_torques(v, P, J, CI, CF, FN, TF):
    """Explicit friction torque of each contact at speeds v (for the RHS and reference):
    TF[c] > 0 brakes the mass CI[c,0] and drives the housing CI[c,1] (Eq. 28)."""
    g1, g2, g3, g4, g5, g6 = P[P_G1], P[P_G2], P[P_G3], P[P_G4], P[P_G5], P[P_G6]
    for c in range(CI.shape[0]):
        a = CI[c, 0]
        b = CI[c, 1]
        r = CF[c, 1]
        mu, dmu = makkar((v[a] - v[b]) * r, g1, g2, g3, g4, g5, g6)
        TF[c] = CF[c, 0] * FN[a] * r * mu


@njit(inline="always", **JIT)
def _linear_law(c, mu, dmu, v, v0, FN, CI, CF, W):
    """Linearised friction torque of contact c into W: T = W[2c] + W[2c+1] * s, with s the
    end-of-step slip [rad/s]. The law (mu, dmu) is taken at the start-of-step slip s0 and
    applied at the step's midpoint slip (s0 + s)/2 (second order, A-stable); a negative
    slope (Stribeck branch) is applied explicitly at the current slip."""
    a = np.uintp(CI[c, 0])  # unsigned: no negative-index wraparound (see forces)
    b = np.uintp(CI[c, 1])
    r = CF[c, 1]
    cn = CF[c, 0] * FN[a] * r
    s0 = v0[a] - v0[b]
    ss = v[a] - v[b]
    qc = THETA * cn * dmu * r
    qi = max(qc, 0.0)
    W[2 * c] = cn * mu - qi * s0 + (qc - qi) * (ss - s0)
    W[2 * c + 1] = qi


@njit(**LEAF)
def contact_laws(v, v0, FN, P, CI, CF, W, XS, MU, DMU):
    """Linearised friction law of every contact into W[0 : 2 n_contacts] (see
    :func:`_linear_law`).

    XS, MU, DMU: scratch of n_contacts rounded up to a multiple of 8 (an AVX-512 register)
    for the slips [m/s], friction coefficients and slopes. The coefficients are computed
    in one loop over these contiguous arrays, free of calls and branches, which the
    compiler turns into SIMD code; the padding spares it a scalar remainder loop."""
    g1, g2, g3, g4, g5, g6 = P[P_G1], P[P_G2], P[P_G3], P[P_G4], P[P_G5], P[P_G6]
    nc = CI.shape[0]
    for c in range(nc):
        XS[c] = (v0[np.uintp(CI[c, 0])] - v0[np.uintp(CI[c, 1])]) * CF[c, 1]
    if g2 == 10.0 * g3 and g5 == g2:
        for c in range(XS.shape[0]):
            mu, dmu = makkar_fast(XS[c], g1, g2, g3, g4, g6)
            MU[c] = mu
            DMU[c] = dmu
    else:
        for c in range(XS.shape[0]):
            mu, dmu = makkar_general(XS[c], g1, g2, g3, g4, g5, g6)
            MU[c] = mu
            DMU[c] = dmu
    for c in range(nc):
        _linear_law(c, MU[c], DMU[c], v, v0, FN, CI, CF, W)


@njit(**LEAF)
def friction_step(v, v0, J, CI, SG, PG, dt, W, HS):
    """Friction impulses for one step, applied to v in place; returns dissipation [J].

    The linearised friction of every contact is solved implicitly together with the two
    housing bodies it loads (J_sec, J_ter): each spring mass (each nested pair's two
    masses together) is eliminated in terms of the housings' end-of-step speeds, the
    housings' 2x2 system is solved, and the masses are recovered (Eq. 25-28). Solving
    the housings with the masses, rather than after them, removes an ordering bias
    that grows with the springs' share of the housings' inertia. The dissipation is the
    work of the friction torques on the end-of-step slips, the speeds that move the
    positions; measured so, the energy balance closes. W: scratch of length
    2 n_contacts + 2 n_singles + 6 n_pairs whose first 2 n_contacts entries hold the
    step's linearised contact laws (:func:`contact_laws`, computed once per step; a
    re-solve after a hardstop release reuses them).

    HS = (c0, f0, c1, f1) couples the hardstop contacts into the same solve: contact 0
    (outer set, J_pri-J_sec) and 1 (inner set, J_sec-J_ter) pass the torque
    c (w_end) + f, with w_end the end-of-step windup speed of the set; c = 0 and f = 0
    when the contact is open (see :func:`hardstop_coefficients`). Solving them together
    with friction keeps J_pri's inertia on J_sec while the outer hardstop is closed.
    v[0] changes only when contact 0 is closed.
    """
    nc = CI.shape[0]
    ns = SG.shape[0]
    ws = 2 * nc  # per single: alpha, beta (v_m = alpha + beta v_b)
    wp = ws + 2 * ns  # per pair: vo = o0 + o1 v1 + o2 v2, vi = i0 + i1 v1 + i2 v2
    # views indexed from 0 by loop counters, and DOF indices cast to unsigned: numba
    # then emits no negative-index wraparound per access (see forces)
    WS = W[ws:wp]
    WP = W[wp:wp + 6 * PG.shape[0]]
    # housing system A [v1; v2] = R for J_sec (1) and J_ter (2)
    invdt = 1.0 / dt
    a11 = J[1] * invdt
    a22 = J[2] * invdt
    a12 = 0.0
    a21 = 0.0
    r1 = a11 * v[1]
    r2 = a22 * v[2]
    for k in range(ns):
        m = np.uintp(SG[k, 0])
        c = SG[k, 1]
        b = CI[np.uintp(c), 1]
        p = W[np.uintp(2 * c)]
        q = W[np.uintp(2 * c + 1)]
        jm = J[m] * invdt
        inv = 1.0 / (jm + q)
        al = (jm * v[m] - p) * inv
        be = q * inv
        WS[2 * k] = al
        WS[2 * k + 1] = be
        # torque on the housing: p + q (alpha - (1 - beta) v_b)
        if b == 1:
            a11 += q * (1.0 - be)
            r1 += p + q * al
        else:
            a22 += q * (1.0 - be)
            r2 += p + q * al
    for k in range(PG.shape[0]):
        mo = np.uintp(PG[k, 0])
        mi = PG[k, 1]
        c1 = PG[k, 2]
        c2 = PG[k, 3]
        c3 = PG[k, 4]
        p1 = q1 = p2 = q2 = p3 = q3 = 0.0
        if c1 >= 0:
            p1 = W[np.uintp(2 * c1)]
            q1 = W[np.uintp(2 * c1 + 1)]
        if c2 >= 0:
            p2 = W[np.uintp(2 * c2)]
            q2 = W[np.uintp(2 * c2 + 1)]
        if c3 >= 0:
            p3 = W[np.uintp(2 * c3)]
            q3 = W[np.uintp(2 * c3 + 1)]
        jo = J[mo] * invdt
        b11 = jo + q1 + q2 + q3
        r0 = jo * v[mo] - p1 - p2 + p3
        if mi >= 0:
            ji = J[np.uintp(mi)] * invdt
            b22 = ji + q3
            ri = ji * v[np.uintp(mi)] - p3
            idet = 1.0 / (b11 * b22 - q3 * q3)
            o0 = (b22 * r0 + q3 * ri) * idet
            o1 = b22 * q1 * idet
            o2 = b22 * q2 * idet
            i0 = (q3 * r0 + b11 * ri) * idet
            i1 = q3 * q1 * idet
            i2 = q3 * q2 * idet
        else:
            ib = 1.0 / b11
            o0 = r0 * ib
            o1 = q1 * ib
            o2 = q2 * ib
            i0 = i1 = i2 = 0.0
        base = 6 * k
        WP[base] = o0
        WP[base + 1] = o1
        WP[base + 2] = o2
        WP[base + 3] = i0
        WP[base + 4] = i1
        WP[base + 5] = i2
        # t1 = p1 + q1 (vo - v1) acts on J_sec, t2 = p2 + q2 (vo - v2) on J_ter
        a11 += q1 * (1.0 - o1)
        a12 -= q1 * o2
        r1 += p1 + q1 * o0
        a21 -= q2 * o1
        a22 += q2 * (1.0 - o2)
        r2 += p2 + q2 * o0
    # hardstop contacts: inner couples J_sec and J_ter, outer brings in J_pri (eliminated)
    c0 = HS[0]
    f0 = HS[1]
    c1 = HS[2]
    f1 = HS[3]
    a11 += c1
    a12 -= c1
    a21 -= c1
    a22 += c1
    r1 -= f1
    r2 += f1
    j0 = J[0] * invdt
    if c0 != 0.0 or f0 != 0.0:
        a11 += c0 - c0 * c0 / (j0 + c0)
        r1 += f0 + c0 * (j0 * v[0] - f0) / (j0 + c0)
    idet = 1.0 / (a11 * a22 - a12 * a21)
    u1 = (r1 * a22 - a12 * r2) * idet
    u2 = (a11 * r2 - a21 * r1) * idet
    if c0 != 0.0 or f0 != 0.0:
        v[0] = (j0 * v[0] - f0 + c0 * u1) / (j0 + c0)
    v[1] = u1
    v[2] = u2
    for k in range(ns):
        m = np.uintp(SG[k, 0])
        b = np.uintp(CI[np.uintp(SG[k, 1]), 1])
        v[m] = WS[2 * k] + WS[2 * k + 1] * v[b]
    for k in range(PG.shape[0]):
        base = 6 * k
        v[np.uintp(PG[k, 0])] = WP[base] + WP[base + 1] * u1 + WP[base + 2] * u2
        if PG[k, 1] >= 0:
            v[np.uintp(PG[k, 1])] = WP[base + 3] + WP[base + 4] * u1 + WP[base + 5] * u2
    diss = 0.0
    for c in range(nc):
        s = v[np.uintp(CI[c, 0])] - v[np.uintp(CI[c, 1])]
        diss += dt * (W[2 * c] + W[2 * c + 1] * s) * s
    return diss


@njit(**LEAF)
def hardstop_coefficients(q, P, dt, HS):
    """Implicit hardstop contact coefficients for :func:`friction_step` into HS.

    The contact stiffness acts explicitly through FC (:func:`forces`, positions at the
    start of the step); what the implicit solve adds on the end-of-step windup speed w is
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
def hardstop_dissipation(P, dt, HS, v_before, v):
    """Energy [J] the hardstop contacts' damping share removed in the step: the damping
    torque (c - k dt) w_end (or the cancelling torque of an opened contact) times the
    mid-step windup speed, which is what the kinetic energy loses to it. The k dt share
    is stiffness acting on the step's added penetration, booked by the elastic energy."""
    cd = P[P_HS_D]
    e = 0.0
    for st in range(2):
        c = HS[2 * st]
        w1 = v[st] - v[st + 1]
        w0 = v_before[st] - v_before[st + 1]
        if c != 0.0:
            t = cd * w1
        else:
            t = HS[2 * st + 1]
        e += dt * t * 0.5 * (w0 + w1)
    return e


@njit(**JIT)
def rhs(q, v, z, tin, P, SF, SI, J, RIG, CI, CF, n_nodes):
    """Time derivative of (q, v, z) with friction evaluated explicitly.

    Used by the reference comparison and by the scipy (LSODA) benchmark; the production
    integrator :func:`integrate` uses the same forces with implicit friction.
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


@njit(**JIT)
def integrate(q, v, torque, P, SF, SI, J, RIG, CI, CF, SG, PG, n_nodes, rec_every, seg_every, rec, seg_rec,
              gq, gv, gsetpoint, ggas, PE, CH, CYL, grec):
    """March ``len(torque)`` steps of size P[P_DT] from state (q, v) in place.

    torque[n] is the input torque [N m] at t = n dt. Every ``rec_every`` steps a row of
    ``rec`` (columns R_*) is written, every ``seg_every`` steps a row of ``seg_rec`` (slot
    coordinates of all spring nodes). Returns (status, step): status 0 = finished,
    1 = NaN, 2 = runaway speed, 3 = windup far beyond a hardstop.

    Pulsation generator input ([thesis] §4.2-4.3, model-spec §2 "optional input chain"),
    on when ``gq`` is not empty (else pass :func:`no_generator`): the generator chain
    (state gq, gv; arrays PE, CH, CYL of :mod:`dampersim.solver.engine_layout`, whose
    step PE[E_DT] must equal P[P_DT]) is marched with the damper by :func:`engine_step`,
    its set point gsetpoint[n] [N m] and gas ramp ggas[n] [-] indexed like ``torque``.
    Its link shaft drives the damper's input DOF P[P_INPUT]: the link torque, taken at
    the start of each step, is added to torque[n] on that DOF and is the reaction on the
    transducer, so the input work R_E_IN is the link's work on the damper. The
    generator's channels go to ``grec`` (columns ER_*, ER_TOUT = the rig's output
    transducer torque) on the rows of ``rec``.
    """
    ndof = q.shape[0]
    nsteps = torque.shape[0]
    dt = P[P_DT]
    om0 = P[P_OMEGA0]
    held = P[P_HELD] > 0.0
    motor = int(P[P_MOTOR])
    din = int(P[P_INPUT])
    clutch = P[P_CL_ON] > 0.0
    vmax = P[P_VMAX]
    hs_on = P[P_HS_ON] > 0.0
    wlim = 0.0
    if hs_on:
        wlim = 0.35 + max(max(P[P_HSP_O], -P[P_HSN_O]), max(P[P_HSP_I], -P[P_HSN_I]))
    X = np.zeros(n_nodes)
    ST = np.zeros(2 * n_nodes)
    FC = np.zeros(ndof)
    FD = np.zeros(ndof)
    FE = np.zeros(ndof)
    FN = np.zeros(ndof)
    v0 = np.zeros(ndof)
    invj = 1.0 / J
    row = np.zeros(rec.shape[1])
    empty = np.zeros(0)
    stats = np.zeros(1)
    z = 0.0
    e_in = 0.0
    e_motor = 0.0
    e_fric = 0.0
    e_damp = 0.0
    e_stack = 0.0
    irec = 0
    iseg = 0
    vx = np.zeros(ndof)
    vprev = v.copy()
    flags = np.zeros(1)
    FW = np.zeros(2 * CI.shape[0] + 2 * SG.shape[0] + 6 * PG.shape[0])
    HS = np.zeros(4)
    npad = (CI.shape[0] + 7) // 8 * 8  # contact_laws' SIMD scratch
    XS = np.zeros(npad)
    MU = np.zeros(npad)
    DMU = np.zeros(npad)
    vb = np.zeros(ndof)
    rig0 = int(P[P_RIG0])  # spring masses (3 .. rig0-1) carry no viscous torque
    rc = 0  # steps since the last record / segment sample
    sc = 0
    gen = gq.shape[0] > 0  # pulsation generator drives the input DOF
    GF = np.zeros(gq.shape[0])
    GX = np.zeros(gq.shape[0])
    GOUT = np.zeros(EO_SIZE)
    gz = 0.0
    gpmax = 0.0
    tl = 0.0
    for step in range(nsteps):
        tin = torque[step]
        if gen:
            tl = engine_step(gq, gv, step * dt, gsetpoint[step], ggas[step], gz, q[din], v[din], PE, CH, CYL, GF, GX, GOUT)
            gz += dt * (gsetpoint[step] - tl)
            gpmax = max(gpmax, GOUT[EO_PMAX])
            tin += tl
        record = rc == 0 and irec < rec.shape[0]
        rc += 1
        if rc == rec_every:
            rc = 0
        # v holds the speeds half a step before q's time; velocity-dependent forces use
        # the speeds extrapolated to q's time (second order; plain v would make the
        # viscous terms first order)
        for i in range(ndof):
            vx[i] = 1.5 * v[i] - 0.5 * vprev[i]
        rr = row if record else empty
        energy = forces(q, vx, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, rr, flags, 0.0, ST)
        if flags[0] > 0.0:
            # coil stacking (rare: block arcs lie beyond the hardstop travel). Energy the
            # contact removes = impulse losses (the same on absolute and relative speeds,
            # since momentum is conserved) + elastic energy taken out by the projection
            u0 = elastic_energy(q, P, SF, SI, RIG, X)
            stats[0] = 0.0
            stacking(q, v, P, SF, SI, J, X, stats)
            e_stack += stats[0] + u0 - elastic_energy(q, P, SF, SI, RIG, X)
            for i in range(ndof):
                vx[i] = 1.5 * v[i] - 0.5 * vprev[i]
            energy = forces(q, vx, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, rr, flags, 0.0, ST)
        if record:
            ke = 0.0
            for i in range(ndof):
                om = om0 + v[i]
                ke += 0.5 * J[i] * om * om
            row[R_T] = step * dt
            row[R_E_IN] = e_in
            row[R_E_MOTOR] = e_motor
            row[R_E_KIN] = ke
            row[R_E_SPRING] = energy
            row[R_E_FRIC] = e_fric
            row[R_E_DAMP] = e_damp
            row[R_E_STACK] = e_stack
            for k in range(rec.shape[1]):
                rec[irec, k] = row[k]
            if gen and irec < grec.shape[0]:
                engine_record(grec, irec, step * dt, tl, row[R_TOUT], gpmax, GOUT)
                gpmax = 0.0
            irec += 1
        if sc == 0 and iseg < seg_rec.shape[0]:
            spring_nodes(q, P, SF, SI, X)
            for k in range(n_nodes):
                seg_rec[iseg, k] = X[k]
            iseg += 1
        sc += 1
        if sc == seg_every:
            sc = 0
        # 1) smooth forces: explicit velocity update; the viscous work is taken at the
        #    mid-step speed, which makes the kinetic-energy bookkeeping exact
        for i in range(ndof):
            v0[i] = v[i]
            v[i] += dt * (FC[i] + FD[i] + FE[i]) * invj[i]
        if held:
            v[motor] = 0.0
        for i in range(3):
            e_damp -= dt * FD[i] * (om0 + 0.5 * (v0[i] + v[i]))
        for i in range(rig0, ndof):
            e_damp -= dt * FD[i] * (om0 + 0.5 * (v0[i] + v[i]))
        e_motor += dt * FE[motor] * (om0 + 0.5 * (v0[motor] + v[motor]))
        # 2) friction: each spring mass (the two masses of a nested pair together) is
        #    solved implicitly in its slip speeds, the housing bodies' speeds known
        #    with the hardstop contacts in the same implicit solve
        contact_laws(v, v0, FN, P, CI, CF, FW, XS, MU, DMU)
        closed = hs_on and hardstop_coefficients(q, P, dt, HS)
        if closed:
            for i in range(ndof):
                vb[i] = v[i]
        ef = friction_step(v, v0, J, CI, SG, PG, dt, FW, HS)
        if closed:
            if hardstop_release(q, v, P, HS):
                for i in range(ndof):
                    v[i] = vb[i]
                ef = friction_step(v, v0, J, CI, SG, PG, dt, FW, HS)
            e_damp += hardstop_dissipation(P, dt, HS, vb, v)
        e_fric += ef
        if clutch:
            # lock-up clutch slip (effect clutch_slip), implicit like the spring friction
            e_fric += clutch_step(v, v0, P, J, dt)
        # input work on the speeds that move the input DOF (after a clutch impulse)
        e_in += dt * tin * (om0 + 0.5 * (v0[din] + v[din]))
        # 3) PI state and positions
        z -= dt * v[motor]
        for i in range(ndof):
            vprev[i] = v0[i]
            q[i] += dt * v[i]
        if step % 256 == 0:
            for i in range(ndof):
                if not (v[i] == v[i]) or not (q[i] == q[i]):
                    return 1, step
                if abs(v[i]) > vmax:
                    return 2, step
            if hs_on:
                if abs(q[0] - q[1]) > wlim or abs(q[1] - q[2]) > wlim:
                    return 3, step
            if gen:
                st = engine_diverged(gv, PE)
                if st != 0:
                    return st, step
    return 0, nsteps


# --- engine-order input torque on the step grid ----------------------------------------

ORDER_SUM_RESYNC = 32  # samples between exact cos/sin evaluations in order_sum


@njit(**LEAF)
def order_sum(out, dt, speed, mean, mean_ramp, amplitude_ramp, K, A, PH):
    """T_in(n dt) for n = 0 .. len(out)-1 into ``out`` [N m]: the order sum of
    :class:`dampersim.excitation.OrderSum` (model-spec §7, [thesis] §6.2.1) on the
    integrator's grid. speed [rad/s], mean [N m], ramps [s]; order k (K[k] [-]) has
    amplitude A[k] [N m] and phase PH[k] [rad].

    Each order's cosine advances by a rotation through k speed dt, with an exact cos/sin
    every ORDER_SUM_RESYNC samples, so rounding cannot accumulate beyond a few dozen ulp
    (tested against the NumPy form); one pass over the grid instead of a cosine call per
    order and sample."""
    n = out.shape[0]
    for i in range(n):
        t = i * dt
        m = 1.0 if mean_ramp <= 0.0 else min(t / mean_ramp, 1.0)
        out[i] = mean * m
    for k in range(K.shape[0]):
        w = K[k] * speed
        cd = math.cos(w * dt)
        sd = math.sin(w * dt)
        a = A[k]
        i0 = 0
        while i0 < n:
            ph = w * (i0 * dt) + PH[k]
            c = math.cos(ph)
            s = math.sin(ph)
            i1 = min(i0 + ORDER_SUM_RESYNC, n)
            for i in range(i0, i1):
                t = i * dt
                if amplitude_ramp > 0.0:
                    env = min(max((t - mean_ramp) / amplitude_ramp, 0.0), 1.0)
                else:
                    env = 1.0 if t >= mean_ramp else 0.0
                out[i] += env * a * c
                c, s = c * cd - s * sd, s * cd + c * sd
            i0 = i1


# --- optional effects of the discrepancy library (dampersim.discrepancy.effects) --------
# Each is off when its P slot is zero; see dampersim.solver.layout for the slots.


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
    adds to the normal force of the outer spring's mass of the same index (spring rows 1
    and 2: pair outer, pair inner)."""
    if SI.shape[0] < 3:
        return
    n = SI[1, I_N]
    o1 = SI[1, I_OFF]
    o2 = SI[2, I_OFF]
    f = P[P_NRT]
    for i in range(n - 1):
        FN[o1 + i] += f * FN[o2 + i]


@njit(**LEAF)
def effect_forces(q, v, P, FC, FD):
    """Conservative (FC) and dissipative (FD) torques of the smooth effects; returns their
    elastic energy [J].

    - inner_short_springs: a third stage on the inner windup w = q_sec - q_ter,
      T = K3 * dead_zone(w, gap) (shorter springs engage either way once the slot has
      closed by the clearance);
    - turbine_drag: T = c (v_housing - v_sec) on J_sec, the reaction on the housing
      (J_pri, or the clutch drive side when the clutch can slip);
    - pendulum_absorber: linearised pendulum DOF on J_sec with restoring stiffness
      J_a (n Omega0)^2 and damping c_a.
    """
    energy = 0.0
    k3 = P[P_SS_K]
    if k3 > 0.0:
        d = dead_zone(q[1] - q[2], P[P_SS_GAP])
        if d != 0.0:
            t = k3 * d
            FC[1] -= t
            FC[2] += t
            energy += 0.5 * k3 * d * d
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
    if P[P_SS_K] > 0.0:
        d = dead_zone(q[1] - q[2], P[P_SS_GAP])
        energy += 0.5 * P[P_SS_K] * d * d
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


# =====================================================================================
# Pulsation generator (motored engine) chain: [thesis] chapter 4, model-spec §8.
# One step of the chain is :func:`engine_step`; :func:`engine_integrate` marches it
# alone on a stiff propshaft, :func:`integrate` marches it coupled to the full damper.
# Array layouts in dampersim.solver.engine_layout.
# =====================================================================================

# engine scalar vector PE (must match dampersim.solver.engine_layout)
E_OMEGA0 = 0
E_DT = 1
E_PC = 2
E_PATM = 3
E_GAMMA = 4
E_AREA = 5
E_R = 6
E_L = 7
E_VC = 8
E_VBDC = 9
E_MREC = 10
E_RVISC = 11
E_RMU = 12
E_RTENS = 13
E_RBACK = 14  # pi D h_ring [m^2]
E_VREF = 15
E_BEAR = 16
E_KI = 17
E_KLINK = 18  # stiffness of the shaft leaving the transducer [N m/rad]
E_BLINK = 19  # its damping [N m s/rad]
E_VMAX = 20  # divergence threshold on the chain's relative speeds [rad/s]
E_DDYNO = 21  # active damping of the input dyno's torque control on its speed deviation [N m s/rad]
PE_SIZE = 22

# engine record columns
ER_T = 0
ER_TLINK = 1  # torque leaving the generator (into the stiff shaft / J_pri) [N m]
ER_TDYNO = 2  # input dyno torque [N m]
ER_W_TRANS = 3  # absolute speed of the generator's output transducer [rad/s]
ER_THETA1 = 4  # crank angle of section 1 (cylinder 1 from TDC) [rad]
ER_P1 = 5  # cylinder 1 pressure [Pa]
ER_TGAS = 6  # sum of gas torques [N m]
ER_TINER = 7  # sum of reciprocating inertia torques (velocity part) [N m]
ER_TFRIC = 8  # sum of ring + bearing friction torques [N m]
ER_TOUT = 9  # coupled: the rig's output transducer torque (full damper model), else = ER_TLINK [N m]
ER_PMAX = 10  # largest cylinder pressure seen since the last record [Pa]
NEREC = 11

# scratch OUT of engine_step (length EO_SIZE)
EO_TDYNO = 0  # input dyno torque [N m]
EO_W_TRANS = 1  # absolute transducer speed [rad/s]
EO_THETA1 = 2  # crank angle of cylinder 1 [rad]
EO_P1 = 3  # cylinder 1 pressure [Pa]
EO_TGAS = 4
EO_TINER = 5
EO_TFRIC = 6
EO_PMAX = 7  # largest cylinder pressure of this step [Pa]
EO_SIZE = 8


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
    """Polytropic air-spring pressure P = P_c (V_BDC / V)^gamma [Pa] (model-spec §8: the
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
    chain is marched by :func:`integrate` instead.

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


def no_generator():
    """The generator arguments of :func:`integrate` when no pulsation generator drives
    the damper (empty arrays of the right types)."""
    z1 = np.zeros(0)
    return z1, z1, z1, z1, z1, np.zeros((0, 4)), np.zeros((0, 2)), np.zeros((0, NEREC))
