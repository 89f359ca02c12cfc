"""The discrepancy benchmark: its figures from hand-written JSON lines, its case matrix,
its truths and its resumable output (no diagnosis is run)."""

import json

import numpy as np
import pytest

from dampersim.discrepancy import benchmark as B
from dampersim.discrepancy import truths
from dampersim.discrepancy.effects import EFFECTS, NAMES, parameters_of
from dampersim.discrepancy.synth import truth_system
from dampersim.errors import InputError
from dampersim.parameters import default_parameters
from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_discrepancy")


def truth(*effects):
    return {"effects": [{"name": n, "parameters": p} for n, p in effects]}


ROWS = [
    # beyond the estimate, top-1 right by posterior, magnitude inside the interval
    {"id": "e1", "kind": "effect", "truth": truth(("pendulum_absorber", {"inertia": 0.002, "order": 2.1})),
     "detectability": {"pendulum_absorber": 0.0008}, "posterior": {"none": 0.05, "pendulum_absorber": 0.9,
                                                                   "turbine_drag": 0.05},
     "verdict": "missing_effect", "effect": "pendulum_absorber",
     "effects": [{"name": "pendulum_absorber", "parameters": {"inertia": 0.0019},
                  "intervals": {"inertia": [0.0017, 0.0021]}}]},
    # capacity falls as the clutch effect grows: 470 below a 540 threshold is beyond it;
    # top-1 wrong, nothing adopted
    {"id": "e2", "kind": "effect", "truth": truth(("clutch_slip", {"capacity": 470.0})),
     "detectability": {"clutch_slip": 540.0}, "posterior": {"none": 0.3, "turbine_drag": 0.7},
     "verdict": "unexplained", "effect": None, "effects": []},
    # below the estimate, detected anyway (present at 0.7 + 0.22 = 0.92 over two models) and adopted
    {"id": "e3", "kind": "effect", "truth": truth(("pendulum_absorber", {"inertia": 0.0005})),
     "detectability": {"pendulum_absorber": 0.001},
     "posterior": {"none": 0.08, "pendulum_absorber": 0.7, "pendulum_absorber+turbine_drag": 0.22},
     "verdict": "missing_effect", "effect": "pendulum_absorber",
     "effects": [{"name": "pendulum_absorber", "parameters": {}, "intervals": {}}]},
    # below the estimate (cut-off 600 Hz above a 400 Hz threshold), not named
    {"id": "e4", "kind": "effect", "truth": truth(("transducer_bandwidth", {"cutoff": 600.0})),
     "detectability": {"transducer_bandwidth": 400.0}, "posterior": {"none": 0.99}, "verdict": "no_missing_effect",
     "effect": None, "effects": []},
    # no estimate (a diagnosis from before detectability): counted apart; named by `effect`
    {"id": "e5", "kind": "effect", "truth": truth(("spring_preload", {"force": 30.0})), "verdict": "missing_effect",
     "effect": "spring_preload"},
    # beyond, named, but the interval misses the true value
    {"id": "e6", "kind": "effect", "truth": truth(("turbine_drag", {"coefficient": 6.0})),
     "detectability": {"turbine_drag": 2.0}, "posterior": {"none": 0.0, "turbine_drag": 1.0}, "verdict": "missing_effect",
     "effect": "turbine_drag",
     "effects": [{"name": "turbine_drag", "parameters": {"coefficient": 4.0}, "intervals": {"coefficient": [3.5, 4.5]}}]},
    # beyond, the most probable model is right and its interval holds the truth, but the
    # verdict is unexplained: top-1, not adopted (``effects`` describes the top model anyway)
    {"id": "e7", "kind": "effect", "truth": truth(("pendulum_absorber", {"inertia": 0.002})),
     "detectability": {"pendulum_absorber": 0.0008}, "posterior": {"none": 0.0, "pendulum_absorber": 0.9996},
     "verdict": "unexplained", "effect": None,
     "effects": [{"name": "pendulum_absorber", "parameters": {}, "intervals": {"inertia": [0.0015, 0.0021]}}]},
    # controls: a clean one, a false claim, one without a posterior (old diagnosis)
    {"id": "c1", "kind": "control", "truth": truth(), "posterior": {"none": 0.95, "turbine_drag": 0.05},
     "effect": None, "likelihood": {"reduced_chi2_held_out": 1.1, "reduced_chi2_train": 0.9}},
    {"id": "c2", "kind": "control", "truth": truth(), "posterior": {"none": 0.05, "turbine_drag": 0.93},
     "verdict": "missing_effect", "effect": "turbine_drag", "likelihood": {"reduced_chi2_held_out": 3.0, "reduced_chi2_train": 1.2}},
    {"id": "c3", "kind": "control", "truth": truth(), "effect": None, "likelihood": {"reduced_chi2_held_out": 2.0}},
    # out of library: a pair claimed at 0.91, and a clean one
    {"id": "o1", "kind": "out_of_library", "truth": truth(), "posterior": {"none": 0.09, "clutch_slip+turbine_drag": 0.91},
     "verdict": "missing_effect", "effect": "clutch_slip", "effects": [{"name": "clutch_slip"}, {"name": "turbine_drag"}]},
    {"id": "o2", "kind": "out_of_library", "truth": truth(), "posterior": {"none": 0.6, "spring_preload": 0.4}},
    # pairs: both adopted; both as the top model (other order); one only
    {"id": "p1", "kind": "pair", "truth": truth(("turbine_drag", {"coefficient": 3.0}), ("spring_preload", {"force": 15.0})),
     "verdict": "missing_effect", "effects": [{"name": "spring_preload"}, {"name": "turbine_drag"}]},
    {"id": "p2", "kind": "pair", "truth": truth(("clutch_slip", {"capacity": 540.0}), ("pendulum_absorber", {"inertia": 0.001})),
     "posterior": {"none": 0.1, "pendulum_absorber+clutch_slip": 0.6, "clutch_slip": 0.3}, "verdict": "unexplained",
     "effects": []},
    {"id": "p3", "kind": "pair", "truth": truth(("output_backlash", {"free_play": 0.03}),
                                                ("nested_radial_transfer", {"fraction": 0.6})),
     "verdict": "missing_effect", "effect": "nested_radial_transfer"},
    # a case that failed, then succeeded on --resume (the success counts), and one that only failed
    {"id": "c4", "kind": "control", "error": "RuntimeError: boom"},
    {"id": "c4", "kind": "control", "truth": truth(), "posterior": {"none": 1.0}, "likelihood": {"reduced_chi2_held_out": 0.5}},
    {"id": "x1", "kind": "effect", "error": "SimulationDiverged: nan"},
]


