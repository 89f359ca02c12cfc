"""`make test` runs the suite in two lanes (tests/conftest.py): the modules of APART in a
worker of their own, everything else in the other, each lane whole. This checks the split the
scheduler makes, so that a renamed module cannot silently fall back into the main lane."""

import os
import posixpath

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


def test_the_strict_tests_the_makefile_runs_first_exist_and_have_a_lane_when_kept_in_the_lanes():
    # `make test` runs STRICT_TESTS alone before the lanes and ignores them there; a renamed
    # module would otherwise run in neither the first run (no such file) nor, when STRICT_TESTS=
    # keeps them in the lanes, in the lane of their own
    with open(os.path.join(ROOT, "Makefile")) as f:
        lines = [line.split("?=", 1)[1].split() for line in f if line.startswith("STRICT_TESTS ?=")]
    assert len(lines) == 1 and lines[0], "Makefile: one STRICT_TESTS ?= line naming the modules"
    for path in lines[0]:
        assert os.path.isfile(os.path.join(ROOT, path)), path
        assert path in conftest.APART, path
