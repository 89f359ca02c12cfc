"""The chapter 7 studies on their reduced (quick) grids: they run, make exactly the
simulations their plan counts, serialise as strict JSON, hit the cache on a second call and
show the thesis's qualitative findings that the reduced grid can show.

The plan (built from the study's own grid before anything is simulated, the source of
:func:`dampersim.studies.study_cost`) is checked against the run itself. Every simulation
ends in one call of the integrator kernel (``dampersim.simulation.damper.run_damper``),
whatever asked for it (a sweep point or a cached study run); the ``counter`` fixture counts
the calls and their work, ``len(torque)`` steps x the layout's DOF, as the kernel sees them
(not through the cost model's formulas). The studies run with ``executor="serial"`` so every
call happens in this process, on a fresh cache so nothing is served from an earlier run.

Every study run here but the CLI test's runs on SYSTEM, the default damper at the thesis's
18/8 segments (the CLI test runs the default 48/16): these tests check the studies'
machinery and the findings a reduced grid shows, which hold on both sets (measured one after
the other on one machine). The four costliest studies' estimated time falls from 154.5 s of
one core to 71.9 s (study_cost, steps x DOF); in the suite's fresh-clone runs they took
127.0 s (commit 78f03b9) and then 73.8 s (cc49dbe), both in the machine's slow state. The
default set's findings and figures are those of bench/bench_studies.py and
docs/thesis-comparison.md.
"""

import json
import time

import pytest

from dampersim.cli import main
from dampersim.parameters import at_thesis_segments, default_parameters
from dampersim.studies import STUDIES, run_study, study_cost, study_plan, table_7_1


def test_table_7_1_covers_20_to_300_hz():
    f = sorted(k * rpm / 60 for k, rpm in table_7_1())
    assert f[0] == pytest.approx(20.0) and f[-1] == pytest.approx(300.0)
    assert len(f) == 29


@pytest.fixture(scope="module")
def results():
    return {}


#: the set every study run here but the CLI test's runs on (module docstring)
SYSTEM = at_thesis_segments()


def _run(name, results):
    if name not in results:
        results[name] = run_study(name, SYSTEM, quick=True, executor="serial")
    return results[name]


# "slow" marks tests over about 5 s (pyproject.toml). A study is slow when its quick grid's
# estimated time on SYSTEM (costs) exceeds SLOW_SECONDS. The threshold keeps the two cheapest
# studies, order-rule and additional-orders (4.2 s estimated each; 3.2 to 4.5 s wall, serial,
# with the analysis), in the quick selection, so that it still runs studies end to end; the
# next, poor-performance (8.3 s estimated, 6.3 s wall), is slow. The mapping study is the
# costliest (33 runs, 27.5 s estimated, 13 to 20 s wall). Tests that need a slow study's
# result are marked slow too.
SLOW_SECONDS = 6.0
SLOW_STUDIES = {n for n in STUDIES if study_cost(n, quick=True, system=SYSTEM).seconds() > SLOW_SECONDS}


def _needs(name):
    """The slow mark for a test that needs study ``name``'s result, when that study is slow."""
    return pytest.mark.slow if name in SLOW_STUDIES else (lambda test: test)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_STUDIES else n for n in STUDIES])