def lines(rows):
    return [json.loads(json.dumps(r)) for r in rows]  # through JSON, as read from the file


def test_summary_figures_from_hand_written_lines():
    s = B.summary(lines(ROWS))
    assert s["counts"] == {"effect": 7, "pair": 3, "control": 4, "out_of_library": 2}
    assert s["failed"] == 1 and s["rows"] == 16
    eb = s["effect_beyond"]
    assert (eb["top1_correct"]["count"], eb["top1_correct"]["of"]) == (3, 4)  # e1, e6, e7 right; e2 wrong
    assert eb["named_correct"]["count"] == 2  # e1, e6 (e7 is unexplained)
    assert (eb["magnitude_in_90_interval"]["count"], eb["magnitude_in_90_interval"]["of"]) == (2, 4)  # e1, e7
    assert s["effect_below"]["detected"] == {"count": 1, "of": 2, "share": 0.5}  # e3 yes, e4 no
    assert s["effect_below"]["named_correct"]["count"] == 1
    assert B.probability(ROWS[2], "pendulum_absorber") == pytest.approx(0.92)
    assert s["effect_no_estimate"]["named_correct"] == {"count": 1, "of": 1, "share": 1.0}
    # false claims: c2 of the three controls with a posterior (c3 has none); any adopted: c2
    assert s["control"]["claimed_p90"] == {"count": 1, "of": 3, "share": pytest.approx(1 / 3)}
    assert s["control"]["named_any"]["count"] == 1 and s["control"]["named_any"]["of"] == 4
    chi = s["control"]["reduced_chi2_held_out"]
    assert (chi["median"], chi["min"], chi["max"], chi["of"]) == (1.55, 0.5, 3.0, 4)
    assert s["control"]["reduced_chi2_train"]["of"] == 2
    # the range, ends included: c1 (1.1) and c4 (0.5) in it, c2 (3.0) and c3 (2.0) above
    assert B.CONTROL_CHI2_RANGE == (0.5, 1.5)
    assert s["control"]["reduced_chi2_held_out_within"] == {"count": 2, "of": 4, "share": 0.5}
    assert s["control"]["reduced_chi2_held_out_below"]["count"] == 0
    assert s["control"]["reduced_chi2_held_out_above"]["count"] == 2
    assert s["out_of_library"]["claimed_p90"] == {"count": 1, "of": 2, "share": 0.5}
    assert s["pair"]["both_named"] == {"count": 2, "of": 3, "share": pytest.approx(2 / 3)}
    assert s["pair"]["one_named"]["count"] == 3
    table = B.summary_table(s)
    assert "top-1 correct" in table and "3/4" in table and "median 1.55" in table
    assert "reduced chi2 held out within 0.5-1.5" in table


