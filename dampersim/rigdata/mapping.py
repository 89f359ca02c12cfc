"""Channel mapping: which channel of a rig file feeds which campaign column, from a map file or by name and unit.

A rig file's channels are anything with ``.name``, ``.unit``, ``.group``, ``.samples`` and
``.rate_hz`` [Hz] (the readers' ``ChannelInfo``). The campaign columns (targets) are
``input_torque_nm``, ``output_torque_nm``, ``input_speed_rpm``, ``output_speed_rpm``
(required) and ``input_flange_deg``, ``output_flange_deg``, ``windup_deg`` (optional; ramps
need windup or both flange angles).

Map file (TOML), one table per target, every key but ``name`` optional::

    [channels.input_torque_nm]
    name = "Trq_In"     # the channel's name in the file
    unit = "kN m"       # overrides the file's unit (units: see dampersim.rigdata.units)
    gain = 1.0          # calibration factor, applied after the unit conversion
    offset = 0.0        # added after the gain, in the target's unit (N m, rpm, deg)

Without a map entry a target is matched by name and unit (:func:`resolve`). A channel
name is normalised first: camelCase is split ("TorqueIn" -> "torque_in"), case folded,
every run of other characters becomes "_" ("Torque Input" -> "torque_input"). Then:

* **by name**: the normalised name is ``<quantity word>_<side>`` or ``<side>_<quantity
  word>``, optionally followed by a unit suffix (``_nm``, ``_rpm``, ``_deg`` ...), and the
  channel's unit is one of the target's quantity (a torque-like name with a speed unit
  is not a torque);
* **by name and unit (guessed)**, only when no channel matches by name: the quantity is a
  one-letter symbol (``T_in``, ``n_out``, ``w_in``, ``M_ein``, ``phi_ab``), which stands for
  many things and is taken on the strength of the unit; or the name carries a side word
  and no quantity word (``Kanal3_ein``) and the unit decides the quantity.

Quantity words and sides (:data:`WORDS`, :data:`SYMBOLS`, :data:`SIDES`):

=================  ==========================================================  ===========
target quantity    words (by name)                                             symbols
=================  ==========================================================  ===========
torque             torque, trq, tq, moment, drehmoment, md                     t, m
speed              speed, spd, rpm, drehzahl, omega                            n, w
angle (flanges)    angle, ang, flange, flange_angle, winkel, drehwinkel        phi, theta
windup (no side)   windup, wind_up, windup_angle, twist, twist_angle, verdrehwinkel, verdrehung,
                   rel_angle, relative_angle, delta_phi, dphi, torsion_angle
input side         in, input, inp, ein, eingang, an, antrieb, prim, primary, drive
output side        out, output, outp, aus, ausgang, ab, abtrieb, sec, secondary
=================  ==========================================================  ===========

Two candidates for one target at the best level raise InputError listing them (write a map
to choose); a required target without candidates raises InputError listing the file's
channels.
"""

from __future__ import annotations

import os
import re
import tomllib
from dataclasses import dataclass, field

from dampersim.errors import InputError
from dampersim.rigdata.units import (
    UNITS,
    accepted_units,
    check_calibration,
    convert,
    quantity_of,
    target_quantity,
    unit_factor,
)

#: Campaign columns every import needs, and those only ramps use.
REQUIRED = ("input_torque_nm", "output_torque_nm", "input_speed_rpm", "output_speed_rpm")
OPTIONAL = ("input_flange_deg", "output_flange_deg", "windup_deg")
MAP_KEYS = ("name", "unit", "gain", "offset")

#: Quantity words that identify a channel by name (tier "by name"), by target quantity.
WORDS = {
    "torque": ("torque", "trq", "tq", "moment", "drehmoment", "md"),
    "speed": ("speed", "spd", "rpm", "drehzahl", "omega"),
    "angle": ("angle", "ang", "flange", "flange_angle", "winkel", "drehwinkel"),
}
#: One-letter (or Greek) symbols: a match is a guess the unit confirms.
SYMBOLS = {"torque": ("t", "m"), "speed": ("n", "w"), "angle": ("phi", "theta")}
#: Whole names of the windup channel (input flange minus output angle): no side word.
WINDUP_NAMES = ("windup", "wind_up", "windup_angle", "twist", "twist_angle", "verdrehwinkel", "verdrehung", "rel_angle",
                "relative_angle", "delta_phi", "dphi", "torsion_angle")
