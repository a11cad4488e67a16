"""Experiments and studies on disk: read, validate, write (docs/data-formats.md).

An experiment is a folder with ``experiment.toml``, ``samples.csv`` and
either ``notch_points.csv`` or one image per sample; a study is a folder of
experiments. The tables themselves are read and written by
:mod:`notchfit.io.measurements`. Lengths are mm and tensions N in the files, SI (m, N, s) in
memory; the conversion happens here. Every reader error names the file, the
line and the problem.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..physics.geometry import Geometry
from ..units import DEG, MM
from .errors import InputFileError, InputFileNotFoundError
from .models import load_geometry
from .measurements import (angles_from_table, angles_table, points_from_table, points_table, read_angles_table,
                           read_points_table, read_samples)
from .outputs import find_output, read_detections, write_table_atomic, write_text_atomic
from .review import apply_review, read_review, review_path
from .tables import SAMPLE_COLUMNS, Problems
from .toml import TomlError, TomlFile, load_toml, toml_dumps

__all__ = [
    "Experiment",
    "PointsLookup",
    "find_points",
    "has_own_points",
    "is_experiment_dir",
    "load_detected_points",
    "read_experiment",
    "read_experiment_toml",
    "read_study",
    "scan_study",
    "StudyScan",
    "with_points",
    "write_experiment",
]

_TOML_KEYS = {"name", "description", "geometry", "mirror", "calibration", "uncertainty", "protocol", "base",
              "image_gamma"}
#: The tone-curve exponents ``image_gamma`` may take (1: the images are in linear light).
IMAGE_GAMMA_RANGE = (1.0, 4.0)
#: Where the tube's base enters a photograph (``base`` in experiment.toml; absent: found by the detector).
BASE_SIDES = ("top", "bottom", "left", "right")
_UNCERTAINTY_KEYS = {"point_mm": "point_sigma", "tension_N": "tension_sigma", "angle_deg": "angle_sigma"}
#: Unit of each ``[uncertainty]`` key, to SI (point_mm -> m, angle_deg -> rad).
_UNCERTAINTY_UNITS = {"point_mm": MM, "tension_N": 1.0, "angle_deg": DEG}
#: Largest standard uncertainty accepted, in the key's unit (mm, N, deg): beyond it, a typo or a unit mistake.
MAX_UNCERTAINTY = 1e3


@dataclass(frozen=True)
class Experiment:
    """One bend/unbend test as read from its folder (docs/data-formats.md).

    Attributes
    ----------
    name, description : str
    path : Path
        The experiment folder.
    geometry : Geometry
    mirror : bool
        The view is reflected (plane frame ``P = Rot(φ) diag(-1, 1) (x, z) + t``).
    calibration_path : Path or None
        Camera calibration file, resolved relative to the folder.
    point_sigma, tension_sigma : float or None
        Measurement uncertainty of a point coordinate [m] and of a tension
        [N] (``[uncertainty] point_mm, tension_N``).
    angle_sigma : float or None
        Measurement uncertainty of a joint angle [rad] (``[uncertainty] angle_deg``).
    samples : DataFrame
        ``samples.csv`` as read (file units, one row per sample, time order).
    points : ndarray, shape (S, m, 2) [m], or None
        Notch points in the plane frame, NaN where missing; None when the
        folder has no ``notch_points.csv``.
    angles : ndarray, shape (S, n) [rad], or None
        Measured joint angles (``angles.csv``), joint ``j`` in column ``j-1``,
        NaN where not measured; None when the folder has no ``angles.csv``.
    image_paths : tuple of (Path or None), or None
        The image of each sample; None when ``samples.csv`` has no ``image`` column.
    base : str or None
        Where the tube's base enters the photographs (``top``, ``bottom``,
        ``left``, ``right``); None: the detector finds it.
    ramp_time : float or None
        ``[protocol] ramp_time_s`` [s]: after each sample the tensions moved
        linearly to the next sample's over this time, then rested (0: a step);
        None when experiment.toml does not say.
    image_gamma : float or None
        The images' tone curve: a pixel value ``v`` stands for the light
        ``(v / full) ** image_gamma`` (1: linear light, a camera's JPEG about
        2.2); None when experiment.toml does not say (``detect`` then assumes
        2.2 for JPEG files and 1 for others, and says so).
    point_sigmas : ndarray, shape (S, m) [m], or None
        The uncertainty of each point where a person reviewed the points
        (``notchfit review``): a detected corner's ``sigma_mm`` of
        detections.csv, a corrected corner's of review.csv; None otherwise
        (the fits then use ``point_sigma`` or estimate σ).
    """

    name: str
    path: Path
    description: str
    geometry: Geometry
    mirror: bool
    calibration_path: Path | None
    point_sigma: float | None
    tension_sigma: float | None
    samples: pd.DataFrame
    points: np.ndarray | None
    image_paths: tuple | None
    base: str | None = None
    ramp_time: float | None = None
    angles: np.ndarray | None = None
    angle_sigma: float | None = None
    image_gamma: float | None = None
    point_sigmas: np.ndarray | None = None

    @property
    def sample_ids(self) -> np.ndarray:
        """Sample ids (S,) int."""
        return self.samples["sample"].to_numpy(dtype=np.int64)

    @property
    def time(self) -> np.ndarray:
        """Sample times (S,) [s]."""
        return self.samples["time_s"].to_numpy(dtype=float)

    def _tension(self, side: str) -> np.ndarray:
        col = f"tension_{side}_N"
        if side not in self.geometry.tendons or col not in self.samples:
            return np.zeros(self.n_samples)              # a tendon the tube lacks carries nothing
        return np.maximum(self.samples[col].to_numpy(dtype=float), 0.0)

    @property
    def tension_left(self) -> np.ndarray:
        """Left tendon tension at the load cell, the model's input (S,) [N].

        Readings slightly below zero (load-cell offset, down to ``-3 σ_T``: the
        reader refuses lower ones) are clipped at zero (:attr:`n_clipped` counts
        them); zeros for a tube without a left tendon.
        """
        return self._tension("left")

    @property
    def tension_right(self) -> np.ndarray:
        """Right tendon tension at the load cell, the model's input (S,) [N] (see :attr:`tension_left`)."""
        return self._tension("right")

    @property
    def n_clipped(self) -> int:
        """Tension readings below zero that the model takes as zero (load-cell offset)."""
        cols = [f"tension_{t}_N" for t in self.geometry.tendons if f"tension_{t}_N" in self.samples]
        return int(sum((self.samples[c].to_numpy(dtype=float) < 0).sum() for c in cols))

    @property
    def displacement_left(self) -> np.ndarray:
        """Left cable displacement (S,) [m], NaN where not measured."""
        return self._displacement("left")

    @property
    def displacement_right(self) -> np.ndarray:
        """Right cable displacement (S,) [m], NaN where not measured."""
        return self._displacement("right")

    def _displacement(self, side: str) -> np.ndarray:
        col = f"displacement_{side}_mm"
        if col not in self.samples:
            return np.full(self.n_samples, np.nan)
        return self.samples[col].to_numpy(dtype=float) * MM

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return len(self.samples)

    @property
    def has_images(self) -> bool:
        """``samples.csv`` names at least one image."""
        return self.image_paths is not None and any(p is not None for p in self.image_paths)


