"""CLI commands ``sweep`` and ``orders`` (rpm, N m, Hz and s at this edge).

Registered on the main parser by ``add_parsers(subparsers)``; each command function takes
the parsed ``args`` and returns an exit code. Bad input raises a DampersimError subclass,
which the main CLI prints as one line (exit status 2).

    dampersim sweep --speeds 900:2800:10 --torque 200 --orders "2:300,4:100" --out out/sweep
    dampersim orders record.csv --rpm 1500 --json
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

from dampersim.errors import InputError
from dampersim.jsonsafe import jsonable

TIME_COLUMNS = ("time_s", "time", "t")
DEFAULT_SIGNAL_COLUMN = "output_torque_nm"
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
    from dampersim.parameters import load_parameters, parse_set_options
    from dampersim.sweeps.executor import run_sweep
    from dampersim.sweeps.grid import make_grid, parse_range, parse_torques

    system = load_parameters(getattr(args, "params", None), parse_set_options(getattr(args, "set", None)))
    speeds = parse_range(args.speeds)
    torques = parse_torques(args.torque)
    points = make_grid(speeds, torques, parse_orders(args.orders))
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}: accepted is a whole number >= 1")
    for name in ("duration", "window"):
        value = getattr(args, name, None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"--{name} {value!r}: accepted is a positive time in s")

    out_dir = os.path.abspath(args.out)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError(f"--out {args.out!r}: exists and is not a folder")
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {args.out!r}: cannot create the folder ({exc.strerror or exc})") from None

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


def cmd_sweep(args) -> int:
    """Run a sweep, write ``OUT/sweep.parquet`` (and figures), print a summary."""
    system, result, out_dir, table_path = _cli_sweep(args)
    figures, notes = _write_figures(result, out_dir)
    for note in notes:
        print(note, file=sys.stderr)
    if args.json:
        print(json.dumps({
            "points": result.n_points,
            "computed": result.computed,
            "from_cache": result.from_cache,
            "wall_time_s": result.wall_time,
            "table": table_path,
            "figures": figures,
        }))
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
        "points": result.n_points,
        "computed": result.computed,
        "from_cache": result.from_cache,
        "wall_time_s": result.wall_time,
        "table": table_path,
        "figures": figures,
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


# --------------------------------------------------------------------------- orders
def _read_table(path):
    import pandas as pd

    if not os.path.isfile(path):
        raise InputError(f"file {path!r} does not exist (or is not a file)")
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".csv", ".txt"):
            frame = pd.read_csv(path)
        elif ext in (".parquet", ".pq"):
            frame = pd.read_parquet(path)
        else:
            raise InputError(
                f"file {path!r}: unknown file type {ext or '(no extension)'!r}; accepted are "
                ".csv and .parquet"
            )
    except InputError:
        raise
    except pd.errors.EmptyDataError:
        raise InputError(f"file {path!r} is empty; accepted is a table with a header row") from None
    except Exception as exc:
        raise InputError(f"file {path!r} cannot be read as {ext[1:]} ({type(exc).__name__}: {exc})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    if frame.shape[0] == 0:
        raise InputError(f"file {path!r} has no data rows (columns: {', '.join(frame.columns)})")
    return frame


def _is_numeric(series) -> bool:
    import pandas as pd

    return pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series)


def order_amplitudes_of_file(path, rpm, column=None, fs=None, orders=None, window=None):
    """Order amplitudes of one time series in a CSV or Parquet file ([thesis] §3.4).

    Args:
        path: .csv or .parquet file with a time column (time_s, time or t) [s], or give
            ``fs``.
        rpm: mean shaft speed over the record [rpm].
        column: signal column [N m]; default ``output_torque_nm`` if present, else the
            first numeric column that is not the time.
        fs: sample rate [Hz]; overrides the time column.
        orders: engine orders (default 1..8).
        window: analyse only the last ``window`` seconds [s] (default: the whole record;
            the thesis uses 1.25 s).

    Returns:
        dict with ``orders``, ``amplitude_nm``, ``column``, ``sample_rate_hz``, ``samples``.

    Raises:
        InputError: unknown file type, unreadable file, missing/non-numeric column (the
            message lists the available ones), NaN/inf samples, non-uniform time, record
            too short, orders at or above the Nyquist frequency.
    """
    from dampersim.signal import (
        DEFAULT_ORDERS,
        MIN_SAMPLES,
        order_amplitudes,
        sample_rate_from_time,
    )
    from dampersim.units import rpm_to_rad_s

    try:
        rpm = float(rpm)
    except (TypeError, ValueError):
        rpm = float("nan")
    if not (math.isfinite(rpm) and rpm > 0):
        raise InputError(f"--rpm {rpm!r}: accepted is a positive shaft speed in rpm")
    frame = _read_table(path)
    available = ", ".join(frame.columns)
    time_col = next((c for c in TIME_COLUMNS if c in frame.columns), None)

    if fs is not None:
        try:
            fs = float(fs)
        except (TypeError, ValueError):
            fs = float("nan")
        if not (math.isfinite(fs) and fs > 0):
            raise InputError(f"--fs {fs!r}: accepted is a positive sample rate in Hz")
    elif time_col is None:
        raise InputError(
            f"file {path!r} has no time column ({', '.join(TIME_COLUMNS)}) and no --fs was given; "
            f"available columns: {available}"
        )
    else:
        if not _is_numeric(frame[time_col]):
            raise InputError(f"time column {time_col!r} in {path!r} is not numeric (seconds expected)")
        fs = sample_rate_from_time(frame[time_col].to_numpy(dtype=float))

    if column is not None:
        if column not in frame.columns:
            raise InputError(f"column {column!r} is not in {path!r}; available columns: {available}")
    elif DEFAULT_SIGNAL_COLUMN in frame.columns:
        column = DEFAULT_SIGNAL_COLUMN
    else:
        candidates = [c for c in frame.columns if c != time_col and _is_numeric(frame[c])]
        if not candidates:
            raise InputError(f"file {path!r} has no numeric signal column; available columns: {available}")
        column = candidates[0]
    if not _is_numeric(frame[column]):
        raise InputError(
            f"column {column!r} in {path!r} is not numeric (dtype {frame[column].dtype}); "
            f"pick a torque column with --column; available columns: {available}"
        )
    x = frame[column].to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise InputError(
            f"column {column!r} in {path!r} has {bad.size} NaN/inf samples (first in data row "
            f"{bad[0]}); clean or drop them"
        )
    if window is not None:
        window = float(window)
        if not (math.isfinite(window) and window > 0):
            raise InputError(f"--window {window!r}: accepted is a positive time in s")
        n = int(round(window * fs))
        if n > x.size:
            raise InputError(
                f"--window {window:g} s needs {n} samples but {path!r} holds {x.size} "
                f"({x.size / fs:.3g} s at {fs:g} Hz)"
            )
        x = x[x.size - n:]
    if x.size < MIN_SAMPLES:
        raise InputError(
            f"column {column!r} in {path!r} has {x.size} samples"
            f"{' in the window' if window is not None else ''}; at least {MIN_SAMPLES} are needed"
        )
    orders = DEFAULT_ORDERS if orders is None else orders
    amps = order_amplitudes(x, fs, rpm_to_rad_s(rpm), orders)
    return {
        "orders": [float(k) for k in np.atleast_1d(np.asarray(orders, dtype=float))],
        "amplitude_nm": jsonable(np.asarray(amps, dtype=float)),
        "column": column,
        "sample_rate_hz": float(fs),
        "samples": int(x.size),
    }


def cmd_orders(args) -> int:
    """Print the order amplitudes of one time series in a file."""
    from dampersim.sweeps.grid import parse_values

    orders = parse_values(args.orders, option="--orders", unit="orders") if args.orders else None
    out = order_amplitudes_of_file(args.file, args.rpm, column=args.column, fs=args.fs,
                                   orders=orders, window=args.window)
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.file}: column {out['column']}, {out['samples']} samples at "
              f"{out['sample_rate_hz']:g} Hz, {args.rpm:g} rpm")
        print(f"{'order':>6} {'amplitude [N m]':>16}")
        for k, a in zip(out["orders"], out["amplitude_nm"]):
            print(f"{k:>6g} {a:16.4f}")
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
    p.add_argument("--params", metavar="FILE.toml", help="parameter set (default: built-in damper)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter by dotted name")
    p.add_argument("--executor", choices=EXECUTORS, default=None,
                   help="where to compute (default: dask if a scheduler is given, else processes)")
    p.add_argument("--workers", type=int, default=None, metavar="N", help="worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help=f"Dask scheduler address, e.g. tcp://host:8786 (default: ${SCHEDULER_ENV})")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time per point [s]")
    p.add_argument("--window", type=float, default=None, metavar="S",
                   help="analysis window at the end of each record [s] (default 1.25, §3.4)")
    p.add_argument("--out", default=out, metavar="DIR", help=f"output folder (default {out})")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the result cache")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--json", action="store_true", help="machine-readable summary on stdout")


def add_parsers(subparsers) -> None:
    """Register the ``sweep``, ``map`` and ``orders`` commands on an argparse subparsers object."""

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

    o = subparsers.add_parser(
        "orders",
        help="engine-order amplitudes of one time series in a CSV or Parquet file",
        description=(
            "Read one torque column and a time column (time_s, time or t; or give --fs) and "
            "print the amplitude of each engine order (Hann spectrum, §3.4)."
        ),
    )
    o.add_argument("file", metavar="FILE", help=".csv or .parquet file")
    o.add_argument("--rpm", type=float, required=True, metavar="RPM", help="mean shaft speed [rpm]")
    o.add_argument("--column", default=None, metavar="NAME",
                   help=f"signal column (default {DEFAULT_SIGNAL_COLUMN} if present, else the first numeric one)")
    o.add_argument("--fs", type=float, default=None, metavar="HZ", help="sample rate [Hz] (instead of a time column)")
    o.add_argument("--orders", default=None, metavar="LIST", help='orders, e.g. "1,2,4" or "0.5:8:0.5" (default 1-8)')
    o.add_argument("--window", type=float, default=None, metavar="S",
                   help="analyse the last S seconds only [s] (default: whole record)")
    o.add_argument("--json", action="store_true", help="machine-readable output")
    o.set_defaults(func=cmd_orders)


__all__ = ["add_parsers", "cmd_sweep", "cmd_map", "cmd_orders", "order_amplitudes_of_file", "ProgressBar"]
