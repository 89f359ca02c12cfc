"""CLI commands ``hysteresis`` and ``campbell`` (rpm, degrees and Hz at this edge only).

Wire into the main parser with :func:`add_parsers`::

    sub = parser.add_subparsers(dest="command", required=True)
    add_parsers(sub)

Each command function takes the parsed ``argparse.Namespace``, prints its report and
returns the exit status 0; bad input raises :class:`dampersim.errors.InputError` (the main
CLI turns it into one line on stderr and exit status 2).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from dampersim.errors import InputError
from dampersim.units import rad_to_deg, rpm_to_rad_s

#: Accepted shaft speeds [rpm] (as the main CLI).
MIN_RPM, MAX_RPM = 300.0, 6000.0
#: Accepted ramp rates [N m/s]: the thesis uses 50 and shows up to 220 ([thesis] §3.3.1, Fig. 3.9).
MIN_RATE, MAX_RATE = 1.0, 5000.0


def _system(args):
    from dampersim.parameters import load_parameters, parse_set_options

    return load_parameters(getattr(args, "params", None), parse_set_options(getattr(args, "set", None)))


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
    out_dir = getattr(args, "out", None)
    if out_dir and not os.path.isdir(out_dir):
        raise InputError(f"--out {out_dir!r}: accepted is an existing folder")
    system = _system(args)
    loops = run_loops(system, args.protocol, [rpm_to_rad_s(s) for s in speeds], rate=rate, hold=hold, lowpass=bool(args.lowpass))
    analyses = [analyse_loop(lp, system) for lp in loops]
    html = None
    if out_dir:
        from dampersim.plotting.figures import hysteresis_figure, write_html

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

    system = _system(args)
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
        from dampersim.plotting.figures import campbell_figure, write_html

        html = write_html(campbell_figure(data, max_frequency_hz=min(fmax, float(data.order_lines["frequency_hz"].max()))), args.out)
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


def add_parsers(subparsers) -> None:
    """Register the ``hysteresis`` and ``campbell`` sub-commands on ``subparsers``."""
    from dampersim.excitation.ramps import PROTOCOLS

    h = subparsers.add_parser("hysteresis", help="torque-ramp hysteresis loops: knee, stiffness, loop energy")
    h.add_argument("--speeds", default="1000,1500,2000", metavar="RPM,RPM,...", help="shaft speeds [rpm] (default 1000,1500,2000)")
    h.add_argument("--protocol", default="full-450", choices=list(PROTOCOLS), help="torque ramp of thesis Table 3.1 (default full-450)")
    h.add_argument("--rate", type=float, default=50.0, metavar="NMPS", help="ramp rate [N m/s] (default 50, as the thesis)")
    h.add_argument("--hold", type=float, default=2.0, metavar="S", help="hold at each peak [s] (default 2)")
    h.add_argument("--lowpass", action="store_true", help="apply the thesis's 1st-order 10 Hz low pass to the loops")
    h.add_argument("--params", metavar="FILE.toml", help="parameter set (default: built-in damper)")
    h.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter by dotted name")
    h.add_argument("--json", action="store_true", help="machine-readable output")
    h.add_argument("--out", metavar="DIR", help="write an HTML loop figure into this folder")
    h.set_defaults(func=cmd_hysteresis)

    c = subparsers.add_parser("campbell", help="natural frequencies, mode shapes and engine-order crossings")
    c.add_argument("--params", metavar="FILE.toml", help="parameter set (default: built-in damper)")
    c.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter by dotted name")
    c.add_argument("--output-motor", choices=("free", "held"), default="free", help="output motor free (default) or held")
    c.add_argument("--speed-range", metavar="LOW,HIGH", help="speed range [rpm] (default 500,3000)")
    c.add_argument("--max-frequency", type=float, default=500.0, metavar="HZ", help="report modes up to this frequency [Hz] (default 500)")
    c.add_argument("--out", metavar="FILE.html", help="write the Campbell diagram as HTML")
    c.add_argument("--json", action="store_true", help="machine-readable output")
    c.set_defaults(func=cmd_campbell)


__all__ = ["add_parsers", "cmd_hysteresis", "cmd_campbell", "parse_speeds_rpm"]
