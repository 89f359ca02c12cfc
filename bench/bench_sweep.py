"""Benchmark: the thesis's colourmap speed sweep, cold and warm result cache.

191 test points, 900-2800 rpm every 10 rpm ([thesis] §3.3.2), 200 N m mean torque,
orders "2:300,4:100", default damper and solver settings (2.6 s simulated per point,
1.25 s analysis window, [thesis] §3.4). Run 1 computes every point with the process
executor on all cores into an empty temporary cache; run 2 repeats the sweep on the same
cache. The temporary cache is removed afterwards.

    .venv/bin/python bench/bench_sweep.py [--workers N] [--speeds 900:2800:10]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="900:2800:10", help="speeds [rpm], START:STOP:STEP")
    parser.add_argument("--torque", type=float, default=200.0, help="mean torque [N m]")
    parser.add_argument("--orders", default="2:300,4:100", help="excitation orders")
    parser.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    args = parser.parse_args(argv)

    from dampersim import default_parameters
    from dampersim.simulation import ensure_compiled
    from dampersim.sweeps import ResultCache, make_grid, parse_range, run_sweep
    from dampersim.sweeps.backends import cpu_count

    system = default_parameters()
    points = make_grid(parse_range(args.speeds), [args.torque], args.orders)
    workers = args.workers or cpu_count()
    compile_s = ensure_compiled()
    print(f"sweep: {len(points)} points, {args.speeds} rpm, {args.torque:g} N m, orders {args.orders}; "
          f"{system.solver.duration:g} s simulated per point; {workers} worker processes "
          f"(kernel load/compile in this process {compile_s:.2f} s, not timed)")

    tmp = tempfile.mkdtemp(prefix="dampersim-bench-cache-")
    rows = []
    try:
        with ResultCache(os.path.join(tmp, "results")) as store:
            for label in ("cold", "warm"):
                t0 = time.perf_counter()
                result = run_sweep(system, points, executor="processes", workers=workers, cache=store)
                wall = time.perf_counter() - t0
                kernel = float(result.points["wall_time_s"].mean())
                rows.append((label, result.n_points, result.computed, result.from_cache, wall, kernel))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    print(f"{'run':<5} {'points':>6} {'computed':>8} {'cached':>6} {'wall [s]':>9} {'points/s':>9} "
          f"{'per point [ms]':>15} {'kernel/point [ms]':>18}")
    for label, n, computed, cached, wall, kernel in rows:
        print(f"{label:<5} {n:>6} {computed:>8} {cached:>6} {wall:>9.2f} {n / wall:>9.1f} "
              f"{1000 * wall / n:>15.1f} {1000 * kernel:>18.1f}")
    cold, warm = rows[0][4], rows[1][4]
    print(f"warm/cold speed-up: {cold / warm:.0f}x")
    return 0


if __name__ == "__main__":  # required: the process executor spawns workers that import this file
    sys.exit(main())