def test_summary_of_rows_without_the_new_diagnosis_keys():
    old = [{"id": "a", "kind": "control", "truth": truth(), "verdict": "no_missing_effect", "effect": None},
           {"id": "b", "kind": "effect", "truth": truth(("turbine_drag", {"coefficient": 3.0})),
            "verdict": "missing_effect", "effect": "turbine_drag"}]
    s = B.summary(old)
    assert s["control"]["claimed_p90"]["of"] == 0 and s["control"]["claimed_p90"]["share"] is None
    assert s["effect_no_estimate"]["top1_correct"]["count"] == 1
    assert "-" in B.summary_table(s)
    assert B.summary([])["counts"]["effect"] == 0


def test_beyond_means_below_the_threshold_for_capacity_and_cutoff():
    assert not EFFECTS["clutch_slip"].grows and not EFFECTS["transducer_bandwidth"].grows
    assert B.side("clutch_slip", 470.0, 540.0) == "beyond" and B.side("clutch_slip", 620.0, 540.0) == "below"
    assert B.side("transducer_bandwidth", 150.0, 300.0) == "beyond"
    assert B.side("turbine_drag", 6.0, 3.0) == "beyond" and B.side("turbine_drag", 1.5, 3.0) == "below"
    assert B.side("turbine_drag", 1.5, None) == "unknown"
    assert B.side("turbine_drag", 1.5, "620") == B.side("turbine_drag", 1.5, float("nan")) == "unknown"


def test_truth_shape_ranges_lie_inside_the_library_bounds_and_draws_inside_them():
    rng = np.random.default_rng(0)
    for name, ranges in truths.SHAPE_RANGES.items():
        bounds = {p["name"]: p for p in parameters_of(name)}
        for par, (lo, hi) in ranges.items():
            assert bounds[par]["min"] <= lo < hi <= bounds[par]["max"], (name, par)
            assert par != EFFECTS[name].magnitude
        for _ in range(50):
            for par, v in truths.random_shape(name, rng).items():
                assert ranges[par][0] <= v <= ranges[par][1]
    assert truths.random_shape("turbine_drag", rng) == {}


def test_magnitude_levels():
    for name in NAMES:
        e = EFFECTS[name]
        mags = [truths.magnitude_at(name, lv) for lv in truths.LEVELS]
        assert mags[1:] == list(e.magnitudes)
        # subtle is weaker than weak in the effect's own direction
        assert (mags[0] < mags[1]) if e.grows else (mags[0] > mags[1])
    assert truths.magnitude_at("pendulum_absorber", "subtle") == 0.00025
    with pytest.raises(InputError):
        truths.magnitude_at("pendulum_absorber", "huge")


