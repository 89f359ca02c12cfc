"""Flatten a :class:`PulsationGenerator` into the arrays the generator kernels read.

Chain DOFs (angles relative to a frame turning at the nominal speed, docs/model.md §1), in
power-flow order: input dyno, ROBA coupling, crank sections 1-4, flange, transducer.
Cylinders 1-4 sit on crank sections 1-4 with throws at 0, 180, 180 and 0 deg
(inline four); each compresses once per revolution (valves deactivated, [thesis] §4.1).

The shaft leaving the transducer (PE slots E_KLINK, E_BLINK) is either the torsionally
stiff propshaft to a held output dyno (``kernels.engine.engine_integrate``, [thesis]
§4.3.1) or, coupled, the transducer shaft into J_pri of the full nonlinear damper and
rig (``kernels.integrate.integrate`` marches both; the rig mode of [thesis] §4.2,
docs/model.md §2).

The slot constants below (E_*, the record columns ER_* and the step outputs EO_*) are
frozen into the compiled kernels (:mod:`dampersim.solver.kernels`), whose on-disk
cache is keyed by this file's source too; this module imports no kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dampersim.parameters.engine import PulsationGenerator, validate_engine

# --- engine scalar vector PE -----------------------------------------------------------
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

# --- engine record columns (one row per stored sample) -----------------------------------
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

# --- outputs of one generator step (scratch OUT of engine_step, length EO_SIZE) ------------
EO_TDYNO = 0  # input dyno torque [N m]
EO_W_TRANS = 1  # absolute transducer speed [rad/s]
EO_THETA1 = 2  # crank angle of cylinder 1 [rad]
EO_P1 = 3  # cylinder 1 pressure [Pa]
EO_TGAS = 4
EO_TINER = 5
EO_TFRIC = 6
EO_PMAX = 7  # largest cylinder pressure of this step [Pa]
EO_SIZE = 8


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
    PE[E_OMEGA0] = omega0
    PE[E_DT] = dt
    PE[E_PC] = pg.charge_pressure
    PE[E_PATM] = fr.atmosphere
    PE[E_GAMMA] = g.gamma
    PE[E_AREA] = g.piston_area
    PE[E_R] = g.crank_radius
    PE[E_L] = g.rod_length
    PE[E_VC] = g.clearance_volume
    PE[E_VBDC] = g.clearance_volume + g.swept_volume
    PE[E_MREC] = g.reciprocating_mass
    PE[E_RVISC] = fr.ring_viscous
    PE[E_RMU] = fr.ring_boundary
    PE[E_RTENS] = fr.ring_tension
    PE[E_RBACK] = math.pi * g.bore * fr.ring_height
    PE[E_VREF] = fr.ring_speed_ref
    PE[E_BEAR] = fr.bearing_viscous
    PE[E_KI] = pg.mean_torque_gain
    PE[E_KLINK] = pg.link_stiffness if coupled else pg.stiff_shaft_stiffness
    PE[E_BLINK] = pg.link_damping if coupled else pg.stiff_shaft_damping
    PE[E_VMAX] = 50.0 * max(abs(omega0), 100.0)
    PE[E_DDYNO] = pg.dyno_damping
    CH = np.array([[e.inertia, e.inertia_damping, e.shaft_stiffness, e.shaft_damping] for e in pg.chain], dtype=np.float64)
    phases = (0.0, math.pi, math.pi, 0.0)
    CYL = np.array([[d, phases[i]] for i, d in enumerate(pg.crank_dofs)], dtype=np.float64)
    names = tuple(e.name for e in pg.chain)
    return EngineLayout(PE, CH, CYL, names)


__all__ = ["EngineLayout", "build_engine_layout", "PE_SIZE", "NEREC", "EO_SIZE"]