# ----------------------------------------------------------------------------- experiment.toml
def _uncertainty(doc: TomlFile, unc, probs: Problems, out: dict) -> None:
    if not isinstance(unc, dict):
        probs.add(doc.line_of("uncertainty"), "uncertainty must be a table [uncertainty]")
        return
    for k, v in unc.items():
        where = doc.line_of("uncertainty", k)
        if k not in _UNCERTAINTY_KEYS:
            probs.add(where, f"unknown key {k!r} in [uncertainty] (known: {', '.join(_UNCERTAINTY_KEYS)})")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < MAX_UNCERTAINTY:
            probs.add(where, f"[uncertainty] {k} must be a positive number below {MAX_UNCERTAINTY:g}, got {v!r}")
        else:
            out[_UNCERTAINTY_KEYS[k]] = float(v) * _UNCERTAINTY_UNITS[k]


def read_experiment_toml(path) -> dict:
    """Read and validate ``experiment.toml``.

    Returns
    -------
    dict
        ``name, description, geometry, mirror, calibration, point_sigma [m],
        tension_sigma [N], angle_sigma [rad], base, ramp_time [s]`` (absent optional keys as None; ``name`` defaults
        to the folder name, ``geometry`` to "default", ``mirror`` to false).

    Raises
    ------
    TomlError
        Every problem of the file, each with its line.
    """
    path = Path(path)
    doc = load_toml(path)
    data = doc.data
    probs = Problems(path, error=TomlError)
    for k in sorted(set(data) - _TOML_KEYS):
        probs.add(doc.line_of(k), f"unknown key {k!r} (known: {', '.join(sorted(_TOML_KEYS))})")
    out = {"name": path.parent.name, "description": "", "geometry": "default", "mirror": False,
           "calibration": None, "point_sigma": None, "tension_sigma": None, "angle_sigma": None, "base": None,
           "ramp_time": None, "image_gamma": None}
    for key in ("name", "description", "geometry", "calibration"):
        if key in data:
            v = data[key]
            if not isinstance(v, str) or (key != "description" and not v.strip()):
                probs.add(doc.line_of(key), f"{key} must be a non-empty string, got {v!r}")
            elif key == "name" and not _plain_name(v):
                probs.add(doc.line_of(key), f"name {v!r} must be usable as a folder name (no '/', '\\', "
                                            "control characters, leading '.' or leading/trailing spaces)")
            else:
                out[key] = v
    if "mirror" in data:
        if not isinstance(data["mirror"], bool):
            probs.add(doc.line_of("mirror"), f"mirror must be true or false, got {data['mirror']!r}")
        else:
            out["mirror"] = data["mirror"]
    if "uncertainty" in data:
        _uncertainty(doc, data["uncertainty"], probs, out)
    if "base" in data:
        if data["base"] not in BASE_SIDES:
            probs.add(doc.line_of("base"), f"base must be one of {', '.join(BASE_SIDES)}, got {data['base']!r}")
        else:
            out["base"] = data["base"]
    if "protocol" in data:
        _protocol(doc, data["protocol"], probs, out)
    if "image_gamma" in data:
        v, (lo, hi) = data["image_gamma"], IMAGE_GAMMA_RANGE
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
            probs.add(doc.line_of("image_gamma"), f"image_gamma must be a number from {lo:g} (linear light) to "
                                                  f"{hi:g}, got {v!r} (a camera's JPEG: about 2.2)")
        else:
            out["image_gamma"] = float(v)
    probs.raise_if_any()
    return out