SIDES = {
    "input": ("in", "input", "inp", "ein", "eingang", "an", "antrieb", "prim", "primary", "drive"),
    "output": ("out", "output", "outp", "aus", "ausgang", "ab", "abtrieb", "sec", "secondary"),
}
#: Unit suffixes a channel name may end in ("Trq_In_Nm").
UNIT_SUFFIXES = ("nm", "knm", "rpm", "deg", "rad", "rad_s", "rads", "hz", "1_min", "u_min")
#: target -> (quantity, side); windup has no side.
_TARGET_SIDE = {
    "input_torque_nm": ("torque", "input"), "output_torque_nm": ("torque", "output"),
    "input_speed_rpm": ("speed", "input"), "output_speed_rpm": ("speed", "output"),
    "input_flange_deg": ("angle", "input"), "output_flange_deg": ("angle", "output"),
    "windup_deg": ("angle", None),
}
BY_MAP = "from map"
BY_NAME = "by name"
BY_GUESS = "by name and unit (guessed)"


def _alt(words) -> str:
    return "|".join(re.escape(w) for w in sorted(words, key=len, reverse=True))


def _pattern(quantity_words, side_words) -> re.Pattern:
    q, s, u = _alt(quantity_words), _alt(side_words), _alt(UNIT_SUFFIXES)
    return re.compile(rf"^(?:(?:{q})_(?:{s})|(?:{s})_(?:{q}))(?:_(?:{u}))?$")


_NAME_PATTERNS = {}
_GUESS_PATTERNS = {}
for _target, (_q, _side) in _TARGET_SIDE.items():
    if _side is None:
        _NAME_PATTERNS[_target] = re.compile(rf"^(?:{_alt(WINDUP_NAMES)})(?:_(?:{_alt(UNIT_SUFFIXES)}))?$")
        continue
    _NAME_PATTERNS[_target] = _pattern(WORDS[_q], SIDES[_side])
    _GUESS_PATTERNS[_target] = _pattern(SYMBOLS[_q], SIDES[_side])
_ALL_QUANTITY_TOKENS = {t for words in (*WORDS.values(), *SYMBOLS.values(), WINDUP_NAMES) for w in words
                        for t in w.split("_")}


def normalise_name(name) -> str:
    """A channel name as the patterns see it: camelCase split, case folded, every run of
    characters other than letters and digits turned into one "_" ("TorqueIn" ->
    "torque_in", "Drehzahl Ein" -> "drehzahl_ein", "RPMOut" -> "rpm_out")."""
    text = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", str(name))
    text = re.sub(r"(?<=[A-Z])(?=[A-Z][a-z])", "_", text)
    return re.sub(r"[\W_]+", "_", text.casefold()).strip("_")


@dataclass(frozen=True)
class ChannelSpec:
    """How one campaign column is read: the channel ``name``, the ``unit`` its values are
    in (the map's override or the file's), then ``gain`` [-] and ``offset`` [target's unit]
    applied after the unit conversion."""

    name: str
    unit: str
    gain: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class MapEntry:
    """One ``[channels.<target>]`` table of a map file; ``unit`` None keeps the file's."""

    name: str
    unit: str | None = None
    gain: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class ChannelMap:
    """A map file's entries by target and where they came from (``source``, for messages)."""

    entries: dict
    source: str = "map"

    @classmethod
    def from_dict(cls, data, source: str = "map") -> "ChannelMap":
        """Check and build a map from parsed TOML (``{"channels": {target: {...}}}``)."""
        where = f"{source}: "
        if not isinstance(data, dict):
            raise InputError(f"{where}accepted is a TOML document with [channels.<target>] tables")
        for key in data:
            if key != "channels":
                raise InputError(f"{where}[{key}]: unknown table or key; accepted is [channels.<target>] with target "
                                 f"one of {', '.join(REQUIRED + OPTIONAL)}")
        channels = data.get("channels", {})
        if not isinstance(channels, dict):
            raise InputError(f"{where}channels = {channels!r}: accepted is a table of [channels.<target>] tables")
        entries = {}
        for target, table in channels.items():
            if target not in REQUIRED + OPTIONAL:
                raise InputError(f"{where}[channels.{target}]: unknown target; accepted targets are "
                                 f"{', '.join(REQUIRED + OPTIONAL)}")
            if not isinstance(table, dict):
                raise InputError(f"{where}channels.{target} = {table!r}: accepted is a table with keys "
                                 f"{', '.join(MAP_KEYS)}")
            for key in table:
                if key not in MAP_KEYS:
                    raise InputError(f"{where}channels.{target}.{key}: unknown key; accepted keys are "
                                     f"{', '.join(MAP_KEYS)} (name required)")
            name = table.get("name")
            if not isinstance(name, str) or not name.strip():
                raise InputError(f"{where}channels.{target}.name = {name!r}: accepted is the channel's name in the "
                                 "rig file, as text")
            unit = table.get("unit")
            if unit is not None:
                quantity = target_quantity(target)
                if not isinstance(unit, str) or quantity_of(unit) != quantity:
                    raise InputError(f"{where}channels.{target}.unit = {unit!r}: accepted {quantity} units are "
                                     f"{accepted_units(quantity)}")
            gain, offset = check_calibration(table.get("gain", 1.0), table.get("offset", 0.0),
                                             f"{where}channels.{target}.")
            entries[target] = MapEntry(name=name.strip(), unit=unit, gain=gain, offset=offset)
        return cls(entries=entries, source=source)


