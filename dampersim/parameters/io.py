"""Parameter sets to and from plain dicts, TOML files and dotted ``--set`` overrides.

Unknown keys are errors that suggest the closest valid names; values are converted to
the field's kind (float, int, bool, str) and then checked by
:func:`dampersim.parameters.validation.validate`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib

import tomli_w

from dampersim.errors import ParameterError
from dampersim.parameters import model as m
from dampersim.parameters.validation import check_rig_size, validate
from dampersim.fileio import write_text_atomic

#: Largest parameter file read [characters]: a complete set with a rig of the largest
#: accepted size (64 elements) is about 12 kB of TOML; files from the dashboard are
#: limited to 256 kB before they get here.
MAX_TOML_CHARS = 1 * 2**20

# dataclass type of each nested field that holds a dataclass
_NESTED = {
    (m.DamperSystem, "inertias"): m.Inertias,
    (m.DamperSystem, "outer"): m.SpringSet,
    (m.DamperSystem, "inner"): m.SpringSet,
    (m.DamperSystem, "friction"): m.Friction,
    (m.DamperSystem, "hardstops"): m.Hardstops,
    (m.DamperSystem, "rig"): m.Rig,
    (m.DamperSystem, "motor"): m.OutputMotor,
    (m.DamperSystem, "solver"): m.Solver,
    (m.SpringSet, "spring"): m.ArcSpring,
    (m.SpringSet, "nested"): m.ArcSpring,
    (m.Friction, "outer"): m.SpringFriction,
    (m.Friction, "pair_outer"): m.SpringFriction,
    (m.Friction, "pair_inner"): m.SpringFriction,
    (m.DamperSystem, "effects"): m.Effects,
    (m.Effects, "clutch_slip"): m.ClutchSlip,
    (m.Effects, "output_backlash"): m.OutputBacklash,
    (m.Effects, "inner_short_springs"): m.InnerShortSprings,
    (m.Effects, "turbine_drag"): m.TurbineDrag,
    (m.Effects, "pendulum_absorber"): m.PendulumAbsorber,
    (m.Effects, "nested_radial_transfer"): m.NestedRadialTransfer,
    (m.Effects, "spring_preload"): m.SpringPreload,
    (m.Effects, "transducer_bandwidth"): m.TransducerBandwidth,
}


def to_dict(obj) -> dict:
    """Nested plain dict of a parameter dataclass (rig elements as a list of tables)."""
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if v is None:
            continue
        if dataclasses.is_dataclass(v):
            out[f.name] = to_dict(v)
        elif isinstance(v, tuple):
            out[f.name] = [to_dict(e) for e in v]
        else:
            out[f.name] = v
    return out


def _suggest(name, options):
    close = difflib.get_close_matches(name, list(options), n=3, cutoff=0.5)
    return f"did you mean {', '.join(close)}?" if close else f"valid names: {', '.join(sorted(options))}"


def _convert(path, raw, kind):
    """Convert ``raw`` (from TOML or a command-line string) to ``kind``."""
    if kind is bool:
        if isinstance(raw, bool):
            return raw
        if isinstance(raw, str) and raw.strip().lower() in ("true", "1", "yes", "on"):
            return True
        if isinstance(raw, str) and raw.strip().lower() in ("false", "0", "no", "off"):
            return False
        raise ParameterError(path, raw, "true or false")
    if kind is int:
        if isinstance(raw, bool):
            raise ParameterError(path, raw, "a whole number")
        try:
            val = float(raw)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(path, raw, "a whole number") from None
        if not math.isfinite(val) or val != int(val):
            raise ParameterError(path, raw, "a whole number")
        return int(val)
    if kind is float:
        if isinstance(raw, bool):
            raise ParameterError(path, raw, "a number")
        try:
            val = float(raw)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(path, raw, "a number") from None
        return val
    if kind is str:
        if not isinstance(raw, str):
            raise ParameterError(path, raw, "a text string")
        return raw
    raise TypeError(kind)


def _field_kind(f):
    kind = f.metadata.get("kind")
    if kind is not None:
        return kind
    return str


def from_dict(cls, data: dict, path: str = ""):
    """Build dataclass ``cls`` from ``data``; unknown keys and wrong kinds raise ParameterError."""
    if not isinstance(data, dict):
        raise ParameterError(path or cls.__name__, data, "a table of named values")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in data:
        if key not in fields:
            full = f"{path}.{key}" if path else key
            raise ParameterError(full, data[key], "a known parameter name", _suggest(key, fields))
    kwargs = {}
    for name, f in fields.items():
        if name not in data:
            continue
        full = f"{path}.{name}" if path else name
        raw = data[name]
        sub = _NESTED.get((cls, name))
        if sub is not None:
            kwargs[name] = from_dict(sub, raw, full)
        elif cls is m.Rig and name == "elements":
            if not isinstance(raw, list):
                raise ParameterError(full, raw, "a list of rig element tables")
            check_rig_size(len(raw), full)  # counted before a single element is built
            kwargs[name] = tuple(from_dict(m.RigElement, e, f"{full}[{i}]") for i, e in enumerate(raw))
        else:
            kwargs[name] = _convert(full, raw, _field_kind(f))
    try:
        return cls(**kwargs)
    except TypeError as exc:  # a required field is missing
        raise ParameterError(path or cls.__name__, sorted(data), "all required fields", str(exc)) from None


def system_from_dict(data: dict) -> m.DamperSystem:
    """A validated :class:`DamperSystem` from a nested dict (e.g. parsed TOML)."""
    system = from_dict(m.DamperSystem, data)
    validate(system)
    return system


def dumps_toml(system: m.DamperSystem) -> str:
    """TOML text of a parameter set; floats are written with round-trip precision."""
    header = (
        f"# dampersim parameter set '{system.name}'. SI units: kg, m, rad, s, N m.\n"
        "# Load with dampersim.load_parameters(path) or --params FILE.\n"
    )
    return header + tomli_w.dumps(to_dict(system))


def loads_toml(text: str) -> m.DamperSystem:
    """Parse and validate a parameter set from TOML text (at most :data:`MAX_TOML_CHARS`
    characters). Every refusal is a ParameterError naming the field, the value and what is
    accepted."""
    if not isinstance(text, str):
        raise ParameterError("file", type(text).__name__, "TOML text")
    if len(text) > MAX_TOML_CHARS:
        raise ParameterError("file", f"{len(text)} characters", f"a parameter file of at most {MAX_TOML_CHARS} characters")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("file", "(TOML text)", "valid TOML", str(exc)) from None
    except RecursionError:
        raise ParameterError("file", "(TOML text)", "valid TOML", "arrays or tables nested too deeply") from None
    return system_from_dict(data)


def save_toml(system: m.DamperSystem, path) -> None:
    """Write ``system`` to ``path`` atomically (temporary file + rename)."""

    write_text_atomic(path, dumps_toml(system))


def load_toml(path) -> m.DamperSystem:
    """Read and validate a parameter set from a TOML file."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read(MAX_TOML_CHARS + 1)
    except OSError as exc:
        raise ParameterError("file", str(path), "a readable TOML file", exc.strerror or str(exc)) from None
    except UnicodeDecodeError:
        raise ParameterError("file", str(path), "a UTF-8 text file") from None
    return loads_toml(text)


