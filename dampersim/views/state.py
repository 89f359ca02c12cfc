"""Page state: the URL-query fields of every dashboard page, their validation on the way in
and the query string written back.

Every dashboard page keeps its state in the URL query string. A page's fields are
declared in :data:`PAGES` (key, unit, default, accepted range); :func:`parse_query` turns
a query dict (strings, as a browser sends them) into a state dict plus a list of notices,
one per rejected value, each naming the key, the value, what is accepted and the value
used instead. Unknown keys are ignored. :func:`to_query` writes a state back, so that
``parse_query(page, to_query(page, state))`` gives the state again. Units at this edge are
rpm, N m, s, Hz and degrees; the views convert to SI explicitly. The parameter part of a
state comes from :mod:`dampersim.views.params`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from urllib.parse import quote

from dampersim import costs
from dampersim.analysis.repeatability import repeatability_cost
from dampersim.errors import InputError
from dampersim.excitation import PROTOCOLS, OrderSum, parse_orders, ramp_protocol
from dampersim.sweeps.grid import count_values, parse_values
from dampersim.units import deg_to_rad, number_text, parse_number, rpm_to_rad_s
from dampersim.views.notices import notice, query_value
from dampersim.views.params import parameter_query_items, parse_parameters, resolve_system

#: Most excitation orders one page state may hold.
MAX_ORDERS = 6
#: Largest excitation order [-] and amplitude [N m] accepted from a page.
MAX_ORDER = 16.0
MAX_AMPLITUDE_NM = 1000.0
#: Most test points of one sweep started from the dashboard.
MAX_SWEEP_POINTS = 400
#: Most speeds of a hysteresis page.
MAX_LOOP_SPEEDS = 6
#: Longest query a page reads [characters, keys and values together]; a longer one is
#: ignored as a whole (a notice, every value at its default). The longest useful link
#: (six orders, every field, a dozen parameter overrides) is under 1 kB.
MAX_QUERY_CHARS = 4096
#: Longest single query value [characters]; a longer one is refused (notice, default).
MAX_VALUE_CHARS = 512


@dataclass(frozen=True)
class Field:
    """One page-state key.

    kind: "float", "int", "runs" (off = None, or a whole number lo-hi), "bool", "choice", "orders" (ORDER:AMPLITUDE[@PHASE_DEG] items),
    "speeds" (rpm value/list/START:STOP:STEP), "torques" (N m value/list/range),
    "order_list" (engine orders "2,4"); lo/hi: accepted range (inclusive) in ``unit``;
    default None means "resolved from the parameter set" (``duration``).
    """

    key: str
    label: str
    kind: str
    default: object
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    doc: str = ""

    def accepted(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        if self.kind in ("float", "int"):
            return f"a number from {number_text(self.lo)} to {number_text(self.hi)}{u}"
        if self.kind == "runs":
            return f"off (no value) or a whole number from {number_text(self.lo)} to {number_text(self.hi)}{u}"
        if self.kind == "bool":
            return "true or false (1/0)"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices)
        if self.kind == "orders":
            return (f"up to {MAX_ORDERS} items ORDER:AMPLITUDE[@PHASE_DEG] with orders in (0, {number_text(MAX_ORDER)}] "
                    f"and amplitudes 0-{number_text(MAX_AMPLITUDE_NM)} N m, e.g. 2:300,4:100@90")
        if self.kind == "speeds":
            return (f"speeds in rpm ({number_text(self.lo)}-{number_text(self.hi)}) as a value, a list or START:STOP:STEP, "
                    f"e.g. 900:2800:50, at most {self.choices[0] if self.choices else MAX_SWEEP_POINTS} speeds")
        if self.kind == "torques":
            return (f"mean torques in N m ({number_text(self.lo)} to {number_text(self.hi)}) as a value, a list or "
                    f"START:STOP:STEP, at most {MAX_SWEEP_POINTS} torques and {MAX_SWEEP_POINTS} test points with the speeds")
        if self.kind == "order_list":
            return f"engine orders separated by commas, e.g. 2,4 (each from {number_text(self.lo)} to {number_text(self.hi)})"
        return "a value"


_ORDER_LIMITS = dict(lo=0.5, hi=8.0)

PAGES: dict[str, tuple[Field, ...]] = {
    "explorer": (
        Field("speed", "Speed", "float", 1500.0, "rpm", 300.0, 6000.0, doc="shaft speed of the test point"),
        Field("torque", "Mean torque", "float", 200.0, "N m", -500.0, 1000.0, doc="mean input torque"),
        Field("orders", "Excitation orders", "orders", "2:300", doc="engine orders with amplitude [N m] and phase [deg]"),
        Field("duration", "Simulated time", "float", None, "s", 1.0, 20.0, doc="default: the parameter set's solver.duration"),
        Field("repeat", "Repeatability runs", "runs", None, "runs", 2, 32,
              doc="off (default) or K runs with the input amplitudes scaled by 1 + i·1e-9: the spread of each order"),
        Field("spread_check", "Spread check", "bool", None, doc="with repeat: the K runs again at half the step label each spread"),
    ),
    "colourmap": (
        Field("speeds", "Speeds", "speeds", "900:2800:50", "rpm", 300.0, 6000.0, doc="speed sweep (the thesis steps 10 rpm)"),
        Field("torque", "Mean torque", "float", 200.0, "N m", -500.0, 1000.0),
        Field("orders", "Excitation orders", "orders", "2:300,4:100"),
        Field("duration", "Simulated time per point", "float", None, "s", 1.0, 20.0),
        Field("window", "Analysis window", "float", 1.25, "s", 0.2, 10.0, doc="end of each record, [thesis] 1.25 s"),
        Field("fmax", "Top frequency", "float", 500.0, "Hz", 50.0, 1000.0),
        Field("db", "Colour in dB", "bool", True),
        Field("cuts", "Order cuts", "order_list", "2,4", **_ORDER_LIMITS),
        Field("repeat", "Repeatability runs", "runs", None, "runs", 2, 32, doc="off (default) or K runs per speed: a band"),
    ),
    "hysteresis": (
        Field("protocol", "Ramp protocol", "choice", "full-450", choices=tuple(PROTOCOLS)),
        Field("speeds", "Speeds", "speeds", "1000,2000", "rpm", 300.0, 6000.0, choices=(MAX_LOOP_SPEEDS,)),
        Field("rate", "Ramp rate", "float", 50.0, "N m/s", 5.0, 2000.0),
        Field("hold", "Hold at the peaks", "float", 2.0, "s", 0.0, 10.0),
        Field("windup", "Windup", "choice", "total", choices=("total", "outer", "inner")),
        Field("lowpass", "10 Hz low pass", "bool", False),
    ),
    "segments": (
        Field("speed", "Speed", "float", 1500.0, "rpm", 300.0, 6000.0),
        Field("torque", "Mean torque", "float", 200.0, "N m", -500.0, 1000.0),
        Field("orders", "Excitation orders", "orders", "2:300"),
        Field("duration", "Simulated time", "float", None, "s", 1.0, 20.0),
        Field("spring", "Spring", "choice", "outer", choices=("outer", "pair_outer", "pair_inner")),
        Field("window", "Heatmap window", "float", 0.2, "s", 0.01, 20.0, doc="the last part of the record in the heatmap"),
        Field("span", "Animated span", "float", 0.04, "s", 0.005, 0.5, doc="the last part of the record that is animated"),
        Field("gain", "Motion exaggeration", "float", 5.0, "x", 1.0, 50.0, doc="oscillation about the mean, drawn enlarged"),
    ),
    "maps": (
        Field("speeds", "Speeds", "speeds", "1000:2800:200", "rpm", 300.0, 6000.0),
        Field("torques", "Mean torques", "torques", "50:400:50", "N m", -500.0, 1000.0),
        Field("orders", "Excitation orders", "orders", "2:300,4:100"),
        Field("duration", "Simulated time per point", "float", None, "s", 1.0, 20.0),
        Field("window", "Analysis window", "float", 1.25, "s", 0.2, 10.0),
        Field("map_orders", "Orders on the map", "order_list", "2,4", **_ORDER_LIMITS),
        Field("fmin", "Lowest frequency", "float", 30.0, "Hz", 1.0, 999.0),
        Field("fmax", "Highest frequency", "float", 200.0, "Hz", 2.0, 1000.0),
        Field("curve_order", "Torque-curve order", "float", 2.0, "", 0.5, 8.0, doc="engine order used to draw the torque curve"),
    ),
    "parameters": (),
}


#: Page name -> URL path.
PAGE_PATHS = {
    "explorer": "/explorer",
    "colourmap": "/colourmap",
    "hysteresis": "/hysteresis",
    "segments": "/segments",
    "maps": "/maps",
    "parameters": "/parameters",
}


def page_fields(page: str) -> tuple:
    if page not in PAGES:
        raise InputError(f"page {page!r}: accepted is one of {', '.join(PAGES)}")
    return PAGES[page]


def field(page: str, key: str) -> Field:
    for f in page_fields(page):
        if f.key == key:
            return f
    raise InputError(f"{page} has no state key {key!r}")


# --- value parsers: return the canonical value or raise ValueError(reason) ------------------
def _parse_float(f: Field, raw):
    v = parse_number(raw)
    if (f.lo is not None and v < f.lo) or (f.hi is not None and v > f.hi):
        raise ValueError("is out of range")
    return v


def _parse_int(f: Field, raw):
    v = _parse_float(f, raw)
    if not v.is_integer():
        raise ValueError("is not a whole number")
    return int(v)


def _parse_runs(f: Field, raw):
    if raw is None or (isinstance(raw, str) and raw.strip().lower() in ("", "off")):
        return None
    return _parse_int(f, raw)


def _parse_bool(f: Field, raw):
    if isinstance(raw, bool):
        return raw
    text = str(raw).strip().lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off", ""):
        return False
    raise ValueError("is not true or false")


def _parse_choice(f: Field, raw):
    text = str(raw).strip()
    if text not in f.choices:
        raise ValueError("is not one of the choices")
    return text


def parse_orders_deg(text) -> list:
    """``"2:300,4:100@90"`` -> ``[[2.0, 300.0, 0.0], [4.0, 100.0, 90.0]]`` (phase in degrees).

    Validated with :func:`dampersim.excitation.parse_orders` (its InputError explains a
    malformed item) and against the page limits; raises ValueError with the reason.
    """
    try:
        parse_orders(text)
    except InputError as exc:
        raise ValueError(str(exc).replace("--orders ", "").split(": accepted is")[0].split(" (ORDER:")[0]) from None
    out = []
    for item in str(text or "").split(","):
        item = item.strip()
        if not item:
            continue
        head, _, phase = item.partition("@")
        k_s, a_s = head.split(":")
        k, a = float(k_s), float(a_s)
        ph = float(phase) if phase else 0.0
        if k > MAX_ORDER:
            raise ValueError(f"order {number_text(k)} is above {number_text(MAX_ORDER)}")
        if a > MAX_AMPLITUDE_NM:
            raise ValueError(f"amplitude {number_text(a)} N m of order {number_text(k)} is above {number_text(MAX_AMPLITUDE_NM)} N m")
        if abs(ph) > 360.0:
            raise ValueError(f"phase {number_text(ph)} deg of order {number_text(k)} is outside -360 to 360 deg")
        out.append([k, a, ph])
    if len(out) > MAX_ORDERS:
        raise ValueError(f"has {len(out)} orders, at most {MAX_ORDERS} are accepted")
    return out


def format_orders(orders) -> str:
    """Inverse of :func:`parse_orders_deg`: ``[[2, 300, 0], [4, 100, 90]]`` -> "2:300,4:100@90"."""
    items = []
    for k, a, ph in orders or ():
        s = f"{number_text(float(k))}:{number_text(float(a))}"
        if float(ph) != 0.0:
            s += f"@{number_text(float(ph))}"
        items.append(s)
    return ",".join(items)


def orders_si(orders) -> tuple:
    """Page orders (phase in degrees) -> ((order, amplitude [N m], phase [rad]), ...)."""
    return tuple((float(k), float(a), float(deg_to_rad(float(ph)))) for k, a, ph in orders or ())


def point_excitation(state: dict) -> OrderSum:
    """The order-sum excitation of a one-test-point state (``speed`` [rpm], ``torque``
    [N m], ``orders`` with phases in degrees)."""
    return OrderSum(speed=rpm_to_rad_s(float(state["speed"])), mean_torque=float(state["torque"]),
                    orders=orders_si(parse_orders_deg(state["orders"])))


def orders_text_from_rows(ks, amps, phases):
    """Order rows of a page (order, amplitude [N m], phase [deg] per row) -> ("2:300,4:100@90",
    notices). A row without an order is skipped; a row with an order but a missing
    amplitude is refused with a notice."""
    items, notes = [], []
    for i, (k, a, ph) in enumerate(zip(ks or [], amps or [], phases or [])):
        if k in (None, ""):
            continue
        if a in (None, ""):
            notes.append(notice(f"Order row {i + 1} (order {k}) has no amplitude; the row is ignored."))
            continue
        item = f"{_num(k)}:{_num(a)}"
        if ph not in (None, "") and float(ph) != 0.0:
            item += f"@{_num(ph)}"
        items.append(item)
    return ",".join(items), notes


def _num(v) -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isfinite(f) and f.is_integer():
        return str(int(f))
    return repr(f)


def _parse_orders(f: Field, raw):
    return format_orders(parse_orders_deg(raw))


def _parse_value_list(f: Field, raw, unit: str, noun: str, sep: str, limit=None):
    """A value, list or START:STOP:STEP range -> normalised text; every value within the
    field's bounds and at most ``limit`` values."""
    text = re.sub(r"\s+", "", str(raw))
    limit = MAX_SWEEP_POINTS if limit is None else limit
    try:
        count = count_values(text, option=f.key, unit=unit)  # counted from the numbers, nothing built
        if count > limit:
            shown = "more than 1e15" if not math.isfinite(count) else f"{count:.0f}"
            raise ValueError(f"expands to {shown} {noun}, at most {limit} are accepted")
        values = parse_values(text, option=f.key, unit=unit, limit=limit)
    except InputError as exc:
        raise ValueError(str(exc)) from None
    bad = [v for v in values if not (f.lo <= v <= f.hi)]
    if bad:
        raise ValueError(f"{number_text(bad[0])} {unit} is outside {number_text(f.lo)}{sep}{number_text(f.hi)} {unit}")
    return text