def _protocol(doc, table, probs, out) -> None:
    """``[protocol] ramp_time_s``: how the drive moved between samples (0 = a step)."""
    if not isinstance(table, dict):
        probs.add(doc.line_of("protocol"), "[protocol] must be a table")
        return
    for k in sorted(set(table) - {"ramp_time_s"}):
        probs.add(doc.line_of("protocol", k), f"unknown key {k!r} in [protocol] (known: ramp_time_s)")
    if "ramp_time_s" in table:
        v = table["ramp_time_s"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v >= 0 and v < 1e6):
            probs.add(doc.line_of("protocol", "ramp_time_s"), f"ramp_time_s must be a number >= 0 s, got {v!r}")
        else:
            out["ramp_time"] = float(v)


def _plain_name(name: str) -> bool:
    """``name`` can be an output sub-folder ``OUT/<name>``: one path component, not hidden, no controls."""
    return (0 < len(name) <= 200 and name == name.strip() and not name.startswith(".")
            and not any(c in name for c in "/\\") and all(c.isprintable() for c in name))


# ----------------------------------------------------------------------------- folders
def _experiment_geometry(folder: Path, meta_path: Path, source: str) -> Geometry:
    if source == "default":
        return load_geometry("default")
    try:
        return load_geometry(folder / source)
    except ValueError as exc:
        line = load_toml(meta_path).line_of("geometry")
        raise TomlError(f"{meta_path}: line {line}: geometry {source!r}: {exc}") from None


def _calibration_path(folder: Path, meta_path: Path, meta: dict, has_images: bool) -> Path | None:
    calib = folder / meta["calibration"] if meta["calibration"] is not None else None
    if has_images:
        # images without a camera file are allowed: `detect` then takes the scale from the
        # tube's outer diameter (a fronto-parallel view) and says so
        if calib is not None and not calib.is_file():
            line = load_toml(meta_path).line_of("calibration")
            raise TomlError(f"{meta_path}: line {line}: calibration file not found: {meta['calibration']} "
                            f"(looked for {calib})")
    return calib


