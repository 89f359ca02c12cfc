"""DAQ corruption of recorded channels: each setting does what it documents, and only that.

Every test measures the corruption it names against the clean channels, so it fails when
that corruption is removed (an assertion that the change is present, not only bounded).
"""

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.signal import sosfreqz

from dampersim.discrepancy import daq as D
from dampersim.discrepancy import synth
from dampersim.discrepancy.campaign import MeasuredPoint, read_campaign
from dampersim.errors import InputError

FS = 5000.0
T = np.arange(0.0, 2.0, 1.0 / FS)
RPM = 1500.0
OMEGA = RPM * math.pi / 30.0


def channels(tin=None, tout=None):
    z = np.zeros_like(T)
    return {"time_s": T.copy(), "input_torque_nm": z.copy() if tin is None else tin.copy(),
            "output_torque_nm": z.copy() if tout is None else tout.copy(),
            "input_speed_rpm": np.full_like(T, RPM), "output_speed_rpm": np.full_like(T, RPM)}


def lockin(x, f, t=T, skip=0.2):
    """Complex amplitude of ``x`` at ``f`` [Hz] over whole seconds after ``skip`` s (whole
    periods of every whole-hertz frequency used here, so that they do not leak)."""
    dt = t[1] - t[0]
    start = int(round(skip / dt))
    n = int(round(int((len(t) - start) * dt + 1e-9) / dt))
    sl = slice(start, start + n)
    return 2.0 * np.mean(x[sl] * np.exp(-2j * np.pi * f * t[sl]))


def test_skew_shifts_the_phase_of_an_order_by_k_omega_tau():
    tau = 1.5e-4
    for k in (2.0, 6.0):
        sig = 100.0 * np.cos(k * OMEGA * T + 0.3)
        ch = channels(sig, sig)
        clean = D.corrupt(ch, FS, D.DaqCorruption())
        out = D.corrupt(ch, FS, D.DaqCorruption(skew=D.Skew(delay_s=tau)))
        f = k * OMEGA / (2 * np.pi)
        dphi = np.angle(lockin(out["output_torque_nm"], f) / lockin(out["input_torque_nm"], f))
        assert dphi == pytest.approx(-k * OMEGA * tau, abs=2e-4)
        assert k * OMEGA * tau > 0.04  # large enough that no skew fails the line above
        assert np.angle(lockin(clean["output_torque_nm"], f) / lockin(clean["input_torque_nm"], f)) == pytest.approx(0, abs=1e-9)
        # the amplitude is kept: interpolation, not a smoothing filter
        assert abs(lockin(out["output_torque_nm"], f)) == pytest.approx(100.0, rel=1e-3)
        np.testing.assert_array_equal(out["input_torque_nm"], sig)


def test_negative_skew_advances_the_output_and_whole_samples_shift_exactly():
    x = np.sin(np.linspace(0, 40, len(T)))
    np.testing.assert_allclose(D.fractional_delay(x, 3.0)[3:], x[:-3], atol=1e-12)
    np.testing.assert_allclose(D.fractional_delay(x, -2.0)[:-2], x[2:], atol=1e-12)


@pytest.mark.parametrize("f", [300.0, 800.0, 1500.0])
def test_anti_alias_filter_attenuates_by_the_butterworth_magnitude(f):
    fs, fc, order = 10000.0, 1000.0, 4
    t = np.arange(0.0, 1.5, 1.0 / fs)
    sig = np.cos(2 * np.pi * f * t)
    ch = {"time_s": t, "input_torque_nm": sig, "output_torque_nm": 2 * sig,
          "input_speed_rpm": np.zeros_like(t), "output_speed_rpm": np.zeros_like(t)}
    out = D.corrupt(ch, fs, D.DaqCorruption(anti_alias=D.AntiAlias(cutoff_hz=fc, order=order)))
    _, h = sosfreqz(D.butterworth_sos(fc, order, fs), worN=[f], fs=fs)
    for name, a in (("input_torque_nm", 1.0), ("output_torque_nm", 2.0)):
        got = lockin(out[name], f, t, skip=0.05)
        # magnitude and (causal) phase lag of the digital filter
        assert abs(got / (a * h[0]) - 1.0) < 1e-3
        # the Butterworth magnitude 1/sqrt(1 + (f/fc)^2n), at the bilinear transform's
        # warped frequencies tan(pi f/fs) (equal to f/fc well below the Nyquist frequency)
        ratio = math.tan(math.pi * f / fs) / math.tan(math.pi * fc / fs)
        assert abs(got) / a == pytest.approx(1.0 / math.sqrt(1.0 + ratio ** (2 * order)), rel=1e-3)
    assert abs(h[0]) < 0.95 or np.angle(h[0]) < -0.5  # the filter does act at these frequencies
    np.testing.assert_array_equal(out["input_speed_rpm"], ch["input_speed_rpm"])  # encoders are not filtered


