"""Excitation sources: order sums with start-up, parsing, ramps, measured drive."""

import math

import numpy as np
import pytest

from dampersim.errors import InputError
from dampersim.excitation import MeasuredTorque, OrderSum, PROTOCOLS, parse_orders, ramp_protocol
from dampersim.solver.driver import torque_grid


def test_order_sum_startup_and_steady_signal():
    w = 2 * math.pi * 25.0
    ex = OrderSum(speed=w, mean_torque=200.0, orders=((2, 300.0, 0.0), (0.5, 10.0, math.pi / 2)))
    t = np.array([0.0, 0.15, 0.3, 0.45, 1.0])
    y = ex.torque(t)
    assert y[0] == 0.0 and y[1] == pytest.approx(100.0)  # mean ramp, no fluctuation yet
    assert y[2] == pytest.approx(200.0)
    steady = 200 + 300 * math.cos(2 * w * 1.0) + 10 * math.cos(0.5 * w * 1.0 + math.pi / 2)
    assert y[4] == pytest.approx(steady, abs=1e-9)


@pytest.mark.parametrize("ramps", [(0.3, 0.3), (0.0, 0.0), (0.2, 0.0), (0.0, 0.5)])
def test_order_sum_on_the_step_grid_equals_numpy_form(ramps):
    # the compiled one-pass evaluation (rotation recurrence, exact cos/sin every 32
    # samples) against the NumPy definition: agreement to 1e-11 of the largest term,
    # i.e. accumulated rounding only (the recurrence's error grows ~ 32 ulp at most)
    w = 2 * math.pi * 2800 / 60
    ex = OrderSum(speed=w, mean_torque=-150.0, orders=((2, 300.0, 0.3), (4.5, 80.0, -1.0), (8, 20.0, 0.0)),
                  mean_ramp=ramps[0], amplitude_ramp=ramps[1])
    dt = 1.0 / 60000.0
    n = 156001
    fast = torque_grid(ex, n, dt)
    slow = ex.torque(np.arange(n) * dt)
    assert fast.shape == (n,)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-11 * 300.0)
    assert torque_grid(OrderSum(speed=w, mean_torque=5.0), 3, dt).tolist() == pytest.approx(
        OrderSum(speed=w, mean_torque=5.0).torque(np.arange(3) * dt).tolist())


def test_parse_orders_forms_and_errors():
    assert parse_orders("2:300,4:100@90") == ((2.0, 300.0, 0.0), (4.0, 100.0, math.pi / 2))
    assert parse_orders("1.5:20") == ((1.5, 20.0, 0.0),)
    for bad in ("2:", "x:3", "2:300,2:100", "-1:20", "2;300"):
        with pytest.raises(InputError) as e:
            parse_orders(bad)
        assert "accepted" in str(e.value) or "twice" in str(e.value) or "must be" in str(e.value)


def test_ramp_protocol_table_3_1():
    r = ramp_protocol("full-450", speed=100.0)
    kt, ky = r.knots()
    assert list(ky) == [0, 0, 450, 450, -180, -180, 0, 0]
    # 450 N m at 50 N m/s takes 9 s; 2 s hold at each peak
    assert kt[2] - kt[1] == pytest.approx(9.0) and kt[3] - kt[2] == pytest.approx(2.0)
    assert set(PROTOCOLS) >= {"full-100", "full-450", "full-500"}
    with pytest.raises(InputError):
        ramp_protocol("full-999", speed=100.0)


def test_measured_drive_joins_record_without_jump():
    t = np.arange(0, 1.0, 1e-4)
    y = 250 + 80 * np.sin(2 * np.pi * 50 * t + 0.3)
    m = MeasuredTorque(speed=100.0, time=t, torque_samples=y)
    tt = np.array([0.0, m.steady_start - 1e-9, m.steady_start, m.steady_start + 0.5])
    out = m.torque(tt)
    assert out[0] == pytest.approx(0.0, abs=1e-6)
    assert out[1] == pytest.approx(out[2], abs=1e-3)
    assert out[3] == pytest.approx(np.interp(0.5, t, y))
    with pytest.raises(InputError):
        MeasuredTorque(speed=100.0, time=t, torque_samples=np.where(t > 0.5, np.nan, y))


def test_the_start_up_loops_the_record_over_whole_engine_cycles():
    """An engine-like torque (orders 0.5 to 4 of the crank speed, so periodic in two
    revolutions): the loop the start-up plays is a whole number of cycles, within one sample,
    and the loop's end joins the record's start without a jump."""
    from dampersim.excitation.measured import loop_length

    speed = 2 * np.pi * 15.0  # 900 rpm [rad/s]
    t = np.arange(0, 1.0, 2e-4)
    y = 150 + sum(a * np.cos(k * speed * t + k) for k, a in ((0.5, 3.0), (1, 5.0), (2, 90.0), (4, 20.0)))
    m = MeasuredTorque(speed=speed, time=t, torque_samples=y)
    cycle = 4 * np.pi / speed
    n = m._loop / cycle
    assert abs(n - round(n)) * cycle <= 2e-4 and round(n) >= 4  # at least half the record: 4 of 7.5 cycles
    before = m.torque(np.array([m.steady_start - 1e-9, m.steady_start - 0.1]))
    assert before[0] == pytest.approx(y[0], abs=0.05)  # continuous at the join
    env = (m.steady_start - 0.1 - m.mean_ramp) / m.amplitude_ramp  # the fade-in's share at that time
    looped = y.mean() + env * (np.interp(m._loop - 0.1, t, y) - y.mean())
    assert before[1] == pytest.approx(looped, abs=1e-6)  # the record, looped
    # fewer than four revolutions: no loop; the record is played backwards as before
    assert loop_length(t[:800], y[:800], speed) is None
    short = MeasuredTorque(speed=speed, time=t[:800], torque_samples=y[:800], settle=0.5)
    assert short._loop is None
    span = t[799]
    # with the 0.5 s settling the lead-in (1.1 s) is longer than the 0.16 s record: it plays
    # backwards from the record's start, then forwards again from its other end, never
    # holding a sample (before: every time earlier than 0.16 s ahead of the record held y[799])
    for ago in (0.05, span + 0.05, 2 * span + 0.05):
        pos = ago if ago <= span else (2 * span - ago if ago <= 2 * span else ago - 2 * span)
        got = short.torque(np.array([short.steady_start - ago]))[0]
        assert got == pytest.approx(np.interp(pos, t[:800], y[:800]), abs=1e-9), ago  # full amplitude (settling)
