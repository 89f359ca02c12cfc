"""Benchmarks of the rig-data import on 500 MB MDF4 files: the reader window by window, and a full import.

Part 1: writes an MDF4 file of about 500 MB (one channel group: a float64 time master and
5 float64 channels at 20 kHz, 10.5 M samples each; written in chunks with asammdf's
``MDF.append`` + ``MDF.extend``, which keep the samples in a temporary file, so writing
needs about one chunk of memory), then reads every channel window by window with
``Recording.read_window`` in a child process that does nothing else, and prints:

- file size [MB], write time [s] and the writer's peak RSS [MB] (its own child process,
  next to its RSS after importing asammdf);
- open time [s] (block check + one streaming pass over the time stamps);
- read wall time [s] for all channels, throughput [MB/s] = file size / (open + read time),
  samples read, and the reader's peak RSS [MB] (``resource.getrusage`` ``ru_maxrss`` of
  the child) next to its RSS after the imports, before opening the file.

Every ``read_window`` reads the group's records of that window, all channels at once
(MDF4 stores records), so reading 5 channels one after the other reads the file 5 times
(from the page cache after the first pass); the throughput counts the file once.

Part 2: a full import of a long recording. Writes an MDF4 file of about 500 MB that
looks like a rig run (channels as :func:`dampersim.rigdata.examples.long_recording_channels`
names them: ``Trq_In`` [kN m] and ``Torque_Output`` [N m] in a 20 kHz group, ``n_In``
[rpm], ``Speed_Out`` [rad/s] and ``Windup_Angle`` [rad] in a 5 kHz group), generated and
written 10 s at a time so that the recording is never held whole in memory. Its
programme repeats a cycle of six torsional plateaus of 8 s (speed and mean torque step,
then settle through second-order lags with overshoot; order 2 content on both torques)
and one hysteresis protocol (0 -> 450 -> -180 -> 0 N m at 50 N m/s, 2 s holds) at a
steady speed without order excitation, preceded by a 2.5 s unexcited level while the
speed settles; each cycle shifts the speeds and torques a little, so no two points are
the same. Then ``import_campaign([file], out)`` runs in a child process that does
nothing else, and the script prints:

- file size [MB], recording length, write time [s] and the writer's peak RSS [MB];
- import wall time [s] (open, segmentation, every point read, resampled and written,
  the written campaign read back and checked), throughput [MB/s] = file size / wall
  time, and the importing child's peak RSS [MB] next to its RSS after the imports; a
  thread samples the child's RSS every 20 ms and keeps its peak per step of the import
  (each step marked by the importer function that starts it);
- the segmentation step alone (open + speed and torque traces at 500 Hz + finding the
  segments) in a second child: wall time and peak RSS;
- the points found against the programme: a found point counts when its kind matches,
  its window lies inside one programme item (plateau, or protocol with its 1 s leads;
  0.05 s of lag allowed at the end, the measured signals follow a step with a lag) and
  its speed (and, for a plateau, its mean torque) is that item's within the segmenter's
  tolerance; missed = programme items without a point, invented = points matching no
  item or an item already taken;
- the import report's dropped lines, and what the written points hold: samples and
  size on disk, and their float64 size in memory (the importer keeps every point until
  it writes the campaign, so that size is a floor of its peak memory).

    python bench/bench_import.py                      # in a temporary folder, deleted after
    python bench/bench_import.py --dir DIR --keep     # keep DIR/bench_import.mf4 (and DIR/bench_long.mf4)
    python bench/bench_import.py --samples 2000000    # a smaller file
    python bench/bench_import.py --part 2             # only the full import (--part 1: only the reading)
    python bench/bench_import.py --part 2 --long-mb 50   # a smaller long recording
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

CHANNELS = ("Trq_In", "Torque_Output", "n_In", "Speed_Out", "Windup")
UNITS = ("kN m", "N m", "rpm", "rad/s", "deg")
RATE_HZ = 20_000.0
CHUNK = 1_000_000  # samples per written chunk
DEFAULT_SAMPLES = 10_500_000  # 5 channels + time, float64: 48 bytes a record -> about 504 MB
WINDOW_S = 10.0  # read window [s]


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def _chunk(lo: int, hi: int):
    """Time [s] and 5 synthetic channels of samples lo:hi."""
    t = np.arange(lo, hi, dtype=np.float64) / RATE_HZ
    phase = 2.0 * math.pi * 25.0 * t
    return t, [0.2 + 0.05 * np.sin(2 * phase), 200.0 + 40.0 * np.sin(2 * phase - 0.6),
               1500.0 + 3.0 * np.sin(2 * phase), 157.0 + 0.1 * np.cos(phase), 4.0 * np.sin(2 * phase - 0.3)]


def write(path: str, samples: int) -> dict:
    """Write the benchmark file in chunks; returns write time and peak RSS."""
    from asammdf import MDF, Signal

    baseline = _peak_rss_mb()
    start = time.perf_counter()
    folder = os.path.dirname(os.path.abspath(path))
    mdf = MDF(version="4.10", temporary_folder=folder)
    t, xs = _chunk(0, min(CHUNK, samples))
    mdf.append([Signal(x, t, name=n, unit=u) for n, u, x in zip(CHANNELS, UNITS, xs)], acq_name="fast")
    for lo in range(CHUNK, samples, CHUNK):
        t, xs = _chunk(lo, min(lo + CHUNK, samples))
        mdf.extend(0, [(t, None)] + [(x, None) for x in xs])
    mdf.save(path, overwrite=True)
    mdf.close()
    return {"write_s": time.perf_counter() - start, "write_peak_rss_mb": _peak_rss_mb(), "baseline_rss_mb": baseline}


def read(path: str, window_s: float) -> dict:
    """Open ``path`` and read every channel window by window; times and peak RSS."""
    from dampersim.rigdata.readers import open_recording

    importlib.import_module("asammdf")  # imported before the baseline: the reader needs it

    baseline = _peak_rss_mb()
    start = time.perf_counter()
    rec = open_recording(path)
    opened = time.perf_counter()
    samples, checksum, largest = 0, 0.0, 0
    with rec:
        for info in rec.channels:
            end = info.samples / info.rate_hz
            for k in range(int(math.ceil(end / window_s)) + 1):
                t, x = rec.read_window(info.name, k * window_s, (k + 1) * window_s)
                samples += x.size
                largest = max(largest, x.size)
                checksum += float(x.sum())
    done = time.perf_counter()
    return {"open_s": opened - start, "read_s": done - opened, "samples_read": samples, "largest_window": largest,
            "channels": len(rec.channels), "checksum": checksum, "baseline_rss_mb": baseline,
            "read_peak_rss_mb": _peak_rss_mb()}


# -- part 2: full import of a long recording --------------------------------------------

LONG_FAST_HZ = 20_000.0  # torque group [Hz]
LONG_SLOW_HZ = 5_000.0  # speed and windup group [Hz]
LONG_STRIDE = int(round(LONG_FAST_HZ / LONG_SLOW_HZ))
LONG_CHUNK_S = 10.0  # generated and written per chunk [s]
#: bytes a second of recording: float64 time + 2 channels at 20 kHz, time + 3 at 5 kHz
LONG_BYTES_PER_S = 8 * 3 * LONG_FAST_HZ + 8 * 4 * LONG_SLOW_HZ
DEFAULT_LONG_MB = 500.0
PLATEAU_S = 8.0  # [s] per plateau, settling included
#: one cycle's plateaus (speed [rpm], mean torque [N m]); cycle c adds 25 rpm x (c mod 4)
#: and 10 N m x (c mod 5)
PLATEAUS = ((1000.0, 100.0), (1500.0, 250.0), (2000.0, 150.0), (2500.0, 350.0), (1200.0, 50.0), (1800.0, 300.0))
PROTOCOL_RPM = (1200.0, 1600.0, 2000.0)  # cycle c runs its protocol at PROTOCOL_RPM[c mod 3]
PROTOCOL_POINTS = (0.0, 450.0, -180.0, 0.0)  # [N m], [thesis] Table 3.1 full-450
PROTOCOL_LEAD_S = 2.5  # unexcited level at the protocol's speed before it [s]: the speed settles
LAG_S = 0.05  # [s] the measured signals stay in a plateau's band this long after the next step
WINDUP_STIFFNESS = 381.0  # [N m/rad] the default set's outer stage


def programme(long_mb: float) -> list:
    """Items ``{kind, start, end, rpm, torque, knots}`` (kind torsional, lead or ramp; times
    [s]; a ramp's ``knots`` are (times from its start [s], torques [N m])) of whole cycles
    reaching ``long_mb`` MB."""
    from dampersim.excitation.ramps import TorqueRamp

    ramp = TorqueRamp(speed=1.0, points=PROTOCOL_POINTS, rate=50.0, hold=2.0, lead=1.0)
    knots = ramp.knots()
    target_s = long_mb * 1e6 / LONG_BYTES_PER_S
    items, t, c = [], 0.0, 0
    while t < target_s:
        for rpm, torque in PLATEAUS:
            items.append({"kind": "torsional", "start": t, "end": t + PLATEAU_S, "rpm": rpm + 25.0 * (c % 4),
                          "torque": torque + 10.0 * (c % 5), "knots": None})
            t += PLATEAU_S
        rpm = PROTOCOL_RPM[c % len(PROTOCOL_RPM)]
        items.append({"kind": "lead", "start": t, "end": t + PROTOCOL_LEAD_S, "rpm": rpm, "torque": 0.0, "knots": None})
        t += PROTOCOL_LEAD_S
        items.append({"kind": "ramp", "start": t, "end": t + ramp.duration, "rpm": rpm, "torque": None, "knots": knots})
        t += ramp.duration
        c += 1
    return items


class _Lag:
    """Second-order lag (natural frequency [Hz], damping) run chunk by chunk: the
    settling transients of :func:`dampersim.rigdata.examples.long_recording_channels`."""

    def __init__(self, rate_hz: float, natural_hz: float, damping: float = 0.6):
        from scipy import signal

        wn = 2.0 * math.pi * natural_hz
        sys_d = signal.cont2discrete(([wn * wn], [1.0, 2.0 * damping * wn, wn * wn]), 1.0 / rate_hz, method="bilinear")
        self.b, self.a = np.ravel(sys_d[0]), np.ravel(sys_d[1])
        self.zi = None

    def __call__(self, x):
        from scipy import signal

        if self.zi is None:
            self.zi = signal.lfilter_zi(self.b, self.a) * x[0]
        y, self.zi = signal.lfilter(self.b, self.a, x, zi=self.zi)
        return y


def long_chunks(items, seed: int = 1):
    """The recording of ``items``, LONG_CHUNK_S at a time: yields (t fast [s], Trq_In [kN m],
    Torque_Output [N m], t slow [s], n_In [rpm], Speed_Out [rad/s], Windup_Angle [rad])."""
    rng = np.random.default_rng(seed)
    total = int(round(items[-1]["end"] * LONG_FAST_HZ)) // LONG_STRIDE * LONG_STRIDE
    chunk = int(LONG_CHUNK_S * LONG_FAST_HZ)
    starts = np.array([it["start"] for it in items])
    speed_lag, torque_lag = _Lag(LONG_FAST_HZ, 0.8), _Lag(LONG_FAST_HZ, 2.0)
    angle0 = 0.0
    for lo in range(0, total, chunk):
        t = np.arange(lo, min(lo + chunk, total), dtype=np.float64) / LONG_FAST_HZ
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(items) - 1)
        speed_cmd, torque_cmd, excited = np.empty_like(t), np.empty_like(t), np.zeros(t.size)
        for j in np.unique(k):
            m = k == j
            it = items[j]
            speed_cmd[m] = it["rpm"]
            torque_cmd[m] = np.interp(t[m] - it["start"], *it["knots"]) if it["kind"] == "ramp" else it["torque"]
            excited[m] = it["kind"] == "torsional"
        rpm = speed_lag(speed_cmd)
        mean_torque = torque_lag(torque_cmd)
        angle = angle0 + np.cumsum(rpm * (2.0 * math.pi / 60.0)) / LONG_FAST_HZ  # rotation angle [rad]
        angle0 = float(angle[-1])
        amp = (0.3 * np.abs(mean_torque) + 40.0) * excited
        trq_in = mean_torque + amp * np.sin(2.0 * angle) + rng.normal(0.0, 2.0, t.size)
        trq_out = mean_torque + 0.25 * amp * np.sin(2.0 * angle - 0.6) + rng.normal(0.0, 1.0, t.size)
        s = slice(0, t.size, LONG_STRIDE)
        ts = t[s]
        n_in = rpm[s] + 3.0 * np.sin(2.0 * angle[s]) * excited[s] + rng.normal(0.0, 0.5, ts.size)
        speed_out = (rpm[s] - 2.0) * (2.0 * math.pi / 60.0) + rng.normal(0.0, 0.02, ts.size)
        windup = mean_torque[s] / WINDUP_STIFFNESS + rng.normal(0.0, 1e-4, ts.size)
        yield t, trq_in / 1000.0, trq_out, ts, n_in, speed_out, windup


def write_long(path: str, long_mb: float) -> dict:
    """Write the long recording chunk by chunk; returns write time and peak RSS."""
    from asammdf import MDF, Signal

    baseline = _peak_rss_mb()
    start = time.perf_counter()
    mdf = MDF(version="4.10", temporary_folder=os.path.dirname(os.path.abspath(path)))
    for k, (t, trq_in, trq_out, ts, n_in, speed_out, windup) in enumerate(long_chunks(programme(long_mb))):
        if k == 0:
            mdf.append([Signal(trq_in, t, name="Trq_In", unit="kN m"),
                        Signal(trq_out, t, name="Torque_Output", unit="N m")], acq_name="torque 20 kHz")
            mdf.append([Signal(n_in, ts, name="n_In", unit="rpm"),
                        Signal(speed_out, ts, name="Speed_Out", unit="rad/s"),
                        Signal(windup, ts, name="Windup_Angle", unit="rad")], acq_name="speed 5 kHz")
        else:
            mdf.extend(0, [(t, None), (trq_in, None), (trq_out, None)])
            mdf.extend(1, [(ts, None), (n_in, None), (speed_out, None), (windup, None)])
    mdf.save(path, overwrite=True)
    mdf.close()
    return {"write_s": time.perf_counter() - start, "write_peak_rss_mb": _peak_rss_mb(), "baseline_rss_mb": baseline}


def _import_baseline():
    """Import what the importer will use, so that the baseline RSS counts the libraries."""
    for name in ("asammdf", "pandas", "pyarrow.parquet", "scipy.signal", "dampersim.rigdata.importer",
                 "dampersim.rigdata.readers.mdf"):
        importlib.import_module(name)
    return _peak_rss_mb()


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return math.nan


#: steps of import_campaign whose peak RSS is reported, by the importer function that
#: starts each (the step runs until the next one starts)
PHASES = (("_segment_traces", "segmentation traces"), ("_point", "cutting a point"),
          ("write_point", "writing a point"), ("check_point", "reading it back (check)"),
          ("write_manifest", "writing the manifest"))


def import_long(path: str, out: str) -> dict:
    """``import_campaign([path], out)``: wall time, peak RSS and the report; the RSS is
    also sampled every 20 ms by a thread, and its peak kept per step of the import."""
    import threading

    baseline = _import_baseline()
    from dampersim.rigdata import importer

    state = {"phase": "opening", "peaks": {}, "stop": False}

    def sample():
        while not state["stop"]:
            ph = state["phase"]
            state["peaks"][ph] = max(state["peaks"].get(ph, 0.0), _rss_mb())
            time.sleep(0.02)

    def marked(fn, label):
        def run(*a, **kw):
            state["phase"] = label
            return fn(*a, **kw)
        return run

    for name, label in PHASES:
        setattr(importer, name, marked(getattr(importer, name), label))
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    start = time.perf_counter()
    report = importer.import_campaign([path], out)
    wall = time.perf_counter() - start
    state["stop"] = True
    sampler.join()
    return {"import_s": wall, "import_peak_rss_mb": _peak_rss_mb(), "baseline_rss_mb": baseline,
            "phase_peaks_mb": state["peaks"], "points": report.points, "dropped": report.dropped,
            "lines": report.lines}


def segment_long(path: str) -> dict:
    """The import's segmentation step alone: open, the 500 Hz traces, find_segments."""
    baseline = _import_baseline()
    from dampersim.rigdata import importer, mapping, segment
    from dampersim.rigdata.readers import open_recording

    start = time.perf_counter()
    with open_recording(path) as rec:
        specs = dict(mapping.resolve(rec.channels, None).specs)
        t, speed, torque = importer._segment_traces(rec, specs)
        found = segment.find_segments(t, speed, torque)
    return {"segment_s": time.perf_counter() - start, "segment_peak_rss_mb": _peak_rss_mb(),
            "baseline_rss_mb": baseline, "segments": len(found.segments), "trace_samples": int(t.size)}


def match_points(items, points) -> tuple:
    """(matched, missed items, invented points) of found ``points`` against ``items``."""
    from dampersim.rigdata.segment import SPEED_TOLERANCE, TORQUE_TOLERANCE

    expected = [it for it in items if it["kind"] in ("torsional", "ramp")]
    taken, invented = set(), []
    for p in points:
        hits = [i for i, it in enumerate(expected)
                if it["kind"] == p["kind"] and it["start"] - 1e-6 <= p["start_s"] < p["end_s"] <= it["end"] + LAG_S
                and abs(p["speed_rpm"] - it["rpm"]) <= max(SPEED_TOLERANCE[0] * it["rpm"], SPEED_TOLERANCE[1])
                and (it["kind"] == "ramp" or abs(p["mean_torque_nm"] - it["torque"])
                     <= max(TORQUE_TOLERANCE[0] * abs(it["torque"]), TORQUE_TOLERANCE[1]))]
        if len(hits) == 1 and hits[0] not in taken:
            taken.add(hits[0])
        else:
            invented.append(p)
    missed = [it for i, it in enumerate(expected) if i not in taken]
    return len(taken), missed, invented


def campaign_size(folder: str) -> dict:
    """Samples, columns and size of the written points: on disk and as float64 in memory."""
    import pyarrow.parquet as pq

    disk, samples, in_memory = 0, 0, 0
    for name in os.listdir(os.path.join(folder, "points")):
        path = os.path.join(folder, "points", name)
        disk += os.path.getsize(path)
        meta = pq.ParquetFile(path).metadata
        samples += meta.num_rows
        in_memory += 8 * meta.num_rows * meta.num_columns
    return {"disk_mb": disk / 1e6, "samples": samples, "float64_mb": in_memory / 1e6}


def _child(args: list) -> dict:
    out = subprocess.run([sys.executable, os.path.abspath(__file__), *args], capture_output=True, text=True)
    if out.returncode != 0:
        sys.stderr.write(out.stderr)
        raise SystemExit(f"child {args[0]} failed with status {out.returncode}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def part1(folder: str, args) -> None:
    path = os.path.join(folder, "bench_import.mf4")
    try:
        w = _child(["--child-write", path, "--samples", str(args.samples)])
        size_mb = os.path.getsize(path) / 1e6
        r = _child(["--child-read", path, "--window", str(args.window)])
    finally:
        if not args.keep and os.path.exists(path):
            os.unlink(path)
    total = r["open_s"] + r["read_s"]
    print(f"MDF4 file: {size_mb:.1f} MB ({r['channels']} float64 channels x {args.samples} samples + time, "
          f"{RATE_HZ:g} Hz, one channel group)")
    print(f"write:  {w['write_s']:.1f} s, writer peak RSS {w['write_peak_rss_mb']:.0f} MB "
          f"(after imports: {w['baseline_rss_mb']:.0f} MB; chunks of {CHUNK} samples)")
    print(f"open:   {r['open_s']:.2f} s (block check + time-stamp scan)")
    print(f"read:   {r['read_s']:.2f} s for every channel in {args.window:g} s windows "
          f"({r['largest_window']} samples each), {r['samples_read']} samples")
    print(f"throughput: {size_mb / total:.0f} MB/s (file size / (open + read))")
    print(f"reader peak RSS: {r['read_peak_rss_mb']:.0f} MB (after imports, before opening: {r['baseline_rss_mb']:.0f} MB)")


def part2(folder: str, args) -> None:
    path = os.path.join(folder, "bench_long.mf4")
    out = os.path.join(folder, "bench_long_campaign")
    items = programme(args.long_mb)
    try:
        w = _child(["--child-write-long", path, "--long-mb", str(args.long_mb)])
        size_mb = os.path.getsize(path) / 1e6
        m = _child(["--child-import", path, "--out", out])
        size = campaign_size(out)
        g = _child(["--child-segment", path])
    finally:
        shutil.rmtree(out, ignore_errors=True)
        if not args.keep and os.path.exists(path):
            os.unlink(path)
    n_plateaus = sum(it["kind"] == "torsional" for it in items)
    n_ramps = sum(it["kind"] == "ramp" for it in items)
    matched, missed, invented = match_points(items, m["points"])
    found_kinds = [p["kind"] for p in m["points"]]
    print(f"MDF4 file: {size_mb:.1f} MB, a {items[-1]['end'] / 60:.1f} min rig run: {n_ramps} cycles of "
          f"{len(PLATEAUS)} plateaus of {PLATEAU_S:g} s and a torque-ramp protocol; Trq_In, Torque_Output at "
          f"{LONG_FAST_HZ:g} Hz, n_In, Speed_Out, Windup_Angle at {LONG_SLOW_HZ:g} Hz (float64)")
    print(f"write:  {w['write_s']:.1f} s in {LONG_CHUNK_S:g} s chunks, writer peak RSS {w['write_peak_rss_mb']:.0f} MB "
          f"(after imports: {w['baseline_rss_mb']:.0f} MB)")
    print(f"import: {m['import_s']:.1f} s wall, {size_mb / m['import_s']:.1f} MB/s; importer peak RSS "
          f"{m['import_peak_rss_mb']:.0f} MB (after imports: {m['baseline_rss_mb']:.0f} MB)")
    print("  peak RSS by step [MB]: " + ", ".join(f"{k} {v:.0f}" for k, v in m["phase_peaks_mb"].items()))
    print(f"  segmentation alone (open, speed and torque at 500 Hz, find_segments): {g['segment_s']:.1f} s, "
          f"peak RSS {g['segment_peak_rss_mb']:.0f} MB (after imports: {g['baseline_rss_mb']:.0f} MB), "
          f"{g['trace_samples']} trace samples")
    print(f"points: {len(m['points'])} found ({found_kinds.count('torsional')} torsional, {found_kinds.count('ramp')} "
          f"ramps) of {n_plateaus + n_ramps} in the programme ({n_plateaus} plateaus, {n_ramps} protocols): "
          f"{matched} matched, {len(missed)} missed, {len(invented)} invented")
    for it in missed:
        print(f"  missed: {it['kind']} {it['start']:.2f}-{it['end']:.2f} s at {it['rpm']:g} rpm")
    for p in invented:
        print(f"  invented: {p['kind']} {p['start_s']:.2f}-{p['end_s']:.2f} s at {p['speed_rpm']:g} rpm")
    print(f"dropped: {len(m['dropped'])}" + "".join(f"\n  {d['kind']} {d['start_s']:.2f}-{d['end_s']:.2f} s: "
                                                  f"{d['reason']}" for d in m["dropped"]))
    print(f"written: {size['samples']} samples per column in {len(m['points'])} points at the file's highest rate, "
          f"{size['disk_mb']:.0f} MB of Parquet (float32), {size['float64_mb']:.0f} MB as float64 (one point at a time in memory)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dir", help="folder for the files (default: a temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep the MDF4 files")
    ap.add_argument("--part", choices=("1", "2", "all"), default="all",
                    help="1: read window by window; 2: full import of a long recording; all: both (default)")
    ap.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, help="part 1: samples per channel")
    ap.add_argument("--window", type=float, default=WINDOW_S, help="part 1: read window [s]")
    ap.add_argument("--long-mb", type=float, default=DEFAULT_LONG_MB, help="part 2: size of the long recording [MB]")
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--child-write", help=argparse.SUPPRESS)
    ap.add_argument("--child-read", help=argparse.SUPPRESS)
    ap.add_argument("--child-write-long", help=argparse.SUPPRESS)
    ap.add_argument("--child-import", help=argparse.SUPPRESS)
    ap.add_argument("--child-segment", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child_write:
        print(json.dumps(write(args.child_write, args.samples)))
        return
    if args.child_read:
        print(json.dumps(read(args.child_read, args.window)))
        return
    if args.child_write_long:
        print(json.dumps(write_long(args.child_write_long, args.long_mb)))
        return
    if args.child_import:
        print(json.dumps(import_long(args.child_import, args.out)))
        return
    if args.child_segment:
        print(json.dumps(segment_long(args.child_segment)))
        return
    tmp = None
    folder = args.dir
    if folder is None:
        tmp = tempfile.TemporaryDirectory(prefix="bench-import-")
        folder = tmp.name
    os.makedirs(folder, exist_ok=True)
    try:
        if args.part in ("1", "all"):
            print("Part 1: reading an MDF4 file window by window")
            part1(folder, args)
        if args.part in ("2", "all"):
            print("Part 2: full import of a long MDF4 recording (plateaus and torque-ramp protocols)")
            part2(folder, args)
    finally:
        if tmp is not None:
            tmp.cleanup()


if __name__ == "__main__":
    main()
