"""Flatten a :class:`DamperSystem` once into the float64/int64 arrays the kernels read.

Degrees of freedom (all angles in a frame turning at the nominal speed Omega0 [rad/s],
all speeds relative to Omega0; docs/model.md §1):

====================  =========================================================
index                 body
====================  =========================================================
0, 1, 2               J_pri, J_sec, J_ter
3 ...                 segment masses of each integrated spring, in spring order
                      (outer spring; nested pair outer; nested pair inner; with
                      effect inner_short_springs the short pair's outer and inner)
then                  rig elements in power-flow order; the last is the motor
then (optional)       clutch drive side (effect clutch_slip), pendulum
                      absorber (effect pendulum_absorber)
====================  =========================================================

Each integrated spring stands for ``count`` identical springs: its masses carry
``count`` times one spring's inertia and all its forces are ``count`` times one
spring's, so the bodies receive the whole set's torque and momentum is conserved.
With effect inner_short_springs the inner set has two pair designs, each integrated as
one representative pair (docs/model.md §4): the normal pairs (count nS - n_short) and
the pairs with a short inner spring (count n_short).

Spring coordinates ([thesis] Eq. 16-18, docs/model.md §3): for a set between body A
(before) and body B (after), a node's slot coordinate is ``x = q_A - q_node`` [rad],
measured against the rotation from the centre of A's stopper. B's stopper sits at
``x = w`` with windup ``w = q_A - q_B``.

The slot constants below (P_*, F_*, I_*, and the record columns R_*) are frozen into the
compiled kernels (:mod:`dampersim.solver.kernels`), whose on-disk cache is keyed by
this file's source too; this module imports no kernel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dampersim.parameters.model import DamperSystem

PRI, SEC, TER = 0, 1, 2

# --- scalar parameter vector P -------------------------------------------------------
P_OMEGA0 = 0
P_DT = 1
P_G1, P_G2, P_G3, P_G4, P_G5, P_G6 = 2, 3, 4, 5, 6, 7
P_HS_ON = 8
P_HS_K = 9
P_HS_D = 10
P_HSP_O = 11  # outer positive hardstop windup [rad]
P_HSN_O = 12  # outer negative hardstop windup [rad] (negative number)
P_HSP_I = 13
P_HSN_I = 14
P_KP = 15
P_KI = 16
P_HELD = 17  # 1.0: motor speed prescribed
P_NRIG = 18
P_RIG0 = 19  # DOF index of the first rig element
P_TRANS = 20  # DOF index of the output transducer element
P_VMAX = 21  # divergence threshold on relative speed [rad/s]
# optional effects (dampersim.discrepancy.effects); a zero entry switches an effect off
P_MOTOR = 22  # DOF index of the output motor
P_INPUT = 23  # DOF the input torque acts on (J_pri, or the clutch drive side)
P_CL_ON = 24  # 1.0: lock-up clutch of finite capacity between P_INPUT and J_pri
P_CL_CAP = 25  # clutch capacity [N m]
P_CL_WS = 26  # clutch slip speed of the friction build-up [rad/s]
P_CL_VISC = 27  # clutch oil-film drag [N m s/rad]
P_BL_HALF = 28  # half the free play of the first rig shaft [rad]
# 29, 30: unused (held the massless third inner stage that the short nested pair replaced)
P_TD_C = 31  # turbine drag against the housing [N m s/rad]
P_PA_DOF = 32  # DOF index of the pendulum absorber (-1: none)
P_PA_K = 33  # pendulum restoring stiffness J_a (n Omega0)^2 [N m/rad]
P_PA_C = 34  # pendulum damping [N m s/rad]
P_NRT = 35  # share of the nested inner spring's normal force loading the outer spring
P_FR_SCHEME = 36  # friction scheme (kernels.friction.SCHEME_*)
P_FR_TOL = 37  # Newton tolerance of the friction law [-] (friction coefficient units)
P_FR_ITER = 38  # Newton re-solves of the friction step
P_SIZE = 39

#: solver.friction_scheme names -> P[P_FR_SCHEME] codes (kernels.friction.SCHEME_*)
FRICTION_SCHEMES = {"trapezoidal": 0, "backward-euler": 1, "fitted": 2}

# --- spring table SF (float) and SI (int), one row per integrated spring --------------
F_KSEG = 0  # segment stiffness k_seg = N k_spring [N m/rad]
F_PHISEG = 1  # relaxed segment arc [rad]
F_BLOCK = 2  # block (coil-bound) arc of one segment [rad]
F_MASS = 3  # mass of one node [kg] (one spring)
F_REFF = 4  # effective radius [m]
F_NW = 5  # coils per segment [-]
F_PRELOAD = 6  # radial preload per mass [N]
F_COUNT = 7  # number of identical springs represented
F_PITCH = 8  # stopper pitch 2 pi / nS [rad]
F_PHIPS = 9  # stopper half width of body A [rad]
F_PHISS = 10  # stopper half width of body B [rad]
NF = 11

I_A = 0  # body before the set
I_N = 1  # segments
I_OFF = 2  # DOF index of the first mass (node 1)
I_NODE = 3  # offset of node 0 in the node scratch / record arrays
NI = 4

# --- record columns: one row of the integrator's record per stored sample -------------
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
R_E_HS = 22  # hardstop contacts' share of R_E_DAMP (their damping) [J]
NREC = 23

# --- integrator state besides (q, v), carried from step to step (vector S) -------------
S_Z = 0  # PI state of the output motor: minus its angle, the integral of -v_motor [rad]
S_E_IN = 1  # work of the input torque [J]
S_E_MOTOR = 2  # work of the output motor [J]
S_E_FRIC = 3  # friction dissipation [J]
S_E_DAMP = 4  # viscous dissipation [J]
S_E_STACK = 5  # energy removed by coil-stacking contacts [J]
S_E_HS = 6  # hardstop contacts' share of S_E_DAMP [J]
S_SIZE = 7


@dataclass(frozen=True)
class SpringInfo:
    """Where one integrated spring lives in the arrays (for results and plots)."""

    name: str
    set_name: str
    segments: int
    first_dof: int
    first_node: int


@dataclass(frozen=True)
class Layout:
    """All arrays the kernel needs, built once per (parameters, speed)."""

    P: np.ndarray
    SF: np.ndarray
    SI: np.ndarray
    J: np.ndarray
    contacts_idx: np.ndarray  # (nc, 2) int: [mass dof, housing dof]
    contacts_f: np.ndarray  # (nc, 2) float: [alpha x housing weight, friction radius]
    singles: np.ndarray  # (n, 2) int: [mass, contact]
    pairs: np.ndarray  # (n, 5) int: [outer mass, inner mass|-1, contact sec|-1, ter|-1, inner|-1]
    rig: np.ndarray  # (nrig, 3) float: [shaft K, shaft B_k, inertia damping B_j]
    dof_names: tuple
    springs: tuple
    n_nodes: int
    rig_names: tuple

    @property
    def ndof(self) -> int:
        return len(self.J)


def build_layout(system: DamperSystem, omega0: float) -> Layout:
    """Flatten ``system`` at nominal speed ``omega0`` [rad/s] into kernel arrays."""
    s = system
    fr = s.friction
    names = ["primary", "secondary", "tertiary"]
    J = [s.inertias.primary, s.inertias.secondary, s.inertias.tertiary]
    SF, SI, springs, contacts_idx, contacts_f = [], [], [], [], []
    n_nodes = 0

    def add_spring(name, set_name, a_body, spring_set, spring, n_seg, count):
        nonlocal n_nodes
        first = len(J)
        row = np.zeros(NF)
        row[F_KSEG] = n_seg * spring.stiffness
        row[F_PHISEG] = spring.arc / n_seg
        row[F_BLOCK] = spring.active_coils * spring.wire_thickness / spring.effective_radius / n_seg
        row[F_MASS] = spring.mass / (n_seg - 1)
        row[F_REFF] = spring.effective_radius
        row[F_NW] = spring.active_coils / n_seg
        row[F_COUNT] = count
        row[F_PITCH] = spring_set.pitch
        row[F_PHIPS] = spring_set.primary_stopper_half_width
        row[F_PHISS] = spring_set.secondary_stopper_half_width
        irow = np.array([a_body, n_seg, first, n_nodes], dtype=np.int64)
        for i in range(1, n_seg):
            names.append(f"{name}[{i}]")
            J.append(count * row[F_MASS] * spring.effective_radius**2)
        SF.append(row)
        SI.append(irow)
        springs.append(SpringInfo(name, set_name, n_seg, first, n_nodes))
        n_nodes += n_seg + 1
        return len(SF) - 1, first

    no, ni = s.solver.outer_segments, s.solver.inner_segments
    # effect spring_preload adds its radial preload to every spring mass
    extra = s.effects.spring_preload.force if s.effects.spring_preload.enabled else 0.0
    i_o, first_o = add_spring("outer", "outer", PRI, s.outer, s.outer.spring, no, s.outer.count)
    SF[i_o][F_PRELOAD] = fr.outer.preload + extra
    # effect inner_short_springs: n_short of the pairs hold a shorter inner spring
    # (docs/model.md §4); both pair designs get a representative pair of their own
    n_short = s.short_pairs
    pair_designs = [("pair", s.inner.spring, s.inner.nested, s.inner.count - n_short)]
    if n_short > 0:
        short = s.effects.inner_short_springs.spring(s.inner)
        pair_designs.append(("short_pair", s.inner.spring, short, n_short))
    pair_firsts = []  # (outer first mass, inner first mass or -1, inner spring or None)
    for prefix, outer_sp, inner_sp, count in pair_designs:
        i_po, first_po = add_spring(f"{prefix}_outer", "inner", SEC, s.inner, outer_sp, ni, count)
        SF[i_po][F_PRELOAD] = fr.pair_outer.preload + extra
        first_pi = -1
        if inner_sp is not None:
            i_pi, first_pi = add_spring(f"{prefix}_inner", "inner", SEC, s.inner, inner_sp, ni, count)
            SF[i_pi][F_PRELOAD] = fr.pair_inner.preload + extra
        pair_firsts.append((first_po, first_pi, inner_sp))

    singles = []  # [mass, contact]: a spring mass rubbing on one body
    pairs = []  # [outer mass, inner mass or -1, contact on J_sec, on J_ter, inner on outer]

    def add_contact(mass, housing, weight, radius):
        if weight <= 0:
            return -1
        contacts_idx.append((mass, housing))
        contacts_f.append((weight, radius))
        return len(contacts_idx) - 1

    if fr.enabled:
        # [thesis] §5.3.1/§5.4: outer springs rub on J_sec's race only.
        for i in range(no - 1):
            c = add_contact(first_o + i, SEC, fr.outer.alpha, s.outer.spring.friction_radius)
            if c >= 0:
                singles.append((first_o + i, c))
        # Nested pair outer spring rubs on the housing made of J_sec and J_ter parts; we
        # compute each part's friction with its own slip speed and weight it by alpha_sec /
        # alpha_ter (the thesis weights one friction torque computed against J_sec).
        # The inner spring of the pair rubs on the outer spring's mass of the same index
        # (Eq. 25-26); the two masses are solved together. The short pair's contacts are
        # the normal pair's: same law, tuning factors and radii (docs/model.md §4).
        r_po = s.inner.spring.friction_radius
        for first_po, first_pi, inner_sp in pair_firsts:
            for i in range(ni - 1):
                c_sec = add_contact(first_po + i, SEC, fr.pair_outer.alpha * fr.alpha_sec, r_po)
                c_ter = add_contact(first_po + i, TER, fr.pair_outer.alpha * fr.alpha_ter, r_po)
                c_in, m2 = -1, -1
                if inner_sp is not None:
                    m2 = first_pi + i
                    c_in = add_contact(m2, first_po + i, fr.pair_inner.alpha, inner_sp.friction_radius)
                if max(c_sec, c_ter, c_in) >= 0:
                    pairs.append((first_po + i, m2, c_sec, c_ter, c_in))

    rig_names = []
    rig = []
    rig0 = len(J)
    for e in s.rig.elements:
        names.append(e.name)
        rig_names.append(e.name)
        J.append(e.inertia)
        rig.append((e.shaft_stiffness, e.shaft_damping, e.inertia_damping))
    trans = rig0 + rig_names.index(s.rig.output_transducer)
    motor = len(J) - 1
    input_dof, pa_dof = _add_effect_dofs(s, omega0, names, J)

    P = np.zeros(P_SIZE)
    P[P_OMEGA0] = omega0
    P[P_DT] = s.solver.time_step
    P[P_G1:P_G6 + 1] = (fr.gamma1, fr.gamma2, fr.gamma3, fr.gamma4, fr.gamma5, fr.gamma6)
    P[P_HS_ON] = 1.0 if s.hardstops.enabled else 0.0
    P[P_HS_K] = s.hardstops.stiffness
    P[P_HS_D] = s.hardstops.damping
    P[P_HSP_O] = s.outer.hardstop_positive
    P[P_HSN_O] = s.outer.hardstop_negative
    P[P_HSP_I] = s.inner.hardstop_positive
    P[P_HSN_I] = s.inner.hardstop_negative
    P[P_KP] = s.motor.proportional_gain
    P[P_KI] = s.motor.integral_gain
    P[P_HELD] = 1.0 if s.motor.mode == "held" else 0.0
    P[P_NRIG] = len(rig)
    P[P_RIG0] = rig0
    P[P_TRANS] = trans
    P[P_VMAX] = 50.0 * max(abs(omega0), 100.0) + 5000.0
    P[P_MOTOR] = motor
    P[P_INPUT] = input_dof
    P[P_PA_DOF] = pa_dof
    P[P_FR_SCHEME] = FRICTION_SCHEMES[s.solver.friction_scheme]
    P[P_FR_TOL] = s.solver.friction_tolerance
    P[P_FR_ITER] = s.solver.friction_iterations
    _effect_slots(s, omega0, P)
    return Layout(
        P=P,
        SF=np.array(SF, dtype=np.float64),
        SI=np.array(SI, dtype=np.int64),
        J=np.array(J, dtype=np.float64),
        contacts_idx=np.array(contacts_idx, dtype=np.int64).reshape(-1, 2),
        contacts_f=np.array(contacts_f, dtype=np.float64).reshape(-1, 2),
        singles=np.array(singles, dtype=np.int64).reshape(-1, 2),
        pairs=np.array(pairs, dtype=np.int64).reshape(-1, 5),
        rig=np.array(rig, dtype=np.float64).reshape(-1, 3),
        dof_names=tuple(names),
        springs=tuple(springs),
        n_nodes=n_nodes,
        rig_names=tuple(rig_names),
    )


def _add_effect_dofs(s: DamperSystem, omega0: float, names: list, J: list) -> tuple[int, int]:
    """Append the DOFs of enabled effects after the rig; returns (input DOF, pendulum DOF|-1).

    clutch_slip splits J_pri: the engine-side share (cover, pump) becomes the clutch drive
    DOF that takes the input torque; the rest (clutch plate, drive ring) stays J_pri.
    """
    eff = s.effects
    input_dof, pa_dof = PRI, -1
    if eff.clutch_slip.enabled:
        f = eff.clutch_slip.drive_inertia_fraction
        J[PRI] = (1.0 - f) * s.inertias.primary
        names.append("clutch_drive")
        J.append(f * s.inertias.primary)
        input_dof = len(J) - 1
    if eff.pendulum_absorber.enabled:
        names.append("pendulum")
        J.append(eff.pendulum_absorber.inertia)
        pa_dof = len(J) - 1
    return input_dof, pa_dof


def _effect_slots(s: DamperSystem, omega0: float, P: np.ndarray) -> None:
    """Fill the P slots of the optional effects (zeros leave an effect off)."""
    eff = s.effects
    if eff.clutch_slip.enabled:
        P[P_CL_ON] = 1.0
        P[P_CL_CAP] = eff.clutch_slip.capacity
        P[P_CL_WS] = eff.clutch_slip.slip_speed
        P[P_CL_VISC] = eff.clutch_slip.viscous
    if eff.output_backlash.enabled:
        P[P_BL_HALF] = 0.5 * eff.output_backlash.free_play
    if eff.turbine_drag.enabled:
        P[P_TD_C] = eff.turbine_drag.coefficient
    if eff.pendulum_absorber.enabled:
        pa = eff.pendulum_absorber
        P[P_PA_K] = pa.inertia * (pa.order * omega0) ** 2
        P[P_PA_C] = pa.damping
    if eff.nested_radial_transfer.enabled and s.inner.nested is not None:
        P[P_NRT] = eff.nested_radial_transfer.fraction


def initial_state(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """Unloaded start: bodies at zero angle and zero relative speed; each spring's masses
    spread evenly over the arc the spring occupies (its free arc, or the slot when the
    slot is shorter, i.e. preloaded), centred in the slot."""
    q = np.zeros(layout.ndof)
    v = np.zeros(layout.ndof)
    for k in range(len(layout.SF)):
        row, irow = layout.SF[k], layout.SI[k]
        n = int(irow[I_N])
        slot_lo = max(row[F_PHIPS], row[F_PHISS])
        slot_hi = row[F_PITCH] - slot_lo
        length = min(n * row[F_PHISEG], slot_hi - slot_lo)
        x0 = 0.5 * (slot_lo + slot_hi) - 0.5 * length
        for i in range(1, n):
            x = x0 + i * length / n
            q[irow[I_OFF] + i - 1] = q[int(irow[I_A])] - x
    return q, v
