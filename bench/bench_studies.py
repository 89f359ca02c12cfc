"""Wall time of each chapter 7 study on its full grid: cold (empty cache) and cached.

    python bench/bench_studies.py [--out DIR] [--quick] [--segments OUTER/INNER] [NAME ...]

Uses a fresh temporary cache directory unless DAMPERSIM_CACHE_DIR is set, runs every
study twice with the process pool and prints one line per run; with --out the full
result documents are written as DIR/NAME.json (the numbers in docs/thesis-comparison.md).
"""

import argparse
import json
import os
import sys
import tempfile
import time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("names", nargs="*")
    ap.add_argument("--out")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--segments", default=None, metavar="OUTER/INNER",
                    help="run at these segment counts instead of the default set's (e.g. 18/8, the thesis's)")
    args = ap.parse_args()
    if not os.environ.get("DAMPERSIM_CACHE_DIR"):
        os.environ["DAMPERSIM_CACHE_DIR"] = tempfile.mkdtemp(prefix="dampersim-bench-")
    from dampersim.parameters import default_parameters, with_updates
    from dampersim.studies import STUDIES, run_study

    system = default_parameters()
    if args.segments:
        no, ni = (int(x) for x in args.segments.split("/"))
        system = with_updates(system, {"solver.outer_segments": no, "solver.inner_segments": ni})

    names = args.names or list(STUDIES)
    for name in names:
        times = []
        for label in ("cold", "cached"):
            t0 = time.perf_counter()
            res = run_study(name, system, quick=args.quick, executor="processes")
            times.append(time.perf_counter() - t0)
            print(f"{name:22s} {label:6s} {times[-1]:8.1f} s  points {res['points']:5d}  from cache {res['from_cache']:5d}  "
                  f"checks {res['checks']}", flush=True)
        if args.out:
            os.makedirs(args.out, exist_ok=True)
            res["bench_wall_time_s"] = {"cold": times[0], "cached": times[1]}
            with open(os.path.join(args.out, f"{name}.json"), "w") as fh:
                json.dump(res, fh, allow_nan=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
