"""Experiments, studies and every output file on disk (``../shared/spec/data-format.md``).

Readers validate everything and raise :class:`ValueError` with a message that
names the file, the line and the problem (``samples.csv: line 7: time_s 12.0
is not after 15.0 (line 6); samples must be in time order``); they never
guess. Lengths are mm and tensions N in files, SI (m, N, s) in memory; the
conversion happens here.

Writers are atomic: a file is written to a temporary file in the same folder
and moved into place with :func:`os.replace`, so a reader never sees half a
file. A command writes a whole run through :class:`OutputRun`: every output
is first written into a hidden staging folder inside ``--out`` and moved into
place only once the run has succeeded, so a crash or an error mid-way leaves
the previous results untouched (a crash *during* the final moves, a loop of
renames, can leave a mix of old and new files; each file is still whole).
An existing output is never replaced without ``force``.

Layout of outputs: a command given one experiment writes into ``DIR``; given a
study it writes the per-experiment tables into ``DIR/<experiment name>/`` and
study-wide files (``diagnosis.json``, ``report.html``) into ``DIR``
(:func:`experiment_output_dir`).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import re
import shutil
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .geometry import Geometry, load_geometry

__all__ = [
    "Experiment",
    "OutputRun",
    "SAMPLE_COLUMNS",
    "POINT_COLUMNS",
    "DETECTION_COLUMNS",
    "experiment_output_dir",
    "find_output",
    "load_detected_points",
    "points_from_table",
    "points_table",
    "prepare_output_dir",
    "read_csv_table",
    "read_detections",
    "read_diagnosis",
    "read_experiment",
    "read_experiment_toml",
    "read_fits",
    "read_json",
    "read_points_table",
    "read_pointwise",
    "read_samples",
    "read_simulation",
    "read_study",
    "toml_dumps",
    "with_points",
    "write_experiment",
    "write_json_atomic",
    "write_table_atomic",
    "write_text_atomic",
]

_MM = 1e-3
SAMPLE_COLUMNS = ("sample", "time_s", "tension_left_N", "tension_right_N",
                  "displacement_left_mm", "displacement_right_mm")
POINT_COLUMNS = ("sample", "point", "x_mm", "y_mm")
DETECTION_COLUMNS = ("sample", "point", "x_mm", "y_mm", "u_px", "v_px", "sigma_mm", "status")
FITS_COLUMNS = ("sample", "model", "a", "b", "base_x_mm", "base_y_mm", "base_phi_rad", "rms_mm", "max_mm",
                "n_points")
POINTWISE_COLUMNS = ("sample", "model", "point", "err_mm")
SIMULATION_COLUMNS = ("sample", "regime", "a", "b")
_TOML_KEYS = {"name", "description", "geometry", "mirror", "calibration", "uncertainty"}
_UNCERTAINTY_KEYS = {"point_mm": "point_sigma", "tension_N": "tension_sigma"}
_MAX_PROBLEMS = 12
STAGE_PREFIX = ".notchfit-stage-"


# ----------------------------------------------------------------------------- errors
class _Problems:
    """Collects the problems found in one file and raises them together."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.items: list[str] = []

    def add(self, line: int | None, text: str) -> None:
        self.items.append(f"line {line}: {text}" if line is not None else text)

    def raise_if_any(self) -> None:
        if not self.items:
            return
        shown = self.items[:_MAX_PROBLEMS]
        more = len(self.items) - len(shown)
        if len(shown) == 1:
            msg = f"{self.path}: {shown[0]}"
        else:
            msg = f"{self.path}: {len(self.items)} problems:\n  " + "\n  ".join(shown)
            if more:
                msg += f"\n  ... and {more} more"
        raise ValueError(msg)


# ----------------------------------------------------------------------------- CSV core
def _read_csv_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and ``(line number, fields)`` for every non-blank data row."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: file not found")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = None
            rows = []
            for fields in reader:
                if not fields or all(not f.strip() for f in fields):
                    continue
                if header is None:
                    header = [f.strip() for f in fields]
                    header_line = reader.line_num
                    continue
                rows.append((reader.line_num, [f.strip() for f in fields]))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    except csv.Error as exc:
        raise ValueError(f"{path}: line {reader.line_num}: malformed CSV ({exc})") from None
    if header is None:
        raise ValueError(f"{path}: empty file (expected a header row)")
    probs = _Problems(path)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        probs.add(header_line, f"duplicate column(s) {', '.join(dup)}")
    for line, fields in rows:
        if len(fields) != len(header):
            probs.add(line, f"{len(fields)} fields, the header has {len(header)}")
    probs.raise_if_any()
    return header, rows


