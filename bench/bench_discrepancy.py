"""Benchmark of the discrepancy workflow on synthetic campaigns with hidden effects.

Two case matrices (``--matrix``):

hard (default)
    * every effect at four magnitudes (subtle = half the weak one, or the weak one's
      equivalent for clutch capacity and transducer cut-off, then the library's weak,
      typical and strong ones) with its shape parameters drawn at random
      (dampersim/discrepancy/truths.py), ``--seeds`` of each;
    * two-effect cases: each pair of ``truths.PAIRS`` at the typical magnitude, ``--seeds``
      of each;
    * 22 controls: 8 with no change but the usual parameter perturbation, 10 with one or
      two calibration groups 10-30 % off, 4 with the stiff rig parts changed;
    * 12 out-of-library cases: gearbox shaft stiffness or inertia 20-30 % off, friction
      laws of another shape, another friction split, a retuned output motor.
    Every case has a random DAQ corruption (dampersim/discrepancy/daq.py), sensor noise
    of -6 to +3 dB re 1 N m, 10 % parameter perturbation, ``--points`` torsional points
    and ``--ramps`` hysteresis ramps (default 1). The groups are interleaved, so that the
    first cases of a run already mix every kind.
classic
    The matrix before: every effect x three magnitudes x seeds at the library's default
    shapes, no-effect and mis-calibration controls, no DAQ corruption, no ramps
    (``--reduced``, ``--mags`` and ``--only no_effect|miscalibration`` as before).

Each finished case is appended to ``--out`` as one JSON line at once (a killed run keeps
its work); ``--resume`` skips the cases already in the file. A line holds the case, its
truth (effects with all parameters, parameter changes, DAQ settings, noise) and the
diagnosis's figures. The summary (dampersim/discrepancy/benchmark.py) is printed as a
table at the end, or alone with ``--summary``.

    python bench/bench_discrepancy.py --out bench.jsonl                     # hard matrix (a day)
    python bench/bench_discrepancy.py --out bench.jsonl --resume            # continue it
    python bench/bench_discrepancy.py --list                                # the cases, nothing run
    python bench/bench_discrepancy.py --only pendulum_absorber --limit 1 --points 6 --record 0.6 --ramps 0
    python bench/bench_discrepancy.py --only ool/rig_inertia/1 --out b.jsonl --misfit-inputs kept
    python bench/bench_discrepancy.py --summary bench.jsonl                 # figures of a file
    python bench/bench_discrepancy.py --summary a.jsonl b.jsonl             # ... of several together
    python bench/bench_discrepancy.py --rows a.jsonl b.jsonl                # a Markdown row per case
    python bench/bench_discrepancy.py --matrix classic --only miscalibration --out classic.jsonl
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import tempfile
import time
import traceback
import zlib

import numpy as np

from dampersim.discrepancy import truths
from dampersim.discrepancy.benchmark import case_table, summary, summary_table
from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.diagnose import diagnose
from dampersim.discrepancy.effects import EFFECTS, NAMES
from dampersim.discrepancy.synth import plan, synthesize
from dampersim.jsonsafe import jsonable
from dampersim.keys import NUMBA_CODEGEN_ENV, platform

#: diagnosis keys kept per case (plus every gap_*_nm key)
KEEP = ("verdict", "effect", "effects", "effect_parameters", "posterior", "detectability", "outliers",
        "recommended_points", "likelihood", "calibration", "ranking", "noise_floor_nm", "simulations", "wall_time_s")

MISCAL = (
    {"outer.spring.stiffness": 127.0 * 1.15},
    {"inner.spring.stiffness": 240.0 * 0.85, "inner.nested.stiffness": 240.0 * 0.85},
    {"friction.outer.alpha": 0.6, "friction.pair_outer.alpha": 0.3},
    {"friction.outer.alpha": 0.15},
    {"inertias.primary": 0.22, "inertias.secondary": 0.054},
)
#: hard matrix: controls and out-of-library cases (kind, count)
HARD_CONTROLS = (("none", 8), ("calibration", 10), ("rig_stiff_parts", 4))
HARD_OUT_OF_LIBRARY = (("rig_shaft", 3), ("rig_inertia", 2), ("friction_shape", 3), ("friction_split", 2),
                       ("motor_control", 2))
#: environment settings that change how the same arithmetic is compiled or dispatched, and so
#: a campaign's figures (docs/discrepancy.md, Known limits, "A campaign's figures move with the
#: machine's rounding"; bench_float_paths.py varies three of them)
FLOAT_PATH_ENV = ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", "NUMBA_ENABLE_AVX", *NUMBA_CODEGEN_ENV,
                  "NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")
NOISE_DB = (-6.0, 3.0)  # sensor noise range of the hard matrix [dB re 1 N m]
PERTURB = 0.1  # estimated-parameter perturbation of the hard matrix (synth's default)


def _case(cid, kind, group, truth, seed, perturb, noise_db, daq, level=None):
    return {"id": cid, "kind": kind, "group": group, "level": level, "seed": int(seed), "perturb": perturb,
            "noise_db": float(noise_db), "daq": daq, "spec": truth}


def _seed_of(matrix_seed: int, cid: str) -> int:
    return zlib.crc32(f"{matrix_seed}/{cid}".encode()) % 1_000_000


def hard_cases(seeds: int = 2, matrix_seed: int = 0) -> list:
    """The hard matrix (see the module doc), interleaved across its groups."""

    def make(cid, kind, group, build, level=None):
        seed = _seed_of(matrix_seed, cid)
        rng = np.random.default_rng([matrix_seed, seed])
        truth = build(rng)
        noise = float(rng.uniform(*NOISE_DB))
        return _case(cid, kind, group, truth, seed, PERTURB, noise, "random", level)

    groups = []
    for name in NAMES:
        groups.append([make(f"effect/{name}/{lv}/s{s}", "effect", name,
                            lambda rng, n=name, lv=lv: truths.single(n, lv, rng), lv)
                       for s in range(seeds) for lv in reversed(truths.LEVELS)])
    groups.append([make(f"pair/{a}+{b}/s{s}", "pair", f"{a}+{b}", lambda rng, a=a, b=b: truths.pair(a, b, rng), "typical")
                   for s in range(seeds) for a, b in truths.PAIRS])
    for kind, n in HARD_CONTROLS:
        groups.append([make(f"control/{kind}/{i}", "control", kind, lambda rng, k=kind: truths.control(k, rng))
                       for i in range(n)])
    for kind, n in HARD_OUT_OF_LIBRARY:
        groups.append([make(f"ool/{kind}/{i}", "out_of_library", kind, lambda rng, k=kind: truths.out_of_library(k, rng))
                       for i in range(n)])
    return [c for tier in itertools.zip_longest(*groups) for c in tier if c is not None]


def classic_cases(reduced: bool = False, seeds: int = 3, mags=None) -> list:
    """The matrix before the hard one: library default shapes, no DAQ, no ramps."""
    mags = mags if mags is not None else ((1,) if reduced else (0, 1, 2))
    out = []
    for name in NAMES:
        e = EFFECTS[name]
        for mi in mags:
            for seed in range(1 if reduced else seeds):
                truth = {"effects": [[name, {e.magnitude: e.magnitudes[mi]}]], "updates": {},
                         "description": f"{name} magnitude {mi}"}
                out.append(_case(f"classic/{name}/m{mi}/s{seed}", "effect", name, truth, seed, 0.05, 0.0, None,
                                 truths.LEVELS[mi + 1]))
    for seed in range(2 if reduced else 5):
        out.append(_case(f"classic/no_effect/{seed}", "control", "no_effect",
                         {"effects": [], "updates": {}, "description": "no effect"}, 100 + seed, 0.05, 0.0, None))
    for i, upd in enumerate(MISCAL[:2] if reduced else MISCAL):
        out.append(_case(f"classic/miscalibration/{i}", "control", "miscalibration",
                         {"effects": [], "updates": dict(upd), "description": f"miscalibration {upd}"}, 200 + i, 0.0,
                         0.0, None))
    return out


def selected(cases, only=None) -> list:
    """Cases whose kind, group, level, hidden effect or id matches one of ``only``."""
    if not only:
        return list(cases)
    keep = set(only)

    def hit(c):
        names = {n for n, _ in c["spec"]["effects"]}
        return bool(keep & ({c["kind"], c["group"], c["level"]} | names)) or any(t in c["id"] for t in keep if "/" in t)

    return [c for c in cases if hit(c)]


def point_ids(n_points: int, n_ramps: int) -> list:
    """``n_points`` torsional ids spread over the plan, then ``n_ramps`` ramps (middle speed first)."""
    pts = plan("all")
    ids = [p[0] for p in pts if p[1] == "torsional"]
    ids = ids[::max(1, len(ids) // n_points)][:n_points]
    ramps = [p[0] for p in pts if p[1] == "ramp"]
    ramps = sorted(ramps, key=lambda r: abs(float(r.split("_")[1]) - 1500.0))
    return ids + ramps[:n_ramps]


def machine() -> dict:
    """What a result line's figures depend on besides the code and the case: the versions, the
    CPU numba compiles for, the CPU features numpy reads (a group switched off by
    NPY_DISABLE_CPU_FEATURES, such as X86_V3, reads off while its members may still read on)
    and the OpenBLAS kernels (:func:`dampersim.keys.platform`), and those of
    :data:`FLOAT_PATH_ENV` that are set. The same case moves with them, by more than its
    printed digits, where its truth or its model is chaotic."""
    return {**platform(), "env": {k: os.environ[k] for k in FLOAT_PATH_ENV if k in os.environ}}


def inputs_file(directory, case_id: str) -> str:
    """The file ``--misfit-inputs`` keeps a case's inputs in: its id with "/" as "__"."""
    return os.path.join(directory, case_id.replace("/", "__") + ".npz")


