"""Strict identification on the real model: a hidden effect is named, a control is not.

Each campaign is synthesised from a truth that differs from the diagnosed model the way a
rig does (estimated parameters perturbed by up to 3 %, finer springs and step, sensor noise,
channel gain errors and, for the absorber case, a random DAQ chain with skew, hum, offsets,
drift and anti-alias filtering). Nine mapping points of 0.8 s for the absorber, the first eight
for the control, three candidates, torsional points only, the model at three times the library's
step (TIME_STEP). `make test` runs this module in a lane of its own, on one core beside the
rest of the suite (WORKERS); `make test STRICT_TESTS=tests/discrepancy/test_identification.py`
runs it first, alone, with both cores. Its times are in docs/discrepancy.md (Known limits,
"The strict tests' model step" and "The strict tests run first and alone"); at the library's
step, on one core beside the rest of the suite, it took 685 to 713 s (856 s with nine points
for both). These tests are strict: a
change that stops the method naming the absorber as the most probable model with its
magnitude, or that makes it name an effect in a clean campaign, fails here. The full
benchmark lives in bench/bench_discrepancy.py.
"""

import json
import os

import pytest

from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.diagnose import diagnose
from dampersim.discrepancy.effects import NAMES
from dampersim.discrepancy.fitting import CAL_STEP_FRACTIONS, UNCALIBRATED
from dampersim.discrepancy.model_terms import RUNS_PER_POINT
from dampersim.discrepancy.synth import synthesize
from dampersim.parameters import at_thesis_segments, with_updates

POINTS = ["map_900_150", "map_1200_250", "map_1500_150", "map_1800_350", "map_2000_50", "map_1200_500",
          "map_1500_350", "map_1800_150", "map_900_350"]
#: the clean campaign's points: the first eight of POINTS, without map_900_350. Until commit
#: a8d5936 it had all nine (bench_control_misfit.CI_POINTS, which docs/discrepancy.md quotes up
#: to then) and took 987 model runs, the most expensive test of `make test`; on eight it took
#: 629 to 791 over four floating-point paths with the same verdict, and 654 to 754 at TIME_STEP
#: (docs/discrepancy.md, Known limits). The synthesiser orders a campaign by speed, then torque,
#: and seeds each point by its place in that order, so the eight are a new draw, not the nine less one, and the held-out
#: points (every third from the second, CONTROL_HELD_OUT) are other points than the nine's
#: (ABSORBER_HELD_OUT). The absorber campaign keeps nine: on eight, one path preferred a pair of
#: effects, and on six the interval barely held the truth (same section)
CONTROL_POINTS = POINTS[:8]
CONTROL_HELD_OUT = ["map_1200_250", "map_1500_350", "map_2000_50"]
ABSORBER_HELD_OUT = ["map_900_350", "map_1500_150", "map_1800_350"]
CANDIDATES = ["pendulum_absorber", "turbine_drag", "transducer_bandwidth"]
TRUE_INERTIA = 0.002  # [kg m^2] the library's strong absorber


#: Under pytest-xdist (`make test`) this module runs in a process of its own beside the rest of
#: the suite (tests/conftest.py, APART) and takes one core, leaving the other to the rest; run
#: first and alone (Makefile, STRICT_TESTS) its diagnoses take both cores. Every model run is
#: deterministic: the count changes no number.
WORKERS = 1 if os.environ.get("PYTEST_XDIST_WORKER") else 2

#: lower bounds of the clean campaign's held-out and training reduced chi^2, each about half the
#: smallest value it took over four floating-point paths of one machine (held out / training on
#: the eight points with the model at TIME_STEP: host 0.319 / 0.296, numba generic 0.236 / 0.293,
#: numpy without X86_V3 0.319 / 0.309, OpenBLAS Sandybridge 0.220 / 0.365: `python
#: bench/bench_float_paths.py --points 8 --time-step 1/40000 --workers 1`, commit 0005f3a's
#: library). Not near 1: the uncertainties are inflated (the hard benchmark's 22 controls read
#: 0.08 to 2.58 held out, median 0.24, 15 below 0.5; docs/discrepancy.md, "The remaining
#: controls on commit f163644"), and this one campaign's value is a draw that moves with how the
#: machine rounds: its truth runs are chaotic at three of the eight points (their measured orders
#: move by up to 0.8 times the diagnosis's repeatability term with the kernel's machine code), and
#: the diagnosis's own path moves with the float path (654 to 754 model runs over the four
#: paths). At the library's step the bounds were 0.13 and 0.14 (held out 0.261 to 0.314, training
#: 0.283 to 0.322), and on the nine points of commit a8d5936 0.07 and 0.2 (held out 0.148 to
#: 0.321; the held-out bound was 0.3 from commit 0080e51 on, and failed on one machine at 0.148).
#: To first order (the same path, the residuals unchanged) a change that inflates every cell's
#: variance by more than 2.0 (OpenBLAS Sandybridge) to 2.9 times (host) fails the held-out bound,
#: and by more than 2.1 to 2.6 times the training bound, so a doubled sigma (variance times 4)
#: fails on every path measured.
HELD_OUT_CHI2_LOW = 0.11
TRAIN_CHI2_LOW = 0.14

