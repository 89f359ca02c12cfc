"""Command line outputs: every --out (and --report, --out-params, --truth) creates what it
needs, on a fresh working folder, through one helper; impossible paths are one line and exit 2."""

import json
import os

import pandas as pd
import pytest

from dampersim.cli import main
from dampersim.cli.options import prepare_output
from dampersim.errors import InputError

#: A short simulation: 1 s simulated, the last 0.4 s analysed.
SHORT_SWEEP = ["--duration", "1.0", "--window", "0.4", "--executor", "serial", "--no-progress"]


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """An empty working folder, as on a fresh clone: relative paths land in it."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and "Traceback" not in err
    return err


# --------------------------------------------------------------------------- the helper
def test_prepare_output_file_creates_its_parent_folders(tmp_path):
    target = tmp_path / "a" / "b" / "run.parquet"
    assert prepare_output(target, "file") == str(target)
    assert (tmp_path / "a" / "b").is_dir() and not target.exists()


def test_prepare_output_folder_creates_the_folder_and_accepts_an_existing_one(tmp_path):
    target = tmp_path / "a" / "b"
    assert prepare_output(target, "folder") == str(target)
    assert target.is_dir()
    assert prepare_output(target, "folder") == str(target)


def test_prepare_output_returns_an_absolute_path(fresh):
    assert prepare_output("out/x.html", "file") == str(fresh / "out" / "x.html")


def test_prepare_output_refuses_impossible_paths(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(InputError, match=r"--out .*afile.*exists and is not a folder; accepted is a folder"):
        prepare_output(afile, "folder")
    with pytest.raises(InputError, match=r"--report .*: is a folder; accepted is a file name"):
        prepare_output(tmp_path, "file", option="--report")
    with pytest.raises(InputError, match=r"--out .*: cannot create the folder"):
        prepare_output(afile / "sub" / "run.parquet", "file")
    with pytest.raises(InputError, match=r"--out .*: cannot create the folder"):
        prepare_output(afile / "sub", "folder")


# --------------------------------------------------------------------------- folder outputs
def test_hysteresis_out_creates_the_folder(fresh, capsys):
    # the README's command, shortened: the folder does not exist yet
    args = ["hysteresis", "--speeds", "1000", "--protocol", "full-100", "--rate", "200", "--hold", "0.2",
            "--json", "--out", "out/loops"]
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["figure"] == str(fresh / "out" / "loops" / "hysteresis-full-100.html")
    assert (fresh / "out" / "loops" / "hysteresis-full-100.html").is_file()


def test_sweep_out_creates_nested_folders(fresh, capsys):
    args = ["sweep", "--speeds", "1000", "--torque", "200", *SHORT_SWEEP, "--out", "out/a/sweep", "--json"]
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["table"] == str(fresh / "out" / "a" / "sweep" / "sweep.parquet")
    assert len(pd.read_parquet(d["table"])) > 0


def test_map_out_creates_nested_folders(fresh, capsys):
    args = ["map", "--speeds", "1000,1600", "--torque", "100,400", "--orders", "2:300", *SHORT_SWEEP,
            "--out", "out/b/map", "--json"]
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert (fresh / "out" / "b" / "map" / "sweep.parquet").is_file()
    assert all(os.path.dirname(f) == str(fresh / "out" / "b" / "map") for f in d["figures"])


def test_study_out_creates_nested_folders(fresh, capsys):
    assert main(["study", "order-rule", "--quick", "--executor", "serial", "--json", "--out", "out/c/study"]) == 0
    doc = json.loads(capsys.readouterr().out)
    written = json.loads((fresh / "out" / "c" / "study" / "order-rule.json").read_text())
    assert written["study"] == doc["study"] == "order-rule"


def test_synth_out_and_truth_create_their_folders(fresh, capsys):
    args = ["synth", "--out", "out/d/campaign", "--points", "map_900_150", "--record", "0.6",
            "--truth", "out/truths/t.json"]
    assert main(args) == 0
    assert (fresh / "out" / "d" / "campaign" / "manifest.csv").is_file()
    assert json.loads((fresh / "out" / "truths" / "t.json").read_text())["points"] == ["map_900_150"]


def test_folder_output_at_an_existing_file_is_one_line_exit_2(fresh, capsys):
    (fresh / "taken").write_text("x")
    for args in (["hysteresis", "--speeds", "1000", "--out", "taken"],
                 ["sweep", "--speeds", "1000", *SHORT_SWEEP, "--out", "taken"],
                 ["study", "order-rule", "--quick", "--out", "taken"],
                 ["synth", "--out", "taken", "--points", "map_900_150"]):
        assert main(args) == 2, args
        err = one_line_error(capsys)
        assert "--out 'taken': exists and is not a folder" in err, args
    assert (fresh / "taken").read_text() == "x"


# --------------------------------------------------------------------------- file outputs
def test_simulate_out_creates_parent_folders(fresh, capsys):
    args = ["simulate", "--speed", "1200", "--torque", "150", "--set", "solver.duration=1.0",
            "--out", "out/e/run.parquet", "--json"]
    assert main(args) == 0
    frame = pd.read_parquet(fresh / "out" / "e" / "run.parquet")
    assert {"time_s", "output_torque_nm"} <= set(frame.columns)
    assert frame["time_s"].iloc[-1] < 1.0


def test_campbell_and_modes_out_create_parent_folders(fresh, capsys):
    assert main(["campbell", "--out", "out/f/campbell.html", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figure"] == str(fresh / "out" / "f" / "campbell.html")
    assert main(["modes", "--out", "out/g/modes.html", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["campbell_html"] == str(fresh / "out" / "g" / "modes.html")


def test_file_output_at_a_folder_or_below_a_file_is_one_line_exit_2(fresh, capsys):
    (fresh / "folder").mkdir()
    (fresh / "afile").write_text("x")
    assert main(["campbell", "--out", "folder"]) == 2
    assert "--out 'folder': is a folder; accepted is a file name" in one_line_error(capsys)
    assert main(["simulate", "--speed", "1200", "--torque", "150", "--out", "afile/run.parquet"]) == 2
    assert "--out 'afile/run.parquet': cannot create the folder" in one_line_error(capsys)
    assert main(["modes", "--out", "afile/m.html"]) == 2
    assert "--out 'afile/m.html': cannot create the folder" in one_line_error(capsys)


def test_diagnose_report_and_out_params_create_parent_folders(fresh, capsys, monkeypatch):
    from dampersim.discrepancy import drive
    from dampersim.discrepancy.campaign_write import write_campaign
    from dampersim.parameters import at_thesis_segments, save_toml
    from tests.discrepancy import fake_rig as F

    # the folders are what is tested: the six-point campaign of the stand-in model, which the
    # diagnosis drives in this process (--workers 1) in about a second instead of simulating
    write_campaign(fresh / "campaign", [F.point(*p) for p in F.POINTS])
    monkeypatch.setattr(drive, "simulate_point", F.fake_model())
    save_toml(at_thesis_segments(), "coarse.toml")  # --params is read on the way
    args = ["diagnose", "campaign", "--workers", "1", "--json", "--candidates", "turbine_drag,pendulum_absorber",
            "--no-recommend", "--report", "out/h/report.html", "--out-params", "out/i/augmented.toml",
            "--params", "coarse.toml"]
    assert main([*args[:2], "--candidates", "warp_drive"]) == 2  # refused before any work, with the accepted names
    assert "accepted is a comma-separated list of clutch_slip" in capsys.readouterr().err
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["verdict"]
    assert (fresh / "out" / "h" / "report.html").stat().st_size > 1000
    assert main(["params", "validate", "out/i/augmented.toml"]) == 0
