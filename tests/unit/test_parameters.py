"""Parameter sets: TOML round trip, dotted overrides, validation messages, default targets."""

import math

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
        ("solver.time_step", 1e-4, "stability bound"),
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


def test_validate_returns_valid_set():
    p = default_parameters()
    assert validate(p) is p


def test_default_set_qualitative_targets():
    """model-spec §10: positive knee near 300 N m, inner knee above the 500 N m test range,
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
