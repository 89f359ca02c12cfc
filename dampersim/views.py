"""The data behind each dashboard view, and the validated page state of every view.

This module is plain library code (no Dash): the dashboard pages call it, and so can tests,
benchmarks and notebooks. It has three parts.

**Page state.** Every dashboard page keeps its state in the URL query string. A page's
fields are declared in :data:`PAGES` (key, unit, default, accepted range);
:func:`parse_query` turns a query dict (strings, as a browser sends them) into a state dict
plus a list of notices, one per rejected value, each naming the key, the value, what is
accepted and the value used instead. Unknown keys are ignored. :func:`to_query` writes a
state back, so that ``parse_query(page, to_query(page, state))`` gives the state again.
Units at this edge are rpm, N m, s, Hz and degrees; the views convert to SI explicitly.

Parameter-set changes travel in the same query string, as dotted parameter names with SI
values (``inertias.primary=0.22``, ``outer.hardstop_positive=0.7``): only values that
differ from the base set are written. A parameter file whose structure differs from the
default set (other rig elements, ...) is stored on the server and referenced by
``set=<id>`` (see :func:`store_parameter_set`).

**Views.** :func:`explorer_view`, :func:`colourmap_view`, :func:`hysteresis_view`,
:func:`segments_view`, :func:`maps_view` and :func:`parameters_view` compute what a page
shows: Plotly figures (as dicts, built with :mod:`dampersim.plotting`), tables and
summary figures, all JSON-ready. :func:`discrepancy_view` caches the diagnosis of a
measured campaign (:mod:`dampersim.discrepancy`) keyed by a hash of the campaign's files;
:func:`discrepancy_figures` draws it from its JSON document.

**Cache.** Views are cached in diskcache under ``cache_dir()/"views"`` keyed by a SHA-256
of the view name, the complete parameter set, the page state, the package version and the
source hash of the simulation and view code (:func:`views_source_hash`), so a physics
change can never return a stale view. Sweep test points are cached per point by
:mod:`dampersim.sweeps` as usual, so a cancelled sweep keeps its finished points.
"""

from __future__ import annotations

import base64
import binascii
import copy
import dataclasses
import functools
import hashlib
import json
import math
import os
import re
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from urllib.parse import quote

import numpy as np

import dampersim
from dampersim.errors import DampersimError, InputError, ParameterError
from dampersim.jsonsafe import jsonable
from dampersim.units import deg_to_rad, rad_s_to_rpm, rad_to_deg, rpm_to_rad_s

#: Sub-directories of :func:`dampersim.sweeps.cache.cache_dir` used here.
VIEWS_SUBDIR = "views"
SETS_SUBDIR = "parameter-sets"
#: Size limit of the view cache [bytes].
VIEWS_SIZE_LIMIT = 2 * 2**30
#: Most excitation orders one page state may hold.
MAX_ORDERS = 6
#: Largest excitation order [-] and amplitude [N m] accepted from a page.
MAX_ORDER = 16.0
MAX_AMPLITUDE_NM = 1000.0
#: Most test points of one sweep started from the dashboard.
MAX_SWEEP_POINTS = 400
#: Most speeds of a hysteresis page.
MAX_LOOP_SPEEDS = 6
#: Largest uploaded parameter file [bytes].
MAX_UPLOAD_BYTES = 256 * 1024
#: Display thinning of long time series (points per trace).
TRACE_POINTS = 4000
ENERGY_POINTS = 2000
#: Orders whose amplitudes the Explorer always reports.
REPORT_ORDERS = tuple(float(k) for k in range(1, 9))
#: Magnification is not reported for orders whose input is below this share of the
#: largest input order (the order is not excited; same rule as the sweep tables).
MIN_INPUT_REL = 1e-3
#: Angle units of the views (the pages show degrees).
ANGLE_UNIT = "deg"


# =============================================================================== notices
def notice(text: str, level: str = "warning") -> dict:
    """A notice for the page: ``{"level": "warning"|"error"|"info", "text": ...}``."""
    return {"level": level, "text": str(text)}


# =============================================================================== fields
@dataclass(frozen=True)
class Field:
    """One page-state key.

    kind: "float", "int", "bool", "choice", "orders" (ORDER:AMPLITUDE[@PHASE_DEG] items),
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
            return f"a number from {_fmt(self.lo)} to {_fmt(self.hi)}{u}"
        if self.kind == "bool":
            return "true or false (1/0)"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices)
        if self.kind == "orders":
            return (f"up to {MAX_ORDERS} items ORDER:AMPLITUDE[@PHASE_DEG] with orders in (0, {_fmt(MAX_ORDER)}] "
                    f"and amplitudes 0-{_fmt(MAX_AMPLITUDE_NM)} N m, e.g. 2:300,4:100@90")
        if self.kind == "speeds":
            return (f"speeds in rpm ({_fmt(self.lo)}-{_fmt(self.hi)}) as a value, a list or START:STOP:STEP, "
                    f"e.g. 900:2800:50, at most {self.choices[0] if self.choices else MAX_SWEEP_POINTS} speeds")
        if self.kind == "torques":
            return f"mean torques in N m ({_fmt(self.lo)} to {_fmt(self.hi)}) as a value, a list or START:STOP:STEP"
        if self.kind == "order_list":
            return f"engine orders separated by commas, e.g. 2,4 (each from {_fmt(self.lo)} to {_fmt(self.hi)})"
        return "a value"


def _fmt(v) -> str:
    """Compact, exact text of a number for URLs and messages (1500, 0.22, 1e-05)."""
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


_ORDER_LIMITS = dict(lo=0.5, hi=8.0)

PAGES: dict[str, tuple[Field, ...]] = {
    "explorer": (
        Field("speed", "Speed", "float", 1500.0, "rpm", 300.0, 6000.0, doc="shaft speed of the test point"),
        Field("torque", "Mean torque", "float", 200.0, "N m", -500.0, 1000.0, doc="mean input torque"),
        Field("orders", "Excitation orders", "orders", "2:300", doc="engine orders with amplitude [N m] and phase [deg]"),
        Field("duration", "Simulated time", "float", None, "s", 1.0, 20.0, doc="default: the parameter set's solver.duration"),
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
    ),
    "hysteresis": (
        Field("protocol", "Ramp protocol", "choice", "full-450", choices=()),  # filled below
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


def _fill_protocols():
    from dampersim.excitation import PROTOCOLS

    fields = list(PAGES["hysteresis"])
    fields[0] = dataclasses.replace(fields[0], choices=tuple(PROTOCOLS))
    PAGES["hysteresis"] = tuple(fields)


_fill_protocols()

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
def _number(raw):
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


def _parse_float(f: Field, raw):
    v = _number(raw)
    if (f.lo is not None and v < f.lo) or (f.hi is not None and v > f.hi):
        raise ValueError("is out of range")
    return v


def _parse_int(f: Field, raw):
    v = _parse_float(f, raw)
    if not v.is_integer():
        raise ValueError("is not a whole number")
    return int(v)


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
    from dampersim.excitation import parse_orders

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
            raise ValueError(f"order {_fmt(k)} is above {_fmt(MAX_ORDER)}")
        if a > MAX_AMPLITUDE_NM:
            raise ValueError(f"amplitude {_fmt(a)} N m of order {_fmt(k)} is above {_fmt(MAX_AMPLITUDE_NM)} N m")
        if abs(ph) > 360.0:
            raise ValueError(f"phase {_fmt(ph)} deg of order {_fmt(k)} is outside -360 to 360 deg")
        out.append([k, a, ph])
    if len(out) > MAX_ORDERS:
        raise ValueError(f"has {len(out)} orders, at most {MAX_ORDERS} are accepted")
    return out


def format_orders(orders) -> str:
    """Inverse of :func:`parse_orders_deg`: ``[[2, 300, 0], [4, 100, 90]]`` -> "2:300,4:100@90"."""
    items = []
    for k, a, ph in orders or ():
        s = f"{_fmt(float(k))}:{_fmt(float(a))}"
        if float(ph) != 0.0:
            s += f"@{_fmt(float(ph))}"
        items.append(s)
    return ",".join(items)


def orders_si(orders) -> tuple:
    """Page orders (phase in degrees) -> ((order, amplitude [N m], phase [rad]), ...)."""
    return tuple((float(k), float(a), float(deg_to_rad(float(ph)))) for k, a, ph in orders or ())


def _parse_orders(f: Field, raw):
    return format_orders(parse_orders_deg(raw))


def _parse_value_list(f: Field, raw, unit: str, noun: str, sep: str, limit=None):
    """A value, list or START:STOP:STEP range -> normalised text; every value within the
    field's bounds and at most ``limit`` values."""
    from dampersim.sweeps.grid import parse_values

    text = re.sub(r"\s+", "", str(raw))
    try:
        values = parse_values(text, option=f.key, unit=unit)
    except InputError as exc:
        raise ValueError(str(exc)) from None
    if limit is not None and len(values) > limit:
        raise ValueError(f"expands to {len(values)} {noun}, at most {limit} are accepted")
    bad = [v for v in values if not (f.lo <= v <= f.hi)]
    if bad:
        raise ValueError(f"{_fmt(bad[0])} {unit} is outside {_fmt(f.lo)}{sep}{_fmt(f.hi)} {unit}")
    return text


def _parse_speeds(f: Field, raw):
    return _parse_value_list(f, raw, "rpm", "speeds", "-", f.choices[0] if f.choices else MAX_SWEEP_POINTS)


def _parse_torques(f: Field, raw):
    return _parse_value_list(f, raw, "N m", "torques", " to ")


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
            raise ValueError(f"order {item} is not a whole or half order from {_fmt(f.lo)} to {_fmt(f.hi)}")
        if k not in out:
            out.append(k)
    return ",".join(_fmt(k) for k in out)


