"""Load benchmark of the dashboard server: 4, 16 and 64 sessions open links that start sweeps.

For each session count a fresh server (``python app.py`` on loopback, its own empty cache
folder, the job limits given below) is started; every session opens one of four colourmap
links (so sessions ``i`` and ``i + 4`` ask for the identical sweep) and follows the sweep
the way the browser does (page layout, request callback, background job, polls until the
result). Meanwhile a probe loads a light page as a browser does (the Explorer's HTML, the app
layout and the ``_pages_content`` callback) every 0.1 s.
Printed per session count:

- probe latency p50 / p95 [ms] while the sweeps run;
- the most job processes seen at once (descendants leading their own session), the most processes
  in the server's tree, and the peak RSS of the whole tree [MB];
- sessions whose sweep answered, and wall time [s];
- orphans: processes of the server still alive after it was stopped with SIGTERM.

    python bench/bench_load.py [--sessions 4,16,64] [--points 6] [--duration 8] [--max-jobs N]

Each sweep is ``--points`` speeds of ``--duration`` simulated seconds (about 0.4 s of
compute per point on one core of the reference machine), so the runs overlap.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.hardening.loadrun import run_load, start_server, stop_server  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", default="4,16,64", help="session counts, comma-separated")
    parser.add_argument("--points", type=int, default=6, help="speeds per sweep")
    parser.add_argument("--duration", type=float, default=8.0, help="simulated time per point [s]")
    parser.add_argument("--max-jobs", type=int, default=None, help="server's global job limit (default: its own)")
    parser.add_argument("--deadline", type=float, default=900.0, help="give up on a session after this many seconds")
    args = parser.parse_args(argv)
    counts = [int(x) for x in args.sessions.split(",") if x.strip()]
    server_args = [] if args.max_jobs is None else ["--max-jobs", str(args.max_jobs)]
    print(f"{'sessions':>8} {'p50 ms':>8} {'p95 ms':>8} {'jobs':>5} {'procs':>6} {'RSS MB':>8} {'done':>6} {'wall s':>8} {'orphans':>8}")
    for n in counts:
        with tempfile.TemporaryDirectory() as tmp:
            proc, base = start_server(Path(tmp) / "cache", *server_args)
            out = {}
            try:
                out = run_load(base, proc.pid, n, points=args.points, duration=args.duration, deadline_s=args.deadline)
            finally:
                orphans = stop_server(proc, seen=out.get("seen", ()))
        print(f"{n:>8} {1e3 * out['latency_p50_s']:>8.1f} {1e3 * out['latency_p95_s']:>8.1f} {out['max_jobs']:>5} "
              f"{out['max_processes']:>6} {out['peak_rss_mb']:>8.0f} {out['finished']:>3}/{n:<2} {out['wall_s']:>8.1f} "
              f"{len(orphans):>8}")
        for i, status, text in out["failed"][:3]:
            print(f"         session {i}: HTTP {status}: {text[:160]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
