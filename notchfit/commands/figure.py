"""``notchfit figure``: reproduce a figure of the paper as data (CSV) + PNG."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from ..figures import discover
from ..io import atomic_write
from ..io.interrupts import deferred_interrupts
from ._common import EXIT_ITEMS_FAILED, InputError

NAME = "figure"
ORDER = 80
HELP = "write a paper figure's data (CSV) and PNG"
DESCRIPTION = """Reproduce figures of Moses et al. (2015) as data (CSV) and PNG.

Figures are discovered from the modules of the package notchfit.figures.
Nothing in --out is overwritten unless --force is given.

Examples:
  notchfit figure --list
  notchfit figure fig3 --out figs
  notchfit figure fig3 fig5 fig6 fig8 --out figs --force
"""


def add_arguments(parser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME", help="figure name(s), see --list")
    parser.add_argument("--list", action="store_true", help="list the available figures and exit")
    parser.add_argument("--out", default="figures", help="output folder (default: ./figures)")
    parser.add_argument("--force", action="store_true", help="overwrite existing files")


def run(args) -> int:
    figures = discover()
    if args.list:
        for name, func in figures.items():
            doc = (func.__doc__ or "").strip().splitlines()
            print(f"{name:12s} {doc[0] if doc else ''}")
        return 0
    if not args.names:
        raise InputError("give a figure NAME (see `notchfit figure --list`)")
    unknown = [n for n in args.names if n not in figures]
    if unknown:
        raise InputError(f"unknown figure(s) {', '.join(unknown)}; available: {', '.join(figures)}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    failed = []
    for name in dict.fromkeys(args.names):
        with tempfile.TemporaryDirectory(prefix=f"notchfit-{name}-") as tmp:
            try:
                written = figures[name](Path(tmp))
            except (ValueError, FileNotFoundError):
                raise
            except Exception as exc:  # noqa: BLE001 - reported, the other figures still run
                print(f"{name}: FAILED: {type(exc).__name__}: {exc}")
                failed.append(name)
                continue
            targets = [out / Path(p).relative_to(tmp) for p in written]
            clash = [str(t) for t in targets if t.exists()]
            if clash and not args.force:
                raise FileExistsError(f"{', '.join(clash)} already exist(s); use --force to overwrite")
            with deferred_interrupts():     # a figure's PNG and CSV arrive together, each file whole
                for src, dst in zip(written, targets):
                    atomic_write(dst, lambda tmp, src=src: shutil.copyfile(src, tmp))
            print(f"{name}: " + ", ".join(str(t) for t in targets))
    if failed:
        print(f"failed: {', '.join(failed)}")
        return EXIT_ITEMS_FAILED
    return 0
