"""Where an experiment's measured data come from, said in one line, and whether they are enough for a fit.

Every command that needs measured data (``fit``, ``simulate``, ``identify``,
``diagnose``, and ``demo`` through them) looks in the same places in the
same order (:func:`notchfit.io.find_points`): the experiment's own
``notch_points.csv``, then the detect run named by ``--points DIR``, then the
``--out`` folder, then the experiment's own ``angles.csv`` (measured joint
angles); and says which it used (:func:`source_lines`). An experiment without
usable data is reported with its name, its file and the step the user asked
for (not a model the user never named).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .. import io

__all__ = ["MISSING_HINT", "lookup_points", "points_problem", "source_lines"]

#: How to give an experiment without points its points (appended to the messages).
MISSING_HINT = ("run `notchfit detect STUDY --out DIR` first and give the same --out, or --points DIR of "
                "that detect run, or give the experiment an angles.csv of measured joint angles")


def _where(path: Path) -> str:
    """A path as the user would type it: relative to the working folder when inside it."""
    try:
        rel = os.path.relpath(path)
    except ValueError:                      # another drive (Windows)
        return str(path)
    return str(path) if rel.startswith("..") else rel


def _names(names: list[str], limit: int = 6) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def source_lines(lookup, command: str) -> list[str]:
    """One line per place the points came from, e.g.
    ``fit: points of L045, L150 from detections.csv in out (--out)``."""
    groups: dict = {}
    for name, (where, path) in lookup.sources.items():
        folder = None if where.startswith("own") else (path.parent.parent if path.parent.name == name
                                                        else path.parent)
        key = (where, folder)
        groups.setdefault(key, []).append(name)
    lines = []
    for (where, folder), names in groups.items():
        if where == "own":
            lines.append(f"{command}: points of {_names(names)} from their own notch_points.csv")
        elif where == "own angles":
            lines.append(f"{command}: joint angles of {_names(names)} from their own angles.csv")
        else:
            files = "detections.csv corrected by review.csv" if where.endswith(", reviewed") else "detections.csv"
            lines.append(f"{command}: points of {_names(names)} from {files} in {_where(folder)} ({where})")
    return lines


def lookup_points(exps, args, command: str, *, say=print) -> "io.PointsLookup":
    """:func:`notchfit.io.find_points` over the experiment's own files, ``--points``, ``--out``; the
    sources said in one line each (``say``)."""
    lookup = io.find_points(exps, [("--points", getattr(args, "points", None)), ("--out", args.out)])
    for line in source_lines(lookup, command):
        say(line)
    return lookup


def _why_empty(source) -> str:
    """What an experiment's file without a single usable point holds, in words."""
    if Path(source).name != "detections.csv":
        return "no notch points (every row empty, or header only)"
    try:
        status = io.read_detections(source)["status"].astype(str).str.lower()
    except (OSError, ValueError, KeyError):
        return "no notch point with status ok"
    if not len(status):
        return "header only: the detect run wrote no row for this experiment"
    counts = ", ".join(f"{k} {v}" for k, v in status.value_counts().items())
    return (f"no point with status ok in its {len(status)} rows ({counts}): the detector numbered no corner "
            "in these images (detect_run.json gives each image's message; the overlays show what was found)")


def points_problem(exp, source, what: str) -> str | None:
    """Why ``exp``'s points cannot feed ``what`` (a fit, the diagnosis), naming ``source``; None if they can.

    Every fit first estimates the plane transform with the ``free`` model
    (one angle per joint), so some sample needs more than ``n_joints / 2``
    points (two coordinates each).
    """
    counts = np.isfinite(exp.points).all(-1).sum(1) if exp.points is not None else np.zeros(0, int)
    n = exp.geometry.n_joints
    if counts.max(initial=0) == 0:
        return f"{source}: {_why_empty(source)}: nothing for {what}"
    if (2 * counts <= n).all():
        return (f"{source}: no sample has enough notch points for {what}: the plane transform needs more "
                f"than {n // 2} points of one sample, the most is {counts.max()}")
    return None
