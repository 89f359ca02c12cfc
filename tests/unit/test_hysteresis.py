"""Hysteresis analysis: filter, knee, dynamic stiffness, loop energy; one short real loop."""

import argparse
import json
import math

import numpy as np
import pytest

import dampersim
from dampersim.analysis import hysteresis as hy
from dampersim.cli.analysis import add_parsers, parse_speeds_rpm
from dampersim.errors import InputError
from dampersim.units import deg_to_rad, rpm_to_rad_s

K1, K2 = 380.0, 2400.0  # N m/rad: stiffness below / above the knee (default-set-like)
TK = 300.0  # N m: elastic torque at the knee
F = 20.0  # N m: friction band half width
DT_NM = 0.5  # N m per sample: puts the knee torques TK +- F exactly on samples


def _elastic_windup(te):
    """Bilinear spring: windup [rad] at elastic torque te [N m] (knee only on the positive side)."""
    return np.where(te <= TK, te / K1, TK / K1 + (te - TK) / K2)


def _play(torque, stop_at=None):
    """Coulomb-friction play operator: the elastic torque follows the applied one within +-F.

    Loading runs along T = g(theta) + F, unloading along T = g(theta) - F, and at each
    reversal the windup stays put while the torque changes by 2F: the textbook friction
    loop, whose area is exactly 2 F (theta_max - theta_min) per closed cycle.
    """
    te = np.empty_like(torque)
    e = 0.0
    for i, tq in enumerate(torque):
        if tq - e > F:
            e = tq - F
        elif e - tq > F:
            e = tq + F
        te[i] = e
    w = _elastic_windup(te)
    if stop_at is not None:
        w = np.minimum(w, stop_at)
    return w


def _ramp(points):
    """Torque samples [N m] through ``points`` in steps of DT_NM."""
    out = [np.array([points[0]])]
    for a, b in zip(points[:-1], points[1:]):
        n = int(round(abs(b - a) / DT_NM))
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)


# --- filter -------------------------------------------------------------------------------
def _amplitude(y, fs, f):
    t = np.arange(y.size) / fs
    A = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    return math.hypot(c[0], c[1])


def test_lowpass_is_minus_3db_at_the_break_and_passes_dc():
    fs = 1000.0
    t = np.arange(int(5 * fs)) / fs
    x = np.sin(2 * np.pi * 10.0 * t)
    y = hy.lowpass_first_order(x, fs)  # thesis default: 1st order, 10 Hz
    last = slice(-int(fs), None)  # the start transient (tau = 16 ms) has died out after 4 s
    # pre-warped bilinear transform: |H(10 Hz)| = 1/sqrt(2) exactly; 1e-6 covers the fit
    assert _amplitude(y[last], fs, 10.0) == pytest.approx(1 / math.sqrt(2), abs=1e-6)
    # at 100 Hz the bilinear filter's gain is K / sqrt(K^2 + tan^2(pi f / fs)), K = tan(pi fc / fs)
    # (~0.096, near the analogue fc/f = 0.1); same 1e-6 fit tolerance
    y100 = hy.lowpass_first_order(np.sin(2 * np.pi * 100.0 * t), fs)
    k = math.tan(math.pi * 10.0 / fs)
    assert _amplitude(y100[last], fs, 100.0) == pytest.approx(k / math.hypot(k, math.tan(math.pi * 100.0 / fs)), abs=1e-6)
    # starts in steady state: a constant passes through unchanged from the first sample
    assert np.allclose(hy.lowpass_first_order(np.full(50, 3.0), fs), 3.0, rtol=0, atol=1e-12)
    # zero phase: squared magnitude (-6 dB) and no lag
    z = hy.lowpass_first_order(x, fs, zero_phase=True)
    mid = slice(int(fs), int(4 * fs))
    assert _amplitude(z[mid], fs, 10.0) == pytest.approx(0.5, abs=1e-3)  # 1e-3: filtfilt edge padding
    lag = np.argmax(np.correlate(z[mid], x[mid], "full")) - (z[mid].size - 1)
    assert lag == 0
    with pytest.raises(InputError, match="cutoff"):
        hy.lowpass_first_order(x, 15.0)
    with pytest.raises(InputError, match="NaN"):
        hy.lowpass_first_order(np.array([1.0, np.nan, 2.0]), fs)


