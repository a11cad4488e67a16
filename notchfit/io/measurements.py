"""The measurement tables of an experiment folder: ``samples.csv``, ``notch_points.csv``, ``angles.csv``.

Readers validate every row and raise an :class:`~notchfit.io.InputFileError` naming
the file, the line and the problem; lengths are mm and tensions N in the files,
SI (m, N, s) in memory (docs/data-formats.md). The folder they sit in, its
``experiment.toml`` and whole studies are :mod:`notchfit.io.experiments`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..physics.friction import LOAD_CELL_SIGMA
from ..units import DEG, MM
from .tables import POINT_COLUMNS, Problems, check_point_rows, read_csv_table

__all__ = ["ANGLE_COLUMNS", "DEFAULT_TENSION_SIGMA", "MAX_JOINT_ANGLE", "angles_from_table", "angles_table",
           "points_from_table", "points_table", "read_angles_table", "read_points_table", "read_samples"]

#: Load-cell uncertainty when experiment.toml gives none [N] (docs/data-formats.md).
DEFAULT_TENSION_SIGMA = LOAD_CELL_SIGMA
#: Columns of ``angles.csv``: ``sample,joint`` and exactly one of the two angle columns.
ANGLE_COLUMNS = ("sample", "joint", "theta_deg", "theta_rad")


def _image_paths(df: pd.DataFrame, lines, folder: Path, missing_images: str, probs: Problems):
    out = []
    for rel, ln in zip(df["image"], lines):
        if rel == "":
            out.append(None)
            continue
        p = folder / rel
        if not p.is_file() and missing_images == "error":
            probs.add(ln, f"image missing: {rel} (looked for {p})")
        out.append(p)
    return tuple(out)


def read_samples(path, *, folder=None, missing_images: str = "error", tendons=("left", "right"),
                 tension_sigma: float | None = None) -> tuple[pd.DataFrame, tuple | None]:
    """Read and validate ``samples.csv``.

    Checks: every column of docs/data-formats.md present (the tension column of
    a tendon the tube lacks may be absent or empty, and so may the
    displacements); integer, unique sample ids; finite numeric times and
    tensions; no tension below ``-3 σ_T`` (``σ_T = tension_sigma``, default
    :data:`DEFAULT_TENSION_SIGMA`: a load cell reads slightly below zero at
    rest, lower is an error); strictly increasing ``time_s``; every named
    image exists (unless ``missing_images="keep"``, which keeps the path of a
    missing image for a batch to report).

    Returns
    -------
    samples : DataFrame
    image_paths : tuple of (Path or None) or None
    """
    path = Path(path)
    folder = Path(folder) if folder is not None else path.parent
    if missing_images not in ("error", "keep"):
        raise ValueError(f"missing_images must be 'error' or 'keep', got {missing_images!r}")
    present = tuple(f"tension_{t}_N" for t in ("left", "right") if t in tendons)
    absent = tuple(f"tension_{t}_N" for t in ("left", "right") if t not in tendons)
    df, lines = read_csv_table(
        path, required=("sample", "time_s") + present, integer=("sample",), numeric=("time_s",) + present,
        optional_numeric=("displacement_left_mm", "displacement_right_mm") + absent, text=("image",))
    probs = Problems(path)
    if len(df) == 0:
        probs.add(None, "no samples (the file has only a header)")
    floor = -3.0 * (DEFAULT_TENSION_SIGMA if tension_sigma is None else tension_sigma)
    for col in present:
        for v, ln in zip(df[col].to_numpy(dtype=float), lines):
            if v < floor:
                probs.add(ln, f"{col} {v:g} is below -3 sigma_T = {floor:g} N (a load-cell offset is at most "
                              "that; set [uncertainty] tension_N in experiment.toml if the cell is noisier)")
    first: dict[int, int] = {}
    for s, ln in zip(df["sample"].to_numpy(), lines):
        if s in first:
            probs.add(ln, f"duplicate sample {s} (first on line {first[s]})")
        else:
            first[s] = ln
    t = df["time_s"].to_numpy()
    for i in range(1, len(t)):
        if not t[i] > t[i - 1]:
            probs.add(lines[i], f"time_s {t[i]:g} is not after {t[i - 1]:g} (line {lines[i - 1]}); "
                                "samples must be in strictly increasing time order")
    image_paths = None
    if "image" in df.columns:
        image_paths = _image_paths(df, lines, folder, missing_images, probs)
    probs.raise_if_any()
    return df, image_paths


def read_points_table(path, *, n_points: int | None = None, sample_ids=None) -> pd.DataFrame:
    """Read and validate ``notch_points.csv`` (``sample,point,x_mm,y_mm``).

    Checks: integer sample and point ids, point in ``1..n_points``, the
    sample present in ``sample_ids`` (when given), no duplicate
    (sample, point), numeric coordinates (empty or ``nan`` = missing).
    """
    path = Path(path)
    df, lines = read_csv_table(path, required=POINT_COLUMNS, integer=("sample", "point"),
                               nan_ok=("x_mm", "y_mm"))
    check_point_rows(path, df, lines, n_points, sample_ids)
    return df


def points_from_table(df: pd.DataFrame, sample_ids, n_points: int) -> np.ndarray:
    """``(S, m, 2)`` plane-frame points [m] from a ``sample,point,x_mm,y_mm`` frame (NaN = missing)."""
    ids = np.asarray(sample_ids, dtype=np.int64)
    pos = {int(s): i for i, s in enumerate(ids)}
    out = np.full((len(ids), n_points, 2), np.nan)
    if len(df):
        rows = np.array([pos.get(int(s), -1) for s in df["sample"].to_numpy()])
        pts = df["point"].to_numpy(dtype=np.int64) - 1
        ok = (rows >= 0) & (pts >= 0) & (pts < n_points)
        out[rows[ok], pts[ok], 0] = df["x_mm"].to_numpy(dtype=float)[ok] * MM
        out[rows[ok], pts[ok], 1] = df["y_mm"].to_numpy(dtype=float)[ok] * MM
    return out


def points_table(points, sample_ids) -> pd.DataFrame:
    """The ``notch_points.csv`` layout of ``(S, m, 2)`` plane-frame points [m].

    Points with a NaN coordinate are left out (a missing row = a missing point).

    Returns
    -------
    DataFrame with columns ``sample, point, x_mm, y_mm`` (point 1-based).
    """
    pts = np.asarray(points, dtype=float)
    ids = np.asarray(sample_ids, dtype=np.int64)
    if pts.ndim != 3 or pts.shape[-1] != 2 or pts.shape[0] != len(ids):
        raise ValueError(f"points must have shape (S, m, 2) with S={len(ids)} samples, got {pts.shape}")
    S, m, _ = pts.shape
    sample = np.repeat(ids, m)
    point = np.tile(np.arange(1, m + 1, dtype=np.int64), S)
    flat = pts.reshape(-1, 2) / MM
    keep = np.isfinite(flat).all(axis=1)
    return pd.DataFrame({"sample": sample[keep], "point": point[keep],
                         "x_mm": flat[keep, 0], "y_mm": flat[keep, 1]})


#: The largest joint angle an ``angles.csv`` may hold [rad]: a notch turns far less than half a turn.
MAX_JOINT_ANGLE = math.pi


def read_angles_table(path, *, n_joints: int | None = None, sample_ids=None,
                      max_angle: float = MAX_JOINT_ANGLE) -> pd.DataFrame:
    """Read and validate ``angles.csv`` (``sample,joint,theta_deg`` or ``sample,joint,theta_rad``).

    Measured joint angles, joint ``j`` in ``1..n`` from the base (docs/data-formats.md).
    Checks: exactly one of ``theta_deg`` / ``theta_rad``; integer sample and
    joint ids; joint in ``1..n_joints`` (when given); the sample present in
    ``sample_ids`` (when given); no (sample, joint) twice; angles finite with
    ``|θ| <= max_angle`` or missing (an empty cell or ``nan``). Every problem
    names its line.

    Returns
    -------
    DataFrame
        Columns ``sample, joint, theta`` with ``theta`` in radians (NaN = missing).
    """
    path = Path(path)
    df, lines = read_csv_table(path, required=("sample", "joint"), integer=("sample", "joint"),
                               nan_ok=("theta_deg", "theta_rad"))
    probs = Problems(path)
    cols = [c for c in ("theta_deg", "theta_rad") if c in df.columns]
    if len(cols) != 1:
        probs.add(1, "both theta_deg and theta_rad: give the angle in exactly one of them" if cols else
                  "missing column theta_deg or theta_rad (expected sample,joint,theta_deg)")
        probs.raise_if_any()
    unit = DEG if cols[0] == "theta_deg" else 1.0
    theta = df[cols[0]].to_numpy(dtype=float) * unit
    known = set(int(s) for s in sample_ids) if sample_ids is not None else None
    seen: dict[tuple, int] = {}
    for s, j, th, ln in zip(df["sample"].to_numpy(), df["joint"].to_numpy(), theta, lines):
        if n_joints is not None and not 1 <= j <= n_joints:
            probs.add(ln, f"joint {j} out of range 1..{n_joints} (joints are numbered from the base)")
        if known is not None and s not in known:
            probs.add(ln, f"sample {s} is not in samples.csv")
        if abs(th) > max_angle:
            probs.add(ln, f"{cols[0]} {th / unit:g} is beyond a joint's physical range "
                          f"(|theta| <= {max_angle / unit:g} {cols[0][6:]})")
        if (s, j) in seen:
            probs.add(ln, f"duplicate joint {j} of sample {s} (first on line {seen[(s, j)]})")
        else:
            seen[(s, j)] = ln
    probs.raise_if_any()
    return pd.DataFrame({"sample": df["sample"].to_numpy(), "joint": df["joint"].to_numpy(), "theta": theta})


def angles_from_table(df: pd.DataFrame, sample_ids, n_joints: int) -> np.ndarray:
    """``(S, n)`` joint angles [rad] from a ``sample, joint, theta`` frame (NaN = not measured)."""
    ids = np.asarray(sample_ids, dtype=np.int64)
    pos = {int(s): i for i, s in enumerate(ids)}
    out = np.full((len(ids), n_joints), np.nan)
    if len(df):
        rows = np.array([pos.get(int(s), -1) for s in df["sample"].to_numpy()])
        cols = df["joint"].to_numpy(dtype=np.int64) - 1
        ok = (rows >= 0) & (cols >= 0) & (cols < n_joints)
        out[rows[ok], cols[ok]] = df["theta"].to_numpy(dtype=float)[ok]
    return out


def angles_table(angles, sample_ids) -> pd.DataFrame:
    """The ``angles.csv`` layout (``sample, joint, theta_deg``) of ``(S, n)`` joint angles [rad].

    NaN angles are left out (a missing row = an angle not measured).
    """
    th = np.asarray(angles, dtype=float)
    ids = np.asarray(sample_ids, dtype=np.int64)
    if th.ndim != 2 or th.shape[0] != len(ids):
        raise ValueError(f"angles must have shape (S, n) with S={len(ids)} samples, got {th.shape}")
    S, n = th.shape
    sample, joint = np.repeat(ids, n), np.tile(np.arange(1, n + 1, dtype=np.int64), S)
    flat = th.reshape(-1) / DEG
    keep = np.isfinite(flat)
    return pd.DataFrame({"sample": sample[keep], "joint": joint[keep], "theta_deg": flat[keep]})