def flat_values(system: m.DamperSystem) -> dict:
    """{dotted name: value} of every scalar in ``system``'s dict form (rig elements stay
    one list-valued entry, ``rig.elements``)."""
    flat = {}

    def walk(d, pre):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, f"{pre}{k}.")
            else:
                flat[f"{pre}{k}"] = v

    walk(to_dict(system), "")
    return flat


def named_values(system: m.DamperSystem) -> dict:
    """{dotted name: value} of every settable field of ``system`` (numbers, and the rig
    elements' names), the names :func:`with_updates` accepts (rig elements addressed by their name, e.g.
    ``rig.elements.gearbox.inertia``; unlike :func:`flat_values`)."""
    values = {}

    def walk(obj, prefix):
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            p = f"{prefix}{f.name}"
            if v is None:
                continue
            if dataclasses.is_dataclass(v):
                walk(v, p + ".")
            elif isinstance(v, tuple):
                for e in v:
                    walk(e, f"{p}.{e.name}.")
            else:
                values[p] = v

    walk(system, "")
    return values


def dotted_names(system: m.DamperSystem) -> list[str]:
    """Every settable dotted name of ``system`` (rig elements addressed by their name)."""
    return list(named_values(system))


def _replace_path(obj, parts, raw, full):
    fields = {f.name: f for f in dataclasses.fields(obj)}
    head = parts[0]
    if head not in fields:
        raise ParameterError(full, raw, "a known parameter name", _suggest(head, fields))
    current = getattr(obj, head)
    if len(parts) == 1:
        if dataclasses.is_dataclass(current) or isinstance(current, tuple):
            raise ParameterError(full, raw, "a single value, not a whole group", "name one of its fields")
        return dataclasses.replace(obj, **{head: _convert(full, raw, _field_kind(fields[head]))})
    if isinstance(current, tuple):  # rig elements, addressed by name
        names = [e.name for e in current]
        if parts[1] not in names:
            raise ParameterError(full, raw, "a rig element name", _suggest(parts[1], names))
        if len(parts) < 3:
            raise ParameterError(full, raw, "a rig element field", "e.g. rig.elements.gearbox.inertia")
        idx = names.index(parts[1])
        new = _replace_path(current[idx], parts[2:], raw, full)
        return dataclasses.replace(obj, **{head: current[:idx] + (new,) + current[idx + 1:]})
    if current is None:
        sub = _NESTED.get((type(obj), head))
        if sub is None:
            raise ParameterError(full, raw, "a known parameter name")
        raise ParameterError(full, raw, f"a value inside an existing group; {head} is not set in this parameter set")
    if not dataclasses.is_dataclass(current):
        raise ParameterError(full, raw, "a known parameter name", f"{head} has no sub-fields")
    return dataclasses.replace(obj, **{head: _replace_path(current, parts[1:], raw, full)})


def with_updates(system: m.DamperSystem, updates: dict, check: bool = True) -> m.DamperSystem:
    """Return ``system`` with dotted-name overrides applied, e.g. ``{"friction.outer.alpha": 0}``."""
    for name, raw in updates.items():
        system = _replace_path(system, name.split("."), raw, name)
    if check:
        validate(system)
    return system


def parse_set_options(items) -> dict:
    """``["a.b=1", ...]`` -> ``{"a.b": "1"}``; malformed items raise ParameterError."""
    out = {}
    for item in items or ():
        if "=" not in item:
            raise ParameterError("--set", item, "NAME=VALUE with a dotted name, e.g. friction.outer.alpha=0")
        name, value = item.split("=", 1)
        out[name.strip()] = value.strip()
    return out


__all__ = [
    "to_dict",
    "from_dict",
    "system_from_dict",
    "dumps_toml",
    "loads_toml",
    "save_toml",
    "load_toml",
    "dotted_names",
    "flat_values",
    "named_values",
    "with_updates",
    "parse_set_options",
]
