"""Tests of dampersim.analysis.metrics."""

import warnings

import numpy as np
import pandas as pd
import pytest

from dampersim.analysis.metrics import error_table, magnification_ratio, simulation_error
from dampersim.signal import order_amplitudes

FS = 10_000.0  # [Hz]
DURATION = 1.25  # [s], [thesis] §3.4
T = np.arange(int(FS * DURATION)) / FS


def rad_s(rpm):
    return rpm * 2.0 * np.pi / 60.0


@pytest.mark.parametrize("rpm", [1100, 2600])
def test_magnification_ratio_of_pure_gain(rpm):
    gain = 0.35
    rng = np.random.default_rng(rpm)
    amps = np.array([40.0, 250.0, 12.0, 90.0, 8.0, 30.0, 5.0, 15.0])  # [N m]
    theta = rad_s(rpm) * T * (1.0 + 0.005 * (2.0 * T / T[-1] - 1.0))
    x_in = 200.0 + sum(
        a * np.cos(k * theta + p)
        for k, a, p in zip(range(1, 9), amps, rng.uniform(0, 2 * np.pi, 8))
    )
    x_out = 60.0 + gain * x_in  # a different mean torque does not matter
    mr = magnification_ratio(
        order_amplitudes(x_in, FS, rad_s(rpm)), order_amplitudes(x_out, FS, rad_s(rpm))
    )
    np.testing.assert_allclose(mr, gain, rtol=0, atol=1e-6)


def test_magnification_ratio_nan_below_min_input_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no divide-by-zero RuntimeWarning
        mr = magnification_ratio([100.0, 0.0, 1e-12, np.nan, 0.5], [50.0, 3.0, 1.0, 2.0, 1.0])
        np.testing.assert_array_equal(mr, [0.5, np.nan, np.nan, np.nan, 2.0])
        mr = magnification_ratio([2.0, 0.5], [1.0, 1.0], min_input=1.0)
        np.testing.assert_array_equal(mr, [0.5, np.nan])
        assert np.isnan(magnification_ratio([0.0], [1.0], min_input=0.0)[0])


@pytest.mark.parametrize(
    "inp, out, min_input, match",
    [
        ([1.0, 2.0], [1.0], 1e-9, "same shape"),
        ([1.0, -2.0], [1.0, 1.0], 1e-9, "input_amp must hold amplitudes >= 0"),
        ([1.0, 2.0], [1.0, np.inf], 1e-9, "output_amp"),
        ([1.0, 2.0], [1.0, 1.0], -1.0, "min_input"),
    ],
)
def test_magnification_ratio_bad_input(inp, out, min_input, match):
    with pytest.raises(ValueError, match=match):
        magnification_ratio(inp, out, min_input)


def test_simulation_error_relative_to_measured_input():
    err = simulation_error(
        sim_out=[10.0, 52.0, 3.0], meas_out=[12.0, 50.0, 1.0], meas_in=[100.0, 400.0, 0.0]
    )
    np.testing.assert_allclose(err["abs_nm"], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(err["relative_to_input"], [0.02, 0.005, np.nan])
    with pytest.raises(ValueError, match="same shape"):
        simulation_error([1.0], [1.0, 2.0], [1.0, 2.0])


def test_error_table_over_campaign():
    table = error_table(
        {
            "1200rpm_100Nm": [0.01, 0.04, np.nan],
            "1800rpm_200Nm": [0.03, 0.02, np.nan],
            "2400rpm_300Nm": [0.02, 0.06, np.nan],
        }
    )
    assert isinstance(table, pd.DataFrame)
    assert list(table.columns) == ["min", "mean", "max"]
    assert table.index.name == "order" and list(table.index) == [1, 2, 3]
    np.testing.assert_allclose(table.loc[1], [0.01, 0.02, 0.03])
    np.testing.assert_allclose(table.loc[2], [0.02, 0.04, 0.06])
    assert table.loc[3].isna().all()  # order never excited
    half = error_table({"a": [1.0, 2.0], "b": [3.0, 4.0]}, orders=[0.5, 1.0])
    assert list(half.index) == [0.5, 1.0] and half.loc[0.5, "mean"] == 2.0


def test_error_table_bad_input():
    with pytest.raises(ValueError, match="non-empty mapping"):
        error_table({})
    with pytest.raises(ValueError, match="same number of orders"):
        error_table({"a": [1.0, 2.0], "b": [1.0]})
    with pytest.raises(ValueError, match="test point 'b'"):
        error_table({"a": [1.0, 2.0], "b": [[1.0, 2.0]]})
    with pytest.raises(ValueError, match="3 labels"):
        error_table({"a": [1.0, 2.0]}, orders=[1, 2, 3])