def _parse_float(text: str, *, allow_empty: bool, allow_nan: bool) -> float:
    if text == "":
        if allow_empty:
            return math.nan
        raise ValueError("empty value")
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"non-numeric value {text!r}") from None
    if math.isnan(v) and not allow_nan:
        raise ValueError(f"value {text!r} is not a number")
    if math.isinf(v):
        raise ValueError(f"value {text!r} is not finite")
    return v


def _parse_int(text: str) -> int:
    if text == "":
        raise ValueError("empty value (expected an integer)")
    try:
        return int(text)
    except ValueError:
        try:
            v = float(text)
        except ValueError:
            raise ValueError(f"non-numeric value {text!r} (expected an integer)") from None
        if v.is_integer():
            return int(v)
        raise ValueError(f"value {text!r} is not an integer") from None


def read_csv_table(path, *, required, integer=(), numeric=(), optional_numeric=(), nan_ok=(),
                   text=(), extra_ok=True, auto_extra=False) -> tuple[pd.DataFrame, np.ndarray]:
    """Read a CSV file with validated columns.

    Parameters
    ----------
    path : path
    required : sequence of str
        Columns that must be present (a missing one is an error naming it).
    integer, numeric : sequence of str
        Columns parsed as integers / finite floats (an empty cell is an error).
    optional_numeric : sequence of str
        Float columns whose cells may be empty (NaN).
    nan_ok : sequence of str
        Float columns that may hold empty cells or ``nan``.
    text : sequence of str
        Columns kept as strings.
    extra_ok : bool
        Keep unknown columns (True) or reject them.
    auto_extra : bool
        Unknown columns become floats when every cell is a number (or
        empty), booleans when every cell is ``True``/``False``, else strings.

    Returns
    -------
    frame : DataFrame
        Required columns first in the given order, then the other known and
        extra columns in file order.
    lines : ndarray of int, shape (rows,)
        The file line of each row (for later messages).
    """
    path = Path(path)
    header, rows = _read_csv_rows(path)
    probs = _Problems(path)
    missing = [c for c in required if c not in header]
    if missing:
        probs.add(1, f"missing column(s) {', '.join(missing)} (expected {','.join(required)})")
        probs.raise_if_any()
    known = set(required) | set(integer) | set(numeric) | set(optional_numeric) | set(nan_ok) | set(text)
    extras = [h for h in header if h not in known]
    if extras and not extra_ok:
        probs.add(1, f"unknown column(s) {', '.join(extras)}")
        probs.raise_if_any()
    idx = {h: i for i, h in enumerate(header)}
    cols: dict[str, list] = {h: [] for h in header}
    for line, fields in rows:
        for h, i in idx.items():
            s = fields[i]
            try:
                if h in integer:
                    v = _parse_int(s)
                elif h in numeric:
                    v = _parse_float(s, allow_empty=False, allow_nan=False)
                elif h in optional_numeric:
                    v = _parse_float(s, allow_empty=True, allow_nan=False)
                elif h in nan_ok:
                    v = _parse_float(s, allow_empty=True, allow_nan=True)
                else:
                    v = s
            except ValueError as exc:
                probs.add(line, f"column {h}: {exc}")
                v = None
            cols[h].append(v)
    probs.raise_if_any()
    order = [c for c in required] + [h for h in header if h not in required]
    data = {}
    for h in order:
        if h in integer:
            data[h] = pd.Series(cols[h], dtype="int64")
        elif h in numeric or h in optional_numeric or h in nan_ok:
            data[h] = pd.Series(cols[h], dtype="float64")
        elif auto_extra and h not in known:
            data[h] = _auto_series(cols[h])
        else:
            data[h] = pd.Series(cols[h], dtype="str")
    frame = pd.DataFrame(data, columns=order)
    return frame, np.array([ln for ln, _ in rows], dtype=int)


def _auto_series(values: list) -> pd.Series:
    if values and all(v in ("True", "False", "true", "false") for v in values):
        return pd.Series([v.lower() == "true" for v in values], dtype=bool)
    try:
        return pd.Series([_parse_float(v, allow_empty=True, allow_nan=True) for v in values],
                         dtype="float64")
    except ValueError:
        return pd.Series(values, dtype="str")


