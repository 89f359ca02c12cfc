"""Command line ``python -m dampersim <command> ...``: assemble the parser and run one command.

Units at this edge are rpm, N m and Hz; everything inside is SI. Every command reports
bad input as one line on stderr naming the field, the value and what is accepted, and
exits with status 2 (no traceback).

The command line is the top layer: it may import anything in dampersim, and nothing in
dampersim imports it (``dampersim.__main__`` excepted). Modules:

- :mod:`~dampersim.cli.options`: parameter-set options, output paths, speed limits
- :mod:`~dampersim.cli.core`: ``simulate``, ``modes``, ``params``
- :mod:`~dampersim.cli.sweeps`: ``sweep``, ``map``
- :mod:`~dampersim.cli.analysis`: ``hysteresis``, ``campbell``, ``orders``
- :mod:`~dampersim.cli.studies`: ``study``, ``pulsation``
- :mod:`~dampersim.cli.discrepancy`: ``effects``, ``synth``, ``diagnose``
- :mod:`~dampersim.cli.rigdata`: ``import`` (rig recordings into a campaign)
"""

from __future__ import annotations

import argparse
import sys
import warnings

from dampersim.errors import AccuracyWarning, DampersimError

def build_parser() -> argparse.ArgumentParser:
    """The ``dampersim`` parser with every command; each sets ``func`` to its command."""
    from dampersim.cli import analysis, core, discrepancy, rigdata, studies, sweeps

    p = argparse.ArgumentParser(prog="dampersim", description="Torque converter damper simulation")
    sub = p.add_subparsers(dest="command", required=True)
    for group in (core, sweeps, analysis, studies, discrepancy, rigdata):  # the order of --help
        group.add_parsers(sub)
    return p


_SHOWN: set = set()


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Print a warning as one line for the engineer, each text once per command
    (:func:`main` clears the record of shown texts)."""
    if str(message) not in _SHOWN:
        _SHOWN.add(str(message))
        print(f"warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``), run the command, return its exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _SHOWN.clear()  # each command says each warning once
    try:
        with warnings.catch_warnings():
            # a warning of ours is a line for the engineer, once, without a source line
            warnings.filterwarnings("always", category=AccuracyWarning)
            warnings.showwarning = _show_warning
            return args.func(args)
    except DampersimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0


__all__ = ["build_parser", "main"]
