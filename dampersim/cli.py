"""Command line: ``python -m dampersim <command> ...`` (rpm, N m and Hz at this edge).

Every command reports bad input as one line on stderr naming the field, the value and
what is accepted, and exits with status 2 (no traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from dampersim.errors import DampersimError, InputError
from dampersim.jsonsafe import jsonable
from dampersim.units import rpm_to_rad_s

ORDERS = tuple(range(1, 9))
MIN_RPM, MAX_RPM = 300.0, 6000.0
VALIDATED_RPM = (900.0, 2800.0)  # [thesis] §3.3.2: tested speed range


def _system_from_args(args):
    from dampersim.parameters import load_parameters, parse_set_options

    updates = parse_set_options(getattr(args, "set", None))
    if getattr(args, "no_friction", False):
        updates["friction.enabled"] = False
    if getattr(args, "no_hardstops", False):
        updates["hardstops.enabled"] = False
    mode = getattr(args, "output_motor", None)
    if mode in ("pi", "held"):
        updates["motor.mode"] = mode
    return load_parameters(getattr(args, "params", None), updates)


def _speed(rpm: float) -> float:
    if not (math.isfinite(rpm) and MIN_RPM <= rpm <= MAX_RPM):
        raise InputError(f"--speed {rpm!r} rpm: accepted is {MIN_RPM:g} to {MAX_RPM:g} rpm")
    if not VALIDATED_RPM[0] <= rpm <= VALIDATED_RPM[1]:
        print(
            f"warning: {rpm:g} rpm lies outside {VALIDATED_RPM[0]:g}-{VALIDATED_RPM[1]:g} rpm, "
            "where the thesis validated the model",
            file=sys.stderr,
        )
    return rpm_to_rad_s(rpm)


def cmd_simulate(args) -> int:
    from dampersim.analysis.metrics import magnification_ratio
    from dampersim.excitation import OrderSum, parse_orders
    from dampersim.simulation import simulate

    system = _system_from_args(args)
    orders = parse_orders(args.orders)
    if not math.isfinite(args.torque) or abs(args.torque) > 5000:
        raise InputError(f"--torque {args.torque!r} N m: accepted is a mean torque within +-5000 N m")
    ex = OrderSum(speed=_speed(args.speed), mean_torque=args.torque, orders=orders)
    res = simulate(system, ex, duration=args.duration, record_segments=False)
    a_in, a_out = res.order_amplitudes(ORDERS)
    # an order without input (below 0.1 % of the largest) has no meaningful ratio
    mr = magnification_ratio(a_in, a_out, min_input=max(1e-3 * float(np.max(a_in)), 1e-6))
    if args.out:
        from dampersim.fileio import write_parquet_atomic

        write_parquet_atomic(res.to_frame(), args.out)
    if args.json:
        print(
            json.dumps(
                {
                    "orders": list(ORDERS),
                    "input_amplitude_nm": jsonable(np.asarray(a_in, dtype=float)),
                    "output_amplitude_nm": jsonable(np.asarray(a_out, dtype=float)),
                    "magnification": jsonable(np.asarray(mr, dtype=float)),
                    "wall_time_s": res.wall_time,
                }
            )
        )
    else:
        print(f"{system.name}: {args.speed:g} rpm, {args.torque:g} N m mean, {res.t[-1] + 1 / res.sample_rate:.2f} s")
        print(f"{'order':>5} {'input [N m]':>12} {'output [N m]':>13} {'MR [-]':>8}")
        for k, ai, ao, m in zip(ORDERS, a_in, a_out, mr):
            ms = f"{m:8.3f}" if math.isfinite(m) else f"{'-':>8}"
            print(f"{k:>5} {ai:12.3f} {ao:13.3f} {ms}")
        print(f"simulation wall time {res.wall_time:.3f} s")
    return 0


def cmd_modes(args) -> int:
    from dampersim.analysis.modal import campbell, modal_analysis
    from dampersim.solver.linear import linearise

    system = _system_from_args(args)
    motor = args.output_motor or "free"
    lm = linearise(system, motor=motor)
    modal = modal_analysis(system, motor=motor)
    d = lm.to_dict()
    d["mode_shapes"] = modal.shapes.tolist()  # columns = modes, ascending frequency
    # the three DOFs holding most of each mode's kinetic energy: [[name, share], ...]
    d["dominant_dofs"] = [[[n, float(w)] for n, w in modal.dominant_dofs(i, 3)] for i in range(len(modal.frequencies_hz))]
    if args.out:
        from dampersim import plotting

        fig = plotting.campbell_figure(campbell(modal), max_frequency_hz=400.0)
        d["campbell_html"] = plotting.write_html(fig, args.out)
    if args.json:
        print(json.dumps(d))
    else:
        print(f"{system.name}: {len(d['dof_names'])} DOFs, output motor {lm.motor}")
        for i, f in enumerate(d["natural_frequencies_hz"][:12]):
            parts = ", ".join(f"{n} {100 * w:.0f} %" for n, w in d["dominant_dofs"][i])
            print(f"mode {i + 1:2d}: {f:10.2f} Hz   {parts}")
        if args.out:
            print(f"Campbell diagram: {d['campbell_html']}")
    return 0


def cmd_params(args) -> int:
    from dampersim.parameters import dumps_toml, load_parameters, parse_set_options

    system = load_parameters(args.file, parse_set_options(args.set))
    if args.action == "show":
        print(dumps_toml(system), end="")
    else:
        print(f"valid: {system.name}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dampersim", description="Torque converter damper simulation")
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp, motor_choices):
        sp.add_argument("--params", metavar="FILE.toml", help="parameter set (default: built-in damper)")
        sp.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter by dotted name")
        sp.add_argument("--no-friction", action="store_true", help="shorthand for --set friction.enabled=false")
        sp.add_argument("--no-hardstops", action="store_true", help="shorthand for --set hardstops.enabled=false")
        sp.add_argument("--output-motor", choices=motor_choices, help="output motor control")
        sp.add_argument("--json", action="store_true", help="machine-readable output")

    s = sub.add_parser("simulate", help="one test point: order amplitudes and magnification")
    s.add_argument("--speed", type=float, required=True, metavar="RPM")
    s.add_argument("--torque", type=float, required=True, metavar="NM", help="mean torque [N m]")
    s.add_argument("--orders", default="2:300", help='ORDER:AMPLITUDE[@PHASE_DEG],... e.g. "2:300,4:100"')
    s.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time [s]")
    s.add_argument("--out", metavar="FILE.parquet", help="write the time series")
    common(s, ("pi", "held"))
    s.set_defaults(func=cmd_simulate)

    m = sub.add_parser("modes", help="linearised model (M, C, K), natural frequencies, mode shapes")
    common(m, ("free", "held"))
    m.add_argument("--out", metavar="FILE.html", help="write a Campbell diagram (orders 1-8 vs the modes)")
    m.set_defaults(func=cmd_modes)

    pa = sub.add_parser("params", help="show or validate a parameter set")
    pa.add_argument("action", choices=("show", "validate"))
    pa.add_argument("file", nargs="?", default=None)
    pa.add_argument("--set", action="append", metavar="NAME=VALUE")
    pa.set_defaults(func=cmd_params)

    from dampersim.analysis.commands import add_parsers as add_analysis
    from dampersim.sweeps.commands import add_parsers as add_sweeps

    add_sweeps(sub)
    add_analysis(sub)
    from dampersim.studies.commands import add_parsers as add_studies

    add_studies(sub)
    from dampersim.discrepancy.commands import add_parsers as add_discrepancy
    add_discrepancy(sub)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except DampersimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
