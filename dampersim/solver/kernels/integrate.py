"""The damper's production integration step and the loop that marches it over a run.

Integrator: symplectic (semi-implicit) Euler for the smooth forces, and an implicit
friction step for all contacts together with the housings and hardstop contacts (an
exponentially fitted weight per contact, Newton re-solves of the law;
:mod:`.friction`), so the stiff friction slope at small slip speed (about 38 per m/s)
needs no tiny step. One step is
:func:`step`; :func:`integrate` repeats it, writes the records and checks for
divergence. With the pulsation generator as the torque source ([thesis] §4.2, the rig
mode), :func:`integrate` marches the generator chain
(:func:`dampersim.solver.kernels.engine.engine_step`) with the same step and adds its
link torque to the input torque. The Python side calls :func:`integrate` only through
:mod:`dampersim.solver.driver`.
"""

from collections import namedtuple

import numpy as np
from numba import njit

from dampersim.solver.engine_layout import EO_PMAX, EO_SIZE
from dampersim.solver.kernels import JIT, LEAF
from dampersim.solver.kernels.contacts import hardstop_coefficients, hardstop_dissipation, hardstop_release, stacking
from dampersim.solver.kernels.effects import clutch_step
from dampersim.solver.kernels.engine import engine_diverged, engine_record, engine_step
from dampersim.solver.kernels.forces import elastic_energy, forces
from dampersim.solver.kernels.friction import contact_laws, friction_step, newton_friction
from dampersim.solver.kernels.springs import spring_nodes
from dampersim.solver.layout import (
    P_CL_ON,
    P_DT,
    P_HELD,
    P_HS_ON,
    P_HSN_I,
    P_HSN_O,
    P_HSP_I,
    P_HSP_O,
    P_INPUT,
    P_MOTOR,
    P_OMEGA0,
    P_RIG0,
    P_VMAX,
    R_E_DAMP,
    R_E_FRIC,
    R_E_HS,
    R_E_IN,
    R_E_KIN,
    R_E_MOTOR,
    R_E_SPRING,
    R_E_STACK,
    R_T,
    R_TOUT,
    S_E_DAMP,
    S_E_FRIC,
    S_E_HS,
    S_E_IN,
    S_E_MOTOR,
    S_E_STACK,
    S_SIZE,
    S_Z,
)

#: Scratch arrays of :func:`step` (all float64), made by :func:`workspace`: node
#: coordinates X, segment torques ST, torques FC/FD/FE, normal forces FN, start-of-step
#: speeds v0, 1/J, extrapolated speeds vx, the stacking flag, the friction solve's FW,
#: the hardstop coefficients HS, the friction law's padded XS/MU/DMU/TH/SK/ML, the speeds
#: before the friction solve vb (each re-solve restarts from them) and the stacking
#: energy stats.
Work = namedtuple("Work", "X ST FC FD FE FN v0 invj vx flags FW HS XS MU DMU TH SK ML vb stats")


@njit(**JIT)
def workspace(J, n_nodes, n_contacts, n_singles, n_pairs):
    """Scratch of :func:`step` for a damper with inertias J (one per DOF), ``n_nodes``
    spring nodes and the given numbers of friction contacts, single masses and pairs
    (the lengths of the layout's CI, SG and PG)."""
    ndof = J.shape[0]
    npad = (n_contacts + 7) // 8 * 8  # contact_laws' SIMD scratch
    return Work(
        np.zeros(n_nodes),
        np.zeros(2 * n_nodes),
        np.zeros(ndof),
        np.zeros(ndof),
        np.zeros(ndof),
        np.zeros(ndof),
        np.zeros(ndof),
        1.0 / J,
        np.zeros(ndof),
        np.zeros(1),
        np.zeros(2 * n_contacts + 2 * n_singles + 6 * n_pairs),
        np.zeros(4),
        np.full(npad, np.nan),  # no law evaluated yet: the first step evaluates it
        np.zeros(npad),
        np.zeros(npad),
        np.zeros(npad),
        np.zeros(npad),
        np.zeros(npad),
        np.zeros(ndof),
        np.zeros(3),
    )


