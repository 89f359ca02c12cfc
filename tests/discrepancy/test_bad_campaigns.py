"""Campaigns that cannot be diagnosed get the verdict insufficient_data and a message that
names what is missing and what is accepted, with every JSON field present (no model run
is needed to tell, so nothing here simulates)."""

import json

import pytest

from dampersim.cli import main
from dampersim.discrepancy import drive
from dampersim.discrepancy.campaign_write import write_campaign
from dampersim.discrepancy.diagnose import INSUFFICIENT, diagnose, shortfall, speeds_of
from tests.discrepancy import fake_rig as F
from tests.discrepancy.test_failed_runs import EXISTING_KEYS


@pytest.fixture(autouse=True)
def no_simulation(monkeypatch):
    """Any model run here is a test failure: the campaign's shape decides."""
    def refuse(system, point):
        raise AssertionError(f"simulated {point.id}")
    monkeypatch.setattr(drive, "simulate_point", refuse)


def verdict_of(points):
    d = diagnose(F.campaign(points), workers=1)
    doc = json.loads(json.dumps(d.to_json(), allow_nan=True))
    assert set(doc) >= EXISTING_KEYS | {"message", "missing"}
    assert d.verdict == INSUFFICIENT and d.effect is None and d.ranking == [] and d.simulations == 0
    return d


def test_too_few_torsional_points():
    d = verdict_of([F.point("a", 1000.0, 100.0), F.point("b", 1600.0, 200.0), F.ramp("r")])
    assert d.missing == ["torsional_points"]
    assert "only 2 valid torsional test point(s) (a, b)" in d.message
    assert "Accepted: at least 3 valid torsional test points" in d.message


def test_no_torsional_points():
    d = verdict_of([F.ramp("r1"), F.ramp("r2", 2000.0)])
    assert d.missing == ["torsional_points"]
    assert "no valid torsional test point (2 ramp(s)" in d.message and "Accepted: at least 3" in d.message


def test_only_one_speed():
    # 1510 rpm is within 2 % of 1500 rpm: the same set point, measured
    d = verdict_of([F.point("a", 1500.0, 100.0), F.point("b", 1500.0, 300.0), F.point("c", 1510.0, 200.0),
                    F.point("d", 1500.0, 400.0)])
    assert d.missing == ["speeds"]
    assert "all 4 torsional test points are at one speed (1500 rpm)" in d.message
    assert "at 2 or more speeds" in d.message


def test_too_few_points_at_one_speed_names_both():
    d = verdict_of([F.point("a", 1500.0, 100.0), F.point("b", 1500.0, 300.0)])
    assert d.missing == ["torsional_points", "speeds"]


def test_speeds_within_two_per_cent_count_as_one():
    pts = [F.point(i, s, 100.0) for i, s in (("a", 900.0), ("b", 900.246), ("c", 1200.0), ("d", 1225.0))]
    assert speeds_of(pts) == [900.0, 1200.0, 1225.0]  # 1225 is 2.1 % above 1200: another speed
    assert speeds_of(pts[:2]) == [900.0]  # an imported campaign's measured mean of a 900 rpm set point
    assert shortfall(pts[:3]) == ([], "")


@pytest.mark.parametrize("points, missing", [
    ([("a", 1000.0, 100.0), ("b", 1600.0, 200.0)], "torsional_points"),
    ([("a", 1500.0, 100.0), ("b", 1500.0, 300.0), ("c", 1500.0, 200.0)], "speeds"),
])
def test_cli_prints_the_verdict_and_exits_2(tmp_path, capsys, points, missing):
    folder = tmp_path / "camp"
    write_campaign(folder, [F.point(*p) for p in points])
    out_params = tmp_path / "augmented.toml"
    assert main(["diagnose", str(folder), "--json", "--workers", "1", "--out-params", str(out_params)]) == 2
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert set(doc) >= EXISTING_KEYS
    assert doc["verdict"] == INSUFFICIENT and missing in doc["missing"] and doc["noise_floor_nm"] is None
    assert captured.err.startswith("error: campaign camp: not diagnosed:") and "Accepted:" in captured.err
    assert not out_params.exists()
    assert main(["diagnose", str(folder), "--workers", "1"]) == 2
    assert capsys.readouterr().out.strip() == "verdict: insufficient_data"