def _duplicate_tables(text: str, source: str) -> None:
    """InputError for a ``[channels.<target>]`` header given twice (clearer than TOML's)."""
    seen = {}
    header = re.compile(r"^\s*\[\s*channels\s*\.\s*(\"?)([^\]\"]+?)\1\s*\]\s*(?:#.*)?$")
    for number, line in enumerate(text.splitlines(), start=1):
        m = header.match(line)
        if not m:
            continue
        target = m.group(2).strip()
        if target in seen:
            raise InputError(f"{source}: [channels.{target}] appears twice (lines {seen[target]} and {number}); "
                             "accepted is each target once")
        seen[target] = number


def load_map(path) -> ChannelMap:
    """Read and check a TOML map file (format: module docstring).

    Raises InputError naming the file, the field, its value and what is accepted for: an
    unreadable file, invalid TOML, a table or key other than ``[channels.<target>]`` with
    ``name``/``unit``/``gain``/``offset``, a target given twice, a unit not of the target's
    quantity, a gain that is not a finite non-zero number, an offset that is not finite.
    """
    source = os.fspath(path)
    try:
        with open(source, "rb") as fh:
            raw = fh.read()
        text = raw.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: cannot read the map file ({exc}); accepted is a UTF-8 TOML file") from None
    _duplicate_tables(text, source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not valid TOML ({exc})") from None
    return ChannelMap.from_dict(data, source=source)


@dataclass(frozen=True)
class Resolution:
    """The outcome of :func:`resolve`.

    ``specs``: target -> :class:`ChannelSpec`; ``report``: one line per target saying what
    was matched and how ("from map", "by name", "by name and unit (guessed)", or not
    found); ``channels``: target -> the matched channel object (its ``rate_hz`` and
    ``group`` for the resampling)."""

    specs: dict
    report: list
    channels: dict = field(default_factory=dict)


def _describe(ch) -> str:
    unit = getattr(ch, "unit", "") or "no unit"
    rate = getattr(ch, "rate_hz", None)
    rate_text = f", {float(rate):g} Hz" if rate else ""
    return f"{ch.name!r} [{unit}] (group {getattr(ch, 'group', '')!r}{rate_text})"


def _channel_list(channels) -> str:
    return "; ".join(_describe(ch) for ch in channels) or "(none)"


def _from_map(target, entry: MapEntry, channels, source):
    hits = [ch for ch in channels if ch.name == entry.name]
    if not hits:
        hits = [ch for ch in channels if str(ch.name).casefold() == entry.name.casefold()]
    if not hits:
        raise InputError(f"{source}: channels.{target}.name = {entry.name!r}: no such channel in the file; its "
                         f"channels are {_channel_list(channels)}")
    if len(hits) > 1:
        raise InputError(f"{source}: channels.{target}.name = {entry.name!r}: the file has {len(hits)} channels of "
                         f"that name: {_channel_list(hits)}; accepted is a name that occurs once")
    ch = hits[0]
    unit = entry.unit if entry.unit is not None else (ch.unit or "")
    unit_factor(unit, target, ch.name)
    return ch, ChannelSpec(name=ch.name, unit=unit, gain=entry.gain, offset=entry.offset)


def _tier(target, ch) -> str | None:
    """How ``ch`` can match ``target`` by itself (BY_NAME, BY_GUESS) or None. The unit must
    be of the target's quantity."""
    quantity, side = _TARGET_SIDE[target]
    if quantity_of(getattr(ch, "unit", "")) != quantity:
        return None
    name = normalise_name(ch.name)
    if _NAME_PATTERNS[target].match(name):
        return BY_NAME
    if side is None:
        return None
    if _GUESS_PATTERNS[target].match(name):
        return BY_GUESS
    tokens = set(name.split("_"))
    other_side = SIDES["output" if side == "input" else "input"]
    if tokens & set(SIDES[side]) and not tokens & set(other_side) and not tokens & _ALL_QUANTITY_TOKENS:
        return BY_GUESS
    return None


def _near_misses(target, channels) -> list:
    """Channels whose name matches ``target`` but whose unit does not (for messages)."""
    quantity, side = _TARGET_SIDE[target]
    out = []
    for ch in channels:
        name = normalise_name(ch.name)
        if _NAME_PATTERNS[target].match(name) or (side and _GUESS_PATTERNS[target].match(name)):
            if quantity_of(getattr(ch, "unit", "")) != quantity:
                out.append(f"{ch.name!r} matches {target} by name but its unit {getattr(ch, 'unit', '')!r} is not a "
                           f"{quantity} unit (accepted: {accepted_units(quantity)})")
    return out


def _line(target, ch, spec: ChannelSpec, how: str) -> str:
    unit_out = UNITS[target_quantity(target)][0]
    conv = spec.unit or "no unit"
    if spec.unit != ch.unit:
        conv = f"{spec.unit} (file says {ch.unit or 'no unit'})"
    factor = unit_factor(spec.unit, target, ch.name)
    if factor != 1.0:
        conv += f" -> {unit_out} x {factor:.6g}"
    cal = ""
    if spec.gain != 1.0 or spec.offset != 0.0:
        cal = f", gain {spec.gain:g}, offset {spec.offset:g} {unit_out}"
    rate = getattr(ch, "rate_hz", None)
    rate_text = f", {float(rate):g} Hz" if rate else ""
    return f"{target} <- {ch.name!r} (group {getattr(ch, 'group', '')!r}, {conv}{rate_text}{cal}): {how}"


def resolve(channels, channel_map: ChannelMap | None = None) -> Resolution:
    """Match a rig file's channels to the campaign columns.

    Args:
        channels: the file's channels, objects with ``.name``, ``.unit`` (text, see
            :mod:`dampersim.rigdata.units`), ``.group``, ``.samples`` and ``.rate_hz`` [Hz].
        channel_map: a :class:`ChannelMap` (:func:`load_map`); its targets are taken from
            it, the others are matched by name and unit among the channels it leaves.

    Returns:
        :class:`Resolution`: a :class:`ChannelSpec` per matched target, the report lines
        (every target, found or not) and the matched channel objects.

    Raises:
        InputError: a map names a channel the file lacks (or has twice) or one whose unit
            cannot be converted; two candidates for one target (listed; write a map);
            required targets without a channel (named, with the file's channels listed).
    """
    channels = list(channels)
    specs, found, report = {}, {}, []
    used = set()
    entries = channel_map.entries if channel_map is not None else {}
    source = channel_map.source if channel_map is not None else "map"
    for target in REQUIRED + OPTIONAL:
        if target in entries:
            ch, spec = _from_map(target, entries[target], channels, source)
            specs[target], found[target] = spec, ch
            used.add(id(ch))
    free = [ch for ch in channels if id(ch) not in used]
    missing = []
    for target in REQUIRED + OPTIONAL:
        if target in specs:
            continue
        tiers = {}
        for ch in free:
            tier = _tier(target, ch)
            if tier:
                tiers.setdefault(tier, []).append(ch)
        best = next((tiers[t] for t in (BY_NAME, BY_GUESS) if t in tiers), [])
        if len(best) > 1:
            raise InputError(
                f"{target}: {len(best)} channels match {next(t for t in (BY_NAME, BY_GUESS) if t in tiers)}: "
                f"{_channel_list(best)}; write a map file that names the one to use, e.g. "
                f"[channels.{target}] name = {best[0].name!r}"
            )
        if not best:
            if target in REQUIRED:
                missing.append(target)
            continue
        ch = best[0]
        specs[target] = ChannelSpec(name=ch.name, unit=ch.unit or "")
        found[target] = ch
    if missing:
        hints = [h for target in missing for h in _near_misses(target, free)]
        raise InputError(
            f"no channel found for required {', '.join(missing)}; the file's channels are {_channel_list(channels)}"
            + (f"; {'; '.join(hints)}" if hints else "")
            + "; write a map file: [channels.<target>] name = \"...\" (unit = \"...\" if the file's unit is missing "
            "or wrong)"
        )
    names = {}
    for target in REQUIRED + OPTIONAL:
        if target not in specs:
            report.append(f"{target}: not found (optional)")
            continue
        ch = found[target]
        how = BY_MAP if target in entries else (_tier(target, ch) or BY_NAME)
        line = _line(target, ch, specs[target], how)
        if id(ch) in names:
            line += f" (same channel as {names[id(ch)]})"
        names.setdefault(id(ch), target)
        report.append(line)
    return Resolution(specs=specs, report=report, channels=found)


__all__ = ["REQUIRED", "OPTIONAL", "WORDS", "SYMBOLS", "WINDUP_NAMES", "SIDES", "UNIT_SUFFIXES", "BY_MAP", "BY_NAME",
           "BY_GUESS", "ChannelSpec", "MapEntry", "ChannelMap", "Resolution", "normalise_name", "load_map", "resolve",
           "convert"]
