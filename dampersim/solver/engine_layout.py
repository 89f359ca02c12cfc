"""Flatten a :class:`PulsationGenerator` into the arrays of ``_kernels.engine_step``.

Chain DOFs (angles relative to a frame turning at the nominal speed, model-spec §1), in
power-flow order: input dyno, ROBA coupling, crank sections 1-4, flange, transducer.
Cylinders 1-4 sit on crank sections 1-4 with throws at 0, 180, 180 and 0 deg
(inline four); each compresses once per revolution (valves deactivated, [thesis] §4.1).

The shaft leaving the transducer (PE slots KLINK, BLINK) is either the torsionally
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

PE_SIZE = 23
_NAMES = {
    "OMEGA0": 0, "DT": 1, "PC": 2, "PATM": 3, "GAMMA": 4, "AREA": 5, "R": 6, "L": 7, "VC": 8, "VBDC": 9,
    "MREC": 10, "RVISC": 11, "RMU": 12, "RTENS": 13, "RBACK": 14, "VREF": 15, "BEAR": 16, "KI": 17,
    "MODE": 18, "KLINK": 19, "BLINK": 20, "VMAX": 21, "DDYNO": 22,
}
# keep the kernel's private indices and ours in step
for _k, _i in _NAMES.items():
    assert getattr(kern, f"_E_{_k}") == _i, _k


@dataclass(frozen=True)
class EngineLayout:
    PE: np.ndarray
    CH: np.ndarray
    CYL: np.ndarray
    chain_names: tuple
    coupled: bool


def build_engine_layout(pg: PulsationGenerator, omega0: float, dt: float, coupled: bool = False) -> EngineLayout:
    """Arrays for ``pg`` at nominal speed ``omega0`` [rad/s] and step ``dt`` [s]. The
    transducer drives the stiff propshaft, or with ``coupled`` the link shaft into the
    damper's input DOF (``pg.link_stiffness`` [N m/rad], ``pg.link_damping``
    [N m s/rad])."""
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
    PE[18] = 1.0 if coupled else 0.0
    PE[19] = pg.link_stiffness if coupled else pg.stiff_shaft_stiffness
    PE[20] = pg.link_damping if coupled else pg.stiff_shaft_damping
    PE[21] = 50.0 * max(abs(omega0), 100.0)
    PE[22] = pg.dyno_damping
    CH = np.array([[e.inertia, e.inertia_damping, e.shaft_stiffness, e.shaft_damping] for e in pg.chain], dtype=np.float64)
    phases = (0.0, math.pi, math.pi, 0.0)
    CYL = np.array([[d, phases[i]] for i, d in enumerate(pg.crank_dofs)], dtype=np.float64)
    names = tuple(e.name for e in pg.chain)
    return EngineLayout(PE, CH, CYL, names, bool(coupled))


__all__ = ["EngineLayout", "build_engine_layout", "PE_SIZE"]
