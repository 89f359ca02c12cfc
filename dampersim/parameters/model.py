"""Frozen dataclasses describing a two-stage arc-spring turbine damper on its test rig.

Every physical field carries its unit, bounds and meaning in ``dataclasses.field``
metadata; :mod:`dampersim.parameters.validation` checks values against it and
:mod:`dampersim.parameters.io` uses it for TOML load/save and ``--set`` paths.
All values are SI: kg, m, rad, N m/rad, N m s/rad, kg m^2, s.

Structure ([thesis] §5.1, Fig. 5.3; docs/model.md §2)::

    T_in -> J_pri -[outer set]-> J_sec -[inner set of nested pairs]-> J_ter -> rig chain -> output motor
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

INF = math.inf


def param(unit, doc, lo=None, hi=None, lo_open=False, default=None, kind=float):
    """A dataclass field with physical metadata.

    ``lo``/``hi`` are inclusive bounds unless ``lo_open`` (strictly greater than ``lo``).
    """
    meta = {"unit": unit, "doc": doc, "lo": lo, "hi": hi, "lo_open": lo_open, "kind": kind}
    if default is None:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class Inertias:
    """The three damper bodies ([thesis] §5.2, Eq. 4-6)."""

    primary: float = param("kg m^2", "housing, pump, lock-up clutch and drive ring, lumped", 0.0, lo_open=True)
    secondary: float = param("kg m^2", "turbine, damper housing and retaining plate", 0.0, lo_open=True)
    tertiary: float = param("kg m^2", "output hub splined to the transmission input shaft", 0.0, lo_open=True)


@dataclass(frozen=True)
class ArcSpring:
    """One arc spring ([thesis] §5.3.1). Integrated as N segments and N-1 point masses."""

    stiffness: float = param("N m/rad", "torsional rate of the whole spring about the damper axis", 0.0, lo_open=True)
    mass: float = param("kg", "mass of the whole spring", 0.0, lo_open=True)
    arc: float = param("rad", "free (relaxed) arc length", 0.0, 2 * math.pi, lo_open=True)
    effective_radius: float = param("m", "radius of the coil centre line (r_eff)", 0.0, 1.0, lo_open=True)
    friction_radius: float = param("m", "radius of the friction contact (r_fri)", 0.0, 1.0, lo_open=True)
    active_coils: float = param("-", "number of active coils (nC)", 1.0)
    wire_thickness: float = param("m", "wire thickness (W_thick)", 0.0, 0.05, lo_open=True)


@dataclass(frozen=True)
class SpringSet:
    """A set of identical springs (or nested pairs) between two bodies ([thesis] §5.3, §5.5.2).

    Windup of the set = angle of the body before it minus angle of the body after it.
    """

    count: int = param("-", "number of springs (or nested pairs) in the set (nS)", 1, 12, kind=int)
    spring: ArcSpring = field(metadata={"doc": "the spring (outer spring of a nested pair)"})
    primary_stopper_half_width: float = param("rad", "half width of the stopper of the body before the set (phi_PS)", 0.0, math.pi)
    secondary_stopper_half_width: float = param("rad", "half width of the stopper of the body after the set (phi_SS)", 0.0, math.pi)
    hardstop_positive: float = param("rad", "windup at which the positive hardstop engages (phi_HS,P)", 0.0, math.pi, lo_open=True)
    hardstop_negative: float = param("rad", "windup limit under negative torque, a negative number (-phi_HS,N)", -math.pi, 0.0)
    nested: ArcSpring | None = field(default=None, metadata={"doc": "inner spring of each nested pair, or none ([thesis] §5.3.2)"})

    @property
    def pitch(self) -> float:
        """Stopper pitch 2*pi/nS [rad]."""
        return 2.0 * math.pi / self.count

    @property
    def slot_arc(self) -> float:
        """Free arc between the stoppers at zero windup [rad] ([thesis] Eq. 16-17)."""
        return self.pitch - 2.0 * max(self.primary_stopper_half_width, self.secondary_stopper_half_width)


@dataclass(frozen=True)
class SpringFriction:
    """Friction tuning of one spring type ([thesis] Eq. 28, §6.1)."""

    alpha: float = param("-", "friction tuning factor alpha_fric (share of the coil surface in contact)", 0.0, 10.0)
    preload: float = param("N", "radial preload per segment mass F_p ([thesis] Eq. 19)", 0.0, 1.0e4, default=0.0)


@dataclass(frozen=True)
class Friction:
    """Makkar friction law and its tuning ([thesis] §5.4, Eq. 27-28)."""

    enabled: bool = param("-", "friction on (false: frictionless springs)", default=True, kind=bool)
    gamma1: float = param("-", "Stribeck level", 0.0, 10.0, default=0.2)
    gamma2: float = param("s/m", "Stribeck rise rate", 0.0, 1.0e5, default=100.0)
    gamma3: float = param("s/m", "Stribeck decay rate", 0.0, 1.0e5, default=10.0)
    gamma4: float = param("-", "Coulomb level", 0.0, 10.0, default=0.2)
    gamma5: float = param("s/m", "Coulomb rise rate", 0.0, 1.0e5, default=100.0)
    gamma6: float = param("s/m", "viscous slope", 0.0, 100.0, default=0.01)
    outer: SpringFriction = field(default=None, metadata={"doc": "outer arc springs on the secondary race"})
    pair_outer: SpringFriction = field(default=None, metadata={"doc": "outer spring of each nested pair on the sec/ter housing"})
    pair_inner: SpringFriction = field(default=None, metadata={"doc": "inner spring of each nested pair on its outer spring"})
    alpha_sec: float = param("-", "share of the inner set's housing friction carried by J_sec", 0.0, 1.0, default=0.5)
    alpha_ter: float = param("-", "share carried by J_ter; alpha_sec + alpha_ter = 1", 0.0, 1.0, default=0.5)


@dataclass(frozen=True)
class Hardstops:
    """Hardstop contact ([thesis] §5.5.2). We use a stiff, damped, one-sided contact
    instead of the thesis's inertia merge (Eq. 30-33); see docs/model.md §6."""

    enabled: bool = param("-", "hardstops active (false: windup unlimited)", default=True, kind=bool)
    stiffness: float = param("N m/rad", "contact stiffness of a hardstop", 1.0e3, 1.0e9, default=2.0e6)
    # 600 N m s/rad is about critical for J_pri against J_sec on 2e6 N m/rad (2 sqrt(k J_eff),
    # J_eff = 0.046 kg m^2), so the outer contact has no rebound, like the thesis's inertia
    # merge; the lighter inner contact (J_eff = 0.0078 kg m^2) is overdamped. A bouncing
    # contact (restitution ~0.6 at 100 N m s/rad) makes knee-crossing test points chaotic:
    # subharmonics appear and no time step converges them.
    damping: float = param("N m s/rad", "contact damping (acts only while in contact, never pulls; integrated implicitly)", 0.0, 1.0e5, default=600.0)


