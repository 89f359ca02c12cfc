"""Benchmark of reading a large MDF4 recording window by window (the rig-data import's reader).

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

    python bench/bench_import.py                      # in a temporary folder, deleted after
    python bench/bench_import.py --dir DIR --keep     # keep DIR/bench_import.mf4
    python bench/bench_import.py --samples 2000000    # a smaller file
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import resource
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


def _child(args: list) -> dict:
    out = subprocess.run([sys.executable, os.path.abspath(__file__), *args], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dir", help="folder for the file (default: a temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep the file")
    ap.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, help="samples per channel")
    ap.add_argument("--window", type=float, default=WINDOW_S, help="read window [s]")
    ap.add_argument("--child-write", help=argparse.SUPPRESS)
    ap.add_argument("--child-read", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child_write:
        print(json.dumps(write(args.child_write, args.samples)))
        return
    if args.child_read:
        print(json.dumps(read(args.child_read, args.window)))
        return
    tmp = None
    folder = args.dir
    if folder is None:
        tmp = tempfile.TemporaryDirectory(prefix="bench-import-")
        folder = tmp.name
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "bench_import.mf4")
    try:
        w = _child(["--child-write", path, "--samples", str(args.samples)])
        size_mb = os.path.getsize(path) / 1e6
        r = _child(["--child-read", path, "--window", str(args.window)])
    finally:
        if not args.keep and os.path.exists(path):
            os.unlink(path)
        if tmp is not None:
            tmp.cleanup()
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


if __name__ == "__main__":
    main()