def save_misfit_inputs(path, inputs: dict) -> None:
    """Write a diagnosis's ``misfit_inputs`` ({"torsion": {...}, "ramps": {...} or None}) as
    one .npz, each array under "part.name" (no pickled objects; read back with
    bench_unnamed_replay.read_inputs)."""
    flat = {f"{part}.{k}": np.asarray(v) for part, d in inputs.items() if d is not None for k, v in d.items()}
    np.savez_compressed(path, **flat)


def run_case(case, n_points: int, record: float, n_ramps: int, workers: int, recommend: bool = True,
             inputs_dir: str | None = None) -> dict:
    """Synthesise the case's campaign, diagnose it, return its JSON line; with ``inputs_dir``
    keep what the unnamed misfit's gain was computed from there (:func:`inputs_file`)."""
    ids = point_ids(n_points, n_ramps)
    spec = case["spec"]
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        camp = os.path.join(d, "campaign")
        doc = synthesize(camp, effects=[(n, dict(v)) for n, v in spec["effects"]], perturb=case["perturb"],
                         noise_db=case["noise_db"], seed=case["seed"], updates=dict(spec["updates"]) or None,
                         points=ids, record=record, workers=workers, daq=case["daq"])
        t0 = time.perf_counter()
        result = diagnose(read_campaign(camp), workers=workers, recommend=recommend)
        wall = time.perf_counter() - t0
        diag = jsonable(result.to_json())
        if inputs_dir is not None and result.misfit_inputs:
            save_misfit_inputs(inputs_file(inputs_dir, case["id"]), result.misfit_inputs)
    truth = dict(doc)
    truth.update({"description": spec["description"], "updates": spec["updates"], "level": case["level"]})
    row = {k: case[k] for k in ("id", "kind", "group", "level", "seed", "perturb", "noise_db")}
    row.update({"truth": truth, "campaign": {"points": ids, "record_s": record}})
    row.update({k: diag.get(k) for k in KEEP})
    row.update({k: v for k, v in diag.items() if k.startswith("gap_")})
    row["wall_s"] = wall
    row["case_wall_s"] = time.perf_counter() - t_start
    row["machine"] = machine()
    return jsonable(row)


