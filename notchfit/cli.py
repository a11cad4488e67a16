"""The ``notchfit`` command line.

Each sub-command is a module in :mod:`notchfit.commands` that defines

* ``NAME`` (the sub-command), ``HELP`` (one line), ``DESCRIPTION`` (``--help``
  text with examples), ``ORDER`` (position in the listing);
* ``add_arguments(parser)`` and ``run(args) -> int``.

This module discovers the command modules and runs the chosen one; what the
commands share (the input-error type, exit codes, common options) is in
:mod:`notchfit.commands._common`, which imports neither this module nor the
commands. Exit codes: 0 ok, 1 some items failed (listed by the command), 2
usage or input error (a clear message on stderr).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import __version__, commands
from .commands._common import EXIT_INPUT_ERROR, add_command, execute


def _command_modules():
    """The command modules of :mod:`notchfit.commands`, in listing order (``ORDER``, then ``NAME``)."""
    mods = []
    for info in pkgutil.iter_modules(commands.__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "NAME") and hasattr(mod, "run"):
            mods.append(mod)
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    """The ``notchfit`` parser with one sub-parser per command module."""
    parser = argparse.ArgumentParser(
        prog="notchfit",
        description="Kinematics, friction simulation, calibrated image processing and "
                    "model diagnosis for cable-driven notched-tube manipulators.",
        epilog="Run `notchfit COMMAND --help` for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"notchfit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _command_modules():
        add_command(sub, mod)
    return parser


def main(argv=None) -> int:
    """Run ``notchfit`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return EXIT_INPUT_ERROR
    return execute(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
