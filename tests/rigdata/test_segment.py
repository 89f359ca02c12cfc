"""Segmentation of a long synthetic rig recording into torsional plateaus and ramp protocols.

The recording: speed and mean torque step through plateaus, each step settling over about
0.5 s (damped second order, overshoot), an order-2 excitation of 100-300 N m on the torque,
white noise of 1 % of the signal on both traces, 50 Hz hum, an offset on both, and one
hysteresis protocol (0 -> +450 -> -180 -> 0 N m at 50 N m/s, 2 s holds) at a steady speed.
The truth of each plateau's settled start is computed from the noise-free means with the
detector's own tolerances.
"""

import re

import numpy as np
import pytest

from dampersim.discrepancy.campaign import MIN_TORSIONAL_S
from dampersim.errors import InputError
from dampersim.excitation.ramps import TorqueRamp
from dampersim.rigdata.resample import common_time_base
from dampersim.rigdata.segment import (
    SPEED_TOLERANCE,
    TORQUE_TOLERANCE,
    Segment,
    SegmentList,
    apply_edits,
    find_segments,
    segment_table,
)

FS = 2000.0  # [Hz] as recorded
T0 = 100.0  # [s] the recording's clock does not start at 0
TORQUE_OFFSET = 7.0  # [N m] transducer zero offset
SPEED_OFFSET = 3.0  # [rpm]
#: (kind, speed [rpm], torque [N m], dwell [s], order-2 amplitude [N m]); the third plateau
#: settles for only ~0.4 s: too short for the order analysis, it must be rejected.
PLAN = [("plateau", 1000, 150, 4.0, 200), ("plateau", 1500, 250, 3.5, 300), ("plateau", 2000, 100, 0.9, 150),
        ("plateau", 2000, 300, 3.0, 100), ("lead", 1200, 0, 1.5, 0), ("ramp", 1200, 0, None, 0),
        ("plateau", 2500, 200, 3.0, 250), ("plateau", 800, -120, 3.5, 150)]
RAMP = TorqueRamp(speed=1200 * np.pi / 30, points=(0, 450, -180, 0), rate=50.0, hold=2.0, lead=1.0)


def still_to_go(t, zeta, wn):
    """Fraction of a step still to go at t >= 0 [s] (1 -> 0): damped second order."""
    wd = wn * np.sqrt(1 - zeta**2)
    return np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))


def recording(seed=1, plan=PLAN):
    """(t [s], speed [rpm], torque [N m], truth); truth: (kind, settled start, end, rpm,
    torque, step time) per plateau and ramp protocol, times [s] on the recording's clock."""
    rng = np.random.default_rng(seed)
    knots_t, knots_y = RAMP.knots()
    spans, start = [], 0.0
    for kind, rpm, tq, dwell, amp in plan:
        dwell = RAMP.duration if kind == "ramp" else dwell
        spans.append((start, start + dwell, kind, rpm, tq, amp))
        start += dwell
    t = np.arange(int(start * FS)) / FS
    speed, mean, amps = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    truth, prev = [], None
    for a, b, kind, rpm, tq, amp in spans:
        sel = (t >= a) & (t < b)
        tl = t[sel] - a
        s = np.full(tl.size, float(rpm))
        m = np.interp(tl, knots_t, knots_y) if kind == "ramp" else np.full(tl.size, float(tq))
        if prev is not None and kind != "ramp":
            s += (prev[0] - rpm) * still_to_go(tl, 0.7, 12.0)
            m += (prev[1] - tq) * still_to_go(tl, 0.5, 16.0)
        speed[sel], mean[sel], amps[sel] = s, m, amp
        if kind == "plateau":
            ok = ((np.abs(s - rpm) <= max(SPEED_TOLERANCE[0] * rpm, SPEED_TOLERANCE[1]))
                  & (np.abs(m - tq) <= max(TORQUE_TOLERANCE[0] * abs(tq), TORQUE_TOLERANCE[1])))
            bad = np.flatnonzero(~ok)
            truth.append(("torsional", a + (tl[bad[-1] + 1] if bad.size else 0.0), b, rpm, tq, a))
        elif kind == "ramp":
            truth.append(("ramp", a + knots_t[1], a + knots_t[-2], rpm, None, a))
        prev = (rpm, knots_y[-1] if kind == "ramp" else tq)
    theta = np.cumsum(speed * np.pi / 30) / FS
    hum = np.sin(2 * np.pi * 50.0 * t)
    torque = (mean + amps * np.sin(2 * theta + 0.3) + 4.5 * rng.standard_normal(t.size) + 4.5 * hum
              + TORQUE_OFFSET)
    speed_m = (speed * (1 + 0.004 * np.sin(2 * theta) + 0.01 * rng.standard_normal(t.size)) + 2.0 * hum
               + SPEED_OFFSET)
    shift = lambda row: (row[0], row[1] + T0, row[2] + T0, row[3], row[4], row[5] + T0)  # noqa: E731
    return t + T0, speed_m, torque, [shift(r) for r in truth]


