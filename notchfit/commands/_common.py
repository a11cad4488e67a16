"""What every sub-command shares: the input-error type, exit codes, common options, running a command.

This module imports nothing from :mod:`notchfit.cli` or from the command
modules, so that :mod:`notchfit.cli` can import the commands and the
commands (and the demo, which runs other commands) can import this without a
cycle.

Exit codes: 0 ok, :data:`EXIT_ITEMS_FAILED` (1) some items failed (listed by
the command), :data:`EXIT_INPUT_ERROR` (2) a usage or input error (a one-line
message on stderr).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["EXIT_INPUT_ERROR", "EXIT_ITEMS_FAILED", "INPUT_ERRORS", "InputError", "add_batch_options",
           "add_command", "add_points_option", "call", "execute"]

EXIT_ITEMS_FAILED = 1
EXIT_INPUT_ERROR = 2


class InputError(Exception):
    """A usage or input problem that the user must fix (exit code 2)."""


#: Exceptions that a command reports as ``notchfit NAME: error: ...`` with exit code 2.
INPUT_ERRORS = (InputError, ValueError, FileNotFoundError, FileExistsError)


def add_command(subparsers, mod) -> argparse.ArgumentParser:
    """Add command module ``mod`` (``NAME``, ``HELP``, ``DESCRIPTION``, ``add_arguments``, ``run``).

    Parameters
    ----------
    subparsers : argparse subparsers action, or None
        ``None`` makes a stand-alone parser (``prog = "notchfit NAME"``).
    mod : module

    Returns
    -------
    argparse.ArgumentParser
        The command's parser; its defaults carry ``_run`` and ``command``.
    """
    kw = dict(description=getattr(mod, "DESCRIPTION", mod.HELP),
              formatter_class=argparse.RawDescriptionHelpFormatter)
    if subparsers is None:
        parser = argparse.ArgumentParser(prog=f"notchfit {mod.NAME}", **kw)
    else:
        parser = subparsers.add_parser(mod.NAME, help=mod.HELP, **kw)
    mod.add_arguments(parser)
    parser.set_defaults(_run=mod.run, command=mod.NAME)
    return parser


def execute(args) -> int:
    """Run the parsed command ``args._run(args)``; an input error becomes a message and exit code 2."""
    try:
        return int(args._run(args) or 0)
    except INPUT_ERRORS as exc:
        print(f"notchfit {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT_ERROR


def call(mod, argv) -> int:
    """Run command module ``mod`` on the arguments ``argv`` (without the command name), as the CLI would."""
    return execute(add_command(None, mod).parse_args([str(a) for a in argv]))


def add_batch_options(parser) -> None:
    """``--jobs N`` and ``--scheduler ADDRESS`` of the commands that run on :func:`notchfit.batch.run_batch`."""
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1; 0 = all CPUs)")
    parser.add_argument("--scheduler", default=None, help="Dask distributed scheduler address")


def add_points_option(parser, *aliases, help: str) -> None:
    """``--points DIR``: the folder of a ``notchfit detect`` run to take notch points from.

    The one option name for "points from a detect run" (``fit``, ``simulate``,
    ``diagnose``); ``aliases`` are older names that still work (e.g.
    ``"--detections"``). The value is ``args.points`` (a Path or None).
    """
    parser.add_argument("--points", *aliases, dest="points", type=Path, default=None, metavar="DIR", help=help)
