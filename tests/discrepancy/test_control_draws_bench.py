"""bench/bench_control_draws.py's figures (docs/discrepancy.md quotes them): which points it
reads as held out, the input draw it rebuilds from a case seed, and the rows it ranks."""

import json
import math

import pytest

from dampersim.discrepancy.likelihood import input_mean_sd
from dampersim.discrepancy.synth import plan
from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_control_draws")


def test_the_held_out_points_are_the_diagnosis_s(bench):
    # the bench reads the diagnosis's own rule (diagnose.held_out_indices): every third kept
    # torsional point, from the second
    assert bench.held_out_points() == ["tc_1600", "tc_2800", "map_1200_50", "map_1500_150"]


def test_the_input_draw_of_control_none_4(bench):
    # docs/discrepancy.md ("What control/none/4's held-out chi2 is made of"): this case's
    # chain has its input offset at -1.65 N m and its gain 0.24 % low; rounded to those
    # figures the draw must come out within the rounding (2 %)
    seed = {c["id"]: c for c in bench.B.hard_cases()}["control/none/4"]["seed"]
    mean_nm = {p[0]: p[3] for p in plan("all")}
    points = bench.held_out_points()
    by_hand = sum(((-1.65 - 0.0024 * mean_nm[p]) / input_mean_sd(mean_nm[p])) ** 2 for p in points) / len(points)
    assert bench.input_draw_z2(seed, points) == pytest.approx(by_hand, rel=0.02)


def test_rows_and_rank_correlations(bench):
    def line(cid, kind, chi):
        return {"id": cid, "kind": kind, "likelihood": {"reduced_chi2_held_out": chi}}

    rows = [line("control/none/0", "control", 5.0), line("control/none/0", "control", 0.3),  # the later line counts
            line("ool/rig_shaft/0", "out_of_library", 9.0),  # not a control
            line("control/none/1", "control", None),  # no figure: left out
            line("control/rig_stiff_parts/0", "control", 2.0), line("control/calibration/0", "control", 0.7)]
    table = bench.control_rows(json.loads(json.dumps(rows)), {"control/calibration/3": 1.49})
    assert [r[0] for r in table] == ["control/none/0", "control/calibration/0", "control/calibration/3",
                                     "control/rig_stiff_parts/0"]
    assert [r[2] for r in table] == [0.3, 0.7, 1.49, 2.0]
    assert all(r[3] >= 0 and math.isfinite(r[3]) for r in table)
    rho = bench.rank_correlations(table)
    assert rho["all"]["n"] == 4 and "without rig changes" in rho  # three controls without a changed rig
    assert rho["without rig changes"]["n"] == 3
    assert -1.0 <= rho["all"]["noise"][0] <= 1.0


def test_bad_arguments_are_named(bench, tmp_path, capsys):
    with pytest.raises(SystemExit):
        bench.main([str(tmp_path / "nope.jsonl")])
    assert "no such file" in capsys.readouterr().err
    f = tmp_path / "a.jsonl"
    f.write_text("")
    with pytest.raises(SystemExit):
        bench.main([str(f), "--add", "control/calibration/3"])
    assert "CASE_ID=CHI2" in capsys.readouterr().err
