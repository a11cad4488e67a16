"""``review.csv``: a person's corrections of a ``detect`` run, kept beside its ``detections.csv``.

``notchfit review`` writes one row per corrected corner; the detector's own
file is never changed. Every command that takes points from a detect run
(:func:`notchfit.io.find_points`) applies the corrections on top of the
detections (:func:`apply_review`). The format is in docs/data-formats.md
(``review.csv``).

Statuses of a row:

``manual``
    the corner is where the person put it (moved, placed, or an
    ``ambiguous`` detection accepted as it is); used by the fits with its
    ``sigma_mm``.
``deleted``
    the detection is wrong and the corner was not placed: missing.
``occluded``
    the corner cannot be seen in the photograph: missing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..units import MM
from .outputs import write_table_atomic
from .tables import Problems, check_point_rows, read_csv_table

__all__ = ["REVIEW_COLUMNS", "REVIEW_NAME", "REVIEW_STATUSES", "apply_review", "read_review", "review_path",
           "write_review"]

#: File name of the corrections, beside ``detections.csv``.
REVIEW_NAME = "review.csv"
#: Columns of review.csv, in file order (``prev_*``: the detect run's value the row replaces).
REVIEW_COLUMNS = ("sample", "point", "u_px", "v_px", "x_mm", "y_mm", "sigma_mm", "status",
                  "prev_u_px", "prev_v_px", "prev_x_mm", "prev_y_mm", "prev_status", "time")
#: Statuses a review row may have; only ``manual`` carries a position.
REVIEW_STATUSES = ("manual", "deleted", "occluded")
_FLOATS = ("u_px", "v_px", "x_mm", "y_mm", "sigma_mm", "prev_u_px", "prev_v_px", "prev_x_mm", "prev_y_mm")


def review_path(detections) -> Path:
    """The ``review.csv`` that belongs to a ``detections.csv`` (same folder)."""
    return Path(detections).parent / REVIEW_NAME


def read_review(path, *, n_points: int | None = None, sample_ids=None) -> pd.DataFrame:
    """Read and check ``review.csv``.

    Parameters
    ----------
    path : path
    n_points : int, optional
        Point ids must be in ``1..n_points``.
    sample_ids : sequence of int, optional
        Samples must be among these.

    Returns
    -------
    DataFrame
        Columns :data:`REVIEW_COLUMNS` (``prev_status`` and ``time`` as text,
        empty cells as ``""``).

    Raises
    ------
    InputFileError
        One line naming the file, the line and the problem: a missing column,
        an unknown status, a ``manual`` row without finite coordinates or a
        positive ``sigma_mm``, a point out of range, a duplicate corner.
    """
    path = Path(path)
    df, lines = read_csv_table(path, required=REVIEW_COLUMNS, integer=("sample", "point"), nan_ok=_FLOATS,
                               text=("status", "prev_status", "time"))
    check_point_rows(path, df, lines, n_points, sample_ids)
    probs = Problems(path)
    for row, ln in zip(df.itertuples(index=False), lines):
        if row.status not in REVIEW_STATUSES:
            probs.add(ln, f"status {row.status!r} is not one of {', '.join(REVIEW_STATUSES)}")
        elif row.status == "manual":
            if not np.isfinite([row.u_px, row.v_px, row.x_mm, row.y_mm]).all():
                probs.add(ln, "a manual corner needs u_px, v_px, x_mm and y_mm")
            if not (np.isfinite(row.sigma_mm) and row.sigma_mm > 0):
                probs.add(ln, f"a manual corner needs a positive sigma_mm, got {row.sigma_mm}")
    probs.raise_if_any()
    for c in ("prev_status", "time"):
        df[c] = df[c].fillna("").astype(str)
    return df


def write_review(rows, path) -> Path:
    """Write ``review.csv`` atomically, sorted by sample and point.

    Parameters
    ----------
    rows : DataFrame or iterable of dict
        With the columns of :data:`REVIEW_COLUMNS` (missing ones written empty).
    path : path
    """
    df = pd.DataFrame(list(rows) if not isinstance(rows, pd.DataFrame) else rows)
    for c in REVIEW_COLUMNS:
        if c not in df.columns:
            df[c] = np.nan if c in _FLOATS else ""
    df = df[list(REVIEW_COLUMNS)]
    if len(df):
        df = df.sort_values(["sample", "point"], kind="stable")
    return write_table_atomic(df, path)


def apply_review(points, sigma, review: pd.DataFrame, sample_ids) -> tuple[np.ndarray, np.ndarray]:
    """Detected points with a review's corrections applied.

    Parameters
    ----------
    points : array (S, m, 2) [m]
        Plane-frame points of the detect run (NaN = missing).
    sigma : array (S, m) [m]
        Their uncertainties.
    review : DataFrame
        From :func:`read_review`.
    sample_ids : sequence of int, length S

    Returns
    -------
    points : ndarray (S, m, 2) [m]
        ``manual`` rows replace the point, ``deleted`` and ``occluded`` rows
        make it missing.
    sigma : ndarray (S, m) [m]
        A manual corner's ``sigma_mm``.
    """
    pts = np.array(points, dtype=float, copy=True)
    sig = np.array(sigma, dtype=float, copy=True)
    index = {int(s): i for i, s in enumerate(sample_ids)}
    for row in review.itertuples(index=False):
        i, q = index[int(row.sample)], int(row.point) - 1
        if row.status == "manual":
            pts[i, q] = (row.x_mm * MM, row.y_mm * MM)
            sig[i, q] = row.sigma_mm * MM
        else:
            pts[i, q] = np.nan
            sig[i, q] = np.nan
    return pts, sig