# ----------------------------------------------------------------------------- TOML
def _toml_line_of_key(text: str, key: str) -> int | None:
    pat = re.compile(rf"^\s*[\"']?{re.escape(key)}[\"']?\s*=", re.M)
    m = pat.search(text)
    return text.count("\n", 0, m.start()) + 1 if m else None


def _load_toml(path: Path) -> tuple[dict, str]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: file not found")
    text = path.read_bytes().decode("utf-8", errors="replace")
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"line (\d+)", msg)
        where = f"line {m.group(1)}: " if m else ""
        raise ValueError(f"{path}: {where}bad TOML: {msg}") from None


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def toml_dumps(data: dict, *, _table: str = "") -> str:
    """Serialise a mapping of scalars, lists and nested tables to TOML.

    Keys whose value is None are skipped. Sub-tables (dicts, any depth: written
    as ``[outer.inner]``) and arrays of tables (a list of dicts) are written
    after the plain keys. Floats use ``repr`` (exact round trip); NaN and
    infinities are written as TOML's ``nan`` and ``inf``.
    """
    plain, tables, arrays = [], [], []
    for k, v in data.items():
        if v is None:
            continue
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            arrays.append((k, v))
        else:
            plain.append(f"{_key(k)} = {_toml_value(v)}")
    out = "\n".join(plain) + ("\n" if plain else "")
    for k, v in tables:
        name = f"{_table}.{_key(k)}" if _table else _key(k)
        out += f"\n[{name}]\n" + toml_dumps(v, _table=name)
    for k, items in arrays:
        name = f"{_table}.{_key(k)}" if _table else _key(k)
        for item in items:
            out += f"\n[[{name}]]\n" + toml_dumps(item, _table=name)
    return out


def _key(k) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