def test_anti_alias_filter_is_causal_and_starts_settled():
    x = np.zeros(2000)
    x[1000:] = 1.0
    y = D.lowpass(x, 500.0, 4, 5000.0)
    assert np.all(y[:1000] == 0.0) and y[1001] < 0.05 and y[-1] == pytest.approx(1.0, abs=1e-6)
    assert np.all(D.lowpass(np.full(500, 3.0), 500.0, 4, 5000.0) == pytest.approx(3.0))
    with pytest.raises(InputError):
        D.butterworth_sos(2600.0, 4, 5000.0)


def test_mains_hum_shows_at_50_hz_and_its_third_harmonic():
    hum = D.MainsHum(input_nm=0.4, output_nm=0.2, third_harmonic=0.25, seed=3)
    out = D.corrupt(channels(), FS, D.DaqCorruption(hum=hum))
    assert abs(lockin(out["input_torque_nm"], 50.0, skip=0)) == pytest.approx(0.4, rel=1e-6)
    assert abs(lockin(out["output_torque_nm"], 50.0, skip=0)) == pytest.approx(0.2, rel=1e-6)
    assert abs(lockin(out["input_torque_nm"], 150.0, skip=0)) == pytest.approx(0.1, rel=1e-6)
    assert abs(lockin(out["input_torque_nm"], 75.0, skip=0)) < 1e-6
    # each record (stream) picks the mains at another phase
    other = D.corrupt(channels(), FS, D.DaqCorruption(hum=hum), stream=1)
    assert np.angle(lockin(other["input_torque_nm"], 50.0, skip=0)) != pytest.approx(
        np.angle(lockin(out["input_torque_nm"], 50.0, skip=0)), abs=1e-3)


def test_gains_offsets_and_drift():
    base = 100.0 + 50.0 * np.cos(2 * OMEGA * T)
    ch = channels(base, base)
    out = D.corrupt(ch, FS, D.DaqCorruption(gains=D.Gains(1.01, 0.995), offsets=D.Offsets(1.5, -2.0),
                                            drift=D.Drift(0.05, -0.02)))
    np.testing.assert_allclose(out["input_torque_nm"], 1.01 * base + 1.5 + 0.05 * T, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["output_torque_nm"], 0.995 * base - 2.0 - 0.02 * T, rtol=0, atol=1e-9)
    assert ch["input_torque_nm"] is not out["input_torque_nm"] and np.all(ch["input_torque_nm"] == base)


def test_drift_random_walk_grows_with_the_square_root_of_time():
    walks = []
    for stream in range(200):
        out = D.corrupt(channels(), FS, D.DaqCorruption(drift=D.Drift(walk_input_nm_per_sqrt_s=0.05, seed=1)), stream)
        walks.append(out["input_torque_nm"][[int(0.5 * FS), -1]])
        assert np.all(out["output_torque_nm"] == 0.0)
    sd = np.std(walks, axis=0)
    assert sd[0] == pytest.approx(0.05 * math.sqrt(0.5), rel=0.15)
    assert sd[1] == pytest.approx(0.05 * math.sqrt(T[-1]), rel=0.15)


def test_speed_ripple_on_both_speed_channels():
    r = D.SpeedRipple(amplitude_rpm=1.5, frequency_hz=25.0, seed=4)
    out = D.corrupt(channels(), FS, D.DaqCorruption(ripple=r))
    a_in = lockin(out["input_speed_rpm"] - RPM, 25.0, skip=0)
    a_out = lockin(out["output_speed_rpm"] - RPM, 25.0, skip=0)
    assert abs(a_in) == pytest.approx(1.5, rel=1e-6) and abs(a_out) == pytest.approx(1.5, rel=1e-6)
    assert abs(np.angle(a_in / a_out)) > 1e-3  # own phase per channel
    assert np.all(out["input_torque_nm"] == 0.0)


def test_the_corruption_is_reproducible_from_the_seed():
    a = D.random_corruption(np.random.default_rng(11))
    b = D.random_corruption(np.random.default_rng(11))
    c = D.random_corruption(np.random.default_rng(12))
    assert a == b and a != c
    sig = 200.0 + 80.0 * np.cos(2 * OMEGA * T)
    x1 = D.corrupt(channels(sig, 0.7 * sig), FS, a, stream=2)
    x2 = D.corrupt(channels(sig, 0.7 * sig), FS, b, stream=2)
    x3 = D.corrupt(channels(sig, 0.7 * sig), FS, a, stream=3)
    for k in D.TORQUE_CHANNELS + D.SPEED_CHANNELS:
        np.testing.assert_array_equal(x1[k], x2[k])
        assert not np.array_equal(x1[k], x3[k])  # another record: another walk and other phases
    doc = json.loads(json.dumps(a.to_dict()))
    assert D.DaqCorruption.from_dict(doc) == a
    with pytest.raises(InputError):
        D.DaqCorruption.from_dict({"bogus": {}})


