"""The reference equations of :mod:`tests.reference.reference_model`, compiled, for stiff
integration with scipy (issue 14, item 4: an independent check of the production
integrator).

The slow NumPy reference costs about 0.3 ms per evaluation; an implicit scipy integration
of an order-analysis window needs millions of evaluations (finite-difference Jacobians
included), so the same equations are written here again as plain loops over plain arrays
and compiled with numba. They are transcribed from :func:`reference_model.accelerations`
(docs/model.md §2-6), not from the production kernels (:mod:`dampersim.solver.kernels`):
no shared code, no shared tables, exact ``math.tanh`` and ``math.sin`` where the kernels
use polynomials, friction explicit (as a smooth right-hand side; the regularised Makkar
law, [thesis] Eq. 27, has no stick/slip events). ``tests/reference/test_production_vs_reference.py``
checks that it equals the slow reference on random states.

Scope: the default model without optional effects. Not modelled: coil stacking
(docs/model.md §3); callers must stay where it does not occur (the production run's
stacking energy stays zero) and say so.

State vector y = (q [rad], v [rad/s], z [rad]): angles and speeds of all DOFs in the
frame turning at Omega0 (the DOF order of :mod:`tests.reference.reference_model`), and
the output motor's PI state z (dz/dt = -v_motor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# columns of the spring table SP (one row per integrated spring)
_KSEG, _PHISEG, _MASS, _REFF, _NW, _COUNT, _PITCH, _PHIPS, _PHISS, _PRELOAD = range(10)
# columns of the integer spring table SPI: body A, segments, first mass DOF
_A, _N, _FIRST = range(3)


@dataclass(frozen=True)
class CompiledReference:
    """Arrays of the reference equations for one parameter set and nominal speed.

    omega0 [rad/s]; inertia [kg m^2] per DOF; SP/SPI: spring tables; FR: friction
    contacts (mass DOF, housing DOF, alpha x housing weight [-], radius [m]); GAM: Makkar
    coefficients; HS: (on, stiffness [N m/rad], damping [N m s/rad], outer +/- limit,
    inner +/- limit [rad]); RIG: (prev DOF, DOF, K [N m/rad], B_k [N m s/rad], B_j
    [N m s/rad]) per rig element; motor: (held 0/1, DOF, k_p, k_i); orders: (k [-], A [N m],
    phase [rad]) of the input; mean torque [N m]; transducer: index of its rig row.
    """

    omega0: float
    inertia: np.ndarray
    SP: np.ndarray
    SPI: np.ndarray
    FR: np.ndarray
    GAM: np.ndarray
    HS: np.ndarray
    RIG: np.ndarray
    motor: np.ndarray
    orders: np.ndarray
    mean_torque: float
    transducer: int
    steady_start: float

    @property
    def ndof(self) -> int:
        return len(self.inertia)

    def input_torque(self, t: float) -> float:
        """Steady input torque [N m] at time t [s] (docs/model.md §7, order sum)."""
        return _tin(t, self.omega0, self.mean_torque, self.orders)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt at time t [s] (t must lie in the steady part of the excitation)."""
        return _rhs(t, y, self.omega0, self.inertia, self.SP, self.SPI, self.FR, self.GAM, self.HS, self.RIG,
                    self.motor, self.mean_torque, self.orders)

    def output_torque(self, Y: np.ndarray) -> np.ndarray:
        """Torque [N m] in the output transducer's shaft ([thesis] §6.2.1, docs/model.md §2)
        for states Y of shape (2 ndof + 1, samples)."""
        n = self.ndof
        p, d, k, bk, _ = self.RIG[self.transducer]
        p, d = int(p), int(d)
        return k * (Y[p] - Y[d]) + bk * (Y[n + p] - Y[n + d])

    @staticmethod
    def windups(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Outer and inner windup [rad] (docs/model.md §1) for states Y."""
        return Y[0] - Y[1], Y[1] - Y[2]


def build(system, omega0: float, excitation) -> CompiledReference:
    """The reference arrays of ``system`` at ``omega0`` [rad/s], driven by the order sum
    ``excitation`` in its steady part. Written from the parameter set (as
    :func:`reference_model.accelerations` is), not from :mod:`dampersim.solver.layout`."""
    s = system
    ef = s.effects
    on = [name for name in ("clutch_slip", "output_backlash", "inner_short_springs", "turbine_drag",
                            "pendulum_absorber", "nested_radial_transfer", "spring_preload", "transducer_bandwidth")
          if getattr(ef, name).enabled]
    if on:
        raise ValueError(f"the compiled reference has no optional effects; enabled: {on}")
    if s.inner.nested is None:
        raise ValueError("the compiled reference needs the nested inner spring")
    no, ni = s.solver.outer_segments, s.solver.inner_segments
    specs = [  # spring, its set, segments, body A, first mass DOF, radial preload
        (s.outer.spring, s.outer, no, 0, 3, s.friction.outer.preload),
        (s.inner.spring, s.inner, ni, 1, 3 + no - 1, s.friction.pair_outer.preload),
        (s.inner.nested, s.inner, ni, 1, 3 + no - 1 + ni - 1, s.friction.pair_inner.preload),
    ]
    SP = np.zeros((3, 10))
    SPI = np.zeros((3, 3), dtype=np.int64)
    rig0 = 3 + no - 1 + 2 * (ni - 1)
    n = rig0 + len(s.rig.elements)
    inertia = np.zeros(n)
    inertia[:3] = (s.inertias.primary, s.inertias.secondary, s.inertias.tertiary)
    for i, (spring, sset, nseg, a, first, pre) in enumerate(specs):
        SP[i] = (nseg * spring.stiffness, spring.arc / nseg, spring.mass / (nseg - 1), spring.effective_radius,
                 spring.active_coils / nseg, sset.count, 2 * math.pi / sset.count, sset.primary_stopper_half_width,
                 sset.secondary_stopper_half_width, pre)
        SPI[i] = (a, nseg, first)
        inertia[first:first + nseg - 1] = sset.count * SP[i, _MASS] * spring.effective_radius ** 2
    fr = s.friction
    rows = []
    if fr.enabled:
        for d in range(3, 3 + no - 1):
            rows.append((d, 1, fr.outer.alpha, s.outer.spring.friction_radius))
        for i in range(ni - 1):
            d = 3 + no - 1 + i
            di = d + ni - 1
            rows.append((d, 1, fr.pair_outer.alpha * fr.alpha_sec, s.inner.spring.friction_radius))
            rows.append((d, 2, fr.pair_outer.alpha * fr.alpha_ter, s.inner.spring.friction_radius))
            rows.append((di, d, fr.pair_inner.alpha, s.inner.nested.friction_radius))
    FR = np.array(rows, dtype=np.float64).reshape(-1, 4)
    GAM = np.array([fr.gamma1, fr.gamma2, fr.gamma3, fr.gamma4, fr.gamma5, fr.gamma6])
    HS = np.array([1.0 if s.hardstops.enabled else 0.0, s.hardstops.stiffness, s.hardstops.damping,
                   s.outer.hardstop_positive, s.outer.hardstop_negative,
                   s.inner.hardstop_positive, s.inner.hardstop_negative])
    RIG = np.zeros((len(s.rig.elements), 5))
    names = []
    for e, el in enumerate(s.rig.elements):
        d = rig0 + e
        RIG[e] = (2 if e == 0 else d - 1, d, el.shaft_stiffness, el.shaft_damping, el.inertia_damping)
        inertia[d] = el.inertia
        names.append(el.name)
    motor = np.array([1.0 if s.motor.mode == "held" else 0.0, n - 1, s.motor.proportional_gain,
                      s.motor.integral_gain])
    orders = np.array([(k, a, ph) for k, a, ph in excitation.orders], dtype=np.float64).reshape(-1, 3)
    return CompiledReference(
        omega0=float(omega0), inertia=inertia, SP=SP, SPI=SPI, FR=FR, GAM=GAM, HS=HS, RIG=RIG, motor=motor,
        orders=orders, mean_torque=float(excitation.mean_torque), transducer=names.index(s.rig.output_transducer),
        steady_start=float(excitation.steady_start),
    )


@njit(cache=True)
def _tin(t, omega0, mean, orders):
    """T_in(t) = T_mean + sum_k A_k cos(k Omega0 t + phi_k) [N m] (docs/model.md §7)."""
    x = mean
    for i in range(orders.shape[0]):
        x += orders[i, 1] * math.cos(orders[i, 0] * omega0 * t + orders[i, 2])
    return x


@njit(cache=True)
def _makkar(v, g):
    """Makkar friction coefficient at slip speed v [m/s] ([thesis] Eq. 27)."""
    return g[0] * (math.tanh(g[1] * v) - math.tanh(g[2] * v)) + g[3] * math.tanh(g[4] * v) + g[5] * v


@njit(cache=True)
def _rhs(t, y, omega0, inertia, SP, SPI, FR, GAM, HS, RIG, motor, mean, orders):
    n = inertia.shape[0]
    q = y[:n]
    v = y[n:2 * n]
    z = y[2 * n]
    torque = np.zeros(n)
    normal = np.zeros(n)
    for s in range(SP.shape[0]):
        a = SPI[s, _A]
        b = a + 1
        nseg = SPI[s, _N]
        first = SPI[s, _FIRST]
        kseg = SP[s, _KSEG]
        phiseg = SP[s, _PHISEG]
        count = SP[s, _COUNT]
        reff = SP[s, _REFF]
        nw = SP[s, _NW]
        pitch = SP[s, _PITCH]
        phips = SP[s, _PHIPS]
        phiss = SP[s, _PHISS]
        # slot coordinates of the N+1 nodes (docs/model.md §3, [thesis] Eq. 16-18)
        x = np.empty(nseg + 1)
        for j in range(1, nseg):
            x[j] = q[a] - q[first + j - 1]
        w = q[a] - q[b]
        x[0] = max(phips, max(w + phiss, x[1] - phiseg))
        x[nseg] = min(pitch - phips, min(w + pitch - phiss, x[nseg - 1] + phiseg))
        # segment torques, positive in compression ([thesis] Eq. 15, sign fixed)
        tseg = np.empty(nseg)
        defl = np.empty(nseg)
        for j in range(nseg):
            seg = x[j + 1] - x[j]
            tseg[j] = kseg * (phiseg - seg)
            # redirection force of a compressed segment ([thesis] Eq. 21)
            defl[j] = tseg[j] / reff * 2.0 * nw * math.sin(seg / (2.0 * nw)) if tseg[j] > 0.0 else 0.0
        for j in range(1, nseg):
            torque[first + j - 1] += count * (tseg[j] - tseg[j - 1])
        # end nodes push on the stopper they rest on (half each when both faces coincide)
        fa = phips
        fb = w + phiss
        f = count * tseg[0]
        if fa == fb:
            torque[a] += 0.5 * f
            torque[b] += 0.5 * f
        elif fb > fa:
            torque[b] += f
        else:
            torque[a] += f
        fa = pitch - phips
        fb = w + pitch - phiss
        f = -count * tseg[nseg - 1]
        if fa == fb:
            torque[a] += 0.5 * f
            torque[b] += 0.5 * f
        elif fb < fa:
            torque[b] += f
        else:
            torque[a] += f
        # normal force: centrifugal + redirection (half of each neighbour, end segments
        # fully) + preload ([thesis] Eq. 19-24)
        for j in range(1, nseg):
            left = 1.0 if j == 1 else 0.5
            right = 1.0 if j == nseg - 1 else 0.5
            om = omega0 + v[first + j - 1]
            normal[first + j - 1] = count * (SP[s, _MASS] * reff * om * om + left * defl[j - 1] + right * defl[j]
                                             + SP[s, _PRELOAD])
    # hardstops: one-sided stiff damped contact on each set's windup (docs/model.md §6)
    if HS[0] > 0.0:
        for st in range(2):
            w = q[st] - q[st + 1]
            pen = 0.0
            if w > HS[3 + 2 * st]:
                pen = w - HS[3 + 2 * st]
            elif w < HS[4 + 2 * st]:
                pen = w - HS[4 + 2 * st]
            if pen != 0.0:
                tc = HS[1] * pen + HS[2] * (v[st] - v[st + 1])
                if tc * pen < 0.0:
                    tc = 0.0
                torque[st] -= tc
                torque[st + 1] += tc
    # rig chain ([thesis] Eq. 34-35)
    for e in range(RIG.shape[0]):
        p = int(RIG[e, 0])
        d = int(RIG[e, 1])
        ts = RIG[e, 2] * (q[p] - q[d]) + RIG[e, 3] * (v[p] - v[d])
        torque[p] -= ts
        torque[d] += ts
        torque[d] -= RIG[e, 4] * (omega0 + v[d])
    torque[0] += _tin(t, omega0, mean, orders)
    m = int(motor[1])
    held = motor[0] > 0.0
    if not held:
        torque[m] += -motor[2] * v[m] + motor[3] * z
    # friction ([thesis] Eq. 27-28), explicit: opposes the slip, reaction on the housing
    for c in range(FR.shape[0]):
        mass = int(FR[c, 0])
        hous = int(FR[c, 1])
        r = FR[c, 3]
        tf = FR[c, 2] * _makkar((v[mass] - v[hous]) * r, GAM) * normal[mass] * r
        torque[mass] -= tf
        torque[hous] += tf
    out = np.empty(2 * n + 1)
    for i in range(n):
        out[i] = v[i]
        out[n + i] = torque[i] / inertia[i]
    if held:
        out[n + m] = 0.0
    out[2 * n] = -v[m]
    return out