#: the diagnosed model's time step [s]: three times the library's 1/120 000 s. The truth is
#: synthesised at 5e-6 s whatever the model's step (synth.truth_system), so the campaigns are the
#: same data as at 1/120 000 s; what the coarser step adds is model error, which the method must
#: not read as an effect. Over the nine CI points it moves the model's orders against a
#: 1/120 000 s run by at most 1.53 repeatability terms (halving the step: 1.75), 0.39 RMS over the
#: cells (0.46), at most 2.1 % of a point's largest order (2.1 %); those largest changes are at
#: map_1500_150 and map_1800_150, two of the three points (with map_1200_250) whose runs are
#: chaotic and move with any change of the arithmetic. At the six other points it moves them
#: by up to 0.56 terms, about 1.6 times what halving the step gives (0.36; `python
#: bench/bench_ci_step.py`, commit 0005f3a's library). Over four
#: floating-point paths both tests pass with their bounds, in 765 to 786 model runs (absorber)
#: and 654 to 754 (control), each a third of the steps of a run at 1/120 000 s (same section).
#: A step above the checked one warns (AccuracyWarning); here that is the intent
TIME_STEP = 1 / 40000

#: the diagnosed model at the thesis's 18/8 segments (the truth then has 24/10) and TIME_STEP: the
#: method is what is tested, and these counts halve the run time against the default 48/16
BASE = with_updates(at_thesis_segments(), {"solver.time_step": TIME_STEP})

pytestmark = pytest.mark.filterwarnings("ignore::dampersim.errors.AccuracyWarning")


def _diagnosis(tmp_path_factory, name, effects, points, daq=None):
    d = tmp_path_factory.mktemp(name)
    synthesize(d / "c", effects=effects, perturb=0.03, seed=3, truth=d / "truth.json", points=points, record=0.8,
               daq=daq, base=BASE, workers=WORKERS)  # seeded per point: any worker count gives the same
    return diagnose(read_campaign(d / "c"), BASE, workers=WORKERS, candidates=CANDIDATES, calibration_iterations=3,
                    shortlist=2, recommend=False)


@pytest.fixture(scope="module")
def absorber(tmp_path_factory):
    return _diagnosis(tmp_path_factory, "absorber", [("pendulum_absorber", {"inertia": TRUE_INERTIA})], POINTS,
                      daq="random")


@pytest.fixture(scope="module")
def control(tmp_path_factory):
    return _diagnosis(tmp_path_factory, "control", [], CONTROL_POINTS)


