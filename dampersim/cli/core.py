"""Commands ``simulate``, ``modes`` and ``params``: one test point, the linearised model and parameter sets.

Units at this edge are rpm, N m, Hz and s. Register the commands with
:func:`add_parsers`; each command function takes the parsed ``args`` and returns the exit
status 0, bad input raises a :class:`~dampersim.errors.DampersimError`.
"""

from __future__ import annotations

import json
import math
import re
import sys

import numpy as np

from dampersim.cli.options import MAX_RPM, MIN_RPM, add_parameter_options, parameters_from_args, prepare_output
from dampersim.errors import InputError
from dampersim.jsonsafe import jsonable
from dampersim.units import rpm_to_rad_s

ORDERS = tuple(range(1, 9))
VALIDATED_RPM = (900.0, 2800.0)  # [thesis] §3.3.2: tested speed range


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


def _repeat_runs(raw) -> int | None:
    """``--repeatability K``: None when not given, else K as an int from 2 to 32."""
    from dampersim.analysis.repeatability import MAX_RUNS, MIN_RUNS

    if raw is None:
        return None
    text = str(raw).strip()
    if not (re.fullmatch(r"[0-9]{1,3}", text) and MIN_RUNS <= int(text) <= MAX_RUNS):
        raise InputError(f"--repeatability {raw!r}: accepted is a whole number of runs from {MIN_RUNS} to {MAX_RUNS}")
    return int(text)


def cmd_simulate(args) -> int:
    """Simulate one test point; print order amplitudes and magnification, optionally
    write the result (Parquet, :meth:`~dampersim.results.SimulationResult.save`).

    With ``--repeatability K`` the point runs K times, run i with every input order
    amplitude scaled by (1 + i·1e-9) (:func:`dampersim.analysis.repeatability.repeatability`);
    run 0 is reported as without the option, plus the spread of each output order over the
    K runs [%] (``repeatability_pct`` in JSON, null where the order's median output is below
    0.1 % of the largest). ``--spread-check`` (only with ``--repeatability``) runs the K runs
    again at half ``solver.time_step`` and labels each order's spread
    (:func:`dampersim.analysis.repeatability.spread_origin`: ``spread_origin`` in JSON,
    "physical", "numerical" or null)."""
    from dampersim.analysis.metrics import magnification_ratio
    from dampersim.excitation import OrderSum, parse_orders
    from dampersim.simulation import simulate

    runs = _repeat_runs(getattr(args, "repeatability", None))
    check = bool(getattr(args, "spread_check", False))
    if check and runs is None:
        raise InputError("--spread-check needs --repeatability K: accepted is --spread-check together with --repeatability K")
    system = parameters_from_args(args)
    orders = parse_orders(args.orders)
    if not math.isfinite(args.torque) or abs(args.torque) > 5000:
        raise InputError(f"--torque {args.torque!r} N m: accepted is a mean torque within +-5000 N m")
    ex = OrderSum(speed=_speed(args.speed), mean_torque=args.torque, orders=orders)
    out = prepare_output(args.out, "file") if args.out else None
    spread = origin = None
    if runs is None:
        res = simulate(system, ex, duration=args.duration, record_segments=False)
    else:
        from dampersim.analysis.repeatability import repeatability

        rep = repeatability(system, ex, runs, ORDERS, duration=args.duration)
        res, spread = rep.result, rep.spread_pct
        if check:
            from dampersim.analysis.repeatability import spread_check

            sc = spread_check(system, ex, rep, duration=args.duration)
            half, origin = sc.spread_pct, sc.origin
    a_in, a_out = res.order_amplitudes(ORDERS)
    # an order without input (below 0.1 % of the largest) has no meaningful ratio
    mr = magnification_ratio(a_in, a_out, min_input=max(1e-3 * float(np.max(a_in)), 1e-6))
    if out:
        res.save(out)
    if args.json:
        d = {
            "orders": list(ORDERS),
            "input_amplitude_nm": jsonable(np.asarray(a_in, dtype=float)),
            "output_amplitude_nm": jsonable(np.asarray(a_out, dtype=float)),
            "magnification": jsonable(np.asarray(mr, dtype=float)),
            "wall_time_s": res.wall_time,
        }
        if spread is not None:
            d["repeatability_pct"] = list(spread)
        if origin is not None:
            d["spread_origin"] = list(origin)
        print(json.dumps(d))
    else:
        print(f"{system.name}: {args.speed:g} rpm, {args.torque:g} N m mean, {res.t[-1] + 1 / res.sample_rate:.2f} s")
        head = f"{'order':>5} {'input [N m]':>12} {'output [N m]':>13} {'MR [-]':>8}"
        print(head + (f" {f'spread of {runs} runs [%]':>22}" if spread is not None else "")
              + (f" {'at dt/2 [%]':>12} {'origin':>10}" if origin is not None else ""))
        for i, (k, ai, ao, m) in enumerate(zip(ORDERS, a_in, a_out, mr)):
            ms = f"{m:8.3f}" if math.isfinite(m) else f"{'-':>8}"
            line = f"{k:>5} {ai:12.3f} {ao:13.3f} {ms}"
            if spread is not None:
                line += f" {spread[i]:22.3g}" if spread[i] is not None else f" {'-':>22}"
            if origin is not None:
                line += (f" {half[i]:12.3g}" if half[i] is not None else f" {'-':>12}") + f" {origin[i] or '-':>10}"
            print(line)
        if spread is not None:
            print(f"spread: 100 (max - min) / median of each output order over {runs} runs with the input amplitudes "
                  f"scaled by 1 + i 1e-9; - where the order is below 0.1 % of the largest")
        if origin is not None:
            from dampersim.analysis.repeatability import SPREAD_FLOOR_PCT

            print(f"origin: the same runs at half the step ({system.solver.time_step / 2:.4g} s); physical where both spreads "
                  f"are at least {SPREAD_FLOOR_PCT:g} % and the one at dt/2 at least half the one at dt, numerical where it "
                  f"falls below half or is above {SPREAD_FLOOR_PCT:g} % at one step only, - where both are below")
        print(f"simulation wall time {res.wall_time:.3f} s" + (" (run 0)" if spread is not None else ""))
    return 0


