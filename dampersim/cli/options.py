"""Options shared by the commands: parameter-set options, output paths and speed limits.

Every command that takes a damper parameter set registers its options with
:func:`add_parameter_options` and turns them into a validated
:class:`~dampersim.parameters.DamperSystem` with :func:`parameters_from_args`; every
command that writes files prepares each output path with :func:`prepare_output` before
its long work starts. Bad input raises :class:`~dampersim.errors.InputError` (or
:class:`~dampersim.errors.ParameterError`) naming the option, the value and what is
accepted; :func:`dampersim.cli.main` prints it as one line and exits with status 2.
"""

from __future__ import annotations

import os

from dampersim.errors import InputError
from dampersim.parameters import load_parameters, parse_set_options
from dampersim.solver.linear import check_time_step

#: Shaft speeds [rpm] the commands accept.
MIN_RPM, MAX_RPM = 300.0, 6000.0

#: ``--output-motor`` values that set the simulated output motor (``motor.mode``);
#: "free" only concerns the linearised model (modes, campbell).
MOTOR_MODES = ("pi", "held")


def add_parameter_options(parser, *, overrides=True, shorthands=False,
                          params_help="parameter set (default: built-in damper)",
                          set_help="override a parameter by dotted name") -> None:
    """Register ``--params FILE`` and, with ``overrides``, ``--set NAME=VALUE``
    (repeatable); with ``shorthands`` also ``--no-friction`` and ``--no-hardstops``.

    A command with a positional parameter file gives it ``dest="params"`` instead of
    ``--params``. ``--output-motor`` stays with each command (its choices differ) and is
    read by :func:`parameters_from_args` too.
    """
    parser.add_argument("--params", metavar="FILE.toml", help=params_help)
    if overrides:
        parser.add_argument("--set", action="append", metavar="NAME=VALUE", help=set_help)
    if shorthands:
        parser.add_argument("--no-friction", action="store_true", help="shorthand for --set friction.enabled=false")
        parser.add_argument("--no-hardstops", action="store_true", help="shorthand for --set hardstops.enabled=false")


def parameter_updates(args) -> dict:
    """Dotted overrides from ``--set`` and the shorthands ({"friction.enabled": False, ...}).

    ``--set`` items come first; a shorthand given as well wins over a ``--set`` of the
    same name. Options the command does not have count as not given.
    """
    updates = parse_set_options(getattr(args, "set", None))
    if getattr(args, "no_friction", False):
        updates["friction.enabled"] = False
    if getattr(args, "no_hardstops", False):
        updates["hardstops.enabled"] = False
    mode = getattr(args, "output_motor", None)
    if mode in MOTOR_MODES:
        updates["motor.mode"] = mode
    return updates


def parameters_from_args(args):
    """The validated parameter set of ``--params`` (default: the built-in damper) with
    :func:`parameter_updates` applied, its time step checked against the solver's
    stability bound."""
    return check_time_step(load_parameters(getattr(args, "params", None), parameter_updates(args)))


def prepare_output(path, kind="file", option="--out") -> str:
    """Make ``path`` writable and return it as an absolute path.

    kind "file": ``path`` is a file to write; its missing parent folders are created.
    kind "folder": ``path`` is a folder to write into; it is created with its parents.
    An existing file where a folder is wanted (or the reverse), or a folder that cannot
    be created, raises InputError naming ``option`` and ``path``.
    """
    if kind not in ("file", "folder"):
        raise ValueError(f"kind {kind!r}: accepted is 'file' or 'folder'")
    target = os.path.abspath(os.fspath(path))
    if kind == "folder":
        if os.path.exists(target) and not os.path.isdir(target):
            raise InputError(f"{option} {path!r}: exists and is not a folder; accepted is a folder (created if missing)")
        folder = target
    else:
        if os.path.isdir(target):
            raise InputError(f"{option} {path!r}: is a folder; accepted is a file name (its folder is created if missing)")
        folder = os.path.dirname(target)
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {path!r}: cannot create the folder ({exc.strerror or exc})") from None
    return target


__all__ = [
    "MIN_RPM",
    "MAX_RPM",
    "MOTOR_MODES",
    "add_parameter_options",
    "parameter_updates",
    "parameters_from_args",
    "prepare_output",
]
