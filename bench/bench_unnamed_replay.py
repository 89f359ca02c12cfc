"""The unnamed smooth misfit's evidence gain beside "none", and the posterior it gives,
recomputed from what a benchmark run kept, under variants of the misfit, without running
the model again.

A run of ``bench/bench_discrepancy.py --misfit-inputs DIR`` keeps, per case, what the
diagnosis computed the misfit's gain from (``Diagnosis.misfit_inputs``: "none"'s
standardised training residual, the Jacobian and prior precisions of its evidence columns,
their offsets from the prior centres, the learning rate and the torsional basis; the ramps'
residual, sensitivities, covariance, sample variances, basis and effective share). This
script reads those files beside the run's JSON lines and prints, per case:

* the run's D_torsional, D_ramps and log evidence gain, and the same recomputed from the
  kept inputs: they must agree (to 1e-9 nats; the same arithmetic on the same arrays), or
  the script reports the case and exits with status 1 (the inputs are not those of that
  run: incomplete, stale, or from another run of the same case);
* what the torsional basis takes of the residual: the chi^2 left after the calibration and
  the channels' gain and delay (the residual projected off their columns, least squares
  without their priors), the part of it the basis takes up as well, and that part as the
  tempered likelihood reads it (times the learning rate);
* for every variant (the run's settings, each ``--eta``, each ``--torsion-sds`` grid):
  D_torsional, D_ramps, the gain and the three most probable models. A variant changes
  only the misfit's term: every other model's log evidence is the run's, so a learning
  rate other than the run's is read by the misfit alone (the effects stay tempered as
  they were; the script says nothing about how their evidence would move).

    python bench/bench_discrepancy.py --only ool/rig_inertia/1 --out r.jsonl --misfit-inputs kept --no-recommend
    python bench/bench_unnamed_replay.py --inputs kept --results r.jsonl
    python bench/bench_unnamed_replay.py --inputs kept --results r.jsonl --eta 1 \
        --torsion-sds 0,0.001,0.003,0.01,0.03,0.1
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import zipfile
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_discrepancy as B  # noqa: E402 - the kept inputs' file naming and the JSON lines' reader

from dampersim.discrepancy import selection  # noqa: E402
from dampersim.discrepancy import unnamed as U  # noqa: E402

#: agreement of a recomputed gain with the run's [nats]: the same arithmetic on the same
#: arrays (float64 written to and read from .npz exactly), so only the order of summation
#: inside BLAS could differ, far below this
AGREE_NATS = 1e-9


#: the arrays a case's kept inputs must hold, per part (bench_discrepancy.save_misfit_inputs)
KEYS = {part: set(names) for part, names in U.INPUT_KEYS.items()}


def read_inputs(path) -> dict:
    """A case's kept inputs ({"torsion": {...}, "ramps": {...} or None}) from the .npz that
    bench_discrepancy.save_misfit_inputs wrote; scalars come back as floats. Raises
    ValueError naming the file when it is not such an .npz (unreadable, pickled objects,
    unknown or missing arrays)."""
    out = {"torsion": {}, "ramps": {}}
    try:
        with np.load(path, allow_pickle=False) as f:
            for key in f.files:
                part, _, name = key.partition(".")
                if name not in KEYS.get(part, ()):
                    raise ValueError(f"unknown array {key!r}")
                v = f[key]
                out[part][name] = float(v) if v.ndim == 0 else v
    except (OSError, EOFError, ValueError, TypeError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"{path}: not the kept inputs of a diagnosis ({exc})") from None
    for part, need in KEYS.items():
        if (out[part] and set(out[part]) != need) or (part == "torsion" and not out[part]):
            raise ValueError(f"{path}: {part} lacks {', '.join(sorted(need - set(out[part])))}")
    out["ramps"] = out["ramps"] or None
    return out


def basis_take(torsion: dict) -> tuple:
    """(chi^2 left after the calibration and channels' columns, the part of it the basis
    takes up as well): the residual at the fit less its least-squares fit on the Jacobian,
    and on the Jacobian and the basis together (no priors). Minimum-norm least squares (SVD):
    the basis's degree-0 real column repeats the output gain's, so the columns together are
    rank-deficient, and a plain QR would remove an arbitrary extra direction."""
    r, jac, basis = torsion["r_fit"], torsion["jac"], torsion["basis"]

    def left(cols):
        sol = np.linalg.lstsq(cols, r, rcond=None)[0]
        v = r - cols @ sol
        return float(v @ v)

    after = left(jac)
    return after, after - left(np.column_stack([jac, basis]))


def posterior_with(row, gain: float) -> dict:
    """The run's posterior with "none"'s misfit gain replaced by ``gain`` (every other log
    evidence as the run gave it; a model the JSON holds as null had -inf)."""
    lik = row["likelihood"]
    log_z = {m: (-math.inf if z is None else float(z)) for m, z in lik["log_evidence"].items()}
    log_z["none"] += gain - lik["unnamed_misfit"]["log_evidence"]
    return selection.posterior(log_z, lik["model_prior"])


def _top(post: dict, k: int = 3) -> str:
    return ", ".join(f"{m} {p:.3f}" for m, p in sorted(post.items(), key=lambda t: -t[1])[:k])


def _grid(text: str) -> tuple:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = (math.nan,)
    if any(not math.isfinite(v) or v < 0 for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: accepted is a comma-separated list of spreads >= 0")
    return vals


def _eta(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not 0.0 < v <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: a learning rate lies in (0, 1]")
    return v


def replay(row, inputs, etas=(), grids=()) -> tuple:
    """The printed lines for one case and whether the recomputed gains agree with the run's."""
    run = row["likelihood"]["unnamed_misfit"]
    d_t, d_r = U.gains(inputs)
    ok = abs(d_t - run["torsional"]) <= AGREE_NATS and abs(d_r - run["ramps"]) <= AGREE_NATS
    eta = inputs["torsion"]["eta"]
    after, taken = basis_take(inputs["torsion"])
    lines = [f"{row['id']}: learning rate {eta:.4f}",
             f"  run        D_t {run['torsional']:.4f}  D_r {run['ramps']:.4f}  gain {run['log_evidence']:.4f}",
             f"  recomputed D_t {d_t:.4f}  D_r {d_r:.4f}  " + ("(agrees)" if ok else "DISAGREES with the run"),
             f"  chi^2 after the calibration and channels {after:.1f}; the basis takes {taken:.1f} of it, "
             f"{eta * taken:.1f} as the tempered likelihood reads it"]
    variants = [("as run", None, U.TORSION_SDS)] + [(f"misfit at eta {e:g}", e, U.TORSION_SDS) for e in etas] + \
               [("sds " + ",".join(f"{s:g}" for s in g), None, g) for g in grids]
    for label, e, sds in variants:
        t, r = U.gains(inputs, e, sds)
        g = U.combined(t, r)
        lines.append(f"  {label:34s} D_t {t:8.3f}  D_r {r:7.3f}  gain {g:8.3f}  -> {_top(posterior_with(row, g))}")
    return lines, ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", required=True, metavar="DIR", help="the --misfit-inputs directory of the run")
    ap.add_argument("--results", required=True, nargs="+", metavar="FILE", help="the run's JSON lines (--out)")
    ap.add_argument("--eta", type=_eta, nargs="*", default=[], help="learning rates to read the torsional misfit at")
    ap.add_argument("--torsion-sds", type=_grid, nargs="*", default=[],
                    help="grids of the torsional spreads (relative), e.g. 0,0.001,0.01,0.1")
    a = ap.parse_args(argv)
    if not os.path.isdir(a.inputs):
        ap.error(f"--inputs {a.inputs}: no such directory")
    rows = B.read_files(ap, a.results)
    agree, seen, skipped = True, 0, 0
    for row in rows:
        path = B.inputs_file(a.inputs, str(row.get("id", "")))
        if row.get("error") or not os.path.isfile(path):
            skipped += 1
            continue
        seen += 1
        try:
            lines, ok = replay(row, read_inputs(path), a.eta, a.torsion_sds)
        except (ValueError, KeyError, TypeError) as exc:  # a file or a line not of one run: said, never skipped
            lines, ok = [f"{row.get('id')}: cannot be replayed ({type(exc).__name__}: {exc})"], False
        agree &= ok
        print("\n".join(lines))
    if skipped:
        print(f"{skipped} line(s) of the results without kept inputs (or a failed case): not replayed")
    if not seen:
        print(f"no case of {', '.join(a.results)} has kept inputs in {a.inputs}", file=sys.stderr)
        return 1
    return 0 if agree else 1


if __name__ == "__main__":
    raise SystemExit(main())