# --- synthetic bilinear loop -------------------------------------------------------------------
def test_knee_and_stiffness_of_a_synthetic_bilinear_loop():
    torque = _ramp([0.0, 450.0, -180.0, 0.0])
    windup = _play(torque)
    kn = hy.find_knee(torque, windup)
    assert kn.found
    # exact bilinear data: only the bounded search's tolerance remains (1e-6 relative)
    assert kn.torque_nm == pytest.approx(TK + F, rel=1e-6)
    assert kn.windup_rad == pytest.approx(TK / K1, rel=1e-6)
    assert kn.stiffness_below == pytest.approx(K1, rel=1e-6)
    assert kn.stiffness_above == pytest.approx(K2, rel=1e-6)
    assert kn.rms_residual_rad < 1e-9
    d = kn.to_dict("deg")
    assert d["windup_deg"] == pytest.approx(math.degrees(TK / K1), rel=1e-6)
    assert d["stiffness_below_nm_per_deg"] == pytest.approx(K1 * math.pi / 180, rel=1e-6)


def test_knee_of_a_set_that_stops_on_its_hardstop_has_infinite_stiffness_above():
    stop = deg_to_rad(30.0)
    torque = _ramp([0.0, 400.0, 0.0])
    windup = _play(torque, stop_at=stop)
    kn = hy.find_knee(torque, windup)
    assert kn.found and kn.stiffness_above == math.inf
    assert kn.windup_rad == pytest.approx(stop, rel=1e-6)  # fit tolerance as above
    assert kn.stiffness_below == pytest.approx(K1, rel=1e-6)


def test_no_knee_on_a_linear_loop_reports_branch_stiffness():
    torque = _ramp([0.0, 250.0, -100.0, 0.0])  # stays below TK: one slope only
    kn = hy.find_knee(torque, _play(torque))
    assert not kn.found and math.isnan(kn.windup_rad) and math.isnan(kn.stiffness_above)
    assert kn.stiffness_below == pytest.approx(K1, rel=1e-9)  # straight-line fit of exact data


def test_dynamic_stiffness_along_the_synthetic_loop():
    torque = _ramp([0.0, 450.0, -180.0, 0.0])
    windup = _play(torque)
    k = hy.dynamic_stiffness(torque, windup, window_nm=10.0)
    s = hy.branch_directions(torque)
    load = s > 0
    # windows entirely on one straight piece return its slope; 1e-6 covers the round-off of
    # the running sums the windows are computed from
    below = load & (torque > F + 10) & (torque < TK + F - 10)
    above = load & (torque > TK + F + 10) & (torque < 440)
    assert np.allclose(k[below], K1, rtol=1e-6)
    assert np.allclose(k[above], K2, rtol=1e-6)
    # where the windup is stuck (reversal inside the friction band) the slope is unbounded: NaN
    stuck = load & (torque > 2) & (torque < F - 10)
    assert stuck.any() and np.all(np.isnan(k[stuck]))
    # unloading ramp sees the same springs
    unload = (s < 0) & (torque < TK - F - 10) & (torque > -150)
    assert np.allclose(k[unload], K1, rtol=1e-6)


def test_loop_energy_of_a_closed_cycle_is_two_f_times_the_windup_range():
    torque = _ramp([0.0, 450.0, -180.0, 450.0, -180.0])
    windup = _play(torque)
    first_bottom = int(np.flatnonzero(torque == -180.0)[0])
    t, w = torque[first_bottom:], windup[first_bottom:]
    assert w[0] == w[-1]  # one exactly closed cycle
    exact = 2 * F * (w.max() - w.min())
    # the knee torques are samples, so the trapezoid rule is exact up to round-off
    assert hy.loop_energy(t, w, closed=False) == pytest.approx(exact, rel=1e-9)
    # traversed the other way round (counter-clockwise) the sign flips
    assert hy.loop_energy(t[::-1], w[::-1], closed=False) == pytest.approx(-exact, rel=1e-9)


