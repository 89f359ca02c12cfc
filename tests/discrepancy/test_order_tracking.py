"""Measured campaigns read their orders on the measured input speed (order tracking), and the
model runs they drive are read with the same angle over the same revolutions."""

import math
from types import SimpleNamespace

import numpy as np

from dampersim.discrepancy import drive, tracking
from dampersim.discrepancy.likelihood import measured_coefficients
from dampersim.discrepancy.campaign import MeasuredPoint, read_campaign
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.signal import order_amplitudes

FS = 5000.0  # [Hz]
SECONDS = 1.25  # [s]
RPM = 1500.0
IN_AMPS = np.array([20.0, 200.0, 15.0, 60.0, 10.0, 25.0, 8.0, 12.0])  # [N m]
OUT_AMPS = np.array([6.0, 40.0, 5.0, 12.0, 3.0, 4.0, 2.0, 2.5])  # [N m]


def shaft(t, rpm0=RPM, rpm1=1530.0, ripple=0.02, vibration=0.02):
    """(angle [rad], speed [rad/s]) at ``t`` [s]: the rig's speed drifting from rpm0 to rpm1
    over the record and rippling slowly by ``ripple`` (relative) at 0.3 times the 1st
    order's frequency; angle is the angle of that motion, which the excitation follows. The
    speed channel also carries the damper's torsional vibration, ``vibration`` (relative) at
    the 2nd order, which the excitation does not follow."""
    w0, w1 = rpm0 * math.pi / 30.0, rpm1 * math.pi / 30.0
    acc = (w1 - w0) / SECONDS
    base = w0 * t + 0.5 * acc * t ** 2
    angle = base + ripple / 0.3 * np.sin(0.3 * base)
    speed = (w0 + acc * t) * (1.0 + ripple * np.cos(0.3 * base))
    return angle, speed * (1.0 + vibration * np.sin(2.0 * angle))


def orders_at(angle, amps, mean=300.0):
    return mean + sum(a * np.cos(k * angle + 0.4 * k) for k, a in zip(drive.ORDERS, amps))


def drifting_point(t=None, speed_scale=1.0):
    t = np.arange(int(FS * SECONDS)) / FS if t is None else t
    angle, speed = shaft(t)
    rpm = speed * speed_scale * 30.0 / math.pi
    return MeasuredPoint(id="p0", kind="torsional", speed_rpm=RPM, mean_torque_nm=300.0, sample_rate_hz=FS, time=t,
                         input_torque=orders_at(angle, IN_AMPS), output_torque=orders_at(angle, OUT_AMPS),
                         input_speed_rpm=rpm, output_speed_rpm=rpm.copy(), file="points/p0.parquet")


def test_measured_orders_are_tracked_on_the_speed_channel():
    p = drifting_point()
    # 1 %: the tracking itself is exact to 3e-5 on noise-free records, the speed channel's
    # vibration at the 2nd order filtered out (tests/unit/test_ordertrack.py)
    np.testing.assert_allclose(np.abs(measured_coefficients(p, drive.ORDERS)), OUT_AMPS, rtol=0.01)
    # the nominal-speed read-out the campaign used before is more than 5 % off here (5x the
    # tolerance above)
    nominal = order_amplitudes(p.output_torque, FS, p.speed, drive.ORDERS)
    assert np.max(np.abs(nominal / OUT_AMPS - 1.0)) > 0.05


def fake_run(point, steady_start=0.6, rate=3 * FS, speed_scale=1.0):
    """A model run that reproduces the record exactly, on its own finer time base that starts
    ``steady_start`` [s] before the record (as :class:`dampersim.excitation.MeasuredTorque`)."""
    t = np.arange(int(rate * (steady_start + SECONDS))) / rate
    angle, _ = shaft(t - steady_start)
    res = SimpleNamespace(t=t, output_torque=orders_at(angle, OUT_AMPS), sample_rate=rate)
    res.window = lambda seconds: slice(t.size - min(t.size, int(round(seconds * rate))), t.size)
    return res


def test_a_driven_run_is_read_through_the_same_operator_as_the_measurement():
    p = drifting_point()
    sim = tracking.driven_orders(p, fake_run(p), 0.6, drive.ORDERS)
    # 1e-4: the same orders read by one exact method on two time bases (2e-5 each)
    np.testing.assert_allclose(sim, np.abs(measured_coefficients(p, drive.ORDERS)), rtol=1e-4)
    # a speed channel 1 % off in scale misreads both alike: the gap stays closed
    q = drifting_point(speed_scale=1.01)
    meas = np.abs(measured_coefficients(q, drive.ORDERS))
    assert np.max(np.abs(meas / OUT_AMPS - 1.0)) > 0.02  # the misread (order 8 lands 2.5 bins away)
    np.testing.assert_allclose(tracking.driven_orders(q, fake_run(q), 0.6, drive.ORDERS), meas, rtol=1e-3)


def test_without_a_speed_channel_the_nominal_spectrum_is_kept():
    p = drifting_point()
    q = MeasuredPoint(**{**p.__dict__, "input_speed_rpm": None})
    np.testing.assert_array_equal(np.abs(measured_coefficients(q, drive.ORDERS)), order_amplitudes(p.output_torque, FS, p.speed, drive.ORDERS))
    res = fake_run(q)
    w = res.window(q.duration)
    np.testing.assert_array_equal(tracking.driven_orders(q, res, 0.6, drive.ORDERS),
                                  order_amplitudes(res.output_torque[w], res.sample_rate, q.speed, drive.ORDERS))


def test_a_campaign_point_with_an_unusable_speed_channel_is_reported(tmp_path):
    good = drifting_point()
    rpm = good.input_speed_rpm.copy()
    rpm[200:210] = 0.0  # a dropout of the speed pickup
    bad = MeasuredPoint(**{**good.__dict__, "id": "p1", "input_speed_rpm": rpm, "file": "points/p1.parquet"})
    write_campaign(tmp_path / "c", [good, bad])
    camp = read_campaign(tmp_path / "c")
    assert [p.id for p in camp.points] == ["p0"]
    (prob,) = camp.problems
    assert prob.point == "p1" and prob.field == "input_speed_rpm"
    assert "10 samples are zero or negative" in prob.message and "accepted" in prob.message