_PARSERS = {
    "float": _parse_float,
    "int": _parse_int,
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
        return "(none)"
    u = f" {f.unit}" if f.unit and f.kind in ("float", "int") else ""
    return f"{_fmt(value)}{u}"


def _single(query: dict, key: str, notices: list, label: str):
    """The query value of ``key``; a repeated key keeps its first value, with a notice."""
    raw = query[key]
    if isinstance(raw, (list, tuple)):
        if not raw:
            return ""
        notices.append(notice(f"{label} ({key}) is given {len(raw)} times in the link; using the first value {raw[0]!r}."))
        raw = raw[0]
    return raw


# =============================================================================== parameters
def _field_meta(system, name: str):
    """(value, metadata dict) of a dotted parameter name."""
    obj = system
    parts = name.split(".")
    meta = {}
    i = 0
    while i < len(parts):
        p = parts[i]
        if isinstance(obj, tuple):  # rig elements addressed by name
            obj = next(e for e in obj if e.name == p)
            i += 1
            continue
        fields = {f.name: f for f in dataclasses.fields(obj)}
        meta = dict(fields[p].metadata)
        obj = getattr(obj, p)
        i += 1
    return obj, meta


def parameter_value(system, name: str):
    """Value of a dotted parameter name (``"inertias.primary"``) of ``system``."""
    from dampersim.parameters import dotted_names

    if name not in dotted_names(system):
        raise ParameterError(name, None, "a known parameter name")
    return _field_meta(system, name)[0]


#: Plausible ranges of the parameters the Explorer offers as controls (SI), tighter than the
#: library's validation (which only rules out impossible values); outside them a link value
#: is refused with a notice.
PARAMETER_RANGES = {
    "inertias.primary": (1e-3, 5.0),
    "inertias.secondary": (1e-4, 5.0),
    "inertias.tertiary": (1e-4, 5.0),
    "outer.spring.stiffness": (1.0, 1e5),
    "inner.spring.stiffness": (1.0, 1e5),
    "inner.nested.stiffness": (1.0, 1e5),
    "friction.outer.alpha": (0.0, 2.0),
    "friction.pair_outer.alpha": (0.0, 2.0),
    "friction.pair_inner.alpha": (0.0, 2.0),
    "solver.outer_segments": (4, 200),
    "solver.inner_segments": (4, 200),
    "solver.duration": (0.5, 60.0),
}

#: Labels and display units of the Explorer's parameter controls: dotted name ->
#: (label, display unit, factor from SI to display).
KEY_PARAMETERS = {
    "solver.outer_segments": ("Outer segments", "-", 1.0),
    "solver.inner_segments": ("Inner segments", "-", 1.0),
    "inertias.primary": ("J primary", "kg m²", 1.0),
    "inertias.secondary": ("J secondary", "kg m²", 1.0),
    "inertias.tertiary": ("J tertiary", "kg m²", 1.0),
    "outer.spring.stiffness": ("Outer spring rate", "N m/rad", 1.0),
    "inner.spring.stiffness": ("Pair outer spring rate", "N m/rad", 1.0),
    "inner.nested.stiffness": ("Pair inner spring rate", "N m/rad", 1.0),
    "friction.outer.alpha": ("α outer springs", "-", 1.0),
    "friction.pair_outer.alpha": ("α pair outer", "-", 1.0),
    "friction.pair_inner.alpha": ("α pair inner", "-", 1.0),
    "outer.hardstop_positive": ("Outer + hardstop", "deg", float(rad_to_deg(1.0))),
    "hardstops.enabled": ("Hardstops", "", 1.0),
    "friction.enabled": ("Friction", "", 1.0),
    "motor.mode": ("Output motor", "", 1.0),
}

_LABEL_NAMES = ("name", "source")  # labels, not physics: never carried as overrides


def _set_id_ok(set_id) -> bool:
    return isinstance(set_id, str) and re.fullmatch(r"[0-9a-f]{16}", set_id) is not None


def base_system(set_id=None):
    """The base parameter set: the default set, or a stored set ``set_id``."""
    if set_id is None:
        return dampersim.default_parameters()
    text = load_parameter_set(set_id)
    if text is None:
        raise InputError(f"parameter set {set_id!r} is not stored on this server")
    from dampersim.parameters import loads_toml

    return loads_toml(text)


def _override_value(system, name):
    v = parameter_value(system, name)
    return v.item() if isinstance(v, np.generic) else v


def apply_overrides(base, overrides: dict, notices: list | None = None, source: str = "link"):
    """Apply dotted overrides one by one to ``base``; refused ones get a notice.

    Returns (system, accepted overrides {name: typed value}). Overrides equal to the base
    value are dropped. Each accepted one is validated together with the ones before it
    (the time-step stability bound depends on several parameters).
    """
    from dampersim.parameters import dotted_names, with_updates

    names = set(dotted_names(base))
    system = base
    accepted = {}
    for name, raw in overrides.items():
        if name not in names or name in _LABEL_NAMES:
            continue
        old = _override_value(system, name)
        try:
            if name in PARAMETER_RANGES and not isinstance(old, (bool, str)):
                lo, hi = PARAMETER_RANGES[name]
                v = _number(raw)
                if not (lo <= v <= hi):
                    raise ParameterError(name, raw, f"a value from {_fmt(lo)} to {_fmt(hi)} on this dashboard")
            system = with_updates(system, {name: raw})
        except ParameterError as exc:
            if notices is not None:
                shown = raw if isinstance(raw, str) else _fmt(raw)
                if exc.field == name:
                    reason = f"accepted is {exc.accepted}"
                else:
                    reason = f"with it {exc.field} = {_fmt(exc.value)} would be invalid (accepted is {exc.accepted})"
                notices.append(notice(f"Parameter {name} = {shown!r} from the {source} is not accepted: {reason}. Using {_fmt(old)}."))
            continue
        except ValueError as exc:
            if notices is not None:
                notices.append(notice(f"Parameter {name} = {raw!r} from the {source} {exc}. Using {_fmt(old)}."))
            continue
        new = _override_value(system, name)
        if new != _override_value(base, name):
            accepted[name] = new
        else:
            accepted.pop(name, None)
    return system, accepted


def parse_parameters(query: dict, notices: list | None = None) -> dict:
    """Parameter state of a query: ``{"set": id or None, "overrides": {name: value}}``."""
    notices = [] if notices is None else notices
    set_id = None
    if "set" in query:
        raw = _single(query, "set", notices, "Parameter set")
        if raw not in (None, ""):
            if not _set_id_ok(raw):
                notices.append(notice(f"Parameter set set={raw!r} is not a valid set id (16 hex digits); using the default set."))
            elif load_parameter_set(raw) is None:
                notices.append(notice(f"Parameter set {raw!r} is not stored on this server (it was uploaded elsewhere or the cache was cleared); using the default set."))
            else:
                set_id = raw
    base = base_system(set_id)
    raw_overrides = {}
    for k in query:
        if "." in k:
            raw_overrides[k] = _single(query, k, notices, f"Parameter {k}")
    _, accepted = apply_overrides(base, raw_overrides, notices)
    return {"set": set_id, "overrides": accepted}


def resolve_system(params: dict | None, notices: list | None = None):
    """The :class:`DamperSystem` of a parameter state (see :func:`parse_parameters`)."""
    params = params or {}
    set_id = params.get("set")
    try:
        base = base_system(set_id)
    except DampersimError as exc:
        if notices is not None:
            notices.append(notice(f"{exc}; using the default set."))
        base = dampersim.default_parameters()
    system, _ = apply_overrides(base, dict(params.get("overrides") or {}), notices)
    return system


def parameter_query_items(params: dict | None) -> list:
    """[(key, text)] of a parameter state, for query strings."""
    params = params or {}
    items = []
    if params.get("set"):
        items.append(("set", params["set"]))
    for name in sorted(params.get("overrides") or {}):
        items.append((name, _fmt(params["overrides"][name])))
    return items


# =============================================================================== page state
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
    params = parse_parameters(query, notices)
    system = resolve_system(params)
    state = {}
    for f in page_fields(page):
        default = f.default
        if f.key == "duration" and default is None:
            default = float(system.solver.duration)
        if f.key in query:
            raw = _single(query, f.key, notices, f.label)
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


def _cross_checks(page, state, notices):
    """Checks between fields; fix the state and add notices."""
    if page in ("colourmap", "maps"):
        steady = 0.6  # OrderSum start-up: 0.3 s mean ramp + 0.3 s amplitude ramp
        room = state["duration"] - steady
        if state["window"] > room + 1e-9:
            new = round(max(0.2, min(1.25, room)), 3)
            notices.append(notice(
                f"Analysis window ({_fmt(state['window'])} s) does not fit after the 0.6 s start-up of a "
                f"{_fmt(state['duration'])} s record; using {_fmt(new)} s."
            ))
            state["window"] = new
    if page == "maps" and state["fmin"] >= state["fmax"]:
        f_lo, f_hi = field("maps", "fmin").default, field("maps", "fmax").default
        notices.append(notice(
            f"Frequency range fmin={_fmt(state['fmin'])} Hz to fmax={_fmt(state['fmax'])} Hz is empty: "
            f"accepted is fmin < fmax. Using {_fmt(f_lo)}-{_fmt(f_hi)} Hz."
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
            items.append((f.key, _fmt(state[f.key])))
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


def state_from_controls(page: str, values: dict, params: dict | None) -> tuple:
    """Validate control values (numbers or text from the page) -> ``(state, notices)``.

    Same rules as :func:`parse_query`; a missing (None) value means "default".
    """
    query = {k: v for k, v in values.items() if v is not None}
    query.update(dict(parameter_query_items(params)))
    return parse_query(page, query)


# =============================================================================== caching
_STORES: dict = {}


def cache_dir() -> Path:
    from dampersim.sweeps.cache import cache_dir as _cd

    return _cd()


def _open(sub: str, size_limit=VIEWS_SIZE_LIMIT):
    import diskcache

    path = str(cache_dir() / sub)
    key = (os.getpid(), path)  # never reuse a SQLite connection across a fork
    store = _STORES.get(key)
    if store is None:
        try:
            os.makedirs(path, exist_ok=True)
            store = diskcache.Cache(path, size_limit=size_limit)
        except OSError as exc:
            raise InputError(f"cache directory {path!r} cannot be used ({exc.strerror or exc}); set DAMPERSIM_CACHE_DIR to a writable folder") from None
        _STORES[key] = store
    return store


def view_store():
    """The diskcache of views (``cache_dir()/"views"``)."""
    return _open(VIEWS_SUBDIR)


def close_stores() -> None:
    """Close the stores this process opened (tests switch cache directories)."""
    for key in list(_STORES):
        if key[0] == os.getpid():
            try:
                _STORES.pop(key).close()
            except Exception:
                pass


def _canonical(obj):
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return {"f": float(obj).hex()}
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _canonical(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    raise InputError(f"cannot build a view key from a {type(obj).__name__} value")


#: Bumped when the content of a cached view changes shape.
VIEW_FORMAT = 1


#: package files (relative to ``dampersim/``) that shape a view besides the simulation's
#: (:data:`dampersim.sweeps.cache.SOURCE_FILES`)
VIEW_SOURCES = ("views.py", "plotting/figures.py", "plotting/theme.py", "analysis/colourmap.py", "analysis/maps.py",
                "analysis/hysteresis.py", "excitation/ramps.py", "excitation/torque_curve.py")


def views_source_hash() -> str:
    """Hash of the code that shapes a view: the simulation's source files and
    :data:`VIEW_SOURCES` (read once per process, by :func:`dampersim.sweeps.cache.source_hash`)."""
    from dampersim.sweeps.cache import SOURCE_FILES, source_hash

    return source_hash(SOURCE_FILES + VIEW_SOURCES)


def view_key(kind: str, system, state: dict, source: str | None = None) -> str:
    """SHA-256 key of a view: kind, complete parameter set (labels excluded), page state
    (without the parameter state, which ``system`` already holds), package version and the
    hash of the code behind the view (``source``; default :func:`views_source_hash`, the
    simulation, analysis and figure code)."""
    from dampersim.parameters import to_dict

    doc = {
        "schema": "dampersim.view",
        "format": VIEW_FORMAT,
        "kind": kind,
        "version": dampersim.__version__,
        "source": views_source_hash() if source is None else source,
        "parameters": {k: v for k, v in to_dict(system).items() if k not in _LABEL_NAMES},
        # numbers as floats: a state that went through JSON (a browser store) may bring 30 for 30.0
        "state": {k: (float(v) if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) else v)
                  for k, v in state.items() if k != "params"},
    }
    text = json.dumps(_canonical(doc), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def load_view(key: str):
    """A cached view by key, or None."""
    try:
        view = view_store().get(key, default=None, retry=True)
    except Exception:
        return None
    if not isinstance(view, dict):
        return None
    return {**view, "from_cache": True}


def _save_view(key: str, view: dict) -> dict:
    view = {**view, "key": key, "from_cache": False}
    try:
        view_store().set(key, view, retry=True)
    except Exception:
        pass  # a view that cannot be cached is still shown
    return view


# --- stored parameter sets ------------------------------------------------------------------
def _sets_store():
    return _open(SETS_SUBDIR, size_limit=2**28)


def store_parameter_set(system) -> str:
    """Store a parameter set on this server; returns its id (16 hex digits)."""
    from dampersim.parameters import dumps_toml

    text = dumps_toml(system)
    set_id = hashlib.sha256(text.encode()).hexdigest()[:16]
    _sets_store().set(set_id, text, retry=True)
    return set_id


def load_parameter_set(set_id: str):
    """TOML text of a stored parameter set, or None."""
    if not _set_id_ok(set_id):
        return None
    try:
        return _sets_store().get(set_id, default=None, retry=True)
    except Exception:
        return None


# =============================================================================== helpers
def _fig(fig) -> dict:
    """Figure -> plain dict for JSON (numpy arrays travel base64-encoded)."""
    return fig.to_dict()


def _thin(n: int, max_points: int) -> slice:
    if n <= max_points:
        return slice(None)
    return slice(None, None, int(math.ceil(n / max_points)))


def _finite(v):
    v = float(v)
    return v if math.isfinite(v) else None


def _excitation(state):
    from dampersim.excitation import OrderSum

    return OrderSum(speed=rpm_to_rad_s(float(state["speed"])), mean_torque=float(state["torque"]),
                    orders=orders_si(parse_orders_deg(state["orders"])))


def analysis_seconds(duration: float, steady_start: float = 0.6) -> float:
    """Analysis window [s]: the thesis's 1.25 s, shortened to fit after the start-up."""
    from dampersim.results import ANALYSIS_WINDOW

    return float(min(ANALYSIS_WINDOW, max(duration - steady_start, 0.2)))


def order_table(result, excited_orders, seconds: float) -> list:
    """Rows {order, frequency_hz, input_nm, output_nm, mr, excited} for orders 1-8 and every
    excited order (input and output amplitudes over the analysis window, [thesis] §3.4)."""
    from dampersim.analysis.metrics import magnification_ratio
    from dampersim.signal import order_amplitudes

    w = result.window(seconds)
    fs = result.sample_rate
    x_in, x_out = result.input_torque[w], result.output_torque[w]
    f1 = result.speed / (2 * math.pi)
    nyq = fs / 2
    whole = [k for k in REPORT_ORDERS if k * f1 < nyq]
    amps = {}
    if whole:
        a_in = order_amplitudes(x_in, fs, result.speed, whole)
        a_out = order_amplitudes(x_out, fs, result.speed, whole)
        amps.update({k: (a, b) for k, a, b in zip(whole, a_in, a_out)})
    for k in excited_orders:
        if k in amps or k * f1 >= nyq:
            continue
        a, = order_amplitudes(x_in, fs, result.speed, [k])
        b, = order_amplitudes(x_out, fs, result.speed, [k])
        amps[k] = (a, b)
    ks = sorted(amps)
    a_in = np.array([amps[k][0] for k in ks])
    a_out = np.array([amps[k][1] for k in ks])
    largest = float(np.max(a_in)) if a_in.size else 0.0
    mr = magnification_ratio(a_in, a_out, min_input=max(MIN_INPUT_REL * largest, 1e-12))
    rows = []
    for k, ai, ao, m in zip(ks, a_in, a_out, mr):
        rows.append({
            "order": float(k),
            "frequency_hz": float(k * f1),
            "input_nm": float(ai),
            "output_nm": float(ao),
            "mr": _finite(m),
            "excited": bool(any(abs(k - e) < 1e-9 for e in excited_orders)),
        })
    return rows


# --- figures the library does not have ------------------------------------------------------
def mr_figure(rows, title="Magnification ratio per order"):
    """MR [-] per order on a log axis with MR = 1 marked (excited orders dark); orders
    without input (not excited) have no ratio and are left out."""
    import plotly.graph_objects as go

    from dampersim.plotting import theme

    rows = [r for r in rows if r["mr"] is not None and r["mr"] > 0]
    fig = go.Figure()
    if rows:
        labels = [f"{_fmt(r['order'])}" for r in rows]
        fig.add_trace(go.Bar(
            x=labels,
            y=[r["mr"] for r in rows],
            text=[f"{r['mr']:.3g}" for r in rows],
            textposition="outside",
            width=0.45 if len(rows) > 1 else 0.3,
            marker=dict(color=[theme.COLOURWAY[0] if r["excited"] else "#9AB8D3" for r in rows]),
            customdata=[[r["input_nm"], r["output_nm"], r["frequency_hz"]] for r in rows],
            hovertemplate="order %{x}<br>MR %{y:.4g}<br>input %{customdata[0]:.3g} N m<br>"
                          "output %{customdata[1]:.3g} N m<br>%{customdata[2]:.1f} Hz<extra></extra>",
            name="MR",
        ))
        lo = min(r["mr"] for r in rows)
        hi = max(r["mr"] for r in rows)
        fig.add_hline(y=1.0, line=dict(color="#D55E00", dash="dash", width=1.5),
                      annotation_text="MR = 1", annotation_position="top left")
        fig.update_yaxes(type="log", dtick=1, exponentformat="power",
                         range=[math.floor(math.log10(min(lo, 0.5))) - 0.1, math.log10(max(hi, 1.0)) + 0.45])
    else:
        fig.add_annotation(text="no excited order", showarrow=False, xref="paper", yref="paper", x=0.5, y=0.5)
    fig.update_xaxes(title_text=theme.axis_title("Engine order", "-"), type="category")
    fig.update_yaxes(title_text=theme.axis_title("Magnification ratio", "-"))
    fig.update_layout(showlegend=False, margin=dict(t=50, b=50))
    return theme.apply(fig, title)


def windup_figure(result, system, max_points=TRACE_POINTS, title="Windup per set with hardstop limits"):
    """Windup of each set over time [deg] with its hardstop limits (dashed)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from dampersim.plotting import theme

    sl = _thin(result.t.size, max_points)
    t = result.t[sl]
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.12,
                        subplot_titles=("Outer set (J_pri → J_sec)", "Inner set (J_sec → J_ter)"))
    on = system.hardstops.enabled
    for row, (name, w, ss, col) in enumerate((("outer", result.windup_outer, system.outer, theme.COLOURWAY[0]),
                                              ("inner", result.windup_inner, system.inner, theme.COLOURWAY[2])), 1):
        fig.add_trace(go.Scatter(x=t, y=rad_to_deg(w[sl]), name=f"{name} set windup", line=dict(color=col)), row=row, col=1)
        for lim, lab in ((ss.hardstop_positive, "positive hardstop"), (ss.hardstop_negative, "negative hardstop")):
            fig.add_trace(go.Scatter(
                x=[float(t[0]), float(t[-1])], y=[float(rad_to_deg(lim))] * 2, mode="lines",
                line=dict(color="#D55E00" if on else "#AAAAAA", dash="dash", width=1.5),
                name=("hardstops" if on else "hardstops (disabled)"), legendgroup="hs", showlegend=(row == 1 and lab.startswith("pos")),
                hovertemplate=f"{name} {lab}: %{{y:.1f}} deg<extra></extra>"), row=row, col=1)
        fig.update_yaxes(title_text=theme.axis_title("Windup", "deg"), row=row, col=1)
    fig.update_xaxes(title_text=theme.axis_title("Time", "s"), row=2, col=1)
    fig.update_layout(legend=dict(orientation="h", y=-0.16, x=0.5, xanchor="center", yanchor="top"), margin=dict(b=90))
    return theme.apply(fig, title)


def energy_balance_figure(result, max_points=ENERGY_POINTS, title="Energy balance"):
    """:func:`dampersim.plotting.energy_figure` of a thinned copy of the record."""
    from dampersim.plotting import energy_figure

    sl = _thin(result.t.size, max_points)
    light = SimpleNamespace(t=result.t[sl], energy={k: np.asarray(v)[sl] for k, v in result.energy.items()})
    fig = energy_figure(light, title=title)
    fig.update_layout(height=None, legend=dict(font=dict(size=11)))
    return fig


def _energy_summary(result) -> dict:
    e = result.energy
    resid = result.energy_residual()
    work = float(abs(e["input_work"][-1]) + abs(e["motor_work"][-1]))
    return {
        "input_work_j": float(e["input_work"][-1]),
        "dissipated_j": float(e["friction"][-1] + e["damping"][-1] + e["stacking"][-1]),
        "friction_j": float(e["friction"][-1]),
        "residual_j": float(resid[-1]),
        "residual_rel": float(abs(resid[-1]) / work) if work > 0 else 0.0,
    }


# =============================================================================== explorer
def _spectrum(res, seconds):
    """Input and output amplitude spectra over the analysis window on a log axis, engine
    orders marked (as :func:`dampersim.plotting.result_spectrum_figure`, with the order
    markers set in one layout update: adding them one by one costs ~30 ms each)."""
    from dampersim.signal import DEFAULT_ORDERS, amplitude_spectrum
    from dampersim.plotting import spectrum_figure

    w = res.window(seconds)
    f, a_in = amplitude_spectrum(res.input_torque[w], res.sample_rate)
    _, a_out = amplitude_spectrum(res.output_torque[w], res.sample_rate)
    top = min(500.0, 0.45 * res.sample_rate)
    fig = spectrum_figure(f, {"input": a_in, "output": a_out}, speed_rad_s=None, f_max_hz=top, log_y=True, title="Amplitude spectra")
    f1 = res.speed / (2 * math.pi)
    ks = [k for k in DEFAULT_ORDERS if k * f1 <= top]
    fig.update_layout(
        shapes=[dict(type="line", xref="x", yref="paper", x0=k * f1, x1=k * f1, y0=0, y1=1,
                     line=dict(color="#888888", width=1, dash="dot"), layer="below") for k in ks],
        annotations=[dict(x=k * f1, y=1.0, xref="x", yref="paper", text=_fmt(k), showarrow=False, yanchor="bottom",
                          font=dict(size=11, color="#555555")) for k in ks],
        margin=dict(t=70),
        legend=dict(orientation="v", y=0.99, x=0.99, xanchor="right", yanchor="top", bgcolor="rgba(255,255,255,0.85)"),
    )
    fig.update_yaxes(exponentformat="power", dtick=1)
    fig.update_xaxes(title_text=f"Frequency [Hz] (last {_fmt(round(seconds, 3))} s, Hann)")
    return fig


def explorer_view(system, state: dict, use_cache: bool = True) -> dict:
    """One test point: traces, spectra with order markers, MR per order, windup per set
    with hardstop limits and the energy balance.

    state: from :func:`parse_query` ("explorer"): speed [rpm], torque [N m], orders
    ("2:300,4:100@90", phase in deg), duration [s]. Returns a dict with ``figures``
    (traces, spectrum, mr, windup, energy), ``orders`` (rows of :func:`order_table`),
    ``summary`` and ``key``; ``from_cache`` tells whether it came from the view cache.
    Raises ParameterError / InputError / SimulationDiverged with a clear message.
    """
    from dampersim.plotting import result_spectrum_figure, time_trace_figure
    from dampersim.simulation import simulate

    key = view_key("explorer", system, state)
    if use_cache:
        hit = load_view(key)
        if hit is not None:
            return hit
    t0 = time.perf_counter()
    ex = _excitation(state)
    duration = float(state["duration"])
    res = simulate(system, ex, duration=duration, record_segments=False)
    seconds = analysis_seconds(duration, ex.steady_start)
    excited = [k for k, a, _ in ex.orders if a > 0]
    rows = order_table(res, excited, seconds)
    speed_rpm = float(state["speed"])
    traces = time_trace_figure(res, max_points=TRACE_POINTS,
                               title=f"Torque at {_fmt(round(speed_rpm, 1))} rpm, {_fmt(state['torque'])} N m mean")
    # open on the last few revolutions (double-click shows the whole record)
    rev = 2 * math.pi / ex.speed
    show = min(duration, max(4 * rev, 0.05))
    traces.update_xaxes(range=[duration - show, float(res.t[-1])],
                        title_text=f"Time [s] (last {_fmt(round(show, 3))} s; double-click: all)")
    traces.update_layout(legend=dict(orientation="h", y=1.01, x=0, xanchor="left", yanchor="bottom", borderwidth=0,
                                     bgcolor="rgba(0,0,0,0)"), margin=dict(t=80))
    figures = {
        "traces": _fig(traces),
        "spectrum": _fig(_spectrum(res, seconds)),
        "mr": _fig(mr_figure(rows)),
        "windup": _fig(windup_figure(res, system)),
        "energy": _fig(energy_balance_figure(res)),
    }
    w = res.window(seconds)
    main = max((r for r in rows if r["excited"] and r["mr"] is not None), key=lambda r: r["input_nm"], default=None)
    summary = {
        "speed_rpm": speed_rpm,
        "mean_torque_nm": float(state["torque"]),
        "duration_s": duration,
        "analysis_window_s": seconds,
        "main_order": main["order"] if main else None,
        "main_mr": main["mr"] if main else None,
        "mean_output_torque_nm": float(np.mean(res.output_torque[w])),
        "windup_outer_deg": [float(rad_to_deg(np.min(res.windup_outer[w]))), float(rad_to_deg(np.max(res.windup_outer[w])))],
        "windup_inner_deg": [float(rad_to_deg(np.min(res.windup_inner[w]))), float(rad_to_deg(np.max(res.windup_inner[w])))],
        "hardstop_outer_share": float(np.mean(res.hardstop_outer[w] != 0.0)),
        "hardstop_inner_share": float(np.mean(res.hardstop_inner[w] != 0.0)),
        "kernel_time_s": float(res.wall_time),
        **_energy_summary(res),
    }
    summary["compute_time_s"] = time.perf_counter() - t0
    view = {"kind": "explorer", "figures": figures, "orders": rows, "summary": summary}
    return _save_view(key, view)


# =============================================================================== sweeps
class SweepRegistry:
    """Which dashboard sweeps are running on this server (all processes), so a page can say
    that it shares the cores. Entries expire unless refreshed (a killed job disappears)."""

    TTL = 20.0

    def __init__(self):
        self.id = uuid.uuid4().hex
        self._last = 0.0

    @staticmethod
    def _store():
        return view_store()

    def start(self, label: str, n_points: int):
        self._info = {"label": label, "points": int(n_points), "started": time.time()}
        self.beat(force=True)

    def beat(self, force=False):
        now = time.monotonic()
        if force or now - self._last > 2.0:
            self._last = now
            try:
                self._store().set(f"running:{self.id}", self._info, expire=self.TTL, retry=True)
            except Exception:
                pass

    def stop(self):
        try:
            self._store().delete(f"running:{self.id}", retry=True)
        except Exception:
            pass

    def others(self) -> int:
        return max(0, running_sweeps() - 1)


def running_sweeps() -> int:
    """Number of dashboard sweeps currently running on this server."""
    try:
        store = view_store()
        n = 0
        for k in store.iterkeys():
            if isinstance(k, str) and k.startswith("running:") and store.get(k) is not None:
                n += 1
        return n
    except Exception:
        return 0


def _sweep_points(speeds_text, torques, orders_text):
    from dampersim.sweeps.grid import make_grid, parse_range

    return make_grid(parse_range(speeds_text), list(torques), orders_si(parse_orders_deg(orders_text)))


def _table_orders(orders_text, extra=()):
    ks = set(REPORT_ORDERS)
    for k, a, _ in parse_orders_deg(orders_text):
        if k <= 8 and float(2 * k).is_integer():
            ks.add(float(k))
    for k in extra:
        ks.add(float(k))
    return tuple(sorted(ks))


def sweep_status(system, points, duration, window) -> dict:
    """How many of ``points`` are in the result cache: {"total", "cached"}."""
    from dampersim.sweeps.cache import ResultCache, cache_key, kernel_source_hash

    src = kernel_source_hash()
    keys = {cache_key(system, p, duration, window, source_hash=src) for p in points}
    cached = 0
    with ResultCache() as store:
        for k in keys:
            if store.diskcache.get(k, default=None) is not None:
                cached += 1
    return {"total": len(keys), "cached": cached}


def _run_points(system, points, duration, window, orders, progress=None, cancel=None, cache_only=False, workers=None,
                executor=None):
    """run_sweep with the dashboard's executor choice; ``cache_only`` assembles from the
    result cache without simulating (raises SweepCancelled when points are missing)."""
    from dampersim.sweeps.executor import run_sweep

    if cache_only:
        return run_sweep(system, points, executor="serial", duration=duration, window=window,
                         orders=orders, cancel=lambda: True)
    if executor is None:
        status = sweep_status(system, points, duration, window)
        missing = status["total"] - status["cached"]
        executor = "serial" if missing <= 2 else "processes"
    try:
        return run_sweep(system, points, executor=executor, workers=workers, progress=progress, cancel=cancel,
                         duration=duration, window=window, orders=orders)
    except InputError as exc:
        if executor == "processes" and "source files changed" in str(exc):
            # new worker processes would run newer code than this process: compute here
            return run_sweep(system, points, executor="serial", progress=progress, cancel=cancel,
                             duration=duration, window=window, orders=orders)
        raise


def colourmap_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False, workers=None, executor=None):
    """Speed sweep -> FFT colourmaps of input and output with order lines, and order cuts
    with the input for context ([thesis] §6.3.1).

    state: from :func:`parse_query` ("colourmap"). ``progress(done, total, from_cache)``
    and ``cancel`` go to :func:`dampersim.sweeps.run_sweep` (SweepCancelled when
    cancelled; finished points stay cached). ``cache_only``: return None unless every
    point is cached (nothing is simulated). ``executor``: "serial" or "processes"
    (default: processes when more than two points are missing).
    """
    from dampersim.analysis.colourmap import colourmaps, order_cuts
    from dampersim.plotting import colourmap_figure, order_cut_figure
    from dampersim.sweeps.executor import SweepCancelled

    key = view_key("colourmap", system, state)
    hit = load_view(key)
    if hit is not None:
        return hit
    t0 = time.perf_counter()
    points = _sweep_points(state["speeds"], [float(state["torque"])], state["orders"])
    cuts = [float(k) for k in str(state["cuts"]).split(",") if k]
    table_orders = _table_orders(state["orders"], cuts)
    try:
        result = _run_points(system, points, float(state["duration"]), float(state["window"]), table_orders,
                             progress, cancel, cache_only, workers, executor)
    except SweepCancelled:
        if cache_only:
            return None
        raise
    fmax = float(state["fmax"])
    maps = colourmaps(result.spectra("input"), result.spectra("output"), f_max_hz=fmax)
    fig = colourmap_figure(maps, orders=REPORT_ORDERS, f_max_hz=fmax, db=bool(state["db"]),
                           title=f"FFT colourmaps at {_fmt(state['torque'])} N m mean torque")
    for i, tr in enumerate(fig.data):
        if tr.type == "heatmap":
            z = np.asarray(tr.z, dtype=np.float32)
            tr.z = z
            if state["db"] and np.isfinite(z).any():
                # 60 dB of dynamic range below each map's peak: numerical noise far below stays dark
                top = float(np.nanmax(z))
                fig.layout[tr.coloraxis].update(cmin=top - 60.0, cmax=top)
    fig.update_layout(height=460)
    cut_table = order_cuts(result.table, orders=cuts)
    cut_fig = order_cut_figure(cut_table, orders=cuts, title="Order cuts: output (solid, left) and input (dashed, right)")
    rows = []
    for k in cuts:
        sub = cut_table[np.isclose(cut_table["order"], k)]
        mr = sub["magnification"].to_numpy(float)
        ok = np.isfinite(mr)
        if ok.any():
            i = int(np.nanargmax(np.where(ok, mr, -np.inf)))
            rows.append({"order": k, "max_mr": float(mr[i]), "at_rpm": float(sub["speed_rpm"].iloc[i]),
                         "mean_mr": float(np.nanmean(mr))})
        else:
            rows.append({"order": k, "max_mr": None, "at_rpm": None, "mean_mr": None})
    summary = {
        "points": int(result.n_points),
        "computed": int(result.computed),
        "from_cache": int(result.from_cache),
        "sweep_time_s": float(result.wall_time),
        "executor": result.executor,
        "compute_time_s": time.perf_counter() - t0,
    }
    view = {"kind": "colourmap", "figures": {"colourmap": _fig(fig), "cuts": _fig(cut_fig)}, "cuts": rows, "summary": summary}
    return _save_view(key, view)


def colourmap_status(system, state) -> dict:
    """{"total", "cached"} test points of a colourmap state in the result cache."""
    points = _sweep_points(state["speeds"], [float(state["torque"])], state["orders"])
    return sweep_status(system, points, float(state["duration"]), float(state["window"]))


def maps_status(system, state) -> dict:
    """{"total", "cached"} test points of a maps state in the result cache."""
    from dampersim.sweeps.grid import parse_torques

    points = _sweep_points(state["speeds"], parse_torques(state["torques"]), state["orders"])
    return sweep_status(system, points, float(state["duration"]), float(state["window"]))


def maps_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False, workers=None, executor=None):
    """Magnification map over (excitation frequency, mean torque) from a speed x torque
    sweep, with the engine torque curve drawn for one order and the MR predicted along it
    ([thesis] §6.3.1, §7.1.3). Arguments as :func:`colourmap_view`."""
    import plotly.graph_objects as go

    from dampersim.analysis.maps import magnification_map, predict_along_curve, torque_curve_overlay
    from dampersim.excitation import default_torque_curve
    from dampersim.plotting import magnification_map_figure, theme
    from dampersim.sweeps.executor import SweepCancelled
    from dampersim.sweeps.grid import parse_torques

    key = view_key("maps", system, state)
    hit = load_view(key)
    if hit is not None:
        return hit
    t0 = time.perf_counter()
    torques = parse_torques(state["torques"])
    points = _sweep_points(state["speeds"], torques, state["orders"])
    map_orders = [float(k) for k in str(state["map_orders"]).split(",") if k]
    try:
        result = _run_points(system, points, float(state["duration"]), float(state["window"]),
                             _table_orders(state["orders"], map_orders), progress, cancel, cache_only, workers, executor)
    except SweepCancelled:
        if cache_only:
            return None
        raise
    frange = (float(state["fmin"]), float(state["fmax"]))
    mmap = magnification_map(result.table, frequency_range_hz=frange, orders=map_orders)
    curve = default_torque_curve()
    k = float(state["curve_order"])
    overlay = torque_curve_overlay(curve, k, frequency_range_hz=frange)
    finite_mr = mmap.magnification[np.isfinite(mmap.magnification)]
    zmax = max(1.25, float(finite_mr.max()) * 1.05) if finite_mr.size else None  # resolve MR < 1 as well
    fig = magnification_map_figure(mmap, overlays=overlay if len(overlay) else None, show_points=True, zmax=zmax,
                                   title=f"Magnification map, orders {state['map_orders']}")
    fig.update_layout(height=520)
    pred = predict_along_curve(mmap, curve, k)
    pfig = go.Figure()
    pfig.add_trace(go.Scatter(x=pred["speed_rpm"], y=pred["magnification"], mode="lines", name=f"order {_fmt(k)}",
                              line=dict(color=theme.COLOURWAY[0]),
                              customdata=np.column_stack([pred["frequency_hz"], pred["mean_torque_nm"]]),
                              hovertemplate="%{x:.0f} rpm<br>MR %{y:.3f}<br>%{customdata[0]:.1f} Hz, %{customdata[1]:.0f} N m<extra></extra>"))
    pfig.add_trace(go.Scatter(x=[float(pred["speed_rpm"].min()), float(pred["speed_rpm"].max())], y=[1, 1], mode="lines",
                              line=dict(color="#D55E00", dash="dash", width=1.5), name="MR = 1", hoverinfo="skip"))
    pfig.update_xaxes(title_text=theme.axis_title("Engine speed on the torque curve", "rpm"))
    pfig.update_yaxes(title_text=theme.axis_title("Predicted magnification ratio", "-"), rangemode="tozero")
    pfig.update_layout(legend=dict(orientation="h", y=1.1, x=1, xanchor="right"))
    theme.apply(pfig, f"MR along the torque curve ({curve.name}), order {_fmt(k)}")
    finite = pred["magnification"].to_numpy(float)
    finite = finite[np.isfinite(finite)]
    mr = mmap.magnification[np.isfinite(mmap.magnification)]
    summary = {
        "points": int(result.n_points),
        "computed": int(result.computed),
        "from_cache": int(result.from_cache),
        "sweep_time_s": float(result.wall_time),
        "executor": result.executor,
        "map_points": int(len(mmap.points)),
        "share_above_one": float(np.mean(mr > 1.0)) if mr.size else None,
        "max_mr": float(mr.max()) if mr.size else None,
        "curve_max_mr": float(finite.max()) if finite.size else None,
        "curve_covered": float(np.isfinite(pred["magnification"].to_numpy(float)).mean()),
        "compute_time_s": time.perf_counter() - t0,
    }
    view = {"kind": "maps", "figures": {"map": _fig(fig), "curve": _fig(pfig)}, "summary": summary}
    return _save_view(key, view)


# =============================================================================== hysteresis
_LOOP_ARRAYS = ("time_s", "torque_nm", "windup_rad", "windup_outer_rad", "windup_inner_rad", "output_torque_nm")


def _loop_key(system, state, rpm) -> str:
    """Key of one simulated loop: only what the simulation depends on (display options such
    as the windup shown or the low pass are applied afterwards)."""
    return view_key("hysteresis-loop", system, {"protocol": state["protocol"], "speed_rpm": float(rpm),
                                                "rate": float(state["rate"]), "hold": float(state["hold"])})


def _load_loop(key):
    from dampersim.analysis.hysteresis import HysteresisLoop

    data = load_view(key)
    if data is None or "loop" not in data:
        return None
    d = data["loop"]
    return HysteresisLoop(speed_rad_s=d["speed_rad_s"], protocol=d["protocol"], label=d["label"],
                          **{k: (np.asarray(d[k]) if d[k] is not None else None) for k in _LOOP_ARRAYS})


def _save_loop(key, loop):
    d = {k: getattr(loop, k) for k in _LOOP_ARRAYS}
    d.update(speed_rad_s=float(loop.speed_rad_s), protocol=loop.protocol, label=loop.label)
    _save_view(key, {"kind": "hysteresis-loop", "loop": d})


def hysteresis_view(system, state: dict, progress=None, cancel=None, cache_only: bool = False):
    """Torque-ramp protocol at each speed -> hysteresis loops, dynamic stiffness along the
    loading branch and energy per loop ([thesis] §6.3.2, §7.3.1).

    state: from :func:`parse_query` ("hysteresis"). Each speed's loop is cached on its own
    (protocol, speed, rate, hold), so display options (windup shown, low pass) and added
    speeds reuse the loops already simulated. ``progress(done, total, from_cache)`` after
    each speed; ``cancel()`` returning True stops between speeds (InputError);
    ``cache_only``: return None unless every loop is cached.
    """
    import plotly.graph_objects as go

    from dampersim.analysis.hysteresis import analyse_loop, run_loops
    from dampersim.plotting import hysteresis_figure, stiffness_figure, theme
    from dampersim.sweeps.grid import parse_values

    key = view_key("hysteresis", system, state)
    hit = load_view(key)
    if hit is not None:
        return hit
    t0 = time.perf_counter()
    speeds_rpm = parse_values(state["speeds"], option="speeds", unit="rpm")
    keys = [_loop_key(system, state, rpm) for rpm in speeds_rpm]
    cached = {k: _load_loop(k) for k in keys}
    cached = {k: v for k, v in cached.items() if v is not None}
    if cache_only and len(cached) < len(set(keys)):
        return None
    loops, analyses = [], []
    n_cached = sum(k in cached for k in keys)
    if progress:
        progress(n_cached, len(speeds_rpm), n_cached)
    done = n_cached
    for i, (rpm, k) in enumerate(zip(speeds_rpm, keys)):
        lp = cached.get(k)
        if lp is None:
            if cancel is not None and (cancel() if callable(cancel) else cancel.is_set()):
                raise InputError(f"hysteresis run cancelled after {done} of {len(speeds_rpm)} speeds; the finished loops are cached")
            lp, = run_loops(system, state["protocol"], [rpm_to_rad_s(rpm)], rate=float(state["rate"]), hold=float(state["hold"]))
            lp = dataclasses.replace(lp, result=None)
            _save_loop(k, lp)
            cached[k] = lp
            done += 1
            if progress:
                progress(done, len(speeds_rpm), n_cached)
        if state["lowpass"]:
            lp = lp.filtered()
        loops.append(lp)
        analyses.append(analyse_loop(lp, system))
    which = state["windup"]
    knees = [a.knee for a in analyses] if which == "total" else None
    loops_fig = hysteresis_figure(loops, windup=which, knees=knees,
                                  title=f"Hysteresis loops, protocol {state['protocol']} ({_fmt(state['rate'])} N m/s)")
    stiff_fig = stiffness_figure(loops, windup=which, log_y=True)
    stiff_fig.update_yaxes(dtick=1, exponentformat="power")
    efig = go.Figure(go.Bar(x=[f"{_fmt(r)} rpm" for r in speeds_rpm], y=[a.energy_j for a in analyses], width=0.4 if len(analyses) > 1 else 0.3,
                            text=[f"{a.energy_j:.3g} J" for a in analyses], textposition="outside",
                            marker=dict(color=[theme.COLOURWAY[i % len(theme.COLOURWAY)] for i in range(len(analyses))]),
                            hovertemplate="%{x}: %{y:.4g} J<extra></extra>"))
    efig.update_xaxes(title_text=theme.axis_title("Speed", "rpm"), type="category")
    efig.update_yaxes(title_text=theme.axis_title("Energy dissipated per loop", "J"), rangemode="tozero")
    top = max([a.energy_j for a in analyses if math.isfinite(a.energy_j)] or [1.0])
    efig.update_yaxes(range=[0, 1.25 * top if top > 0 else 1.0])
    theme.apply(efig, "Energy per loop (loop area)")
    rows = []
    for rpm, a in zip(speeds_rpm, analyses):
        d = a.to_dict(ANGLE_UNIT)
        rows.append({
            "speed_rpm": float(rpm),
            "knee_torque_nm": d["knee"]["torque_nm"] if d["knee"]["found"] else None,
            "knee_windup_deg": d["knee"]["windup_deg"] if d["knee"]["found"] else None,
            "stiffness_below_nm_per_deg": d["knee"]["stiffness_below_nm_per_deg"],
            "energy_j": d["energy_per_loop_j"],
            "max_windup_deg": d["max_windup_deg"],
            "min_windup_deg": d["min_windup_deg"],
            "closure_gap_deg": d["closure_gap_deg"],
        })
    summary = {"speeds": len(speeds_rpm), "protocol": state["protocol"], "compute_time_s": time.perf_counter() - t0,
               "simulated_s": float(loops[0].time_s[-1]) if loops else 0.0}
    view = {"kind": "hysteresis", "figures": {"loops": _fig(loops_fig), "stiffness": _fig(stiff_fig), "energy": _fig(efig)},
            "loops": rows, "summary": summary}
    return _save_view(key, view)


# =============================================================================== segments
def damper_animation_figure(result, system, span: float = 0.04, gain: float = 5.0, max_frames: int = 60,
                            title="Damper drawing (primary plate fixed)"):
    """Animated drawing of the damper from the simulated segment states.

    Drawn in the frame of the primary plate: the outer set's springs run between the
    primary's stoppers (grey) and the secondary's (blue), the nested pairs of the inner set
    between the secondary's inner stoppers and the tertiary's (green). Every spring is drawn
    through its simulated nodes (slot coordinates, docs/model.md), each segment as one coil,
    so compressed segments show as tight coils. Red ticks mark where the driven body's
    stopper meets its hardstop. ``gain`` enlarges the motion about its mean over the
    animated span (the span is the last ``span`` seconds of the record); 1 draws true angles.
    """
    import plotly.graph_objects as go

    from dampersim.plotting import theme

    if result.nodes.shape[0] < 2:
        raise InputError("the result holds no segment states: simulate with record_segments=True")
    ts = result.segment_t
    keep = np.flatnonzero(ts >= ts[-1] - float(span))
    if keep.size < 2:
        keep = np.arange(max(0, ts.size - 2), ts.size)
    keep = keep[_thin(keep.size, max_frames)]
    t_frames = ts[keep]
    w_o = np.interp(t_frames, result.t, result.windup_outer)
    w_i = np.interp(t_frames, result.t, result.windup_inner)
    nodes = {sp.name: result.spring_nodes(sp.name)[keep] for sp in result.springs}

    def exaggerate(a):
        m = a.mean(axis=0, keepdims=True)
        return m + gain * (a - m)

    w_o_d, w_i_d = exaggerate(w_o[:, None])[:, 0], exaggerate(w_i[:, None])[:, 0]
    # drawing: angle on screen = 90 deg - slot angle measured in the primary's frame
    r_out, r_in, r_nest = 1.0, 0.62, 0.55
    band = 0.07

    def xy(angle_rad, r):
        a = np.pi / 2 - np.asarray(angle_rad)
        return r * np.cos(a), r * np.sin(a)

    def coil(x_nodes, r, amp, offset, count, pitch):
        """Polyline of one spring type in all slots: one coil per segment."""
        xs, ys = [], []
        n_sub = 6
        s = np.linspace(0, 1, n_sub, endpoint=False)
        for k in range(count):
            seg_a = x_nodes[:-1, None] + np.diff(x_nodes)[:, None] * s[None, :]
            ang = np.append(seg_a.ravel(), x_nodes[-1]) + offset + k * pitch
            wig = np.append(np.tile(np.sin(2 * np.pi * s), x_nodes.size - 1), 0.0)
            x, y = xy(ang, r + amp * wig)
            xs += list(np.round(x, 4)) + [None]
            ys += list(np.round(y, 4)) + [None]
        return xs, ys

    def node_marks(x_nodes, r, offset, count, pitch):
        xs, ys = [], []
        for k in range(count):
            x, y = xy(x_nodes + offset + k * pitch, r)
            xs += list(np.round(x, 4))
            ys += list(np.round(y, 4))
        return xs, ys

    def stoppers(offset, half, count, pitch, r, width):
        xs, ys = [], []
        for k in range(count):
            for side in (-half, half):
                a = offset + k * pitch + side
                x0, y0 = xy(a, r - width)
                x1, y1 = xy(a, r + width)
                xs += [round(float(x0), 4), round(float(x1), 4), None]
                ys += [round(float(y0), 4), round(float(y1), 4), None]
            # the stopper's face ring segment
            aa = offset + k * pitch + np.linspace(-half, half, 6)
            x, y = xy(aa, r + width)
            xs += list(np.round(x, 4)) + [None]
            ys += list(np.round(y, 4)) + [None]
        return xs, ys

    def ticks(angles, r, length):
        xs, ys = [], []
        for a in angles:
            x0, y0 = xy(a, r + length)
            x1, y1 = xy(a, r + 2.2 * length)
            xs += [round(float(x0), 4), round(float(x1), 4), None]
            ys += [round(float(y0), 4), round(float(y1), 4), None]
        return xs, ys

    so, si = system.outer, system.inner
    n_o = nodes["outer"]
    n_po = nodes["pair_outer"]
    n_pi = nodes.get("pair_inner")
    n_o_d, n_po_d = exaggerate(n_o), exaggerate(n_po)
    n_pi_d = exaggerate(n_pi) if n_pi is not None else None
    hs_colour = "#D55E00" if system.hardstops.enabled else "#BBBBBB"

    def frame_traces(j):
        tr = []
        x, y = coil(n_o_d[j], r_out, 0.035, 0.0, so.count, so.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[1], width=2), name="outer springs", hoverinfo="skip"))
        x, y = node_marks(n_o_d[j], r_out, 0.0, so.count, so.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="markers", marker=dict(size=4, color="#7A4F00"), name="outer segment nodes", hoverinfo="skip"))
        off_i = w_o_d[j]
        x, y = coil(n_po_d[j], r_in, 0.03, off_i, si.count, si.pitch)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[4], width=2), name="nested pairs, outer", hoverinfo="skip"))
        if n_pi_d is not None:
            x, y = coil(n_pi_d[j], r_nest, 0.018, off_i, si.count, si.pitch)
        else:
            x, y = [], []
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[5], width=1.5), name="nested pairs, inner", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j], so.secondary_stopper_half_width, so.count, so.pitch, r_out, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[0], width=4), name="secondary stoppers", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j], si.primary_stopper_half_width, si.count, si.pitch, r_in, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[0], width=3, dash="dot"), name="secondary inner stoppers", hoverinfo="skip"))
        x, y = stoppers(w_o_d[j] + w_i_d[j], si.secondary_stopper_half_width, si.count, si.pitch, r_in, band * 0.8)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=theme.COLOURWAY[2], width=4), name="tertiary (hub) stoppers", hoverinfo="skip"))
        angs = [off_i + k * si.pitch + lim for k in range(si.count) for lim in (si.hardstop_positive, si.hardstop_negative)]
        x, y = ticks(angs, r_in, band)
        tr.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=hs_colour, width=3), name="inner hardstops", hoverinfo="skip"))
        return tr

    # static parts: primary stoppers, outer hardstops, plate rings
    static = []
    circ = np.linspace(0, 2 * np.pi, 241)
    for r, col in ((r_out + band + 0.04, "#888888"), (r_in + band + 0.03, "#9AB8D3"), (r_nest - 0.08, "#B5D9C6")):
        static.append(go.Scatter(x=list(np.round(r * np.cos(circ), 4)), y=list(np.round(r * np.sin(circ), 4)), mode="lines",
                                 line=dict(color=col, width=1), hoverinfo="skip", showlegend=False))
    x, y = stoppers(0.0, so.primary_stopper_half_width, so.count, so.pitch, r_out, band)
    static.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color="#555555", width=4), name="primary stoppers", hoverinfo="skip"))
    angs = [k * so.pitch + lim for k in range(so.count) for lim in (so.hardstop_positive, so.hardstop_negative)]
    x, y = ticks(angs, r_out, band)
    static.append(go.Scatter(x=x, y=y, mode="lines", line=dict(color=hs_colour, width=3), name="outer hardstops", hoverinfo="skip"))

    first = frame_traces(0)
    n_static = len(static)
    fig = go.Figure(data=static + first)
    moving = list(range(n_static, n_static + len(first)))
    frames = []
    for j in range(len(keep)):
        frames.append(go.Frame(data=frame_traces(j), traces=moving, name=f"{t_frames[j]:.4f}"))
    fig.frames = frames
    steps = [dict(method="animate", label=f"{t_frames[j]:.3f}",
                  args=[[f"{t_frames[j]:.4f}"], dict(mode="immediate", frame=dict(duration=0, redraw=False), transition=dict(duration=0))])
             for j in range(len(keep))]
    fig.update_layout(
        updatemenus=[dict(type="buttons", showactive=False, x=0.0, y=-0.02, xanchor="left", yanchor="top", direction="left", pad=dict(t=10),
                          buttons=[dict(label="▶ Play", method="animate",
                                        args=[None, dict(frame=dict(duration=60, redraw=False), fromcurrent=True, transition=dict(duration=0), mode="immediate")]),
                                   dict(label="❚❚ Pause", method="animate",
                                        args=[[None], dict(frame=dict(duration=0, redraw=False), mode="immediate", transition=dict(duration=0))])])],
        sliders=[dict(active=0, steps=steps, x=0.3, len=0.7, y=-0.02, yanchor="top",
                      currentvalue=dict(prefix="t = ", suffix=" s", font=dict(size=12)), pad=dict(t=10))],
        xaxis=dict(visible=False, range=[-1.35, 1.35], scaleanchor="y", scaleratio=1, showgrid=False),
        yaxis=dict(visible=False, range=[-1.3, 1.3], showgrid=False),
        legend=dict(orientation="v", x=1.02, y=1, font=dict(size=11)),
        margin=dict(l=10, r=10, t=60, b=80),
    )
    theme.apply(fig, title + (f" · motion ×{_fmt(gain)} about the mean" if gain != 1 else ""))
    fig.update_xaxes(visible=False, showline=False)
    fig.update_yaxes(visible=False, showline=False)
    return fig


def segments_view(system, state: dict, use_cache: bool = True) -> dict:
    """Segment motion of one test point: compression of each segment over time (heatmap)
    and the animated damper drawing ([thesis] §7.3, Fig. 7.24-7.25)."""
    from dampersim.plotting import segment_compression_figure
    from dampersim.simulation import simulate

    key = view_key("segments", system, state)
    if use_cache:
        hit = load_view(key)
        if hit is not None:
            return hit
    t0 = time.perf_counter()
    ex = _excitation(state)
    # the simulation is cached apart from the display options (spring, windows, gain)
    sim_key = view_key("segments-simulation", system, {k: state[k] for k in ("speed", "torque", "orders", "duration")})
    try:
        res = view_store().get(sim_key, default=None, retry=True) if use_cache else None
    except Exception:
        res = None
    if res is None or not hasattr(res, "nodes"):
        res = simulate(system, ex, duration=float(state["duration"]), record_segments=True)
        try:
            view_store().set(sim_key, res, retry=True)
        except Exception:
            pass
    names = [s.name for s in res.springs]
    spring = state["spring"] if state["spring"] in names else names[0]
    k0 = int(np.searchsorted(res.segment_t, res.segment_t[-1] - float(state["window"]) - 1e-12))
    k0 = min(k0, max(res.segment_t.size - 2, 0))
    tail = dataclasses.replace(res, nodes=res.nodes[k0:], segment_t=res.segment_t[k0:])
    heat = segment_compression_figure(tail, spring=spring, max_frames=1500,
                                      title=f"Segment compression, {spring.replace('_', ' ')} spring, last {_fmt(float(state['window']))} s")
    heat.data[0].z = np.asarray(heat.data[0].z, dtype=np.float32)
    anim = damper_animation_figure(res, system, span=float(state["span"]), gain=float(state["gain"]))
    comp = rad_to_deg(res.segment_compression(spring))
    steady = res.segment_t >= ex.steady_start
    c = comp[steady] if steady.any() else comp
    amp = (c.max(axis=0) - c.min(axis=0)) / 2
    rows = [{"segment": i + 1, "mean_deg": float(c[:, i].mean()), "amplitude_deg": float(amp[i]),
             "max_deg": float(c[:, i].max())} for i in range(c.shape[1])]
    summary = {
        "spring": spring,
        "segments": int(c.shape[1]),
        "frames": int(res.nodes.shape[0]),
        "end_to_middle_amplitude": float(max(amp[0], amp[-1]) / max(np.median(amp), 1e-12)),
        "compute_time_s": time.perf_counter() - t0,
    }
    view = {"kind": "segments", "figures": {"heatmap": _fig(heat), "animation": _fig(anim)}, "segments": rows, "summary": summary}
    return _save_view(key, view)


# =============================================================================== parameters
def parameters_view(system, base=None) -> list:
    """Rows {name, value, unit, doc, accepted, changed, kind} of every dotted parameter
    (values as text, SI units); ``changed`` compares with ``base`` (default set)."""
    from dampersim.parameters import dotted_names
    from dampersim.parameters.validation import _describe

    base = base if base is not None else dampersim.default_parameters()
    base_names = set(dotted_names(base))
    rows = []
    for name in dotted_names(system):
        value, meta = _field_meta(system, name)
        kind = meta.get("kind")
        kind_name = {bool: "bool", int: "int", float: "float"}.get(kind, "text")
        try:
            changed = name not in base_names or _field_meta(base, name)[0] != value
        except Exception:
            changed = True
        rows.append({
            "name": name,
            "value": _fmt(value),
            "unit": meta.get("unit", "") if meta.get("unit") not in (None, "-") else "",
            "doc": meta.get("doc", ""),
            "accepted": _describe(meta) if kind in (int, float) else ("true or false" if kind is bool else "text"),
            "kind": kind_name,
            "changed": bool(changed),
        })
    return rows


def params_for_system(system) -> dict:
    """Parameter state that reproduces ``system``: overrides of the default set when the
    structure matches it, else a stored set (``{"set": id, "overrides": {}}``)."""
    from dampersim.parameters import dotted_names

    default = dampersim.default_parameters()
    if set(dotted_names(system)) == set(dotted_names(default)) and \
            [e.name for e in system.rig.elements] == [e.name for e in default.rig.elements]:
        overrides = {}
        for name in dotted_names(system):
            if name in _LABEL_NAMES:
                continue
            v = _override_value(system, name)
            if v != _override_value(default, name):
                overrides[name] = v
        check, accepted = apply_overrides(default, overrides)
        if accepted == overrides:
            return {"set": None, "overrides": overrides}
    return {"set": store_parameter_set(system), "overrides": {}}


def _decode_upload(contents, name: str, accepted: str, max_bytes: int, size_text, *, size_accepted: str | None = None,
                   base64_accepted: bool = True) -> bytes:
    """The bytes of a browser upload (``data:...;base64,...``).

    Raises InputError naming the file (``name``) for an upload without content, data
    that is not base64 and more than ``max_bytes`` bytes (``size_text(n)`` writes the size,
    ``size_accepted`` replaces ``accepted`` in that message); ``base64_accepted=False``
    leaves "accepted is ..." out of the base64 message.
    """
    if not isinstance(contents, str) or "," not in contents:
        raise InputError(f"{name}: the upload arrived without content; accepted is {accepted}")
    try:
        data = base64.b64decode(contents.split(",", 1)[1], validate=True)
    except (binascii.Error, ValueError):
        raise InputError(f"{name}: the upload is not valid base64 data"
                         + (f"; accepted is {accepted}" if base64_accepted else "")) from None
    if len(data) > max_bytes:
        raise InputError(f"{name} is {size_text(len(data))}; accepted is {size_accepted or accepted}")
    return data


def parse_uploaded_parameters(contents, filename: str = "parameters.toml"):
    """A parameter file from a browser upload (``data:...;base64,...``) -> DamperSystem.

    Raises InputError / ParameterError with a message that names the file and what is
    wrong (not base64, too large, not UTF-8 text, not TOML, unknown or invalid values).
    """
    from dampersim.parameters import loads_toml

    name = filename or "uploaded file"
    data = _decode_upload(contents, name, "a TOML parameter file", MAX_UPLOAD_BYTES, lambda n: f"{n / 1024:.0f} kB",
                          size_accepted=f"a TOML parameter file up to {MAX_UPLOAD_BYTES // 1024} kB",
                          base64_accepted=False)
    if not data.strip():
        raise InputError(f"{name} is empty; accepted is a TOML parameter file (download one to see the format)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{name} is not UTF-8 text; accepted is a TOML parameter file") from None
    try:
        return loads_toml(text)
    except ParameterError as exc:
        raise ParameterError(f"{name}: {exc.field}", exc.value, exc.accepted,
                             str(exc).split(" (", 1)[1].rstrip(")") if " (" in str(exc) else "") from None


def parameters_toml(system) -> str:
    """TOML text of ``system`` for download."""
    from dampersim.parameters import dumps_toml

    return dumps_toml(system)


def apply_table_edits(params: dict | None, rows: list) -> tuple:
    """Edited parameter rows (name, value as text) -> (new params, system) or raise
    ParameterError naming the first refused value. The previous params stay untouched."""
    from dampersim.parameters import with_updates

    params = params or {}
    base = base_system(params.get("set"))
    current = resolve_system(params)
    updates = {}
    for r in rows:
        name, text = r.get("name"), r.get("value")
        if name in _LABEL_NAMES or name is None:
            continue
        if str(_fmt(_override_value(current, name))) != str(text).strip():
            updates[name] = str(text).strip()
    if not updates:
        return params, current
    system = with_updates(current, updates)
    overrides = dict(params.get("overrides") or {})
    for name in updates:
        overrides[name] = _override_value(system, name)
    _, accepted = apply_overrides(base, overrides)
    return {"set": params.get("set"), "overrides": accepted}, system


# =============================================================================== discrepancy
# The Discrepancy page: which campaign (a bundled example or an upload), the campaign's
# validation report, and the cached diagnosis of :mod:`dampersim.discrepancy` with its
# figures. Uploaded zips are unpacked under ``cache_dir()/"campaign-uploads"/<id>``, where
# the id is a hash of the zip's bytes, so the same upload lands in the same folder.

#: Sub-directory of the cache with the unpacked campaign uploads.
UPLOADS_SUBDIR = "campaign-uploads"
#: Largest campaign zip accepted [bytes] (the server refuses requests above 16 MB and the
#: browser sends the file base64-encoded, 4/3 of its size).
MAX_CAMPAIGN_ZIP_BYTES = 10 * 2**20
#: Most files, and most bytes once unpacked, of one uploaded campaign (refused before
#: anything is written, so an archive that expands enormously is never unpacked).
MAX_CAMPAIGN_FILES = 2000
MAX_CAMPAIGN_UNPACKED_BYTES = 256 * 2**20
#: Keyword arguments of :func:`dampersim.discrepancy.diagnose.diagnose` used by the
#: dashboard (empty: the library's defaults); part of the cache key.
DISCREPANCY_OPTIONS: dict = {}
#: Bumped when the content of a cached diagnosis view changes shape.
DISCREPANCY_FORMAT = 1
#: Default example campaign of the page (the first bundled one if it is missing).
DEFAULT_EXAMPLE = "hidden-effect-example"
#: Rough cost of the diagnosis [core seconds per second of torsional record], measured
#: on the bundled example (12 points of 1 s: 69 s on 2 cores with
#: ``python -m dampersim diagnose examples/campaigns/hidden-effect-example --json``).
DIAGNOSIS_CORE_S_PER_RECORD_S = 11.2

CAMPAIGN_ACCEPTED = (f"a .zip (up to {MAX_CAMPAIGN_ZIP_BYTES // 2**20} MB) of one campaign folder: manifest.csv with the "
                     "columns id, kind, speed_rpm, mean_torque_nm, file, sample_rate_hz, the time series it lists "
                     "(.parquet or .csv) and optionally campaign.json (see docs/discrepancy.md)")
_UPLOAD_ID = re.compile(r"^[0-9a-f]{16}$")
UPLOAD_PREFIX = "upload:"


def example_campaigns_dir() -> Path:
    """Folder of the bundled example campaigns (``examples/campaigns`` of the checkout)."""
    from dampersim.sweeps.cache import repo_root

    return repo_root() / "examples" / "campaigns"


def example_campaigns(root=None) -> dict:
    """Bundled example campaigns: folder name -> path (folders holding a manifest.csv)."""
    from dampersim.discrepancy.campaign import MANIFEST

    root = Path(root) if root is not None else example_campaigns_dir()
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return {}
    return {p.name: p for p in entries if p.is_dir() and (p / MANIFEST).is_file()}


def default_example(examples: dict):
    """The example a page shows first (None when nothing is bundled)."""
    return DEFAULT_EXAMPLE if DEFAULT_EXAMPLE in examples else next(iter(examples), None)


def _uploads_dir() -> Path:
    return cache_dir() / UPLOADS_SUBDIR


def _manifest_dirs(root: Path) -> list:
    """Shallowest folders under ``root`` that hold a manifest.csv."""
    from dampersim.discrepancy.campaign import MANIFEST

    hits = []
    for sub, dirs, files in os.walk(root):
        dirs.sort()
        if MANIFEST in files:
            hits.append(Path(sub))
            dirs[:] = []  # a campaign's own sub-folders are its data, not more campaigns
    if not hits:
        return []
    depth = min(len(h.relative_to(root).parts) for h in hits)
    return [h for h in hits if len(h.relative_to(root).parts) == depth]


def upload_folder(upload_id):
    """Campaign folder of an earlier upload, or None (unknown id or cleared cache)."""
    if not isinstance(upload_id, str) or not _UPLOAD_ID.match(upload_id):
        return None
    root = _uploads_dir() / upload_id
    if not root.is_dir():
        return None
    found = _manifest_dirs(root)
    return found[0] if len(found) == 1 else None


def upload_label(upload_id: str) -> str:
    """Dropdown label of an upload: its file name and campaign name when known."""
    try:
        meta = json.loads((_uploads_dir() / f"{upload_id}.json").read_text(encoding="utf-8"))
        return f"uploaded: {meta.get('name') or upload_id} ({meta.get('filename') or 'zip'})"
    except (OSError, ValueError, AttributeError):
        return f"uploaded campaign {upload_id}"


def _zip_members(zf, name: str, accepted: str) -> list:
    """(ZipInfo, relative parts) of the files to unpack; refuses unsafe or huge archives."""
    import stat
    from pathlib import PurePosixPath

    members, total = [], 0
    for zi in zf.infolist():
        if zi.is_dir():
            continue
        raw = zi.filename.replace("\\", "/")
        parts = PurePosixPath(raw).parts
        if raw.startswith("/") or not parts or ".." in parts or ":" in parts[0]:
            raise InputError(f"{name}: the entry {zi.filename!r} points outside the archive; accepted is {accepted}")
        if parts[0] == "__MACOSX" or parts[-1].startswith("._") or parts[-1] == ".DS_Store":
            continue  # file-system litter of archivers, not campaign data
        if stat.S_ISLNK(zi.external_attr >> 16):
            raise InputError(f"{name}: the entry {zi.filename!r} is a symbolic link; accepted is {accepted}")
        if zi.flag_bits & 0x1:
            raise InputError(f"{name} is encrypted; accepted is {accepted}, without a password")
        total += zi.file_size
        members.append((zi, parts))
    if len(members) > MAX_CAMPAIGN_FILES:
        raise InputError(f"{name} holds {len(members)} files, more than the {MAX_CAMPAIGN_FILES} accepted; accepted is {accepted}")
    if total > MAX_CAMPAIGN_UNPACKED_BYTES:
        raise InputError(f"{name} unpacks to {total / 2**20:.0f} MB, more than the {MAX_CAMPAIGN_UNPACKED_BYTES // 2**20} MB "
                         f"accepted; accepted is {accepted}")
    return members


def unpack_campaign_zip(contents, filename: str = "campaign.zip") -> str:
    """A campaign zip from a browser upload (``data:...;base64,...``) -> its upload id.

    The zip is unpacked under the cache (see :func:`upload_folder`); the campaign is the
    shallowest folder holding a manifest.csv (the zip may hold the folder or its content).
    Raises InputError naming the file and what is accepted: not base64, too large, not a
    zip, damaged, unsafe entries (absolute paths, "..", links), too many or too large
    files, no manifest.csv, more than one campaign or manifest entries outside the campaign
    folder (:func:`dampersim.discrepancy.campaign.paths_outside`). Nothing is kept of a
    refused upload.
    """
    import io
    import shutil
    import tempfile
    import zipfile
    import zlib

    from dampersim.discrepancy.campaign import MANIFEST, paths_outside, read_campaign

    name = filename or "uploaded file"
    accepted = CAMPAIGN_ACCEPTED
    data = _decode_upload(contents, name, accepted, MAX_CAMPAIGN_ZIP_BYTES, lambda n: f"{n / 2**20:.1f} MB")
    if not data:
        raise InputError(f"{name} is empty; accepted is {accepted}")
    buf = io.BytesIO(data)
    if not zipfile.is_zipfile(buf):
        raise InputError(f"{name} is not a zip archive; accepted is {accepted}")
    upload_id = hashlib.sha256(data).hexdigest()[:16]
    if upload_folder(upload_id) is not None:
        return upload_id  # the same zip was unpacked before
    root = _uploads_dir()
    try:
        os.makedirs(root, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cache directory {str(root)!r} cannot be used ({exc.strerror or exc}); "
                         "set DAMPERSIM_CACHE_DIR to a writable folder") from None
    tmp = Path(tempfile.mkdtemp(prefix=f".{upload_id}-", dir=root))
    try:
        try:
            with zipfile.ZipFile(buf) as zf:
                members = _zip_members(zf, name, accepted)
                if not any(parts[-1] == MANIFEST for _zi, parts in members):
                    raise InputError(f"{name} holds no {MANIFEST}; accepted is {accepted}")
                budget = MAX_CAMPAIGN_UNPACKED_BYTES
                for zi, parts in members:
                    target = tmp.joinpath(*parts)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(zi) as src, open(target, "wb") as dst:
                        while chunk := src.read(2**20):
                            budget -= len(chunk)
                            if budget < 0:  # the sizes in the archive's directory were wrong
                                raise InputError(f"{name} unpacks to more than {MAX_CAMPAIGN_UNPACKED_BYTES // 2**20} MB; "
                                                 f"accepted is {accepted}")
                            dst.write(chunk)
        except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as exc:
            raise InputError(f"{name} is a damaged or unsupported zip archive ({exc}); accepted is {accepted}") from None
        found = _manifest_dirs(tmp)
        if len(found) > 1:
            names = ", ".join(str(f.relative_to(tmp)) or "." for f in found)
            raise InputError(f"{name} holds {len(found)} campaigns ({names}); accepted is {accepted}")
        outside = paths_outside(found[0])  # an upload may only make the server read its own files
        if outside:
            row, rel = outside[0]
            raise InputError(f"{name}: {MANIFEST} row {row} [file]: {rel!r} lies outside the campaign folder; "
                             "accepted is a path relative to the folder, e.g. points/tc_1200.parquet")
        try:
            cname = read_campaign(found[0]).name
        except InputError:
            cname = found[0].name  # the validation report on the page says what is wrong
        dest = root / upload_id
        try:
            os.replace(tmp, dest)
        except OSError:
            if upload_folder(upload_id) is None:  # not a concurrent upload of the same zip
                raise
        (root / f"{upload_id}.json").write_text(json.dumps({"filename": name, "name": cname}), encoding="utf-8")
        return upload_id
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def parse_discrepancy_query(query: dict | None, examples: dict) -> tuple:
    """The Discrepancy page's query -> ``(state, notices)``.

    Keys: ``campaign`` (a bundled example's folder name) or ``upload`` (the id of a
    campaign uploaded to this server; it wins over ``campaign``). A refused value gives a
    notice naming the key, the value, what is accepted and what is used instead; unknown
    keys are ignored. ``state`` = {"campaign": name or None, "upload": id or None}.
    """
    state, notices, _folder = _discrepancy_query(query, examples)
    return state, notices


def _discrepancy_query(query: dict | None, examples: dict) -> tuple:
    """:func:`parse_discrepancy_query` plus the campaign folder it resolved (see
    :func:`discrepancy_folder`): ``(state, notices, folder or None)``."""
    query = dict(query or {})
    notices: list = []
    fallback = default_example(examples)
    used = f"the example {fallback}" if fallback else "no campaign (upload one)"
    state = {"campaign": fallback, "upload": None}
    if "upload" in query:
        raw = _single(query, "upload", notices, "Uploaded campaign")
        text = str(raw).strip()
        if not _UPLOAD_ID.match(text):
            notices.append(notice(f"Uploaded campaign (upload={raw!r}) is not an upload id: accepted is the 16 hex digits "
                                  f"the page writes into the link after an upload. Using {used}."))
        elif (folder := upload_folder(text)) is None:
            notices.append(notice(f"Uploaded campaign (upload={raw!r}) is not on this server (uploads live in the cache, "
                                  f"which may have been cleared): upload the zip again. Using {used}."))
        else:
            return {"campaign": None, "upload": text}, notices, folder
    if "campaign" in query:
        raw = _single(query, "campaign", notices, "Example campaign")
        if isinstance(raw, str) and raw in examples:
            state["campaign"] = raw
        else:
            names = ", ".join(examples) if examples else "(none bundled with this installation)"
            notices.append(notice(f"Example campaign (campaign={raw!r}) is not a bundled example: accepted is one of {names}. "
                                  f"Using {used}."))
    if not examples:
        notices.append(notice("No example campaigns are bundled with this installation: upload a campaign.", "info"))
    return state, notices, discrepancy_folder(state, examples)


def discrepancy_choice(value, examples: dict) -> tuple:
    """A campaign dropdown value (example name or ``upload:<id>``) -> ``(state, notices,
    folder)``: the state and notices of :func:`parse_discrepancy_query` and the campaign
    folder (:func:`discrepancy_folder`, resolved once) or None."""
    if isinstance(value, str) and value.startswith(UPLOAD_PREFIX):
        return _discrepancy_query({"upload": value[len(UPLOAD_PREFIX):]}, examples)
    return _discrepancy_query({"campaign": value} if value is not None else {}, examples)


def discrepancy_value(state: dict):
    """Dropdown value of a state (inverse of :func:`discrepancy_choice`)."""
    return UPLOAD_PREFIX + state["upload"] if state.get("upload") else state.get("campaign")


def discrepancy_query(state: dict) -> str:
    """Query string (with "?") of a Discrepancy page state."""
    if state.get("upload"):
        return "?upload=" + quote(state["upload"], safe="")
    if state.get("campaign"):
        return "?campaign=" + quote(state["campaign"], safe="._-")
    return ""


def discrepancy_folder(state: dict, examples: dict):
    """Campaign folder of a state, or None."""
    if state.get("upload"):
        return upload_folder(state["upload"])
    path = examples.get(state.get("campaign") or "")
    return Path(path) if path is not None else None


def summarise_campaign(camp) -> dict:
    """Validation report of a campaign already read (a
    :class:`dampersim.discrepancy.campaign.Campaign`), JSON-ready: see :func:`campaign_summary`."""
    from dampersim.discrepancy.diagnose import MIN_TORSIONAL_POINTS

    rep = camp.report()
    return {"name": camp.name, "description": camp.description, "rows": rep["rows"], "valid": len(camp.points),
            "torsional": len(camp.torsional), "ramps": len(camp.ramps),
            "record_s": float(sum(p.duration for p in camp.torsional)),
            "problems": rep["problems"], "error": None, "ready": len(camp.torsional) >= MIN_TORSIONAL_POINTS}


def _folder_files(folder: Path) -> tuple:
    """((relative path, size, mtime_ns), ...) of every file under ``folder`` in a fixed
    order: the memo key of :func:`campaign_summary` and :func:`campaign_digest`, so a
    changed, added or removed file gives a new key."""
    out = []
    for sub, dirs, files in os.walk(folder):
        dirs.sort()
        for f in sorted(files):
            p = Path(sub) / f
            try:
                st = p.stat()
            except OSError:
                continue  # gone since the walk
            out.append((p.relative_to(folder).as_posix(), st.st_size, st.st_mtime_ns))
    return tuple(out)


def campaign_summary(folder) -> dict:
    """Validation report of the campaign in ``folder``, JSON-ready.

    {"name", "description", "rows", "valid", "torsional", "ramps", "record_s", "problems"
    (each with file, field, point, message), "error" (a campaign that cannot be read at
    all) and "ready" (enough valid torsional points for the diagnosis)}. Paths in messages
    are relative to the campaign folder (the server's folders are not shown). Memoised
    per process on the folder and the size and modification time of its files.
    """
    folder = Path(folder)
    return copy.deepcopy(_campaign_summary(str(folder), _folder_files(folder)))


@functools.lru_cache(maxsize=32)
def _campaign_summary(folder: str, _files: tuple) -> dict:
    from dampersim.discrepancy.campaign import read_campaign

    folder = Path(folder)
    try:
        camp = read_campaign(folder)
    except InputError as exc:
        msg = str(exc).replace(str(folder) + os.sep, "").replace(str(folder), folder.name)
        return {"name": folder.name, "description": "", "rows": 0, "valid": 0, "torsional": 0, "ramps": 0,
                "record_s": 0.0, "problems": [], "error": msg, "ready": False}
    return summarise_campaign(camp)


def diagnosis_seconds(record_s: float, cores: int | None = None) -> float:
    """Rough wall time [s] of diagnosing torsional records of ``record_s`` seconds in all."""
    from dampersim.discrepancy.drive import Runner

    cores = cores or Runner(None).workers
    return 2.0 + DIAGNOSIS_CORE_S_PER_RECORD_S * float(record_s) / max(1, cores)


def campaign_digest(folder) -> str:
    """SHA-256 of every file of a campaign folder (relative path and bytes); memoised per
    process on the folder and the size and modification time of its files."""
    folder = Path(folder)
    return _campaign_digest(str(folder), _folder_files(folder))


@functools.lru_cache(maxsize=32)
def _campaign_digest(folder: str, files: tuple) -> str:
    h = hashlib.sha256()
    for rel, _size, _mtime in files:
        h.update(rel.encode() + b"\0")
        with open(Path(folder, rel), "rb") as fh:
            for chunk in iter(lambda: fh.read(2**20), b""):
                h.update(chunk)
        h.update(b"\0")
    return h.hexdigest()


#: package files behind a diagnosis besides the simulation's (sweeps.cache.SOURCE_FILES)
#: and the discrepancy package's own modules
DISCREPANCY_EXTRA_SOURCES = ("analysis/hysteresis.py", "excitation/measured.py", "solver/linear.py")


def discrepancy_source_hash() -> str:
    """Hash of the code behind a diagnosis: the simulation's source files, every module
    of the discrepancy package and the analysis it uses (read once per process)."""
    from dampersim.sweeps.cache import SOURCE_FILES, source_hash

    pkg = Path(dampersim.__file__).resolve().parent
    own = tuple(p.relative_to(pkg).as_posix() for p in sorted((pkg / "discrepancy").glob("*.py")))
    return source_hash(SOURCE_FILES + own + DISCREPANCY_EXTRA_SOURCES)


def discrepancy_key(folder, system=None) -> str:
    """Cache key of a diagnosis: campaign files, parameter set, options, code and version
    (a :func:`view_key` of kind "discrepancy" with the code of :func:`discrepancy_source_hash`)."""
    from dampersim.parameters import default_parameters

    state = {"format": DISCREPANCY_FORMAT, "campaign": campaign_digest(folder), "options": DISCREPANCY_OPTIONS}
    return view_key("discrepancy", system or default_parameters(), state, source=discrepancy_source_hash())


def diagnosis_document(diag) -> dict:
    """A Diagnosis -> JSON-ready document: :meth:`Diagnosis.to_json` plus the per-point
    data the figures need (``points``: measured and simulated order amplitudes per stage;
    ``residuals``: stage -> point id -> order errors [N m])."""
    doc = dict(diag.to_json())
    doc["points"] = diag.points
    doc["residuals"] = diag.residuals
    return jsonable(doc)


_DOC_FLOATS = ("noise_floor_nm", "gap_before_nm", "gap_calibrated_nm", "gap_after_nm")


def diagnosis_from_document(doc: dict) -> SimpleNamespace:
    """A diagnosis document (or the ``diagnose --json`` output) -> an object with the
    attributes the figure builders of :mod:`dampersim.plotting.discrepancy` read.
    Missing numbers become NaN; a document without ``points``/``residuals`` (the CLI's)
    gives empty ones."""
    if not isinstance(doc, dict) or "verdict" not in doc:
        raise InputError("a diagnosis document: accepted is the JSON of Diagnosis.to_json() (with a 'verdict')")
    d = dict(doc)
    for k in _DOC_FLOATS:
        d[k] = float("nan") if d.get(k) is None else float(d[k])
    d.setdefault("effect", None)
    d.setdefault("effect_parameters", {})
    d.setdefault("ranking", [])
    d.setdefault("held_out_points", [])
    d["points"] = list(d.get("points") or [])
    d["residuals"] = {k: dict(v) for k, v in (d.get("residuals") or {}).items()}
    d.setdefault("locate", {})
    d.setdefault("problems", [])
    return SimpleNamespace(**d)


def has_point_data(doc: dict) -> bool:
    """Whether a diagnosis document holds the per-point data of the residual figures."""
    res = (doc or {}).get("residuals") or {}
    return bool((doc or {}).get("points")) and all(s in res for s in ("before", "calibrated", "after"))


def discrepancy_figures(doc: dict) -> dict:
    """Figures (plain dicts) of a diagnosis document: ``gap``, ``ranking`` and, when the
    document holds per-point data, ``map``, ``profile`` and ``overlays`` (else None)."""
    from dampersim.plotting import discrepancy as fig

    d = diagnosis_from_document(doc)
    gap = fig.gap_figure(d, None)
    ranking = fig.ranking_figure(d, None)
    out = {"gap": _fig(gap), "ranking": _fig(ranking)}
    full = has_point_data(doc)
    out["map"] = _fig(fig.residual_map_figure(d, None)) if full else None
    out["profile"] = _fig(fig.residual_profile_figure(d, None)) if full else None
    out["overlays"] = _fig(fig.held_out_overlay_figure(d, None)) if full else None
    return out


def effect_parameter_text(name, values: dict) -> str:
    """"capacity = 930 N m, drag = 0.4 N m s/rad" with the units of the effect registry."""
    from dampersim.discrepancy.effects import NAMES, parameters_of

    units = {p["name"]: p["unit"] for p in parameters_of(name)} if name in NAMES else {}
    items = []
    for k, v in (values or {}).items():
        unit = units.get(k, "")
        val = f"{v:.4g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)
        items.append(f"{k} = {val}" + (f" {unit}" if unit and unit != "-" else ""))
    return ", ".join(items)


def ranking_rows(doc: dict) -> list:
    """Ranking of a diagnosis document as table rows: effect, fitted parameters (with
    units), held-out gap [N m], improvement over the calibrated model [%], complexity
    penalty [N m] (score minus gap), score [N m], training fit and screen fit [N m], and
    the starting point the effect was fitted from ("calibrated" or "estimated"
    parameters; None in documents from before that choice existed)."""
    rows = []
    for i, r in enumerate(doc.get("ranking") or [], start=1):
        gap, score = r.get("gap_held_out_nm"), r.get("score")
        imp = r.get("improvement")
        rows.append({
            "rank": i,
            "effect": r.get("effect"),
            "parameters": effect_parameter_text(r.get("effect"), r.get("parameters") or {}) or "screened out",
            "gap_held_out_nm": gap,
            "improvement_pct": None if imp is None else 100.0 * imp,
            "penalty_nm": None if gap is None or score is None else score - gap,
            "score_nm": score,
            "train_fit_nm": r.get("train_fit_nm"),
            "screen_fit_nm": r.get("screen_fit_nm"),
            "start": r.get("fitted_from"),
            "named": r.get("effect") == doc.get("effect"),
        })
    return rows


def verdict_summary(doc: dict) -> dict:
    """What a diagnosis document concludes, in words: {"verdict", "level" (notice level),
    "headline", "reason", "effect" (registry description or None), "parameters" (text with
    units), "collapses_on"}. The thresholds are those of :mod:`dampersim.discrepancy.diagnose`."""
    from dampersim.discrepancy import diagnose as dg
    from dampersim.discrepancy.effects import NAMES, describe

    def nm(v):
        return "—" if v is None else f"{float(v):.3g} N m"

    verdict, effect = doc.get("verdict"), doc.get("effect")
    floor, cal, after = doc.get("noise_floor_nm"), doc.get("gap_calibrated_nm"), doc.get("gap_after_nm")
    ranked = [r for r in doc.get("ranking") or [] if r.get("gap_held_out_nm") is not None]
    if verdict == "missing_effect":
        level, headline = "success", f"Missing effect: {effect}"
        reason = (f"With {effect} added, the held-out gap falls from {nm(cal)} (calibrated) to {nm(after)}, within "
                  f"{dg.FLOOR_FACTOR_UNEXPLAINED:g}x the noise floor of {nm(floor)}.")
    elif verdict == "no_missing_effect":
        level, headline = "info", "No missing effect"
        reason = (f"After calibration the held-out gap is {nm(cal)}, within {dg.FLOOR_FACTOR_NONE:g}x the noise floor of "
                  f"{nm(floor)}: the model explains this campaign; any candidate would be fitting noise.")
    else:
        level, headline = "warning", "Unexplained discrepancy"
        best = ranked[0] if ranked else None
        reason = (f"After calibration the held-out gap is {nm(cal)}, above {dg.FLOOR_FACTOR_NONE:g}x the noise floor of "
                  f"{nm(floor)}, but no candidate closes it: " + (
                      f"the best, {best['effect']}, leaves {nm(best['gap_held_out_nm'])} (a named effect must cut the gap by "
                      f"at least {100 * dg.MIN_IMPROVEMENT:.0f} % and leave it within {dg.FLOOR_FACTOR_UNEXPLAINED:g}x the floor)."
                      if best else "no candidate could be fitted."))
    axes = (doc.get("locate") or {}).get("axes") or {}
    where = (doc.get("locate") or {}).get("collapses_on")
    return {
        "verdict": verdict,
        "level": level,
        "headline": headline,
        "reason": reason,
        "effect": describe(effect) if effect in NAMES else None,
        "parameters": effect_parameter_text(effect, doc.get("effect_parameters") or {}) if effect else "",
        "collapses_on": where,
        "collapse_eta2": (axes.get(where) or {}).get("eta2") if where else None,
    }


def discrepancy_view(folder, progress=None, cache_only: bool = False, workers=None, system=None):
    """The diagnosis of the campaign in ``folder`` for the page, cached.

    Returns {"key", "campaign" (see :func:`campaign_summary`), "diagnosis" (see
    :func:`diagnosis_document`), "summary"} or, with ``cache_only``, None on a miss.
    ``progress(fraction, text)`` is passed to the diagnosis. Raises InputError for a
    campaign that cannot be diagnosed.
    """
    key = discrepancy_key(folder, system)
    hit = load_view(key)
    if hit is not None or cache_only:
        return hit
    from dampersim.discrepancy.campaign import read_campaign
    from dampersim.discrepancy.diagnose import diagnose  # the diagnosis code only once it has to run

    t0 = time.perf_counter()
    camp = read_campaign(folder)
    summary = summarise_campaign(camp)  # the campaign just read, not a second reading
    diag = diagnose(camp, system, workers=workers, progress=progress, **DISCREPANCY_OPTIONS)
    doc = diagnosis_document(diag)
    view = {
        "kind": "discrepancy",
        "campaign": summary,
        "diagnosis": doc,
        "summary": {"compute_time_s": time.perf_counter() - t0, "simulations": diag.simulations},
    }
    return _save_view(key, view)


__all__ = [
    "PAGES",
    "PAGE_PATHS",
    "Field",
    "KEY_PARAMETERS",
    "notice",
    "parse_query",
    "to_query",
    "page_href",
    "default_state",
    "state_from_controls",
    "parse_parameters",
    "resolve_system",
    "apply_overrides",
    "parameter_value",
    "parse_orders_deg",
    "format_orders",
    "view_key",
    "load_view",
    "explorer_view",
    "colourmap_view",
    "colourmap_status",
    "maps_view",
    "maps_status",
    "hysteresis_view",
    "segments_view",
    "damper_animation_figure",
    "parameters_view",
    "params_for_system",
    "parse_uploaded_parameters",
    "parameters_toml",
    "apply_table_edits",
    "SweepRegistry",
    "running_sweeps",
    "example_campaigns",
    "unpack_campaign_zip",
    "upload_folder",
    "parse_discrepancy_query",
    "discrepancy_query",
    "campaign_summary",
    "summarise_campaign",
    "discrepancy_key",
    "discrepancy_view",
    "diagnosis_document",
    "diagnosis_from_document",
    "discrepancy_figures",
    "ranking_rows",
    "verdict_summary",
]
