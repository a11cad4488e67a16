"""The ``notchfit`` command line.

Each sub-command is a module in :mod:`notchfit.commands` that defines

* ``NAME`` (the sub-command), ``HELP`` (one line), ``DESCRIPTION`` (``--help``
  text with examples), ``ORDER`` (position in the listing);
* ``add_arguments(parser)`` and ``run(args) -> int``.

This module discovers the command modules and runs the chosen one; what the
commands share (the input-error type, exit codes, common options) is in
:mod:`notchfit.commands._common`, which imports neither this module nor the
commands. The listing (``notchfit --help``) reads ``NAME``, ``HELP`` and
``ORDER`` from the modules' source, and :func:`main` imports only the command
it runs, so that start-up does not pay for every command's libraries. Exit
codes: 0 ok, 1 some items failed (listed by the command), 2 usage or input
error (one line on stderr naming the file and the problem), 130/143
interrupted by Ctrl-C/SIGTERM, 141 a closed pipe (``notchfit figure --list |
head -1``) — docs/reliability.md. ``--debug`` (or ``NOTCHFIT_DEBUG=1``)
shows the traceback of an error.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import importlib.util
import os
import pkgutil
import sys

from . import __version__, commands
from .commands._common import (EXIT_BROKEN_PIPE, EXIT_INPUT_ERROR, OneLineParser, add_command, debug_enabled,
                               error_exit, execute)
from .io.interrupts import handle_interrupts


def _source_metadata(modname: str) -> dict | None:
    """``NAME``, ``HELP``, ``ORDER`` of a command module read from its source (None if not literal)."""
    spec = importlib.util.find_spec(modname)
    if spec is None or not spec.origin or not spec.origin.endswith(".py"):
        return None
    with open(spec.origin, encoding="utf-8") as fh:
        tree = ast.parse(fh.read(), spec.origin)
    meta, funcs = {}, set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            funcs.add(node.name)
        elif isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            key = node.targets[0].id
            if key in ("NAME", "HELP", "ORDER"):
                try:
                    meta[key] = ast.literal_eval(node.value)
                except ValueError:
                    return None
    if not {"run", "add_arguments"} <= funcs:
        return {}
    return meta if {"NAME", "HELP"} <= set(meta) else None


def _command_specs() -> list[tuple]:
    """``(ORDER, NAME, HELP, module name)`` of every command module, in listing order.

    A module whose metadata is not literal in its source is imported to read it.
    """
    specs = []
    for info in pkgutil.iter_modules(commands.__path__):
        if info.name.startswith("_"):
            continue
        modname = f"{commands.__name__}.{info.name}"
        meta = _source_metadata(modname)
        if meta is None:
            mod = importlib.import_module(modname)
            if not (hasattr(mod, "NAME") and hasattr(mod, "run")):
                continue
            meta = {"NAME": mod.NAME, "HELP": mod.HELP, "ORDER": getattr(mod, "ORDER", 100)}
        if meta:
            specs.append((meta.get("ORDER", 100), meta["NAME"], meta["HELP"], modname))
    return sorted(specs)


def _requested_command(argv) -> str | None:
    """The sub-command named in ``argv`` (the first word that is not an option), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(load=None) -> argparse.ArgumentParser:
    """The ``notchfit`` parser with one sub-parser per command module.

    Parameters
    ----------
    load : collection of str, optional
        Commands whose modules are imported and whose options are added; the
        others get a listing entry only. Default: every command.
    """
    parser = OneLineParser(
        prog="notchfit",
        description="Kinematics, friction simulation, calibrated image processing and "
                    "model diagnosis for cable-driven notched-tube manipulators.",
        epilog="Run `notchfit COMMAND --help` for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"notchfit {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error (also NOTCHFIT_DEBUG=1)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for _, name, help_, modname in _command_specs():
        if load is None or name in load:
            add_command(sub, importlib.import_module(modname))
        else:
            sub.add_parser(name, help=help_)
    return parser


def _requested_command_name(argv) -> str | None:
    return _requested_command([a for a in argv if a != "--debug"])


def _quiet_stdout() -> None:
    """Send what is left of stdout to /dev/null (the reader of a pipe is gone; no second error at exit)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv=None) -> int:
    """Run ``notchfit`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    SIGINT and SIGTERM are handled while the command runs (exit 130/143 and
    one line, :mod:`notchfit.io.interrupts`); an error before the command
    starts (an unimportable module) is one line as well.
    """
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    name = _requested_command_name(argv) or "CLI"
    with handle_interrupts():
        try:
            parser = build_parser(load={name})
            args = parser.parse_args(argv)
            if not getattr(args, "_run", None):
                parser.print_help()
                return EXIT_INPUT_ERROR
            code = execute(args)
            sys.stdout.flush()
        except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - start-up and flush errors
            code = error_exit(name, exc, debug=debug_enabled())
    if code == EXIT_BROKEN_PIPE:
        _quiet_stdout()
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