# ----------------------------------------------------------------------------- experiment
@dataclass(frozen=True)
class Experiment:
    """One bend/unbend test as read from its folder (data-format.md).

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
    samples : DataFrame
        ``samples.csv`` as read (file units, one row per sample, time order).
    points : ndarray, shape (S, m, 2) [m], or None
        Notch points in the plane frame, NaN where missing; None when the
        folder has no ``notch_points.csv``.
    image_paths : tuple of (Path or None), or None
        The image of each sample; None when ``samples.csv`` has no ``image`` column.
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

    @property
    def sample_ids(self) -> np.ndarray:
        """Sample ids (S,) int."""
        return self.samples["sample"].to_numpy(dtype=np.int64)

    @property
    def time(self) -> np.ndarray:
        """Sample times (S,) [s]."""
        return self.samples["time_s"].to_numpy(dtype=float)

    @property
    def tension_left(self) -> np.ndarray:
        """Left cable tension at the load cell (S,) [N]."""
        return self.samples["tension_left_N"].to_numpy(dtype=float)

    @property
    def tension_right(self) -> np.ndarray:
        """Right cable tension at the load cell (S,) [N]."""
        return self.samples["tension_right_N"].to_numpy(dtype=float)

    @property
    def displacement_left(self) -> np.ndarray:
        """Left cable displacement (S,) [m], NaN where not measured."""
        return self.samples["displacement_left_mm"].to_numpy(dtype=float) * _MM

    @property
    def displacement_right(self) -> np.ndarray:
        """Right cable displacement (S,) [m], NaN where not measured."""
        return self.samples["displacement_right_mm"].to_numpy(dtype=float) * _MM

    @property
    def n_samples(self) -> int:
        return len(self.samples)

    @property
    def has_images(self) -> bool:
        return self.image_paths is not None and any(p is not None for p in self.image_paths)


def read_experiment_toml(path) -> dict:
    """Read and validate ``experiment.toml``.

    Returns
    -------
    dict
        ``name, description, geometry, mirror, calibration, point_sigma [m],
        tension_sigma [N]`` (absent optional keys as None; ``name`` defaults
        to the folder name, ``geometry`` to "default", ``mirror`` to false).
    """
    path = Path(path)
    data, text = _load_toml(path)
    probs = _Problems(path)

    def where(key):
        return _toml_line_of_key(text, key)

    unknown = sorted(set(data) - _TOML_KEYS)
    for k in unknown:
        probs.add(where(k), f"unknown key {k!r} (known: {', '.join(sorted(_TOML_KEYS))})")
    out = {"name": path.parent.name, "description": "", "geometry": "default", "mirror": False,
           "calibration": None, "point_sigma": None, "tension_sigma": None}
    for key in ("name", "description", "geometry", "calibration"):
        if key in data:
            v = data[key]
            if not isinstance(v, str) or (key != "description" and not v.strip()):
                probs.add(where(key), f"{key} must be a non-empty string, got {v!r}")
            else:
                out[key] = v
    if "mirror" in data:
        if not isinstance(data["mirror"], bool):
            probs.add(where("mirror"), f"mirror must be true or false, got {data['mirror']!r}")
        else:
            out["mirror"] = data["mirror"]
    if "uncertainty" in data:
        unc = data["uncertainty"]
        if not isinstance(unc, dict):
            probs.add(where("uncertainty"), "uncertainty must be a table [uncertainty]")
        else:
            for k, v in unc.items():
                if k not in _UNCERTAINTY_KEYS:
                    probs.add(where(k), f"unknown key {k!r} in [uncertainty] "
                                        f"(known: {', '.join(_UNCERTAINTY_KEYS)})")
                elif (isinstance(v, bool) or not isinstance(v, (int, float))
                      or not math.isfinite(v) or v <= 0):
                    probs.add(where(k), f"[uncertainty] {k} must be a positive number, got {v!r}")
                else:
                    out[_UNCERTAINTY_KEYS[k]] = float(v) * (_MM if k == "point_mm" else 1.0)
    probs.raise_if_any()
    return out


def read_samples(path, *, folder=None, missing_images: str = "error") -> tuple[pd.DataFrame, tuple | None]:
    """Read and validate ``samples.csv``.

    Checks: every column of data-format.md present; integer, unique sample
    ids; finite numeric times and tensions (displacements may be empty);
    strictly increasing ``time_s``; every named image exists (unless
    ``missing_images="keep"``, which keeps the path of a missing image for a
    batch to report).

    Returns
    -------
    samples : DataFrame
    image_paths : tuple of (Path or None) or None
    """
    path = Path(path)
    folder = Path(folder) if folder is not None else path.parent
    if missing_images not in ("error", "keep"):
        raise ValueError(f"missing_images must be 'error' or 'keep', got {missing_images!r}")
    df, lines = read_csv_table(
        path, required=SAMPLE_COLUMNS, integer=("sample",),
        numeric=("time_s", "tension_left_N", "tension_right_N"),
        optional_numeric=("displacement_left_mm", "displacement_right_mm"), text=("image",))
    probs = _Problems(path)
    if len(df) == 0:
        probs.add(None, "no samples (the file has only a header)")
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
        image_paths = []
        for rel, ln in zip(df["image"], lines):
            if rel == "":
                image_paths.append(None)
                continue
            p = (folder / rel)
            if not p.is_file() and missing_images == "error":
                probs.add(ln, f"image missing: {rel} (looked for {p})")
            image_paths.append(p)
        image_paths = tuple(image_paths)
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
    _check_point_rows(path, df, lines, n_points, sample_ids)
    return df


def _check_point_rows(path, df, lines, n_points, sample_ids):
    probs = _Problems(path)
    known = set(int(s) for s in sample_ids) if sample_ids is not None else None
    seen: dict[tuple, int] = {}
    for s, q, ln in zip(df["sample"].to_numpy(), df["point"].to_numpy(), lines):
        if n_points is not None and not 1 <= q <= n_points:
            probs.add(ln, f"point id {q} out of range 1..{n_points}")
        if known is not None and s not in known:
            probs.add(ln, f"sample {s} is not in samples.csv")
        if (s, q) in seen:
            probs.add(ln, f"duplicate point {q} of sample {s} (first on line {seen[(s, q)]})")
        else:
            seen[(s, q)] = ln
    probs.raise_if_any()


def points_from_table(df: pd.DataFrame, sample_ids, n_points: int) -> np.ndarray:
    """``(S, m, 2)`` plane-frame points [m] from a ``sample,point,x_mm,y_mm`` frame (NaN = missing)."""
    ids = np.asarray(sample_ids, dtype=np.int64)
    pos = {int(s): i for i, s in enumerate(ids)}
    out = np.full((len(ids), n_points, 2), np.nan)
    if len(df):
        rows = np.array([pos.get(int(s), -1) for s in df["sample"].to_numpy()])
        pts = df["point"].to_numpy(dtype=np.int64) - 1
        ok = (rows >= 0) & (pts >= 0) & (pts < n_points)
        out[rows[ok], pts[ok], 0] = df["x_mm"].to_numpy(dtype=float)[ok] * _MM
        out[rows[ok], pts[ok], 1] = df["y_mm"].to_numpy(dtype=float)[ok] * _MM
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
    flat = pts.reshape(-1, 2) / _MM
    keep = np.isfinite(flat).all(axis=1)
    return pd.DataFrame({"sample": sample[keep], "point": point[keep],
                         "x_mm": flat[keep, 0], "y_mm": flat[keep, 1]})


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
        raise FileNotFoundError(f"{path}: experiment folder not found")
    meta_path = path / "experiment.toml"
    if not meta_path.is_file():
        raise FileNotFoundError(f"{path}: not an experiment folder (no experiment.toml)")
    meta = read_experiment_toml(meta_path)
    geom_src = meta["geometry"]
    if geom_src == "default":
        geom = load_geometry("default")
    else:
        gpath = (path / geom_src)
        try:
            geom = load_geometry(gpath)
        except ValueError as exc:
            line = _toml_line_of_key(meta_path.read_text(errors="replace"), "geometry")
            raise ValueError(f"{meta_path}: line {line}: geometry {geom_src!r}: {exc}") from None
    samples, image_paths = read_samples(path / "samples.csv", folder=path, missing_images=missing_images)
    calib = None
    if meta["calibration"] is not None:
        calib = (path / meta["calibration"])
    has_images = image_paths is not None and any(p is not None for p in image_paths)
    if has_images:
        text = meta_path.read_text(errors="replace")
        if calib is None:
            raise ValueError(f"{meta_path}: samples.csv names images but there is no `calibration` "
                             "key (a camera file is required with images)")
        if not calib.is_file():
            raise ValueError(f"{meta_path}: line {_toml_line_of_key(text, 'calibration')}: "
                             f"calibration file not found: {meta['calibration']} (looked for {calib})")
    pts_path = path / "notch_points.csv"
    points = None
    if pts_path.is_file():
        df = read_points_table(pts_path, n_points=geom.n_points, sample_ids=samples["sample"])
        points = points_from_table(df, samples["sample"], geom.n_points)
    elif not has_images:
        raise ValueError(f"{path}: no notch_points.csv and no images: an experiment needs measured "
                         "notch points or one image per sample")
    return Experiment(name=meta["name"], path=path, description=meta["description"], geometry=geom,
                      mirror=meta["mirror"], calibration_path=calib, point_sigma=meta["point_sigma"],
                      tension_sigma=meta["tension_sigma"], samples=samples, points=points,
                      image_paths=image_paths)


def is_experiment_dir(path) -> bool:
    return (Path(path) / "experiment.toml").is_file()


def read_study(path, *, missing_images: str = "error") -> list[Experiment]:
    """Every experiment of a study folder (sorted by folder name), or ``[one]`` for an experiment folder.

    Raises
    ------
    FileNotFoundError, ValueError
        No such folder; no experiments in it; two experiments with one name.
    """
    path = Path(path)
    if not path.is_dir():
        raise FileNotFoundError(f"{path}: folder not found")
    if is_experiment_dir(path):
        return [read_experiment(path, missing_images=missing_images)]
    folders = sorted(p for p in path.iterdir() if p.is_dir() and is_experiment_dir(p))
    if not folders:
        raise ValueError(f"{path}: neither an experiment folder (experiment.toml) nor a study "
                         "(sub-folders with experiment.toml)")
    exps = [read_experiment(f, missing_images=missing_images) for f in folders]
    seen: dict[str, Path] = {}
    for e in exps:
        if e.name in seen:
            raise ValueError(f"{path}: two experiments named {e.name!r}: {seen[e.name]} and {e.path}")
        seen[e.name] = e.path
    return exps


def with_points(exp: Experiment, points) -> Experiment:
    """A copy of ``exp`` with measured points ``(S, m, 2)`` [m] (e.g. from ``detect``)."""
    pts = np.asarray(points, dtype=float)
    if pts.shape != (exp.n_samples, exp.geometry.n_points, 2):
        raise ValueError(f"points for {exp.name} must have shape "
                         f"{(exp.n_samples, exp.geometry.n_points, 2)}, got {pts.shape}")
    return dataclasses.replace(exp, points=pts)


def write_experiment(folder, *, name: str, samples: pd.DataFrame, points=None, mirror: bool = False,
                     description: str = "", geometry="default", calibration=None,
                     point_sigma: float | None = None, tension_sigma: float | None = None,
                     force: bool = False) -> Path:
    """Write an experiment folder per data-format.md.

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
    df = samples.copy()
    missing = [c for c in SAMPLE_COLUMNS[:4] if c not in df.columns]
    if missing:
        raise ValueError(f"samples frame lacks column(s) {', '.join(missing)}")
    for c in SAMPLE_COLUMNS[4:]:
        if c not in df.columns:
            df[c] = np.nan
    order = list(SAMPLE_COLUMNS) + [c for c in df.columns if c not in SAMPLE_COLUMNS]
    df = df[order]
    if points is not None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 3 or pts.shape[0] != len(df):
            raise ValueError(f"points must have shape (S={len(df)}, m, 2), got {pts.shape}")
    meta = {"name": name, "description": description, "geometry": str(geometry), "mirror": bool(mirror),
            "calibration": None if calibration is None else str(calibration)}
    unc = {}
    if point_sigma is not None:
        unc["point_mm"] = float(point_sigma) / _MM
    if tension_sigma is not None:
        unc["tension_N"] = float(tension_sigma)
    if unc:
        meta["uncertainty"] = unc
    write_table_atomic(df, folder / "samples.csv")
    if points is not None:
        write_table_atomic(points_table(points, df["sample"].to_numpy()), folder / "notch_points.csv")
    elif (folder / "notch_points.csv").exists():
        os.remove(folder / "notch_points.csv")
    # experiment.toml last: a folder without it is not an experiment yet.
    write_text_atomic(toml_dumps(meta), folder / "experiment.toml")
    return folder