@pytest.fixture(scope="module")
def run():
    return recording()


@pytest.fixture(scope="module", params=["as recorded", "at 200 Hz"])
def found(request, run):
    t, speed, torque, truth = run
    if request.param == "at 200 Hz":  # as the importer cuts: resampled first
        t, cols, _ = common_time_base({"s": (t, speed), "q": (t, torque)}, rate_hz=200.0)
        speed, torque = cols["s"], cols["q"]
    return find_segments(t, speed, torque), truth


def usable(truth):
    return [r for r in truth if r[0] == "ramp" or r[2] - r[1] >= MIN_TORSIONAL_S]


def test_every_plateau_and_ramp_is_found_and_none_invented(found):
    segments, truth = found
    assert isinstance(segments, SegmentList) and segments.segments == list(segments)
    assert [s.kind for s in segments] == [r[0] for r in usable(truth)]
    for seg, (kind, settled, end, rpm, tq, step) in zip(segments, usable(truth)):
        assert seg.speed_rpm == pytest.approx(rpm + SPEED_OFFSET, rel=0.005)
        if kind == "torsional":
            assert seg.mean_torque_nm == pytest.approx(tq + TORQUE_OFFSET, abs=3.0)
            assert "torque ripple" in seg.note


def test_each_window_lies_in_its_plateau_within_0_2_s_of_the_settled_start_and_end(found):
    segments, truth = found
    for seg, (kind, settled, end, rpm, tq, step) in zip(segments, usable(truth)):
        where = f"{kind} at {rpm} rpm, settled {settled:.3f}-{end:.3f} s, found {seg.start_s:.3f}-{seg.end_s:.3f} s"
        assert abs(seg.start_s - settled) <= 0.2 and abs(seg.end_s - end) <= 0.2, where
        if kind == "torsional":
            assert step <= seg.start_s < seg.end_s <= end, where
    ramp = next(s for s in segments if s.kind == "ramp")
    path = re.search(r"ramp protocol (.*) N m at", ramp.note).group(1).split(" -> ")
    np.testing.assert_allclose([float(v) for v in path], np.array([0, 450, -180, 0]) + TORQUE_OFFSET, atol=15)
    assert "at 50 N m/s" in ramp.note and "3 ramps" in ramp.note


def test_the_short_plateau_is_rejected_with_its_reason(found):
    segments, truth = found
    short = [r for r in truth if r[0] == "torsional" and r[2] - r[1] < MIN_TORSIONAL_S]
    assert len(short) == 1 and len(segments.rejected) == 1
    rej = segments.rejected[0]
    assert rej.kind == "torsional" and abs(rej.start_s - short[0][1]) <= 0.2 and rej.end_s <= short[0][2]
    assert "shorter than" in rej.reason and "MIN_TORSIONAL_S" in rej.reason
    assert segments.span_s[0] == pytest.approx(T0)


def test_a_plateau_without_order_excitation_is_rejected_as_such():
    plan = [("plateau", 1000, 150, 3.0, 200), ("plateau", 1500, 250, 3.0, 0), ("plateau", 2000, 300, 3.0, 100)]
    t, speed, torque, _ = recording(seed=3, plan=plan)
    found = find_segments(t, speed, torque)
    assert [round(s.speed_rpm, -2) for s in found] == [1000, 2000]
    assert len(found.rejected) == 1 and "no order excitation" in found.rejected[0].reason


