"""Input torque sources: order sums with the thesis's start-up ramps, hysteresis torque
ramps and measured signals. Each has ``speed`` [rad/s] and ``torque(t)`` [N m]."""

from dampersim.excitation.orders import OrderSum, parse_orders
from dampersim.excitation.ramps import TorqueRamp, ramp_protocol, PROTOCOLS
from dampersim.excitation.measured import MeasuredTorque
from dampersim.excitation.torque_curve import TorqueCurve, default_torque_curve

__all__ = ["OrderSum", "parse_orders", "TorqueRamp", "ramp_protocol", "PROTOCOLS", "MeasuredTorque", "TorqueCurve", "default_torque_curve"]