def read_experiment(path, *, missing_images: str = "error") -> Experiment:
    """Read and validate one experiment folder.

    Parameters
    ----------
    path : path
        The folder holding ``experiment.toml`` (or the toml file itself).
    missing_images : {"error", "keep"}
        A sample whose image file is absent is an input error ("error"), or is
        kept as a path for a batch to report per image ("keep").

    Raises
    ------
    FileNotFoundError
        The folder or a required file is absent.
    ValueError
        Naming the file, the line and the problem.
    """
    path = Path(path)
    if path.is_file() and path.name == "experiment.toml":
        path = path.parent
    if not path.is_dir():
        raise InputFileNotFoundError(f"{path}: experiment folder not found", path=path)
    meta_path = path / "experiment.toml"
    if not meta_path.exists():
        raise InputFileNotFoundError(f"{path}: not an experiment folder (no experiment.toml)", path=path)
    meta = read_experiment_toml(meta_path)
    geom = _experiment_geometry(path, meta_path, meta["geometry"])
    samples, image_paths = read_samples(path / "samples.csv", folder=path, missing_images=missing_images,
                                        tendons=geom.tendons, tension_sigma=meta["tension_sigma"])
    has_images = image_paths is not None and any(p is not None for p in image_paths)
    calib = _calibration_path(path, meta_path, meta, has_images)
    pts_path, ang_path = path / "notch_points.csv", path / "angles.csv"
    points = angles = None
    if pts_path.is_file():
        df = read_points_table(pts_path, n_points=geom.n_points, sample_ids=samples["sample"])
        points = points_from_table(df, samples["sample"], geom.n_points)
    if ang_path.is_file():
        df = read_angles_table(ang_path, n_joints=geom.n_joints, sample_ids=samples["sample"])
        angles = angles_from_table(df, samples["sample"], geom.n_joints)
    if points is None and angles is None and not has_images:
        raise InputFileError(f"{path}: no notch_points.csv, no angles.csv and no images: an experiment needs "
                             "measured notch points, measured joint angles or one image per sample", path=path)
    return Experiment(name=meta["name"], path=path, description=meta["description"], geometry=geom,
                      mirror=meta["mirror"], calibration_path=calib, point_sigma=meta["point_sigma"],
                      tension_sigma=meta["tension_sigma"], samples=samples, points=points,
                      image_paths=image_paths, base=meta["base"], ramp_time=meta["ramp_time"],
                      angles=angles, angle_sigma=meta["angle_sigma"], image_gamma=meta["image_gamma"])


def is_experiment_dir(path) -> bool:
    """The folder holds an ``experiment.toml``."""
    return (Path(path) / "experiment.toml").is_file()


#: Files whose presence makes a sub-folder of a study an experiment that lost its experiment.toml.
_EXPERIMENT_FILES = ("samples.csv", "notch_points.csv", "angles.csv")


@dataclass(frozen=True)
class StudyScan:
    """What a study folder holds: the experiments read, those that could not be, the other folders.

    Attributes
    ----------
    experiments : list of Experiment
        Valid experiments, sorted by folder name.
    problems : dict
        ``{folder name: reason}`` for each sub-folder that is an experiment
        but cannot be read (the reason names the file and the line), or that
        holds experiment files but no ``experiment.toml``.
    ignored : list of str
        Sub-folders holding no experiment file (e.g. ``calibration/``);
        hidden folders are not listed.
    study : bool
        The path is a study (False: one experiment folder).
    """

    experiments: list
    problems: dict
    ignored: list
    study: bool


def _subfolders(path: Path) -> list[Path]:
    try:
        return sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError as exc:
        raise InputFileError(f"{path}: cannot list the folder: {exc.strerror or exc}", path=path) from None


def _scan_one(folder: Path, missing_images: str, problems: dict, exps: list, ignored: list) -> None:
    """Read sub-folder ``folder`` of a study into ``exps``, or record why not."""
    if not is_experiment_dir(folder):
        held = [f for f in _EXPERIMENT_FILES if (folder / f).exists()]
        if held:
            problems[folder.name] = (f"{folder}: not an experiment: no experiment.toml "
                                     f"(the folder holds {', '.join(held)})")
        else:
            ignored.append(folder.name)
        return
    try:
        exps.append(read_experiment(folder, missing_images=missing_images))
    except (ValueError, OSError) as exc:
        problems[folder.name] = str(exc)