def cmd_modes(args) -> int:
    """Print (or dump as JSON) the linearised model, its natural frequencies and mode
    shapes; optionally write a Campbell diagram."""
    from dampersim.analysis.modal import campbell, modal_analysis
    from dampersim.solver.linear import linearise

    system = parameters_from_args(args)
    motor = args.output_motor or "free"
    lm = linearise(system, motor=motor)
    modal = modal_analysis(system, motor=motor)
    d = lm.to_dict()
    d["mode_shapes"] = modal.shapes.tolist()  # columns = modes, ascending frequency
    # the three DOFs holding most of each mode's kinetic energy: [[name, share], ...]
    d["dominant_dofs"] = [[[n, float(w)] for n, w in modal.dominant_dofs(i, 3)] for i in range(len(modal.frequencies_hz))]
    if args.out:
        from dampersim import plotting

        out = prepare_output(args.out, "file")
        fig = plotting.campbell_figure(campbell(modal), max_frequency_hz=400.0)
        d["campbell_html"] = plotting.write_html(fig, out)
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
    """Print a parameter set as TOML (``show``) or check it (``validate``)."""
    from dampersim.parameters import dumps_toml

    system = parameters_from_args(args)
    if args.action == "show":
        print(dumps_toml(system), end="")
    else:
        print(f"valid: {system.name}")
    return 0


def add_parsers(subparsers) -> None:
    """Register ``simulate``, ``modes`` and ``params`` on an argparse subparsers object."""
    s = subparsers.add_parser("simulate", help="one test point: order amplitudes and magnification")
    s.add_argument("--speed", type=float, required=True, metavar="RPM")
    s.add_argument("--torque", type=float, required=True, metavar="NM", help="mean torque [N m]")
    s.add_argument("--orders", default="2:300", help='ORDER:AMPLITUDE[@PHASE_DEG],... e.g. "2:300,4:100"')
    s.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time [s]")
    s.add_argument("--out", metavar="FILE.parquet", help="write the result: time series and run data (missing folders are created)")
    add_parameter_options(s, shorthands=True)
    s.add_argument("--output-motor", choices=("pi", "held"), help="output motor control")
    s.add_argument("--json", action="store_true", help="machine-readable output")
    s.add_argument("--repeatability", metavar="K", default=None,
                   help="run K times (2-32) with the input amplitudes scaled by 1 + i 1e-9 and report the spread "
                        "of each output order [%%] (repeatability_pct in JSON)")
    s.add_argument("--spread-check", action="store_true",
                   help="with --repeatability: run the K runs again at half the time step and label each order's spread "
                        "physical (it does not shrink) or numerical (spread_origin in JSON)")
    s.set_defaults(func=cmd_simulate)

    m = subparsers.add_parser("modes", help="linearised model (M, C, K), natural frequencies, mode shapes")
    add_parameter_options(m, shorthands=True)
    m.add_argument("--output-motor", choices=("free", "held"), help="output motor control")
    m.add_argument("--json", action="store_true", help="machine-readable output")
    m.add_argument("--out", metavar="FILE.html", help="write a Campbell diagram (orders 1-8 vs the modes)")
    m.set_defaults(func=cmd_modes)

    pa = subparsers.add_parser("params", help="show or validate a parameter set")
    pa.add_argument("action", choices=("show", "validate"))
    pa.add_argument("params", nargs="?", default=None, metavar="file")
    pa.add_argument("--set", action="append", metavar="NAME=VALUE")
    pa.set_defaults(func=cmd_params)


__all__ = ["add_parsers", "cmd_simulate", "cmd_modes", "cmd_params"]