def _parse_speeds(f: Field, raw):
    return _parse_value_list(f, raw, "rpm", "speeds", "-", f.choices[0] if f.choices else MAX_SWEEP_POINTS)


def _parse_torques(f: Field, raw):
    return _parse_value_list(f, raw, "N m", "torques", " to ", MAX_SWEEP_POINTS)


def _parse_order_list(f: Field, raw):
    text = re.sub(r"\s+", "", str(raw))
    if not text:
        raise ValueError("is empty")
    out = []
    for item in text.split(","):
        try:
            k = float(item)
        except ValueError:
            raise ValueError(f"item {item!r} is not a number") from None
        if not (f.lo <= k <= f.hi) or (2 * k) != int(2 * k):
            raise ValueError(f"order {item} is not a whole or half order from {number_text(f.lo)} to {number_text(f.hi)}")
        if k not in out:
            out.append(k)
    return ",".join(number_text(k) for k in out)


_PARSERS = {
    "float": _parse_float,
    "int": _parse_int,
    "runs": _parse_runs,
    "bool": _parse_bool,
    "choice": _parse_choice,
    "orders": _parse_orders,
    "speeds": _parse_speeds,
    "torques": _parse_torques,
    "order_list": _parse_order_list,
}


def parse_field(f: Field, raw):
    """Canonical value of ``raw`` for field ``f``; raises ValueError(reason)."""
    return _PARSERS[f.kind](f, raw)


