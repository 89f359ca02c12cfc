"""Regression tier: pinned values of a few test points (cases.py says how to regenerate)."""

import json
from pathlib import Path

import numpy as np
import pytest

from tests.regression.cases import CASES, SHARE_COMPARED, linear_frequencies, run_case

VALUES = json.loads(Path(__file__).with_name("values.json").read_text())


def test_linear_frequencies_unchanged():
    # 1e-9: an eigenvalue problem of fixed matrices; only the assembly can move it
    np.testing.assert_allclose(linear_frequencies(), VALUES["linear_frequencies_hz"], rtol=1e-9)


@pytest.mark.parametrize("name", sorted(CASES))
def test_case_unchanged(name):
    rtol = CASES[name][3]  # per case, set from the measured change quoted in cases.py
    got = run_case(name)
    want = VALUES["cases"][name]
    a, b = np.array(got["output_amplitude_nm"]), np.array(want["output_amplitude_nm"])
    big = b >= SHARE_COMPARED * b.max()
    np.testing.assert_allclose(a[big], b[big], rtol=rtol)
    assert got["friction_dissipation_j"] == pytest.approx(want["friction_dissipation_j"], rel=rtol)
    assert got["windup_outer_mean_deg"] == pytest.approx(want["windup_outer_mean_deg"], rel=rtol)
