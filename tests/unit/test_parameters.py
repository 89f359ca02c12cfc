"""Parameter sets: TOML round trip, dotted overrides, validation messages, default targets,
and the origin of every default value."""

import math
import re

import pytest

from dampersim import default_parameters
from dampersim.errors import ParameterError
from dampersim.parameters import (
    dotted_names,
    dumps_toml,
    load_toml,
    loads_toml,
    save_toml,
    to_dict,
    validate,
    with_updates,
)
from dampersim.solver.linear import check_time_step


def test_toml_round_trip_is_exact(tmp_path):
    p = default_parameters()
    path = tmp_path / "set.toml"
    save_toml(p, path)
    q = load_toml(path)
    assert q == p  # dataclass equality: every float bit-identical
    assert dumps_toml(q) == dumps_toml(p)


def test_toml_round_trip_after_edits():
    p = with_updates(default_parameters(), {"outer.spring.stiffness": 1 / 3 * 400, "rig.elements.gearbox.inertia": 0.1234567890123})
    assert loads_toml(dumps_toml(p)) == p


def test_every_dotted_name_is_settable():
    p = default_parameters()
    names = dotted_names(p)
    assert "friction.outer.alpha" in names and "rig.elements.transducer.shaft_stiffness" in names
    # setting each numeric field to its own value is accepted and changes nothing
    d = {}
    for n in names:
        obj = p
        for part in n.split("."):
            if isinstance(obj, tuple):
                obj = next(e for e in obj if e.name == part)
            else:
                obj = getattr(obj, part)
        d[n] = obj
    assert with_updates(p, d) == p


def test_unknown_name_suggests_closest():
    with pytest.raises(ParameterError) as e:
        with_updates(default_parameters(), {"friction.outer.alhpa": 0.1})
    assert "friction.outer.alhpa" in str(e.value) and "alpha" in str(e.value)


def test_unknown_toml_key_is_named():
    text = dumps_toml(default_parameters()).replace("[inertias]\n", "[inertias]\nprimery = 0.3\n")
    with pytest.raises(ParameterError) as e:
        loads_toml(text)
    assert "inertias.primery" in str(e.value) and "primary" in str(e.value)


@pytest.mark.parametrize(
    "name, value, fragment",
    [
        ("inertias.primary", 0.0, "> 0"),
        ("outer.spring.stiffness", -1.0, "> 0"),
        ("solver.outer_segments", 3, "[4, 200]"),
        ("solver.inner_segments", 2.5, "whole number"),
        ("outer.hardstop_negative", 0.2, "[-3.14159, 0]"),
        ("inner.hardstop_positive", -0.1, "(0, 3.14159]"),
        ("outer.spring.arc", 2.2, "shorter than the stopper pitch"),
        ("friction.alpha_ter", 0.7, "1 - alpha_sec"),
        ("motor.mode", "fast", "'pi' or 'held'"),
        ("hardstops.enabled", "maybe", "true or false"),
    ],
)
def test_impossible_values_name_field_value_and_range(name, value, fragment):
    with pytest.raises(ParameterError) as e:
        with_updates(default_parameters(), {name: value})
    msg = str(e.value)
    assert msg.startswith(name) and fragment in msg


def test_unstable_time_step_names_field_value_and_bound():
    # the bound depends on the discretisation, so the solver checks it after validation
    name, value, fragment = "solver.time_step", 1e-4, "stability bound"
    with pytest.raises(ParameterError) as e:
        check_time_step(with_updates(default_parameters(), {name: value}))
    msg = str(e.value)
    assert msg.startswith(name) and fragment in msg


def test_stable_step_above_the_tested_default_warns_and_runs():
    # allowed (below the stability bound) but outside the accuracy grid: a warning that
    # names the field, the bound and the tested step; the default itself is silent
    import warnings

    from dampersim.errors import AccuracyWarning
    from dampersim.solver.linear import accuracy_tested_time_step

    tested = accuracy_tested_time_step()
    assert tested == default_parameters().solver.time_step
    coarse = with_updates(default_parameters(), {"solver.time_step": 2 * tested})
    with pytest.warns(AccuracyWarning, match=r"solver.time_step = .* largest step whose accuracy is checked"):
        assert check_time_step(coarse) is coarse
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_time_step(default_parameters())


def test_validate_returns_valid_set():
    p = default_parameters()
    assert validate(p) is p


