"""A slow, readable NumPy reference of the damper equations (docs/model.md §2-6).

It is written from the specification, not from the kernel: objects and plain loops, no
numba, no flattened tables. The kernel's right-hand side must agree with it.

State convention (the documented DOF order of :mod:`dampersim.solver.layout`):
J_pri, J_sec, J_ter; the N_o-1 outer-spring masses; the N_i-1 masses of the nested
pair's outer spring; the N_i-1 masses of its inner spring; with effect
inner_short_springs the same two groups again for the pair with a short inner spring;
the rig elements (motor last); then, when enabled, the clutch drive side (effect
clutch_slip) and the pendulum absorber (effect pendulum_absorber). Angles are taken in a
frame turning at Omega0, speeds relative to Omega0.

Short inner springs (docs/model.md §4): ``count`` of the nS pairs hold an
inner spring shorter than the slot by the clearance. Each pair design is one
representative pair standing for its own number of pairs (nS - count and count), with
its own masses and friction; the short spring touches a stopper only as a free end.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np


def makkar(v, g):
    """Friction coefficient at slip speed v [m/s] ([thesis] Eq. 27)."""
    g1, g2, g3, g4, g5, g6 = g
    return g1 * (np.tanh(g2 * v) - np.tanh(g3 * v)) + g4 * np.tanh(g5 * v) + g6 * v


class Spring:
    """One representative spring of a set between body A (index a) and body B (a+1)."""

    def __init__(self, spring, spring_set, n_seg, a, first_dof, preload, count=None):
        self.k_seg = n_seg * spring.stiffness
        self.phi_seg = spring.arc / n_seg
        self.mass = spring.mass / (n_seg - 1)
        self.r_eff = spring.effective_radius
        self.n_w = spring.active_coils / n_seg
        self.count = spring_set.count if count is None else count
        self.pitch = 2 * math.pi / spring_set.count
        self.phi_ps = spring_set.primary_stopper_half_width
        self.phi_ss = spring_set.secondary_stopper_half_width
        self.n = n_seg
        self.a = a
        self.b = a + 1
        self.dofs = list(range(first_dof, first_dof + n_seg - 1))
        self.preload = preload

    def nodes(self, q):
        """Slot coordinates x of the N+1 nodes: x = angle of A minus node angle."""
        x = np.empty(self.n + 1)
        x[1:self.n] = q[self.a] - q[self.dofs]
        w = q[self.a] - q[self.b]
        x[0] = max(self.phi_ps, w + self.phi_ss, x[1] - self.phi_seg)
        x[self.n] = min(self.pitch - self.phi_ps, w + self.pitch - self.phi_ss, x[self.n - 1] + self.phi_seg)
        return x

    def segment_torques(self, q):
        """Torque of each segment, positive in compression (docs/model.md §3)."""
        x = self.nodes(q)
        return self.k_seg * (self.phi_seg - np.diff(x)), np.diff(x)

    def apply(self, q, v, omega0, torque, normal):
        """Add this set's spring torques (count springs) to ``torque`` and the normal
        force on each mass (count springs) to ``normal``."""
        t, seg = self.segment_torques(q)
        # torques on the masses (theta direction): T_j - T_{j-1} for the mass at node j
        for j in range(1, self.n):
            torque[self.dofs[j - 1]] += self.count * (t[j] - t[j - 1])
        # the end nodes press on the stopper they touch
        w = q[self.a] - q[self.b]
        for end, sign, face_a, face_b in (
            (0, +1.0, self.phi_ps, w + self.phi_ss),
            (self.n - 1, -1.0, self.pitch - self.phi_ps, w + self.pitch - self.phi_ss),
        ):
            f = sign * self.count * t[end]
            ahead_b = face_b > face_a if end == 0 else face_b < face_a
            if face_a == face_b:
                torque[self.a] += 0.5 * f
                torque[self.b] += 0.5 * f
            elif ahead_b:
                torque[self.b] += f
            else:
                torque[self.a] += f
        # radial forces: centrifugal, redirection (Eq. 21-24), preload
        f_defl = np.where(t > 0, t / self.r_eff * 2 * self.n_w * np.sin(seg / (2 * self.n_w)), 0.0)
        for j in range(1, self.n):
            share_left = 1.0 if j == 1 else 0.5
            share_right = 1.0 if j == self.n - 1 else 0.5
            f_red = share_left * f_defl[j - 1] + share_right * f_defl[j]
            om = omega0 + v[self.dofs[j - 1]]
            normal[self.dofs[j - 1]] = self.count * (self.mass * self.r_eff * om**2 + f_red + self.preload)


def accelerations(system, omega0, q, v, z, tin):
    """Accelerations [rad/s^2] of all DOFs, friction explicit; motor held -> 0."""
    s = system
    ef = s.effects
    no, ni = s.solver.outer_segments, s.solver.inner_segments
    extra = ef.spring_preload.force if ef.spring_preload.enabled else 0.0
    springs = [Spring(s.outer.spring, s.outer, no, 0, 3, s.friction.outer.preload + extra)]
    short = ef.inner_short_springs
    n_short = short.count if short.enabled and s.inner.nested is not None else 0
    n_normal = s.inner.count - n_short
    po = Spring(s.inner.spring, s.inner, ni, 1, 3 + no - 1, s.friction.pair_outer.preload + extra, n_normal)
    springs.append(po)
    pi_ = None
    if s.inner.nested is not None:
        pi_ = Spring(s.inner.nested, s.inner, ni, 1, 3 + no - 1 + ni - 1, s.friction.pair_inner.preload + extra,
                     n_normal)
        springs.append(pi_)
    pairs = [(po, pi_)]  # (outer of pair, inner of pair or None) per pair design
    if n_short > 0:
        # the short inner spring: the nested spring's coil (radii, wire) with the effect's
        # rate, mass and coils; free arc = the slot between the stoppers at zero windup
        # minus the clearance
        pitch = 2 * math.pi / s.inner.count
        slot = pitch - 2 * max(s.inner.primary_stopper_half_width, s.inner.secondary_stopper_half_width)
        short_spring = SimpleNamespace(
            stiffness=short.stiffness, arc=slot - short.clearance, mass=short.mass,
            effective_radius=s.inner.nested.effective_radius, active_coils=short.active_coils,
        )
        first = springs[-1].dofs[-1] + 1
        spo = Spring(s.inner.spring, s.inner, ni, 1, first, s.friction.pair_outer.preload + extra, n_short)
        spi = Spring(short_spring, s.inner, ni, 1, first + ni - 1, s.friction.pair_inner.preload + extra, n_short)
        springs += [spo, spi]
        pairs.append((spo, spi))
    rig0 = springs[-1].dofs[-1] + 1
    elements = s.rig.elements
    motor = rig0 + len(elements) - 1
    n = motor + 1
    drive = pend = None
    if ef.clutch_slip.enabled:
        drive, n = n, n + 1
    if ef.pendulum_absorber.enabled:
        pend, n = n, n + 1
    assert len(q) == n
    inertia = np.zeros(n)
    inertia[:3] = [s.inertias.primary, s.inertias.secondary, s.inertias.tertiary]
    if drive is not None:
        inertia[drive] = ef.clutch_slip.drive_inertia_fraction * s.inertias.primary
        inertia[0] -= inertia[drive]
    if pend is not None:
        inertia[pend] = ef.pendulum_absorber.inertia
    for sp in springs:
        inertia[sp.dofs] = sp.count * sp.mass * sp.r_eff**2
    torque = np.zeros(n)
    normal = np.zeros(n)
    for sp in springs:
        sp.apply(q, v, omega0, torque, normal)
    if ef.nested_radial_transfer.enabled:
        # the inner spring presses on the outer spring of its pair ([thesis] §5.3.2)
        for outer_of_pair, inner_of_pair in pairs:
            if inner_of_pair is not None:
                for do, di in zip(outer_of_pair.dofs, inner_of_pair.dofs):
                    normal[do] += ef.nested_radial_transfer.fraction * normal[di]
    # hardstops: one-sided stiff damped contact on each set's windup
    if s.hardstops.enabled:
        for a, st in ((0, s.outer), (1, s.inner)):
            w = q[a] - q[a + 1]
            pen = 0.0
            if w > st.hardstop_positive:
                pen = w - st.hardstop_positive
            elif w < st.hardstop_negative:
                pen = w - st.hardstop_negative
            if pen != 0.0:
                t = s.hardstops.stiffness * pen + s.hardstops.damping * (v[a] - v[a + 1])
                if t * pen < 0:
                    t = 0.0
                torque[a] -= t
                torque[a + 1] += t
    # rig chain: each shaft joins an element to the body before it (Eq. 34-35)
    for e, el in enumerate(elements):
        d = rig0 + e
        p = 2 if e == 0 else d - 1
        inertia[d] = el.inertia
        dq = q[p] - q[d]
        if e == 0 and ef.output_backlash.enabled:  # free play: no torque inside the band
            half = 0.5 * ef.output_backlash.free_play
            dq = float(np.sign(dq) * max(abs(dq) - half, 0.0))
        t = el.shaft_stiffness * dq + (el.shaft_damping * (v[p] - v[d]) if dq != 0.0 else 0.0)
        torque[p] -= t
        torque[d] += t
        torque[d] -= el.inertia_damping * (omega0 + v[d])
    housing = 0 if drive is None else drive
    torque[housing] += tin
    if drive is not None:  # lock-up clutch: Coulomb (smoothed) plus oil drag
        cl = ef.clutch_slip
        slip = v[drive] - v[0]
        t = cl.capacity * np.tanh(slip / cl.slip_speed) + cl.viscous * slip
        torque[drive] -= t
        torque[0] += t
    if ef.turbine_drag.enabled:
        t = ef.turbine_drag.coefficient * (v[housing] - v[1])
        torque[1] += t
        torque[housing] -= t
    if pend is not None:
        pa = ef.pendulum_absorber
        t = pa.inertia * (pa.order * omega0) ** 2 * (q[1] - q[pend]) + pa.damping * (v[1] - v[pend])
        torque[1] -= t
        torque[pend] += t
    if s.motor.mode == "pi":
        torque[motor] += -s.motor.proportional_gain * v[motor] + s.motor.integral_gain * z
    # friction (Eq. 27-28)
    if s.friction.enabled:
        fr = s.friction
        g = (fr.gamma1, fr.gamma2, fr.gamma3, fr.gamma4, fr.gamma5, fr.gamma6)

        def rub(mass, housing, alpha, r):
            t = alpha * makkar((v[mass] - v[housing]) * r, g) * normal[mass] * r
            torque[mass] -= t
            torque[housing] += t

        for d in springs[0].dofs:
            rub(d, 1, fr.outer.alpha, s.outer.spring.friction_radius)
        # every pair design rubs alike: its outer spring on the J_sec/J_ter housing, its
        # inner spring (on the nested spring's friction radius) on its own outer spring
        for outer_of_pair, inner_of_pair in pairs:
            for i, d in enumerate(outer_of_pair.dofs):
                rub(d, 1, fr.pair_outer.alpha * fr.alpha_sec, s.inner.spring.friction_radius)
                rub(d, 2, fr.pair_outer.alpha * fr.alpha_ter, s.inner.spring.friction_radius)
                if inner_of_pair is not None:
                    rub(inner_of_pair.dofs[i], d, fr.pair_inner.alpha, s.inner.nested.friction_radius)
    acc = torque / inertia
    if s.motor.mode == "held":
        acc[motor] = 0.0
    return acc
