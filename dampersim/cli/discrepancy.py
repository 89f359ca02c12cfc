"""Commands ``effects``, ``synth`` and ``diagnose``: the discrepancy workflow from synthetic campaign to named missing effect.

Register the commands with :func:`add_parsers`; each command function takes the parsed
``args`` and returns the exit status: 0, or 2 for a campaign that cannot be diagnosed
(verdict ``insufficient_data``, still printed); other bad input raises a
:class:`~dampersim.errors.DampersimError`.
"""

from __future__ import annotations

import json
import math
import sys

from dampersim.cli.options import add_parameter_options, parameters_from_args, prepare_output
from dampersim.errors import InputError
from dampersim.jsonsafe import jsonable


def cmd_effects(args) -> int:
    """List the candidate effects with their parameters and signatures."""
    from dampersim.discrepancy.effects import catalogue

    cat = catalogue()
    if args.json:
        print(json.dumps([{"name": c["name"], "description": c["description"],
                           "parameters": [{k: p[k] for k in ("name", "unit", "default", "min", "max")} for p in c["parameters"]],
                           "cause": c["cause"], "signature": c["signature"],
                           "magnitude_parameter": c["magnitude_parameter"]} for c in cat], indent=2))
        return 0
    for c in cat:
        print(f"{c['name']}: {c['description']}")
        for p in c["parameters"]:
            print(f"    {p['name']} = {p['default']} {p['unit']}  [{p['min']}, {p['max']}]  {p['doc']}")
        print(f"    signature: {c['signature']}")
    return 0


def cmd_synth(args) -> int:
    """Write a synthetic measured campaign (and optionally its truth)."""
    from dampersim.discrepancy.effects import parse_effect_spec
    from dampersim.discrepancy.synth import synthesize

    effects = [parse_effect_spec(e) for e in args.effect or ()]
    if not (0.0 <= args.perturb < 1.0):
        raise InputError(f"--perturb {args.perturb!r}: accepted is a fraction in [0, 1)")
    if not math.isfinite(args.noise_db) or not -80 <= args.noise_db <= 40:
        raise InputError(f"--noise-db {args.noise_db!r}: accepted is -80 to 40 dB re 1 N m")
    base = parameters_from_args(args)
    prepare_output(args.out, "folder")
    if args.truth:
        prepare_output(args.truth, "file", option="--truth")
    doc = synthesize(args.out, campaign=args.campaign, effects=effects, perturb=args.perturb, noise_db=args.noise_db,
                     seed=args.seed, truth=args.truth, base=base, workers=args.workers, record=args.record,
                     daq=getattr(args, "daq", "none"),
                     points=[x.strip() for x in args.points.split(",") if x.strip()] if args.points else None)
    print(f"wrote {len(doc['points'])} test points to {args.out}" + (f"; truth in {args.truth}" if args.truth else ""))
    return 0