def test_random_corruption_stays_in_its_stated_ranges():
    rng = np.random.default_rng(0)
    for _ in range(200):
        d = D.random_corruption(rng, 5000.0)
        assert abs(d.gains.input - 1) <= 0.01 and abs(d.gains.output - 1) <= 0.01
        assert abs(d.offsets.input_nm) <= 2 and abs(d.offsets.output_nm) <= 2
        assert abs(d.drift.input_nm_per_s) <= 0.05 and 0 <= d.drift.walk_output_nm_per_sqrt_s <= 0.05
        assert 0 <= d.hum.input_nm <= 0.5 and d.hum.frequency_hz == 50.0 and 0 <= d.hum.third_harmonic <= 0.3
        assert 1000.0 <= d.anti_alias.cutoff_hz <= 2000.0 and d.anti_alias.order == 4
        assert abs(d.skew.delay_s) <= 2e-4
        assert 0 <= d.ripple.amplitude_rpm <= 2 and 5 <= d.ripple.frequency_hz <= 60


def test_no_daq_changes_nothing_and_a_point_can_be_corrupted():
    sig = 50.0 * np.cos(2 * OMEGA * T)
    ch = channels(sig, sig)
    out = D.corrupt(ch, FS, None)
    for k in ch:
        np.testing.assert_array_equal(out[k], ch[k])
    p = MeasuredPoint(id="p", kind="torsional", speed_rpm=RPM, mean_torque_nm=0.0, sample_rate_hz=FS, time=T,
                      input_torque=sig, output_torque=sig, input_speed_rpm=ch["input_speed_rpm"],
                      output_speed_rpm=ch["output_speed_rpm"])
    q = D.corrupt_point(p, D.DaqCorruption(offsets=D.Offsets(1.0, 2.0)))
    assert q.id == "p" and np.mean(q.output_torque - p.output_torque) == pytest.approx(2.0)
    np.testing.assert_array_equal(p.output_torque, sig)


class _FakeResult:
    """What synth reads of a simulation: a 2nd-order torsional record at 10 kHz."""

    def __init__(self, system, ex, record_segments=False):
        self.sample_rate = 10000.0
        self.t = np.arange(0.0, ex.duration, 1.0 / self.sample_rate)
        self.input_torque = ex.torque(self.t)
        self.output_torque = 0.8 * self.input_torque
        self.speed_primary = np.full_like(self.t, ex.speed)
        self.speed_motor = np.full_like(self.t, ex.speed)
        self.windup_total = np.zeros_like(self.t)

    def window(self, seconds):
        n = int(round(seconds * self.sample_rate))
        return slice(len(self.t) - n, len(self.t))


def test_synth_records_through_the_daq_and_writes_it_to_the_truth(tmp_path, monkeypatch):
    monkeypatch.setattr(synth, "simulate", _FakeResult)
    calls = []

    def spy(ch, fs, daq, stream=0):
        out = D.corrupt(ch, fs, daq, stream)
        calls.append((ch, fs, stream, out))
        return out

    monkeypatch.setattr(synth, "corrupt", spy)
    kw = {"points": ["map_1500_150"], "record": 0.6, "perturb": 0.0, "seed": 4, "noise_db": -80.0}
    plain = synth.synthesize(tmp_path / "a", truth=tmp_path / "ta.json", **kw)
    assert not calls  # no DAQ: the plain path, as before
    noisy = synth.synthesize(tmp_path / "b", truth=tmp_path / "tb.json", daq="random", **kw)
    again = synth.synthesize(tmp_path / "c", daq="random", **kw)
    assert plain["daq"] is None and json.loads((tmp_path / "tb.json").read_text())["daq"] == noisy["daq"]
    assert noisy["daq"] == again["daq"] and noisy["channel_gains"]["input"] == noisy["daq"]["gains"]["input"]
    pa, pb, pc = (read_campaign(tmp_path / x).points[0] for x in "abc")
    np.testing.assert_array_equal(pb.output_torque, pc.output_torque)
    # the DAQ records the whole run from its start at the simulation's rate; the record is
    # then cut (last 0.6 s) and sampled at 5 kHz
    ch, fs, stream, out = calls[0]
    assert fs == 10000.0 and stream == 0 and ch["time_s"][0] == 0.0 and len(ch["time_s"]) > 6000
    for name, got in (("input_torque_nm", pb.input_torque), ("output_torque_nm", pb.output_torque),
                      ("input_speed_rpm", pb.input_speed_rpm)):
        np.testing.assert_allclose(got, out[name][-6000:][::2], atol=5.0 if "speed" in name else 1e-3)
    clean = pa.output_torque / plain["channel_gains"]["output"]
    np.testing.assert_allclose(clean, ch["output_torque_nm"][-6000:][::2], atol=1e-3)
    assert np.sqrt(np.mean((pb.output_torque - clean) ** 2)) > 0.3  # the DAQ did change the record
    with pytest.raises(InputError):
        synth.daq_setting("sometimes")
    assert synth.daq_setting("none") is None and dataclasses.is_dataclass(synth.daq_setting("random", 1))