def _display(f: Field, value) -> str:
    if value is None:
        return "off" if f.kind in ("runs", "bool") else "(none)"
    u = f" {f.unit}" if f.unit and f.kind in ("float", "int") else ""
    return f"{number_text(value)}{u}"


def parse_query(page: str, query: dict | None) -> tuple:
    """Validate a page's query dict -> ``(state, notices)``.

    ``state`` holds every field of :data:`PAGES` ``[page]`` (canonical values) and
    ``"params"`` (see :func:`parse_parameters`). An invalid or out-of-range value gives a
    notice naming the key, the value, what is accepted and the value used instead, and the
    field falls back to its default. Unknown keys are ignored; a key given twice uses its
    first value. Query values may be strings (from a URL) or numbers.
    """
    query = dict(query or {})
    notices: list = []
    query = _capped_query(query, notices)
    params = parse_parameters(query, notices)
    system = resolve_system(params)
    state = {}
    for f in page_fields(page):
        default = f.default
        if f.key == "duration" and default is None:
            default = float(system.solver.duration)
        if f.key in query:
            raw = query_value(query, f.key, notices, f.label)
            try:
                state[f.key] = parse_field(f, raw)
                continue
            except ValueError as exc:
                notices.append(notice(
                    f"{f.label} ({f.key}={raw!r}) {exc}: accepted is {f.accepted()}. Using {_display(f, default)}."
                ))
        state[f.key] = default
    state["params"] = params
    _cross_checks(page, state, notices)
    return state, notices


