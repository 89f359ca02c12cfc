"""The factors bench/bench_ramp_misfit.py replays a ramp at with ``--factors-from`` (no
simulation): the truth's group factors and a result line's reported ones."""

import json
import math

import numpy as np
import pytest

from dampersim.discrepancy.fitting import CALIBRATION, calibrated_system
from dampersim.parameters import default_parameters, with_updates
from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_ramp_misfit")


def test_the_truths_factors_of_a_calibrated_set_are_its_own(bench):
    est = default_parameters()
    x = np.array([0.04, -0.06, 0.05, 0.08, -0.05, 0.07])
    np.testing.assert_allclose(bench.truth_factors(calibrated_system(est, x), est), x, atol=1e-12)


def test_a_group_whose_members_moved_apart_reads_their_geometric_mean(bench):
    # the inner spring 10 % up, the nested one 10 % down: the group's factor is their geometric mean
    est = default_parameters()
    truth = with_updates(est, {"inner.spring.stiffness": est.inner.spring.stiffness * 1.1,
                               "inner.nested.stiffness": est.inner.nested.stiffness * 0.9})
    got = bench.truth_factors(truth, est)
    k = list(CALIBRATION).index("inner_stiffness")
    assert got[k] == pytest.approx(0.5 * (math.log(1.1) + math.log(0.9)), abs=1e-12)
    assert np.count_nonzero(np.delete(got, k)) == 0


def test_the_reported_factors_are_the_case_lines(bench, tmp_path):
    path = tmp_path / "b.jsonl"
    lines = [{"id": "a", "calibration": {k: 2.0 for k in CALIBRATION}},
             {"id": "b", "calibration": {k: 1.0 + i / 10 for i, k in enumerate(CALIBRATION)}}]
    path.write_text("\n".join(json.dumps(r) for r in lines) + "\n", encoding="utf-8")
    np.testing.assert_allclose(bench.reported_factors(path, "b"), np.log(1.0 + np.arange(len(CALIBRATION)) / 10))
    with pytest.raises(SystemExit, match="no line with calibration factors for c"):
        bench.reported_factors(path, "c")


def test_the_groups_split_the_factors_into_stiffnesses_and_inertias_and_frictions(bench):
    names = list(CALIBRATION)
    assert [names[k] for k in bench.GROUPS["frictions"]] == ["outer_friction", "inner_friction"]
    assert sorted(bench.GROUPS["stiffnesses and inertias"] + bench.GROUPS["frictions"]) == list(range(len(names)))


def test_a_prediction_spread_without_factors_is_the_parsers_error(bench):
    with pytest.raises(SystemExit):
        bench.main(["effect/output_backlash/typical/s0", "--prediction-sd", "0.03"])
