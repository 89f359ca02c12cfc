"""Signal primitives: amplitude spectrum, engine-order amplitudes and the first-order low pass.

Everything here works on plain sampled arrays, whatever produced them (a simulation, a rig
record): the layers above (results, analysis, discrepancy) all read signals through it.

Spectrum and orders ([thesis] §3.4): the thesis analyses every rig record the same way: a
1.25 s window of the torque signal [N m] is Hann-windowed, transformed to a single-sided
amplitude spectrum and a peak finder ("Peakfinder") reads the amplitudes of the first eight
engine orders from it.

:func:`order_amplitudes` keeps that structure but makes the read-out robust:

* the peak of each order is searched within +-max(1.5 bins, 1 % of the order frequency)
  of the nominal frequency, which absorbs a speed offset or drift of up to about +-0.5 %;
* the amplitude is not the height of the highest bin (which loses up to 15 % when an order
  falls between two bins, and more when the speed drifts during the record) but the energy
  of all bins under the Hann main lobe around that peak, divided by the window's equivalent
  noise bandwidth (1.5 bins). By Parseval this returns the amplitude of a sinusoid whatever
  its position between bins, and also when its energy is smeared over several bins by a
  drifting speed, which a single-frequency fit of the main lobe cannot follow.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from dampersim.errors import InputError

#: Engine orders read by default: the first eight, as in [thesis] §3.4.
DEFAULT_ORDERS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)
#: Fewest samples accepted by the spectral functions.
MIN_SAMPLES = 16
#: Equivalent noise bandwidth of the Hann window [bins].
HANN_ENBW_BINS = 1.5
#: Half width of the Hann main lobe [bins].
HANN_HALF_LOBE_BINS = 2.0
#: Peak search half width: the larger of this many bins ...
SEARCH_HALF_WIDTH_BINS = 1.5
#: ... and this fraction of the order frequency.
SEARCH_HALF_WIDTH_REL = 0.01
#: Largest accepted deviation of a time step from the mean time step (relative).
MAX_TIME_JITTER = 1e-3


def _signal(x, name="x"):
    """``x`` as a 1-D finite float array of at least MIN_SAMPLES samples."""
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise InputError(f"{name} must be a 1-D array of real samples: {exc}") from exc
    if arr.dtype.kind not in "biuf":
        raise InputError(f"{name} must hold real numbers (float samples), got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise InputError(
            f"{name} must be a 1-D array of samples, got shape {arr.shape}; "
            "pass one channel, e.g. x[:, 0] or x.ravel()"
        )
    if arr.size < MIN_SAMPLES:
        raise InputError(f"{name} has {arr.size} samples; at least {MIN_SAMPLES} are needed")
    arr = arr.astype(float)
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise InputError(
            f"{name}: signal contains {bad.size} NaN/inf samples (first at index {bad[0]}); "
            "clean or drop them"
        )
    return arr


def _positive(value, name, unit):
    """``value`` as a positive finite float, else an error naming ``name`` and ``unit``."""
    try:
        val = float(value)
    except (TypeError, ValueError):
        val = float("nan")
    if not (np.isfinite(val) and val > 0):
        raise InputError(f"{name} must be a positive finite number in {unit}, got {value!r}")
    return val


def _orders(orders):
    """``orders`` as a 1-D array of distinct positive finite engine orders."""
    arr = np.atleast_1d(np.asarray(orders, dtype=float))
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr) & (arr > 0)):
        raise InputError(
            f"orders must be a non-empty list of positive engine orders (e.g. 1, 2, 2.5), "
            f"got {orders!r}"
        )
    if np.unique(arr).size != arr.size:
        raise InputError(f"orders must not repeat an order, got {arr.tolist()}")
    return arr


@functools.lru_cache(maxsize=8)
def _hann(n):
    """Periodic (DFT-even) Hann window of ``n`` samples; its sum is exactly n/2. Read-only
    and remembered: a sweep analyses every point over the same window length."""
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    w.flags.writeable = False
    return w


def _spectrum(x, fs):
    """Amplitude spectrum of an already validated signal (see :func:`amplitude_spectrum`)."""
    n = x.size
    window = _hann(n)
    amp = np.abs(np.fft.rfft((x - x.mean()) * window)) * (2.0 / window.sum())
    amp[0] *= 0.5  # DC has no mirror image in the negative frequencies
    if n % 2 == 0:
        amp[-1] *= 0.5  # neither has the Nyquist bin
    return np.fft.rfftfreq(n, 1.0 / fs), amp


def amplitude_spectrum(x, fs):
    """Single-sided, amplitude-corrected Hann spectrum of a signal ([thesis] §3.4).

    The mean is removed, a periodic Hann window applied and the FFT scaled so that a sine
    of amplitude A lying exactly on a frequency bin shows as A: magnitudes are divided by the
    window sum and doubled, except the DC and Nyquist bins. An off-bin sine shows lower (down
    to 0.85 A halfway between bins); use :func:`order_amplitudes` to read order amplitudes.

    Args:
        x: 1-D torque signal [N m] (any unit; the amplitudes come out in the same unit),
            finite, at least 16 samples. The thesis uses 1.25 s records.
        fs: sample rate [Hz].

    Returns:
        ``(freq_hz, amplitude)``: bin frequencies [Hz], spacing ``fs / len(x)``, and the
        amplitude per bin [N m, unit of ``x``].

    Raises:
        ValueError: ``x`` not 1-D, too short or with NaN/inf samples; ``fs`` not > 0.
    """
    return _spectrum(_signal(x), _positive(fs, "fs", "Hz (samples per second)"))


def order_frequencies_hz(speed_rad_s, orders=DEFAULT_ORDERS):
    """Frequencies of engine orders at a shaft speed ([thesis] §3.4).

    Args:
        speed_rad_s: engine (input shaft) speed [rad/s]; from rpm: ``rpm * 2 * pi / 60``.
        orders: engine orders (positive, fractional allowed, e.g. 0.5 or 1.5).

    Returns:
        Array of ``order * speed_rad_s / (2 pi)`` [Hz].
    """
    speed = _positive(speed_rad_s, "speed_rad_s", "rad/s (rpm * 2*pi/60)")
    return _orders(orders) * speed / (2.0 * np.pi)


def order_amplitudes(x, fs, speed_rad_s, orders=DEFAULT_ORDERS):
    """Amplitude of each engine order in a torque signal ([thesis] §3.4, "Peakfinder").

    For order k the nominal frequency is ``k * speed_rad_s / (2 pi)``. The highest bin of
    the Hann amplitude spectrum within +-max(1.5 bins, 1 % of that frequency) is taken as the
    order's peak; the amplitude is then the energy of the bins within that search half width
    plus the Hann main lobe (2 bins) around the peak, divided by the Hann window's equivalent
    noise bandwidth of 1.5 bins. This is exact for a sinusoid at any position between bins
    and keeps its full amplitude when the speed drifts (by up to about +-0.5 %) during the
    record. Bands never reach beyond half the spacing to the nearest other order.

    Accuracy on synthetic 1.25 s records at 20 kHz (the unit tests): < 0.01 % without noise,
    orders between bins and +-0.5 % speed drift included; within 1 % with white noise 40 dB
    below the largest order for orders down to 1/20 of the largest. Weaker orders are limited
    by the noise itself, not by the method.

    Args:
        x: 1-D torque signal [N m] (or any unit; the amplitudes come out in that unit).
        fs: sample rate [Hz].
        speed_rad_s: mean engine speed over the record [rad/s]; from rpm:
            ``rpm * 2 * pi / 60``.
        orders: engine orders to read, default the first eight; fractional (half) orders
            are allowed.

    Returns:
        Array of amplitudes [N m, unit of ``x``], one per entry of ``orders``.

    Raises:
        ValueError: bad ``x``/``fs``/``speed_rad_s``/``orders``; an order at or above the
            Nyquist frequency ``fs / 2``; a record too short to separate the orders (the
            frequency resolution ``fs / len(x)`` must be finer than half the smallest
            spacing between the requested orders, counting DC as order 0).
    """
    x = _signal(x)
    fs = _positive(fs, "fs", "Hz (samples per second)")
    f_1 = _positive(speed_rad_s, "speed_rad_s", "rad/s (rpm * 2*pi/60)") / (2.0 * np.pi)
    orders = _orders(orders)
    freqs = orders * f_1  # [Hz]
    nyquist = fs / 2.0
    for k, f_k in zip(orders, freqs):
        if f_k >= nyquist:
            raise InputError(
                f"order {k:g} lies at {f_k:.1f} Hz, at or above the Nyquist frequency "
                f"{nyquist:.1f} Hz (fs = {fs:g} Hz); drop that order or sample faster than "
                f"{2 * f_k:.0f} Hz"
            )

    n = x.size
    df = fs / n
    spacing_hz = np.min(np.diff(np.concatenate(([0.0], np.sort(orders))))) * f_1
    if df >= 0.5 * spacing_hz:
        min_duration = 2.0 / spacing_hz
        raise InputError(
            f"record too short to resolve the orders: {n} samples at {fs:g} Hz "
            f"({n / fs:.3g} s) give {df:.3g} Hz resolution, but orders {spacing_hz:.3g} Hz "
            f"apart (at {f_1 * 60:.0f} rpm) need a resolution finer than "
            f"{0.5 * spacing_hz:.3g} Hz, i.e. a record longer than {min_duration:.3g} s "
            f"(at least {int(np.floor(min_duration * fs)) + 1} samples)"
        )

    freq, amp = _spectrum(x, fs)
    power = amp**2
    limit = 0.5 * spacing_hz  # never reach into the neighbouring order's half of the gap

    def bins(lo, hi):
        return slice(max(int(np.ceil(lo / df)), 1), min(int(np.floor(hi / df)) + 1, freq.size))

    result = np.empty(orders.size)
    for i, f_k in enumerate(freqs):
        half = min(max(SEARCH_HALF_WIDTH_BINS * df, SEARCH_HALF_WIDTH_REL * f_k), limit)
        search = bins(f_k - half, f_k + half)
        f_peak = freq[search.start + int(np.argmax(amp[search]))]
        reach = half + HANN_HALF_LOBE_BINS * df
        band = bins(max(f_peak - reach, f_k - limit), min(f_peak + reach, f_k + limit))
        result[i] = np.sqrt(power[band].sum() / HANN_ENBW_BINS)
    return result


def sample_rate_from_time(t):
    """Sample rate of a uniformly sampled time column ([thesis] §3.4 analyses such records).

    Args:
        t: 1-D time stamps [s], strictly increasing, at least 2 of them.

    Returns:
        Sample rate [Hz] = (len(t) - 1) / (t[-1] - t[0]).

    Raises:
        ValueError: time stamps not finite, not strictly increasing, or any step deviating
            from the mean step by more than 1e-3 (relative); the message names the first
            offending index.
    """
    try:
        t = np.asarray(t, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"t must be a 1-D array of time stamps in s: {exc}") from exc
    if t.ndim != 1 or t.size < 2:
        raise InputError(
            f"t must be a 1-D array of at least 2 time stamps in s, got shape {t.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputError(f"t contains {bad.size} NaN/inf time stamps (first at index {bad[0]})")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        raise InputError(
            f"time stamps must be strictly increasing, but t[{i}] = {t[i]!r} s does not come "
            f"after t[{i - 1}] = {t[i - 1]!r} s"
        )
    step = (t[-1] - t[0]) / (t.size - 1)
    jitter = np.abs(dt - step) / step
    bad = np.flatnonzero(jitter > MAX_TIME_JITTER)
    if bad.size:
        i = bad[0] + 1
        raise InputError(
            f"time stamps are non-uniform: the step from t[{i - 1}] to t[{i}] is "
            f"{dt[i - 1]:.6g} s, {jitter[i - 1]:.2%} off the mean step {step:.6g} s (accepted: "
            f"{MAX_TIME_JITTER:.1%}); look for dropped samples or split the record there"
        )
    return 1.0 / step


def resample_uniform(t, x):
    """Put a signal with slightly jittered time stamps on an exactly uniform grid.

    Checks ``t`` like :func:`sample_rate_from_time` (jitter up to 1e-3 of the step is
    accepted) and linearly interpolates ``x`` onto ``t[0] + i / fs``, i = 0 .. len(t) - 1,
    ready for :func:`amplitude_spectrum` / :func:`order_amplitudes` ([thesis] §3.4).

    Args:
        t: 1-D time stamps [s].
        x: signal samples at ``t`` [N m, or any unit], same length, finite.

    Returns:
        ``(x_uniform, fs)``: resampled signal [unit of ``x``] and sample rate [Hz].

    Raises:
        ValueError: as :func:`sample_rate_from_time`, or ``x`` not matching ``t``.
    """
    fs = sample_rate_from_time(t)
    t = np.asarray(t, dtype=float)
    x = _signal(x)
    if x.size != t.size:
        raise InputError(f"x has {x.size} samples but t has {t.size} time stamps; they must match")
    return np.interp(t[0] + np.arange(t.size) / fs, t, x), fs


#: Break frequency of the thesis's smoothing filter [Hz] ([thesis] §3.4).
LOWPASS_CUTOFF_HZ = 10.0


# --- filtering ---------------------------------------------------------------------------
def lowpass_coefficients(sample_rate_hz: float, cutoff_hz: float = LOWPASS_CUTOFF_HZ):
    """(b, a) of the discrete first-order low pass with its -3 dB point at ``cutoff_hz``.

    The analogue filter 1 / (1 + s / (2 pi fc)) is mapped with the bilinear transform,
    pre-warped so that the -3 dB point lands exactly at ``cutoff_hz`` [Hz]; DC gain is 1.
    ``sample_rate_hz`` [Hz] must exceed 2 x ``cutoff_hz``.
    """
    fs, fc = float(sample_rate_hz), float(cutoff_hz)
    if not (math.isfinite(fs) and fs > 0):
        raise InputError(f"sample rate {sample_rate_hz!r} Hz: accepted is a positive rate")
    if not (math.isfinite(fc) and 0 < fc < fs / 2):
        raise InputError(f"cutoff {cutoff_hz!r} Hz: accepted is 0 < cutoff < sample rate / 2 = {fs / 2:g} Hz")
    k = math.tan(math.pi * fc / fs)
    b = np.array([k, k]) / (1.0 + k)
    a = np.array([1.0, (k - 1.0) / (k + 1.0)])
    return b, a


def lowpass_first_order(x, sample_rate_hz: float, cutoff_hz: float = LOWPASS_CUTOFF_HZ, zero_phase: bool = False) -> np.ndarray:
    """First-order low pass of a sampled signal ([thesis] §3.4: 1st order, 10 Hz break).

    Args:
        x: samples (any unit; output in the same unit), 1-D.
        sample_rate_hz: sample rate [Hz].
        cutoff_hz: -3 dB break frequency [Hz] (default 10 Hz, as the thesis).
        zero_phase: run the filter forwards and backwards (``scipy.signal.filtfilt``): no
            lag between channels, but the magnitude is squared (-6 dB at the break). The
            default is the causal filter the thesis describes; it lags by about
            1 / (2 pi fc) = 16 ms at 10 Hz, which for torque and windup filtered alike is
            harmless.

    The filter starts in steady state at ``x[0]`` (no start-up transient).
    """
    from scipy.signal import filtfilt, lfilter, lfilter_zi

    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise InputError(f"signal to filter: accepted is a 1-D array of >= 2 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InputError("signal to filter contains NaN/inf samples: clean them first")
    b, a = lowpass_coefficients(sample_rate_hz, cutoff_hz)
    if zero_phase:
        if x.size <= 6:
            raise InputError("zero-phase filtering needs more than 6 samples")
        return filtfilt(b, a, x)
    y, _ = lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0])
    return y