def test_closed_part_and_analysis_of_an_open_ramp_loop():
    torque = np.concatenate([np.zeros(100), _ramp([0.0, 450.0, -180.0, 0.0]), np.zeros(100)])
    windup = _play(torque)
    i0, i1 = hy.closed_part(torque, windup)
    assert torque[i0] == 0.0 and torque[i0 + 1] > 0.0  # last sample of the lead-in
    assert torque[i1] == 0.0 and i1 > torque.size - 150
    loop = hy.HysteresisLoop.from_arrays(torque, windup, sample_rate_hz=100.0, speed_rad_s=rpm_to_rad_s(1500))
    a = hy.analyse_loop(loop)
    # the play loop ends at g^-1(-F) = -F/K1: that is the closure gap it reports
    assert a.closure_gap_rad == pytest.approx(-F / K1, rel=1e-9)
    assert a.knee.found and a.knee.windup_rad == pytest.approx(TK / K1, rel=1e-6)
    # energy: the closed cycle's 2 F dtheta less the corner cut by the closing segment,
    # at most F * F / K1 (a triangle F high and F/K1 wide, cut in half)
    full = 2 * F * (windup.max() - windup.min())
    assert full - F * F / K1 <= a.energy_j <= full
    assert a.outer_knee is None and a.outer_hardstop_positive_rad is None
    json.dumps(a.to_dict())  # JSON-ready: no NaN/inf leaks


def test_filtered_loop_and_input_errors():
    torque = _ramp([0.0, 450.0, -180.0, 0.0])
    loop = hy.HysteresisLoop.from_arrays(torque, _play(torque), sample_rate_hz=1000.0)
    f = loop.filtered()
    assert f.lowpass_hz == 10.0 and f.torque_nm.shape == torque.shape
    assert not np.allclose(f.torque_nm, torque)
    with pytest.raises(InputError, match="time_s"):
        hy.HysteresisLoop.from_arrays(torque, torque)
    with pytest.raises(InputError, match="outer"):
        loop.windup("outer")
    with pytest.raises(InputError, match="equal length"):
        hy.find_knee(torque, torque[:-1])
    with pytest.raises(InputError, match="branch"):
        hy.find_knee(torque, torque, branch="up")


# --- one short real simulation loop ------------------------------------------------------------------
@pytest.fixture(scope="module")
def real_loop():
    # full-100 ramp at 1000 rpm, 4x the thesis's rate and 0.2 s holds: 3.4 s simulated
    system = dampersim.default_parameters()
    return hy.run_loops(system, "full-100", [rpm_to_rad_s(1000.0)], rate=200.0, hold=0.2)[0]


def test_real_loop_stays_within_hardstops_and_dissipates(real_loop):
    system = real_loop.result.parameters
    assert real_loop.result.sample_rate == pytest.approx(1000.0)  # run_loops' 1 kHz default
    tol = deg_to_rad(0.1)  # docs/model.md §6: a limit is never exceeded by more than 0.1 deg
    for which, s in (("outer", system.outer), ("inner", system.inner)):
        w = real_loop.windup(which)
        assert w.max() <= s.hardstop_positive + tol and w.min() >= s.hardstop_negative - tol
    # +-100 N m stays below the positive knee: total windup about 100 N m / 6 N m/deg
    assert 10.0 < math.degrees(real_loop.windup_rad.max()) < 25.0
    a = hy.analyse_loop(real_loop)
    assert not a.knee.found  # 100 N m is far below the ~300 N m knee
    assert a.energy_j > 0
    # the loop area is the energy the spring friction dissipated over the same samples;
    # 10 % leaves room for rig shaft and contact damping and the small closure gap
    i0, i1 = hy.closed_part(real_loop.torque_nm, real_loop.windup_rad)
    fric = real_loop.result.energy["friction"]
    assert a.energy_j == pytest.approx(fric[i1] - fric[i0], rel=0.10)
    assert abs(math.degrees(a.closure_gap_rad)) < 0.05  # returns to its start within 0.05 deg


def test_hysteresis_command(real_loop, capsys, tmp_path):
    p = argparse.ArgumentParser()
    add_parsers(p.add_subparsers(dest="command"))
    args = p.parse_args(["hysteresis", "--speeds", "1000", "--protocol", "full-100", "--rate", "200", "--hold", "0.2", "--json", "--out", str(tmp_path)])
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["protocol"] == "full-100" and len(out["loops"]) == 1
    assert out["loops"][0]["energy_per_loop_j"] > 0
    assert out["loops"][0]["outer_hardstop_positive_deg"] == pytest.approx(45.0)
    assert (tmp_path / "hysteresis-full-100.html").exists()
    with pytest.raises(InputError, match="300 to 6000 rpm"):
        parse_speeds_rpm("1000,100")
    with pytest.raises(InputError, match="not a number"):
        parse_speeds_rpm("1000,fast")
    bad = p.parse_args(["hysteresis", "--rate", "0"])
    with pytest.raises(InputError, match="--rate"):
        bad.func(bad)