# ----------------------------------------------------------------------------- outputs
def read_detections(path, *, n_points: int | None = None, sample_ids=None) -> pd.DataFrame:
    """Read ``detections.csv`` (``detect``): sample,point,x_mm,y_mm,u_px,v_px,sigma_mm,status."""
    path = Path(path)
    df, lines = read_csv_table(path, required=DETECTION_COLUMNS, integer=("sample", "point"),
                               nan_ok=("x_mm", "y_mm", "u_px", "v_px", "sigma_mm"), text=("status",))
    _check_point_rows(path, df, lines, n_points, sample_ids)
    return df


def load_detected_points(exp: Experiment, detections, *, ok_status=("ok",)) -> Experiment:
    """``exp`` with its points taken from a ``detections.csv`` (rows whose status is not ok are missing)."""
    df = read_detections(detections, n_points=exp.geometry.n_points, sample_ids=exp.sample_ids)
    df = df[df["status"].str.lower().isin([s.lower() for s in ok_status])]
    return with_points(exp, points_from_table(df, exp.sample_ids, exp.geometry.n_points))


def attach_detections(exps, detections_dir, *, require: bool = True) -> tuple[list, dict]:
    """Give experiments without ``notch_points.csv`` the points ``detect`` found.

    Looks for ``detections.csv`` of each experiment in ``detections_dir``
    (``DIR/<name>/detections.csv`` for a study run, ``DIR/detections.csv``
    for a single experiment).

    Returns
    -------
    experiments : list of Experiment
        Those that have points (measured or detected).
    problems : dict
        ``{name: reason}`` for experiments left out.
    """
    found = find_output(detections_dir, "detections.csv") if detections_dir is not None else {}
    out, problems = [], {}
    for e in exps:
        if e.points is not None:
            out.append(e)
            continue
        path = found.get(e.name) or (found.get("") if len(exps) == 1 else None)
        if path is None:
            problems[e.name] = ("no notch_points.csv and no detections.csv for it"
                                + (f" in {detections_dir}" if detections_dir is not None else "")
                                + " (run `notchfit detect` first)")
            continue
        try:
            out.append(load_detected_points(e, path))
        except (ValueError, FileNotFoundError) as exc:
            problems[e.name] = str(exc)
    if require and not out:
        raise ValueError("no experiment has notch points: " + "; ".join(f"{k}: {v}" for k, v in problems.items()))
    return out, problems