def scan_study(path, *, missing_images: str = "error") -> StudyScan:
    """Read every experiment of a study, recording (not raising) what is wrong with each.

    A command runs on the valid experiments and lists the others with their
    reason (nothing is skipped in silence). For one experiment folder, an
    error in it is raised (nothing could be done).

    Raises
    ------
    InputFileError
        No such folder; a file given for a folder; neither an experiment
        folder nor a study; a study none of whose experiments can be read
        (listing why).
    """
    path = Path(path)
    if not path.exists():
        raise InputFileNotFoundError(f"{path}: folder not found", path=path)
    if not path.is_dir():
        raise InputFileError(f"{path}: is a file, not a folder (expected an experiment or a study folder)",
                             path=path)
    if is_experiment_dir(path):
        return StudyScan([read_experiment(path, missing_images=missing_images)], {}, [], False)
    held = [f for f in _EXPERIMENT_FILES if (path / f).exists()]
    if held:
        raise InputFileError(f"{path}: not an experiment folder: no experiment.toml (the folder holds "
                             f"{', '.join(held)})", path=path)
    exps, problems, ignored = [], {}, []
    for folder in _subfolders(path):
        _scan_one(folder, missing_images, problems, exps, ignored)
    seen: dict[str, Path] = {}
    for e in list(exps):
        if e.name in seen:
            problems[e.path.name] = f"{e.path}: two experiments named {e.name!r}: {seen[e.name]} and {e.path}"
            exps.remove(e)
        else:
            seen[e.name] = e.path
    if not exps:
        if problems:
            raise InputFileError(f"{path}: no experiment can be read: " + _joined(problems), path=path)
        raise InputFileError(f"{path}: neither an experiment folder (experiment.toml) nor a study "
                             "(sub-folders with experiment.toml)", path=path)
    return StudyScan(exps, problems, ignored, True)


def _joined(problems: dict) -> str:
    return "; ".join(f"{k}: {v}" for k, v in problems.items())


def read_study(path, *, missing_images: str = "error") -> list[Experiment]:
    """Every experiment of a study folder (sorted by folder name), or ``[one]`` for an experiment folder.

    Strict: any sub-folder that is an experiment but cannot be read is an
    error (:func:`scan_study` reads the valid ones and lists the others).

    Raises
    ------
    InputFileError (a ValueError; a FileNotFoundError when the folder is missing)
        No such folder; no experiments in it; an experiment that cannot be
        read; two experiments with one name.
    """
    scan = scan_study(path, missing_images=missing_images)
    if scan.problems:
        if len(scan.problems) == 1:
            raise InputFileError(next(iter(scan.problems.values())), path=path)
        raise InputFileError(f"{path}: {len(scan.problems)} experiments cannot be read: "
                             + _joined(scan.problems), path=path)
    return scan.experiments


def with_points(exp: Experiment, points) -> Experiment:
    """A copy of ``exp`` with measured points ``(S, m, 2)`` [m] (e.g. from ``detect``)."""
    pts = np.asarray(points, dtype=float)
    if pts.shape != (exp.n_samples, exp.geometry.n_points, 2):
        raise ValueError(f"points for {exp.name} must have shape "
                         f"{(exp.n_samples, exp.geometry.n_points, 2)}, got {pts.shape}")
    return dataclasses.replace(exp, points=pts)


def _samples_for_file(samples: pd.DataFrame) -> pd.DataFrame:
    df = samples.copy()
    missing = [c for c in SAMPLE_COLUMNS[:4] if c not in df.columns]
    if missing:
        raise ValueError(f"samples frame lacks column(s) {', '.join(missing)}")
    for c in SAMPLE_COLUMNS[4:]:
        if c not in df.columns:
            df[c] = np.nan
    order = list(SAMPLE_COLUMNS) + [c for c in df.columns if c not in SAMPLE_COLUMNS]
    return df[order]