def _text_size(value) -> int:
    if isinstance(value, (list, tuple)):
        return sum(_text_size(v) for v in value)
    return len(value) if isinstance(value, str) else len(str(value)) if isinstance(value, (int, float, bool)) else 64


def _short(value, n: int = 40) -> str:
    text = str(value)
    return repr(text) if len(text) <= n else repr(text[:n]) + f"… ({len(text)} characters)"


def _capped_query(query: dict, notices: list) -> dict:
    """The query with the length caps applied: above :data:`MAX_QUERY_CHARS` in all it is
    dropped as a whole; a value above :data:`MAX_VALUE_CHARS` (or of a type no URL gives)
    is dropped. Each with a notice."""
    total = sum(len(str(k)) + 1 + _text_size(v) for k, v in query.items())
    if total > MAX_QUERY_CHARS:
        notices.append(notice(f"The link's query is {total} characters long: accepted are at most {MAX_QUERY_CHARS}. "
                              "Nothing in it is used; every value is at its default."))
        return {}
    out = {}
    for k, v in query.items():
        vals = v if isinstance(v, (list, tuple)) else [v]
        bad = next((x for x in vals if not isinstance(x, (str, int, float, bool))
                    or (isinstance(x, int) and not isinstance(x, bool) and abs(x) > 2**53)), "")
        if bad != "":
            notices.append(notice(f"{_short(k)} is given as {type(bad).__name__}: accepted is text or a number. "
                                  "Using the default."))
            continue
        long = next((x for x in vals if isinstance(x, str) and len(x) > MAX_VALUE_CHARS), None)
        if long is not None:
            notices.append(notice(f"{_short(k)}={_short(long)} is {len(long)} characters long: accepted are at most "
                                  f"{MAX_VALUE_CHARS}. Using the default."))
            continue
        out[k] = v
    return out