def test_truths_build_valid_parameter_sets():
    base = default_parameters()
    rng = np.random.default_rng(3)
    specs = [truths.single(n, "strong", rng) for n in NAMES] + [truths.pair(a, b, rng) for a, b in truths.PAIRS]
    specs += [truths.out_of_library(k, rng) for k in truths.OUT_OF_LIBRARY for _ in range(3)]
    specs += [truths.control(k, rng) for k in truths.CONTROLS for _ in range(3)]
    for spec in specs:
        system, applied = truth_system(base, [tuple(e) for e in spec["effects"]], 0.0, rng, spec["updates"])
        for n, values in spec["effects"]:
            for par, v in values.items():
                assert getattr(getattr(system.effects, n), par) == v
        for k, v in spec["updates"].items():
            assert applied[k] == v
    shaft = truths.out_of_library("rig_shaft", rng)["updates"]["rig.elements.gearbox.shaft_stiffness"]
    assert 0.2 <= abs(shaft / 10500.0 - 1.0) <= 0.3
    shape = truths.out_of_library("friction_shape", rng)["updates"]
    assert shape and all(k.startswith("friction.gamma") for k in shape)
    with pytest.raises(InputError):
        truths.out_of_library("weather", rng)
    with pytest.raises(InputError):
        truths.pair("turbine_drag", "turbine_drag", rng)


def test_the_hard_matrix(bench):
    cases = bench.hard_cases()
    assert cases == bench.hard_cases()  # reproducible
    kinds = [c["kind"] for c in cases]
    assert kinds.count("control") >= 20 and kinds.count("out_of_library") >= 10 and kinds.count("pair") >= 6
    assert len({c["id"] for c in cases}) == len(cases)
    eff = [c for c in cases if c["kind"] == "effect"]
    assert {c["level"] for c in eff} == set(truths.LEVELS) and {c["group"] for c in eff} == set(NAMES)
    assert all(c["daq"] == "random" for c in cases)
    absorbers = [c["spec"]["effects"][0][1] for c in eff if c["group"] == "pendulum_absorber"]
    assert len({a["order"] for a in absorbers}) == len(absorbers)  # random shapes
    assert set(kinds[:17]) == {"effect", "pair", "control", "out_of_library"}  # interleaved: one of each group first
    ids = bench.point_ids(6, 1)
    assert len(ids) == 7 and ids[-1] == "ramp_1500" and not any(i.startswith("ramp") for i in ids[:-1])
    classic = bench.classic_cases()
    assert len(classic) == 82 and all(c["daq"] is None for c in classic)
    assert [c["id"] for c in bench.selected(classic, ["miscalibration"])] == [f"classic/miscalibration/{i}" for i in range(5)]
    assert {c["group"] for c in bench.selected(cases, ["out_of_library"])} == {k for k, _ in bench.HARD_OUT_OF_LIBRARY}


def test_each_case_is_written_at_once_and_resume_skips_it(bench, tmp_path, monkeypatch, capsys):
    ran = []

    def fake_run(case, n_points, record, ramps, workers, recommend, inputs_dir=None):
        ran.append(case["id"])
        if len(ran) == 2:
            raise RuntimeError("diverged")
        return {"id": case["id"], "kind": case["kind"], "truth": {"effects": []}, "verdict": "no_missing_effect"}

    monkeypatch.setattr(bench, "run_case", fake_run)
    out = tmp_path / "b.jsonl"
    bench.main(["--only", "control", "--limit", "3", "--out", str(out)])
    rows = bench.read_lines(out)
    assert [r["id"] for r in rows] == ran and "error" in rows[1] and len(rows) == 3
    with pytest.raises(SystemExit):  # an existing file is never overwritten
        bench.main(["--only", "control", "--limit", "3", "--out", str(out)])
    with open(out, "a") as fh:
        fh.write('{"id": "torn')  # a run killed while writing
    ran.clear()
    bench.main(["--only", "control", "--limit", "2", "--out", str(out), "--resume"])
    assert ran[0] == rows[1]["id"]  # the failed case is tried again, the finished ones are not
    rows = bench.read_lines(out)
    assert len(rows) == 5 and "controls" in capsys.readouterr().out


