"""Command line: simulate / modes / params, and one-line errors with exit code 2."""

import json
import subprocess
import sys

import pandas as pd
import pytest

from dampersim.cli import main


def run(*args):
    return subprocess.run([sys.executable, "-m", "dampersim", *args], capture_output=True, text=True, timeout=300)


def test_simulate_json_contract(capsys):
    assert main(["simulate", "--speed", "1500", "--torque", "200", "--orders", "2:300,4:100", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert set(d) == {"orders", "input_amplitude_nm", "output_amplitude_nm", "magnification", "wall_time_s"}
    assert d["orders"] == list(range(1, 9))
    assert d["input_amplitude_nm"][1] == pytest.approx(300.0, rel=1e-3)
    assert d["input_amplitude_nm"][3] == pytest.approx(100.0, rel=1e-3)
    assert 0 < d["magnification"][1] < 0.2  # well attenuated below the knee
    assert d["magnification"][0] is None  # no input at order 1: no ratio
    assert 0 < d["wall_time_s"] < 60


def test_simulate_writes_time_series(tmp_path, capsys):
    out = tmp_path / "run.parquet"
    assert main(["simulate", "--speed", "1200", "--torque", "150", "--duration", "1.5", "--no-friction",
                 "--output-motor", "held", "--out", str(out)]) == 0
    frame = pd.read_parquet(out)
    assert {"time_s", "input_torque_nm", "output_torque_nm", "windup_outer_rad"} <= set(frame.columns)
    assert len(frame) == 15000


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--orders", "2:abc"], "--orders item '2:abc'"),
        (["--set", "friction.outr.alpha=0"], "did you mean outer"),
        (["--set", "outer.spring.stiffness=-5"], "outer.spring.stiffness = -5.0"),
        (["--set", "solver.outer_segments=3"], "solver.outer_segments"),
        (["--set", "solver.time_step=0.001"], "solver.time_step"),
        (["--set", "inner.hardstop_negative=0.2"], "inner.hardstop_negative"),
        (["--set", "inner.spring.arc=1.4"], "shorter than the stopper pitch"),
        (["--set", "noequals"], "NAME=VALUE"),
    ],
)
def test_bad_input_is_one_line_exit_2(args, fragment, capsys):
    assert main(["simulate", "--speed", "1500", "--torque", "200", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_process_level_error_has_no_traceback():
    p = run("simulate", "--speed", "99999", "--torque", "200")
    assert p.returncode == 2 and "Traceback" not in p.stderr and "--speed" in p.stderr


def test_modes_json_contract(capsys):
    assert main(["modes", "--output-motor", "held", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert {"dof_names", "M", "C", "K", "input_dof", "output_shaft", "natural_frequencies_hz"} <= set(d)
    assert set(d["output_shaft"]) == {"dofs", "k", "c"}
    assert "output_motor" not in d["dof_names"]
    assert d["natural_frequencies_hz"][0] < 20


def test_params_show_validate_round_trip(tmp_path, capsys):
    assert main(["params", "show", "--set", "inertias.primary=0.25"]) == 0
    text = capsys.readouterr().out
    f = tmp_path / "p.toml"
    f.write_text(text)
    assert main(["params", "validate", str(f)]) == 0
    assert "valid" in capsys.readouterr().out
    f.write_text(text.replace("primary = 0.25", "primary = -1.0"))
    assert main(["params", "validate", str(f)]) == 2
    assert "inertias.primary" in capsys.readouterr().err


def test_modes_shapes_and_campbell_html(tmp_path, capsys):
    out = tmp_path / "campbell.html"
    assert main(["modes", "--json", "--out", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    n = len(d["dof_names"])
    assert len(d["mode_shapes"]) == n and len(d["mode_shapes"][0]) == n
    assert d["dominant_dofs"][1][0][0] == "primary"  # the first elastic mode: J_pri on the springs
    assert out.exists() and out.stat().st_size > 10_000


def test_map_command_small_grid(tmp_path, capsys):
    args = ["map", "--speeds", "1000,1600", "--torque", "100,400", "--orders", "2:300,4:100",
            "--duration", "1.6", "--window", "0.8", "--executor", "serial", "--no-progress",
            "--out", str(tmp_path / "map"), "--json"]
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["points"] == 4 and d["computed"] + d["from_cache"] == 4
    assert set(d["zones"]) == {"spike", "low", "below_knee_high", "above_knee_high"}
    # above the knee only the inner set works: attenuation is poorer than below it
    assert d["zones"]["above_knee_high"]["median_mr"] > d["zones"]["below_knee_high"]["median_mr"]
    assert (tmp_path / "map" / "sweep.parquet").exists()


def test_step_above_the_tested_default_is_one_warning_line(capsys):
    # a stable but coarser step runs (exit 0) and says once, on stderr, that its accuracy
    # is not checked; a step above the stability bound is refused with the bound (exit 2)
    argv = ["simulate", "--speed", "1500", "--torque", "200", "--orders", "2:50", "--duration", "0.3",
            "--set", "solver.time_step=3.3333333e-5", "--json"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert err.count("warning: solver.time_step") == 1 and "accuracy is checked" in err
    assert main(argv[:-2] + ["solver.time_step=2e-4", "--json"]) == 2
    assert "stability bound" in capsys.readouterr().err
