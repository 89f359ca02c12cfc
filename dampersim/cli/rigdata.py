"""The ``import`` command: turn rig recordings (MDF4, TDMS, MAT, CSV) into a campaign folder.

    python -m dampersim import SOURCE... --out CAMPAIGN [--map MAP.toml] [--cuts MANIFEST.csv]
                                        [--rate HZ] [--json]

Review the cuts by reading the written manifest (``start_s``/``end_s`` per point); to
change them, edit a copy of it and import again with ``--cuts`` into a new folder.
"""

from __future__ import annotations

import json
import sys


def cmd_import(args) -> int:
    from dampersim.errors import InputError
    from dampersim.rigdata.importer import import_campaign

    if args.rate is not None and not (args.rate > 0):
        raise InputError(f"--rate {args.rate!r}: accepted is a positive sample rate in Hz")
    report = import_campaign(args.sources, args.out, map_path=args.map, cuts_path=args.cuts, rate_hz=args.rate,
                             name=args.name or "", description=args.description or "")
    if args.json:
        print(json.dumps(report.to_dict()))
    else:
        print(report.text())
    if report.dropped:
        print(f"{len(report.dropped)} cut(s) dropped; see the report", file=sys.stderr)
    return 0


def add_parsers(sub) -> None:
    p = sub.add_parser("import", help="import rig recordings (MDF4, TDMS, MAT, CSV) as a campaign folder",
                       description="Read one or more recordings, map their channels onto the campaign's columns, cut "
                                   "them into test points (steady plateaus and torque ramps) and write a campaign folder "
                                   "for `diagnose`. The source files are never modified.")
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="recording files, or folders of them")
    p.add_argument("--out", required=True, metavar="CAMPAIGN", help="campaign folder to create (must not exist or be empty)")
    p.add_argument("--map", metavar="MAP.toml", help="channel map: [channels.<column>] name, unit, gain, offset")
    p.add_argument("--cuts", metavar="MANIFEST.csv", help="an import's manifest with edited cuts (start_s, end_s, kind)")
    p.add_argument("--rate", type=float, metavar="HZ", help="sample rate of the written points [Hz] (default: the file's)")
    p.add_argument("--name", help="campaign name (default: the folder name)")
    p.add_argument("--description", help="campaign description")
    p.add_argument("--json", action="store_true", help="print the import report as JSON")
    p.set_defaults(func=cmd_import)


__all__ = ["add_parsers", "cmd_import"]