def test_the_summary_of_several_files_counts_each_case_once(bench, tmp_path, capsys):
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    first = {"id": "c1", "kind": "control", "truth": truth(), "posterior": {"none": 0.05, "turbine_drag": 0.95},
             "likelihood": {"reduced_chi2_held_out": 0.2}}
    again = dict(first, posterior={"none": 0.9, "turbine_drag": 0.1}, likelihood={"reduced_chi2_held_out": 0.8})
    other = {"id": "c2", "kind": "control", "truth": truth(), "posterior": {"none": 1.0},
             "likelihood": {"reduced_chi2_held_out": 2.0}}
    a.write_text(json.dumps(first) + "\n" + json.dumps(other) + "\n")
    b.write_text(json.dumps(again) + "\n")
    assert bench.main(["--summary", str(a), str(b)]) == 0
    values = {line[:58].strip(): line[58:].strip() for line in capsys.readouterr().out.splitlines()}
    # c1 counts once, by its later line (b): no claim, in range; c2 above the range
    assert values["controls: a named model at posterior >= 0.9"].startswith("0/2")
    assert values["controls: reduced chi2 held out within 0.5-1.5"].startswith("1/2")
    assert values["controls: reduced chi2 held out above 1.5"].startswith("1/2")
    with pytest.raises(SystemExit):  # a missing file is an error, not an empty benchmark
        bench.main(["--summary", str(a), str(tmp_path / "nope.jsonl")])
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # nor is a folder
        bench.main(["--summary", str(tmp_path)])


def test_the_controls_chi2_range_includes_both_ends():
    rows = [{"id": f"c{i}", "kind": "control", "truth": truth(), "likelihood": {"reduced_chi2_held_out": v}}
            for i, v in enumerate([0.49, 0.5, 1.0, 1.5, 1.51, float("nan"), None])]
    rows += [{"id": "cs", "kind": "control", "truth": truth(), "likelihood": {"reduced_chi2_held_out": "1.0"}},
             {"id": "cb", "kind": "control", "truth": truth(), "likelihood": {"reduced_chi2_held_out": True}}]
    c = B.summary(lines(rows))["control"]
    # NaN, None, a string and a bool are no figure: five values, 0.5 and 1.5 inside
    assert c["reduced_chi2_held_out_within"] == {"count": 3, "of": 5, "share": 0.6}
    assert c["reduced_chi2_held_out_below"]["count"] == 1 and c["reduced_chi2_held_out_above"]["count"] == 1


def test_the_posterior_without_the_misfit_takes_its_gain_off_none():
    # log evidences that already carry a 2-nat misfit gain on "none", equal priors on the
    # two effects: with the gain e^0 : e^-1 : e^-1 ... without it e^-2 : e^-1 : e^-1
    like = {"log_evidence": {"none": 0.0, "turbine_drag": -1.0, "output_backlash+turbine_drag": -1.0},
            "model_prior": {"none": 0.5, "turbine_drag": 0.25, "output_backlash+turbine_drag": 0.25},
            "unnamed_misfit": {"torsional": 1.5, "ramps": 0.5, "log_evidence": 2.0}}
    post = B.posterior_without_misfit({"likelihood": like})
    w_none, w_eff = 0.5 * np.exp(-2.0), 0.25 * np.exp(-1.0)
    assert post["none"] == pytest.approx(w_none / (w_none + 2 * w_eff), rel=1e-12)
    assert post["turbine_drag"] == pytest.approx(post["output_backlash+turbine_drag"], rel=1e-12)
    assert sum(post.values()) == pytest.approx(1.0, rel=1e-12)
    # a zero gain gives the posterior the evidences and priors give with the misfit
    same = B.posterior_without_misfit({"likelihood": dict(like, unnamed_misfit={"log_evidence": 0.0})})
    assert same["none"] == pytest.approx(0.5 / (0.5 + 2 * 0.25 * np.exp(-1.0)), rel=1e-12)
    # a model without a finite evidence (written as null) or with a zero prior gets 0
    odd = B.posterior_without_misfit({"likelihood": dict(
        like, log_evidence=dict(like["log_evidence"], clutch_slip=None, spring_preload=5.0),
        model_prior=dict(like["model_prior"], clutch_slip=0.1, spring_preload=0.0))})
    assert odd["clutch_slip"] == odd["spring_preload"] == 0.0 and odd["none"] == pytest.approx(post["none"])
    # no such posterior: rows from before the misfit (no key), from its first form (one gain per
    # model, no top-level evidences), without a finite evidence of "none", or without priors
    assert B.posterior_without_misfit({"likelihood": {k: v for k, v in like.items() if k != "unnamed_misfit"}}) is None
    first_form = {"unnamed_misfit": {"none": {"torsional": 1.0, "ramps": 0.5}}}
    assert B.posterior_without_misfit({"likelihood": first_form}) is None
    no_none = dict(like, log_evidence=dict(like["log_evidence"], none=None))
    assert B.posterior_without_misfit({"likelihood": no_none}) is None
    assert B.posterior_without_misfit({"likelihood": dict(like, model_prior=None)}) is None
    assert B.posterior_without_misfit({}) is None


