"""Round trip of a diagnosis through rig recordings: a campaign written as rig files in every
format, imported back, diagnosed again, and compared with the diagnosis of the original.

1. A small synthetic campaign with a hidden effect is made by the library's synthesiser
   (:func:`dampersim.discrepancy.synth.synthesize`): the three torsional points of the
   dashboard tests (900 rpm and 1500 rpm at 150 N m, 2000 rpm at 50 N m; three is the
   fewest a diagnosis accepts), 0.6 s records at 5 kHz, a pendulum absorber of
   0.002 kg m^2 hidden in the truth, estimated parameters perturbed by up to 3 %, seed 3.
2. Each point is written as a rig recording in each format (MDF4, TDMS, MAT v5, MAT
   v7.3, CSV) with the channel names and units a rig might use: ``Trq_In`` [kN m],
   ``Torque_Output`` [N m], ``n_In`` [rpm], ``Speed_Out`` [rad/s].
3. The recordings of each format are imported back with ``--cuts`` that cover each
   record (from 0 s to half a sample interval past its last sample), so the imported
   points hold exactly the original samples, found by name and unit matching.
4. The original and every imported campaign are diagnosed
   (:func:`dampersim.discrepancy.diagnose.diagnose` with the dashboard tests' reduced
   options: candidates pendulum_absorber and turbine_drag, one calibration iteration,
   a shortlist of one; ``--full-options``: the diagnosis's own defaults).

Printed per format: the largest relative difference of the order amplitudes (orders
1-8 of :func:`dampersim.signal.order_amplitudes`, input and output torque of every
point, orders carrying at least 2 % of that signal's largest order); the operating
points the import wrote into the manifest; and two diagnoses next to the original's
(verdict, named effect, held-out gaps, noise floor, wall time):

- **as imported**: the import's manifest gives each point's *measured* mean speed and
  torque over its cut, where the synthesiser's manifest gives the *nominal* ones
  (900.246 against 900 rpm: the mean of a 0.6 s record of an oscillating speed). The
  diagnosis runs the model and reads the orders at the manifest speed, so this is the
  diagnosis a user of the import gets;
- **at the original's operating points**: the imported series with the original
  manifest's speed and torque put back, which isolates what the files and the import do
  to the data. Its verdict and named effect must be the original's, otherwise the script
  exits with status 1. Its gaps are printed as the largest relative difference from the
  original's: the torque and speed samples come back bit for bit, but the time column
  is the import's uniform base (i / rate), which differs from the synthesiser's time
  stamps in the last bit (1e-16 s), and the diagnosis does not always keep that small
  (with its default options the calibrated gap moved by 14 %).

    python bench/bench_import_roundtrip.py                        # every format
    python bench/bench_import_roundtrip.py --formats mdf4 csv     # some of them
    python bench/bench_import_roundtrip.py --dir DIR --keep       # keep the files in DIR
    python bench/bench_import_roundtrip.py --full-options         # the diagnosis's own defaults
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time

import numpy as np

#: The dashboard tests' tiny campaign (tests/dashboard/test_discrepancy_page.py TINY_POINTS,
#: TINY_OPTIONS) and the synthesiser's arguments it is made with there.
POINTS = ["map_900_150", "map_1500_150", "map_2000_50"]
OPTIONS = {"candidates": ["pendulum_absorber", "turbine_drag"], "calibration_iterations": 1, "shortlist": 1}
SYNTH = {"effects": [("pendulum_absorber", {"inertia": 0.002})], "perturb": 0.03, "seed": 3, "record": 0.6}
STRONG = 0.02  # orders compared: at least this share of the signal's largest order
GAPS = ("gap_before_nm", "gap_calibrated_nm", "gap_after_nm", "noise_floor_nm")


def largest_order_difference(original, imported) -> tuple:
    """(largest relative difference, point id, signal, order) of the order amplitudes of
    every torsional point's input and output torque, orders carrying >= STRONG of the
    signal's largest order."""
    from dampersim.signal import DEFAULT_ORDERS, order_amplitudes

    back = {p.id: p for p in imported.points}
    worst = (-1.0, "", "", 0.0)
    for p in original.torsional:
        q = back[p.id]
        for signal in ("input_torque", "output_torque"):
            a = order_amplitudes(getattr(p, signal), p.sample_rate_hz, p.speed)
            b = order_amplitudes(getattr(q, signal), q.sample_rate_hz, q.speed)
            strong = a >= STRONG * a.max()
            rel = np.abs(b[strong] - a[strong]) / a[strong]
            k = int(np.argmax(rel))
            if rel[k] > worst[0]:
                worst = (float(rel[k]), p.id, signal, float(np.asarray(DEFAULT_ORDERS)[strong][k]))
    return worst


def summary(diag) -> str:
    effect = f" ({diag.effect})" if diag.effect else ""
    return (f"{diag.verdict}{effect}, held-out gap {diag.gap_before_nm:.3f} / {diag.gap_calibrated_nm:.3f} / "
            f"{diag.gap_after_nm:.3f} N m, floor {diag.noise_floor_nm:.3f} N m")


