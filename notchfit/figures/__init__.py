"""Figures of the paper, reproduced as data (CSV) + PNG by ``notchfit figure NAME``.

Every module in this package defines ``FIGURES = {"name": func, ...}`` where
``func(out_dir: Path, **kw) -> list[Path]`` writes the figure's data and PNG
into ``out_dir`` (matplotlib's Agg canvas, no pyplot state) and returns the
paths it wrote. :func:`discover` imports every module of the package and
merges their ``FIGURES``; adding a figure module needs no other edit.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
from typing import Callable

import pandas as pd

__all__ = ["discover", "natural_key", "new_figure", "save_png", "write_csv"]


def natural_key(name: str) -> tuple:
    """Sort key that orders the numbers in a name by value: fig3 before fig11."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def discover(package: str = __name__) -> dict[str, Callable]:
    """All figures of ``package``: ``{name: func}`` merged from every module's ``FIGURES``, in
    natural order of the names (fig3 before fig11).

    Parameters
    ----------
    package : str
        Dotted name of the package to scan (this package by default).

    Raises
    ------
    ValueError
        Two modules define the same figure name, or ``FIGURES`` is not a dict
        of callables.
    ImportError
        A module fails to import (its name is in the message).
    """
    pkg = importlib.import_module(package)
    found: dict[str, Callable] = {}
    where: dict[str, str] = {}
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        modname = f"{package}.{info.name}"
        try:
            mod = importlib.import_module(modname)
        except Exception as exc:  # noqa: BLE001 - re-raised with the module's name
            raise ImportError(f"figure module {modname} failed to import: {exc}") from exc
        figs = getattr(mod, "FIGURES", None)
        if figs is None:
            continue
        if not isinstance(figs, dict) or not all(callable(f) for f in figs.values()):
            raise ValueError(f"{modname}.FIGURES must be a dict of name -> callable")
        for name, func in figs.items():
            if name in found:
                raise ValueError(f"figure {name!r} is defined twice: in {where[name]} and {modname}")
            found[name] = func
            where[name] = modname
    return dict(sorted(found.items(), key=lambda kv: natural_key(kv[0])))


def new_figure(width: float = 6.4, height: float = 4.8):
    """A matplotlib Figure on an Agg canvas (no global pyplot state); ``width``, ``height`` [inch]."""
    # slow optional dependency: matplotlib loads only when a figure is drawn
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_png(fig, path, dpi: int = 150):
    """Write ``fig`` as PNG and return the path."""
    fig.savefig(path, dpi=dpi)
    return path


def write_csv(path, columns: dict, float_format: str = "%.9g"):
    """Write equal-length columns (header = the dict keys, with units) and return the path."""
    pd.DataFrame(columns).to_csv(path, index=False, float_format=float_format)
    return path
