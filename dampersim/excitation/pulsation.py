"""The motored-engine pulsation generator as a torque source ([thesis] chapter 4).

:func:`simulate_pulsation` integrates the generator's chain (input dyno, coupling, four
flexible crank sections with their cylinders, flange, transducer) either alone on a
torsionally stiff propshaft to a held output dyno ([thesis] §4.3.1, "pulsation generator
only" tests) or coupled to the damper and rig (model-spec §2, the rig mode of [thesis]
§4.2). Coupled, the transducer's shaft drives J_pri of the full nonlinear damper model
(arc-spring segments, friction, hardstops, the rig's output chain with its PI output
motor): one kernel marches the generator and the damper with the same step, so the
interaction of the generator with the rig's inertias and stiffnesses, which the thesis
names as the cause of the 4th-order dominance on the rig ([thesis] §4.3.2), includes
the damper's friction and hardstop contacts.

:func:`pulsation_excitation` turns the generator's output torque into a
:class:`~dampersim.excitation.MeasuredTorque` that drives the full nonlinear damper
model, as the thesis drove its damper with measured pulsation-generator records (§6.2.1).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field, replace

import numpy as np

from dampersim.errors import InputError, SimulationDiverged
from dampersim.parameters.engine import BAR, PRESSURE_THESIS_BAR, PulsationGenerator, check_pressure_bar, default_pulsation_generator
from dampersim.units import rad_s_to_rpm, rpm_to_rad_s

#: Speeds the generator model accepts [rpm] and where the thesis ran it ([thesis] §3.3.2,
#: §7.1.3: the rig's dynamometers are limited to 3000 rpm; the model was validated up to it).
SPEED_LIMITS_RPM = (500.0, 4000.0)
SPEED_VALIDATED_RPM = (900.0, 3000.0)
DEFAULT_ORDERS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)
ANALYSIS_WINDOW = 1.25


def check_speed_rpm(rpm, warn=True) -> list:
    """Raise InputError outside SPEED_LIMITS_RPM; return warnings (and print them to
    stderr when ``warn``) outside the validated range."""
    lo, hi = SPEED_LIMITS_RPM
    try:
        r = float(rpm)
    except (TypeError, ValueError):
        r = float("nan")
    if not (math.isfinite(r) and lo <= r <= hi):
        raise InputError(f"speed {rpm!r} rpm: accepted is {lo:g} to {hi:g} rpm for the pulsation generator model")
    out = []
    vlo, vhi = SPEED_VALIDATED_RPM
    if not vlo <= r <= vhi:
        out.append(f"warning: {r:g} rpm lies outside {vlo:g}-{vhi:g} rpm, where the thesis validated the model")
    if warn:
        for w in out:
            print(w, file=sys.stderr)
    return out


def pressure_warnings(pressure_bar) -> list:
    lo, hi = PRESSURE_THESIS_BAR
    if not lo <= pressure_bar <= hi:
        return [f"warning: {pressure_bar:g} bar lies outside the {lo:g}-{hi:g} bar the thesis used"]
    return []


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
    #: dampersim.solver._kernels: speeds, windups, hardstop torques, energies); else None
    damper_record: np.ndarray | None = field(default=None, repr=False)

    def window(self, seconds: float = ANALYSIS_WINDOW) -> slice:
        n = int(round(seconds * self.sample_rate))
        return slice(max(0, len(self.t) - n), len(self.t))

    def order_amplitudes(self, orders=DEFAULT_ORDERS, which="output", seconds=ANALYSIS_WINDOW) -> np.ndarray:
        from dampersim.signal import order_amplitudes

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
    from dampersim.solver import _kernels as kern
    from dampersim.solver.engine_layout import build_engine_layout

    if not (math.isfinite(speed) and speed > 0):
        raise InputError(f"speed = {speed!r} rad/s: accepted is a positive speed")
    check_speed_rpm(rad_s_to_rpm(speed), warn=False)
    p = check_pressure_bar(pressure_bar)
    if not (math.isfinite(mean_torque) and abs(mean_torque) <= 1000.0):
        raise InputError(f"mean torque {mean_torque!r} N m: accepted is within +-1000 N m")
    if not (duration > mean_ramp + gas_ramp + ANALYSIS_WINDOW - 1e-9):
        raise InputError(f"duration {duration!r} s: accepted is at least {mean_ramp + gas_ramp + ANALYSIS_WINDOW:g} s")
    pg = generator if generator is not None else default_pulsation_generator()
    pg = replace(pg, charge_pressure=p * BAR)
    lay = build_engine_layout(pg, float(speed), float(time_step), coupled=bool(coupled))
    nsteps = int(round(duration / time_step))
    t = np.arange(nsteps) * time_step
    setpoint = mean_torque * np.clip(t / mean_ramp, 0.0, 1.0) if mean_ramp > 0 else np.full(nsteps, mean_torque)
    gas = np.clip((t - mean_ramp) / gas_ramp, 0.0, 1.0) if gas_ramp > 0 else np.ones(nsteps)
    setpoint = np.ascontiguousarray(setpoint, dtype=np.float64)
    gas = np.ascontiguousarray(gas, dtype=np.float64)
    rec_every = max(1, int(round(1.0 / (sample_rate * time_step))))
    nrec = (nsteps + rec_every - 1) // rec_every
    rec = np.zeros((nrec, kern.NEREC))
    q = np.zeros(len(lay.CH))
    v = np.zeros(len(lay.CH))
    drec = None
    if coupled:
        drec, wall = _run_coupled(system, float(speed), float(time_step), sample_rate, nsteps, rec_every, setpoint, gas,
                                  lay, q, v, rec)
    else:
        t0 = time.perf_counter()
        status, step = kern.engine_integrate(q, v, setpoint, gas, lay.PE, lay.CH, lay.CYL, rec_every, rec)
        wall = time.perf_counter() - t0
        if status != 0:
            raise SimulationDiverged(step * time_step, "NaN in the state" if status == 1 else "runaway speed", time_step)
    fs = 1.0 / (rec_every * time_step)
    steady = rec[:, kern.ER_T] >= mean_ramp + gas_ramp
    return PulsationResult(
        t=rec[:, kern.ER_T],
        output_torque=rec[:, kern.ER_TLINK],
        dyno_torque=rec[:, kern.ER_TDYNO],
        crank_angle=rec[:, kern.ER_THETA1],
        cylinder_pressure=rec[:, kern.ER_P1],
        gas_torque=rec[:, kern.ER_TGAS],
        inertia_torque=rec[:, kern.ER_TINER],
        friction_torque=rec[:, kern.ER_TFRIC],
        damper_output_torque=rec[:, kern.ER_TOUT],
        peak_pressure=float(np.max(rec[steady, kern.ER_PMAX])),
        speed=float(speed),
        mean_torque_set=float(mean_torque),
        charge_pressure=p * BAR,
        coupled=bool(coupled),
        sample_rate=fs,
        wall_time=wall,
        damper_record=drec,
    )


def _run_coupled(system, speed, time_step, sample_rate, nsteps, rec_every, setpoint, gas, lay, q, v, rec):
    """March the generator (state q, v; record ``rec``) coupled to the full damper model
    with the common step ``time_step`` [s]; returns the damper's record and the wall
    time [s] (compilation excluded)."""
    from dampersim.parameters import default_parameters
    from dampersim.parameters.validation import validate
    from dampersim.simulation import _STATUS, ensure_compiled
    from dampersim.solver import _kernels as kern
    from dampersim.solver.layout import build_layout, initial_state

    sysm = system if system is not None else default_parameters()
    _refuse_incompatible_effects(sysm)
    own = sysm.solver.time_step
    if own != default_parameters().solver.time_step and own != time_step:
        # a step the user chose for the damper cannot apply: the chain sets the common step
        print(f"warning: solver.time_step = {own:g} s is replaced by the coupled run's common step "
              f"{time_step:g} s (the generator's)", file=sys.stderr)
    sysm = replace(sysm, solver=replace(sysm.solver, time_step=time_step, output_sample_rate=sample_rate))
    validate(sysm)
    dl = build_layout(sysm, speed)
    ensure_compiled(dl)
    dq, dv = initial_state(dl)
    drec = np.zeros((rec.shape[0], kern.NREC))
    seg = np.zeros((0, dl.n_nodes))
    t0 = time.perf_counter()
    status, step = kern.integrate(
        dq, dv, np.zeros(nsteps), dl.P, dl.SF, dl.SI, dl.J, dl.rig, dl.contacts_idx, dl.contacts_f, dl.singles, dl.pairs,
        dl.n_nodes, rec_every, nsteps + 1, drec, seg, q, v, setpoint, gas, lay.PE, lay.CH, lay.CYL, rec,
    )
    wall = time.perf_counter() - t0
    if status != 0:
        raise SimulationDiverged(step * time_step, _STATUS.get(int(status), "unknown"), time_step)
    return drec, wall


def _refuse_incompatible_effects(system) -> None:
    """The coupled mode owns the input side of J_pri: it cannot be combined with an
    effect that moves the input torque elsewhere (lock-up clutch slip)."""
    from dampersim.errors import ParameterError

    effects = getattr(system, "effects", None)
    slip = getattr(effects, "clutch_slip", None) if effects is not None else None
    on = getattr(slip, "enabled", slip) if slip is not None else False
    if on:
        raise ParameterError("effects.clutch_slip", True, "off when the pulsation generator is coupled to the damper "
                             "(the coupled input chain drives J_pri directly)")


def pulsation_excitation(result: PulsationResult):
    """The generator's steady output torque as a MeasuredTorque drive for :func:`simulate`."""
    from dampersim.excitation.measured import MeasuredTorque

    sel = result.t >= result.t[-1] - 2.0 + 1e-12
    return MeasuredTorque(speed=result.speed, time=result.t[sel], torque_samples=result.output_torque[sel])


def dominant_order_over_speed(speeds_rpm, pressure_bar=2.5, mean_torque=200.0, coupled=False, orders=(2.0, 4.0, 6.0),
                              **kw) -> list:
    """[(rpm, dominant order, amplitudes)] over a speed list ([thesis] Fig. 4.12)."""
    out = []
    for rpm in speeds_rpm:
        res = simulate_pulsation(rpm_to_rad_s(rpm), pressure_bar, mean_torque, coupled, **kw)
        amp = res.order_amplitudes(orders)
        out.append((float(rpm), float(orders[int(np.argmax(amp))]), [float(a) for a in amp]))
    return out


__all__ = [
    "SPEED_LIMITS_RPM",
    "SPEED_VALIDATED_RPM",
    "PulsationResult",
    "simulate_pulsation",
    "pulsation_excitation",
    "dominant_order_over_speed",
    "check_speed_rpm",
    "pressure_warnings",
]
