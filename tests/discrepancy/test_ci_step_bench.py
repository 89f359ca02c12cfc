"""bench/bench_ci_step.py's reading (docs/discrepancy.md, Known limits, "The strict tests' model
step", quotes it): each step's change of the model's complex orders against the reference run,
in units of the cells' repeatability term."""

import numpy as np
import pytest

from tests.discrepancy.benches import load_bench


@pytest.fixture(scope="module")
def bench():
    return load_bench("bench_ci_step")


def test_a_change_is_read_against_each_cell_s_own_term(bench):
    # rows are points, columns orders: each point's figure is its own largest over its orders
    # (not over the points), and the relative change is against its own largest order
    ref = np.array([[10 + 0j, 2j, 1 + 0j], [4 + 0j, 1 + 0j, 0.5j]])
    coarse = ref + np.array([[0.3 + 0.4j, 0.1, 0], [0, -0.2, 0.05]])  # |0.5|, 0.1 | 0.2, 0.05
    sigma = np.array([[0.25, 1.0, 1.0], [1.0, 0.05, 1.0]])
    out = bench.changes({1e-5: ref, 3e-5: coarse}, sigma, reference=1e-5)
    assert out[1e-5] == {"per_point": [0.0, 0.0], "largest": 0.0, "rms": 0.0, "largest_relative": 0.0}
    c = out[3e-5]
    assert c["per_point"] == pytest.approx([2.0, 4.0])  # 0.5 / 0.25 and 0.2 / 0.05
    assert c["largest"] == pytest.approx(4.0)
    assert c["rms"] == pytest.approx(np.sqrt((4.0 + 0.01 + 16.0 + 0.0025) / 6))
    # 0.5 of point 1's 10 N m is 5 %; 0.2 of point 2's 4 N m is 5 % too, but of the campaign's
    # largest order (10 N m) only 2 %: make point 2's change the larger relative one
    coarse[1, 1] = 1 - 0.4
    c = bench.changes({1e-5: ref, 3e-5: coarse}, sigma, reference=1e-5)[3e-5]
    assert c["largest_relative"] == pytest.approx(0.1)  # 0.4 of 4 N m, not 0.4 of 10 N m


def test_the_reference_is_the_parameter_set_s_step_and_the_default_steps_hold_the_strict_tests(bench):
    # the docs' table reads 1/240 000, 1/60 000 and the strict tests' step against 1/120 000 s
    from tests.discrepancy import test_identification as T

    assert bench.REFERENCE == 1 / 120000
    assert bench.DEFAULT_STEPS == (1 / 240000, 1 / 120000, 1 / 60000, T.TIME_STEP)
