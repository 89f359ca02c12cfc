"""Mains pick-up: measured where it falls between the orders, carried where it falls on one."""

import dataclasses
import math

import numpy as np
import pytest

from dampersim.discrepancy import pickup
from dampersim.discrepancy.campaign import MeasuredPoint

FS = 5000.0
ORDERS = tuple(float(k) for k in range(1, 9))


def _point(rpm, hum_nm, seed, noise=0.05, record=0.8):
    """A torsional record: orders 1-8 at fixed amplitudes, white noise of ``noise`` N m and
    a 50 Hz line of ``hum_nm`` with a random phase on the output channel."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(record * FS)) / FS
    w = rpm * math.pi / 30.0
    orders = sum((3.0 / k) * np.cos(k * w * t + k) for k in ORDERS)
    out = 200.0 + orders + hum_nm * np.cos(2 * math.pi * 50.0 * t + rng.uniform(0, 2 * math.pi))
    out = out + noise * rng.standard_normal(len(t))
    inp = 200.0 + 2.0 * orders + noise * rng.standard_normal(len(t))
    speed = np.full(len(t), float(rpm))
    return MeasuredPoint(id=f"p{rpm}_{seed}", kind="torsional", speed_rpm=float(rpm), mean_torque_nm=200.0,
                         sample_rate_hz=FS, time=t, input_torque=inp, output_torque=out, input_speed_rpm=speed,
                         output_speed_rpm=speed)


def test_the_hann_response_is_one_on_the_bin_a_half_next_to_it_and_zero_at_whole_bins():
    assert pickup.hann_response([0.0, 1.0, -1.0, 2.0, 3.0, 7.0]) == pytest.approx([1.0, 0.5, 0.5, 0, 0, 0], abs=1e-12)
    assert pickup.hann_response(2.5) == pytest.approx(1.0 / (2.5 * math.pi) / 5.25)  # between whole bins


def test_a_line_between_the_orders_is_measured_and_carried_onto_the_order_it_falls_on():
    hum = 0.3
    # 50 Hz at 1100, 1300 and 1800 rpm is at least 4 Hz (3 bins of 0.8 s) from every whole and
    # half order; at 1500 rpm it is order 2
    pts = [_point(rpm, hum, s) for s, rpm in enumerate((1100, 1300, 1800, 1800, 1500, 1500))]
    powers = pickup.line_powers(pts)
    # four points are clear of the orders at 50 Hz; their median |line|^2 less the noise: the
    # noise of one coefficient is about 0.005 N m here, so the estimate is within 20 % of the
    # 0.3 N m line (a median of four random-phase lines plus noise)
    assert math.sqrt(powers[50.0]) == pytest.approx(hum, rel=0.2)
    assert powers[60.0] == 0.0 and powers[150.0] == 0.0  # no such lines: below the significance test
    sig = pickup.pickup_sigma(pts, ORDERS)
    # 50 Hz is order 2 at 1500 rpm (25 Hz): the whole line; one bin away nothing whole leaks
    assert sig[4, 1] == pytest.approx(math.sqrt(powers[50.0]))
    assert sig[5, 1] == pytest.approx(math.sqrt(powers[50.0]))
    others = np.delete(sig, 1, axis=1)
    assert np.all(others[4:] < 1e-3 * hum)
    # the clear points: the line falls between their whole orders, at least 3.3 bins from one
    # over the revolutions read (window response at most 1 %)
    assert np.all(sig[:4] < 0.01 * hum)


def test_without_a_line_nothing_is_added():
    pts = [_point(rpm, 0.0, s) for s, rpm in enumerate((1100, 1300, 1800, 1500))]
    assert np.all(pickup.pickup_sigma(pts, ORDERS) == 0.0)


def test_content_at_the_line_that_is_not_steady_is_not_taken_for_pickup():
    """A 0.3 N m component at 50 Hz in the first half of each record only (not a steady
    line: the damper's own non-stationary content) reads about 0.15 N m over the record,
    but its halves differ by as much: it is below the significance test."""
    pts = []
    for s, rpm in enumerate((1100, 1300, 1800, 1500)):
        p = _point(rpm, 0.0, s)
        burst = 0.3 * np.cos(2 * math.pi * 50.0 * p.time) * (p.time < 0.5 * p.time[-1])
        pts.append(dataclasses.replace(p, output_torque=p.output_torque + burst))
    assert abs(pickup.line_coefficient(pts[0], 50.0)) > 0.1  # it is there
    assert pickup.line_powers(pts)[50.0] == 0.0


def test_half_orders_are_not_clear_of_the_engine():
    # 50 Hz is order 2.5 at 1200 rpm and 1.5 at 2000 rpm: half orders of a four-stroke engine
    assert not pickup._clear(_point(1200, 0.0, 0), 50.0) and not pickup._clear(_point(2000, 0.0, 0), 50.0)
    assert pickup._clear(_point(1800, 0.0, 0), 50.0)


def test_too_few_clear_points_carry_nothing():
    pts = [_point(1500, 0.3, s) for s in range(3)]  # 50 Hz is an order at every point
    assert pickup.line_powers(pts)[50.0] == 0.0
    # two clear points are one point's word against the other's: not enough
    two = [_point(rpm, 0.3, s) for s, rpm in enumerate((1100, 1300, 1500))]
    assert pickup.line_powers(two)[50.0] == 0.0


def test_a_point_without_a_speed_channel_takes_the_line_in_its_band():
    pts = [_point(rpm, 0.3, s) for s, rpm in enumerate((1100, 1300, 1800, 1800, 1500))]
    bare = dataclasses.replace(pts[-1], input_speed_rpm=None)
    sig = pickup.pickup_sigma(pts[:-1] + [bare], ORDERS)
    a = math.sqrt(pickup.line_powers(pts[:-1] + [bare])[50.0])
    assert sig[-1, 1] == pytest.approx(a) and np.all(np.delete(sig[-1], 1) == 0.0)


def test_clearance_is_judged_at_the_measured_speed():
    """A point recorded at 1200 rpm under a nominal 1800 rpm (a manifest off, the rig's speed
    channel right): 50 Hz is order 2.5 of the measured speed, not clear; without the speed
    channel only the nominal speed is known, where it is clear."""
    p = _point(1200, 0.0, 0)
    mislabelled = dataclasses.replace(p, speed_rpm=1800.0)
    assert not pickup._clear(mislabelled, 50.0)
    assert pickup._clear(dataclasses.replace(mislabelled, input_speed_rpm=None, output_speed_rpm=None), 50.0)


@pytest.mark.parametrize("d_bins, inside", [(15.0, True), (-15.0, True), (22.0, False), (3.0, True)])
def test_the_band_without_a_speed_channel_is_the_order_reader_s(d_bins, inside):
    """band_half_width is the band dampersim.signal.order_amplitudes reads: on a 10 s record
    at 1200 rpm (200 revolutions) order 8's band is 1 % of 160 Hz plus the main lobe, 18
    bins, far wider than the 1.5 + 2 bins of a short record. A line 15 bins from the order
    adds its whole power to the order's reading, one 22 bins away none of it (a line at
    whole bins leaks nothing through the Hann window beyond its main lobe)."""
    from dampersim.signal import order_amplitudes

    fs, rpm, record = 2000.0, 1200.0, 10.0
    t = np.arange(int(record * fs)) / fs
    f8 = 8 * rpm / 60.0
    x = 5.0 * np.cos(2 * np.pi * f8 * t) + 1.0 * np.cos(2 * np.pi * (f8 + d_bins / record) * t + 0.3)
    read = order_amplitudes(x, fs, rpm * math.pi / 30.0, ORDERS)[7]
    band = pickup.band_half_width(ORDERS, rpm / 60.0 * record)[7]
    assert band == pytest.approx(0.01 * f8 * record + 2.0)
    assert (abs(d_bins) <= band) == inside
    # 1e-3 relative: the other orders are absent, so only the window's leakage differs
    assert read ** 2 == pytest.approx(26.0 if inside else 25.0, rel=1e-3)
    assert pickup.band_half_width(ORDERS, 0.8 * rpm / 60.0)[0] == pytest.approx(3.5)  # a short record: 1.5 + 2 bins


def test_a_point_without_a_speed_channel_takes_a_line_anywhere_in_the_order_s_wide_band():
    """10 s records: at 1485 rpm 50 Hz lies 5 bins above order 2, outside the 1.5 + 2 bins of
    a short record but inside order 2's band on this one (1 % of 49.5 Hz is 4.95 bins, plus
    the main lobe: 6.95 bins), so the bare point's order 2 takes the whole line."""
    pts = [_point(rpm, 0.3, s, record=10.0) for s, rpm in enumerate((1100, 1300, 1800))]
    bare = dataclasses.replace(_point(1485, 0.3, 9, record=10.0), input_speed_rpm=None)
    assert pickup.band_half_width(ORDERS, 1485 / 60.0 * 10.0)[1] == pytest.approx(6.95, abs=0.01)
    sig = pickup.pickup_sigma(pts + [bare], ORDERS)
    a = math.sqrt(pickup.line_powers(pts + [bare])[50.0])
    assert a > 0.2  # the 0.3 N m line is found on the clear points
    assert sig[-1, 1] == pytest.approx(a) and np.all(np.delete(sig[-1], 1) == 0.0)
