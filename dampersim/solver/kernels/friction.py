"""Friction of the spring masses: Makkar's law and its linearly implicit solve per step.

Makkar friction (Eq. 27-28) against the housing or, for the inner spring of a nested
pair, against the outer spring's mass (Eq. 25-26). Each contact's law is linearised at
the start-of-step slip, applied with an exponentially fitted weight between the start
and the end of the step (L-stable on stiff contacts, second order on soft ones) and
solved implicitly together with the housing bodies it loads, so the stiff friction slope
at small slip speed (about 38 per m/s) needs no tiny step; Newton re-solves keep the
applied torque on the law (docs/model.md §12). We differ from the thesis here: its
Simulink model ran the same law with a fixed step of 1e-6 s ([thesis] §5.6), 8x finer
than our default.
"""

import math

import numpy as np
from numba import njit

from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.fastmath import expm1_neg, fast_tanh
from dampersim.solver.layout import P_FR_ITER, P_FR_SCHEME, P_FR_TOL, P_G1, P_G2, P_G3, P_G4, P_G5, P_G6

#: friction schemes (P[P_FR_SCHEME]): where in the step the linearised law is applied
SCHEME_TRAPEZOIDAL = 0  # at the midpoint slip, theta = 1/2 (A-stable only: rings when stiff)
SCHEME_BACKWARD_EULER = 1  # at the end-of-step slip, theta = 1 (L-stable, first order)
SCHEME_FITTED = 2  # exponentially fitted theta(z): 1/2 + z/12 when soft, -> 1 when stiff



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
def fitted_theta(z):
    """Weight theta of the end-of-step slip for a contact of stiffness ratio z [-].

    theta(z) = 1/(1 - exp(-z)) - 1/z makes the theta-method's amplification factor
    (1 - (1 - theta) z) / (1 + theta z) equal to exp(-z), the exact decay of a stuck
    contact's linearised slip over the step: 1/2 + z/12 for small z (second order),
    tending to 1 as z grows (L-stable: the factor tends to 0, never negative).
    Branch-free select between the series (z < 0.05, truncation < 1e-11) and the closed
    form (no cancellation above 0.05)."""
    zb = max(z, 0.05)
    big = -1.0 / expm1_neg(zb) - 1.0 / zb
    small = 0.5 + z * (1.0 / 12.0) - z * z * z * (1.0 / 720.0)
    return small if z < 0.05 else big


@njit(inline="always", **JIT)
def _linear_law(c, mu, dmu, th, s_lin, s_pred, x_eval, safe, FN, CI, CF, W):
    """Linearised friction torque of contact c into W: T = W[2c] + W[2c+1] * s, with s the
    end-of-step slip [rad/s].

    The law (mu, dmu) is taken at the slip x_eval [m/s] = r ((1 - th) s0 + th s_lin)
    (s0: start of step, s_lin: the current estimate of the end-of-step slip) and
    applied at (1 - th) s0 + th s: a line through the law's value there with slope
    th * m in s.
    First solve (``safe`` false): m = dmu, the tangent; a falling (Stribeck) slope is
    not made implicit but applied explicitly at the predicted slip s_pred (the slip
    after the smooth forces), which keeps it second order.
    Newton re-solves (``safe``): m = max(dmu, mu / x_eval), at least the secant through
    zero slip. The regularised law is concave in |v| wherever it matters, so a tangent
    step from a far slip can overshoot to the other side and oscillate there (a mass
    caught by friction within one step); with the secant bound every iterate approaches
    the solution from one side (Kacanov's iteration), and near zero slip the two
    coincide."""
    a = np.uintp(CI[c, 0])  # unsigned: no negative-index wraparound (see forces)
    r = CF[c, 1]
    cn = CF[c, 0] * FN[a] * r
    if safe:
        m = dmu
        if x_eval != 0.0:
            m = max(dmu, mu / x_eval)
        q = th * cn * m * r
        W[2 * c] = cn * mu - q * s_lin
        W[2 * c + 1] = q
    else:
        qc = th * cn * dmu * r
        qi = max(qc, 0.0)
        W[2 * c] = cn * mu - qi * s_lin + (qc - qi) * (s_pred - s_lin)
        W[2 * c + 1] = qi