def test_a_drop_out_splits_a_plateau_and_no_segment_holds_nan(run):
    t, speed, torque, truth = run
    torque = torque.copy()
    torque[(t > T0 + 1.5) & (t < T0 + 1.55)] = np.nan
    found = find_segments(t, speed, torque)
    first = [s for s in found if s.start_s < T0 + 4.0]
    assert len(first) == 2 and first[0].end_s < T0 + 1.5 < T0 + 1.55 < first[1].start_s
    assert "drop-out" in first[0].note and "drop-out" in first[1].note
    for s in found:
        inside = (t >= s.start_s) & (t <= s.end_s)
        assert np.isfinite(torque[inside]).all()


def test_the_review_table_round_trips_and_takes_edits(found, run):
    segments, _ = found
    t, speed, torque, _ = run
    rows = segment_table(segments)
    assert list(rows[0]) == ["id", "kind", "speed_rpm", "mean_torque_nm", "start_s", "end_s"]
    assert apply_edits(segments, rows) == list(segments)  # rounding in the table moves nothing
    as_text = [{k: str(v) for k, v in r.items()} for r in rows]  # a CSV table gives text
    assert apply_edits(segments, as_text) == list(segments)

    edited = [dict(r) for r in rows]
    del edited[1]  # drop the second plateau
    edited[0]["end_s"] = round(edited[0]["end_s"] - 1.0, 3)  # shorten the first
    edited[2]["kind"] = "torsional"  # the ramp protocol, taken as a torsional point
    out = apply_edits(segments, edited, t=t, speed_rpm=speed, torque_nm=torque)
    assert len(out) == len(segments) - 1 and out.rejected == segments.rejected
    assert out[0].end_s == pytest.approx(segments[0].end_s - 1.0, abs=1e-3) and "edited" in out[0].note
    assert out[1] is segments[2] and out[2].kind == "torsional" and out[2].start_s == segments[3].start_s


@pytest.mark.parametrize("change, needle", [
    ({"start_s": 1e6}, "row 1 (id 'seg001'): end_s = .*accepted is a time after start_s"),
    ({"start_s": 50.0}, "row 1 (id 'seg001'): start_s = 50.0: accepted is a time inside the recording"),
    ({"kind": "sweep"}, "row 1 (id 'seg001'): kind = 'sweep': accepted is torsional or ramp"),
    ({"id": "seg999"}, "row 1 (id 'seg999'): id: not a segment of this table"),
    ({"end_s": "soon"}, "row 1 (id 'seg001'): end_s = 'soon': accepted is a finite number"),
    ({"speed_rpm": 1234.0}, "row 1 (id 'seg001'): speed_rpm = 1234.0: a measured value"),
    ({"end_s": T0 + 0.3}, "row 1 (id 'seg001'): end_s = .*window of 0.3 s is too short"),
])
def test_bad_edits_name_the_row_and_the_field(found, change, needle):
    segments, _ = found
    rows = segment_table(segments)
    rows[0] = {**rows[0], **change}
    with pytest.raises(InputError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        apply_edits(segments, rows)


def test_an_id_given_twice_is_refused(found):
    segments, _ = found
    rows = segment_table(segments)
    with pytest.raises(InputError, match=r"row 2 \(id 'seg001'\): id: given twice"):
        apply_edits(segments, [rows[0], rows[0]])


def test_bad_traces_raise():
    t = np.arange(2000) / 200.0
    with pytest.raises(InputError, match="same length"):
        find_segments(t, np.ones(2000), np.ones(1999))
    bumpy = t.copy()
    bumpy[1000:] += 0.5
    with pytest.raises(InputError, match="non-uniform"):
        find_segments(bumpy, np.ones(2000), np.ones(2000))
    with pytest.raises(InputError, match="settle_s"):
        find_segments(t, np.ones(2000), np.ones(2000), settle_s=-1)
    assert find_segments(t, np.full(2000, 1000.0), np.full(2000, 100.0)).rejected[0].reason.startswith("no order")


def test_segments_are_plain_frozen_records():
    seg = Segment("torsional", 1.0, 2.0, 1000.0, 100.0, "n")
    with pytest.raises(AttributeError):
        seg.start_s = 0.0  # type: ignore[misc]
