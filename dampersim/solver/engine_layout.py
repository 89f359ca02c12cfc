"""Flatten a :class:`PulsationGenerator` into the arrays of ``_kernels.engine_step``.

Chain DOFs (angles relative to a frame turning at the nominal speed, model-spec §1), in
power-flow order: input dyno, ROBA coupling, crank sections 1-4, flange, transducer.
Cylinders 1-4 sit on crank sections 1-4 with throws at 0, 180, 180 and 0 deg
(inline four); each compresses once per revolution (valves deactivated, [thesis] §4.1).

The shaft leaving the transducer (PE slots E_KLINK, E_BLINK of the kernel module) is either the torsionally
stiff propshaft to a held output dyno (``_kernels.engine_integrate``, [thesis] §4.3.1)
or, coupled, the transducer shaft into J_pri of the full nonlinear damper and rig
(``_kernels.integrate`` marches both; the rig mode of [thesis] §4.2, model-spec §2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.parameters.engine import PulsationGenerator, validate_engine
from dampersim.solver import _kernels as kern

PE_SIZE = kern.PE_SIZE


@dataclass(frozen=True)
class EngineLayout:
    PE: np.ndarray
    CH: np.ndarray
    CYL: np.ndarray
    chain_names: tuple


def build_engine_layout(pg: PulsationGenerator, omega0: float, dt: float, coupled: bool = False) -> EngineLayout:
    """Arrays for ``pg`` at nominal speed ``omega0`` [rad/s] and step ``dt`` [s]. The
    transducer drives the stiff propshaft, or with ``coupled`` the link shaft into the
    damper's input DOF (``pg.link_stiffness`` [N m/rad], ``pg.link_damping``
    [N m s/rad])."""
    validate_engine(pg)
    g, fr = pg.geometry, pg.friction
    PE = np.zeros(PE_SIZE)
    PE[kern.E_OMEGA0] = omega0
    PE[kern.E_DT] = dt
    PE[kern.E_PC] = pg.charge_pressure
    PE[kern.E_PATM] = fr.atmosphere
    PE[kern.E_GAMMA] = g.gamma
    PE[kern.E_AREA] = g.piston_area
    PE[kern.E_R] = g.crank_radius
    PE[kern.E_L] = g.rod_length
    PE[kern.E_VC] = g.clearance_volume
    PE[kern.E_VBDC] = g.clearance_volume + g.swept_volume
    PE[kern.E_MREC] = g.reciprocating_mass
    PE[kern.E_RVISC] = fr.ring_viscous
    PE[kern.E_RMU] = fr.ring_boundary
    PE[kern.E_RTENS] = fr.ring_tension
    PE[kern.E_RBACK] = math.pi * g.bore * fr.ring_height
    PE[kern.E_VREF] = fr.ring_speed_ref
    PE[kern.E_BEAR] = fr.bearing_viscous
    PE[kern.E_KI] = pg.mean_torque_gain
    PE[kern.E_KLINK] = pg.link_stiffness if coupled else pg.stiff_shaft_stiffness
    PE[kern.E_BLINK] = pg.link_damping if coupled else pg.stiff_shaft_damping
    PE[kern.E_VMAX] = 50.0 * max(abs(omega0), 100.0)
    PE[kern.E_DDYNO] = pg.dyno_damping
    CH = np.array([[e.inertia, e.inertia_damping, e.shaft_stiffness, e.shaft_damping] for e in pg.chain], dtype=np.float64)
    phases = (0.0, math.pi, math.pi, 0.0)
    CYL = np.array([[d, phases[i]] for i, d in enumerate(pg.crank_dofs)], dtype=np.float64)
    names = tuple(e.name for e in pg.chain)
    return EngineLayout(PE, CH, CYL, names)


__all__ = ["EngineLayout", "build_engine_layout", "PE_SIZE"]