def _cross_checks(page, state, notices):
    """Checks between fields; fix the state and add notices."""
    if page == "explorer" and state["spread_check"] and not state["repeat"]:
        notices.append(notice("Spread check (spread_check=true) needs repeat: accepted is it with repeat from 2 to 32. Using off."))
        state["spread_check"] = None
    if page in ("colourmap", "maps"):
        steady = 0.6  # OrderSum start-up: 0.3 s mean ramp + 0.3 s amplitude ramp
        room = state["duration"] - steady
        if state["window"] > room + 1e-9:
            new = round(max(0.2, min(1.25, room)), 3)
            notices.append(notice(
                f"Analysis window ({number_text(state['window'])} s) does not fit after the 0.6 s start-up of a "
                f"{number_text(state['duration'])} s record; using {number_text(new)} s."
            ))
            state["window"] = new
    if page == "maps":
        n_speeds = count_values(state["speeds"], "speeds", "rpm")
        n_torques = count_values(state["torques"], "torques", "N m")
        if n_speeds * n_torques > MAX_SWEEP_POINTS:
            sp, tq = field("maps", "speeds").default, field("maps", "torques").default
            notices.append(notice(
                f"Speeds ({state['speeds']}) x mean torques ({state['torques']}) are {n_speeds:.0f} x {n_torques:.0f} = "
                f"{n_speeds * n_torques:.0f} test points: accepted are at most {MAX_SWEEP_POINTS}. "
                f"Using speeds={sp} and torques={tq}."
            ))
            state["speeds"], state["torques"] = sp, tq
    if page == "maps" and state["fmin"] >= state["fmax"]:
        f_lo, f_hi = field("maps", "fmin").default, field("maps", "fmax").default
        notices.append(notice(
            f"Frequency range fmin={number_text(state['fmin'])} Hz to fmax={number_text(state['fmax'])} Hz is empty: "
            f"accepted is fmin < fmax. Using {number_text(f_lo)}-{number_text(f_hi)} Hz."
        ))
        state["fmin"], state["fmax"] = f_lo, f_hi