def write_experiment(folder, *, name: str, samples: pd.DataFrame, points=None, mirror: bool = False,
                     description: str = "", geometry="default", calibration=None,
                     point_sigma: float | None = None, tension_sigma: float | None = None,
                     angles=None, angle_sigma: float | None = None, protocol: dict | None = None,
                     force: bool = False) -> Path:
    """Write an experiment folder per docs/data-formats.md.

    Parameters
    ----------
    folder : path
        Created; an existing experiment there is replaced only with ``force``.
    name, description : str
    samples : DataFrame
        Columns of ``samples.csv`` in file units (``sample, time_s,
        tension_left_N, tension_right_N, displacement_left_mm,
        displacement_right_mm[, image]``); missing displacement columns are
        written empty.
    points : array (S, m, 2) [m] or None
        Plane-frame notch points, NaN = missing (written to notch_points.csv).
    mirror : bool
    geometry : str
        ``"default"`` or a path relative to the folder.
    calibration : str or None
        Camera file path relative to the folder.
    point_sigma : float or None
        Point uncertainty [m] (written as ``point_mm``).
    tension_sigma : float or None
        Tension uncertainty [N].
    angles : array (S, n) [rad] or None
        Measured joint angles, NaN = not measured (written to angles.csv in degrees).
    angle_sigma : float or None
        Angle uncertainty [rad] (written as ``angle_deg``).
    protocol : dict or None
        ``{"ramp_time_s": ...}`` written as ``[protocol]``.
    force : bool

    Returns
    -------
    Path
        The folder.
    """
    folder = Path(folder)
    if (folder / "experiment.toml").exists() and not force:
        raise FileExistsError(f"{folder}: an experiment already exists there (use --force to replace it)")
    folder.mkdir(parents=True, exist_ok=True)
    df = _samples_for_file(samples)
    if points is not None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 3 or pts.shape[0] != len(df):
            raise ValueError(f"points must have shape (S={len(df)}, m, 2), got {pts.shape}")
    ang_rows = None if angles is None else angles_table(angles, df["sample"].to_numpy())
    meta = {"name": name, "description": description, "geometry": str(geometry), "mirror": bool(mirror),
            "calibration": None if calibration is None else str(calibration)}
    unc = {}
    if point_sigma is not None:
        unc["point_mm"] = float(point_sigma) / MM
    if tension_sigma is not None:
        unc["tension_N"] = float(tension_sigma)
    if angle_sigma is not None:
        unc["angle_deg"] = float(angle_sigma) / DEG
    if unc:
        meta["uncertainty"] = unc
    if protocol:
        meta["protocol"] = {k: float(v) for k, v in protocol.items()}
    write_table_atomic(df, folder / "samples.csv")
    if points is not None:
        write_table_atomic(points_table(points, df["sample"].to_numpy()), folder / "notch_points.csv")
    elif (folder / "notch_points.csv").exists():
        os.remove(folder / "notch_points.csv")
    if ang_rows is not None:
        write_table_atomic(ang_rows, folder / "angles.csv")
    elif (folder / "angles.csv").exists():
        os.remove(folder / "angles.csv")
    # experiment.toml last: a folder without it is not an experiment yet.
    write_text_atomic(toml_dumps(meta), folder / "experiment.toml")
    return folder


# ----------------------------------------------------------------------------- detections
def load_detected_points(exp: Experiment, detections, *, ok_status=("ok",), review=None) -> Experiment:
    """``exp`` with its points taken from a ``detections.csv`` (rows whose status is not ok are missing).

    With ``review`` (a ``review.csv``, :func:`notchfit.io.apply_review`) its
    corrections are applied and the experiment carries every point's σ
    (``point_sigmas``: ``sigma_mm`` of the detections and of the corrections).
    """
    df = read_detections(detections, n_points=exp.geometry.n_points, sample_ids=exp.sample_ids)
    df = df[df["status"].str.lower().isin([s.lower() for s in ok_status])]
    pts = points_from_table(df, exp.sample_ids, exp.geometry.n_points)
    if review is None:
        return with_points(exp, pts)
    sig = points_from_table(df.assign(x_mm=df["sigma_mm"], y_mm=df["sigma_mm"]), exp.sample_ids,
                            exp.geometry.n_points)[..., 0]
    rows = read_review(review, n_points=exp.geometry.n_points, sample_ids=exp.sample_ids)
    pts, sig = apply_review(pts, sig, rows, exp.sample_ids)
    has = np.isfinite(pts).all(-1)
    if not np.isfinite(sig[has]).all():         # a detected point without sigma_mm: the run's median
        fill = np.nanmedian(sig[has]) if np.isfinite(sig[has]).any() else np.nan
        sig = np.where(has & ~np.isfinite(sig), fill, sig)
    return dataclasses.replace(with_points(exp, pts), point_sigmas=np.where(has, sig, np.nan))