@njit(**LEAF)
def contact_laws(v, v0, FN, P, CI, CF, invj, dt, W, XS, MU, DMU, TH):
    """Linearised friction law of every contact into W[0 : 2 n_contacts] about the
    start-of-step slips (v0), and each contact's weight theta into TH (see
    :func:`_linear_law`, :func:`fitted_theta`); v: the speeds after the smooth forces
    (the predicted slips of the explicit Stribeck branch). invj: 1/J per DOF
    [1/(kg m^2)]; dt: step [s].

    Scheme P[P_FR_SCHEME] (SCHEME_*): theta = 1/2, 1, or fitted to the contact's
    stiffness ratio z = alpha F_N r^2 mu'(s0) dt (1/J_a + 1/J_b) [-], the linearised
    slip's decay over one step with the housing side's inertia included.

    XS, MU, DMU, TH: scratch of n_contacts rounded up to a multiple of 8 (an AVX-512
    register) for the slips [m/s], friction coefficients, slopes and weights. The
    coefficients are computed in one loop over these contiguous arrays, free of calls
    and branches, which the compiler turns into SIMD code; the padding spares it a scalar
    remainder loop. XS, MU, DMU hold the law at the previous step's end-of-step slips
    (:func:`refine_laws`), which are this step's start slips unless something moved
    the speeds in between (a coil-stacking impulse, a Newton re-solve): the law is
    evaluated again only if some slip differs."""
    scheme = P[P_FR_SCHEME]
    nc = CI.shape[0]
    moved = 0
    for c in range(nc):
        x = (v0[np.uintp(CI[c, 0])] - v0[np.uintp(CI[c, 1])]) * CF[c, 1]
        moved += x != XS[c]
        XS[c] = x
    if moved > 0:
        _laws(XS, MU, DMU, P[P_G1], P[P_G2], P[P_G3], P[P_G4], P[P_G5], P[P_G6])
    if scheme == SCHEME_FITTED:
        for c in range(nc):
            a = np.uintp(CI[c, 0])
            r = CF[c, 1]
            TH[c] = CF[c, 0] * FN[a] * r * r * max(DMU[c], 0.0) * dt * (invj[a] + invj[np.uintp(CI[c, 1])])
        for c in range(TH.shape[0]):
            TH[c] = fitted_theta(TH[c])
    else:
        th = 1.0 if scheme == SCHEME_BACKWARD_EULER else 0.5
        for c in range(TH.shape[0]):
            TH[c] = th
    for c in range(nc):
        a = np.uintp(CI[c, 0])
        b = np.uintp(CI[c, 1])
        _linear_law(c, MU[c], DMU[c], TH[c], v0[a] - v0[b], v[a] - v[b], XS[c], False, FN, CI, CF, W)


@njit(inline="always", **JIT)
def _laws(XS, MU, DMU, g1, g2, g3, g4, g5, g6):
    """Makkar coefficient and slope at every slip of XS [m/s] (padded length), SIMD."""
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