def read_lines(path) -> list:
    """The JSON lines of ``path`` ([] if it does not exist); a torn last line is skipped."""
    if not os.path.exists(path):
        return []
    rows = []
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            line = line.strip()
            if not line:
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def read_files(ap, paths) -> list:
    """The JSON lines of the result files ``paths``, in the order given; a path that is not
    a file is the parser ``ap``'s error (never an empty benchmark)."""
    missing = [f for f in paths if not os.path.isfile(f)]
    if missing:
        ap.error(f"no such file: {', '.join(missing)}")
    return [r for f in paths for r in read_lines(f)]


def append_line(path, row) -> None:
    """Append ``row`` as one JSON line and flush it to disk (after a newline if a killed
    run left a torn last line, which :func:`read_lines` then skips)."""
    torn = False
    if os.path.exists(path) and os.path.getsize(path) > 0:
        with open(path, "rb") as fh:
            fh.seek(-1, os.SEEK_END)
            torn = fh.read(1) != b"\n"
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(("\n" if torn else "") + json.dumps(row, allow_nan=False) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matrix", choices=("hard", "classic"), default="hard")
    ap.add_argument("--out", default="bench-discrepancy.jsonl", help="JSON lines, one per finished case")
    ap.add_argument("--resume", action="store_true", help="skip the cases already in --out (else --out must not exist)")
    ap.add_argument("--only", nargs="*", help="kinds (effect, pair, control, out_of_library), groups (an effect, "
                    "'calibration', 'rig_shaft', ...; classic: 'no_effect', 'miscalibration'), levels or case ids")
    ap.add_argument("--limit", type=int, help="run at most this many cases")
    ap.add_argument("--list", action="store_true", help="print the cases and their truths, run nothing")
    read_only = ap.add_mutually_exclusive_group()
    read_only.add_argument("--summary", metavar="FILE", nargs="+",
                    help="print the figures of one or more results files, run nothing (read in the order given: "
                    "a case in several files counts once, by its last successful line)")
    read_only.add_argument("--rows", metavar="FILE", nargs="+",
                    help="print one Markdown table row per case of one or more results files (as --summary "
                    "reads them), run nothing")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per effect (hard: 2, classic: 3)")
    ap.add_argument("--matrix-seed", type=int, default=0, help="hard: seed of the random truths and DAQ settings")
    ap.add_argument("--reduced", action="store_true", help="classic: one magnitude and one seed, fewer controls")
    ap.add_argument("--mags", help="classic: magnitude indices, e.g. '2' (0 weak, 1 typical, 2 strong)")
    ap.add_argument("--points", type=int, default=12, help="torsional test points per campaign")
    ap.add_argument("--ramps", type=int, default=None, help="hysteresis ramps per campaign (hard: 1, classic: 0)")
    ap.add_argument("--record", type=float, default=1.0, help="record length [s]")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-recommend", action="store_true",
                    help="skip the next-test design (its runs do not change any figure of the summary)")
    ap.add_argument("--misfit-inputs", metavar="DIR",
                    help="keep each case's unnamed-misfit inputs in DIR (one .npz per case) for "
                         "bench/bench_unnamed_replay.py")
    a = ap.parse_args(argv)
    if a.summary:
        print(summary_table(summary(read_files(ap, a.summary))))
        return 0
    if a.rows:
        print(case_table(read_files(ap, a.rows)))
        return 0
    if a.matrix == "hard":
        cases = hard_cases(a.seeds or 2, a.matrix_seed)
    else:
        mags = tuple(int(x) for x in a.mags.split(",")) if a.mags else None
        cases = classic_cases(a.reduced, a.seeds or 3, mags)
    cases = selected(cases, a.only)
    ramps = a.ramps if a.ramps is not None else (1 if a.matrix == "hard" else 0)
    if a.list:
        for c in cases[:a.limit]:
            print(f"{c['id']:48s} seed {c['seed']:6d} noise {c['noise_db']:+.1f} dB  {c['spec']['description']}")
        print(f"{len(cases[:a.limit])} cases")
        return 0
    done = {r.get("id") for r in read_lines(a.out) if not r.get("error")}
    if done and not a.resume:
        ap.error(f"--out {a.out} already holds {len(done)} finished cases: pass --resume to continue it, "
                 "or name another file")
    todo = [c for c in cases if c["id"] not in done][:a.limit]
    if a.misfit_inputs:
        os.makedirs(a.misfit_inputs, exist_ok=True)
    print(f"{len(todo)} cases to run ({len(cases) - len(todo)} skipped)", flush=True)
    for c in todo:
        try:
            r = run_case(c, a.points, a.record, ramps, a.workers, not a.no_recommend, a.misfit_inputs)
        except Exception as exc:  # noqa: BLE001 - one failed case must not end the run
            r = {"id": c["id"], "kind": c["kind"], "error": f"{type(exc).__name__}: {exc}",
                 "traceback": traceback.format_exc(limit=5)}
        append_line(a.out, r)
        print(json.dumps({k: r.get(k) for k in ("id", "verdict", "effect", "gap_calibrated_nm", "noise_floor_nm",
                                                "wall_s", "error")}), flush=True)
    print(summary_table(summary(read_lines(a.out))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
