"""Tests of dampersim.analysis.ordertrack: order amplitudes and phases on the measured shaft angle."""

import math

import numpy as np
import pytest

from dampersim.analysis.ordertrack import (LOWPASS_SHARE, lowpass_cutoff, track_orders, track_orders_by_speed,
                                          tracking_angle)
from dampersim.errors import InputError
from dampersim.signal import order_amplitudes

FS = 5000.0  # [Hz] the synthetic campaigns' torque sample rate
SECONDS = 1.25  # [s] the thesis's record length
T = np.arange(int(FS * SECONDS)) / FS
ORDERS = np.arange(1.0, 9.0)
# a four-cylinder engine's orders [N m], order 2 dominant, the weakest 1/25 of it
AMPS = np.array([20.0, 200.0, 15.0, 60.0, 10.0, 25.0, 8.0, 12.0])
PHASES = np.linspace(-2.5, 2.8, 8)  # [rad]
NOISE_NM = 0.5  # [N m] RMS white noise on the torque channel
NOISE_RPM = 0.5  # RMS white noise on the speed channel, as in dampersim.discrepancy.synth


def rad_s(rpm):
    return rpm * math.pi / 30.0


def record(rpm0=1500.0, rpm1=1530.0, ripple=0.02, ripple_order=0.3, vibration=0.0, vibration_order=2.0,
           vibration_phase=0.0, orders=ORDERS, amps=AMPS, phases=PHASES, noise=True, seed=1, t=T):
    """(torque [N m], speed [rad/s]) of a rig whose speed drifts linearly from rpm0 to rpm1
    over the record and ripples slowly by ``ripple`` (relative) at ``ripple_order`` (0.3: at
    0.3 times the 1st order's frequency, below the tracking low-pass's cut-off at 0.5). The
    torque is a sum of orders with the given amplitudes and phases on that slow angle (angle 0
    at t = 0), sampled at ``t`` [s]: the excitation follows the rig's speed. The speed channel
    also carries the damper's torsional vibration, ``vibration`` (relative) at
    ``vibration_order`` and ``vibration_phase`` [rad], which the excitation does not follow."""
    w0, w1 = rad_s(rpm0), rad_s(rpm1)
    acc = (w1 - w0) / SECONDS
    base = w0 * t + 0.5 * acc * t ** 2  # angle of the drifting speed alone [rad]
    angle = base + ripple / ripple_order * np.sin(ripple_order * base)  # [rad]
    speed = (w0 + acc * t) * (1.0 + ripple * np.cos(ripple_order * base))  # d angle / dt [rad/s]
    x = 300.0 + sum(a * np.cos(k * angle + p) for k, a, p in zip(orders, amps, phases))
    speed = speed * (1.0 + vibration * np.cos(vibration_order * angle + vibration_phase))
    if noise:
        rng = np.random.default_rng(seed)
        x = x + NOISE_NM * rng.standard_normal(t.size)
        speed = speed + rad_s(NOISE_RPM) * rng.standard_normal(t.size)
    return x, speed


def test_drift_and_slow_ripple_do_not_smear_tracked_orders_but_smear_the_nominal_fft():
    x, speed = record()
    res = track_orders_by_speed(x, T, speed, ORDERS, channel="input_speed_rpm")
    # 1 %: without noise the method is exact to 3e-5 (spline interpolation at 24 samples
    # per period of order 8, trapezoidal integration, the low-pass keeping 98.3 % of the
    # slow ripple); the torque noise puts sqrt(3 / 6250) * 0.5 N m = 0.011 N m RMS into an
    # order bin, 0.14 % of the weakest order (8 N m), and 1 % is above 5 of those deviations
    np.testing.assert_allclose(res.amplitudes, AMPS, rtol=0.01)
    assert res.revolutions == 31 and res.mean_speed == pytest.approx(rad_s(1515.0), rel=1e-3)
    # the nominal-speed spectrum of the same record: the 2 % drift sweeps order k over
    # 0.02 k orders and the ripple spreads it by +-0.3 orders; 7 % off on order 8 at either
    # speed, and 5 % is 5x the tracking's tolerance
    for rpm in (1500.0, 1515.0):
        nominal = order_amplitudes(x, FS, rad_s(rpm), ORDERS)
        assert np.max(np.abs(nominal / AMPS - 1.0)) > 0.05


