"""What the controls' held-out reduced chi^2 ranks with: the input channel's draw and the sensor noise.

Reads result files of ``bench/bench_discrepancy.py`` (no model is run). For each control of
the hard matrix it rebuilds the case's acquisition chain from the case seed
(:func:`dampersim.discrepancy.synth.daq_setting`, as the synthesis draws it) and prints:

* the mean, over the held-out points (every third torsional point, from the second, as the
  diagnosis holds them out when it keeps every point: a case whose diagnosis left a point
  out held out others, and this script does not follow that), of the squared error the input channel puts on the drive's mean
  torque, ``(offset + (gain - 1) T)^2``, in units of the variance the diagnosis assumes for
  it (:func:`dampersim.discrepancy.likelihood.input_mean_sd` at the point's mean torque T
  [N m]); 1 on average when the draws match the diagnosis's uncertainty;
* the case's sensor noise [dB re 1 N m] and its held-out reduced chi^2;

then Spearman's rank correlation of the held-out chi^2 with each, over all controls and
over the controls without a changed rig (groups "none" and "calibration").

    python bench/bench_control_draws.py ool.jsonl ool-controls.jsonl controls.jsonl \\
        --add control/calibration/3=1.49
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from scipy.stats import spearmanr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_discrepancy as B  # noqa: E402

from dampersim.discrepancy.benchmark import latest  # noqa: E402
from dampersim.discrepancy.diagnose import held_out_indices  # noqa: E402
from dampersim.discrepancy.likelihood import input_mean_sd  # noqa: E402
from dampersim.discrepancy.synth import daq_setting, plan  # noqa: E402


def held_out_points(n_points: int = 12, n_ramps: int = 1) -> list:
    """The torsional points the diagnosis holds out of a hard-matrix campaign (every third, from the second)."""
    torsional = [p for p in B.point_ids(n_points, n_ramps) if not p.startswith("ramp")]
    return [torsional[i] for i in held_out_indices(len(torsional))]


def input_draw_z2(seed: int, points: list) -> float:
    """Mean over ``points`` of the input channel's squared mean-torque error in units of the
    diagnosis's variance for it, for the acquisition chain the case seed ``seed`` draws."""
    mean_nm = {p[0]: p[3] for p in plan("all")}
    daq = daq_setting("random", seed).to_dict()
    offset, gain = daq["offsets"]["input_nm"], daq["gains"]["input"]
    return float(np.mean([((offset + (gain - 1.0) * mean_nm[p]) / input_mean_sd(mean_nm[p])) ** 2 for p in points]))


def control_rows(rows: list, added: dict | None = None) -> list:
    """[(id, group, held-out reduced chi^2, input draw z^2, sensor noise dB)] of the hard
    matrix's controls among ``rows`` (each case once, by its last successful line) and of
    ``added`` {case id: held-out chi^2} (controls diagnosed by another script)."""
    cases = {c["id"]: c for c in B.hard_cases()}
    chi = {r["id"]: (r.get("likelihood") or {}).get("reduced_chi2_held_out") for r in latest(rows)[0]
           if r.get("kind") == "control"}
    chi.update(added or {})
    held = held_out_points()
    out = []
    for cid, value in chi.items():
        if value is None or cid not in cases:
            continue
        c = cases[cid]
        out.append((cid, c["group"], float(value), input_draw_z2(c["seed"], held), float(c["noise_db"])))
    return sorted(out, key=lambda r: r[2])


def rank_correlations(table: list) -> dict:
    """Spearman's rho and its p value of the held-out chi^2 with the input draw and the
    noise, over all rows and over the rows of groups "none" and "calibration"."""
    out = {}
    for name, rs in (("all", table), ("without rig changes", [r for r in table if r[1] in ("none", "calibration")])):
        if len(rs) < 3:
            continue
        chi, z2, noise = (np.array([r[k] for r in rs]) for k in (2, 3, 4))
        out[name] = {"n": len(rs), "input_draw": tuple(map(float, spearmanr(z2, chi))),
                     "noise": tuple(map(float, spearmanr(noise, chi)))}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", help="result files of bench_discrepancy.py, read in this order")
    ap.add_argument("--add", nargs="*", default=[], metavar="ID=CHI2",
                    help="controls diagnosed elsewhere, with their held-out reduced chi^2")
    a = ap.parse_args(argv)
    rows = B.read_files(ap, a.files)
    added = {}
    for item in a.add:
        cid, _, value = item.partition("=")
        try:
            added[cid] = float(value)
        except ValueError:
            ap.error(f"--add {item!r}: accepted is CASE_ID=CHI2, e.g. control/calibration/3=1.49")
    table = control_rows(rows, added)
    print(f"{'control':28s} {'group':16s} {'chi2 held out':>13s} {'input draw z2':>13s} {'noise dB':>9s}")
    for cid, group, chi, z2, noise in table:
        print(f"{cid:28s} {group:16s} {chi:13.2f} {z2:13.2f} {noise:+9.2f}")
    for name, c in rank_correlations(table).items():
        print(f"{name} (n={c['n']}): Spearman rho with the input draw {c['input_draw'][0]:+.2f} "
              f"(p {c['input_draw'][1]:.2f}), with the noise {c['noise'][0]:+.2f} (p {c['noise'][1]:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