@dataclass(frozen=True)
class RigElement:
    """One element of the rig's output chain ([thesis] §5.7, Eq. 34-35, Table 9.2).

    The element is an inertia with absolute damping; its shaft connects it to the body
    before it in the power flow (J_ter for the first element).
    """

    name: str = field(default="", metadata={"doc": "identifier (letters, digits, underscore)"})
    inertia: float = param("kg m^2", "inertia J", 0.0, lo_open=True, default=1.0)
    inertia_damping: float = param("N m s/rad", "absolute damping B_j (Eq. 35)", 0.0, default=0.0)
    shaft_stiffness: float = param("N m/rad", "stiffness K of the shaft from the previous body (Eq. 34)", 0.0, lo_open=True, default=1.0e6)
    shaft_damping: float = param("N m s/rad", "damping B_k of that shaft (Eq. 34)", 0.0, default=0.0)


@dataclass(frozen=True)
class Rig:
    """Output side of the test rig: gearbox, flanges, transducer, coupling, output motor."""

    elements: tuple = field(default=(), metadata={"doc": "RigElement chain after J_ter; the last one is the output motor"})
    output_transducer: str = field(default="transducer", metadata={"doc": "element whose shaft torque is the measured output torque"})


@dataclass(frozen=True)
class OutputMotor:
    """Speed control of the output motor ([thesis] §3.1.1: ~15 Hz bandwidth)."""

    mode: str = field(default="pi", metadata={"doc": "'pi' (PI speed control) or 'held' (speed prescribed exactly)"})
    proportional_gain: float = param("N m s/rad", "PI proportional gain", 0.0, default=120.0)
    integral_gain: float = param("N m/rad", "PI integral gain", 0.0, default=2800.0)


