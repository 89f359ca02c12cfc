"""A fast stand-in for the damper model, so that whole diagnoses run in seconds in tests.

The diagnosis drives its model through :func:`dampersim.discrepancy.drive.simulate_point`;
with ``workers=1`` every run goes through that module attribute in this process, so a
test can monkeypatch it with :func:`fake_model`. The stand-in's output order amplitudes
depend smoothly on the outer spring rate and J_sec (what the calibration moves) and on
two effects with the same signature: ``turbine_drag`` (coefficient / 3 times the bump)
and ``clutch_slip`` (540 N m / capacity times the bump). A ramp point's windup is the input
torque over a rate that follows the outer spring, plus a loop for a slipping clutch
(:func:`ramp_windup`). A test campaign is measured from the same construction, so measured
and simulated amplitudes agree exactly where the stand-in is right.
"""

from __future__ import annotations

import dataclasses
import math
import zlib

import numpy as np

from dampersim.discrepancy import drive, tracking
from dampersim.discrepancy.campaign import Campaign, MeasuredPoint
from dampersim.discrepancy.likelihood import measured_coefficients
from dampersim.errors import SimulationDiverged
from dampersim.parameters import default_parameters

RATE = 4000.0  # [Hz]: resolves order 8 at 2500 rpm (333 Hz)
SECONDS = 0.6  # [s]: at least 0.5 s and 8 revolutions at 1000 rpm
BASE = default_parameters()
#: (id, speed [rpm], mean torque [N m]) of the six-point campaign; every third (p1, p4) is held out
POINTS = [("p0", 1000.0, 150.0), ("p1", 1300.0, 250.0), ("p2", 1600.0, 100.0), ("p3", 1900.0, 350.0),
          ("p4", 2200.0, 200.0), ("p5", 2500.0, 50.0)]
#: what neither effect explains (N m at order 6): keeps the right effect's held-out gap above 0
EXTRA = np.array([0, 0, 0, 0, 0, 0.3, 0, 0])
#: white sensor noise on the measured output [N m RMS]: about 0.3 N m on each order of a
#: 0.6 s record, so that EXTRA stays within the noise a likelihood judges against
NOISE_NM = 10.0


def bump(rpm: float) -> np.ndarray:
    """The effects' signature [N m per unit magnitude]: orders 2 and 4, opposite trends with speed."""
    out = np.zeros(len(drive.ORDERS))
    out[1], out[3] = 3.0 * rpm / 1500.0, 1.5 * 1500.0 / rpm
    return out


def amplitudes(system, rpm: float, torque: float) -> np.ndarray:
    """Output order amplitudes 1-8 [N m] the stand-in gives for ``system`` at one point."""
    k = system.outer.spring.stiffness / BASE.outer.spring.stiffness
    j = system.inertias.secondary / BASE.inertias.secondary
    y = np.array([12.0 / n for n in range(1, 9)]) * (1.0 + torque / 400.0) * math.sqrt(rpm / 1500.0)
    y = y * k ** 0.3 * j ** -0.2
    fx = system.effects
    if fx.turbine_drag.enabled:
        y = y + fx.turbine_drag.coefficient / 3.0 * bump(rpm)
    if fx.clutch_slip.enabled:
        y = y + 540.0 / fx.clutch_slip.capacity * bump(rpm)
    return y


def signal(time, rpm: float, torque: float, amps) -> np.ndarray:
    """Mean torque plus cosines of the orders 1-8 with amplitudes ``amps`` [N m]."""
    w = rpm * math.pi / 30.0
    return torque + sum(a * np.cos(n * w * time) for n, a in zip(drive.ORDERS, amps))


