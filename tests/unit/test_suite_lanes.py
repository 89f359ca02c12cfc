"""`make test` runs the suite in two lanes (tests/conftest.py): the modules of APART, the strict
identification tests among them, in a worker of their own, everything else in the other, each
lane whole; with the Makefile's STRICT_TESTS set, those files run first, alone
(scripts/run-tests.sh), and the lanes after them. This checks
the split the scheduler makes, so that a renamed module cannot silently fall back into the main
lane, and how the two runs are made and their exit statuses combined."""

import os
import posixpath
import subprocess

import pytest

from tests import conftest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_every_module_set_apart_exists_and_is_named_as_in_a_test_id(request):
    # a test id starts with the module's path relative to the root, with forward slashes, as
    # this test's own does; an entry written otherwise would never match and fall back into
    # the main lane
    assert request.node.nodeid.split("::", 1)[0] == "tests/unit/test_suite_lanes.py"
    for path in conftest.APART:
        assert os.path.isfile(os.path.join(ROOT, path)), path
        assert not os.path.isabs(path) and "\\" not in path and posixpath.normpath(path) == path, path


def test_the_scheduler_puts_the_apart_modules_in_one_lane_and_the_rest_in_the_other(pytestconfig, monkeypatch):
    loadscope = pytest.importorskip("xdist.scheduler.loadscope")  # `make test` installs it
    # the scheduler reads the worker count from -n, which a run of this file alone lacks
    monkeypatch.setattr(loadscope, "parse_tx_spec_config", lambda config: ["popen", "popen"])
    monkeypatch.setattr(pytestconfig.option, "dist", "each")  # an explicit --dist keeps xdist's scheduler
    assert conftest.pytest_xdist_make_scheduler(pytestconfig, None) is None
    monkeypatch.setattr(pytestconfig.option, "dist", "load")  # what -n alone sets
    sched = conftest.pytest_xdist_make_scheduler(pytestconfig, None)
    ids = [f"{p}::test_x" for p in conftest.APART] + [f"{p}::test_x[a@b]" for p in conftest.APART]
    assert {sched._split_scope(i) for i in ids} == {"apart"}
    others = ["tests/unit/test_structure.py::test_each_module_is_small_and_says_its_job",
              "tests/e2e/test_browser.py::test_moving_a_slider_updates_figures_and_the_url",
              "tests/discrepancy/test_identification_extra.py::test_x"]
    assert {sched._split_scope(i) for i in others} == {"suite"}


def test_the_makefile_keeps_the_strict_tests_in_their_lane_by_default():
    # the whole suite is shortest with the strict module in its lane (docs/discrepancy.md, Known
    # limits, "The strict tests run first and alone"): STRICT_TESTS is empty unless asked for,
    # the module the README names for it exists and has its lane, and the Makefile hands both
    # settings to the runner
    with open(os.path.join(ROOT, "Makefile")) as f:
        makefile = f.read()
    lines = [line.split("?=", 1)[1].split() for line in makefile.splitlines() if line.startswith("STRICT_TESTS ?=")]
    assert lines == [[]], "Makefile: one STRICT_TESTS ?= line, empty"
    strict = "tests/discrepancy/test_identification.py"
    assert f"STRICT_TESTS={strict}" in makefile
    assert os.path.isfile(os.path.join(ROOT, strict)) and strict in conftest.APART
    assert 'STRICT_TESTS="$(STRICT_TESTS)"' in makefile and "bash scripts/run-tests.sh $(PYTEST_ARGS)" in makefile


def _run_tests(tmp_path, first, rest, args=(), strict="tests/a.py tests/b.py"):
    """scripts/run-tests.sh with a stand-in python whose first pytest run exits with ``first``
    and whose second with ``rest``; (exit status, the argument lists each run got)."""
    log = tmp_path / "runs"
    fake = tmp_path / "python"
    fake.write_text('#!/bin/sh\nprintf "%s|" "$@" >> "$LOG"; echo >> "$LOG"\n'
                    'n=$(wc -l < "$LOG"); [ "$n" -eq 1 ] && [ -n "$STRICT_TESTS" ] && exit "$FIRST"; exit "$REST"\n')
    fake.chmod(0o755)
    env = {**os.environ, "PY": str(fake), "STRICT_TESTS": strict, "PYTEST_XDIST": "-n 2", "LOG": str(log),
           "FIRST": str(first), "REST": str(rest)}
    proc = subprocess.run(["bash", os.path.join(ROOT, "scripts", "run-tests.sh"), *args], env=env,
                          capture_output=True, text=True, check=False)
    runs = [line.rstrip("|").split("|") for line in log.read_text().splitlines()] if log.exists() else []
    return proc.returncode, runs


@pytest.mark.parametrize("first, rest, status", [
    (0, 0, 0), (1, 0, 1), (0, 1, 1), (2, 1, 2),  # the first failing run's status
    (1, 5, 1),  # a failing strict run is not hidden by a second run that selected nothing
    (5, 0, 0), (0, 5, 0),  # a -k that selects tests of one run only
    (5, 5, 5),  # nothing selected at all: pytest's own status
])
def test_the_two_runs_exit_statuses_combine_to_the_first_failure(tmp_path, first, rest, status):
    code, runs = _run_tests(tmp_path, first, rest, args=["-k", "a and b"])
    assert code == status
    # the strict files first with the options, then the rest without them and with the options
    assert runs == [["-m", "pytest", "tests/a.py", "tests/b.py", "-k", "a and b"],
                    ["-m", "pytest", "-n", "2", "--ignore=tests/a.py", "--ignore=tests/b.py", "-k", "a and b"]]


def test_exitfirst_skips_the_rest_after_a_failing_strict_run_only(tmp_path):
    (tmp_path / "failed").mkdir()
    (tmp_path / "passed").mkdir()
    code, runs = _run_tests(tmp_path / "failed", 1, 0, args=["-x"])
    assert code == 1 and len(runs) == 1
    code, runs = _run_tests(tmp_path / "passed", 0, 0, args=["-x"])
    assert code == 0 and len(runs) == 2


def test_without_strict_tests_there_is_one_run_with_its_own_status(tmp_path):
    for rest in (0, 1, 5):
        (tmp_path / str(rest)).mkdir()
        code, runs = _run_tests(tmp_path / str(rest), 0, rest, strict="")
        assert code == rest and runs == [["-m", "pytest", "-n", "2"]]