@dataclass(frozen=True)
class Solver:
    """Numerical settings (not hardware)."""

    time_step: float = param("s", "fixed integration step", 1.0e-8, 1.0e-3, default=1.0 / 120000.0)
    outer_segments: int = param("-", "segments per outer spring ([thesis] §6.2.2: 18; 48 by our accuracy grid)", 4, 200,
                                default=48, kind=int)
    inner_segments: int = param("-", "segments per nested-pair spring ([thesis] §6.2.2: 8; 16 by our accuracy grid)", 4,
                                200, default=16, kind=int)
    duration: float = param("s", "simulated time", 0.01, 600.0, default=2.6)
    output_sample_rate: float = param("Hz", "sample rate of the stored time series", 100.0, 1.0e6, default=10000.0)
    segment_sample_rate: float = param("Hz", "sample rate of the stored per-segment states", 1.0, 1.0e6, default=1000.0)
    friction_scheme: str = field(default="fitted", metadata={
        "doc": "where the implicit friction step applies the law: 'fitted' (exponentially fitted weight, "
               "L-stable), 'backward-euler' or 'trapezoidal' (A-stable only; rings on stiff contacts)"})
    friction_tolerance: float = param("-", "Newton tolerance of the friction law, in units of the friction coefficient",
                                      1.0e-9, 0.1, default=1.0e-2)
    friction_iterations: int = param("-", "Newton re-solves of the friction step before the law is applied "
                                     "explicitly at the last iterate", 0, 20, default=8, kind=int)


# --- candidate effects of the discrepancy workflow (all off by default) ----------------
# Physical cause and expected signature of each: dampersim.discrepancy.effects.


@dataclass(frozen=True)
class ClutchSlip:
    """Lock-up clutch of finite capacity between the input and J_pri."""

    enabled: bool = param("-", "lock-up clutch may slip (false: rigidly closed)", default=False, kind=bool)
    capacity: float = param("N m", "friction torque the closed clutch transmits before it slips", 10.0, 1.0e4, default=500.0)
    slip_speed: float = param("rad/s", "slip speed over which the clutch friction builds up", 1.0e-4, 10.0, default=0.02)
    viscous: float = param("N m s/rad", "oil-film drag of the slipping clutch", 0.0, 1.0e4, default=20.0)
    drive_inertia_fraction: float = param("-", "share of J_pri on the engine side of the clutch (cover, pump)", 0.05, 0.95, default=0.6)


@dataclass(frozen=True)
class OutputBacklash:
    """Free play in the transmission output (the gearbox shaft after J_ter)."""

    enabled: bool = param("-", "free play in the first rig shaft", default=False, kind=bool)
    free_play: float = param("rad", "total angular free play of the shaft", 0.0, 0.5, default=0.03)


@dataclass(frozen=True)
class InnerShortSprings:
    """Shorter inner-of-pair springs in some nested pairs: a second pair design and a
    third stiffness stage ([thesis] §5.1, the smaller damper; docs/model.md §4, §11).

    ``count`` of the inner set's pairs hold a short inner spring; the other pairs are the
    normal full-length pairs. Each kind is integrated as one representative pair with its
    own masses and friction contacts. The short pair's outer spring is the set's outer
    spring; its inner spring has the normal inner spring's radii and wire, the rate, mass
    and coil count given here, and the free arc ``inner.slot_arc - clearance``.
    """

    enabled: bool = param("-", "some inner-of-pair springs are shorter than the slot", default=False, kind=bool)
    count: int = param("-", "number of pairs with a short inner spring (fewer than inner.count; 0: none)", 0, 11,
                       default=2, kind=int)
    stiffness: float = param("N m/rad", "rate of one short inner spring about the damper axis", 0.0, 1.0e5,
                             lo_open=True, default=240.0)
    clearance: float = param("rad", "slot arc at zero windup minus the short spring's free arc: the inner-set "
                             "windup at which it starts to carry torque (equal stopper widths)", 0.0, 1.0, default=0.1)
    mass: float = param("kg", "mass of one short inner spring", 0.0, 10.0, lo_open=True, default=0.032)
    active_coils: float = param("-", "active coils of one short inner spring (block arc, redirection force)", 1.0,
                                1000.0, default=10.0)

    def spring(self, inner: SpringSet) -> ArcSpring:
        """The short inner spring of a pair of ``inner``: the nested spring's radii and
        wire, this table's rate, mass and coils, free arc = slot arc - clearance [rad]."""
        return ArcSpring(
            stiffness=self.stiffness,
            mass=self.mass,
            arc=inner.slot_arc - self.clearance,
            effective_radius=inner.nested.effective_radius,
            friction_radius=inner.nested.friction_radius,
            active_coils=self.active_coils,
            wire_thickness=inner.nested.wire_thickness,
        )


