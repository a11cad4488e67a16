"""Where an experiment's measured data come from, and whether they are enough for a fit.

Shared by ``fit``, ``simulate``, ``identify`` and ``diagnose`` so that an
experiment without usable data is reported with its name, its points file and
the step the user asked for (not a model the user never named). Measured data
are notch points (``notch_points.csv`` or detect's ``detections.csv``) or
joint angles (``angles.csv``, :func:`with_measurements`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import io

__all__ = ["points_file", "points_problem", "with_measurements"]


def points_file(exp, points_dir) -> Path:
    """Where ``exp``'s notch points come from: its ``notch_points.csv``, else detect's ``detections.csv``."""
    own = Path(exp.path) / "notch_points.csv"
    if own.is_file() or points_dir is None:
        return own
    found = io.find_output(points_dir, "detections.csv")
    return found.get(exp.name) or found.get("", Path(points_dir) / exp.name / "detections.csv")


def points_problem(exp, source, what: str) -> str | None:
    """Why ``exp``'s points cannot feed ``what`` (a fit, the diagnosis), naming ``source``; None if they can.

    Every fit first estimates the plane transform with the ``free`` model
    (one angle per joint), so some sample needs more than ``n_joints / 2``
    points (two coordinates each).
    """
    counts = np.isfinite(exp.points).all(-1).sum(1) if exp.points is not None else np.zeros(0, int)
    n = exp.geometry.n_joints
    if counts.max(initial=0) == 0:
        return f"{source}: no notch points (header only?): nothing for {what}"
    if (2 * counts <= n).all():
        return (f"{source}: no sample has enough notch points for {what}: the plane transform needs more "
                f"than {n // 2} points of one sample, the most is {counts.max()}")
    return None



def with_measurements(exps, points_dir) -> tuple[list, dict]:
    """The experiments with measured data: notch points (own or detected) or joint angles.

    :func:`notchfit.io.attach_detections` gives experiments without
    ``notch_points.csv`` the points of a detect run; one with ``angles.csv`` is
    kept without points. Order is kept.

    Returns
    -------
    experiments : list of Experiment
    problems : dict
        ``{name: reason}`` for those with neither points nor angles.
    """
    with_pts, problems = io.attach_detections(exps, points_dir, require=False)
    by_name = {e.name: e for e in with_pts}
    out = []
    for e in exps:
        if e.name in by_name:
            out.append(by_name[e.name])
        elif e.angles is not None:
            problems.pop(e.name, None)
            out.append(e)
    return out, problems