def point(pid: str, rpm: float, torque: float, amps=None) -> MeasuredPoint:
    """A torsional point whose output carries ``amps`` (default: the stand-in with the
    estimated parameters, turbine drag of coefficient 3 and EXTRA)."""
    from dampersim.discrepancy.effects import with_effect

    if amps is None:
        amps = amplitudes(with_effect(BASE, "turbine_drag", {"coefficient": 3.0}), rpm, torque) + EXTRA
    t = np.arange(int(SECONDS * RATE) + 1) / RATE
    drive_in = signal(t, rpm, torque, [50.0 / n for n in range(1, 9)])
    noise = np.random.default_rng(zlib.crc32(pid.encode())).normal(0.0, NOISE_NM, t.size)
    return MeasuredPoint(id=pid, kind="torsional", speed_rpm=rpm, mean_torque_nm=torque, sample_rate_hz=RATE, time=t,
                         input_torque=drive_in, output_torque=signal(t, rpm, torque, amps) + noise,
                         input_speed_rpm=np.full(t.size, rpm), output_speed_rpm=np.full(t.size, rpm),
                         file=f"points/{pid}.parquet")


def ramp(pid: str, rpm: float = 1500.0) -> MeasuredPoint:
    """A hysteresis ramp point (3 s, 0 -> 300 -> 0 N m)."""
    t = np.arange(int(3.0 * 1000.0) + 1) / 1000.0
    tq = 300.0 * np.minimum(t, 3.0 - t) / 1.5
    return MeasuredPoint(id=pid, kind="ramp", speed_rpm=rpm, mean_torque_nm=0.0, sample_rate_hz=1000.0, time=t,
                         input_torque=tq, output_torque=tq, input_speed_rpm=np.full(t.size, rpm),
                         output_speed_rpm=np.full(t.size, rpm), windup=tq / 3000.0, file=f"points/{pid}.parquet")


def campaign(points, name: str = "fake") -> Campaign:
    """An in-memory campaign of ``points`` (no problems)."""
    return Campaign(path=name, name=name, points=list(points), problems=[], rows=len(points))


def ramp_windup(system, p) -> np.ndarray:
    """The stand-in's windup [rad] over a ramp point's record: the input torque over a rate
    that scales with the outer spring rate (3000 N m/rad at the estimate, as :func:`ramp`'s
    measured windup), and a slipping clutch opening a loop of 0.001 rad x 540 N m / capacity
    (half of it up while loading, down while unloading)."""
    k = 3000.0 * system.outer.spring.stiffness / BASE.outer.spring.stiffness
    w = np.asarray(p.input_torque, dtype=float) / k
    fx = system.effects
    if fx.clutch_slip.enabled:
        w = w + 0.5e-3 * 540.0 / fx.clutch_slip.capacity * np.sign(np.gradient(p.input_torque))
    return w


def fake_model(fail=None):
    """A replacement for ``drive.simulate_point``. fail(system, point) -> None, "raise"
    (the integration diverges) or "nan" (the run returns non-finite amplitudes)."""
    def simulate_point(system, p, halves=False):
        how = fail(system, p) if fail else None
        if how == "raise":
            raise SimulationDiverged(0.1, "runaway windup", system.solver.time_step)
        if how == "nan":
            return {"orders": np.full(len(drive.ORDERS), np.nan), "coefficients": np.full(len(drive.ORDERS), np.nan + 0j),
                    "halves": np.full((2, len(drive.ORDERS)), np.nan + 0j)}
        if p.kind == "ramp":
            return {"torque": p.input_torque, "windup": ramp_windup(system, p)}
        amps = amplitudes(system, p.speed_rpm, p.mean_torque_nm)
        # read like the measured output: the same tracked operator on the same record
        out = dataclasses.replace(p, output_torque=signal(p.time, p.speed_rpm, p.mean_torque_nm, amps))
        c = measured_coefficients(out, drive.ORDERS)
        return {"orders": np.abs(c), "coefficients": c,
                "halves": tracking.half_coefficients(out, out.output_torque, drive.ORDERS)}
    simulate_point.fake = True  # tells fake_design_task to stand in for the design's runs too
    return simulate_point


def fake_design_task(args) -> dict:
    """The stand-in's output amplitudes for a next-test design candidate (system, speed
    [rad/s], mean torque [N m], orders text), as :func:`dampersim.discrepancy.design.design_task`
    returns them."""
    system, speed, torque, _text = args
    return {"orders": amplitudes(system, speed * 30.0 / math.pi, torque)}
