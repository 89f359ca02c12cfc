"""Channel mapping and unit conversion: map files, the unit table, matching by name and unit."""

from dataclasses import dataclass

import numpy as np
import pytest

from dampersim.errors import InputError
from dampersim.rigdata.mapping import BY_GUESS, BY_MAP, BY_NAME, ChannelMap, load_map, normalise_name, resolve
from dampersim.rigdata.units import convert, quantity_of


@dataclass(frozen=True)
class Ch:
    """A channel as the readers describe it."""

    name: str
    unit: str
    group: str = "fast"
    samples: int = 1000
    rate_hz: float = 10000.0


RIG = [Ch("Time", "s"), Ch("Trq_In", "Nm"), Ch("Torque_Output", "kN m"), Ch("n_In", "rpm", "slow", 100, 1000.0),
       Ch("Speed_Out", "rad/s", "slow", 100, 1000.0), Ch("Flange_In", "deg"), Ch("Angle_Out", "rad"),
       Ch("Temp_In", "degC", "slow", 10, 10.0)]


def report_line(res, target):
    return next(line for line in res.report if line.startswith(target))


# ------------------------------------------------------------------------- units
@pytest.mark.parametrize("unit, target, factor", [
    ("N m", "input_torque_nm", 1.0), ("Nm", "input_torque_nm", 1.0), ("N*m", "input_torque_nm", 1.0),
    ("N.m", "output_torque_nm", 1.0), ("kN m", "input_torque_nm", 1e3), ("kNm", "input_torque_nm", 1e3),
    ("kN*m", "input_torque_nm", 1e3), ("[Nm]", "input_torque_nm", 1.0), (" NM ", "input_torque_nm", 1.0),
    ("rpm", "input_speed_rpm", 1.0), ("1/min", "input_speed_rpm", 1.0), ("min-1", "output_speed_rpm", 1.0),
    ("rad/s", "input_speed_rpm", 30.0 / np.pi), ("Hz", "input_speed_rpm", 60.0), ("deg", "windup_deg", 1.0),
    ("°", "input_flange_deg", 1.0), ("rad", "output_flange_deg", 180.0 / np.pi), ("ms", "time_s", 1e-3),
    ("s", "time_s", 1.0),
])
def test_units_convert_to_the_campaign_unit(unit, target, factor):
    np.testing.assert_allclose(convert([1.0, -2.0], unit, target), [factor, -2.0 * factor], rtol=1e-12)


def test_gain_and_offset_apply_after_the_unit_conversion_in_the_target_unit():
    np.testing.assert_allclose(convert([0.2], "kN m", "input_torque_nm", gain=1.1, offset=-3.0), [1.1 * 200.0 - 3.0])


def test_a_unit_of_another_quantity_names_channel_unit_and_accepted_units():
    with pytest.raises(InputError) as exc:
        convert([1.0], "rpm", "input_torque_nm", channel="Trq_In")
    msg = str(exc.value)
    assert "'Trq_In'" in msg and "'rpm'" in msg and "a speed unit" in msg and "'kN m'" in msg
    with pytest.raises(InputError, match=r"'V'.*accepted units are 'rpm'"):
        convert([1.0], "V", "input_speed_rpm", channel="n_In")
    with pytest.raises(InputError, match="gain"):
        convert([1.0], "Nm", "input_torque_nm", gain=0)


def test_unit_quantities_come_from_the_table_only():
    assert quantity_of("Nm") == "torque" and quantity_of("1/min") == "speed" and quantity_of("°") == "angle"
    assert quantity_of("") is None and quantity_of("V") is None and quantity_of("degC") is None


# ------------------------------------------------------------------------- auto-match
def test_auto_match_by_name_and_unit_with_a_report_line_per_target():
    res = resolve(RIG)
    assert {k: s.name for k, s in res.specs.items()} == {
        "input_torque_nm": "Trq_In", "output_torque_nm": "Torque_Output", "input_speed_rpm": "n_In",
        "output_speed_rpm": "Speed_Out", "input_flange_deg": "Flange_In", "output_flange_deg": "Angle_Out"}
    assert res.specs["output_torque_nm"].unit == "kN m"
    assert report_line(res, "input_torque_nm").endswith(BY_NAME)
    assert report_line(res, "input_speed_rpm").endswith(BY_GUESS)  # "n" is a symbol: a guess the unit confirms
    assert "kN m -> N m x 1000" in report_line(res, "output_torque_nm")
    assert report_line(res, "windup_deg") == "windup_deg: not found (optional)"
    assert len(res.report) == 7 and res.channels["input_speed_rpm"].rate_hz == 1000.0


