"""Parameter-override policy of the pages: which parameter set a page uses (the default set
or a stored one) and which dotted overrides it accepts, from links, controls, the
parameter table and uploaded TOML files.

Parameter-set changes travel in a page's query string as dotted parameter names with SI
values (``inertias.primary=0.22``, ``outer.hardstop_positive=0.7``): only values that
differ from the base set are written. A parameter file whose structure differs from the
default set (other rig elements, ...) is stored on the server and referenced by
``set=<id>`` (see :func:`dampersim.views.store.store_parameter_set`). Each override is
validated on its own and with the ones before it; a refused one gives a notice naming
the parameter, the value, what is accepted and the value used instead.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from dampersim.uploads import decode_upload
from dampersim.errors import DampersimError, InputError, ParameterError
from dampersim.parameters import default_parameters, dotted_names, dumps_toml, loads_toml, with_updates
from dampersim.parameters.validation import describe_range
from dampersim.units import number_text
from dampersim.solver.linear import time_step_note
from dampersim.units import rad_to_deg
from dampersim.units import parse_number
from dampersim.views.notices import notice, query_value
from dampersim.views.store import LABEL_NAMES, load_parameter_set, store_parameter_set, valid_set_id

#: Largest uploaded parameter file [bytes].
MAX_UPLOAD_BYTES = 256 * 1024


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
    # every solver setting a link can reach has a range: together with the cost budget
    # (dampersim.costs) they keep one link from asking for hours of computing or
    # gigabytes of arrays. Time step [s]: the default 1/120 000 s sits in the middle; a
    # finer step than 1e-7 s is a numerical study, not a dashboard view.
    "solver.time_step": (1e-7, 1e-4),
    # sample rates [Hz]: the pages analyse up to 1 kHz (2 kHz is the least that holds it);
    # the segment record feeds the 1 kHz animation and heatmap
    "solver.output_sample_rate": (2000.0, 50000.0),
    "solver.segment_sample_rate": (10.0, 10000.0),
    "solver.outer_segments": (4, 64),
    "solver.inner_segments": (4, 64),
    "solver.duration": (0.5, 20.0),
}
#: Most parameter sets (with their overrides) kept validated in this process.
RESOLVED_CACHE_SIZE = 64

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

def base_system(set_id=None):
    """The base parameter set: the default set, or a stored set ``set_id``.

    A stored set is validated once per process and text (validation includes an
    eigen-solve, and every page load naming the set would repeat it): see
    :data:`RESOLVED_CACHE_SIZE`."""
    if set_id is None:
        return default_parameters()
    text = load_parameter_set(set_id)
    if text is None:
        raise InputError(f"parameter set {set_id!r} is not stored on this server")
    return _system_from_text(text)


@functools.lru_cache(maxsize=RESOLVED_CACHE_SIZE)
def _system_from_text(text: str):
    return loads_toml(text)


def _frozen_items(overrides: dict):
    """Overrides as a hashable key, or None when a value is not a plain number/text/bool."""
    items = []
    for k, v in overrides.items():
        if not isinstance(k, str) or not isinstance(v, (str, int, float, bool)) or v is None:
            return None
        items.append((k, type(v).__name__, v))
    return tuple(items)


@functools.lru_cache(maxsize=RESOLVED_CACHE_SIZE)
def _resolved(base, items: tuple, source: str):
    """(system, accepted overrides, notices) of ``items`` on ``base``, remembered: the
    same set and overrides are validated once per process."""
    notices: list = []
    system, accepted = apply_overrides(base, {k: v for k, _, v in items}, notices, source)
    return system, accepted, tuple(n["text"] for n in notices), tuple(n["level"] for n in notices)


def resolve_overrides(base, overrides: dict, notices: list | None = None, source: str = "link"):
    """:func:`apply_overrides` through the in-process cache of validated sets (same
    result and notices). A value that is not a plain number, text or boolean (possible
    only in data posted by a browser, never in a link) is refused with a notice."""
    items = _frozen_items(overrides)
    if items is None:
        plain = {}
        for k, v in overrides.items():
            if isinstance(k, str) and isinstance(v, (str, int, float, bool)):
                plain[k] = v
            elif notices is not None:
                notices.append(notice(f"Parameter {str(k)[:60]!r} = {type(v).__name__} from the {source} is not "
                                      f"accepted: accepted is a number, text or true/false. Using the set's value."))
        items = _frozen_items(plain)
    try:
        system, accepted, texts, levels = _resolved(base, items, source)
    except TypeError:  # an unhashable value inside the set: validate without the cache
        return apply_overrides(base, overrides, notices, source)
    if notices is not None:
        notices.extend(notice(t, lv) for t, lv in zip(texts, levels))
    return system, dict(accepted)


def _override_value(system, name):
    v = parameter_value(system, name)
    return v.item() if isinstance(v, np.generic) else v


def apply_overrides(base, overrides: dict, notices: list | None = None, source: str = "link"):
    """Apply dotted overrides one by one to ``base``; refused ones get a notice.

    Returns (system, accepted overrides {name: typed value}). Overrides equal to the base
    value are dropped. Each accepted one is validated together with the ones before it,
    time-step stability bound included (it depends on several parameters).
    """
    names = set(dotted_names(base))
    system = base
    accepted = {}
    for name, raw in overrides.items():
        if name not in names or name in LABEL_NAMES:
            continue
        old = _override_value(system, name)
        try:
            if name in PARAMETER_RANGES and not isinstance(old, (bool, str)):
                lo, hi = PARAMETER_RANGES[name]
                v = parse_number(raw)
                if not (lo <= v <= hi):
                    raise ParameterError(name, raw, f"a value from {number_text(lo)} to {number_text(hi)} on this dashboard")
            system = with_updates(system, {name: raw})
            note = time_step_note(system)  # refuses an unstable step (ParameterError)
            if note and name == "solver.time_step" and notices is not None:
                # a stable step above the accuracy-tested default runs, and the page says so
                notices.append(notice(f"Parameter {name} from the {source}: {note}"))
        except ParameterError as exc:
            if notices is not None:
                shown = raw if isinstance(raw, str) else number_text(raw)
                if exc.field == name:
                    reason = f"accepted is {exc.accepted}"
                else:
                    reason = f"with it {exc.field} = {number_text(exc.value)} would be invalid (accepted is {exc.accepted})"
                notices.append(notice(f"Parameter {name} = {shown!r} from the {source} is not accepted: {reason}. Using {number_text(old)}."))
            continue
        except ValueError as exc:
            if notices is not None:
                notices.append(notice(f"Parameter {name} = {raw!r} from the {source} {exc}. Using {number_text(old)}."))
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
        raw = query_value(query, "set", notices, "Parameter set")
        if raw not in (None, ""):
            if not valid_set_id(raw):
                notices.append(notice(f"Parameter set set={raw!r} is not a valid set id (16 hex digits); using the default set."))
            elif load_parameter_set(raw) is None:
                notices.append(notice(f"Parameter set {raw!r} is not stored on this server (it was uploaded elsewhere or the cache was cleared); using the default set."))
            else:
                set_id = raw
    base = base_system(set_id)
    raw_overrides = {}
    for k in query:
        if "." in k:
            raw_overrides[k] = query_value(query, k, notices, f"Parameter {k}")
    _, accepted = resolve_overrides(base, raw_overrides, notices)
    return {"set": set_id, "overrides": accepted}


def resolve_system(params: dict | None, notices: list | None = None):
    """The :class:`DamperSystem` of a parameter state (see :func:`parse_parameters`)."""
    params = params if isinstance(params, dict) else {}
    set_id = params.get("set")
    try:
        if set_id is not None and not valid_set_id(set_id):
            raise InputError(f"parameter set {str(set_id)[:40]!r} is not a valid set id (16 hex digits)")
        base = base_system(set_id)
    except DampersimError as exc:
        if notices is not None:
            notices.append(notice(f"{exc}; using the default set."))
        base = default_parameters()
    overrides = params.get("overrides")
    system, _ = resolve_overrides(base, dict(overrides) if isinstance(overrides, dict) else {}, notices)
    return system


def parameter_query_items(params: dict | None) -> list:
    """[(key, text)] of a parameter state, for query strings."""
    params = params or {}
    items = []
    if params.get("set"):
        items.append(("set", params["set"]))
    for name in sorted(params.get("overrides") or {}):
        items.append((name, number_text(params["overrides"][name])))
    return items


# =============================================================================== page state


def parameters_view(system, base=None) -> list:
    """Rows {name, value, unit, doc, accepted, changed, kind} of every dotted parameter
    (values as text, SI units); ``changed`` compares with ``base`` (default set)."""
    base = base if base is not None else default_parameters()
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
            "value": number_text(value),
            "unit": meta.get("unit", "") if meta.get("unit") not in (None, "-") else "",
            "doc": meta.get("doc", ""),
            "accepted": describe_range(meta) if kind in (int, float) else ("true or false" if kind is bool else "text"),
            "kind": kind_name,
            "changed": bool(changed),
        })
    return rows


def params_for_system(system) -> dict:
    """Parameter state that reproduces ``system``: overrides of the default set when the
    structure matches it, else a stored set (``{"set": id, "overrides": {}}``)."""
    default = default_parameters()
    if set(dotted_names(system)) == set(dotted_names(default)) and \
            [e.name for e in system.rig.elements] == [e.name for e in default.rig.elements]:
        overrides = {}
        for name in dotted_names(system):
            if name in LABEL_NAMES:
                continue
            v = _override_value(system, name)
            if v != _override_value(default, name):
                overrides[name] = v
        check, accepted = apply_overrides(default, overrides)
        if accepted == overrides:
            return {"set": None, "overrides": overrides}
    return {"set": store_parameter_set(system), "overrides": {}}


def parse_uploaded_parameters(contents, filename: str = "parameters.toml"):
    """A parameter file from a browser upload (``data:...;base64,...``) -> DamperSystem.

    Raises InputError / ParameterError with a message that names the file and what is
    wrong (not base64, too large, not UTF-8 text, not TOML, unknown or invalid values).
    """
    name = filename or "uploaded file"
    data = decode_upload(contents, name, "a TOML parameter file", MAX_UPLOAD_BYTES, lambda n: f"{n / 1024:.0f} kB",
                         size_accepted=f"a TOML parameter file up to {MAX_UPLOAD_BYTES // 1024} kB",
                         base64_accepted=False)
    if not data.strip():
        raise InputError(f"{name} is empty; accepted is a TOML parameter file (download one to see the format)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{name} is not UTF-8 text; accepted is a TOML parameter file") from None
    try:
        system = loads_toml(text)
        time_step_note(system)  # refuses an unstable step; a coarse one is noted by accuracy_notices
        return system
    except ParameterError as exc:
        raise ParameterError(f"{name}: {exc.field}", exc.value, exc.accepted,
                             str(exc).split(" (", 1)[1].rstrip(")") if " (" in str(exc) else "") from None


def accuracy_notices(system) -> list:
    """Notices for a parameter set the page accepted: a time step above the
    accuracy-tested default runs, with a notice that its accuracy is not checked."""
    note = time_step_note(system)
    return [notice(note)] if note else []


def parameters_toml(system) -> str:
    """TOML text of ``system`` for download."""
    return dumps_toml(system)


def apply_table_edits(params: dict | None, rows: list) -> tuple:
    """Edited parameter rows (name, value as text) -> (new params, system) or raise
    ParameterError naming the first refused value. The previous params stay untouched."""
    params = params or {}
    base = base_system(params.get("set"))
    current = resolve_system(params)
    updates = {}
    for r in rows:
        name, text = r.get("name"), r.get("value")
        if name in LABEL_NAMES or name is None:
            continue
        if str(number_text(_override_value(current, name))) != str(text).strip():
            updates[name] = str(text).strip()
    if not updates:
        return params, current
    system = with_updates(current, updates)
    time_step_note(system)  # refuses an unstable step; a coarse one is noted by accuracy_notices
    overrides = dict(params.get("overrides") or {})
    for name in updates:
        overrides[name] = _override_value(system, name)
    _, accepted = apply_overrides(base, overrides)
    return {"set": params.get("set"), "overrides": accepted}, system


def display_value(v, factor: float = 1.0):
    """SI value -> display value rounded to 7 significant digits (None stays None)."""
    if v is None or isinstance(v, (bool, str)):
        return v
    x = float(v) * factor
    if x == 0:
        return 0
    x = float(f"{x:.7g}")
    return int(x) if x.is_integer() else x


def control_params(base_params, names, values, notices):
    """Parameter state from parameter controls on top of the link's parameter state.

    ``values`` are display values (see :data:`KEY_PARAMETERS`); a control
    that still shows the (rounded) current value keeps the exact current value, so a link's
    values survive the round trip through the controls unchanged. Returns (params, system).
    """
    base_params = base_params or {"set": None, "overrides": {}}
    set_id = base_params.get("set")
    base = base_system(set_id if set_id and load_parameter_set(set_id) else None)
    current = resolve_system(base_params)
    overrides = dict(base_params.get("overrides") or {})
    for name, shown in zip(names, values):
        if name not in KEY_PARAMETERS:
            continue
        label, unit, factor = KEY_PARAMETERS[name]
        now = parameter_value(current, name)
        if shown is None or shown == "":
            notices.append(notice(f"{label} is empty; using {display_value(now, factor)}{' ' + unit if unit and unit != '-' else ''}."))
            continue
        if isinstance(now, (bool, str)):
            if shown != now:
                overrides[name] = shown
            continue
        if display_value(now, factor) == display_value(shown):
            continue
        try:
            si = float(shown) / factor
        except (TypeError, ValueError):
            notices.append(notice(f"{label} = {shown!r} is not a number; using {display_value(now, factor)}."))
            continue
        if isinstance(now, int) and not isinstance(now, bool):
            if not float(shown).is_integer():
                notices.append(notice(f"{label} = {shown} is not a whole number; using {now}."))
                continue
            si = int(round(si))
        overrides[name] = si
    system, accepted = apply_overrides(base, overrides, notices, source="controls")
    return {"set": base_params.get("set"), "overrides": accepted}, system


__all__ = [
    "MAX_UPLOAD_BYTES",
    "PARAMETER_RANGES",
    "KEY_PARAMETERS",
    "parameter_value",
    "base_system",
    "apply_overrides",
    "parse_parameters",
    "resolve_system",
    "resolve_overrides",
    "RESOLVED_CACHE_SIZE",
    "parameter_query_items",
    "parameters_view",
    "params_for_system",
    "parse_uploaded_parameters",
    "parameters_toml",
    "accuracy_notices",
    "apply_table_edits",
    "display_value",
    "control_params",
]