def provenance(command: str, input_path, **extra) -> dict:
    """The ``<command>_run.json`` record: what ran on which input (the report finds the study here)."""
    import datetime
    import sys

    from . import __version__
    return {"command": command, "input": str(Path(input_path).resolve()), "notchfit": __version__,
            "python": sys.version.split()[0],
            "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), **extra}


def read_fits(path) -> pd.DataFrame:
    """Read ``fits.csv`` (``fit``): one row per sample and shape model."""
    df, _ = read_csv_table(path, required=FITS_COLUMNS, integer=("sample", "n_points"),
                           nan_ok=("a", "b", "base_x_mm", "base_y_mm", "base_phi_rad", "rms_mm", "max_mm"),
                           text=("model", "message"), auto_extra=True)
    return df


def read_pointwise(path) -> pd.DataFrame:
    """Read ``pointwise.csv`` (``fit``): sample,model,point,err_mm."""
    df, _ = read_csv_table(path, required=POINTWISE_COLUMNS, integer=("sample", "point"),
                           nan_ok=("err_mm",), text=("model",))
    return df


def read_simulation(path) -> pd.DataFrame:
    """Read ``simulation.csv`` (``simulate``): sample, regime, a, b, theta_1..theta_n, ..."""
    df, _ = read_csv_table(path, required=SIMULATION_COLUMNS, integer=("sample",),
                           nan_ok=("a", "b"), text=("regime",), auto_extra=True)
    return df


def read_json(path) -> dict:
    """Read a JSON file; a syntax error names the file and line."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: file not found")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: line {exc.lineno}: bad JSON: {exc.msg}") from None


_DIAG_KEYS = ("experiments", "baseline", "discrepancies", "candidates", "cause", "explanation", "gain")


def read_diagnosis(path) -> dict:
    """Read ``diagnosis.json`` and check its top-level keys (data-format.md)."""
    d = read_json(path)
    missing = [k for k in _DIAG_KEYS if k not in d]
    if missing:
        raise ValueError(f"{path}: missing key(s) {', '.join(missing)} (diagnosis.json schema)")
    return d


def experiment_output_dir(out_dir, exp_name: str, study: bool) -> Path:
    """Where a command writes the per-experiment outputs: ``DIR`` or ``DIR/<name>`` for a study."""
    return Path(out_dir) / exp_name if study else Path(out_dir)


def find_output(out_dir, filename: str) -> dict[str, Path]:
    """Per-experiment outputs named ``filename`` under ``out_dir``.

    Returns ``{experiment name: path}``: ``DIR/<name>/filename`` for a study
    run, or ``{"": DIR/filename}`` for a single-experiment run.
    """
    out_dir = Path(out_dir)
    found = {}
    if (out_dir / filename).is_file():
        found[""] = out_dir / filename
    if out_dir.is_dir():
        for sub in sorted(out_dir.iterdir()):
            if sub.is_dir() and not sub.name.startswith(".") and (sub / filename).is_file():
                found[sub.name] = sub / filename
    return found


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _tmp_path(path: Path) -> Path:
    """A temporary file beside ``path``, with the permissions a plain write would give
    (mkstemp creates 0600 files; outputs such as report.html are meant to be shared)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.fchmod(fd, 0o666 & ~_umask())
    os.close(fd)
    return Path(tmp)


def _atomic(path, writer) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_path(path)
    try:
        writer(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_table_atomic(df: pd.DataFrame, path) -> Path:
    """Write a CSV (UTF-8, header, no index, exact float repr) atomically."""
    def w(tmp):
        df.to_csv(tmp, index=False, lineterminator="\n")
    return _atomic(path, w)


def write_text_atomic(text: str, path) -> Path:
    """Write a UTF-8 text file atomically."""
    return _atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_bytes_atomic(data: bytes, path) -> Path:
    """Write a binary file atomically."""
    return _atomic(path, lambda tmp: Path(tmp).write_bytes(data))


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    if dataclasses.is_dataclass(o):
        return dataclasses.asdict(o)
    raise TypeError(f"cannot write {type(o).__name__} to JSON")


def write_json_atomic(obj, path) -> Path:
    """Write JSON (indented, numpy-aware, NaN written as null) atomically."""
    text = json.dumps(_nan_to_none(obj), indent=2, default=_json_default, allow_nan=False) + "\n"
    return write_text_atomic(text, path)


def _nan_to_none(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, np.floating) and not np.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _nan_to_none(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_nan_to_none(v) for v in o]
    if isinstance(o, np.ndarray):
        return _nan_to_none(o.tolist())
    return o


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _clean_stale_stages(out_dir: Path) -> None:
    for p in out_dir.glob(STAGE_PREFIX + "*"):
        m = re.match(re.escape(STAGE_PREFIX) + r"[^-]*-(\d+)-", p.name)
        if m and not _pid_alive(int(m.group(1))):
            shutil.rmtree(p, ignore_errors=True)


def prepare_output_dir(path, force: bool = False, outputs=None) -> Path:
    """Create an output folder, refusing to overwrite results without ``force``.

    Parameters
    ----------
    path : path
    force : bool
        Allow existing outputs to be replaced.
    outputs : sequence of str, optional
        Relative paths this command will write. With it, only those existing
        is a conflict (commands share one ``--out``: fit, simulate, diagnose
        and report write different files); without it, any visible entry in
        the folder is.

    Raises
    ------
    FileExistsError
        Naming the existing outputs and suggesting ``--force``.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path}: exists and is not a folder")
    path.mkdir(parents=True, exist_ok=True)
    _clean_stale_stages(path)
    if force:
        return path
    if outputs is None:
        clash = sorted(p.name for p in path.iterdir() if not p.name.startswith("."))
    else:
        clash = sorted(str(o) for o in outputs if (path / o).exists())
    if clash:
        shown = ", ".join(clash[:5]) + (" ..." if len(clash) > 5 else "")
        raise FileExistsError(f"{path}: already holds outputs ({shown}); use --force to replace them "
                              "or choose another --out")
    return path


class OutputRun:
    """Write a command's outputs into a staging folder, then move them into place.

    Use as a context manager::

        with OutputRun(out_dir, outputs=["fits.csv"], force=args.force) as run:
            write_table_atomic(df, run.path("fits.csv"))

    Nothing in ``out_dir`` changes until the block ends without an exception;
    then every staged file replaces its counterpart (``os.replace``, atomic
    per file). On an exception the staging folder is removed and the old
    results stay as they were.
    
    With ``whole_dirs=True`` each top-level folder of the run replaces its old
    counterpart as a whole (two renames), so no stale file of an earlier run
    survives inside it (``synth --force`` replacing an experiment folder).
    """

    def __init__(self, out_dir, *, outputs=None, force: bool = False, name: str = "run",
                 whole_dirs: bool = False):
        self.out_dir = prepare_output_dir(out_dir, force=force, outputs=outputs)
        self.force = force
        self.whole_dirs = whole_dirs
        self.stage = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{name}-{os.getpid()}-",
                                           dir=self.out_dir))
        self.committed: list[Path] = []

    def path(self, rel) -> Path:
        """The staging path of output ``rel`` (parent folders created)."""
        p = self.stage / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def commit(self) -> list[Path]:
        files = sorted(p for p in self.stage.rglob("*") if p.is_file())
        if not self.force:
            clash = [str(p.relative_to(self.stage)) for p in files
                     if (self.out_dir / p.relative_to(self.stage)).exists()]
            if clash:
                raise FileExistsError(f"{self.out_dir}: already holds {', '.join(clash[:5])}; "
                                      "use --force to replace")
        if self.whole_dirs:
            # each top-level folder replaces its old counterpart as a whole (no stale files left):
            # rename the old one aside, rename the new one in, then delete the old one
            for d in sorted(p for p in self.stage.iterdir() if p.is_dir()):
                dest = self.out_dir / d.name
                old = None
                if dest.exists():
                    old = self.out_dir / f"{STAGE_PREFIX}old-{os.getpid()}-{d.name}"
                    os.replace(dest, old)
                os.replace(d, dest)
                self.committed.append(dest)
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
            files = [p for p in files if p.exists()]
        for p in files:
            dest = self.out_dir / p.relative_to(self.stage)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(p, dest)
            self.committed.append(dest)
        shutil.rmtree(self.stage, ignore_errors=True)
        return self.committed

    def abort(self) -> None:
        shutil.rmtree(self.stage, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            try:
                self.commit()
            finally:
                self.abort()
        else:
            self.abort()
        return False


# ----------------------------------------------------------------------------- camera
def __getattr__(name):
    """Lazy re-export of the camera file I/O (``notchfit.camera``)."""
    if name in ("read_camera", "write_camera"):
        from . import camera
        return getattr(camera, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
