"""bench/bench_float_paths.py's reading (docs/discrepancy.md, Known limits, quotes it): how far a
variant's measured orders lie from the host's, in the host's repeatability term; its variants'
environments; and the machine a benchmark result line records."""

import pytest

from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_float_paths")


def _doc(coef, sigma):
    return {"coef": {pid: [[c.real for c in v], [c.imag for c in v]] for pid, v in coef.items()},
            "sigma": sigma}


def test_the_spread_is_the_largest_change_in_repeatabilities(bench):
    ref = _doc({"a": [1 + 1j, 2 + 0j], "b": [3j, 4 + 0j]}, {"a": [0.5, 2.0], "b": [1.0, 1.0]})
    # a: order 1 moves by |0.3 + 0.4j| = 0.5 against sigma 0.5 (1.0), order 2 by 1 against 2 (0.5)
    other = _doc({"a": [1.3 + 1.4j, 3 + 0j], "b": [3j, 4 + 0j]}, {"a": [9.0, 9.0], "b": [9.0, 9.0]})
    moved = bench.spread(ref, other)
    assert moved["a"] == pytest.approx(1.0, rel=1e-12)  # the host's sigma, not the variant's
    assert moved["b"] == 0.0
    assert bench.spread(ref, ref) == {"a": 0.0, "b": 0.0}


def test_the_variants_change_only_how_the_arithmetic_runs(bench):
    # every variant is the host's environment with one compile or dispatch setting, never a
    # parameter of the model or of the diagnosis, and the benchmark's result lines record each
    allowed = set(load_bench("bench_discrepancy").FLOAT_PATH_ENV)
    assert bench.VARIANTS["host"] == {}
    assert all(set(env) <= allowed and len(env) == 1 for name, env in bench.VARIANTS.items() if name != "host")


def test_a_variant_drops_the_caller_s_float_path_settings(bench):
    # "host" must be the host even where the caller's shell sets a float-path variable, and a
    # variant must carry its own setting alone
    caller = {"PATH": "/bin", "NUMBA_CPU_NAME": "skylake", "OPENBLAS_CORETYPE": "Haswell", "NUMBA_OPT": "1"}
    assert bench.variant_env("host", caller) == {"PATH": "/bin"}
    assert bench.variant_env("numpy-v2", caller) == {"PATH": "/bin", "NPY_DISABLE_CPU_FEATURES": "X86_V3"}


def test_a_result_line_records_the_float_path(monkeypatch):
    b = load_bench("bench_discrepancy")
    for k in b.FLOAT_PATH_ENV:
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    m = b.machine()
    assert m["env"] == {"NUMBA_CPU_NAME": "generic"}  # only the settings that are set
    assert {"numpy", "scipy", "numba", "llvmlite", "cpu", "numpy_cpu", "blas"} <= set(m)


def test_the_benches_ci_points_are_the_strict_tests_campaigns(bench, monkeypatch, capsys):
    # `--points 8` must diagnose what the strict clean test of tests/discrepancy/test_identification.py
    # diagnoses, and the default (the absorber test's) the nine the docs quote up to commit a8d5936
    import argparse
    import json

    from tests.discrepancy import test_identification as T

    m = bench.M
    assert m.CI_POINTS[:m.CI_CONTROL_POINTS] == T.CONTROL_POINTS and m.CI_POINTS == T.POINTS
    assert m.CI_CANDIDATES == T.CANDIDATES
    ap = argparse.ArgumentParser()
    m.add_ci_points(ap)
    assert ap.parse_args([]).points == 9 and ap.parse_args(["--points", "8"]).points == 8
    for bad in ("2", "10", "x"):
        with pytest.raises(SystemExit):
            ap.parse_args(["--points", bad])
    # the parent hands the count to the process that synthesises and diagnoses
    seen = []

    def run(argv, env, check):
        seen.append(argv)
        doc = {"verdict": "no_missing_effect", "none": 1.0, "absorber": 0.0, "inertia": None, "interval": None,
               "held_out_calibrated": 0.3, "held_out": 0.3, "train": 0.3, "noise_level": 1.5, "runs": 1, "wall_s": 1.0,
               "machine": {"env": {}, "cpu": {"name": "x"}, "numpy_cpu": [], "blas": {}}, "time_step": 1 / 120000,
               "coef": {"p": [[1.0], [0.0]]}, "sigma": {"p": [1.0]}}
        with open(argv[argv.index("--worker") + 1], "w") as f:
            json.dump(doc, f)

    monkeypatch.setattr(bench.subprocess, "run", run)
    bench.main(["--points", "8", "--variants", "host"])
    assert len(seen) == 1 and seen[0][seen[0].index("--points") + 1] == "8"
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["points"] == 8