# forceinline: LLVM inlines the step into the loop of march; called, each step would
# pass about 240 words of array descriptors (measured 12 % slower). numba compiles step
# with the caller that first needs it, so the step called on its own and the loop's copy
# come from one compilation and give the same numbers (tests/unit/test_step.py).
@njit(**dict(LEAF, forceinline=True))
def step(t, tin, q, v, vprev, S, P, SF, SI, J, RIG, CI, CF, SG, PG, row, segrow, W):
    """Advance the damper one step of P[P_DT] from time t [s], in place: the production
    step, which :func:`integrate` repeats.

    tin: input torque [N m] on DOF P[P_INPUT] during the step. State: q (angles), v
    (speeds, half a step behind q), vprev (the speeds of the step before v) and S (slots
    S_* of :mod:`dampersim.solver.layout`: PI state and cumulative energies). ``row``:
    filled with the record of the start-of-step state (columns R_*) when its length is
    NREC, else pass an empty array; ``segrow``: filled with the slot coordinates of all
    spring nodes at that state when its length is n_nodes, else empty. W: scratch of
    :func:`workspace`. Allocates nothing.
    """
    ndof = q.shape[0]
    dt = P[P_DT]
    om0 = P[P_OMEGA0]
    held = P[P_HELD] > 0.0
    motor = int(P[P_MOTOR])
    din = int(P[P_INPUT])
    clutch = P[P_CL_ON] > 0.0
    hs_on = P[P_HS_ON] > 0.0
    rig0 = int(P[P_RIG0])  # spring masses (3 .. rig0-1) carry no viscous torque
    X = W.X
    ST = W.ST
    FC = W.FC
    FD = W.FD
    FE = W.FE
    FN = W.FN
    v0 = W.v0
    invj = W.invj
    vx = W.vx
    flags = W.flags
    FW = W.FW
    HS = W.HS
    XS = W.XS
    MU = W.MU
    DMU = W.DMU
    TH = W.TH
    SK = W.SK
    ML = W.ML
    vb = W.vb
    stats = W.stats
    z = S[S_Z]
    e_in = S[S_E_IN]
    e_motor = S[S_E_MOTOR]
    e_fric = S[S_E_FRIC]
    e_damp = S[S_E_DAMP]
    e_stack = S[S_E_STACK]
    e_hs = S[S_E_HS]
    record = row.shape[0] > 0
    # v holds the speeds half a step before q's time; velocity-dependent forces use
    # the speeds extrapolated to q's time (second order; plain v would make the
    # viscous terms first order)
    for i in range(ndof):
        vx[i] = 1.5 * v[i] - 0.5 * vprev[i]
    energy = forces(q, vx, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, row, flags, 0.0, ST)
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
        energy = forces(q, vx, tin, z, P, SF, SI, J, RIG, X, FC, FD, FE, FN, row, flags, 0.0, ST)
    if record:
        ke = 0.0
        for i in range(ndof):
            om = om0 + v[i]
            ke += 0.5 * J[i] * om * om
        row[R_T] = t
        row[R_E_IN] = e_in
        row[R_E_MOTOR] = e_motor
        row[R_E_KIN] = ke
        row[R_E_SPRING] = energy
        row[R_E_FRIC] = e_fric
        row[R_E_DAMP] = e_damp
        row[R_E_STACK] = e_stack
        row[R_E_HS] = e_hs
    if segrow.shape[0] > 0:
        spring_nodes(q, P, SF, SI, X)
        for k in range(segrow.shape[0]):
            segrow[k] = X[k]
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
    #    with the hardstop contacts in the same implicit solve; then Newton
    #    re-solves of the law about the solved slips while it is off by more than
    #    the tolerance (docs/model.md §12)
    contact_laws(v, v0, FN, P, CI, CF, invj, dt, FW, XS, MU, DMU, TH)
    closed = hs_on and hardstop_coefficients(q, P, dt, HS)
    for i in range(ndof):
        vb[i] = v[i]
    ef = friction_step(v, v0, J, CI, SG, PG, dt, FW, HS)
    if closed and hardstop_release(q, v, P, HS):
        for i in range(ndof):
            v[i] = vb[i]
        ef = friction_step(v, v0, J, CI, SG, PG, dt, FW, HS)
    ef = newton_friction(v, vb, v0, J, FN, P, CI, CF, SG, PG, dt, FW, HS, XS, MU, DMU, TH, SK, ML, stats, ef)
    if closed:
        eh = hardstop_dissipation(dt, HS, vb, v)
        e_damp += eh
        e_hs += eh
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
    S[S_Z] = z
    S[S_E_IN] = e_in
    S[S_E_MOTOR] = e_motor
    S[S_E_FRIC] = e_fric
    S[S_E_DAMP] = e_damp
    S[S_E_STACK] = e_stack
    S[S_E_HS] = e_hs


