"""The Pulsation generator page's data: one generator run (output torque, cylinder pressure
and order content with a summary line) and the dominant engine order over speed
([thesis] chapter 4).
"""

from __future__ import annotations

from dampersim import costs
from dampersim.errors import InputError
from dampersim.excitation.pulsation import SPEED_LIMITS_RPM, check_speed_rpm, pressure_warnings
from dampersim.parameters.engine import PRESSURE_LIMITS_BAR, check_pressure_bar
from dampersim.plotting.studies import dominant_order_figure, pulsation_figures
from dampersim.simulation import dominant_order_over_speed, simulate_pulsation
from dampersim.units import number_text, parse_number, rpm_to_rad_s
from dampersim.views.notices import notice, query_value

#: Mean output torque of the generator runs [N m].
MEAN_TORQUE_NM = 200.0
#: Speeds of the dominant-order sweep [rpm] and the orders it compares.
SWEEP_SPEEDS_RPM = tuple(range(1000, 3001, 250))
DOMINANT_ORDERS = (2, 4, 6)
#: Page state defaults: charge pressure [bar abs], speed [rpm], coupled to damper and rig.
DEFAULT_STATE = {"pressure": 2.5, "speed": 1500.0, "coupled": False}
#: Longest query value quoted back in a notice [characters].
QUOTE_LIMIT = 60

_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off", "")


def quoted(raw) -> str:
    """``repr`` of a query value, cut to :data:`QUOTE_LIMIT` characters."""
    text = repr(raw)
    return text if len(text) <= QUOTE_LIMIT else text[:QUOTE_LIMIT] + "…"


def parse_bool(raw) -> bool:
    """A page flag from its query text; raises ValueError."""
    if isinstance(raw, bool):
        return raw
    text = str(raw).strip().lower()
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    raise ValueError("is not true or false")


def _in_range(lo, hi):
    def parse(raw):
        v = parse_number(raw)
        if not lo <= v <= hi:
            raise ValueError("is out of range")
        return v
    return parse


#: key -> (label, parser, accepted text, unit)
FIELDS = {
    "pressure": ("Charge pressure", _in_range(*PRESSURE_LIMITS_BAR),
                 f"a number from {number_text(PRESSURE_LIMITS_BAR[0])} to {number_text(PRESSURE_LIMITS_BAR[1])} bar abs", " bar"),
    "speed": ("Speed", _in_range(*SPEED_LIMITS_RPM),
              f"a number from {number_text(SPEED_LIMITS_RPM[0])} to {number_text(SPEED_LIMITS_RPM[1])} rpm", " rpm"),
    "coupled": ("Coupled", parse_bool, "true or false (1/0)", ""),
}


def parse_pulsation_query(query: dict | None) -> tuple:
    """The Pulsation page's query (strings from a link) -> ``(state, notices)``.

    Each key of :data:`FIELDS` is validated; a bad value gives a notice naming the key, the
    value, what is accepted and the default used instead. Unknown keys are ignored; a
    repeated key uses its first value. Never raises.
    """
    query = dict(query or {})
    state, notices = dict(DEFAULT_STATE), []
    for key, (label, parse, accepted, unit) in FIELDS.items():
        if key not in query or query[key] is None:
            continue
        raw = query_value(query, key, notices, label)
        try:
            state[key] = parse(raw)
        except (ValueError, TypeError) as exc:
            default = DEFAULT_STATE[key]
            shown = ("1" if default else "0") if isinstance(default, bool) else f"{number_text(default)}{unit}"
            notices.append(notice(f"{label} ({key}={quoted(raw)}) {exc}: accepted is {accepted}. Using {shown}."))
    return state, notices


def pulsation_view(pressure, speed, coupled) -> dict:
    """One run of the pulsation generator at charge ``pressure`` [bar abs] and ``speed``
    [rpm], alone or ``coupled`` to the damper and rig.

    Returns {"figures": [output torque, cylinder pressure, order content], "summary": one
    line of text, "warnings": [values outside the range the thesis validated]}. Raises
    ParameterError / InputError naming a pressure or speed outside the model's range, and
    :class:`~dampersim.costs.BudgetError` (estimate and limit) when the run is above the
    server's budget or the foreground limit (it computes in the request thread).
    """
    p = check_pressure_bar(pressure)
    warns = check_speed_rpm(speed, warn=False) + pressure_warnings(p)
    costs.admit(costs.pulsation_cost(_flag(coupled)), foreground=True)  # computed while the browser waits
    res = simulate_pulsation(rpm_to_rad_s(float(speed)), p, MEAN_TORQUE_NM, coupled=_flag(coupled))
    figures = pulsation_figures(res)
    s = res.summary()
    text = (f"dominant order {s['dominant_order']:g}; peak cylinder pressure {s['peak_cylinder_pressure_bar']:.1f} bar; "
            f"mean torque {s['mean_torque_nm']:.1f} N m")
    return {"figures": figures, "summary": text, "warnings": warns}


def dominant_order_view(pressure, coupled, progress=None):
    """The amplitudes of orders 2, 4 and 6 over :data:`SWEEP_SPEEDS_RPM` ([thesis] Fig. 4.12)
    as a figure; ``progress(done, total)`` after each speed. BudgetError (estimate and
    limit) when the runs are above the server's budget."""
    costs.admit(costs.pulsation_cost(_flag(coupled), runs=len(SWEEP_SPEEDS_RPM),
                                     what=f"the dominant order over {len(SWEEP_SPEEDS_RPM)} speeds"))
    rows = dominant_order_over_speed(SWEEP_SPEEDS_RPM, check_pressure_bar(pressure), MEAN_TORQUE_NM, _flag(coupled),
                                     tuple(float(k) for k in DOMINANT_ORDERS), progress=progress)
    return dominant_order_figure(rows)


def _flag(coupled) -> bool:
    """The "coupled" control value (a checklist value list, a bool or flag text) as a bool;
    anything else is an InputError."""
    if isinstance(coupled, (list, tuple)):
        return bool(coupled)
    try:
        return parse_bool(coupled if coupled is not None else "")
    except ValueError:
        raise InputError(f"coupled = {quoted(coupled)}: accepted is true or false (1/0)") from None


__all__ = ["DEFAULT_STATE", "FIELDS", "parse_pulsation_query", "parse_bool", "quoted", "MEAN_TORQUE_NM", "SWEEP_SPEEDS_RPM", "DOMINANT_ORDERS", "pulsation_view", "dominant_order_view"]
