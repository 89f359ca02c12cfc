"""The chapter 7 studies on their reduced (quick) grids: they run, serialise as strict
JSON, hit the cache on a second call and show the thesis's qualitative findings that the
reduced grid can show."""

import json

import pytest

from dampersim.cli import main
from dampersim.studies import STUDIES, run_study, table_7_1


def test_table_7_1_covers_20_to_300_hz():
    f = sorted(k * rpm / 60 for k, rpm in table_7_1())
    assert f[0] == pytest.approx(20.0) and f[-1] == pytest.approx(300.0)
    assert len(f) == 29


@pytest.fixture(scope="module")
def results():
    return {}


def _run(name, results):
    if name not in results:
        results[name] = run_study(name, quick=True, executor="serial")
    return results[name]


# The mapping study takes about 7 s on its quick grid: every test that needs its result
# is slow, the other studies stay in the quick selection (-m "not slow").
SLOW_STUDIES = {"mapping"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_STUDIES else n for n in STUDIES])
def test_study_runs_and_is_json(name, results):
    seen = []
    res = run_study(name, quick=True, executor="serial", progress=lambda d, t, c: seen.append((d, t)))
    results[name] = res
    json.dumps(res, allow_nan=False)
    assert res["study"] == name and res["points"] > 0
    assert seen and seen[-1][0] == seen[-1][1]


def test_second_run_comes_from_cache(results):
    _run("additional-orders", results)
    again = run_study("additional-orders", quick=True, executor="serial")
    assert again["from_cache"] == again["points"]


def test_order_rule(results):
    r = _run("order-rule", results)["results"]["max_abs_change_pct_by_n"]
    # [thesis] §7.1.1: three dominant orders reproduce the full signal's MR within 1-2 %,
    # the dominant order alone by up to ~10 %. In the quick case (2000 rpm, 415 N m, above
    # the knee) our dominant order alone changes MR by ~13 %; three orders leave the 2nd
    # and 6th within 1 % but the 4th (12 N m of output) moves ~6 % once the 23 N m 8th
    # order is dropped -- a difference from the thesis recorded in
    # docs/thesis-comparison.md. Asserted here: the qualitative ordering.
    assert r["1"] > 8.0
    assert r["1"] > 2 * r["3"]
    # the repeatability run (full signal, amplitudes x (1 + 1e-9)) is reported: stick-slip
    # makes small orders move by up to ~1 % for such a change, the scale below which a
    # replica's MR change means nothing
    rep = _run("order-rule", results)["results"]["max_abs_perturbation_mr_change_pct"]
    assert 0.0 <= rep < 5.0


def test_speed_stiffness(results):
    res = _run("speed-stiffness", results)
    assert res["checks"]["stiffening_far_larger_at_5deg"]
    assert res["checks"]["end_segments_stall_at_high_speed"]


@pytest.mark.slow
def test_mapping_300_beats_100(results):
    assert _run("mapping", results)["checks"]["amplitude_300_predicts_better_than_100"]


def test_poor_performance_warns_above_validated_speed(results):
    res = _run("poor-performance", results)
    assert any("3000 rpm" in w for w in res["warnings"])
    assert res["checks"]["mr_rises_below_20hz"]


def test_cli_study_json(capsys, tmp_path):
    assert main(["study", "additional-orders", "--quick", "--executor", "serial", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["study"] == "additional-orders"
    assert (tmp_path / "additional-orders.json").exists()


@pytest.mark.slow  # needs every study, the mapping study too
def test_figures_build_for_every_study(results):
    from dampersim.plotting.studies import study_figures

    for name in STUDIES:
        figs = study_figures(_run(name, results))
        assert figs and all(len(f.data) > 0 for f in figs)