def cmd_diagnose(args) -> int:
    """Diagnose a campaign; print the verdict, optionally write the augmented set and a report."""
    from dampersim.discrepancy.campaign import read_campaign
    from dampersim.discrepancy.diagnose import INSUFFICIENT, diagnose
    from dampersim.parameters import save_toml

    cands = None
    if args.candidates:
        from dampersim.discrepancy.effects import NAMES

        cands = [c.strip() for c in args.candidates.split(",") if c.strip()]
        unknown = [c for c in cands if c not in NAMES]
        if unknown or not cands:
            raise InputError(f"--candidates {args.candidates!r}: {', '.join(unknown) or 'no name'} is not an effect; "
                             f"accepted is a comma-separated list of {', '.join(NAMES)}")
    camp = read_campaign(args.campaign)
    if camp.problems:
        print(camp.report_text(), file=sys.stderr)
    system = parameters_from_args(args)
    if args.out_params:
        prepare_output(args.out_params, "file", option="--out-params")
    if args.report:
        prepare_output(args.report, "file", option="--report")

    def progress(frac, text):
        if not args.json:
            print(f"[{100 * frac:5.1f} %] {text}", file=sys.stderr, flush=True)

    diag = diagnose(camp, system, workers=args.workers, progress=progress, candidates=cands,
                    recommend=not args.no_recommend)
    out = jsonable(diag.to_json())
    for q in diag.problems[len(camp.problems):]:  # the model runs that failed
        print(f"{q['point']} [{q['field']}]: {q['message']}", file=sys.stderr)
    if diag.verdict == INSUFFICIENT:
        # the verdict goes out as usual; no report and no parameter set, since nothing was fitted
        print(json.dumps(out, indent=2) if args.json else f"verdict: {diag.verdict}")
        print(f"error: campaign {camp.name}: {diag.message}"
              + (" No report or parameter set written." if args.report or args.out_params else ""), file=sys.stderr)
        return 2
    if args.out_params:
        import dataclasses

        sysout = dataclasses.replace(diag.system, name=f"{diag.system.name}-augmented",
                                     source=f"{diag.system.source}; diagnosed from campaign {camp.name}: {diag.verdict}"
                                     + (f" ({diag.effect})" if diag.effect else ""))
        save_toml(sysout, args.out_params)
    if args.report:
        from dampersim.fileio import write_text_atomic
        from dampersim.discrepancy.report_tables import report_html

        write_text_atomic(args.report, report_html(diag, camp.name))
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"verdict: {diag.verdict}" + (f" -> {diag.effect} {diag.effect_parameters}" if diag.effect else ""))
        print(f"noise floor {diag.noise_floor_nm:.3f} N m; held-out gap before {diag.gap_before_nm:.3f}, "
              f"calibrated {diag.gap_calibrated_nm:.3f}, after {diag.gap_after_nm:.3f} N m")
        print(diag.message)
        for r in diag.ranking:
            g = r["gap_held_out_nm"]
            print(f"  {r['effect']:24s} " + (f"held-out gap {g:.3f} N m {r['parameters']}" if g is not None
                                             else r["excluded"] or "screened out"))
    return 0


def add_parsers(subparsers) -> None:
    """Register ``effects``, ``synth`` and ``diagnose`` on an argparse subparsers object."""
    p = subparsers.add_parser("effects", help="list the candidate effects of the discrepancy workflow")
    p.add_argument("--json", action="store_true", help="machine-readable list")
    p.set_defaults(func=cmd_effects)

    p = subparsers.add_parser("synth", help="write a synthetic measured campaign (truth optionally hiding effects)")
    p.add_argument("--out", required=True, help="campaign folder to write (created if missing)")
    p.add_argument("--campaign", default="all", choices=("torque-curve", "mapping", "hysteresis", "all"))
    p.add_argument("--effect", action="append", metavar="NAME[:param=value,...]", help="hidden effect (repeatable)")
    p.add_argument("--perturb", type=float, default=0.1, help="relative perturbation of the estimated parameters")
    p.add_argument("--noise-db", type=float, default=0.0, help="sensor noise RMS in dB re 1 N m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--truth", help="file for the truth (outside the campaign folder)")
    add_parameter_options(p, overrides=False, params_help="base parameter set (TOML); default set if omitted")
    p.add_argument("--record", type=float, default=1.25, help="record length of torsional points [s]")
    p.add_argument("--workers", type=int, default=1, help="processes")
    p.add_argument("--points", help="comma-separated test-point ids to keep (e.g. tc_1200,map_900_50); default all")
    p.add_argument("--daq", default="none", choices=("none", "random"),
                   help="acquisition chain: none (default) or random (gains, offsets, drift, mains hum, anti-alias "
                        "filter, channel skew, speed ripple drawn from --seed; written to --truth)")
    p.set_defaults(func=cmd_synth)

    p = subparsers.add_parser("diagnose", help="find, name and add the effect the model is missing")
    p.add_argument("campaign", help="campaign folder (manifest.csv + time series)")
    add_parameter_options(p, overrides=False, params_help="parameter set to diagnose (TOML); default set if omitted")
    p.add_argument("--json", action="store_true")
    p.add_argument("--report", help="write an HTML report")
    p.add_argument("--out-params", help="write the augmented parameter set (TOML)")
    p.add_argument("--workers", type=int, default=None, help="processes (default: up to 2)")
    p.add_argument("--candidates", help="comma-separated effects to consider (default: all of `effects`)")
    p.add_argument("--no-recommend", action="store_true",
                   help="skip the next-test design (its candidate points are simulated with each model in question)")
    p.set_defaults(func=cmd_diagnose)


__all__ = ["add_parsers", "cmd_effects", "cmd_synth", "cmd_diagnose"]
