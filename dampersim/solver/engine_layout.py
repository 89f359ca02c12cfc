"""Flatten a :class:`PulsationGenerator` into the arrays of ``_kernels.engine_integrate``.

Chain DOFs (angles relative to a frame turning at the nominal speed, model-spec §1), in
power-flow order: input dyno, ROBA coupling, crank sections 1-4, flange, transducer.
Cylinders 1-4 sit on crank sections 1-4 with throws at 0, 180, 180 and 0 deg
(inline four); each compresses once per revolution (valves deactivated, [thesis] §4.1).

Coupled mode (model-spec §2, input chain of the rig mode of [thesis] §4.2): the
transducer's shaft drives J_pri of the damper and rig. The damper side enters as its
linearised model (:func:`dampersim.solver.linear.linearise`, frictionless, hardstops
ignored, output motor held) with Rayleigh damping standing in for spring friction; it is
integrated implicitly inside the same kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.parameters.engine import PulsationGenerator, validate_engine
from dampersim.solver import _kernels as kern

PE_SIZE = 27
_NAMES = {
    "OMEGA0": 0, "DT": 1, "PC": 2, "PATM": 3, "GAMMA": 4, "AREA": 5, "R": 6, "L": 7, "VC": 8, "VBDC": 9,
    "MREC": 10, "RVISC": 11, "RMU": 12, "RTENS": 13, "RBACK": 14, "VREF": 15, "BEAR": 16, "KI": 17,
    "MODE": 18, "KLINK": 19, "BLINK": 20, "OUT_A": 21, "OUT_B": 22, "OUT_K": 23, "OUT_C": 24, "VMAX": 25, "DDYNO": 26,
}
# keep the kernel's private indices and ours in step
for _k, _i in _NAMES.items():
    assert getattr(kern, f"_E_{_k}") == _i, _k


@dataclass(frozen=True)
class EngineLayout:
    PE: np.ndarray
    CH: np.ndarray
    CYL: np.ndarray
    AINV: np.ndarray
    MD: np.ndarray
    KD: np.ndarray
    chain_names: tuple
    downstream_names: tuple
    coupled: bool


def build_engine_layout(pg: PulsationGenerator, omega0: float, dt: float, system=None) -> EngineLayout:
    """Arrays for ``pg`` at nominal speed ``omega0`` [rad/s] and step ``dt`` [s]; with a
    :class:`DamperSystem` ``system`` the generator drives its linearised damper and rig."""
    validate_engine(pg)
    g, fr = pg.geometry, pg.friction
    PE = np.zeros(PE_SIZE)
    PE[0] = omega0
    PE[1] = dt
    PE[2] = pg.charge_pressure
    PE[3] = fr.atmosphere
    PE[4] = g.gamma
    PE[5] = g.piston_area
    PE[6] = g.crank_radius
    PE[7] = g.rod_length
    PE[8] = g.clearance_volume
    PE[9] = g.clearance_volume + g.swept_volume
    PE[10] = g.reciprocating_mass
    PE[11] = fr.ring_viscous
    PE[12] = fr.ring_boundary
    PE[13] = fr.ring_tension
    PE[14] = math.pi * g.bore * fr.ring_height
    PE[15] = fr.ring_speed_ref
    PE[16] = fr.bearing_viscous
    PE[17] = pg.mean_torque_gain
    PE[25] = 50.0 * max(abs(omega0), 100.0)
    PE[26] = pg.dyno_damping
    CH = np.array([[e.inertia, e.inertia_damping, e.shaft_stiffness, e.shaft_damping] for e in pg.chain], dtype=np.float64)
    phases = (0.0, math.pi, math.pi, 0.0)
    CYL = np.array([[d, phases[i]] for i, d in enumerate(pg.crank_dofs)], dtype=np.float64)
    names = tuple(e.name for e in pg.chain)
    if system is None:
        PE[18] = 0.0
        PE[19] = pg.stiff_shaft_stiffness
        PE[20] = pg.stiff_shaft_damping
        z = np.zeros((0, 0))
        return EngineLayout(PE, CH, CYL, z, np.zeros(0), z, names, (), False)
    from dampersim.solver.linear import linearise

    lm = linearise(system, motor="held")
    M, C, K = lm.M, lm.C.copy(), lm.K
    # Rayleigh damping in place of the springs' friction: zeta at 10 Hz (mass part) and
    # at 100 Hz (stiffness part), so the frictionless segment modes do not ring forever
    zeta = pg.downstream_damping_ratio
    w1, w2 = 2 * math.pi * 10.0, 2 * math.pi * 100.0
    C = C + (zeta * w1) * M + (2 * zeta / w2) * K
    A = M + dt * C + dt * dt * K
    AINV = np.ascontiguousarray(np.linalg.inv(A))
    PE[18] = 1.0
    PE[19] = pg.link_stiffness
    PE[20] = pg.link_damping
    a, b = lm.output_shaft_dofs
    PE[21] = a
    PE[22] = b
    PE[23] = lm.output_shaft_k
    PE[24] = lm.output_shaft_c
    return EngineLayout(PE, CH, CYL, AINV, np.ascontiguousarray(np.diag(M).copy()), np.ascontiguousarray(K), names,
                        tuple(lm.dof_names), True)


__all__ = ["EngineLayout", "build_engine_layout", "PE_SIZE"]
