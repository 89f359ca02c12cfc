"""DAQ corruption of recorded channels: what the acquisition chain of a rig adds to the signals.

A synthetic campaign (:mod:`dampersim.discrepancy.synth`) without this is an easy problem:
the "measured" torques are the truth model's plus white noise. A real acquisition chain
(transducer, amplifier, cabling, anti-alias filter, ADC) adds more, and each piece is one
frozen, documented setting here:

* :class:`Gains` - relative gain errors of the torque channels (transducer and amplifier
  calibration);
* :class:`Offsets` - zero offsets of the torque channels [N m];
* :class:`Drift` - slow zero drift [N m/s] plus a random walk [N m/sqrt(s)] (amplifier
  temperature);
* :class:`MainsHum` - 50 Hz mains pick-up with a third harmonic [N m];
* :class:`AntiAlias` - a causal Butterworth low pass on the torque channels (the
  analogue anti-alias filter before the ADC);
* :class:`Skew` - a delay [s] of the output torque channel against the input one
  (different group delays of the two amplifier chains, multiplexed sampling), applied by
  windowed-sinc fractional-sample interpolation;
* :class:`SpeedRipple` - a sinusoidal ripple [rpm] on both speed channels (encoder
  tooth-spacing errors, motor-drive ripple).

They are applied in that order to the torque channels, as the signal passes the chain:
gain at the transducer, then offset, drift and hum picked up on the way to the ADC, then
the anti-alias filter (which also filters the hum), then the skew of the output channel.
The speed channels come from encoders and only carry the ripple; a ramp's windup
(encoder angles) is left as it is.

Channels are a mapping of NumPy arrays with the campaign's column names (``time_s``,
``input_torque_nm``, ``output_torque_nm``, ``input_speed_rpm``, ``output_speed_rpm``,
optionally ``windup_rad``); :func:`corrupt` returns a new mapping and never changes its
argument. Settings that draw random numbers (random walk, hum and ripple phases) carry a
``seed``; :func:`corrupt` combines it with a ``stream`` number (one per test point) so
that every record of a campaign gets its own, reproducible realisation.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError

TORQUE_CHANNELS = ("input_torque_nm", "output_torque_nm")
SPEED_CHANNELS = ("input_speed_rpm", "output_speed_rpm")
#: half length of the fractional-delay filter [taps each side] and its Kaiser window shape:
#: amplitude error below 1e-4 up to 0.4 x the sample rate
DELAY_HALF_TAPS = 16
DELAY_KAISER_BETA = 8.0
#: highest anti-alias cut-off accepted, as a share of the sample rate
MAX_CUTOFF_SHARE = 0.49


@dataclass(frozen=True)
class Gains:
    """Gain factors of the torque channels (1.0: exact), e.g. 1.004 for +0.4 %."""

    input: float = 1.0
    output: float = 1.0


@dataclass(frozen=True)
class Offsets:
    """Zero offsets of the torque channels [N m]."""

    input_nm: float = 0.0
    output_nm: float = 0.0


@dataclass(frozen=True)
class Drift:
    """Zero drift of the torque channels from the start of acquisition: a linear rate
    [N m/s] plus a random walk whose standard deviation grows by ``walk_*`` [N m/sqrt(s)]."""

    input_nm_per_s: float = 0.0
    output_nm_per_s: float = 0.0
    walk_input_nm_per_sqrt_s: float = 0.0
    walk_output_nm_per_sqrt_s: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class MainsHum:
    """Mains pick-up on the torque channels: amplitude [N m] at ``frequency_hz`` plus a
    third harmonic of ``third_harmonic`` times that amplitude; phases random per record."""

    input_nm: float = 0.0
    output_nm: float = 0.0
    frequency_hz: float = 50.0
    third_harmonic: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class AntiAlias:
    """Causal Butterworth low pass of ``order`` with -3 dB at ``cutoff_hz`` [Hz] on both
    torque channels, started in steady state at the first sample (a DAQ filter that ran
    before the record began)."""

    cutoff_hz: float
    order: int = 4


@dataclass(frozen=True)
class Skew:
    """Delay [s] of the output torque channel against the input torque channel (negative:
    the output channel leads). An order k at speed Omega [rad/s] is shifted in phase by
    k Omega delay_s."""

    delay_s: float = 0.0


@dataclass(frozen=True)
class SpeedRipple:
    """Sinusoidal ripple of ``amplitude_rpm`` [rpm] at ``frequency_hz`` [Hz] on both speed
    channels, each with its own random phase per record."""

    amplitude_rpm: float = 0.0
    frequency_hz: float = 25.0
    seed: int = 0


_PARTS = {"gains": Gains, "offsets": Offsets, "drift": Drift, "hum": MainsHum, "anti_alias": AntiAlias,
          "skew": Skew, "ripple": SpeedRipple}


@dataclass(frozen=True)
class DaqCorruption:
    """Everything the acquisition chain adds; a setting left ``None`` is absent."""

    gains: Gains | None = None
    offsets: Offsets | None = None
    drift: Drift | None = None
    hum: MainsHum | None = None
    anti_alias: AntiAlias | None = None
    skew: Skew | None = None
    ripple: SpeedRipple | None = None

    def to_dict(self) -> dict:
        """JSON-ready ``{setting: {field: value} or None}``."""
        return {k: (None if getattr(self, k) is None else dataclasses.asdict(getattr(self, k))) for k in _PARTS}

    @classmethod
    def from_dict(cls, doc: dict) -> "DaqCorruption":
        """Inverse of :meth:`to_dict`; unknown settings or fields raise InputError."""
        unknown = sorted(set(doc or {}) - set(_PARTS))
        if unknown:
            raise InputError(f"DAQ settings {', '.join(unknown)}: accepted are {', '.join(_PARTS)}")
        out = {}
        for k, v in (doc or {}).items():
            if v is None:
                continue
            try:
                out[k] = _PARTS[k](**v)
            except TypeError as exc:
                raise InputError(f"DAQ setting {k}: {exc}") from None
        return cls(**out)


def butterworth_sos(cutoff_hz: float, order: int, sample_rate_hz: float) -> np.ndarray:
    """Second-order sections of the digital Butterworth low pass (bilinear, pre-warped so
    that the gain at ``cutoff_hz`` is exactly 1/sqrt(2))."""
    from scipy.signal import butter

    if not 0.0 < cutoff_hz < MAX_CUTOFF_SHARE * sample_rate_hz:
        raise InputError(f"anti-alias cut-off {cutoff_hz!r} Hz: accepted is above 0 and below "
                         f"{MAX_CUTOFF_SHARE:g} x the sample rate ({MAX_CUTOFF_SHARE * sample_rate_hz:g} Hz)")
    if int(order) != order or not 1 <= order <= 12:
        raise InputError(f"anti-alias order {order!r}: accepted is a whole number 1-12")
    return butter(int(order), cutoff_hz, btype="low", fs=sample_rate_hz, output="sos")


def lowpass(x, cutoff_hz: float, order: int, sample_rate_hz: float) -> np.ndarray:
    """``x`` through the causal Butterworth low pass of :func:`butterworth_sos`, starting
    in steady state at ``x[0]``."""
    from scipy.signal import sosfilt, sosfilt_zi

    x = np.asarray(x, dtype=float)
    sos = butterworth_sos(cutoff_hz, order, sample_rate_hz)
    y, _ = sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])
    return y


def fractional_delay(x, delay_samples: float) -> np.ndarray:
    """``x`` delayed by ``delay_samples`` (any real number; negative advances): y[n] =
    x(n - delay), interpolated with a Kaiser-windowed sinc of 2 x DELAY_HALF_TAPS + 1 taps
    (unit gain at 0 Hz). Samples beyond the ends are held at the end values."""
    x = np.asarray(x, dtype=float)
    n_int = int(math.floor(delay_samples))
    frac = float(delay_samples) - n_int
    m = DELAY_HALF_TAPS
    j = np.arange(-m, m + 1)
    u = j - frac
    w = np.i0(DELAY_KAISER_BETA * np.sqrt(np.clip(1.0 - (u / (m + 1)) ** 2, 0.0, None))) / np.i0(DELAY_KAISER_BETA)
    h = np.sinc(u) * w
    h /= h.sum()
    idx = np.arange(len(x)) - n_int
    y = np.zeros_like(x)
    for jj, hj in zip(j, h):
        y += hj * x[np.clip(idx - jj, 0, len(x) - 1)]
    return y


def _phases(seed: int, stream: int, salt: int, n: int) -> np.ndarray:
    return np.random.default_rng([int(seed), int(stream), salt]).uniform(0.0, 2.0 * np.pi, n)


def corrupt(channels, sample_rate_hz: float, daq: DaqCorruption | None, stream: int = 0) -> dict:
    """``channels`` (see the module doc) as the acquisition chain ``daq`` records them,
    sampled at ``sample_rate_hz`` [Hz]; ``stream`` numbers the record (own random walk and
    phases). ``daq`` None returns unchanged copies."""

    out = {k: (None if v is None else np.array(v, dtype=float)) for k, v in channels.items()}
    if daq is None:
        return out
    t = out["time_s"]
    t0 = t - t[0]
    dt = 1.0 / float(sample_rate_hz)
    for i, name in enumerate(TORQUE_CHANNELS):
        x = out[name]
        if daq.gains is not None:
            x = x * (daq.gains.input, daq.gains.output)[i]
        if daq.offsets is not None:
            x = x + (daq.offsets.input_nm, daq.offsets.output_nm)[i]
        if daq.drift is not None:
            d = daq.drift
            x = x + (d.input_nm_per_s, d.output_nm_per_s)[i] * t0
            walk = (d.walk_input_nm_per_sqrt_s, d.walk_output_nm_per_sqrt_s)[i]
            if walk > 0:
                steps = np.random.default_rng([int(d.seed), int(stream), 1, i]).standard_normal(len(x))
                steps[0] = 0.0
                x = x + walk * math.sqrt(dt) * np.cumsum(steps)
        if daq.hum is not None:
            h = daq.hum
            a = (h.input_nm, h.output_nm)[i]
            ph = _phases(h.seed, stream, 2 + i, 2)
            wt = 2.0 * np.pi * h.frequency_hz * t
            x = x + a * (np.cos(wt + ph[0]) + h.third_harmonic * np.cos(3.0 * wt + ph[1]))
        if daq.anti_alias is not None:
            x = lowpass(x, daq.anti_alias.cutoff_hz, daq.anti_alias.order, sample_rate_hz)
        if daq.skew is not None and i == 1 and daq.skew.delay_s != 0.0:
            x = fractional_delay(x, daq.skew.delay_s * sample_rate_hz)
        out[name] = x
    if daq.ripple is not None and daq.ripple.amplitude_rpm != 0.0:
        r = daq.ripple
        ph = _phases(r.seed, stream, 4, len(SPEED_CHANNELS))
        for i, name in enumerate(SPEED_CHANNELS):
            out[name] = out[name] + r.amplitude_rpm * np.sin(2.0 * np.pi * r.frequency_hz * t + ph[i])
    return out


def corrupt_point(point, daq: DaqCorruption | None, stream: int = 0):
    """A :class:`~dampersim.discrepancy.campaign.MeasuredPoint` as ``daq`` records it."""
    ch = corrupt({"time_s": point.time, "input_torque_nm": point.input_torque, "output_torque_nm": point.output_torque,
                  "input_speed_rpm": point.input_speed_rpm, "output_speed_rpm": point.output_speed_rpm},
                 point.sample_rate_hz, daq, stream)
    return dataclasses.replace(point, input_torque=ch["input_torque_nm"], output_torque=ch["output_torque_nm"],
                               input_speed_rpm=ch["input_speed_rpm"], output_speed_rpm=ch["output_speed_rpm"])


def random_corruption(rng, record_rate_hz: float = 5000.0) -> DaqCorruption:
    """A realistic corruption drawn from the NumPy Generator ``rng`` (every setting present,
    each at a random size within these ranges):

    * gains 1 +- 1 % per channel (uniform): torque transducers are calibrated to 0.1-0.5 %,
      amplifier and shunt calibration add as much again; 1 % is a careless worst case;
    * offsets +-2 N m per channel: the zero is set at standstill, but a 3 kN m transducer's
      zero moves by 0.05 % of its range (1.5 N m) per 10 K, and the output flange is
      never quite unloaded when it is set;
    * drift +-0.05 N m/s linear plus a random walk of 0-0.05 N m/sqrt(s) per channel:
      amplifier warm-up over a test of a minute moves the zero by a few N m; the walk
      makes the noise coloured at low frequency;
    * mains hum 0-0.5 N m per channel at 50 Hz (the rig is in Europe), with a third
      harmonic of 0-30 % (transformer saturation, rectifiers); 50 Hz is order 2 at
      1500 rpm and order 1 at 3000 rpm, so it falls on the orders read;
    * anti-alias: 4th-order Butterworth with its cut-off at 0.2-0.4 x ``record_rate_hz``
      (1-2 kHz at the synthetic campaigns' 5 kHz), as rig engineers set the analogue
      filter below the Nyquist frequency;
    * skew of the output channel +-0.2 ms: the two torque chains' amplifiers and filters
      differ in group delay, and a multiplexed ADC samples its channels one after another
      (0.04 ms apart for five channels at 5 kHz);
    * speed ripple 0-2 rpm at 5-60 Hz on both speed channels: tooth-spacing errors of an
      encoder ripple once per revolution (15-47 Hz at 900-2800 rpm), about 0.1 % of speed.
    """

    def seed():
        return int(rng.integers(0, 2**31 - 1))

    u = rng.uniform
    return DaqCorruption(
        gains=Gains(input=float(1.0 + u(-0.01, 0.01)), output=float(1.0 + u(-0.01, 0.01))),
        offsets=Offsets(input_nm=float(u(-2.0, 2.0)), output_nm=float(u(-2.0, 2.0))),
        drift=Drift(input_nm_per_s=float(u(-0.05, 0.05)), output_nm_per_s=float(u(-0.05, 0.05)),
                    walk_input_nm_per_sqrt_s=float(u(0.0, 0.05)), walk_output_nm_per_sqrt_s=float(u(0.0, 0.05)),
                    seed=seed()),
        hum=MainsHum(input_nm=float(u(0.0, 0.5)), output_nm=float(u(0.0, 0.5)), frequency_hz=50.0,
                     third_harmonic=float(u(0.0, 0.3)), seed=seed()),
        anti_alias=AntiAlias(cutoff_hz=float(u(0.2, 0.4) * record_rate_hz), order=4),
        skew=Skew(delay_s=float(u(-2e-4, 2e-4))),
        ripple=SpeedRipple(amplitude_rpm=float(u(0.0, 2.0)), frequency_hz=float(u(5.0, 60.0)), seed=seed()),
    )


__all__ = ["Gains", "Offsets", "Drift", "MainsHum", "AntiAlias", "Skew", "SpeedRipple", "DaqCorruption",
           "butterworth_sos", "lowpass", "fractional_delay", "corrupt", "corrupt_point", "random_corruption",
           "TORQUE_CHANNELS", "SPEED_CHANNELS"]