def test_the_worker_process_diagnoses_the_points_it_is_given(bench, monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(bench, "worker", lambda *a: calls.append(a))
    bench.main(["--worker", str(tmp_path / "o.json"), "--case", "ci-absorber", "--workers", "1", "--points", "8"])
    bench.main(["--worker", str(tmp_path / "o.json"), "--case", "ci-control", "--workers", "1", "--time-step",
                "1/40000"])
    assert calls == [(str(tmp_path / "o.json"), "ci-absorber", 1, 8, None),
                     (str(tmp_path / "o.json"), "ci-control", 1, 9, 2.5e-5)]


def test_the_benches_model_step_is_the_strict_tests(bench, monkeypatch):
    # `--time-step 1/40000` must diagnose with the strict tests' model, the default with the
    # parameter set's step (the strict tests' up to commit 0005f3a, which the docs quote until then)
    import argparse

    from dampersim.parameters import at_thesis_segments
    from tests.discrepancy import test_identification as T

    m = bench.M
    assert m.CI_TIME_STEP == T.TIME_STEP == T.BASE.solver.time_step
    assert m.ci_base(m.CI_TIME_STEP) == T.BASE and m.ci_base() == at_thesis_segments()
    ap = argparse.ArgumentParser()
    m.add_ci_time_step(ap)
    assert ap.parse_args([]).time_step is None
    assert ap.parse_args(["--time-step", "1/40000"]).time_step == 1 / 40000
    assert ap.parse_args(["--time-step", "2.5e-5"]).time_step == 2.5e-5
    for bad in ("0", "-1e-5", "1/0", "x", "nan", "inf", "1/"):
        with pytest.raises(SystemExit):
            ap.parse_args(["--time-step", bad])
    # the parent hands the step to the process that synthesises and diagnoses, exactly
    seen = []
    monkeypatch.setattr(bench.subprocess, "run", lambda argv, env, check: seen.append(argv) or 1 / 0)
    with pytest.raises(ZeroDivisionError):
        bench.main(["--time-step", "1/40000", "--variants", "host"])
    assert float(seen[0][seen[0].index("--time-step") + 1]) == 1 / 40000


class _Stop(Exception):
    pass


def test_the_benches_diagnose_with_the_step_they_are_given(bench, monkeypatch, tmp_path):
    # the campaign is synthesised and diagnosed with the model at --time-step in the worker of
    # bench_float_paths and in bench_control_misfit, not merely parsed and passed on
    from dampersim.discrepancy import synth

    seen = []

    def stop(*a, base=None, **k):
        seen.append(base.solver.time_step)
        raise _Stop

    monkeypatch.setattr(synth, "synthesize", stop)
    with pytest.raises(_Stop):
        bench.worker(str(tmp_path / "o.json"), "ci-control", 1, 8, 1 / 40000)
    with pytest.raises(_Stop):
        bench.worker(str(tmp_path / "o.json"), "ci-control", 1, 8, None)
    m = bench.M
    import inspect

    signature = inspect.signature(m.run)

    def run(*a):
        args = signature.bind(*a).arguments
        seen.append((args["label"], args["base"].solver.time_step))
        return {}

    monkeypatch.setattr(m, "run", run)
    m.main(["--case", "ci-absorber", "--time-step", "1/40000"])
    assert seen[:2] == [1 / 40000, 1 / 120000]
    assert seen[2][1] == 1 / 40000 and "time_step=2.5e-05" in seen[2][0]