@pytest.mark.parametrize("name, unit, target, how", [
    ("Torque_Input", "Nm", "input_torque_nm", BY_NAME), ("TorqueIn", "Nm", "input_torque_nm", BY_NAME),
    ("input torque", "N m", "input_torque_nm", BY_NAME), ("T_in", "Nm", "input_torque_nm", BY_GUESS),
    ("Trq_In_Nm", "Nm", "input_torque_nm", BY_NAME), ("Drehmoment_Abtrieb", "Nm", "output_torque_nm", BY_NAME),
    ("Trq_Out", "kNm", "output_torque_nm", BY_NAME), ("T_out", "Nm", "output_torque_nm", BY_GUESS),
    ("Speed_In", "rpm", "input_speed_rpm", BY_NAME), ("rpm_in", "1/min", "input_speed_rpm", BY_NAME),
    ("Drehzahl_ein", "U/min", "input_speed_rpm", BY_NAME), ("w_in", "rad/s", "input_speed_rpm", BY_GUESS),
    ("RPMOut", "rpm", "output_speed_rpm", BY_NAME), ("nOut", "rpm", "output_speed_rpm", BY_GUESS),
    ("phi_in", "deg", "input_flange_deg", BY_GUESS), ("Flange_Out", "rad", "output_flange_deg", BY_NAME),
    ("Windup", "deg", "windup_deg", BY_NAME), ("twist_deg", "deg", "windup_deg", BY_NAME),
    ("Kanal3_ein", "Nm", "input_torque_nm", BY_GUESS),
])
def test_common_rig_names_are_recognised(name, unit, target, how):
    base = [c for c in RIG if c.name not in ("Trq_In", "Torque_Output", "n_In", "Speed_Out", "Flange_In", "Angle_Out")]
    fill = {"input_torque_nm": Ch("Torque_Input", "Nm"), "output_torque_nm": Ch("Torque_Output", "Nm"),
            "input_speed_rpm": Ch("Speed_In", "rpm"), "output_speed_rpm": Ch("Speed_Out", "rpm")}
    fill.pop(target, None)
    res = resolve(base + list(fill.values()) + [Ch(name, unit)])
    assert res.specs[target].name == name
    assert report_line(res, target).endswith(how)


def test_names_are_normalised_before_matching():
    assert normalise_name("TorqueIn") == "torque_in" and normalise_name("RPMOut") == "rpm_out"
    assert normalise_name("Drehzahl Ein") == "drehzahl_ein" and normalise_name("n-In.") == "n_in"


def test_a_torque_name_with_a_speed_unit_is_not_a_torque():
    channels = [Ch("Trq_In", "rpm"), Ch("Torque_Output", "Nm"), Ch("n_In", "rpm"), Ch("Speed_Out", "rpm")]
    with pytest.raises(InputError) as exc:
        resolve(channels)
    msg = str(exc.value)
    assert "input_torque_nm" in msg and "'Trq_In' matches input_torque_nm by name but its unit 'rpm'" in msg


def test_two_candidates_for_one_target_ask_for_a_map():
    with pytest.raises(InputError) as exc:
        resolve(RIG + [Ch("Torque_Input", "Nm", "other")])
    msg = str(exc.value)
    assert "input_torque_nm" in msg and "'Trq_In'" in msg and "'Torque_Input'" in msg and "map" in msg


def test_a_name_beats_a_guess():
    res = resolve(RIG + [Ch("T_in", "Nm")])
    assert res.specs["input_torque_nm"].name == "Trq_In"


