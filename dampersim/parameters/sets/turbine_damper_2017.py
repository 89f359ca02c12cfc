"""Default set: the larger two-stage turbine damper of the thesis on the Bath test rig.

The thesis ([thesis] §5.1, §6.1, Appendix Table 9.2) publishes the damper's structure,
the friction law and the rig's value ranges, but no OEM spring or inertia values. Every
leaf parameter of the set (every dotted name, effects included) therefore has an entry
in :data:`ORIGINS`, which starts with its kind:

- ``[thesis] §N`` / ``[thesis] Table 9.2`` ...: stated in the thesis, or inside the
  range its appendix gives for the rig;
- ``estimate:``: chosen by us, with the reasoning, so that the set reproduces the
  qualitative behaviour the thesis reports (docs/model.md §10): positive knee near
  300 N m, first elastic mode below 20 Hz, resonance bands near 5-10 Hz and
  170-210 Hz, inner knee above the 500 N m test range, small negative knees;
- ``model:``: a modelling or numerical choice of ours, explained in docs/model.md.

The thesis is entry ``thesis2017`` of docs/references.bib. Identifiers (``name``,
``source``, the rig elements' names) are not values and have no origin.

Key derived figures (checked by ``tests/unit/test_parameters.py``):
outer set rate 3 x 127 = 381 N m/rad, knee 381 x 45 deg = 299 N m;
inner set rate 5 x 480 = 2400 N m/rad, knee 2400 x 15 deg = 628 N m.
"""

import math

from dampersim.parameters.model import (
    ArcSpring,
    DamperSystem,
    Friction,
    Hardstops,
    Inertias,
    OutputMotor,
    Rig,
    RigElement,
    Solver,
    SpringFriction,
    SpringSet,
)

NAME = "turbine-damper-2017"
DEG = math.pi / 180.0

_MID_92 = "[thesis] Table 9.2: middle of the range given for"
_BJ = "[thesis] Table 9.2: middle of the 0.005-0.015 N m s/rad inertia damping range of the rig components"
_BK = "[thesis] Table 9.2: middle of the 50-100 N m s/rad stiffness damping range"