def test_a_case_row_gives_the_verdict_posteriors_fit_and_side(bench, tmp_path, capsys):
    row = dict(ROWS[0], truth=dict(ROWS[0]["truth"], description="pendulum absorber (typical)"), simulations=1500,
               posterior={"none": 0.08, "pendulum_absorber": 0.9, "turbine_drag": 0.02},
               wall_time_s=1234.4, likelihood={
                   "reduced_chi2_held_out": 0.9, "reduced_chi2_held_out_calibrated": 4.25,
                   "reduced_chi2_train": 1.1, "learning_rate": 1.0,
                   "log_evidence": {"none": 0.0, "pendulum_absorber": 3.0, "turbine_drag": -1.0},
                   "model_prior": {"none": 0.5, "pendulum_absorber": 0.25, "turbine_drag": 0.25},
                   "unnamed_misfit": {"torsional": 0.75, "ramps": 0.5, "log_evidence": 1.0}})
    cells = [c.strip() for c in B.case_row(lines([row])[0]).strip("|").split("|")]
    header = [c.strip() for c in B.CASE_TABLE_HEADER.splitlines()[0].strip("|").split("|")]
    assert len(cells) == len(header) == 13
    assert cells[:3] == ["e1", "pendulum absorber (typical)", "`missing_effect`"]
    assert cells[3] == "pendulum_absorber 0.900; none 0.080"
    # "none" loses its 1-nat gain: 0.5 e^-1 : 0.25 e^3 : 0.25 e^-1
    assert cells[4] == "pendulum_absorber 0.948; none 0.035"
    assert cells[5] == "+0.75, +0.50 → +1.00"
    assert cells[6:9] == ["4.25 → 0.90", "1.10", "1.00"]
    assert cells[9] == "pendulum_absorber inertia 0.0019 [0.0017, 0.0021]"
    assert cells[10] == "0.0008 (beyond)" and cells[11:] == ["1500", "1234"]
    # a control: no fitted effect, no misfit, no detectability side; figures it lacks read "—"
    ctl = [c.strip() for c in B.case_row(ROWS[7]).strip("|").split("|")]  # c1
    assert ctl[0] == "c1" and ctl[2] == "—"
    assert ctl[4:] == ["—", "—", "— → 1.10", "0.90", "—", "—", "—", "—", "—"]
    # null figures, an unknown effect and a "|" in a description do not break the row
    odd = dict(row, simulations=None, posterior={"none": None}, effects=[{"name": "zzz"}],
               truth=dict(row["truth"], description="a | b"))
    cells = B.case_row(lines([odd])[0])
    assert "a \\| b" in cells and "None" not in cells and cells.count(" | ") == 12
    path = tmp_path / "rows.jsonl"
    path.write_text(json.dumps(row) + "\n" + json.dumps(ROWS[-1]) + "\n")  # the failed case gives no row
    assert bench.main(["--rows", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == B.CASE_TABLE_HEADER.splitlines()[0] and len(out) == 3 and out[2].startswith("| e1 |")