def with_operating_points(campaign, like):
    """``campaign`` with the manifest speed and mean torque of campaign ``like``'s points."""
    nominal = {p.id: p for p in like.points}
    points = [dataclasses.replace(q, speed_rpm=nominal[q.id].speed_rpm, mean_torque_nm=nominal[q.id].mean_torque_nm)
              for q in campaign.points]
    return dataclasses.replace(campaign, points=points)


def main(argv=None) -> int:
    from dampersim.discrepancy.campaign import read_campaign
    from dampersim.discrepancy.diagnose import diagnose
    from dampersim.discrepancy.synth import synthesize
    from dampersim.rigdata.examples import EXTENSIONS, WRITERS, point_channels, write_recording
    from dampersim.rigdata.importer import import_campaign

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--formats", nargs="+", choices=tuple(WRITERS), default=list(WRITERS), help="formats to try")
    ap.add_argument("--dir", help="folder for the campaigns and recordings (default: a temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep --dir's content")
    ap.add_argument("--workers", type=int, default=None, help="diagnosis worker processes (default: up to 2)")
    ap.add_argument("--full-options", action="store_true",
                    help="diagnose with diagnose()'s own defaults (every candidate, 6 calibration iterations)")
    args = ap.parse_args(argv)
    options = {} if args.full_options else OPTIONS
    tmp = None
    folder = args.dir
    if folder is None or not args.keep:
        tmp = tempfile.TemporaryDirectory(prefix="bench-roundtrip-", dir=folder)
        folder = tmp.name
    os.makedirs(folder, exist_ok=True)
    series_same = True
    try:
        start = time.perf_counter()
        synthesize(os.path.join(folder, "original"), points=POINTS, **SYNTH)
        original = read_campaign(os.path.join(folder, "original"), strict=True)
        print(f"campaign: {len(original.points)} torsional points ({', '.join(POINTS)}), {SYNTH['record']:g} s at "
              f"{original.points[0].sample_rate_hz:g} Hz, hidden pendulum absorber 0.002 kg m^2, synthesised in "
              f"{time.perf_counter() - start:.1f} s")
        print(f"diagnosis ({'diagnose() defaults' if args.full_options else 'options of the dashboard tests'}): "
              "verdict (effect), held-out gap as given / calibrated / augmented, noise floor")
        start = time.perf_counter()
        reference = diagnose(original, workers=args.workers, **options)
        print(f"original: {summary(reference)} ({time.perf_counter() - start:.1f} s)")
        for fmt in args.formats:
            src = os.path.join(folder, f"recordings-{fmt}")
            os.makedirs(src)
            rows, files = ["id,kind,source_file,start_s,end_s"], []
            for p in original.points:
                files.append(write_recording(os.path.join(src, f"{p.id}{EXTENSIONS[fmt]}"), point_channels(p), fmt))
                end = float(p.time[-1]) + 0.5 / p.sample_rate_hz
                rows.append(f"{p.id},{p.kind},{os.path.basename(files[-1])},0,{end!r}")
            cuts = os.path.join(folder, f"cuts-{fmt}.csv")
            with open(cuts, "w") as fh:
                fh.write("\n".join(rows) + "\n")
            start = time.perf_counter()
            # the files in the original's order: the diagnosis holds out every third point
            report = import_campaign(files, os.path.join(folder, f"imported-{fmt}"), cuts_path=cuts)
            imported = read_campaign(os.path.join(folder, f"imported-{fmt}"), strict=True)
            import_s = time.perf_counter() - start
            assert [p.id for p in imported.points] == [p.id for p in original.points]
            rel, pid, signal, order = largest_order_difference(original, imported)
            operating = ", ".join(f"{q.speed_rpm:g} rpm {q.mean_torque_nm:g} N m" for q in imported.points)
            where = f"{pid} {signal}, order {order:g}" if rel > 0 else "the amplitudes are bit for bit the same"
            print(f"{fmt}: {len(imported.points)} points imported in {import_s:.2f} s, {len(report.dropped)} dropped; "
                  f"largest order-amplitude difference {100 * rel:.2g} % ({where})")
            print(f"  manifest operating points as imported (measured means): {operating}")
            start = time.perf_counter()
            diag = diagnose(imported, workers=args.workers, **options)
            print(f"  as imported: {summary(diag)} ({time.perf_counter() - start:.1f} s); verdict "
                  f"{'same as' if diag.verdict == reference.verdict else 'DIFFERS from'} the original")
            start = time.perf_counter()
            diag_n = diagnose(with_operating_points(imported, original), workers=args.workers, **options)
            gaps = max(abs(getattr(diag_n, g) / getattr(reference, g) - 1.0) for g in GAPS)
            same = (diag_n.verdict, diag_n.effect) == (reference.verdict, reference.effect)
            series_same &= same
            print(f"  at the original's operating points: {summary(diag_n)} ({time.perf_counter() - start:.1f} s); "
                  f"verdict {'same as' if same else 'DIFFERS from'} the original, gaps and floor within "
                  f"{100 * gaps:.2g} % of its")
        return 0 if series_same else 1
    finally:
        if tmp is not None:
            tmp.cleanup()


if __name__ == "__main__":
    sys.exit(main())
