"""Runs of the pulsation generator ([thesis] chapter 4), alone or driving the damper, through the solver's driver.

:func:`simulate_pulsation` integrates the generator's chain (input dyno, coupling, four
flexible crank sections with their cylinders, flange, transducer) either alone on a
torsionally stiff propshaft to a held output dyno ([thesis] §4.3.1, "pulsation generator
only" tests) or coupled to the damper and rig (docs/model.md §2, the rig mode of [thesis]
§4.2). Coupled, the transducer's shaft drives J_pri of the full nonlinear damper model
(arc-spring segments, friction, hardstops, the rig's output chain with its PI output
motor): one kernel marches the generator and the damper with the same step, so the
interaction of the generator with the rig's inertias and stiffnesses, which the thesis
names as the cause of the 4th-order dominance on the rig ([thesis] §4.3.2), includes
the damper's friction and hardstop contacts.

:func:`pulsation_excitation` turns the generator's output torque into a
:class:`~dampersim.excitation.MeasuredTorque` that drives the full nonlinear damper
model, as the thesis drove its damper with measured pulsation-generator records (§6.2.1).
The source itself (speed, pressure, set point, start-up) and its checks are
:class:`dampersim.excitation.pulsation.PulsationSource`.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, replace

import numpy as np

from dampersim.errors import InputError
from dampersim.excitation.pulsation import PulsationSource
from dampersim.parameters.engine import BAR, PulsationGenerator
from dampersim.solver.driver import CoupledGenerator, run_damper, run_generator
from dampersim.solver.engine_layout import (
    ER_P1,
    ER_PMAX,
    ER_T,
    ER_TDYNO,
    ER_TFRIC,
    ER_TGAS,
    ER_THETA1,
    ER_TINER,
    ER_TLINK,
    ER_TOUT,
    NEREC,
    build_engine_layout,
)
from dampersim.units import rad_s_to_rpm, rpm_to_rad_s
from dampersim.errors import ParameterError
from dampersim.excitation.measured import MeasuredTorque
from dampersim.parameters import default_parameters
from dampersim.parameters.validation import validate
from dampersim.signal import order_amplitudes
from dampersim.solver.layout import build_layout
from dampersim.solver.linear import check_time_step

DEFAULT_ORDERS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)
ANALYSIS_WINDOW = 1.25


@dataclass(frozen=True, eq=False)
class PulsationResult:
    """Time series of one pulsation generator run (SI units)."""

    t: np.ndarray = field(repr=False)
    output_torque: np.ndarray = field(repr=False)  # torque leaving the generator [N m]
    dyno_torque: np.ndarray = field(repr=False)
    crank_angle: np.ndarray = field(repr=False)  # cylinder 1 crank angle [rad]
    cylinder_pressure: np.ndarray = field(repr=False)  # cylinder 1 [Pa]
    gas_torque: np.ndarray = field(repr=False)
    inertia_torque: np.ndarray = field(repr=False)
    friction_torque: np.ndarray = field(repr=False)
    damper_output_torque: np.ndarray = field(repr=False)  # coupled: rig output transducer [N m]
    peak_pressure: float
    speed: float
    mean_torque_set: float
    charge_pressure: float
    coupled: bool
    sample_rate: float
    wall_time: float
    #: coupled: the damper model's record on the same rows (columns R_* of
    #: dampersim.solver.layout: speeds, windups, hardstop torques, energies); else None
    damper_record: np.ndarray | None = field(default=None, repr=False)

    def window(self, seconds: float = ANALYSIS_WINDOW) -> slice:
        n = int(round(seconds * self.sample_rate))
        return slice(max(0, len(self.t) - n), len(self.t))

    def order_amplitudes(self, orders=DEFAULT_ORDERS, which="output", seconds=ANALYSIS_WINDOW) -> np.ndarray:
        x = {"output": self.output_torque, "damper_output": self.damper_output_torque, "gas": self.gas_torque}[which]
        return np.asarray(order_amplitudes(x[self.window(seconds)], self.sample_rate, self.speed, orders))

    @property
    def mean_output_torque(self) -> float:
        return float(np.mean(self.output_torque[self.window()]))

    def summary(self, orders=DEFAULT_ORDERS) -> dict:
        """The ``pulsation --json`` document."""
        amp = self.order_amplitudes(orders)
        k = int(np.argmax(amp))
        return {
            "orders": [float(o) for o in orders],
            "amplitude_nm": [float(a) for a in amp],
            "dominant_order": float(orders[k]),
            "mean_torque_nm": self.mean_output_torque,
            "peak_cylinder_pressure_bar": self.peak_pressure / BAR,
            "speed_rpm": float(rad_s_to_rpm(self.speed)),
            "pressure_bar": self.charge_pressure / BAR,
            "coupled": self.coupled,
            "wall_time_s": self.wall_time,
        }


def simulate_pulsation(
    speed: float,
    pressure_bar: float = 2.5,
    mean_torque: float = 200.0,
    coupled: bool = False,
    system=None,
    generator: PulsationGenerator | None = None,
    duration: float = 2.6,
    time_step: float = 1.0e-5,
    sample_rate: float = 10000.0,
    mean_ramp: float = 0.3,
    gas_ramp: float = 0.3,
) -> PulsationResult:
    """Run the pulsation generator at nominal ``speed`` [rad/s].

    pressure_bar: charge pressure P_c [bar abs] (0.5-4; the thesis used 1-3);
    mean_torque: mean torque set on the generator's output [N m] (the input dyno's
    integral control holds it, [thesis] §4.3.1); coupled: drive the full damper and rig
    model (``system``, default parameters; its own time step and sample rate are
    replaced by ``time_step`` and ``sample_rate``) instead of the stiff propshaft;
    duration [s], time_step [s], sample_rate [Hz] of the records; start-up as the
    thesis's (§6.2.1): the mean set point ramps over ``mean_ramp`` s, the cylinder
    charge's effect over ``gas_ramp`` s.
    """
    src = PulsationSource(speed, pressure_bar, mean_torque, generator, mean_ramp, gas_ramp)
    if not (duration > mean_ramp + gas_ramp + ANALYSIS_WINDOW - 1e-9):
        raise InputError(f"duration {duration!r} s: accepted is at least {mean_ramp + gas_ramp + ANALYSIS_WINDOW:g} s")
    lay = build_engine_layout(src.charged_generator(), float(speed), float(time_step), coupled=bool(coupled))
    nsteps = int(round(duration / time_step))
    t = np.arange(nsteps) * time_step
    setpoint = np.ascontiguousarray(src.setpoint(t), dtype=np.float64)
    gas = np.ascontiguousarray(src.gas_scale(t), dtype=np.float64)
    rec_every = max(1, int(round(1.0 / (sample_rate * time_step))))
    nrec = (nsteps + rec_every - 1) // rec_every
    rec = np.zeros((nrec, NEREC))
    drec = None
    if coupled:
        gen = CoupledGenerator(lay, np.zeros(len(lay.CH)), np.zeros(len(lay.CH)), setpoint, gas, rec)
        drec, wall = _run_coupled(system, float(speed), float(time_step), sample_rate, nsteps, rec_every, gen)
    else:
        wall = run_generator(lay, setpoint, gas, rec_every, rec)
    fs = 1.0 / (rec_every * time_step)
    steady = rec[:, ER_T] >= mean_ramp + gas_ramp
    return PulsationResult(
        t=rec[:, ER_T],
        output_torque=rec[:, ER_TLINK],
        dyno_torque=rec[:, ER_TDYNO],
        crank_angle=rec[:, ER_THETA1],
        cylinder_pressure=rec[:, ER_P1],
        gas_torque=rec[:, ER_TGAS],
        inertia_torque=rec[:, ER_TINER],
        friction_torque=rec[:, ER_TFRIC],
        damper_output_torque=rec[:, ER_TOUT],
        peak_pressure=float(np.max(rec[steady, ER_PMAX])),
        speed=float(speed),
        mean_torque_set=float(mean_torque),
        charge_pressure=src.charge_pressure,
        coupled=bool(coupled),
        sample_rate=fs,
        wall_time=wall,
        damper_record=drec,
    )


def _run_coupled(system, speed, time_step, sample_rate, nsteps, rec_every, gen: CoupledGenerator):
    """March the generator ``gen`` coupled to the full damper model with the common step
    ``time_step`` [s]; returns the damper's record and the wall time [s] (compilation
    excluded)."""

    sysm = system if system is not None else default_parameters()
    _refuse_incompatible_effects(sysm)
    own = sysm.solver.time_step
    if own != default_parameters().solver.time_step and own != time_step:
        # a step the user chose for the damper cannot apply: the chain sets the common step
        print(f"warning: solver.time_step = {own:g} s is replaced by the coupled run's common step "
              f"{time_step:g} s (the generator's)", file=sys.stderr)
    sysm = replace(sysm, solver=replace(sysm.solver, time_step=time_step, output_sample_rate=sample_rate))
    check_time_step(validate(sysm))
    dl = build_layout(sysm, speed)
    run = run_damper(dl, np.zeros(nsteps), rec_every, gen.rec.shape[0], seg_every=nsteps + 1, nseg=0, generator=gen)
    return run.rec, run.wall_time


def _refuse_incompatible_effects(system) -> None:
    """The coupled mode owns the input side of J_pri: it cannot be combined with an
    effect that moves the input torque elsewhere (lock-up clutch slip)."""

    effects = getattr(system, "effects", None)
    slip = getattr(effects, "clutch_slip", None) if effects is not None else None
    on = getattr(slip, "enabled", slip) if slip is not None else False
    if on:
        raise ParameterError("effects.clutch_slip", True, "off when the pulsation generator is coupled to the damper "
                             "(the coupled input chain drives J_pri directly)")


def pulsation_excitation(result: PulsationResult):
    """The generator's steady output torque as a MeasuredTorque drive for :func:`simulate`."""

    sel = result.t >= result.t[-1] - 2.0 + 1e-12
    return MeasuredTorque(speed=result.speed, time=result.t[sel], torque_samples=result.output_torque[sel])


def dominant_order_over_speed(speeds_rpm, pressure_bar=2.5, mean_torque=200.0, coupled=False, orders=(2.0, 4.0, 6.0),
                              progress=None, **kw) -> list:
    """[(rpm, dominant order, amplitudes [N m])] over a speed list [rpm] ([thesis] Fig. 4.12);
    ``progress(done, total)`` is called after each speed."""
    speeds_rpm = list(speeds_rpm)
    out = []
    for i, rpm in enumerate(speeds_rpm):
        res = simulate_pulsation(rpm_to_rad_s(rpm), pressure_bar, mean_torque, coupled, **kw)
        amp = res.order_amplitudes(orders)
        out.append((float(rpm), float(orders[int(np.argmax(amp))]), [float(a) for a in amp]))
        if progress is not None:
            progress(i + 1, len(speeds_rpm))
    return out


__all__ = ["PulsationResult", "simulate_pulsation", "pulsation_excitation", "dominant_order_over_speed"]
