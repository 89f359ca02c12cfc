"""Frozen dataclasses for the pulsation generator (motored engine) and the fired engine.

The pulsation generator of [thesis] chapter 4 is a motored 2.2 l four-cylinder diesel
with its valves deactivated; the cylinders are charged with compressed air at P_c
(1-3 bar absolute, [thesis] §4.1.1) and act as air springs that compress once per
revolution. The input dynamometer turns the crankshaft and supplies the mean torque.

Values and their origin (SI units inside, like every parameter set of dampersim):

* cited: displacement 2.2 l, four cylinders, compression ratio 16, gamma 1.4, P_c 1-3
  bar ([thesis] §4.1.1-4.2); crankshaft section stiffness and damping ranges
  ([thesis] Appendix Table 9.1); rig coupling, transducer and flange values
  ([thesis] Table 9.2); input dynamometer like the output motor (Table 9.2: 1.00-1.15).
* estimated (the thesis gives no values): bore, stroke and rod length of a typical
  2.2 l common-rail diesel (86 mm bore x 94.6 mm stroke = 2198 cm^3, rod 160 mm);
  reciprocating mass per cylinder (piston, pin, rings, small end share: 0.9 kg);
  crank section inertia (throw, counterweights and rotating con-rod share: 0.012 kg m^2
  each); ring/skirt and bearing friction chosen so that the motored friction torque is
  a few N m at 2000 rpm (no valve train or pumping losses, [thesis] §4.2). Table 9.1's
  stiffness ranges for cylinders 3 and 4 are printed as "60000-700000" and
  "100000-1100000"; we read them as 6.0-7.0e5 and 1.0-1.1e6 N m/rad.

The origin of every single value is in :data:`ORIGINS` (generator) and
:data:`FIRED_ORIGINS` (fired engine), by dotted name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from dampersim.errors import ParameterError
from dampersim.parameters.model import param
from dampersim.parameters.validation import check_fields

BAR = 1.0e5  # Pa per bar

#: Cylinder pressures [bar abs] accepted by the pulsation generator model and the
#: range over which the thesis ran it ([thesis] §4.1.1: 1-3 bar).
PRESSURE_LIMITS_BAR = (0.5, 4.0)
PRESSURE_THESIS_BAR = (1.0, 3.0)


@dataclass(frozen=True)
class EngineGeometry:
    """Crank-slider geometry of one cylinder ([thesis] Eq. 2, Fig. 4.5)."""

    cylinders: int = param("-", "number of cylinders (inline, throws 0-180-180-0 deg)", 4, 4, default=4, kind=int)
    bore: float = param("m", "cylinder bore D (estimate: 86 mm, typical 2.2 l diesel)", 0.03, 0.2, default=0.086)
    stroke: float = param("m", "piston stroke S = 2 r (estimate: 94.6 mm -> 2198 cm^3)", 0.03, 0.2, default=0.0946)
    rod_length: float = param("m", "connecting rod length L (estimate)", 0.05, 0.5, default=0.160)
    compression_ratio: float = param("-", "compression ratio CR ([thesis] §4.1.1: 16)", 2.0, 30.0, default=16.0)
    gamma: float = param("-", "polytropic exponent ([thesis] §4.2: 1.4)", 1.0, 1.67, default=1.4)
    reciprocating_mass: float = param("kg", "piston, pin, rings and small-end share per cylinder (estimate)", 0.0, 5.0, default=0.9)

    @property
    def crank_radius(self) -> float:
        return 0.5 * self.stroke

    @property
    def piston_area(self) -> float:
        return math.pi * self.bore**2 / 4.0

    @property
    def swept_volume(self) -> float:
        """Swept volume of one cylinder [m^3]."""
        return self.piston_area * self.stroke

    @property
    def displacement(self) -> float:
        """Engine displacement [m^3]."""
        return self.cylinders * self.swept_volume

    @property
    def clearance_volume(self) -> float:
        """V_c = V_d / (CR - 1) [m^3]: counted once (the thesis's Eq. 3 counts it twice)."""
        return self.swept_volume / (self.compression_ratio - 1.0)


@dataclass(frozen=True)
class EngineFriction:
    """Ring-pack and bearing friction ([thesis] §4.2 after Zweiri et al.; values estimated).

    Ring pack: F = c_ring v_p + mu_ring (F_tension + (P - P_atm) pi D h_ring) tanh(v_p / v_ref)
    opposing the piston speed v_p (hydrodynamic shear plus a boundary part loaded by gas
    pressure behind the top ring). Main and big-end bearings: hydrodynamic (Petroff)
    torque b_bearing * omega per crank section.
    """

    ring_viscous: float = param("N s/m", "hydrodynamic shear of ring pack and skirt per piston (estimate)", 0.0, 1.0e3, default=8.0)
    ring_boundary: float = param("-", "boundary friction coefficient of the rings (estimate)", 0.0, 1.0, default=0.08)
    ring_tension: float = param("N", "ring tangential load per piston (estimate)", 0.0, 1.0e3, default=60.0)
    ring_height: float = param("m", "height of the top ring's gas-loaded back face (estimate)", 0.0, 0.01, default=0.0015)
    ring_speed_ref: float = param("m/s", "smoothing speed of the boundary term", 1.0e-4, 1.0, lo_open=True, default=0.05)
    bearing_viscous: float = param("N m s/rad", "bearing (Petroff) damping per crank section (estimate)", 0.0, 1.0, default=0.005)
    atmosphere: float = param("Pa", "crankcase pressure", 0.5e5, 1.5e5, default=1.0e5)


@dataclass(frozen=True)
class ChainElement:
    """An inertia with absolute damping and a shaft to the element before it
    ([thesis] §5.7, Eq. 34-35; Table 9.1/9.2)."""

    name: str = field(default="", metadata={"doc": "identifier"})
    inertia: float = param("kg m^2", "inertia J", 0.0, lo_open=True, default=0.01)
    inertia_damping: float = param("N m s/rad", "absolute damping B_j", 0.0, default=0.002)
    shaft_stiffness: float = param("N m/rad", "stiffness K of the shaft from the element before", 0.0, lo_open=True, default=1.0e6)
    shaft_damping: float = param("N m s/rad", "damping B_k of that shaft", 0.0, default=100.0)


def _crank(i, k):
    # Table 9.1: inertia damping 0.001-0.003, stiffness damping 50-150 N m s/rad
    return ChainElement(f"crank{i}", 0.012, 0.002, k, 100.0)


def _default_chain():
    # input dyno -> ROBA -> snub nose -> crank sections 1-4 -> flange -> transducer.
    # Shaft of element i connects it to element i-1 (the dyno's own shaft is unused).
    # Table 9.1's stiffness of "cylinder i" is read as the crank shaft leaving section i
    # towards the output end; the snub nose between the coupling and the first throw is
    # stepped down to a much smaller diameter ([thesis] §4.1.2, where it later sheared,
    # §4.4): estimated as a 25 mm x 60 mm steel shaft, G J_p / L = 5e4 N m/rad.
    return (
        ChainElement("input_dyno", 1.05, 0.01, 1.0e6, 75.0),  # Table 9.2 output motor J 1.00-1.15
        ChainElement("roba", 0.0575, 0.01, 1.735e6, 75.0),  # Table 9.2 ROBA coupling
        _crank(1, 5.0e4),  # snub nose (estimate, see above)
        _crank(2, 5.875e5),  # Table 9.1 cyl 1 (5.8-5.95e5)
        _crank(3, 5.875e5),  # Table 9.1 cyl 2 (5.8-5.95e5)
        _crank(4, 6.5e5),  # Table 9.1 cyl 3 (read as 6.0-7.0e5)
        ChainElement("flange", 0.03, 0.01, 1.05e6, 75.0),  # Table 9.1 cyl 4 (read as 1.0-1.1e6); Table 9.2 flange J
        ChainElement("transducer", 0.0145, 0.01, 1.4e6, 75.0),  # Table 9.2 T40B (K range midpoint)
    )


@dataclass(frozen=True)
class PulsationGenerator:
    """The motored-engine pulsation generator ([thesis] chapter 4, docs/model.md §8)."""

    name: str = field(default="pulsation_generator_2017", metadata={"doc": "short identifier"})
    geometry: EngineGeometry = field(default_factory=EngineGeometry, metadata={"doc": "crank-slider geometry"})
    friction: EngineFriction = field(default_factory=EngineFriction, metadata={"doc": "ring and bearing friction"})
    chain: tuple = field(default_factory=_default_chain, metadata={"doc": "input dyno, coupling, 4 crank sections, flange, transducer"})
    charge_pressure: float = param("Pa", "compressed-air charge P_c (abs) ([thesis] §4.1.1: 1-3 bar)", 0.5e5, 4.0e5, default=2.5e5)
    stiff_shaft_stiffness: float = param("N m/rad", "propshaft to the output dyno when run alone (torsionally stiff)", 1.0e4, 1.0e9, default=1.0e7)
    stiff_shaft_damping: float = param("N m s/rad", "damping of that propshaft", 0.0, default=100.0)
    link_stiffness: float = param("N m/rad", "transducer shaft into the damper's input DOF (J_pri) when coupled (Table 9.2 T40B)", 1.0e4, 1.0e9, default=1.4e6)
    link_damping: float = param("N m s/rad", "damping of that shaft", 0.0, default=75.0)
    mean_torque_gain: float = param("1/s", "integral gain of the input dyno's mean-torque control on the measured output", 0.0, 100.0, default=3.0)
    dyno_damping: float = param("N m s/rad", "active damping of the input dyno's torque control on its speed deviation (estimate)", 0.0, 1.0e4, default=30.0)

    @property
    def crank_dofs(self) -> tuple:
        """Indices of the four crank sections in :attr:`chain`."""
        return tuple(i for i, e in enumerate(self.chain) if e.name.startswith("crank"))


def validate_engine(pg: PulsationGenerator) -> PulsationGenerator:
    """Check every field's bounds (ParameterError naming the field) and the chain."""
    check_fields(pg)
    if len(pg.crank_dofs) != pg.geometry.cylinders:
        raise ParameterError("chain", [e.name for e in pg.chain], f"{pg.geometry.cylinders} elements named crank1..crank4")
    names = [e.name for e in pg.chain]
    if names[0] != "input_dyno" or names[-1] != "transducer":
        raise ParameterError("chain", names, "a chain starting with 'input_dyno' and ending with 'transducer'")
    g = pg.geometry
    if g.rod_length <= g.crank_radius * 1.5:
        raise ParameterError("geometry.rod_length", g.rod_length, f"a rod longer than 1.5 x the crank radius ({1.5 * g.crank_radius:g} m)")
    return pg


def default_pulsation_generator(pressure_bar: float | None = None) -> PulsationGenerator:
    """The thesis's pulsation generator; ``pressure_bar`` sets P_c [bar abs]."""
    pg = PulsationGenerator()
    if pressure_bar is not None:
        check_pressure_bar(pressure_bar)
        pg = PulsationGenerator(charge_pressure=float(pressure_bar) * BAR)
    return validate_engine(pg)


def check_pressure_bar(pressure_bar) -> float:
    lo, hi = PRESSURE_LIMITS_BAR
    try:
        p = float(pressure_bar)
    except (TypeError, ValueError):
        p = float("nan")
    if not (math.isfinite(p) and lo <= p <= hi):
        raise ParameterError("pressure", pressure_bar, f"a charge pressure in [{lo:g}, {hi:g}] bar abs (the thesis ran 1-3 bar)")
    return p


@dataclass(frozen=True)
class FiredEngine:
    """A fired four-stroke version of the same engine: single-zone cylinder pressure
    from a Wiebe heat release (estimates of a typical common-rail diesel at full load)."""

    geometry: EngineGeometry = field(default_factory=EngineGeometry)
    friction: EngineFriction = field(default_factory=EngineFriction)
    intake_pressure: float = param("Pa", "boost pressure at inlet valve closure (estimate: 2.0 bar at WOT)", 0.5e5, 4.0e5, default=2.0e5)
    combustion_start: float = param("rad", "start of combustion after TDC (estimate: -5 deg)", -0.5, 0.5, default=math.radians(-5.0))
    combustion_duration: float = param("rad", "Wiebe burn duration (estimate: 60 deg)", 0.1, 2.0, default=math.radians(60.0))
    wiebe_a: float = param("-", "Wiebe efficiency parameter", 1.0, 10.0, default=5.0)
    wiebe_m: float = param("-", "Wiebe shape exponent", 0.1, 5.0, default=1.5)
    rotating_inertia: float = param("kg m^2", "crankshaft, flywheel-side rotating inertia (rigid crank)", 0.01, 2.0, default=0.05)


_TABLE_91_BK = "[thesis] Table 9.1: middle of the 50-150 N m s/rad stiffness damping range of the crank sections"
_TABLE_91_BJ = "[thesis] Table 9.1: middle of the 0.001-0.003 N m s/rad inertia damping range"
_CRANK_J = ("estimate: throw, counterweights and the rotating share of the con-rod of one section; the thesis took "
            "the section inertias from manufacturer data it does not print ([thesis] §4.2)")
_RIG_BJ = "[thesis] Table 9.2: middle of the 0.005-0.015 N m s/rad inertia damping range"
_RIG_BK = "[thesis] Table 9.2: middle of the 50-100 N m s/rad stiffness damping range"
_FRICTION = ("so that the motored friction torque is a few N m at 2000 rpm; the generator keeps only ring-pack "
             "and bearing friction, with no valve train or pumping losses ([thesis] §4.2)")

_SHARED_ORIGINS = {
    "geometry.cylinders": "[thesis] §4.1.1: four-cylinder diesel",
    "geometry.bore": "estimate: 86 mm, a typical bore of a 2.2 l common-rail four-cylinder diesel",
    "geometry.stroke": "estimate: 94.6 mm, with the 86 mm bore 2198 cm^3 in all",
    "geometry.rod_length": "estimate: 160 mm, about 3.4 crank radii as usual for such engines",
    "geometry.compression_ratio": "[thesis] §4.1.1: 16",
    "geometry.gamma": "[thesis] §4.2: 1.4, air as an ideal gas compressed polytropically",
    "geometry.reciprocating_mass": "estimate: piston, pin, rings and the small-end share of the con-rod, 0.9 kg "
    "per cylinder",
    "friction.ring_viscous": f"estimate: hydrodynamic shear of ring pack and skirt, {_FRICTION}",
    "friction.ring_boundary": f"estimate: boundary friction coefficient of the rings, {_FRICTION}",
    "friction.ring_tension": f"estimate: ring tangential load, {_FRICTION}",
    "friction.ring_height": "estimate: 1.5 mm, the gas-loaded back face of a typical top ring",
    "friction.ring_speed_ref": "estimate: 0.05 m/s smooths the boundary term's sign change at the dead "
    "centres without changing the torque elsewhere",
    "friction.bearing_viscous": f"estimate: hydrodynamic (Petroff) bearing torque per section, {_FRICTION}",
    "friction.atmosphere": "estimate: 1 bar, the crankcase vents to the atmosphere",
}

#: origin of every leaf parameter of the default pulsation generator, by dotted name
#: (same kinds as the damper set's ORIGINS: ``[thesis] ...``, ``estimate:``, ``model:``;
#: identifiers have none)
ORIGINS = {
    **_SHARED_ORIGINS,
    "chain.input_dyno.inertia": "[thesis] Table 9.2: inside the 1.00-1.15 kg m^2 of the output motor; the "
    "input dynamometer is taken to be alike",
    "chain.input_dyno.inertia_damping": _RIG_BJ,
    "chain.input_dyno.shaft_stiffness": "model: unused, the input dyno is the first element of the chain "
    "(docs/model.md §8)",
    "chain.input_dyno.shaft_damping": "model: unused, as its shaft stiffness (docs/model.md §8)",
    "chain.roba.inertia": "[thesis] Table 9.2: middle of the ROBA coupling's 0.057-0.058 kg m^2",
    "chain.roba.inertia_damping": _RIG_BJ,
    "chain.roba.shaft_stiffness": "[thesis] Table 9.2: middle of the ROBA coupling's 1.72e6-1.75e6 N m/rad",
    "chain.roba.shaft_damping": _RIG_BK,
    "chain.crank1.inertia": _CRANK_J,
    "chain.crank1.inertia_damping": _TABLE_91_BJ,
    "chain.crank1.shaft_stiffness": "estimate: the snub nose between coupling and first throw is stepped down "
    "to a much smaller diameter ([thesis] §4.1.2); a 25 mm x 60 mm steel shaft gives G J_p / L = 5e4 N m/rad",
    "chain.crank1.shaft_damping": _TABLE_91_BK,
    "chain.crank2.inertia": _CRANK_J,
    "chain.crank2.inertia_damping": _TABLE_91_BJ,
    "chain.crank2.shaft_stiffness": "[thesis] Table 9.1: middle of cylinder 1's 5.80e5-5.95e5 N m/rad",
    "chain.crank2.shaft_damping": _TABLE_91_BK,
    "chain.crank3.inertia": _CRANK_J,
    "chain.crank3.inertia_damping": _TABLE_91_BJ,
    "chain.crank3.shaft_stiffness": "[thesis] Table 9.1: middle of cylinder 2's 5.80e5-5.95e5 N m/rad",
    "chain.crank3.shaft_damping": _TABLE_91_BK,
    "chain.crank4.inertia": _CRANK_J,
    "chain.crank4.inertia_damping": _TABLE_91_BJ,
    "chain.crank4.shaft_stiffness": "[thesis] Table 9.1: cylinder 3, printed 60000-700000 N m/rad and read as "
    "6.0e5-7.0e5 (a digit lost, like its neighbours' ranges); the middle",
    "chain.crank4.shaft_damping": _TABLE_91_BK,
    "chain.flange.inertia": "[thesis] Table 9.2: middle of flange group 1's 0.025-0.035 kg m^2",
    "chain.flange.inertia_damping": _RIG_BJ,
    "chain.flange.shaft_stiffness": "[thesis] Table 9.1: cylinder 4 (the crank end to the flange), printed "
    "100000-1100000 N m/rad and read as 1.0e6-1.1e6; the middle",
    "chain.flange.shaft_damping": _RIG_BK,
    "chain.transducer.inertia": "[thesis] Table 9.2: middle of the T40B's 0.014-0.015 kg m^2",
    "chain.transducer.inertia_damping": _RIG_BJ,
    "chain.transducer.shaft_stiffness": "[thesis] Table 9.2: middle of the printed T40B range "
    "250000-2550000 N m/rad",
    "chain.transducer.shaft_damping": _RIG_BK,
    "charge_pressure": "[thesis] §4.1.1: 1-3 bar; 2.5 bar, the charge of the thesis's main torque-curve "
    "campaign ([thesis] §6.2.1)",
    "stiff_shaft_stiffness": "estimate: a torsionally stiff propshaft for the generator-only tests "
    "([thesis] §4.3.1), its mode far above the orders studied",
    "stiff_shaft_damping": "estimate: like a crank section, inside the 50-150 N m s/rad of [thesis] Table 9.1",
    "link_stiffness": "[thesis] Table 9.2: the T40B transducer shaft into the damper, middle of the printed "
    "range",
    "link_damping": _RIG_BK,
    "mean_torque_gain": "estimate: a slow integral trim of the mean on the measured output torque, as the rig "
    "controlled it ([thesis] §4.3.1), far below the frequencies of the 2nd order",
    "dyno_damping": "estimate: active damping of the dyno's torque loop on its speed deviation, within the "
    "15 Hz bandwidth of the rig's dynamometers ([thesis] §3.1.1)",
}

#: origin of every leaf parameter of the default fired engine, by dotted name
FIRED_ORIGINS = {
    **_SHARED_ORIGINS,
    "intake_pressure": "estimate: 2.0 bar boost at inlet valve closure, a turbocharged diesel at full load",
    "combustion_start": "estimate: combustion starts 5 deg before top dead centre",
    "combustion_duration": "estimate: 60 deg of crank angle from start to end of the burn",
    "wiebe_a": "estimate: 5, a usual Wiebe efficiency parameter (about 99 % burnt at the end)",
    "wiebe_m": "estimate: 1.5, a usual Wiebe shape exponent for diesel combustion",
    "rotating_inertia": "estimate: crankshaft and the flywheel-side rotating parts of a 2.2 l engine, "
    "0.05 kg m^2",
}


__all__ = [
    "BAR",
    "PRESSURE_LIMITS_BAR",
    "PRESSURE_THESIS_BAR",
    "EngineGeometry",
    "EngineFriction",
    "ChainElement",
    "PulsationGenerator",
    "FiredEngine",
    "validate_engine",
    "default_pulsation_generator",
    "check_pressure_bar",
    "ORIGINS",
    "FIRED_ORIGINS",
]
