"""The Pulsation generator page's data: one generator run (output torque, cylinder pressure
and order content with a summary line) and the dominant engine order over speed
([thesis] chapter 4).
"""

from __future__ import annotations

from dampersim.excitation.pulsation import check_speed_rpm, pressure_warnings
from dampersim.parameters.engine import check_pressure_bar
from dampersim.plotting.studies import dominant_order_figure, pulsation_figures
from dampersim.simulation import dominant_order_over_speed, simulate_pulsation
from dampersim.units import rpm_to_rad_s

#: Mean output torque of the generator runs [N m].
MEAN_TORQUE_NM = 200.0
#: Speeds of the dominant-order sweep [rpm] and the orders it compares.
SWEEP_SPEEDS_RPM = tuple(range(1000, 3001, 250))
DOMINANT_ORDERS = (2, 4, 6)


def pulsation_view(pressure, speed, coupled) -> dict:
    """One run of the pulsation generator at charge ``pressure`` [bar abs] and ``speed``
    [rpm], alone or ``coupled`` to the damper and rig.

    Returns {"figures": [output torque, cylinder pressure, order content], "summary": one
    line of text, "warnings": [values outside the range the thesis validated]}. Raises
    ParameterError / InputError naming a pressure or speed outside the model's range.
    """
    p = check_pressure_bar(pressure)
    warns = check_speed_rpm(speed, warn=False) + pressure_warnings(p)
    res = simulate_pulsation(rpm_to_rad_s(float(speed)), p, MEAN_TORQUE_NM, coupled=bool(coupled))
    figures = pulsation_figures(res)
    s = res.summary()
    text = (f"dominant order {s['dominant_order']:g}; peak cylinder pressure {s['peak_cylinder_pressure_bar']:.1f} bar; "
            f"mean torque {s['mean_torque_nm']:.1f} N m")
    return {"figures": figures, "summary": text, "warnings": warns}


def dominant_order_view(pressure, coupled, progress=None):
    """The amplitudes of orders 2, 4 and 6 over :data:`SWEEP_SPEEDS_RPM` ([thesis] Fig. 4.12)
    as a figure; ``progress(done, total)`` after each speed."""
    rows = dominant_order_over_speed(SWEEP_SPEEDS_RPM, check_pressure_bar(pressure), MEAN_TORQUE_NM, bool(coupled),
                                     tuple(float(k) for k in DOMINANT_ORDERS), progress=progress)
    return dominant_order_figure(rows)


__all__ = ["MEAN_TORQUE_NM", "SWEEP_SPEEDS_RPM", "DOMINANT_ORDERS", "pulsation_view", "dominant_order_view"]