def test_study_runs_as_planned_and_is_json(name, results, counter):
    plan = study_plan(name, quick=True, system=SYSTEM)
    cost = study_cost(name, quick=True, system=SYSTEM)
    seen = []
    t0 = time.perf_counter()
    res = run_study(name, SYSTEM, quick=True, executor="serial", progress=lambda d, t, c: seen.append((d, t)))
    wall = time.perf_counter() - t0
    results[name] = res
    json.dumps(res, allow_nan=False)
    assert res["study"] == name and res["points"] > 0
    assert seen and seen[-1][0] == seen[-1][1]
    # the plan's simulations are the study's: none missing, none extra
    assert len(counter.calls) == plan.simulations(), (name, len(counter.calls), plan.simulations())
    assert res["computed"] == plan.total and res["from_cache"] == 0  # a fresh cache: every progress unit computed
    # steps and DOF are whole numbers on both sides: the estimate is exact, up to the
    # rounding of a float sum of a few dozen products below 1e8 (far under 1e-12 relative)
    assert cost.work == pytest.approx(counter.work, rel=1e-12), (name, cost.work, counter.work)
    if name == "additional-orders":
        # it repeats its dominant-only point (progress 6, simulations 5): a repeated point
        # is counted once, as the sweep computes it once
        assert plan.total > plan.simulations()
    print(f"{name}: {plan.simulations()} simulations planned, {len(counter.calls)} run; "
          f"{cost.work:.3e} step·DOF estimated, {counter.work:.3e} run; ~{cost.seconds():.1f} s of one core "
          f"estimated, {wall:.1f} s wall (serial, including the analysis)")


def test_plan_follows_another_parameter_set():
    # the plan counts the set it is given: the default 48/16 segments and SYSTEM's 18/8 run the
    # same grid with other DOF counts. That the counted work is the run's on a set other than
    # the default is test_study_runs_as_planned_and_is_json's check on SYSTEM: a plan that read
    # the default set whatever it was given fails there
    default, other = (study_plan("order-rule", quick=True, system=s) for s in (default_parameters(), SYSTEM))
    assert default.simulations() == other.simulations()
    work = [study_cost("order-rule", quick=True, system=s).work for s in (default_parameters(), SYSTEM)]
    assert work[0] > 1.5 * work[1]  # 48 + 16 segments against 18 + 8: well over half the DOF again


def test_second_run_comes_from_cache(cache_dir):
    run_study("additional-orders", SYSTEM, quick=True, executor="serial")
    again = run_study("additional-orders", SYSTEM, quick=True, executor="serial")
    assert again["from_cache"] == again["points"]


@_needs("order-rule")
def test_order_rule(results):
    r = _run("order-rule", results)["results"]["max_abs_change_pct_by_n"]
    # [thesis] §7.1.1: three dominant orders reproduce the full signal's MR within 1-2 %,
    # the dominant order alone by up to ~10 %. In the quick case (2000 rpm, 415 N m, above
    # the knee) the largest MR change of a primary order is 8.96 % with the dominant order
    # alone on SYSTEM (8.31 % at the default 48/16 segments), 0.75 % with three (0.65 %); the
    # full grid's figures are in docs/thesis-comparison.md. Asserted here: the qualitative
    # ordering.
    assert r["1"] > 8.0
    assert r["1"] > 2 * r["3"]
    # the repeatability run (full signal, amplitudes x (1 + 1e-9)) is reported: stick-slip
    # makes small orders move by up to ~1 % for such a change, the scale below which a
    # replica's MR change means nothing
    rep = _run("order-rule", results)["results"]["max_abs_perturbation_mr_change_pct"]
    assert 0.0 <= rep < 5.0


@_needs("speed-stiffness")
def test_speed_stiffness(results):
    res = _run("speed-stiffness", results)
    assert res["checks"]["stiffening_far_larger_at_5deg"]
    assert res["checks"]["end_segments_stall_at_high_speed"]


@_needs("mapping")
def test_mapping_300_beats_100(results):
    assert _run("mapping", results)["checks"]["amplitude_300_predicts_better_than_100"]


@_needs("poor-performance")
def test_poor_performance_warns_above_validated_speed(results):
    res = _run("poor-performance", results)
    assert any("3000 rpm" in w for w in res["warnings"])
    assert res["checks"]["mr_rises_below_20hz"]


def test_cli_study_json(capsys, tmp_path):
    assert main(["study", "additional-orders", "--quick", "--executor", "serial", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["study"] == "additional-orders"
    assert (tmp_path / "additional-orders.json").exists()


@pytest.mark.slow  # needs every study, the slow ones too
def test_figures_build_for_every_study(results):
    from dampersim.plotting.studies import study_figures

    for name in STUDIES:
        figs = study_figures(_run(name, results))
        assert figs and all(len(f.data) > 0 for f in figs)