@njit(**JIT)
def integrate(q, v, torque, P, SF, SI, J, RIG, CI, CF, SG, PG, n_nodes, rec_every, seg_every, rec, seg_rec,
              gq, gv, gsetpoint, ggas, PE, CH, CYL, grec):
    """March ``len(torque)`` steps of size P[P_DT] from state (q, v) in place.

    torque[n] is the input torque [N m] at t = n dt. Every ``rec_every`` steps a row of
    ``rec`` (columns R_*) is written, every ``seg_every`` steps a row of ``seg_rec`` (slot
    coordinates of all spring nodes). Returns (status, step): status 0 = finished,
    1 = NaN, 2 = runaway speed, 3 = windup far beyond a hardstop.

    Pulsation generator input ([thesis] §4.2-4.3, docs/model.md §2 "optional input chain"),
    on when ``gq`` is not empty (else pass the driver's no-generator placeholders): the
    generator chain (state gq, gv; arrays PE, CH, CYL of
    :mod:`dampersim.solver.engine_layout`, whose step PE[E_DT] must equal P[P_DT]) is
    marched with the damper by :func:`.engine.engine_step`, its set point gsetpoint[n]
    [N m] and gas ramp ggas[n] [-] indexed like ``torque``. Its link shaft drives the damper's
    input DOF P[P_INPUT]: the link torque, taken at the start of each step, is added to
    torque[n] on that DOF and is the reaction on the transducer, so the input work R_E_IN
    is the link's work on the damper. The generator's channels go to ``grec`` (columns
    ER_*, ER_TOUT = the rig's output transducer torque) on the rows of ``rec``.
    """
    W = workspace(J, n_nodes, CI.shape[0], SG.shape[0], PG.shape[0])
    S = np.zeros(S_SIZE)
    vprev = v.copy()
    G = (np.zeros(gq.shape[0]), np.zeros(gq.shape[0]), np.zeros(EO_SIZE))
    row = np.zeros(rec.shape[1])
    segrow = np.zeros(n_nodes)
    return march(q, v, vprev, S, torque, P, SF, SI, J, RIG, CI, CF, SG, PG, rec_every, seg_every, rec, seg_rec,
                 row, segrow, np.zeros(0), W, gq, gv, gsetpoint, ggas, PE, CH, CYL, grec, G)


@njit(**LEAF)
def march(q, v, vprev, S, torque, P, SF, SI, J, RIG, CI, CF, SG, PG, rec_every, seg_every, rec, seg_rec, row, segrow,
          empty, W, gq, gv, gsetpoint, ggas, PE, CH, CYL, grec, G):
    """The loop of :func:`integrate` on the scratch allocated there; compiled without
    reference counting, so that the loop pays no atomic counter updates on its arrays.

    vprev, S: the state of :func:`step` besides (q, v); row, segrow, empty: scratch of a
    record row, of a segment sample and an empty array; W: :func:`workspace`; G: the
    generator's scratch (force and extra-inertia arrays of the chain's length, the step
    outputs EO_*). Returns (status, step) as :func:`integrate`."""
    ndof = q.shape[0]
    nsteps = torque.shape[0]
    dt = P[P_DT]
    din = int(P[P_INPUT])
    vmax = P[P_VMAX]
    hs_on = P[P_HS_ON] > 0.0
    wlim = 0.0
    if hs_on:
        wlim = 0.35 + max(max(P[P_HSP_O], -P[P_HSN_O]), max(P[P_HSP_I], -P[P_HSN_I]))
    n_nodes = segrow.shape[0]
    irec = 0
    iseg = 0
    rc = 0  # steps since the last record / segment sample
    sc = 0
    gen = gq.shape[0] > 0  # pulsation generator drives the input DOF
    GF = G[0]
    GX = G[1]
    GOUT = G[2]
    gz = 0.0
    gpmax = 0.0
    tl = 0.0
    for n in range(nsteps):
        tin = torque[n]
        if gen:
            tl = engine_step(gq, gv, n * dt, gsetpoint[n], ggas[n], gz, q[din], v[din], PE, CH, CYL, GF, GX, GOUT)
            gz += dt * (gsetpoint[n] - tl)
            gpmax = max(gpmax, GOUT[EO_PMAX])
            tin += tl
        record = rc == 0 and irec < rec.shape[0]
        rc += 1
        if rc == rec_every:
            rc = 0
        sample = sc == 0 and iseg < seg_rec.shape[0]
        sc += 1
        if sc == seg_every:
            sc = 0
        step(n * dt, tin, q, v, vprev, S, P, SF, SI, J, RIG, CI, CF, SG, PG, row if record else empty,
             segrow if sample else empty, W)
        if record:
            for k in range(rec.shape[1]):
                rec[irec, k] = row[k]
            if gen and irec < grec.shape[0]:
                engine_record(grec, irec, n * dt, tl, row[R_TOUT], gpmax, GOUT)
                gpmax = 0.0
            irec += 1
        if sample:
            for k in range(n_nodes):
                seg_rec[iseg, k] = segrow[k]
            iseg += 1
        if n % 256 == 0:
            for i in range(ndof):
                if not (v[i] == v[i]) or not (q[i] == q[i]):
                    return 1, n
                if abs(v[i]) > vmax:
                    return 2, n
            if hs_on:
                if abs(q[0] - q[1]) > wlim or abs(q[1] - q[2]) > wlim:
                    return 3, n
            if gen:
                st = engine_diverged(gv, PE)
                if st != 0:
                    return st, n
    return 0, nsteps