@njit(**LEAF)
def refine_laws(v, v0, FN, P, CI, CF, W, XS, MU, DMU, TH, SK, ML, tol, first, final):
    """Newton check of a solved friction step; returns True when W was changed and the
    step must be solved again from the same pre-friction speeds. tol: accepted error
    of the friction coefficient [-]; SK, ML: padded scratch (solved slips [rad/s],
    predicted coefficients [-]).

    ``first`` (after the step's first solve): is the law linear over the step? The
    start-of-step linearisation's coefficient at the solved end-of-step slip s is
    compared with the law's there; the law at s is kept in XS/MU/DMU, where the next
    step finds it. Later checks are Newton residuals: the law where the scheme applies
    it, (1 - theta) s0 + theta s, against the current linearisation. If some contact is
    off by more than tol, every contact is re-linearised about its solved slip (a Newton
    iteration of the regularised law, with the same theta); with ``final`` the law's
    torque at the last evaluation is applied as a constant instead (slope 0), so the
    re-solve cannot leave the law's bounds, whatever the linearisation's error."""
    g1, g2, g3, g4, g5, g6 = P[P_G1], P[P_G2], P[P_G3], P[P_G4], P[P_G5], P[P_G6]
    nc = CI.shape[0]
    for c in range(nc):
        a = np.uintp(CI[c, 0])
        b = np.uintp(CI[c, 1])
        r = CF[c, 1]
        s0 = v0[a] - v0[b]
        sk = v[a] - v[b]
        SK[c] = sk
        if first:
            ML[c] = MU[c] + DMU[c] * (sk - s0) * r
            XS[c] = sk * r
        else:
            cn = CF[c, 0] * FN[a] * r
            ML[c] = (W[2 * c] + W[2 * c + 1] * sk) / cn if cn != 0.0 else np.nan
            XS[c] = ((1.0 - TH[c]) * s0 + TH[c] * sk) * r
    _laws(XS, MU, DMU, g1, g2, g3, g4, g5, g6)
    err = 0.0
    for c in range(nc):
        if ML[c] == ML[c]:  # a contact without normal force (NaN) carries no torque to check
            err = max(err, abs(ML[c] - MU[c]))
    if err <= tol:
        return False
    if final:
        for c in range(nc):
            W[2 * c] = CF[c, 0] * FN[np.uintp(CI[c, 0])] * CF[c, 1] * MU[c]
            W[2 * c + 1] = 0.0
        return True
    if first:
        # the Newton linearisation needs the law where it is applied
        for c in range(nc):
            a = np.uintp(CI[c, 0])
            XS[c] = ((1.0 - TH[c]) * (v0[a] - v0[np.uintp(CI[c, 1])]) + TH[c] * SK[c]) * CF[c, 1]
        _laws(XS, MU, DMU, g1, g2, g3, g4, g5, g6)
    for c in range(nc):
        _linear_law(c, MU[c], DMU[c], TH[c], SK[c], SK[c], XS[c], True, FN, CI, CF, W)
    return True


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
    when the contact is open (see :func:`.contacts.hardstop_coefficients`). Solving them
    together with friction keeps J_pri's inertia on J_sec while the outer hardstop is closed.
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
    return friction_dissipation(v, CI, dt, W)


@njit(**LEAF)
def newton_friction(v, vb, v0, J, FN, P, CI, CF, SG, PG, dt, W, HS, XS, MU, DMU, TH, SK, ML, stats, ef):
    """Newton iterations of a friction step already solved once (:func:`friction_step`
    on the linearisation of :func:`contact_laws`, which returned its dissipation ef
    [J]); returns the step's friction dissipation [J].

    vb: the speeds before the friction solve, from which every re-solve restarts.
    While :func:`refine_laws` finds the law off by more than P[P_FR_TOL] (friction
    coefficient units), the step is re-linearised about the solved slips and solved
    again, at most P[P_FR_ITER] times; the last resort applies the law's torque at the
    last iterate with slope 0, so no contact ends outside the law's bounds. stats[1]
    counts the re-solves."""
    tol = P[P_FR_TOL]
    maxit = int(P[P_FR_ITER])
    for it in range(maxit + 1):
        if not refine_laws(v, v0, FN, P, CI, CF, W, XS, MU, DMU, TH, SK, ML, tol, it == 0, it == maxit):
            break
        for i in range(v.shape[0]):
            v[i] = vb[i]
        ef = friction_step(v, v0, J, CI, SG, PG, dt, W, HS)
        stats[1] += 1.0
        if it == maxit:
            stats[2] += 1.0
    return ef


@njit(**LEAF)
def friction_dissipation(v, CI, dt, W):
    """Work [J] of the linearised friction torques of W on the slips of v over a step dt
    [s]: the dissipation :func:`friction_step` returns for the speeds it produced."""
    diss = 0.0
    for c in range(CI.shape[0]):
        s = v[np.uintp(CI[c, 0])] - v[np.uintp(CI[c, 1])]
        diss += dt * (W[2 * c] + W[2 * c + 1] * s) * s
    return diss
