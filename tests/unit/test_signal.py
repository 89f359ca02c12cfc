"""Tests of dampersim.signal on synthetic engine-order torque signals."""

import numpy as np
import pytest

from dampersim.signal import (
    DEFAULT_ORDERS,
    amplitude_spectrum,
    order_amplitudes,
    order_frequencies_hz,
    resample_uniform,
    sample_rate_from_time,
)

FS = 20_000.0  # rig sample rate [Hz]
DURATION = 1.25  # analysis window of [thesis] §3.4 [s]
N = int(FS * DURATION)
T = np.arange(N) / FS  # [s]
# Orders 1..8 of a four-cylinder engine, order 2 dominant [N m]. The weakest order is kept at
# 1/20 of the strongest: with noise 40 dB below the strongest order, an order much weaker
# than that is limited by the noise itself (about 1 % scatter at 1/60), not by the method.
AMPS = np.array([60.0, 300.0, 25.0, 150.0, 20.0, 80.0, 15.0, 40.0])
ACCURACY = 0.01  # the accuracy target: order amplitudes within 1 %


def rad_s(rpm):
    return rpm * 2.0 * np.pi / 60.0


def engine_signal(rpm, orders, amps, drift=0.0, offset=0.0, noise_db=None, seed=0):
    """Sum of engine orders [N m] at a mean speed ``rpm`` times (1 + offset).

    ``drift`` ramps the speed linearly from (1 - drift) to (1 + drift) times the mean over
    the record; ``noise_db`` adds white noise whose RMS is that many dB relative to the RMS
    of the strongest order.
    """
    rng = np.random.default_rng(seed)
    omega = rad_s(rpm) * (1.0 + offset)
    # crank angle [rad] = integral of omega * (1 + drift * (2 t / T_end - 1)) dt
    theta = omega * (T * (1.0 - drift) + drift * T**2 / T[-1])
    phases = rng.uniform(0.0, 2.0 * np.pi, len(orders))
    x = 120.0 + sum(a * np.cos(k * theta + p) for k, a, p in zip(orders, amps, phases))
    if noise_db is not None:
        sigma = np.max(amps) / np.sqrt(2.0) * 10.0 ** (noise_db / 20.0)
        x = x + rng.normal(0.0, sigma, N)
    return x


def test_pure_sine_on_bin_gives_exact_amplitude():
    # bin 56 of a 1.25 s record is 44.8 Hz; 150 N m sine on a 80 N m mean torque
    f0, amp = 56 / DURATION, 150.0
    freq, spec = amplitude_spectrum(80.0 + amp * np.sin(2 * np.pi * f0 * T + 0.7), FS)
    assert freq[1] == pytest.approx(FS / N)
    assert freq[np.argmax(spec)] == pytest.approx(f0)
    # exact arithmetic up to float rounding
    assert spec.max() == pytest.approx(amp, abs=1e-9)
    assert spec[0] == pytest.approx(0.0, abs=1e-9)


def test_order_on_bin_gives_exact_amplitude():
    # 1440 rpm -> first order 24 Hz = bin 30, all eight orders on bins
    speed = rad_s(1440)
    x = engine_signal(1440, DEFAULT_ORDERS, AMPS)
    np.testing.assert_allclose(order_amplitudes(x, FS, speed), AMPS, rtol=0, atol=1e-9)


@pytest.mark.parametrize("rpm", [900, 1500, 2200, 2800])
@pytest.mark.parametrize(
    "profile",
    [dict(drift=0.005), dict(drift=-0.005), dict(offset=0.005), dict(offset=-0.005)],
    ids=["drift-up", "drift-down", "offset+", "offset-"],
)
def test_orders_between_bins_with_noise_and_speed_drift(rpm, profile):
    first_order_bins = rad_s(rpm) / (2 * np.pi) * DURATION
    assert abs(first_order_bins - round(first_order_bins)) > 0.1  # really between bins
    x = engine_signal(rpm, DEFAULT_ORDERS, AMPS, noise_db=-40.0, seed=rpm, **profile)
    got = order_amplitudes(x, FS, rad_s(rpm))
    np.testing.assert_allclose(got, AMPS, rtol=ACCURACY)


def test_noise_free_drift_is_nearly_exact():
    x = engine_signal(2200, DEFAULT_ORDERS, AMPS, drift=0.005, seed=3)
    np.testing.assert_allclose(order_amplitudes(x, FS, rad_s(2200)), AMPS, rtol=1e-3)


@pytest.mark.parametrize("rpm", [900, 2000])
def test_half_orders(rpm):
    orders = np.arange(0.5, 8.01, 0.5)
    amps = np.linspace(20.0, 200.0, orders.size)[::-1]
    x = engine_signal(rpm, orders, amps, drift=0.005, noise_db=-40.0, seed=rpm)
    got = order_amplitudes(x, FS, rad_s(rpm), orders)
    np.testing.assert_allclose(got, amps, rtol=ACCURACY)