def test_vibration_at_the_orders_on_the_speed_channel_is_filtered_out():
    # the speed channel vibrates by 2 % at the 2nd order (about 30 rpm, as the damper's own
    # torsional vibration on a rig) while the torque is locked to time at the nominal speed
    x, speed = record(rpm1=1500.0, ripple=0.0, vibration=0.02, vibration_phase=0.5 * math.pi)
    res = track_orders_by_speed(x, T, speed, ORDERS, channel="input_speed_rpm")
    # the low-pass (cut-off 12.5 Hz) passes 1.5e-5 of the vibration at 50 Hz; 1 %: the
    # noise argument of the first test
    np.testing.assert_allclose(res.amplitudes, AMPS, rtol=0.01)
    # the angle's constant matches the unfiltered integral on average, whose vibration term
    # 0.01 (cos 2 angle - 1) rad (0 at t = 0) puts it 0.01 rad below the excitation's angle
    # on average: phases are referred to that; 0.02 rad as in the phase test
    err = np.angle(np.exp(1j * (res.phases - PHASES - 0.01 * ORDERS)))
    assert np.max(np.abs(err)) < 0.02
    # on the unfiltered speed the vibration phase-modulates order k by 0.01 k rad: order 2's
    # sidebands (J1(0.02) = 1 % of 200 N m) land on order 4, order 6's on 4 and 8, ...;
    # measured 6 % off on order 8 and 2 % on order 4, and 3 % is 3x the tolerance above
    raw = track_orders_by_speed(x, T, speed, ORDERS, share=None)
    assert np.max(np.abs(raw.amplitudes / AMPS - 1.0)) > 0.03


def test_the_cut_off_is_a_share_of_the_lowest_order():
    w = rad_s(1500.0)  # 25 revolutions per second
    assert LOWPASS_SHARE == 0.5
    assert lowpass_cutoff(ORDERS, w) == pytest.approx(12.5)  # half of order 1's 25 Hz
    assert lowpass_cutoff([0.5, 1.0, 2.0], w) == pytest.approx(6.25)  # half of order 0.5's 12.5 Hz
    assert lowpass_cutoff(ORDERS, w, share=0.3) == pytest.approx(7.5)
    with pytest.raises(InputError, match="accepted is a share above 0 and below 1"):
        lowpass_cutoff(ORDERS, w, share=1.0)


def test_phases_are_recovered_in_the_angle_domain():
    x, speed = record()
    res = track_orders_by_speed(x, T, speed, ORDERS)
    err = np.angle(np.exp(1j * (res.phases - PHASES)))
    # 0.02 rad: the low-pass leaves 1.7 % of the slow ripple out of the angle, 1.1e-3 rad,
    # times the order (8) is 9e-3 rad; the speed channel's noise below the cut-off adds less
    # than its unfiltered random walk of 0.05 rad/s * 2e-4 s * sqrt(6250) = 8e-4 rad (x 8);
    # the torque noise 0.011 / 8 = 1.4e-3 rad on the weakest order; measured 0.010 rad
    assert np.max(np.abs(err)) < 0.02
    np.testing.assert_allclose(res.complex, AMPS * np.exp(1j * PHASES), atol=0.02 * AMPS.max())


def test_half_orders_on_request():
    orders = np.array([0.5, 1.0, 1.5, 2.0, 4.0])
    amps = np.array([5.0, 20.0, 7.0, 200.0, 60.0])
    phases = np.array([0.3, -1.0, 2.0, 0.5, -2.9])
    # the cut-off is half of order 0.5's frequency: the slow ripple tracked is below 0.25 of
    # the 1st order's, here 0.15 of it
    x, speed = record(orders=orders, amps=amps, phases=phases, ripple_order=0.15)
    res = track_orders_by_speed(x, T, speed, orders)
    assert res.revolutions % 2 == 0  # half orders are whole bins only over an even count
    np.testing.assert_allclose(res.amplitudes, amps, rtol=0.01)  # 1 %: as in the first test
    assert np.max(np.abs(np.angle(np.exp(1j * (res.phases - phases))))) < 0.02  # as in the phase test


