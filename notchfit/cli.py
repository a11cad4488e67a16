"""The ``notchfit`` command line.

Each sub-command is a module in :mod:`notchfit.commands` that defines

* ``NAME`` (the sub-command), ``HELP`` (one line), ``DESCRIPTION`` (``--help``
  text with examples), ``ORDER`` (position in the listing);
* ``add_arguments(parser)`` and ``run(args) -> int``.

Exit codes: 0 ok, 1 some items failed (listed by the command), 2 usage or
input error (a clear message on stderr).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import __version__, commands

EXIT_OK, EXIT_ITEMS_FAILED, EXIT_INPUT_ERROR = 0, 1, 2


class InputError(Exception):
    """A usage or input problem that the user must fix (exit code 2)."""


def _command_modules():
    mods = []
    for info in pkgutil.iter_modules(commands.__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "NAME") and hasattr(mod, "run"):
            mods.append(mod)
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="notchfit",
        description="Kinematics, friction simulation, calibrated image processing and "
                    "model diagnosis for cable-driven notched-tube manipulators.",
        epilog="Run `notchfit COMMAND --help` for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"notchfit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return EXIT_INPUT_ERROR
    try:
        return int(args._run(args) or 0)
    except (InputError, ValueError, FileNotFoundError, FileExistsError) as exc:
        print(f"notchfit {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