def test_half_orders_absent_read_small():
    # integer-order signal read at half orders: the half orders hold only leakage and noise
    x = engine_signal(1500, DEFAULT_ORDERS, AMPS, drift=0.005, noise_db=-40.0, seed=5)
    got = order_amplitudes(x, FS, rad_s(1500), [0.5, 1.5, 2.5])
    assert np.all(got < 0.01 * AMPS.max())


def test_order_frequencies():
    np.testing.assert_allclose(order_frequencies_hz(rad_s(3000), [0.5, 1, 2]), [25, 50, 100])


def test_nan_samples_rejected():
    x = engine_signal(1500, DEFAULT_ORDERS, AMPS)
    x[[10, 200, 3000]] = [np.nan, np.inf, np.nan]
    for call in (lambda: amplitude_spectrum(x, FS), lambda: order_amplitudes(x, FS, 150.0)):
        with pytest.raises(ValueError, match=r"3 NaN/inf samples \(first at index 10\)"):
            call()


@pytest.mark.parametrize(
    "x, fs, match",
    [
        (np.zeros((N, 2)), FS, "1-D"),
        (np.zeros(8), FS, "8 samples; at least 16"),
        (np.zeros(N, dtype=complex), FS, "real numbers"),
        (np.zeros(N), 0.0, "fs must be a positive"),
        (np.zeros(N), np.nan, "fs must be a positive"),
    ],
)
def test_bad_signal_or_rate_rejected(x, fs, match):
    with pytest.raises(ValueError, match=match):
        amplitude_spectrum(x, fs)


@pytest.mark.parametrize(
    "speed, orders", [(-10.0, DEFAULT_ORDERS), (150.0, [1, 0]), (150.0, [2, 2])]
)
def test_bad_speed_or_orders_rejected(speed, orders):
    with pytest.raises(ValueError, match="speed_rad_s|orders"):
        order_amplitudes(np.zeros(N), FS, speed, orders)


def test_order_above_nyquist_rejected():
    # a logger down-sampled to 500 Hz cannot see order 6 at 2800 rpm (280 Hz)
    fs = 500.0
    t = np.arange(int(fs * DURATION)) / fs
    x = 100.0 * np.cos(2 * rad_s(2800) * t)
    with pytest.raises(ValueError, match=r"order 6 lies at 280.0 Hz.*Nyquist frequency 250.0 Hz"):
        order_amplitudes(x, fs, rad_s(2800))
    assert order_amplitudes(x, fs, rad_s(2800), [1, 2, 3])[1] == pytest.approx(100.0, rel=1e-3)


def test_record_too_short_rejected():
    # 900 rpm: orders 15 Hz apart need < 7.5 Hz resolution, i.e. more than 0.1333 s;
    # half orders need more than 0.2667 s
    x = engine_signal(900, DEFAULT_ORDERS, AMPS)
    with pytest.raises(ValueError, match=r"too short.*longer than 0.133 s"):
        order_amplitudes(x[:2000], FS, rad_s(900))
    order_amplitudes(x[:2700], FS, rad_s(900))  # 0.135 s is enough
    with pytest.raises(ValueError, match=r"too short.*longer than 0.267 s"):
        order_amplitudes(x[:2700], FS, rad_s(900), np.arange(0.5, 8.01, 0.5))


def test_sample_rate_from_uniform_time():
    assert sample_rate_from_time(T + 3.0) == pytest.approx(FS, rel=1e-9)
    jitter = np.random.default_rng(1).uniform(-1e-4, 1e-4, N) / FS  # well within 1e-3
    assert sample_rate_from_time(T + jitter) == pytest.approx(FS, rel=1e-6)


def test_non_uniform_time_rejected():
    t = np.delete(T, 1234)  # one dropped sample
    with pytest.raises(ValueError, match=r"non-uniform.*t\[1233\] to t\[1234\]"):
        sample_rate_from_time(t)


def test_non_increasing_time_rejected():
    t = T.copy()
    t[500] = t[499]
    with pytest.raises(ValueError, match=r"strictly increasing.*t\[500\]"):
        sample_rate_from_time(t)
    with pytest.raises(ValueError, match="NaN"):
        sample_rate_from_time(np.r_[T[:10], np.nan])


def test_resample_uniform():
    rng = np.random.default_rng(2)
    t = T + rng.uniform(-2e-4, 2e-4, N) / FS
    t[0], t[-1] = T[0], T[-1]
    x = 40.0 + 3.0 * t  # linear: interpolation is exact
    x_u, fs = resample_uniform(t, x)
    assert fs == pytest.approx(FS, rel=1e-12)
    np.testing.assert_allclose(x_u, 40.0 + 3.0 * T, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="must match"):
        resample_uniform(t, x[:-1])
