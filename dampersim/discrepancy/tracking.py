"""Order amplitudes of measured test points, tracked on each point's measured input speed.

A measured torsional point carries its input speed channel (``input_speed_rpm``). Its order
amplitudes are read on the shaft angle integrated from that channel low-passed below the
analysed orders (:func:`dampersim.analysis.ordertrack.tracking_angle`, cut-off at
LOWPASS_SHARE of the lowest order's frequency), so that the rig's speed drift and slow speed
ripple do not smear the orders, while the damper's own torsional vibration at the orders,
which the channel also carries, does not phase-modulate them: the rig generates its
excitation against time at the set speed's order frequencies. The model run a point drives
lives on the point's time base (it is driven by the measured input torque), so its output is
read with the same angle over exactly the same revolutions: measurement and model go through
one and the same operator, and a speed ripple or a speed sensor's scale error cannot open a
gap between them.

A point without a speed channel (``input_speed_rpm`` None) falls back to the nominal-speed
spectrum of :func:`dampersim.signal.order_amplitudes`, as do simulations that are not driven by
a record (their speed is constant by construction). Units: speed [rad/s] inside, the channel
is in rpm as the campaign format stores it; angle [rad]; torque [N m].
"""

from __future__ import annotations

import math

import numpy as np

from dampersim.analysis.ordertrack import LOWPASS_SHARE, TrackedOrders, check_speed, track_orders, tracking_angle
from dampersim.errors import InputError
from dampersim.signal import order_amplitudes

#: The channel the orders are tracked on: engine orders belong to the input (engine) shaft.
SPEED_CHANNEL = "input_speed_rpm"


def point_speed(point) -> np.ndarray | None:
    """The point's measured input speed [rad/s] checked for order tracking
    (:func:`~dampersim.analysis.ordertrack.check_speed`), or None without a speed channel."""
    rpm = getattr(point, SPEED_CHANNEL, None)
    if rpm is None:
        return None
    return check_speed(np.asarray(rpm, dtype=float) * (math.pi / 30.0), SPEED_CHANNEL)


def point_angle(point, orders, part: slice = slice(None)) -> np.ndarray | None:
    """Input shaft angle [rad] to track ``orders`` on over ``part`` of the point's samples
    (the speed low-passed at LOWPASS_SHARE of the lowest order's frequency), 0 at the part's
    first sample on average over the part; None without a speed channel."""
    w = point_speed(point)
    if w is None:
        return None
    return tracking_angle(point.time[part], w[part], orders, LOWPASS_SHARE, SPEED_CHANNEL)


def record_angle_reader(point, orders):
    """A reader ``read(signal, part)`` of the complex order coefficients [N m] of a signal on
    the point's time base over ``part`` of the record, every part read on the whole record's
    tracked angle (so all parts share one phase reference); None without a speed channel."""
    th = point_angle(point, orders)
    if th is None:
        return None

    def read(signal, part: slice = slice(None)) -> np.ndarray:
        return track_orders(np.asarray(signal)[part], point.time[part], th[part], orders,
                            channel=SPEED_CHANNEL).complex

    return read


def halves(point) -> tuple:
    """The record's two halves as slices of its samples (an odd last sample is left out)."""
    n = len(point.time) // 2
    return slice(0, n), slice(n, 2 * n)


def half_coefficients(point, signal, orders, read=None) -> np.ndarray:
    """Order coefficients [N m] of ``signal`` (on the point's time base) over each of the
    record's two :func:`halves`, shape (2, orders): complex, both halves read on the whole
    record's tracked angle (one phase reference); without a speed channel, each half's real
    amplitudes at the nominal speed. ``read``: the point's :func:`record_angle_reader`, when
    the caller has built it already."""
    read = read or record_angle_reader(point, orders)
    if read is None:
        return np.array([point_orders(point, signal, orders, part).astype(complex) for part in halves(point)])
    return np.array([read(signal, part) for part in halves(point)])


def driven_output(point, res, steady_start: float) -> np.ndarray:
    """Output torque [N m] of a model run ``res`` driven by the point's record (played from
    ``steady_start`` [s] on), interpolated onto the record's time base."""
    w = res.window(point.duration)
    return np.interp(point.time, np.asarray(res.t[w], dtype=float) - steady_start, np.asarray(res.output_torque[w]))


def tracked(point, signal, orders, part: slice = slice(None)) -> TrackedOrders:
    """Tracked order spectrum of ``signal`` (a channel of ``point``, [N m]) over ``part`` of
    the record. The point must have a speed channel."""
    th = point_angle(point, orders, part)
    if th is None:
        raise InputError(f"point {point.id}: no {SPEED_CHANNEL} channel to track the orders on")
    return track_orders(np.asarray(signal)[part], point.time[part], th, orders, channel=SPEED_CHANNEL)


def point_orders(point, signal, orders, part: slice = slice(None)) -> np.ndarray:
    """Order amplitudes [N m] of ``signal`` (a channel of ``point``) over ``part`` of the
    record: tracked on the measured speed, or at the nominal speed without a speed channel."""
    if getattr(point, SPEED_CHANNEL, None) is None:
        return order_amplitudes(np.asarray(signal)[part], point.sample_rate_hz, point.speed, orders)
    return tracked(point, signal, orders, part).amplitudes


def driven_coefficients(point, res, steady_start: float, orders) -> np.ndarray:
    """Complex output order coefficients [N m] of a model run ``res`` (a simulation result)
    driven by the point's record, which the run plays from ``steady_start`` [s] on.

    Read with the point's angle over the revolutions the measured output is read over, so
    that model and measurement are compared through the same operator (amplitude and phase
    on the same angle reference); without a speed channel, the real amplitudes at the
    nominal speed over the record's length at the end of the run."""
    w = res.window(point.duration)
    if getattr(point, SPEED_CHANNEL, None) is None:
        return order_amplitudes(res.output_torque[w], res.sample_rate, point.speed, orders).astype(complex)
    t = np.asarray(res.t[w], dtype=float) - steady_start
    x = np.asarray(res.output_torque[w], dtype=float)
    ref = tracked(point, point.output_torque, orders)
    inside = (t >= point.time[0]) & (t <= point.time[-1])
    th = np.interp(t[inside], point.time, point_angle(point, orders))
    return track_orders(x[inside], t[inside], th, orders, revolutions=ref.revolutions, channel=SPEED_CHANNEL,
                        start=ref.start).complex


def driven_orders(point, res, steady_start: float, orders) -> np.ndarray:
    """Output order amplitudes [N m] of a model run driven by the point's record
    (the magnitudes of :func:`driven_coefficients`)."""
    return np.abs(driven_coefficients(point, res, steady_start, orders))


__all__ = ["SPEED_CHANNEL", "point_speed", "point_angle", "record_angle_reader", "halves", "half_coefficients",
           "driven_output", "tracked", "point_orders", "driven_coefficients", "driven_orders"]
