"""Campaign I/O with validation and synth (the diagnosis end to end: test_identification.py)."""

import hashlib
import json
import os

import numpy as np
import pandas as pd
import pytest

from dampersim.cli import main
from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.synth import synthesize
from dampersim.errors import InputError

POINTS = ["map_900_150", "map_1200_250", "map_1500_150", "map_1800_350", "map_2000_50", "map_1200_500"]


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    d = tmp_path_factory.mktemp("camp")
    out, truth = d / "c", d / "truth.json"
    synthesize(out, effects=[("pendulum_absorber", {"inertia": 0.002})], perturb=0.03, seed=3, truth=truth,
               points=POINTS, record=0.6)
    return out, truth


def _digest(folder):
    h = {}
    for root, _d, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            h[p] = hashlib.sha256(open(p, "rb").read()).hexdigest()
    return h


def test_synth_keeps_the_truth_out_of_the_campaign(hidden):
    out, truth = hidden
    names = {f for _r, _d, fs in os.walk(out) for f in fs}
    assert "manifest.csv" in names and not any("truth" in n for n in names)
    doc = json.loads(open(truth).read())
    assert doc["effects"][0]["name"] == "pendulum_absorber"
    with pytest.raises(InputError):
        synthesize(out, points=POINTS[:1], truth=out / "t.json", record=0.6)


def test_synth_gives_the_same_campaign_with_any_worker_count(hidden, tmp_path):
    """Each point's truth run is seeded by the campaign seed and the point's place in the
    plan, so a process pool writes the same records as one process (the CI identification
    tests synthesise in parallel and rely on it)."""
    out, _truth = hidden
    again = tmp_path / "c"
    synthesize(again, effects=[("pendulum_absorber", {"inertia": 0.002})], perturb=0.03, seed=3,
               truth=tmp_path / "truth.json", points=POINTS, record=0.6, workers=2)
    first = {os.path.relpath(k, out): v for k, v in _digest(out).items()}
    second = {os.path.relpath(k, again): v for k, v in _digest(again).items()}
    assert first == second and len(first) > len(POINTS)


def test_bad_campaign_reports_every_problem_and_keeps_valid_points(hidden, tmp_path):
    import shutil

    src, _ = hidden
    bad = tmp_path / "bad"
    shutil.copytree(src, bad)
    man = pd.read_csv(bad / "manifest.csv")
    files = list(man["file"])
    os.remove(bad / files[0])  # missing file
    df = pd.read_parquet(bad / files[1]).rename(columns={"output_torque_nm": "out_nm"})  # wrong column
    df.to_parquet(bad / files[1])
    df = pd.read_parquet(bad / files[2])
    df.loc[10, "input_torque_nm"] = np.nan  # NaN
    df.to_parquet(bad / files[2])
    df = pd.read_parquet(bad / files[3]).iloc[:500]  # too short
    df.to_parquet(bad / files[3])
    man.loc[4, "sample_rate_hz"] = 2000.0  # inconsistent sample rate
    man.loc[5, "mean_torque_nm"] = 100.0  # manifest disagrees with the file (500 N m)
    man.to_csv(bad / "manifest.csv", index=False)
    before = _digest(bad)
    camp = read_campaign(bad)
    fields = {(q.point, q.field) for q in camp.problems}
    ids = list(man["id"])
    assert (ids[0], "file") in fields
    assert (ids[1], "output_torque_nm") in fields
    assert (ids[2], "input_torque_nm") in fields
    assert (ids[3], "time_s") in fields
    assert (ids[4], "sample_rate_hz") in fields
    assert (ids[5], "input_torque_nm") in fields
    assert camp.points == [] or all(p.id not in ids for p in camp.points)
    assert _digest(bad) == before
    with pytest.raises(InputError):
        read_campaign(bad, strict=True)


def test_cli_effects_json(capsys):
    assert main(["effects", "--json"]) == 0
    items = json.loads(capsys.readouterr().out)
    assert {i["name"] for i in items} >= {"clutch_slip", "transducer_bandwidth"}
    for i in items:
        assert set(i) >= {"name", "description", "parameters"}
        for p in i["parameters"]:
            assert set(p) >= {"name", "unit", "default", "min", "max"}


def test_cli_bad_input_exits_2(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "nothing")]) == 2
    assert main(["synth", "--out", str(tmp_path / "x"), "--effect", "warp_drive"]) == 2


def test_the_synthetic_truth_is_finer_than_its_base():
    # a third more segments, rounded down, at least one more, within the parameter's limit
    from dampersim.discrepancy.synth import fine_segments, truth_system
    from dampersim.parameters import at_thesis_segments, default_parameters

    assert [fine_segments(n) for n in (4, 8, 16, 18, 48, 150, 199, 200)] == [5, 10, 21, 24, 64, 200, 200, 200]
    truth, applied = truth_system(default_parameters(), perturb=0.0)
    assert (truth.solver.outer_segments, truth.solver.inner_segments) == (64, 21)  # default 48/16
    truth, _ = truth_system(at_thesis_segments(), perturb=0.0)
    assert (truth.solver.outer_segments, truth.solver.inner_segments) == (24, 10)
    assert truth.solver.time_step < default_parameters().solver.time_step
