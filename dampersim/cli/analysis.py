"""Commands ``hysteresis``, ``campbell`` and ``orders``: analyses of loops, modes and recorded time series.

Units at this edge are rpm, degrees, N m, Hz and s. Register the commands with
:func:`add_parsers`; each command function takes the parsed ``args``, prints its report
and returns the exit status 0; bad input raises :class:`dampersim.errors.InputError`
(:func:`dampersim.cli.main` turns it into one line on stderr and exit status 2).

    dampersim hysteresis --speeds 1000,1500 --protocol full-450 --out out/loops
    dampersim orders record.csv --rpm 1500 --json
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from dampersim.cli.options import MAX_RPM, MIN_RPM, add_parameter_options, parameters_from_args, prepare_output
from dampersim.errors import InputError
from dampersim.jsonsafe import jsonable
from dampersim.units import rad_to_deg, rpm_to_rad_s

#: Accepted ramp rates [N m/s]: the thesis uses 50 and shows up to 220 ([thesis] §3.3.1, Fig. 3.9).
MIN_RATE, MAX_RATE = 1.0, 5000.0
TIME_COLUMNS = ("time_s", "time", "t")
DEFAULT_SIGNAL_COLUMN = "output_torque_nm"


def parse_speeds_rpm(text) -> list:
    """``"1000,1500,2000"`` -> [1000.0, 1500.0, 2000.0] [rpm], each within 300-6000 rpm."""
    form = 'comma-separated speeds in rpm, e.g. "1000,1500,2000"'
    if text is None or not str(text).strip():
        raise InputError(f"--speeds is empty: accepted is {form}")
    out = []
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        try:
            v = float(item)
        except ValueError:
            raise InputError(f"--speeds item {item!r} is not a number: accepted is {form}") from None
        if not (math.isfinite(v) and MIN_RPM <= v <= MAX_RPM):
            raise InputError(f"--speeds item {item!r} rpm: accepted is {MIN_RPM:g} to {MAX_RPM:g} rpm")
        out.append(v)
    if not out:
        raise InputError(f"--speeds holds no speed: accepted is {form}")
    if len(set(out)) != len(out):
        raise InputError(f"--speeds {text!r} repeats a speed")
    return out


def _nm_per_deg(k_nm_per_rad):
    return k_nm_per_rad / rad_to_deg(1.0)


def _fmt(v, spec):
    return format(v, spec) if v is not None and math.isfinite(v) else "-".rjust(len(format(0.0, spec)))


def cmd_hysteresis(args) -> int:
    """Simulate a Table 3.1 ramp at each speed; print knee, stiffness and loop energy."""
    from dampersim.analysis.hysteresis import analyse_loop, run_loops
    from dampersim.excitation.ramps import PROTOCOLS

    speeds = parse_speeds_rpm(args.speeds)
    if args.protocol not in PROTOCOLS:
        raise InputError(f"--protocol {args.protocol!r}: accepted is one of {', '.join(PROTOCOLS)}")
    rate = float(args.rate)
    if not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
        raise InputError(f"--rate {args.rate!r} N m/s: accepted is {MIN_RATE:g} to {MAX_RATE:g} N m/s (thesis: 50)")
    hold = float(getattr(args, "hold", 2.0))
    if not (math.isfinite(hold) and 0.0 <= hold <= 60.0):
        raise InputError(f"--hold {hold!r} s: accepted is 0 to 60 s (thesis: 2)")
    system = parameters_from_args(args)
    out_dir = prepare_output(args.out, "folder") if getattr(args, "out", None) else None
    loops = run_loops(system, args.protocol, [rpm_to_rad_s(s) for s in speeds], rate=rate, hold=hold, lowpass=bool(args.lowpass))
    analyses = [analyse_loop(lp, system) for lp in loops]
    html = None
    if out_dir:
        from dampersim.plotting import hysteresis_figure, write_html

        fig = hysteresis_figure(loops, knees=[a.knee for a in analyses], title=f"Hysteresis loops, {args.protocol} at {rate:g} N m/s")
        html = write_html(fig, os.path.join(out_dir, f"hysteresis-{args.protocol}.html"))
    if args.json:
        print(
            json.dumps(
                {
                    "parameter_set": system.name,
                    "protocol": args.protocol,
                    "rate_nm_per_s": rate,
                    "hold_s": hold,
                    "lowpass_hz": 10.0 if args.lowpass else None,
                    "loops": [a.to_dict("deg") for a in analyses],
                    "figure": html,
                }
            )
        )
        return 0
    hs = rad_to_deg(system.outer.hardstop_positive)
    print(f"{system.name}: protocol {args.protocol} at {rate:g} N m/s, hold {hold:g} s" + (", 10 Hz low pass" if args.lowpass else ""))
    print(
        f"{'speed':>7} {'knee':>8} {'knee':>8} {'k below':>10} {'k above':>10} {'energy':>9} {'outer knee':>11}\n"
        f"{'[rpm]':>7} {'[deg]':>8} {'[N m]':>8} {'[N m/deg]':>10} {'[N m/deg]':>10} {'[J]':>9} {'[deg]':>11}"
    )
    for rpm, a in zip(speeds, analyses):
        kn = a.knee
        ok = kn.found
        ok_outer = a.outer_knee is not None and a.outer_knee.found
        print(
            f"{rpm:7.0f} {_fmt(rad_to_deg(kn.windup_rad) if ok else None, '8.2f')} {_fmt(kn.torque_nm if ok else None, '8.1f')} "
            f"{_fmt(_nm_per_deg(kn.stiffness_below), '10.3f')} {_fmt(_nm_per_deg(kn.stiffness_above) if ok else None, '10.3f')} "
            f"{a.energy_j:9.2f} {_fmt(rad_to_deg(a.outer_knee.windup_rad) if ok_outer else None, '11.2f')}"
        )
    print(f"outer set positive hardstop: {hs:.2f} deg; '-' = no knee in the ramp (stiffness below = whole branch)")
    if html:
        print(f"figure: {html}")
    return 0


def cmd_campbell(args) -> int:
    """Natural frequencies, mode summary and order crossings of the linearised system."""
    from dampersim.analysis.modal import campbell, modal_analysis

    system = parameters_from_args(args)
    motor = getattr(args, "output_motor", None) or "free"
    lo, hi = _speed_range(getattr(args, "speed_range", None))
    modal = modal_analysis(system, motor=motor)
    fmax = float(getattr(args, "max_frequency", 500.0))
    if not (math.isfinite(fmax) and fmax > 0):
        raise InputError(f"--max-frequency {fmax!r} Hz: accepted is a positive frequency")
    data = campbell(modal, speed_range_rad_s=(rpm_to_rad_s(lo), rpm_to_rad_s(hi)))
    summary = modal.summary(max_frequency_hz=fmax)
    cross = data.crossings[data.crossings["natural_frequency_hz"] <= fmax]
    html = None
    if getattr(args, "out", None):
        from dampersim.plotting import campbell_figure, write_html

        out = prepare_output(args.out, "file")
        html = write_html(campbell_figure(data, max_frequency_hz=min(fmax, float(data.order_lines["frequency_hz"].max()))), out)
    if args.json:
        print(
            json.dumps(
                {
                    "parameter_set": system.name,
                    "motor": motor,
                    "dof_names": list(modal.dof_names),
                    "natural_frequencies_hz": [float(f) for f in modal.frequencies_hz],
                    "rigid": [bool(r) for r in modal.rigid],
                    "modes": summary.to_dict(orient="records"),
                    "speed_range_rpm": [lo, hi],
                    "crossings": cross.to_dict(orient="records"),
                    "figure": html,
                }
            )
        )
        return 0
    nrig = int(np.sum(modal.rigid))
    print(f"{system.name}: {len(modal.dof_names)} DOFs, output motor {motor}, {nrig} rigid-body mode(s)")
    print(f"modes up to {fmax:g} Hz (kinetic-energy share):")
    for _, row in summary.iterrows():
        print(f"  mode {int(row['mode']):2d} {row['frequency_hz']:9.2f} Hz  {row['bodies']}")
    print(f"order crossings {lo:g}-{hi:g} rpm (order k meets mode f_n at rpm = 60 f_n / k):")
    for _, row in cross.iterrows():
        print(f"  order {row['order']:g} x mode {int(row['mode'])} ({row['natural_frequency_hz']:.1f} Hz) at {row['speed_rpm']:7.0f} rpm")
    if html:
        print(f"figure: {html}")
    return 0


def _speed_range(text):
    if text is None:
        return 500.0, 3000.0
    try:
        lo, hi = (float(x) for x in str(text).split(","))
    except ValueError:
        raise InputError(f'--speed-range {text!r}: accepted is "LOW,HIGH" in rpm, e.g. "500,3000"') from None
    if not (MIN_RPM <= lo < hi <= MAX_RPM):
        raise InputError(f"--speed-range {text!r}: accepted is {MIN_RPM:g} <= LOW < HIGH <= {MAX_RPM:g} rpm")
    return lo, hi


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


def add_parsers(subparsers) -> None:
    """Register ``hysteresis``, ``campbell`` and ``orders`` on an argparse subparsers object."""
    from dampersim.excitation.ramps import PROTOCOLS

    h = subparsers.add_parser("hysteresis", help="torque-ramp hysteresis loops: knee, stiffness, loop energy")
    h.add_argument("--speeds", default="1000,1500,2000", metavar="RPM,RPM,...", help="shaft speeds [rpm] (default 1000,1500,2000)")
    h.add_argument("--protocol", default="full-450", choices=list(PROTOCOLS), help="torque ramp of thesis Table 3.1 (default full-450)")
    h.add_argument("--rate", type=float, default=50.0, metavar="NMPS", help="ramp rate [N m/s] (default 50, as the thesis)")
    h.add_argument("--hold", type=float, default=2.0, metavar="S", help="hold at each peak [s] (default 2)")
    h.add_argument("--lowpass", action="store_true", help="apply the thesis's 1st-order 10 Hz low pass to the loops")
    add_parameter_options(h)
    h.add_argument("--json", action="store_true", help="machine-readable output")
    h.add_argument("--out", metavar="DIR", help="write an HTML loop figure into this folder (created if missing)")
    h.set_defaults(func=cmd_hysteresis)

    c = subparsers.add_parser("campbell", help="natural frequencies, mode shapes and engine-order crossings")
    add_parameter_options(c)
    c.add_argument("--output-motor", choices=("free", "held"), default="free", help="output motor free (default) or held")
    c.add_argument("--speed-range", metavar="LOW,HIGH", help="speed range [rpm] (default 500,3000)")
    c.add_argument("--max-frequency", type=float, default=500.0, metavar="HZ", help="report modes up to this frequency [Hz] (default 500)")
    c.add_argument("--out", metavar="FILE.html", help="write the Campbell diagram as HTML")
    c.add_argument("--json", action="store_true", help="machine-readable output")
    c.set_defaults(func=cmd_campbell)

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


__all__ = ["add_parsers", "cmd_hysteresis", "cmd_campbell", "cmd_orders", "order_amplitudes_of_file", "parse_speeds_rpm"]
