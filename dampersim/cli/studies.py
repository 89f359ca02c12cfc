"""Commands ``study`` and ``pulsation``: the thesis chapter 7 studies and the motored-engine pulsation generator.

Units at this edge are rpm, bar, N m and s. Register the commands with
:func:`add_parsers`; each command function takes the parsed ``args`` and returns the exit
status 0, bad input raises a :class:`~dampersim.errors.DampersimError`.
"""

from __future__ import annotations

import json
import math
import os
import sys

from dampersim.cli.options import add_parameter_options, parameters_from_args, prepare_output
from dampersim.errors import InputError


def cmd_study(args) -> int:
    """Run one study; print its checks, optionally write NAME.json and its figures."""
    from dampersim.studies import STUDIES, run_study

    if args.name not in STUDIES:
        raise InputError(f"study {args.name!r}: accepted is one of {', '.join(STUDIES)}")
    system = parameters_from_args(args)
    out_dir = prepare_output(args.out, "folder") if args.out else None

    def progress(done, total, cached):
        if not args.json and sys.stderr.isatty():
            print(f"\r{args.name}: {done}/{total} points ({cached} from cache)", end="", file=sys.stderr)

    result = run_study(args.name, system, quick=args.quick, executor=args.executor, progress=progress)
    for w in result.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)
    if out_dir:
        from dampersim.fileio import write_text_atomic

        write_text_atomic(os.path.join(out_dir, f"{args.name}.json"), json.dumps(result, indent=1, allow_nan=False))
        try:
            from dampersim.plotting import write_html
            from dampersim.plotting.studies import study_figures

            for i, fig in enumerate(study_figures(result)):
                write_html(fig, os.path.join(out_dir, f"{args.name}-{i + 1}.html"), include_plotlyjs="cdn")
        except ImportError:
            pass
    if args.json:
        print(json.dumps(result, allow_nan=False))
    else:
        if sys.stderr.isatty():
            print(file=sys.stderr)
        print(f"{args.name}: {result['points']} points ({result['from_cache']} from cache), {result['wall_time_s']:.1f} s")
        for k, v in result["checks"].items():
            print(f"  {k}: {'yes' if v else 'NO'}")
    return 0


def cmd_pulsation(args) -> int:
    """Simulate the pulsation generator alone or coupled to the damper; print its orders."""
    from dampersim.excitation.pulsation import check_speed_rpm, pressure_warnings
    from dampersim.simulation import simulate_pulsation
    from dampersim.parameters.engine import check_pressure_bar
    from dampersim.units import rpm_to_rad_s

    p = check_pressure_bar(args.pressure)
    for w in check_speed_rpm(args.speed, warn=False) + pressure_warnings(p):
        print(w, file=sys.stderr)
    if not (math.isfinite(args.torque) and abs(args.torque) <= 1000):
        raise InputError(f"--torque {args.torque!r} N m: accepted is a mean torque within +-1000 N m")
    system = parameters_from_args(args) if args.coupled else None
    res = simulate_pulsation(rpm_to_rad_s(args.speed), p, args.torque, coupled=args.coupled, system=system)
    s = res.summary()
    if args.json:
        print(json.dumps(s, allow_nan=False))
    else:
        mode = "coupled to the damper and rig" if args.coupled else "alone on a stiff shaft"
        print(f"pulsation generator {p:g} bar, {args.speed:g} rpm, {mode}")
        print(f"peak cylinder pressure {s['peak_cylinder_pressure_bar']:.1f} bar, mean torque {s['mean_torque_nm']:.1f} N m")
        for k, a in zip(s["orders"], s["amplitude_nm"]):
            print(f"  order {k:g}: {a:9.1f} N m")
        print(f"dominant order {s['dominant_order']:g}")
    return 0


def add_parsers(subparsers) -> None:
    """Register ``study`` and ``pulsation`` on an argparse subparsers object."""
    from dampersim.studies import STUDIES

    s = subparsers.add_parser("study", help="run a thesis chapter 7 study: " + ", ".join(STUDIES))
    s.add_argument("name", metavar="NAME", help="one of " + ", ".join(STUDIES))
    add_parameter_options(s, params_help="damper parameter set (default: built-in damper)",
                          set_help="override a damper parameter by dotted name")
    s.add_argument("--quick", action="store_true", help="reduced grid (seconds instead of minutes)")
    s.add_argument("--executor", choices=("processes", "serial"), default="processes")
    s.add_argument("--json", action="store_true", help="print the result document as JSON")
    s.add_argument("--out", metavar="DIR", help="write NAME.json (and figures) into DIR (created if missing)")
    s.set_defaults(func=cmd_study)

    p = subparsers.add_parser("pulsation", help="motored-engine pulsation generator: order content of its output torque")
    p.add_argument("--pressure", type=float, default=2.5, metavar="BAR", help="charge pressure [bar abs] (0.5-4)")
    p.add_argument("--speed", type=float, required=True, metavar="RPM")
    p.add_argument("--torque", type=float, default=200.0, metavar="NM", help="mean torque [N m]")
    p.add_argument("--coupled", action="store_true", help="drive the damper and rig instead of a stiff propshaft")
    add_parameter_options(p, params_help="damper parameter set for --coupled",
                          set_help="override a damper parameter (with --coupled)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_pulsation)


__all__ = ["add_parsers", "cmd_study", "cmd_pulsation"]