def test_constant_speed_tracking_equals_the_nominal_fft():
    x, speed = record(rpm1=1500.0, ripple=0.0, noise=False)
    res = track_orders_by_speed(x, T, speed, ORDERS)
    fft = order_amplitudes(x, FS, rad_s(1500.0), ORDERS)
    # 1e-3: both are exact for a pure sinusoid, the FFT by the energy under the Hann main
    # lobe divided by the equivalent noise bandwidth (< 1e-4 on noise-free records, its own
    # tests), tracking by the coherent bin of a whole number of revolutions (2e-5)
    np.testing.assert_allclose(res.amplitudes, fft, rtol=1e-3)
    np.testing.assert_allclose(res.amplitudes, AMPS, rtol=1e-4)  # 1e-4: the tracking error above, 5x
    # with noise both read the same orders within the window-correction difference: the FFT
    # adds the noise of about 5 bins around each order, the coherent read-out that of one;
    # 0.5 N m noise gives sqrt(5 / 1.5 * 2 / 6250) * 0.5 = 0.02 N m, 0.3 % of the weakest order
    x, speed = record(rpm1=1500.0, ripple=0.0)
    res = track_orders_by_speed(x, T, speed, ORDERS)
    np.testing.assert_allclose(res.amplitudes, order_amplitudes(x, FS, rad_s(1500.0), ORDERS), rtol=0.01)


def test_an_angle_channel_and_another_time_base():
    x, speed = record(noise=False)
    angle = tracking_angle(T, speed, ORDERS)
    a = track_orders(x, T, angle, ORDERS)
    np.testing.assert_allclose(a.amplitudes, AMPS, rtol=1e-4)  # 1e-4: the method's error (3e-5), 3x
    # the same torque on a 3x finer time base shifted by 0.4 s (as a simulation driven by the
    # record sees it), tracked over a's revolutions with the speed channel on the record's
    # own stamps: the same orders and phases
    t2 = np.arange(int(3 * FS * SECONDS)) / (3 * FS)
    x2, _ = record(noise=False, t=t2)
    b = track_orders_by_speed(x2, t2 + 0.4, speed, ORDERS, speed_time=T + 0.4, revolutions=a.revolutions,
                              start=a.start)
    np.testing.assert_allclose(b.complex, a.complex, atol=1e-4 * AMPS.max())  # 1e-4: as above


@pytest.mark.parametrize("bad, what", [
    (lambda w: np.where(np.arange(w.size) == 100, 0.0, w), "zero or negative"),
    (lambda w: -w, "zero or negative"),
    (lambda w: np.where(np.arange(w.size) == 7, np.nan, w), "NaN/inf"),
    (lambda w: np.where(np.arange(w.size) < 500, 0.2 * w, w), "below 50%"),
])
def test_bad_speed_channels_are_refused_naming_the_channel(bad, what):
    x, speed = record(noise=False)
    with pytest.raises(InputError) as exc:
        track_orders_by_speed(x, T, bad(speed), ORDERS, channel="input_speed_rpm")
    msg = str(exc.value)
    assert "'input_speed_rpm'" in msg and what in msg and "accepted" in msg and "positive" in msg


def test_a_record_too_short_for_the_revolutions_is_refused():
    x, speed = record(noise=False)
    n = int(0.11 * FS)  # 2.75 revolutions at 1500 rpm
    with pytest.raises(InputError) as exc:
        track_orders_by_speed(x[:n], T[:n], speed[:n], ORDERS, channel="input_speed_rpm")
    msg = str(exc.value)
    assert "'input_speed_rpm'" in msg and "holds 2.7" in msg and "at least 4 whole revolutions" in msg
    # half orders 0.5 apart need 2 / 0.5 = 4 revolutions; orders 0.25 apart need 8
    n = int(0.3 * FS)  # 7.5 revolutions
    with pytest.raises(InputError, match="at least 8 whole revolutions"):
        track_orders_by_speed(x[:n], T[:n], speed[:n], [0.25, 0.5, 1.0])
    with pytest.raises(InputError, match="denominator"):
        track_orders_by_speed(x, T, speed, [1.0, 1.1])
