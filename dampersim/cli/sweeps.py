"""Commands ``sweep`` and ``map``: grids of test points run through the result cache, with tables and figures.

Units at this edge are rpm, N m, Hz and s. Register the commands with
:func:`add_parsers`; each command function takes the parsed ``args`` and returns the exit
status 0. Bad input raises a DampersimError subclass, which :func:`dampersim.cli.main`
prints as one line (exit status 2).

    dampersim sweep --speeds 900:2800:10 --torque 200 --orders "2:300,4:100" --out out/sweep
    dampersim map --speeds 900:2000:100 --torque 50:500:50 --out out/map
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import threading
import time

import numpy as np

from dampersim.cli.options import add_parameter_options, parameters_from_args, prepare_output
from dampersim.errors import InputError

TABLE_NAME = "sweep.parquet"


# --------------------------------------------------------------------------- progress
class ProgressBar:
    """Text progress bar on a stream (stderr): redrawn in place on a terminal, one line
    per 10 % otherwise (log files)."""

    def __init__(self, stream=None, width=30, enabled=True):
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = time.perf_counter()
        self._last_decile = -1
        self._drawn = False

    def __call__(self, done, total, from_cache):
        if not self.enabled or total <= 0:
            return
        frac = done / total
        filled = int(round(self.width * frac))
        bar = "#" * filled + "." * (self.width - filled)
        text = (f"[{bar}] {done}/{total} points ({from_cache} from cache) "
                f"{time.perf_counter() - self.t0:6.1f} s")
        if self.tty:
            self.stream.write("\r" + text)
            self._drawn = True
            if done >= total:
                self.stream.write("\n")
                self._drawn = False
        else:
            decile = int(frac * 10)
            if decile != self._last_decile or done >= total:
                self._last_decile = decile
                self.stream.write(text + "\n")
        self.stream.flush()

    def close(self):
        if self.enabled and self.tty and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False


class _CancelOnInterrupt:
    """First Ctrl-C sets ``event`` (the sweep stops and keeps finished points cached); a
    second one interrupts at once. Only active in the main thread."""

    def __init__(self, event, stream):
        self.event = event
        self.stream = stream
        self.previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.getsignal(signal.SIGINT)
            signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame):
        if self.event.is_set():
            raise KeyboardInterrupt
        self.event.set()
        self.stream.write("\ncancelling: finishing the running points (Ctrl-C again to abort)\n")
        self.stream.flush()

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)


# --------------------------------------------------------------------------- sweep
#: At most this many mean-torque levels get their own colourmap and order-cut figures.
MAX_FIGURE_LEVELS = 12


def _torque_label(value):
    return f"{value:g}".replace("-", "m").replace(".", "p") + "nm"


def _default_figures(result, plotting):
    """Colourmap (input and output) and order cuts per mean-torque level ([thesis] §6.3.1)."""
    from dampersim.analysis.colourmap import colourmaps, order_cuts

    torques = result.points["mean_torque_nm"].to_numpy()
    speeds = result.points["speed_rad_s"].to_numpy()
    levels = np.unique(torques)
    figs, notes = {}, []
    if levels.size > MAX_FIGURE_LEVELS:
        notes.append(f"figures drawn for the first {MAX_FIGURE_LEVELS} of {levels.size} mean torque levels")
        levels = levels[:MAX_FIGURE_LEVELS]
    for level in levels:
        sel = np.flatnonzero(torques == level)
        if np.unique(speeds[sel]).size < 2:
            notes.append(f"no figures at {level:g} N m: a colourmap needs at least two speeds")
            continue
        suffix = "" if np.unique(torques).size == 1 else "_" + _torque_label(level)
        spec_in = [(speeds[i], result.frequency_hz, result.input_spectra[i].astype(float)) for i in sel]
        spec_out = [(speeds[i], result.frequency_hz, result.output_spectra[i].astype(float)) for i in sel]
        figs["colourmap" + suffix] = plotting.colourmap_figure(
            colourmaps(spec_in, spec_out), title=f"FFT colourmap, {level:g} N m mean torque"
        )
        cuts = order_cuts(result.table, mean_torque_nm=level, torque_tol_nm=1e-9)
        figs["order_cuts" + suffix] = plotting.order_cut_figure(
            cuts, title=f"Order cuts, {level:g} N m mean torque"
        )
    return figs, notes


def _write_figures(result, out_dir):
    """HTML figures next to the table, built by :mod:`dampersim.plotting` when it is
    installed: its ``sweep_figures(result)`` (name -> Figure) if it has one, else FFT
    colourmaps and order cuts per mean-torque level. Returns (paths, notes); a failure
    here never loses the table, it only becomes a note."""
    try:
        import dampersim.plotting as plotting
    except ImportError:
        return [], ["figures skipped: dampersim.plotting is not available"]
    try:
        builder = getattr(plotting, "sweep_figures", None)
        if builder is not None:
            figs, notes = dict(builder(result)), []
        else:
            figs, notes = _default_figures(result, plotting)
        write = getattr(plotting, "write_html", None)
        paths = []
        for name, fig in figs.items():
            safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(name)) or "figure"
            path = os.path.join(out_dir, f"{safe}.html")
            if write is not None:
                write(fig, path)
            else:
                tmp = path + ".tmp"
                fig.write_html(tmp)
                os.replace(tmp, path)
            paths.append(path)
    except Exception as exc:  # plotting is another module: report, keep the table
        return [], [f"figures skipped: {type(exc).__name__}: {exc}"]
    return paths, notes


def _cli_sweep(args):
    """Parse the grid options, run the sweep with a progress bar and Ctrl-C cancellation,
    write OUT/sweep.parquet. Returns (system, result, out_dir, table_path)."""
    from dampersim.excitation import parse_orders
    from dampersim.sweeps.executor import run_sweep
    from dampersim.sweeps.grid import make_grid, parse_range, parse_torques

    system = parameters_from_args(args)
    speeds = parse_range(args.speeds)
    torques = parse_torques(args.torque)
    points = make_grid(speeds, torques, parse_orders(args.orders))
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}: accepted is a whole number >= 1")
    for name in ("duration", "window"):
        value = getattr(args, name, None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"--{name} {value!r}: accepted is a positive time in s")

    out_dir = prepare_output(args.out, "folder")
    if getattr(args, "allow_insecure_dask", False):  # the user said so explicitly
        from dampersim.sweeps.backends import ALLOW_INSECURE_DASK_ENV

        os.environ[ALLOW_INSECURE_DASK_ENV] = "1"

    bar = ProgressBar(sys.stderr, enabled=not args.no_progress)
    cancel = threading.Event()
    try:
        with _CancelOnInterrupt(cancel, sys.stderr):
            result = run_sweep(
                system,
                points,
                executor=args.executor,
                workers=args.workers,
                scheduler=args.scheduler,
                progress=bar,
                cancel=cancel,
                duration=args.duration,
                window=args.window,
                cache=False if args.no_cache else None,
            )
    finally:
        bar.close()

    table_path = result.to_parquet(os.path.join(out_dir, TABLE_NAME))
    return system, result, out_dir, table_path



def _run_summary(result, table_path, figures) -> dict:
    """The JSON fields every sweep command reports: points, how they were obtained, the
    wall time [s] and the files written."""
    return {"points": result.n_points, "computed": result.computed, "from_cache": result.from_cache,
            "wall_time_s": result.wall_time, "table": table_path, "figures": figures}

def cmd_sweep(args) -> int:
    """Run a sweep, write ``OUT/sweep.parquet`` (and figures), print a summary."""
    system, result, out_dir, table_path = _cli_sweep(args)
    figures, notes = _write_figures(result, out_dir)
    for note in notes:
        print(note, file=sys.stderr)
    if args.json:
        print(json.dumps(_run_summary(result, table_path, figures)))
    else:
        rate = result.n_points / result.wall_time if result.wall_time > 0 else float("inf")
        print(f"{system.name}: {result.n_points} test points in {result.wall_time:.2f} s "
              f"({rate:.1f} points/s, executor {result.executor})")
        print(f"  computed:   {result.computed}")
        print(f"  from cache: {result.from_cache}")
        print(f"  table:      {table_path}")
        for path in figures:
            print(f"  figure:     {path}")
    return 0


def cmd_map(args) -> int:
    """Run a mapping grid (speeds x mean torques), build the magnification map over
    (excitation frequency, mean torque) with the engine torque curve, write the table,
    the map figure and a zone summary ([thesis] §6.3.1, §7.2)."""
    from dampersim.analysis.maps import magnification_map, torque_curve_overlay, zone_summary
    from dampersim.excitation import default_torque_curve, parse_orders
    from dampersim.sweeps.grid import parse_values

    lo_hi = parse_values(args.freq_range.replace(":", ","), option="--freq-range", unit="Hz")
    if len(lo_hi) != 2 or not (0 < lo_hi[0] < lo_hi[1]):
        raise InputError(f"--freq-range {args.freq_range!r}: accepted is LOW:HIGH in Hz with 0 < LOW < HIGH")
    system, result, out_dir, table_path = _cli_sweep(args)
    excited = [k for k, a, _ in parse_orders(args.orders) if a > 0]
    mmap = magnification_map(result.table, frequency_range_hz=tuple(lo_hi), orders=excited,
                             frequency_step_hz=args.freq_step, torque_step_nm=args.torque_step)
    knee = system.outer.count * system.outer.spring.stiffness * system.outer.hardstop_positive
    zones = zone_summary(result.table, knee_nm=knee, orders=excited)
    figures = []
    try:
        from dampersim import plotting

        curve = default_torque_curve()
        overlays = [torque_curve_overlay(curve, order=k) for k in (2.0, 4.0) if k in excited]
        fig = plotting.magnification_map_figure(mmap, overlays=overlays, show_points=True)
        figures.append(plotting.write_html(fig, os.path.join(out_dir, "magnification_map.html")))
    except Exception as exc:  # the figure is a by-product: never lose the table for it
        print(f"figure skipped: {type(exc).__name__}: {exc}", file=sys.stderr)
    summary = {
        **_run_summary(result, table_path, figures),
        "knee_nm": knee,
        "zones": zones,
        "share_of_map_above_one": float(np.mean(mmap.above_one[np.isfinite(mmap.magnification)]))
        if np.isfinite(mmap.magnification).any() else None,
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{system.name}: {result.n_points} test points in {result.wall_time:.2f} s "
              f"(computed {result.computed}, from cache {result.from_cache})")
        print(f"  outer knee {knee:.0f} N m; MR by zone (median / max / share > 1):")
        for name, z in zones.items():
            if z["points"]:
                print(f"  {name:>16}: {z['median_mr']:.3f} / {z['max_mr']:.3f} / "
                      f"{100 * z['share_above_one']:.0f} % of {z['points']} points")
        print(f"  table:  {table_path}")
        for path in figures:
            print(f"  figure: {path}")
    return 0


# --------------------------------------------------------------------------- parsers
def _grid_options(p, speeds, torque, orders, out) -> None:
    """Options shared by ``sweep`` and ``map`` (grid, parameters, execution, output)."""
    from dampersim.sweeps.executor import EXECUTORS, SCHEDULER_ENV

    if speeds is None:
        p.add_argument("--speeds", required=True, metavar="RPM",
                       help='speeds [rpm]: START:STOP:STEP (inclusive), a list or a value, e.g. "900:2800:10"')
    else:
        p.add_argument("--speeds", default=speeds, metavar="RPM",
                       help=f'speeds [rpm]: START:STOP:STEP (inclusive), a list or a value (default {speeds})')
    p.add_argument("--torque", default=torque, metavar="NM",
                   help=f"mean torque(s) [N m]: a value, a list or START:STOP:STEP (default {torque})")
    p.add_argument("--orders", default=orders, help=f'ORDER:AMPLITUDE_NM[@PHASE_DEG],... (default "{orders}")')
    add_parameter_options(p)
    p.add_argument("--executor", choices=EXECUTORS, default=None,
                   help="where to compute (default: dask if a scheduler is given, else processes)")
    p.add_argument("--workers", type=int, default=None, metavar="N", help="worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help=f"Dask scheduler address, e.g. tls://host:8786; plain tcp:// only on this machine unless "
                        f"--allow-insecure-dask (default: ${SCHEDULER_ENV})")
    p.add_argument("--allow-insecure-dask", action="store_true",
                   help="accept an unencrypted tcp:// scheduler on another machine (a trusted network only: "
                        "anyone who reaches it can run code in the workers)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time per point [s]")
    p.add_argument("--window", type=float, default=None, metavar="S",
                   help="analysis window at the end of each record [s] (default 1.25, §3.4)")
    p.add_argument("--out", default=out, metavar="DIR", help=f"output folder, created if missing (default {out})")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the result cache")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--json", action="store_true", help="machine-readable summary on stdout")


def add_parsers(subparsers) -> None:
    """Register the ``sweep`` and ``map`` commands on an argparse subparsers object."""

    s = subparsers.add_parser(
        "sweep",
        help="speed x mean torque sweep with result cache: order table and figures",
        description=(
            "Simulate a grid of test points (speeds x mean torques, one excitation), taking "
            "finished points from the result cache, and write OUT/sweep.parquet with one row "
            "per test point and engine order. The thesis steps speed by 10 rpm (§3.3.2). "
            "Ctrl-C cancels cleanly: finished points stay cached."
        ),
    )
    _grid_options(s, speeds=None, torque="200", orders="2:300", out="out/sweep")
    s.set_defaults(func=cmd_sweep)

    m = subparsers.add_parser(
        "map",
        help="magnification map over excitation frequency x mean torque from a mapping grid",
        description=(
            "Simulate a mapping grid (the thesis maps 900-2000 rpm x 50-500 N m, §3.3.2), "
            "interpolate the magnification ratio of the excited orders over (frequency, mean "
            "torque) and overlay the engine torque curve (§6.3.1, §7.2)."
        ),
    )
    _grid_options(m, speeds="900:2000:100", torque="50:500:50", orders="1:60,2:300,4:100,6:40", out="out/map")
    m.add_argument("--freq-range", default="8:300", metavar="LOW:HIGH", help="map frequency range [Hz] (default 8:300)")
    m.add_argument("--freq-step", type=float, default=2.0, metavar="HZ", help="map grid step [Hz]")
    m.add_argument("--torque-step", type=float, default=10.0, metavar="NM", help="map grid step [N m]")
    m.set_defaults(func=cmd_map)


__all__ = ["add_parsers", "cmd_sweep", "cmd_map", "ProgressBar"]