#: origin of every leaf parameter of the set, by dotted name (see the module docs)
ORIGINS = {
    # --- damper bodies
    "inertias.primary": "estimate: lumped housing, pump, clutch and drive ring of a ~300 mm converter; "
    "sets the first elastic mode (J_pri against the rig through both sets in series) to ~7 Hz, "
    "inside the 5-10 Hz resonance band of [thesis] §7.2",
    "inertias.secondary": "estimate: turbine plus damper housing and retaining plate ([thesis] §5.1 groups them), "
    "lighter than the primary group",
    "inertias.tertiary": "estimate: small output hub; with the gearbox stiffness it places the hub mode "
    "at 177 Hz (python -m dampersim modes), inside the 170-210 Hz band of [thesis] §7.2",
    # --- outer set: 3 long arc springs between J_pri and J_sec
    "outer.count": "[thesis] §5.1: 3 long outer arc springs",
    "outer.spring.stiffness": "estimate: 299 N m knee / (3 springs x 45 deg) so the positive knee sits near "
    "300 N m ([thesis] §6.2.1, Fig. 6.7: knee between 1360 and 1380 rpm on the 2.5 bar torque curve)",
    "outer.spring.mass": "estimate: 18 coils of 5 mm steel wire on a ~30 mm coil diameter",
    "outer.spring.arc": "estimate: fills the 104 deg slot exactly (120 deg pitch minus two 8 deg stopper halves): "
    "no clearance and no preload at zero windup",
    "outer.spring.effective_radius": "estimate: coil centre line of the outer set in a ~300 mm converter",
    "outer.spring.friction_radius": "estimate: effective radius plus half the ~30 mm coil diameter (the coils rub "
    "on the outer race)",
    "outer.spring.active_coils": "estimate: one coil per segment at the thesis's 18 outer segments ([thesis] §6.2.2); "
    "the default 48 segments hold 0.375 coils each, a discretisation of the continuous spring (Eq. 21 takes "
    "fractional coils per segment; docs/model.md §12)",
    "outer.spring.wire_thickness": "estimate: 5 mm; the block arc (18 x 5 mm / 0.110 m = 47 deg) stays beyond "
    "the hardstop travel, as the hardstops are there to keep the springs off block ([thesis] §5.1)",
    "outer.primary_stopper_half_width": "estimate: 8 deg, leaving a 104 deg slot in the 120 deg pitch",
    "outer.secondary_stopper_half_width": "estimate: equal to the primary stopper, so the spring has neither "
    "clearance nor preload",
    "outer.hardstop_positive": "estimate: 45 deg puts the positive knee at 381 N m/rad x 45 deg = 299 N m, "
    "near the 300 N m the thesis located ([thesis] §6.2.1)",
    "outer.hardstop_negative": "estimate: -10 deg, much less travel under negative torque than positive "
    "([thesis] §5.1, Fig. 5.5)",
    # --- inner set: 5 nested pairs between J_sec and J_ter
    "inner.count": "[thesis] §5.1: 5 nested pairs",
    "inner.spring.stiffness": "estimate: half the pair rate; the thesis splits the set rate evenly between the "
    "two springs of a pair ([thesis] §6.1)",
    "inner.spring.mass": "estimate: about 9 coils of 4 mm steel wire on a ~24 mm coil diameter",
    "inner.spring.arc": "estimate: fills the 60 deg slot (72 deg pitch minus two 6 deg stopper halves); all pairs "
    "of the simulated damper are full length ([thesis] §5.1)",
    "inner.spring.effective_radius": "estimate: the inner set runs on a smaller radius than the outer set "
    "(0.110 m) of a ~300 mm converter",
    "inner.spring.friction_radius": "estimate: effective radius plus about half the ~24 mm coil diameter",
    "inner.spring.active_coils": "estimate: about one coil per segment at the thesis's 8 inner segments; the "
    "thesis found its accuracy against rig data falling once a segment held less than one coil ([thesis] "
    "§6.2.2). The default 16 segments hold 0.56 coils each: in this model the inner count converges (16, 20 "
    "and 24 within 0.5 %, docs/model.md §12), the segments discretising the continuous spring",
    "inner.spring.wire_thickness": "estimate: 4 mm; block arc 9 x 4 mm / 0.075 m = 27.5 deg, well below the "
    "45 deg left at the inner hardstop",
    "inner.nested.stiffness": "estimate: the other half of the pair rate ([thesis] §6.1)",
    "inner.nested.mass": "estimate: about 11 coils of 3 mm steel wire on a ~15 mm coil diameter, inside the "
    "outer spring of the pair",
    "inner.nested.arc": "estimate: same length as its outer spring: the pairs compress together from zero "
    "windup ([thesis] §5.1, larger damper)",
    "inner.nested.effective_radius": "estimate: concentric with the outer spring of the pair",
    "inner.nested.friction_radius": "estimate: effective radius plus half its ~14 mm coil diameter: it rubs on "
    "the inside of the outer spring's coils ([thesis] §5.4)",
    "inner.nested.active_coils": "estimate: more, finer coils than its outer partner",
    "inner.nested.wire_thickness": "estimate: 3 mm; block arc 11 x 3 mm / 0.075 m = 25 deg, below the 45 deg "
    "left at the inner hardstop",
    "inner.primary_stopper_half_width": "estimate: 6 deg, leaving a 60 deg slot in the 72 deg pitch of 5 pairs",
    "inner.secondary_stopper_half_width": "estimate: equal to the primary stopper (no clearance, no preload)",
    "inner.hardstop_positive": "estimate: 15 deg puts the inner knee (628 N m) above the 500 N m test range "
    "([thesis] §6.2.1)",
    "inner.hardstop_negative": "estimate: -6 deg, small travel under negative torque like the outer set "
    "([thesis] §5.1)",
    # --- friction
    "friction.enabled": "[thesis] §5.4: spring friction is part of the model",
    "friction.gamma1": "[thesis] §5.4: 0.2, lubricated steel on steel (Stribeck level)",
    "friction.gamma2": "[thesis] §5.4: 100, Makkar's example value",
    "friction.gamma3": "[thesis] §5.4: 10, Makkar's example value",
    "friction.gamma4": "[thesis] §5.4: 0.2, lubricated steel on steel (Coulomb level)",
    "friction.gamma5": "[thesis] §5.4: 100, Makkar's example value",
    "friction.gamma6": "[thesis] §5.4: 0.01, Makkar's example value",
    "friction.outer.alpha": "[thesis] §6.1: 30 % of the coil surface marked by dye",
    "friction.outer.preload": "estimate: none; [thesis] §6.1 lists a radial preload among the parameters to be "
    "estimated but gives no value, and the springs fill their slots without pre-curvature",
    "friction.pair_outer.alpha": "[thesis] §6.1: 0.15, by the same dye method",
    "friction.pair_outer.preload": "estimate: none, as for the outer springs",
    "friction.pair_inner.alpha": "[thesis] §6.1: 0.55, ratio of the contact areas of the two springs of a pair",
    "friction.pair_inner.preload": "estimate: none, as for the outer springs",
    "friction.alpha_sec": "[thesis] §6.1: 0.5, even split between J_sec and J_ter",
    "friction.alpha_ter": "[thesis] §6.1: 0.5, the other half",
    # --- hardstops
    "hardstops.enabled": "[thesis] §5.5.2: both sets have hardstops",
    "hardstops.stiffness": "model: stiff one-sided contact in place of the thesis's inertia merge; 2e6 N m/rad "
    "keeps the windup within 0.03 deg of the limit at the tested loads (docs/model.md §6)",
    "hardstops.damping": "model: about critical for J_pri against J_sec, so the contact does not rebound "
    "(docs/model.md §6)",
    # --- rig output chain
    "rig.elements.gearbox.inertia": f"{_MID_92} the gearbox (0.100-0.130 kg m^2)",
    "rig.elements.gearbox.inertia_damping": _BJ,
    "rig.elements.gearbox.shaft_stiffness": "[thesis] Table 9.2: inside the gearbox range 9000-12500 N m/rad",
    "rig.elements.gearbox.shaft_damping": f"{_BK}, like the other rig shafts. The former 5 N m s/rad (outside "
    "the range) did not make the 170-210 Hz band of [thesis] §7.2 appear: the magnification at 170-210 Hz "
    "shows no peak with 5 that 50-100 lack, above or below the knee (docs/thesis-comparison.md)",
    "rig.elements.flange_group_1.inertia": f"{_MID_92} flange group 1 (0.025-0.035 kg m^2)",
    "rig.elements.flange_group_1.inertia_damping": _BJ,
    "rig.elements.flange_group_1.shaft_stiffness": f"{_MID_92} the flange groups (1.4e6-1.6e6 N m/rad)",
    "rig.elements.flange_group_1.shaft_damping": _BK,
    "rig.elements.transducer.inertia": f"{_MID_92} the T40B transducer (0.014-0.015 kg m^2)",
    "rig.elements.transducer.inertia_damping": _BJ,
    "rig.elements.transducer.shaft_stiffness": "[thesis] Table 9.2: inside the printed T40B range "
    "250000-2550000 N m/rad, near its top (the lower bound reads like a misprint of 2.50e6)",
    "rig.elements.transducer.shaft_damping": _BK,
    "rig.elements.flange_group_2.inertia": f"{_MID_92} flange group 2 (0.015-0.025 kg m^2)",
    "rig.elements.flange_group_2.inertia_damping": _BJ,
    "rig.elements.flange_group_2.shaft_stiffness": f"{_MID_92} the flange groups (1.4e6-1.6e6 N m/rad)",
    "rig.elements.flange_group_2.shaft_damping": _BK,
    "rig.elements.roba_coupling.inertia": f"{_MID_92} the ROBA coupling (0.057-0.058 kg m^2)",
    "rig.elements.roba_coupling.inertia_damping": _BJ,
    "rig.elements.roba_coupling.shaft_stiffness": f"{_MID_92} the ROBA coupling (1.72e6-1.75e6 N m/rad)",
    "rig.elements.roba_coupling.shaft_damping": _BK,
    "rig.elements.output_motor.inertia": f"{_MID_92} the output motor (1.00-1.15 kg m^2)",
    "rig.elements.output_motor.inertia_damping": _BJ,
    "rig.elements.output_motor.shaft_stiffness": "estimate: same as a flange group ([thesis] Table 9.2 gives none "
    "for the motor)",
    "rig.elements.output_motor.shaft_damping": "estimate: same as a flange group, the middle of the 50-100 "
    "N m s/rad range of [thesis] Table 9.2",
    "rig.output_transducer": "[thesis] §6.2.1: the output torque is measured directly after the gearbox, "
    "at the output transducer",
    # --- output motor
    "motor.mode": "model: PI speed control like the rig's output dynamometer, 'held' as the option "
    "(docs/model.md §2)",
    "motor.proportional_gain": "estimate: 120 N m s/rad on the ~1.3 kg m^2 output side gives about the 15 Hz "
    "bandwidth of the rig's dynamometers ([thesis] §3.1.1)",
    "motor.integral_gain": "estimate: integral action about four times slower than the proportional loop "
    "(2800 / 120 = 23 rad/s), so the held speed has no steady error",
    # --- numerical settings
    "solver.time_step": "model: 1/120 000 s, the largest step of the accuracy grid (docs/model.md §12) whose "
    "orders agree with a 1e-6 s reference within 1 % (or twice their spread) wherever the reference has a "
    "single steady state; it divides the usual output rates. The thesis's Simulink model used 1e-6 s ([thesis] §5.6)",
    "solver.outer_segments": "model: 48, by the segment grid of docs/model.md §12: the excited order within 2 % of a "
    "64/24-segment run at 29 of its 32 points and within 3.4 % at all; the thesis's 18 ([thesis] §6.2.2) miss it by up "
    "to 50 % at 3000 rpm with a small fluctuation, where the centrifugal load leaves only the spring ends moving",
    "solver.inner_segments": "model: 16 with the 48 outer segments (docs/model.md §12); the thesis chose 8 for the "
    "nested springs ([thesis] §6.2.2)",
    "solver.duration": "[thesis] §6.2.1: 0.3 s mean ramp, 0.3 s amplitude ramp, then a 2 s sample: 2.6 s",
    "solver.output_sample_rate": "[thesis] §3.4: 1e4 samples/s, the rig's logging rate for hysteresis loops; "
    "it resolves the 8th order at 2800 rpm (373 Hz) many times over",
    "solver.segment_sample_rate": "estimate: 1 kHz shows the segment motion up to 500 Hz (above the 6th order at "
    "2800 rpm) while the segment record stays a tenth of the time series",
    "solver.friction_scheme": "model: the exponentially fitted implicit friction step, chosen by measurement "
    "against backward Euler and the trapezoidal rule (docs/model.md §12)",
    "solver.friction_tolerance": "model: 0.01 of the friction coefficient (3 % of the law's 0.35 peak): a "
    "tighter value re-solves several times more steps without moving the accuracy grid (docs/model.md §12)",
    "solver.friction_iterations": "model: up to eight Newton re-solves (none of the test points of "
    "docs/model.md §12 needed more than four), then the law's own torque at the last iterate",
    # --- optional effects (all off; docs/model.md §11 and dampersim.discrepancy.effects)
    "effects.clutch_slip.enabled": "model: off, the thesis assumes a locked clutch without slip ([thesis] §5.1); "
    "a candidate effect of the discrepancy workflow (docs/model.md §11)",
    "effects.clutch_slip.capacity": "estimate: 500 N m, the input dynamometer's limit ([thesis] §3.1.1), so a "
    "switched-on clutch slips only near the highest torques the rig can apply",
    "effects.clutch_slip.slip_speed": "estimate: friction builds up over a slip far below the 1-3 rpm the thesis "
    "allows for an over-locked clutch ([thesis] §5.1)",
    "effects.clutch_slip.viscous": "estimate: oil-film drag of a wet clutch, small against the capacity at "
    "slip speeds of a few rad/s",
    "effects.clutch_slip.drive_inertia_fraction": "estimate: cover and pump are most of the lumped primary "
    "inertia; piston plate and drive ring the rest ([thesis] §5.1)",
    "effects.output_backlash.enabled": "model: off, the thesis models no free play (docs/model.md §11)",
    "effects.output_backlash.free_play": "estimate: 0.03 rad (1.7 deg), a typical spline and gear clearance of "
    "a transmission input",
    "effects.inner_short_springs.enabled": "model: off, all nested pairs of the simulated damper are full "
    "length ([thesis] §5.1; docs/model.md §4 and docs/model.md §11)",
    "effects.inner_short_springs.count": "[thesis] §5.1: in the smaller damper 2 of the 5 pairs have a "
    "shorter inner spring",
    "effects.inner_short_springs.stiffness": "estimate: the rate of one inner-of-pair spring of this set "
    "(240 N m/rad); the same wire and coil with 10 instead of 11 coils would be ~10 % stiffer, but the thesis "
    "gives no value for the smaller damper ([thesis] §5.1)",
    "effects.inner_short_springs.clearance": "estimate: 0.1 rad (5.7 deg) of inner windup before the short "
    "springs engage, inside the 15 deg travel (free arc 60 - 5.7 = 54.3 deg in the 60 deg slot)",
    "effects.inner_short_springs.mass": "estimate: the inner-of-pair spring's 0.035 kg scaled to the short "
    "spring's 54.3 deg free arc (same wire and coil, [thesis] §5.1)",
    "effects.inner_short_springs.active_coils": "estimate: the inner-of-pair spring's 11 coils scaled to the "
    "54.3 deg free arc; block arc 10 x 3 mm / 0.075 m = 23 deg, below the 45 deg left at the inner hardstop",
    "effects.turbine_drag.enabled": "model: off, the thesis neglects the oil flow with the clutch locked "
    "([thesis] §5.1; docs/model.md §11)",
    "effects.turbine_drag.coefficient": "estimate: a drag of a few N m at the damper's oscillation speeds "
    "(a few rad/s), small against the outer springs",
    "effects.pendulum_absorber.enabled": "model: off, the simulated damper has no absorber (docs/model.md §11)",
    "effects.pendulum_absorber.order": "estimate: the firing order of a four-cylinder engine, 2, the dominant "
    "order of its torque ([thesis] §3.4)",
    "effects.pendulum_absorber.inertia": "estimate: a small absorber, under 2 % of J_sec",
    "effects.pendulum_absorber.damping": "estimate: light damping of the pendulum swing, so the absorber stays "
    "sharply tuned",
    "effects.nested_radial_transfer.enabled": "model: off, the thesis gives each spring of a pair its own "
    "normal force ([thesis] §5.3.2; docs/model.md §11)",
    "effects.nested_radial_transfer.fraction": "estimate: all of the inner spring's normal force, since the "
    "outer spring is its only support ([thesis] §5.4)",
    "effects.spring_preload.enabled": "model: off, the springs fill their slots without preload "
    "(docs/model.md §11)",
    "effects.spring_preload.force": "estimate: 15 N per mass, about the centrifugal force on an outer-spring "
    "mass at 1000 rpm",
    "effects.transducer_bandwidth.enabled": "model: off, the output torque is recorded as the shaft "
    "carries it (docs/model.md §11)",
    "effects.transducer_bandwidth.cutoff": "estimate: 150 Hz, a slow amplifier or filter setting; the T40B "
    "itself measures up to 3 kHz ([thesis] §3.1.3)",
}


