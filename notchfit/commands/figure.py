"""``notchfit figure``: reproduce a figure of the paper as data (CSV) + PNG."""

from __future__ import annotations

import re
import shutil
import tempfile
from pathlib import Path

from ..figures import discover
from ..io import atomic_write
from ..io.interrupts import deferred_interrupts
from ..progress import bar as progress_bar
from ._common import EXIT_ITEMS_FAILED, InputError

NAME = "figure"
ORDER = 80
HELP = "write a paper figure's data (CSV) and PNG"
DESCRIPTION = """Reproduce figures of Moses et al. (2015) as data (CSV) and PNG.

Figures are discovered from the modules of the package notchfit.figures; `all` names every
one. A figure whose files already exist in --out is kept as it is (said, exit 0); --force
draws it again and replaces them.

Examples:
  notchfit figure --list
  notchfit figure fig3 --out figs
  notchfit figure all --out figs
  notchfit figure fig3 fig5 fig6 fig8 --out figs --force
"""

#: reST markup of the docstrings' first lines, shown as plain text by --list
_REST = (re.compile(r":\w+:`~?([^`]*)`"), re.compile(r"``([^`]*)``"), re.compile(r"`([^`]*)`"))


def plain_text(text: str) -> str:
    """``text`` without reST markup (:func:`x` -> x, ``x`` -> x)."""
    for pattern in _REST:
        text = pattern.sub(r"\1", text)
    return text


def add_arguments(parser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME", help="figure name(s), see --list, or all")
    parser.add_argument("--list", action="store_true", help="list the available figures and exit")
    parser.add_argument("--out", default="figures", help="output folder (default: ./figures)")
    parser.add_argument("--force", action="store_true", help="draw figures whose files exist again, replacing them")


def _existing(out: Path, name: str) -> list[Path]:
    """Files of figure ``name`` already in ``out`` (its PNG or its data)."""
    return sorted(p for ext in ("png", "csv") for p in out.glob(f"{name}.{ext}"))


def _names(args, figures: dict) -> list[str]:
    """The figures asked for (``all``: every one), in order, each once."""
    if not args.names:
        raise InputError("give a figure NAME or all (see `notchfit figure --list`)")
    unknown = [n for n in args.names if n not in figures and n != "all"]
    if unknown:
        raise InputError(f"unknown figure(s) {', '.join(unknown)}; available: all, {', '.join(figures)}")
    return list(figures) if "all" in args.names else list(dict.fromkeys(args.names))


def _draw(name: str, func, out: Path, force: bool) -> bool:
    """Draw one figure into ``out``, keeping existing files unless ``force``; False when it failed."""
    with tempfile.TemporaryDirectory(prefix=f"notchfit-{name}-") as tmp:
        try:
            written = func(Path(tmp))
        except (ValueError, FileNotFoundError):
            raise
        except Exception as exc:  # noqa: BLE001 - reported, the other figures still run
            print(f"{name}: FAILED: {type(exc).__name__}: {exc}")
            return False
        targets = [out / Path(p).relative_to(tmp) for p in written]
        clash = [str(t) for t in targets if t.exists()]
        if clash and not force:
            print(f"{name}: kept {', '.join(clash)} (exist; --force draws it again)")
            return True
        with deferred_interrupts():     # a figure's PNG and CSV arrive together, each file whole
            for src, dst in zip(written, targets):
                atomic_write(dst, lambda tmp, src=src: shutil.copyfile(src, tmp))
    print(f"{name}: " + ", ".join(str(t) for t in targets))
    return True


def run(args) -> int:
    figures = discover()
    if args.list:
        for name, func in figures.items():
            doc = (func.__doc__ or "").strip().splitlines()
            print(f"{name:12s} {plain_text(doc[0]) if doc else ''}")
        return 0
    names = _names(args, figures)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    failed = []
    with progress_bar(len(names), "figure" if len(names) > 1 else None, unit="figures") as bar:
        for name in names:
            kept = _existing(out, name) if not args.force else []
            if kept:
                print(f"{name}: kept {', '.join(map(str, kept))} (exist; --force draws it again)")
            elif not _draw(name, figures[name], out, args.force):
                failed.append(name)
            bar.update(1)
    if failed:
        print(f"failed: {', '.join(failed)}")
        return EXIT_ITEMS_FAILED
    return 0