@dataclass(frozen=True)
class TurbineDrag:
    """Hydrodynamic drag on J_sec (turbine) against the housing (J_pri)."""

    enabled: bool = param("-", "hydrodynamic drag between turbine and housing", default=False, kind=bool)
    coefficient: float = param("N m s/rad", "drag torque per unit slip speed", 0.0, 1.0e3, default=3.0)


@dataclass(frozen=True)
class PendulumAbsorber:
    """Centrifugal pendulum absorber on J_sec tuned to an engine order (linearised)."""

    enabled: bool = param("-", "pendulum absorber fitted on J_sec", default=False, kind=bool)
    order: float = param("-", "engine order the pendulums are tuned to", 0.5, 12.0, default=2.0)
    inertia: float = param("kg m^2", "effective inertia of the pendulum masses", 0.0, 1.0, lo_open=True, default=0.001)
    damping: float = param("N m s/rad", "damping of the pendulum motion relative to J_sec", 0.0, 100.0, default=0.02)


@dataclass(frozen=True)
class NestedRadialTransfer:
    """The inner spring of each nested pair presses radially on its outer spring."""

    enabled: bool = param("-", "inner spring's radial force loads the outer spring of the pair", default=False, kind=bool)
    fraction: float = param("-", "share of the inner spring's normal force passed on", 0.0, 1.0, default=1.0)


@dataclass(frozen=True)
class SpringPreload:
    """Radial preload on every arc spring mass (e.g. pre-curved springs)."""

    enabled: bool = param("-", "extra radial preload on the arc springs", default=False, kind=bool)
    force: float = param("N", "radial preload per segment mass (one spring)", 0.0, 1.0e4, default=15.0)


@dataclass(frozen=True)
class TransducerBandwidth:
    """First-order low pass of the output torque transducer chain."""

    enabled: bool = param("-", "output torque passes a first-order low pass", default=False, kind=bool)
    cutoff: float = param("Hz", "-3 dB frequency of the low pass", 1.0, 1.0e5, default=150.0)


@dataclass(frozen=True)
class Effects:
    """Optional physical effects beyond the thesis's model (the discrepancy library)."""

    clutch_slip: ClutchSlip = field(default_factory=ClutchSlip, metadata={"doc": "lock-up clutch slip"})
    output_backlash: OutputBacklash = field(default_factory=OutputBacklash, metadata={"doc": "output free play"})
    inner_short_springs: InnerShortSprings = field(default_factory=InnerShortSprings, metadata={"doc": "third stiffness stage"})
    turbine_drag: TurbineDrag = field(default_factory=TurbineDrag, metadata={"doc": "turbine drag"})
    pendulum_absorber: PendulumAbsorber = field(default_factory=PendulumAbsorber, metadata={"doc": "pendulum absorber"})
    nested_radial_transfer: NestedRadialTransfer = field(default_factory=NestedRadialTransfer, metadata={"doc": "nested radial load"})
    spring_preload: SpringPreload = field(default_factory=SpringPreload, metadata={"doc": "radial spring preload"})
    transducer_bandwidth: TransducerBandwidth = field(default_factory=TransducerBandwidth, metadata={"doc": "transducer low pass"})


@dataclass(frozen=True)
class DamperSystem:
    """A complete, named parameter set: damper, rig, output motor and solver settings."""

    name: str = field(default="unnamed", metadata={"doc": "short identifier of the set"})
    source: str = field(default="", metadata={"doc": "where the values come from"})
    inertias: Inertias = field(default=None, metadata={"doc": "damper bodies"})
    outer: SpringSet = field(default=None, metadata={"doc": "outer spring set (J_pri -> J_sec)"})
    inner: SpringSet = field(default=None, metadata={"doc": "inner set of nested pairs (J_sec -> J_ter)"})
    friction: Friction = field(default=None, metadata={"doc": "spring friction"})
    hardstops: Hardstops = field(default_factory=Hardstops, metadata={"doc": "hardstop contact"})
    rig: Rig = field(default=None, metadata={"doc": "output chain of the test rig"})
    motor: OutputMotor = field(default_factory=OutputMotor, metadata={"doc": "output motor control"})
    solver: Solver = field(default_factory=Solver, metadata={"doc": "numerical settings"})
    effects: Effects = field(default_factory=Effects, metadata={"doc": "optional effects (all off by default)"})

    @property
    def short_pairs(self) -> int:
        """Nested pairs with a short inner spring [-] (effect inner_short_springs; 0 when it
        is off or the inner set has no nested spring)."""
        ss = self.effects.inner_short_springs
        return ss.count if ss.enabled and self.inner.nested is not None else 0
