"""Unit conversions and number text used at the edges (CLI, UI, links, files); the library itself is SI."""

import math

import numpy as np

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
DEG_TO_RAD = math.pi / 180.0
BAR_TO_PA = 1.0e5


def rpm_to_rad_s(rpm):
    """Shaft speed [rpm] -> angular speed [rad/s]."""
    return rpm * RPM_TO_RAD_S


def rad_s_to_rpm(omega):
    """Angular speed [rad/s] -> shaft speed [rpm]."""
    return omega / RPM_TO_RAD_S


def deg_to_rad(deg):
    """Angle [deg] -> [rad]."""
    return deg * DEG_TO_RAD


def rad_to_deg(rad):
    """Angle [rad] -> [deg]."""
    return rad / DEG_TO_RAD


def bar_to_pa(bar):
    """Pressure [bar] -> [Pa]."""
    return bar * BAR_TO_PA


def pa_to_bar(pa):
    """Pressure [Pa] -> [bar]."""
    return pa / BAR_TO_PA


def order_frequency_hz(order, omega):
    """Frequency [Hz] of engine order ``order`` at shaft speed ``omega`` [rad/s]."""
    return order * omega / (2.0 * math.pi)


def number_text(v) -> str:
    """Compact, exact text of a number (1500, 0.22, 1e-05): the same text in figure labels,
    links and messages."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if math.isfinite(v) and v.is_integer() and abs(v) < 1e15:
            return str(int(v))
        return repr(v)
    return str(v)


def parse_number(raw) -> float:
    """A finite float from a number or its text; raises ValueError with the reason
    ("is empty", "is not a number", "is not a finite number")."""
    if isinstance(raw, bool):
        raise ValueError("is not a number")
    if isinstance(raw, (int, float, np.integer, np.floating)):
        v = float(raw)
    else:
        text = str(raw).strip()
        if not text:
            raise ValueError("is empty")
        try:
            v = float(text)
        except ValueError:
            raise ValueError("is not a number") from None
    if not math.isfinite(v):
        raise ValueError("is not a finite number")
    return v
