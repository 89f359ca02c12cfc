"""Resampling onto one time base: overlap, rates, anti-aliasing, drop-outs, bad time stamps."""

import numpy as np
import pytest

from dampersim.errors import InputError
from dampersim.rigdata.resample import GUARD_PERIODS, common_time_base, nice_rate


def amplitude(t, x, f):
    """Amplitude of the tone at f [Hz] in x(t) by a least-squares fit of sine, cosine and mean."""
    a = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
    coef = np.linalg.lstsq(a, x, rcond=None)[0]
    return float(np.hypot(coef[0], coef[1]))


def tone(fs, f, t0=0.0, duration=2.0, amp=1.0):
    t = t0 + np.arange(int(round(duration * fs))) / fs
    return t, amp * np.sin(2 * np.pi * f * t + 0.4)


def test_two_rates_and_spans_onto_one_uniform_base_over_the_overlap():
    t_fast, x_fast = tone(10000.0, 37.0, t0=0.0, duration=2.0)
    t_slow, x_slow = tone(999.99, 37.0, t0=0.0503, duration=1.8)
    t, cols, note = common_time_base({"input_torque_nm": (t_fast, x_fast), "input_speed_rpm": (t_slow, x_slow)})
    assert t[0] == pytest.approx(0.0503) and t[-1] <= t_slow[-1] + 1e-12 and t_slow[-1] - t[-1] < 1e-4
    np.testing.assert_allclose(np.diff(t), 1e-4, rtol=1e-6)
    truth = np.sin(2 * np.pi * 37.0 * t + 0.4)
    np.testing.assert_allclose(cols["input_torque_nm"], truth, atol=1e-6)  # same rate: (cubic) interpolation
    np.testing.assert_allclose(cols["input_speed_rpm"], truth, atol=1e-3)  # up-sampled 10x by cubic convolution
    assert "common time base 10000 Hz" in note and "up-sampled" in note and "same rate" in note


def test_same_rate_and_same_start_is_copied_unchanged():
    t0, x0 = tone(2000.0, 50.0)
    t, cols, note = common_time_base({"a": (t0, x0), "b": (t0, 2 * x0)})
    np.testing.assert_array_equal(t, t0) if np.array_equal(t, t0) else np.testing.assert_allclose(t, t0, atol=1e-12)
    np.testing.assert_array_equal(cols["a"], x0)
    assert "copied" in note


@pytest.mark.parametrize("fraction", [0.51, 0.6, 0.7, 0.9, 1.3])
def test_a_tone_above_the_new_nyquist_is_suppressed_by_40_db(fraction):
    new_rate = 1000.0
    f = fraction * new_rate
    t0, x0 = tone(10000.0, f, duration=3.0)
    t, cols, note = common_time_base({"input_torque_nm": (t0, x0)}, rate_hz=new_rate)
    alias = abs(f - new_rate * round(f / new_rate))  # where the tone would fold to
    inner = slice(200, -200)  # the filter's ends
    assert amplitude(t[inner], cols["input_torque_nm"][inner], alias) < 10 ** (-40 / 20)
    assert "Butterworth order 12" in note and "cut-off 400 Hz" in note


@pytest.mark.parametrize("fraction", [0.05, 0.2, 0.25, 0.3])
def test_a_tone_below_the_cut_off_is_kept_within_half_a_percent(fraction):
    new_rate = 1000.0
    f = fraction * new_rate
    t0, x0 = tone(10000.0 / 3.0, f, duration=3.0, amp=150.0)  # a rate no multiple of the new one
    t, cols, _ = common_time_base({"output_torque_nm": (t0, x0)}, rate_hz=new_rate)
    inner = slice(200, -200)
    assert amplitude(t[inner], cols["output_torque_nm"][inner], f) == pytest.approx(150.0, rel=0.005)


def test_nan_bursts_stay_nan_and_are_never_bridged():
    fs, new_rate = 10000.0, 1000.0
    t0, x0 = tone(fs, 20.0)
    x0[5000:5100] = np.nan  # 0.50-0.51 s
    ts, xs = tone(500.0, 20.0)
    xs[250:253] = np.nan  # 0.500-0.504 s
    t, cols, note = common_time_base({"filtered": (t0, x0), "interpolated": (ts, xs)}, rate_hz=new_rate)
    guard = GUARD_PERIODS / (0.4 * new_rate)
    for name, lo, hi, pad in (("filtered", 0.5, 0.51, guard), ("interpolated", 0.5, 0.504, 2 / 500.0)):
        y = cols[name]
        inside = (t >= lo) & (t <= hi)
        assert np.isnan(y[inside]).all(), name
        far = (t < lo - pad - 2e-3) | (t > hi + pad + 2e-3)
        assert np.isfinite(y[far]).all(), name
        np.testing.assert_allclose(y[far], np.sin(2 * np.pi * 20.0 * t[far] + 0.4), atol=1e-3)
    assert "NaN (drop-outs kept)" in note


@pytest.mark.parametrize("t, needle", [
    (np.array([0.0, 0.001, 0.002, 0.0025, 0.0035]), "non-uniform"),
    (np.array([0.0, 0.001, 0.003, 0.002, 0.004]), "strictly increasing"),
    (np.array([0.0, 0.001, np.nan, 0.003, 0.004]), "NaN"),
])
def test_bad_time_stamps_raise_naming_the_channel(t, needle):
    with pytest.raises(InputError) as exc:
        common_time_base({"input_speed_rpm": (t, np.zeros(t.size))})
    assert needle in str(exc.value) and "input_speed_rpm" in str(exc.value)


def test_channels_that_do_not_overlap_or_do_not_match_raise():
    a = (np.arange(10) / 10.0, np.zeros(10))
    b = (5.0 + np.arange(10) / 10.0, np.zeros(10))
    with pytest.raises(InputError, match="do not overlap"):
        common_time_base({"a": a, "b": b})
    with pytest.raises(InputError, match="same length"):
        common_time_base({"a": (a[0], np.zeros(9))})
    with pytest.raises(InputError, match="rate_hz"):
        common_time_base({"a": a}, rate_hz=-5)


def test_the_default_rate_is_the_highest_rounded_to_four_digits():
    assert nice_rate(19999.7) == 20000.0 and nice_rate(10240.0) == 10240.0 and nice_rate(2083.333) == 2083.0