def has_own_points(exp: Experiment) -> bool:
    """Whether the experiment's own files hold its notch points (``notch_points.csv``).

    The first place :func:`find_points` looks. An experiment whose own
    measurement is joint angles (``angles.csv``) is kept by :func:`find_points`
    too, after the detect runs were searched for points of it.
    """
    return exp.points is not None


@dataclass(frozen=True)
class PointsLookup:
    """Where each experiment's measured points came from (:func:`find_points`).

    Attributes
    ----------
    experiments : tuple of Experiment
        Those with points, in input order.
    sources : dict
        ``{name: (where, path)}``: ``where`` is ``"own"`` (the experiment's
        own notch_points.csv), ``"own angles"`` (its own angles.csv) or the
        label of the folder they were found in (e.g. ``"--points"``,
        ``"--out"``), followed by ``", reviewed"`` when a ``review.csv`` beside
        the detections corrected them; ``path`` the file read (that
        ``review.csv`` for reviewed points).
    problems : dict
        ``{name: reason}`` for the experiments without points.
    """

    experiments: tuple
    sources: dict
    problems: dict


def _detections_for(exp, found: dict, n_exps: int):
    return found.get(exp.name) or (found.get("") if n_exps == 1 else None)


def find_points(exps, folders=()) -> PointsLookup:
    """The measured data of each experiment, looked for in one order.

    First the experiment's own ``notch_points.csv`` (:func:`has_own_points`),
    then ``detections.csv`` of each folder of ``folders`` in turn
    (``DIR/<name>/detections.csv`` of a study run, ``DIR/detections.csv`` of
    a single experiment) with the corrections of the ``review.csv`` beside it
    applied first (``notchfit review``), and last its own ``angles.csv`` (measured joint
    angles: the experiment is kept without points). A ``detections.csv`` that
    is found but cannot be read is a problem of that experiment (never
    silently skipped for the next folder).

    Parameters
    ----------
    exps : sequence of Experiment
    folders : sequence of (str, path or None)
        ``(label, folder)`` in search order, e.g.
        ``[("--points", args.points), ("--out", args.out)]``; None folders are skipped.

    Returns
    -------
    PointsLookup
        ``sources[name]`` is ``("own", notch_points.csv)``, ``(label,
        detections.csv)``, ``(label + ", reviewed", review.csv)`` or
        ``("own angles", angles.csv)``.
    """
    exps = list(exps)
    searched = [(label, Path(f)) for label, f in folders if f is not None]
    found = {label: find_output(f, "detections.csv") for label, f in searched}
    out, sources, problems = [], {}, {}
    for e in exps:
        if has_own_points(e):
            out.append(e)
            sources[e.name] = ("own", Path(e.path) / "notch_points.csv")
            continue
        hit = next(((label, p) for label, _ in searched
                    if (p := _detections_for(e, found[label], len(exps))) is not None), None)
        if hit is None and e.angles is not None:
            out.append(e)
            sources[e.name] = ("own angles", Path(e.path) / "angles.csv")
            continue
        if hit is None:
            where = " nor ".join(f"{f} ({label})" for label, f in searched)
            problems[e.name] = ("no notch_points.csv, no angles.csv and no detections.csv for it"
                                + (f" in {where}" if where else ""))
            continue
        try:
            rev = review_path(hit[1])
            reviewed = rev.is_file()
            out.append(load_detected_points(e, hit[1], review=rev if reviewed else None))
            sources[e.name] = (f"{hit[0]}, reviewed", rev) if reviewed else hit
        except (ValueError, FileNotFoundError) as exc:
            problems[e.name] = str(exc)
    return PointsLookup(tuple(out), sources, problems)