def build() -> DamperSystem:
    """Return the default damper on the test rig (values and origins: see module docs)."""
    outer_spring = ArcSpring(
        stiffness=127.0,
        mass=0.26,
        arc=104.0 * DEG,
        effective_radius=0.110,
        friction_radius=0.125,
        active_coils=18.0,
        wire_thickness=0.005,
    )
    pair_outer = ArcSpring(
        stiffness=240.0,
        mass=0.080,
        arc=60.0 * DEG,
        effective_radius=0.075,
        friction_radius=0.086,
        active_coils=9.0,
        wire_thickness=0.004,
    )
    pair_inner = ArcSpring(
        stiffness=240.0,
        mass=0.035,
        arc=60.0 * DEG,
        effective_radius=0.075,
        friction_radius=0.082,
        active_coils=11.0,
        wire_thickness=0.003,
    )
    return DamperSystem(
        name=NAME,
        source=(
            "Structure, friction law and rig ranges from the 2017 Bath PhD thesis on torque "
            "converter dampers; spring and inertia values estimated (see ORIGINS)"
        ),
        inertias=Inertias(primary=0.20, secondary=0.06, tertiary=0.009),
        outer=SpringSet(
            count=3,
            spring=outer_spring,
            primary_stopper_half_width=8.0 * DEG,
            secondary_stopper_half_width=8.0 * DEG,
            hardstop_positive=45.0 * DEG,
            hardstop_negative=-10.0 * DEG,
        ),
        inner=SpringSet(
            count=5,
            spring=pair_outer,
            nested=pair_inner,
            primary_stopper_half_width=6.0 * DEG,
            secondary_stopper_half_width=6.0 * DEG,
            hardstop_positive=15.0 * DEG,
            hardstop_negative=-6.0 * DEG,
        ),
        friction=Friction(
            outer=SpringFriction(alpha=0.30),
            pair_outer=SpringFriction(alpha=0.15),
            pair_inner=SpringFriction(alpha=0.55),
        ),
        hardstops=Hardstops(),
        rig=Rig(
            elements=(
                RigElement("gearbox", 0.115, 0.010, 10500.0, 75.0),
                RigElement("flange_group_1", 0.030, 0.010, 1.5e6, 75.0),
                RigElement("transducer", 0.0145, 0.010, 2.5e6, 75.0),
                RigElement("flange_group_2", 0.020, 0.010, 1.5e6, 75.0),
                RigElement("roba_coupling", 0.0575, 0.010, 1.735e6, 75.0),
                RigElement("output_motor", 1.075, 0.010, 1.5e6, 75.0),
            ),
            output_transducer="transducer",
        ),
        motor=OutputMotor(),
        solver=Solver(),
    )
