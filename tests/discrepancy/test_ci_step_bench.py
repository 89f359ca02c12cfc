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
    ref = np.array([[10 + 0j, 2j], [4 + 0j, 1 + 0j]])
    coarse = ref + np.array([[0.3 + 0.4j, 0], [0, -0.2]])  # |0.5| at (0, 0), 0.2 at (1, 1)
    sigma = np.array([[0.25, 1.0], [1.0, 0.1]])
    out = bench.changes({1e-5: ref, 3e-5: coarse}, sigma, reference=1e-5)
    assert out[1e-5] == {"per_point": [0.0, 0.0], "largest": 0.0, "rms": 0.0, "largest_relative": 0.0}
    c = out[3e-5]
    assert c["per_point"] == pytest.approx([2.0, 2.0])  # 0.5 / 0.25 and 0.2 / 0.1
    assert c["largest"] == pytest.approx(2.0)
    assert c["rms"] == pytest.approx(np.sqrt((4.0 + 4.0) / 4))
    # relative to the point's largest order: 0.5 of 10 and 0.2 of 4
    assert c["largest_relative"] == pytest.approx(0.05)


def test_the_reference_is_the_parameter_set_s_step_and_the_default_steps_hold_the_strict_tests(bench):
    # the docs' table reads 1/240 000, 1/60 000 and the strict tests' step against 1/120 000 s
    from tests.discrepancy import test_identification as T

    assert bench.REFERENCE == 1 / 120000
    assert bench.DEFAULT_STEPS == (1 / 240000, 1 / 120000, 1 / 60000, T.TIME_STEP)