def test_default_set_qualitative_targets():
    """docs/model.md §10: positive knee near 300 N m, inner knee above the 500 N m test range,
    negative knees much smaller in magnitude."""
    p = default_parameters()
    k_o = p.outer.count * p.outer.spring.stiffness
    k_i = p.inner.count * (p.inner.spring.stiffness + p.inner.nested.stiffness)
    knee = k_o * p.outer.hardstop_positive
    assert 280 < knee < 320
    assert k_i * p.inner.hardstop_positive > 500
    assert abs(k_o * p.outer.hardstop_negative) < 0.5 * knee
    assert to_dict(p)["outer"]["count"] == 3 and to_dict(p)["inner"]["count"] == 5
    assert math.isclose(sum((p.friction.alpha_sec, p.friction.alpha_ter)), 1.0)


# --------------------------------------------------------------------------- origins
# Every value of a default set says where it comes from (ORIGINS, by dotted name):
# "[thesis] §5.4: ...", "[thesis] Table 9.2: ...", "estimate: <reasoning>" or
# "model: <choice>, docs/model.md §N". The thesis has chapters 1-8 and an appendix
# (Tables 9.1 and 9.2); docs/model.md sections are checked by test_citations.py.
THESIS_REF = r"\[thesis\] (§[1-8](\.\d+){0,2}|Eq\. \d+|Table 9\.[12]|Fig\. [1-8]\.\d+|chapter [1-8])\b"
ORIGIN_FORM = re.compile(rf"({THESIS_REF}|estimate: \S.{{19,}}|model: .*docs/model\.md §\d+)")
SECTION_MARK = re.compile(r"(\[thesis\] |docs/model\.md )?§(\S*)")


def _origin_tables():
    from dampersim.parameters import engine
    from dampersim.parameters.sets import turbine_damper_2017

    tables = [
        ("turbine-damper-2017", default_parameters(), turbine_damper_2017.ORIGINS),
        ("pulsation-generator", engine.default_pulsation_generator(), engine.ORIGINS),
        ("fired-engine", engine.FiredEngine(), engine.FIRED_ORIGINS),
    ]
    return [pytest.param(*t, id=t[0]) for t in tables]


def value_names(params) -> list:
    """Dotted names of every value; identifiers (name, source) have no origin."""
    return [n for n in dotted_names(params) if n.rsplit(".", 1)[-1] not in ("name", "source")]


@pytest.mark.parametrize("label, params, origins", _origin_tables())
def test_every_default_value_has_its_origin(label, params, origins):
    names = value_names(params)
    assert len(names) > 15  # the enumeration sees the whole set
    missing = [n for n in names if n not in origins]
    assert not missing, f"{label}: no origin for {missing}"
    stale = [k for k in origins if k not in names]
    assert not stale, f"{label}: origins of parameters that do not exist: {stale}"


@pytest.mark.parametrize("label, params, origins", _origin_tables())
def test_origins_cite_sections_that_look_like_sections(label, params, origins):
    bad = {}
    for name, text in origins.items():
        if not ORIGIN_FORM.match(text):
            bad[name] = "starts with neither '[thesis] <reference>', 'estimate: <reasoning>' nor 'model: ... docs/model.md §N'"
            continue
        for m in SECTION_MARK.finditer(text):
            source, number = m.group(1), m.group(2).rstrip(",;:.)")
            if source is None:
                bad[name] = f"§{number} without '[thesis] ' or 'docs/model.md ' before it"
            elif source == "[thesis] " and not re.fullmatch(r"[1-8](\.\d+){0,2}", number):
                bad[name] = f"[thesis] §{number} is not a thesis section (chapters 1-8, e.g. §5.3.1)"
            elif source == "docs/model.md " and not re.fullmatch(r"\d+", number):
                bad[name] = f"docs/model.md §{number} is not a section number"
    assert not bad, f"{label}: {bad}"


def test_origin_checks_reject_what_they_should():
    for text in ("thesis §5.1: 3 springs", "estimate", "estimate: short", "model: our choice",
                 "[thesis] section 5", "[thesis] §A.1: x"):
        ok = ORIGIN_FORM.match(text) and all(
            m.group(1) and re.fullmatch(r"[1-8](\.\d+){0,2}|\d+", m.group(2).rstrip(",;:.)"))
            for m in SECTION_MARK.finditer(text)
        )
        assert not ok, text
    assert ORIGIN_FORM.match("[thesis] §6.2.2: 18 outer segments")
    assert ORIGIN_FORM.match("model: stiff contact (docs/model.md §6)")