def test_a_missing_required_channel_names_the_target_and_lists_the_channels():
    with pytest.raises(InputError) as exc:
        resolve([c for c in RIG if c.name != "Speed_Out"])
    msg = str(exc.value)
    assert "output_speed_rpm" in msg and "'Trq_In' [Nm]" in msg and "'Temp_In' [degC]" in msg


# ------------------------------------------------------------------------- map files
MAP = """
[channels.input_torque_nm]
name = "Trq_In"
unit = "kN m"      # the file says Nm, the rig engineer knows better
gain = 1.02
offset = -3

[channels.windup_deg]
name = "Temp_In"
unit = "deg"
"""


def test_map_file_targets_come_from_the_map_the_rest_by_name(tmp_path):
    path = tmp_path / "rig.toml"
    path.write_text(MAP, encoding="utf-8")
    cmap = load_map(path)
    res = resolve(RIG, cmap)
    spec = res.specs["input_torque_nm"]
    assert (spec.name, spec.unit, spec.gain, spec.offset) == ("Trq_In", "kN m", 1.02, -3.0)
    assert report_line(res, "input_torque_nm").endswith(BY_MAP)
    assert "file says Nm" in report_line(res, "input_torque_nm") and "gain 1.02" in report_line(res, "input_torque_nm")
    assert res.specs["windup_deg"].name == "Temp_In" and report_line(res, "windup_deg").endswith(BY_MAP)
    assert report_line(res, "output_torque_nm").endswith(BY_NAME)


def test_a_map_settles_an_ambiguity():
    cmap = ChannelMap.from_dict({"channels": {"input_torque_nm": {"name": "Torque_Input"}}})
    res = resolve(RIG + [Ch("Torque_Input", "Nm")], cmap)
    assert res.specs["input_torque_nm"].name == "Torque_Input"


@pytest.mark.parametrize("text, needle", [
    ("[channel.input_torque_nm]\nname = 'a'\n", "[channel]: unknown table"),
    ("[channels.input_torque]\nname = 'a'\n", "[channels.input_torque]: unknown target"),
    ("[channels.input_torque_nm]\nname = 'a'\nscale = 2\n", "channels.input_torque_nm.scale: unknown key"),
    ("[channels.input_torque_nm]\nname = 'a'\n[channels.input_torque_nm]\nname = 'b'\n",
     "[channels.input_torque_nm] appears twice (lines 1 and 3)"),
    ("[channels.input_torque_nm]\nname = 'a'\ngain = 'x'\n", "channels.input_torque_nm.gain = 'x': accepted is a finite"),
    ("[channels.input_torque_nm]\nname = 'a'\ngain = 0\n", "gain = 0: accepted is a finite non-zero number"),
    ("[channels.input_torque_nm]\nname = 'a'\ngain = true\n", "gain = True"),
    ("[channels.input_torque_nm]\nname = 'a'\noffset = nan\n", "offset = nan: accepted is a finite number"),
    ("[channels.input_torque_nm]\nname = 'a'\nunit = 'rpm'\n", "unit = 'rpm': accepted torque units are"),
    ("[channels.input_torque_nm]\nunit = 'Nm'\n", "channels.input_torque_nm.name = None"),
    ("[channels.input_torque_nm\nname = 'a'\n", "not valid TOML"),
])
def test_bad_map_files_name_field_value_and_what_is_accepted(tmp_path, text, needle):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as exc:
        load_map(path)
    assert needle in str(exc.value) and "bad.toml" in str(exc.value)


def test_a_map_naming_a_channel_the_file_lacks_lists_the_channels():
    cmap = ChannelMap.from_dict({"channels": {"output_torque_nm": {"name": "Trq_Abtrieb"}}}, source="rig.toml")
    with pytest.raises(InputError, match=r"rig.toml: channels.output_torque_nm.name = 'Trq_Abtrieb'.*'n_In' \[rpm\]"):
        resolve(RIG, cmap)


def test_a_mapped_channel_whose_file_unit_cannot_be_converted_needs_a_unit_in_the_map():
    cmap = ChannelMap.from_dict({"channels": {"windup_deg": {"name": "Temp_In"}}})
    with pytest.raises(InputError, match=r"'Temp_In' for windup_deg: unit 'degC' cannot be converted"):
        resolve(RIG, cmap)
