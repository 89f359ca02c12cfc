"""Speed stiffening of the outer set at small vibration angles ([thesis] §7.3.2)."""

import numpy as np

from dampersim import OrderSum, default_parameters, simulate
from dampersim.signal import order_amplitudes
from dampersim.studies.studies import secondary_end_share
from dampersim.units import rpm_to_rad_s

P = default_parameters()
FREQ = 2.0  # Hz: slow sine well below the first mode, as in [thesis] §7.3.2 (1-20 Hz)


def _run(rpm, amplitude):
    speed = rpm_to_rad_s(rpm)
    order = FREQ / (rpm / 60.0)
    ex = OrderSum(speed=speed, mean_torque=150.0, orders=((order, amplitude, 0.0),), mean_ramp=0.5, amplitude_ramp=0.5)
    res = simulate(P, ex, duration=4.0)
    w = res.window(2.5)
    a_w = order_amplitudes(res.windup_outer[w], res.sample_rate, speed, (order,))[0]
    a_t = order_amplitudes(res.input_torque[w], res.sample_rate, speed, (order,))[0]
    frames = res.segment_t >= res.segment_t[-1] - 2.5
    comp = res.segment_compression("outer")[frames]
    return a_t / a_w, np.degrees(2 * a_w), comp.max(axis=0) - comp.min(axis=0)


def test_stiffness_rises_with_speed_far_more_at_small_angles():
    k_small_500, ang_500, comp_500 = _run(500, 20.0)
    k_small_3000, ang_3000, comp_3000 = _run(3000, 50.0)
    assert 3.0 < ang_500 < 7.0 and 3.0 < ang_3000 < 7.0  # both near 5 deg of vibration
    k_large_500, big_500, _ = _run(500, 100.0)
    k_large_3000, big_3000, _ = _run(3000, 100.0)
    assert big_500 > 20.0 and big_3000 > 20.0  # both near 30 deg
    small_gain = k_small_3000 / k_small_500
    large_gain = k_large_3000 / k_large_500
    assert small_gain > 1.5
    assert small_gain > 1.5 * large_gain
    # the segments at the secondary end (its first 5/18 of the length: the thesis's five of
    # eighteen) stop compressing at 3000 rpm: friction on the secondary's race carries them
    # along with it ([thesis] Fig. 7.29)
    share_500 = secondary_end_share(comp_500)
    share_3000 = secondary_end_share(comp_3000)
    assert share_3000 < 0.5 * share_500