def default_state(page: str, params: dict | None = None) -> dict:
    """The page's state with every field at its default."""
    query = dict(parameter_query_items(params))
    return parse_query(page, query)[0]


def to_query(page: str, state: dict) -> str:
    """Query string (with the leading "?") of a page state: every page field, then the
    parameter overrides that differ from the base set."""
    items = []
    for f in page_fields(page):
        if f.key in state and state[f.key] is not None:
            items.append((f.key, number_text(state[f.key])))
    items += parameter_query_items(state.get("params"))
    if not items:
        return ""
    return "?" + "&".join(f"{quote(k, safe='._-')}={quote(v, safe=':,@._-')}" for k, v in items)


def page_href(page: str, params: dict | None = None, state: dict | None = None) -> str:
    """Link to ``page`` carrying the parameter state (and a full page state if given)."""
    path = PAGE_PATHS[page]
    if state is not None:
        return path + to_query(page, {**state, "params": params if params is not None else state.get("params")})
    items = parameter_query_items(params)
    if not items:
        return path
    return path + "?" + "&".join(f"{quote(k, safe='._-')}={quote(v, safe=':,@._-')}" for k, v in items)


def reparse_state(page: str, state) -> tuple:
    """Validate a page state that comes back from elsewhere (a job's stored request, data a
    browser posted) exactly as a link: ``(state, notices)`` of :func:`parse_query` over its
    page fields and parameter state. Anything that is not a page state's shape gives a
    notice and the defaults; nothing of it is trusted."""
    notices: list = []
    if not isinstance(state, dict):
        notices.append(notice(f"The request holds {type(state).__name__}, not a page state: accepted is a page state. "
                              "Using the defaults."))
        state = {}
    query = {}
    for f in page_fields(page):
        v = state.get(f.key)
        if v is not None:
            query[f.key] = v
    params = state.get("params")
    if params is not None:
        if not isinstance(params, dict):
            notices.append(notice("The request's parameter state is not a mapping: accepted is {set, overrides}. "
                                  "Using the default set."))
        else:
            set_id = params.get("set")
            if set_id is not None:
                query["set"] = set_id
            overrides = params.get("overrides") or {}
            if not isinstance(overrides, dict):
                notices.append(notice("The request's parameter overrides are not a mapping: accepted is "
                                      "{name: value}. Using none."))
                overrides = {}
            for k, v in overrides.items():
                if isinstance(k, str) and "." in k:
                    query[k] = number_text(v) if isinstance(v, (int, float)) else v
    out, more = parse_query(page, query)
    return out, notices + more