@pytest.mark.slow
def test_a_hidden_absorber_is_named_with_its_magnitude(absorber):
    d = absorber
    lk = d.likelihood
    # named: the most probable model, decisively, with the truth inside its 90 % interval and
    # the estimate within 15 % (perturbation, discretisation and the DAQ chain move it)
    assert lk["model"] == "pendulum_absorber" and d.posterior["pendulum_absorber"] >= 0.9, d.message
    fitted = d.effects[0]
    assert fitted["name"] == "pendulum_absorber"
    lo, hi = fitted["intervals"]["inertia"]
    assert lo <= TRUE_INERTIA <= hi, fitted
    assert fitted["parameters"]["inertia"] == pytest.approx(TRUE_INERTIA, rel=0.15)
    # the interval is the wider of the Laplace one and the points' jackknife (intervals.py):
    # the diagnosis reports their ratio, and the jackknife's with the noise alone, for every
    # fitted parameter of the effect
    for key in ("interval_spread", "interval_spread_noise"):
        spread = lk[key]["pendulum_absorber"]
        assert set(spread) == {"inertia", "order", "damping"} and all(v > 0 for v in spread.values()), (key, spread)
    # the held-out misfit falls by at least 70 % against the calibrated model's
    assert lk["reduced_chi2_held_out"] <= 0.3 * lk["reduced_chi2_held_out_calibrated"]
    # the verdict: with the absorber fitted, this campaign's points at 900 rpm keep a misfit
    # (point reduced chi^2 26 at 350 N m, just above the knee, and 5 at 150 N m,
    # `python bench/bench_control_misfit.py --case ci-absorber`, commit 8a55a67; 11 and 7 at
    # 900 and 1500 rpm, 350 N m, before the term for what the calibration cannot follow; near
    # the knee the model's own segment convergence is slowest, docs/model.md §12), above the
    # noise level, and the verdict can be
    # "unexplained"; it is never another effect, and the adopted effect is the absorber
    # whenever the verdict is "missing_effect"
    assert d.verdict in ("missing_effect", "unexplained")
    assert d.effect in (None, "pendulum_absorber") and (d.verdict == "unexplained") == (d.effect is None)
    # the absorber's first fit leaves the training and the held-out points at the noise level, so
    # its re-calibration (naming.Namer.refit, docs/discrepancy.md Naming 3b) does not run here and
    # the run bound below needs none of its runs
    assert lk["recalibrated"] is None, lk["recalibrated"]
    # each candidate is fitted from one start when its screen is clear: 684 runs on commit
    # 19acb87 against 876 when both starts were fitted (docs/discrepancy.md, Known limits);
    # since then every point also runs with its input moved up and down (the input channel's
    # uncertainty) and with the set moved up and down along each of the three directions the
    # calibration cannot follow (fitting.UNCALIBRATED), 8 runs more per point: 750 runs here
    # (`python bench/bench_control_misfit.py --case ci-absorber`, commit 8a55a67) and 771 in
    # the control campaign (`--case ci-control --daq none`, commit 341837a); neither calibration needed the
    # second derivative step (fitting.CAL_DERIVATIVE_STEPS), whose runs this bound leaves out. With "none"
    # run at the factors each fit found (naming.Namer.recalibrate) the same commands give 756 and 777 runs
    # (commit b14cbb4). Since the model terms are measured again at the calibrated factors
    # (model_terms.RUNS_PER_POINT per point) with one Gauss-Newton step under them (up to three
    # trials on the training points and one held-out check) this campaign took 792; with the model
    # at TIME_STEP 765 to 786 over four floating-point paths (874 allowed); the bound is this
    # campaign's
    train, held = len(POINTS) - len(POINTS[1::3]), len(POINTS[1::3])
    recheck = RUNS_PER_POINT * len(POINTS) + len(CAL_STEP_FRACTIONS) * train + held
    assert d.simulations <= 700 + (2 + 2 * len(UNCALIBRATED)) * len(POINTS) + recheck


@pytest.mark.slow
def test_a_clean_campaign_names_nothing(control):
    d = control
    assert d.verdict == "no_missing_effect", d.message
    assert d.effect is None and d.effects == []
    assert max(v for k, v in d.posterior.items() if k != "none") < 0.5
    # not optimistic: the held-out misfit within the noise level; not inflated beyond what the
    # float paths read (HELD_OUT_CHI2_LOW says why the bounds are not 1 or 0.5)
    assert HELD_OUT_CHI2_LOW <= d.likelihood["reduced_chi2_held_out"] <= d.likelihood["noise_level"]
    assert d.likelihood["reduced_chi2_train"] >= TRAIN_CHI2_LOW
    # the leading fit leaves neither set above the noise level: no re-calibration (Naming 3b)
    assert d.likelihood["recalibrated"] is None, d.likelihood["recalibrated"]


@pytest.mark.slow
def test_the_diagnosis_document_carries_the_whole_contract(absorber, control):
    for d, points in ((absorber, POINTS), (control, CONTROL_POINTS)):
        doc = json.loads(json.dumps(d.to_json(), default=float))
        assert {"posterior", "effects", "detectability", "recommended_points", "outliers", "likelihood", "problems",
                "effect", "verdict", "ranking"} <= set(doc)
        assert set(NAMES) | {"none"} <= set(doc["posterior"])
        assert sum(doc["posterior"].values()) == pytest.approx(1.0)
        assert set(doc["detectability"]) == set(NAMES)
        assert doc["recommended_points"] == []  # recommend=False
        assert set(doc["outliers"]) <= set(points)
    # every third point from the second of the campaign's order (speed, then torque) is held out,
    # and no held-out run failed
    assert absorber.held_out_points == ABSORBER_HELD_OUT and control.held_out_points == CONTROL_HELD_OUT
    for d in (absorber, control):
        assert d.gap_before_nm > 0 and d.noise_floor_nm > 0
        assert [r["effect"] for r in d.ranking if r["gap_held_out_nm"] is not None]  # fitted candidates
    # the absorber is detectable with this campaign, well below the strong magnitude hidden in it
    thr = absorber.detectability["pendulum_absorber"]
    assert thr is not None and thr < TRUE_INERTIA