def state_cost(page: str, system, state: dict, n_points: int | None = None):
    """The :class:`dampersim.costs.Cost` of computing a (validated) page state with
    ``system``: one point (Explorer, K times with ``repeat``; Segments with its segment record), a sweep (Colourmap,
    K runs per speed with ``repeat``; Maps: ``n_points`` test point runs when given, e.g. only those not in the
    cache), or the hysteresis ramps (one protocol run per speed)."""
    if page in ("explorer", "segments"):
        if page == "explorer" and state.get("repeat"):  # K runs (and K at half the step) one after the other
            return repeatability_cost(system, float(state["duration"]), state["repeat"], bool(state.get("spread_check")))
        return costs.point_cost(system, float(state["duration"]), record_segments=(page == "segments"))
    if page in ("colourmap", "maps"):
        n = count_values(state["speeds"], "speeds", "rpm") * (state.get("repeat") or 1)  # K runs of each speed
        if page == "maps":
            n *= count_values(state["torques"], "torques", "N m")
        total = int(n)
        n = total if n_points is None else int(n_points)
        what = f"{n} test point{'s' if n != 1 else ''} of {number_text(float(state['duration']))} s" + (
            f" ({total - n} of {total} already in the cache)" if n != total else "")
        return costs.sweep_cost(system, n, float(state["duration"]), float(state["window"]), what=what)
    if page == "hysteresis":
        n = int(count_values(state["speeds"], "speeds", "rpm"))
        seconds = ramp_protocol(state["protocol"], 100.0, rate=float(state["rate"]), hold=float(state["hold"])).duration
        return costs.ramp_cost(system, seconds, n, what=f"{n} loop{'s' if n != 1 else ''} of {seconds:.0f} s simulated time")
    raise InputError(f"page {page!r} has no cost: accepted is explorer, segments, colourmap, maps or hysteresis")


def state_from_controls(page: str, values: dict, params: dict | None) -> tuple:
    """Validate control values (numbers or text from the page) -> ``(state, notices)``.

    Same rules as :func:`parse_query`; a missing (None) value means "default".
    """
    query = {k: v for k, v in values.items() if v is not None}
    query.update(dict(parameter_query_items(params)))
    return parse_query(page, query)


__all__ = [
    "MAX_ORDERS",
    "MAX_ORDER",
    "MAX_AMPLITUDE_NM",
    "MAX_SWEEP_POINTS",
    "MAX_LOOP_SPEEDS",
    "Field",
    "PAGES",
    "PAGE_PATHS",
    "page_fields",
    "field",
    "parse_field",
    "parse_orders_deg",
    "format_orders",
    "orders_si",
    "point_excitation",
    "orders_text_from_rows",
    "parse_query",
    "reparse_state",
    "state_cost",
    "MAX_QUERY_CHARS",
    "MAX_VALUE_CHARS",
    "default_state",
    "to_query",
    "page_href",
    "state_from_controls",
]
