"""Camera files (OpenCV FileStorage YAML) and calibration-board definitions (TOML).

The camera file's keys are those of docs/data-formats.md: ``camera_matrix``,
``distortion_coefficients`` (1xN), ``image_width``, ``image_height``,
``avg_reprojection_error`` [px], and ``plane_rvec``, ``plane_tvec`` (3x1,
``plane_tvec`` in mm) when the bending plane is known. The models they hold
are :class:`~notchfit.camera.CameraModel` and :class:`~notchfit.camera.Board`.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from ..camera import DIST_LENGTHS, Board, CameraModel
from ..units import MM
from .errors import InputFileError, InputFileNotFoundError, read_input_bytes
from .outputs import atomic_write
from .resources import calibration_dir
from .toml import TomlError, TomlFile, load_toml

__all__ = ["load_board", "read_camera", "write_camera"]

_BOARD_KEYS = {"name", "type", "squares_x", "squares_y", "square_mm", "marker_mm", "dictionary", "legacy"}


# ----------------------------------------------------------------------------- boards
def _board_path(source) -> Path:
    path = Path(source)
    if path.is_file():
        return path
    folder = calibration_dir()
    cand = folder / (path.name if path.suffix == ".toml" else path.name + ".toml")
    if not cand.is_file():
        known = sorted(p.stem for p in folder.glob("*.toml")) if folder.is_dir() else []
        raise InputFileNotFoundError(f"board definition not found: {source} (shipped boards: "
                                     f"{', '.join(known) or 'none'})", path=path)
    return cand


def _board_from_toml(doc: TomlFile) -> Board:
    data = doc.data
    unknown = sorted(set(data) - _BOARD_KEYS)
    if unknown:
        raise doc.error(f"unknown board key(s) {', '.join(unknown)}", unknown[0])
    kind = data.get("type", "charuco")
    need = ["squares_x", "squares_y", "square_mm"] + (["marker_mm", "dictionary"] if kind == "charuco" else [])
    missing = [k for k in need if k not in data]
    if missing:
        raise doc.error(f"missing board key(s) {', '.join(missing)}")

    def num(k):
        v = data[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v < 1e6:
            raise doc.error(f"{k} must be a positive number of mm (below 1e6), got {v!r}", k)
        return float(v)

    for k in ("squares_x", "squares_y"):
        v = data[k]
        if isinstance(v, bool) or not isinstance(v, int) or not 2 <= v <= 1000:
            raise doc.error(f"{k} must be an integer from 2 to 1000, got {v!r}", k)
    dictionary = data.get("dictionary")
    if dictionary is not None and not (isinstance(dictionary, str) and dictionary.startswith("DICT_")):
        raise doc.error(f"dictionary must be a cv2.aruco dictionary name such as DICT_5X5_100, "
                        f"got {dictionary!r}", "dictionary")
    if not isinstance(data.get("legacy", False), bool):
        raise doc.error(f"legacy must be true or false, got {data['legacy']!r}", "legacy")
    try:
        return Board(name=str(data.get("name", doc.path.stem)), kind=str(kind),
                     squares_x=data["squares_x"], squares_y=data["squares_y"],
                     square_size=num("square_mm") * MM,
                     marker_size=num("marker_mm") * MM if "marker_mm" in data else None,
                     dictionary=data.get("dictionary"), legacy=bool(data.get("legacy", False)))
    except TomlError:
        raise
    except (ValueError, TypeError, OverflowError, cv2.error) as exc:
        raise doc.error(f"invalid board: {exc}") from None


def load_board(source) -> Board:
    """Load a board definition (TOML).

    Parameters
    ----------
    source : str or path
        A TOML file, or the name of one in
        :func:`~notchfit.io.resources.calibration_dir` (with or without
        ``.toml``). Keys: ``name``, ``type`` (``charuco``/``chessboard``),
        ``squares_x``, ``squares_y``, ``square_mm``, and for ChArUco
        ``marker_mm``, ``dictionary``, ``legacy``.

    Raises
    ------
    FileNotFoundError
        No such file and no shipped board of that name (the message lists them).
    TomlError
        Naming the file, the problem and, where it can be found, the line.
    """
    return _board_from_toml(load_toml(_board_path(source), what="board definition"))


# ----------------------------------------------------------------------------- camera files
def _write_fields(fs, model: CameraModel, extra: dict | None) -> None:
    fs.write("camera_matrix", np.asarray(model.camera_matrix, np.float64))
    fs.write("distortion_coefficients", np.asarray(model.dist_coeffs, np.float64).reshape(1, -1))
    fs.write("image_width", int(model.image_size[0]))
    fs.write("image_height", int(model.image_size[1]))
    if math.isfinite(model.rms):
        fs.write("avg_reprojection_error", float(model.rms))
    else:
        fs.writeComment("avg_reprojection_error -1: not measured (a synthetic or hand-made camera)")
        fs.write("avg_reprojection_error", -1.0)
    if model.has_plane:
        fs.write("plane_rvec", np.asarray(model.plane_rvec, np.float64).reshape(3, 1))
        fs.write("plane_tvec", (np.asarray(model.plane_tvec, np.float64) / MM).reshape(3, 1))
        if math.isfinite(model.plane_rms):
            fs.write("plane_reprojection_error", float(model.plane_rms))
    if model.std_intrinsics is not None:
        fs.write("intrinsics_std_dev", np.asarray(model.std_intrinsics, np.float64).reshape(1, -1))
    if model.per_view_errors is not None and len(model.per_view_errors):
        fs.write("per_view_reprojection_errors", np.asarray(model.per_view_errors, np.float64).reshape(-1, 1))
    for k, v in (extra or {}).items():
        fs.write(str(k), v if isinstance(v, str) else float(v))


def write_camera(model: CameraModel, path, *, extra: dict | None = None) -> Path:
    """Write an OpenCV FileStorage YAML camera file, atomically.

    Keys: ``camera_matrix``, ``distortion_coefficients`` (1xN), ``image_width``,
    ``image_height``, ``avg_reprojection_error`` [px], ``plane_rvec``,
    ``plane_tvec`` (3x1, mm) when the plane is known; extras:
    ``intrinsics_std_dev``, ``per_view_reprojection_errors``,
    ``plane_reprojection_error``, and ``extra`` (numbers or strings).
    """
    path = Path(path)
    suffix = path.suffix if path.suffix.lower() in (".yml", ".yaml") else ".yml"

    def writer(tmp):
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
        try:
            _write_fields(fs, model, extra)
        finally:
            fs.release()

    return atomic_write(path, writer, suffix=f".tmp{suffix}")


def _open_storage(path: Path):
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)   # the error below is the message
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        opened = fs.isOpened()
    except (cv2.error, SystemError) as exc:
        text = str(exc.__cause__ or exc).strip()
        msg = text.splitlines()[-1] if text else "parse error"
        raise InputFileError(f"{path}: not an OpenCV FileStorage camera file ({msg})", path=path) from None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if not opened:
        raise InputFileError(f"{path}: not an OpenCV FileStorage camera file", path=path)
    return fs


def _matrix(fs, path: Path, key: str, required: bool = True) -> np.ndarray | None:
    node = fs.getNode(key)
    if node.empty() or node.isNone():
        if required:
            raise ValueError(f"{path}: missing key {key!r}")
        return None
    m = node.mat()
    if m is None:
        if not node.isSeq():
            raise ValueError(f"{path}: key {key!r} is not a matrix")
        m = np.array([node.at(i).real() for i in range(node.size())])
    m = np.asarray(m, float)
    if not np.isfinite(m).all():
        raise ValueError(f"{path}: key {key!r} holds non-finite values")
    return m


def _number(fs, path: Path, key: str, required: bool = True) -> float | None:
    node = fs.getNode(key)
    if node.empty() or node.isNone():
        if required:
            raise ValueError(f"{path}: missing key {key!r}")
        return None
    if not (node.isInt() or node.isReal()):
        raise ValueError(f"{path}: key {key!r} must be a number")
    return node.real()


def _camera_from_storage(fs, path: Path) -> CameraModel:
    K = _matrix(fs, path, "camera_matrix")
    if K.shape != (3, 3):
        raise ValueError(f"{path}: camera_matrix must be 3x3, got {K.shape}")
    d = _matrix(fs, path, "distortion_coefficients").ravel()
    if d.size not in DIST_LENGTHS:
        raise ValueError(f"{path}: distortion_coefficients must hold 4, 5, 8, 12 or 14 values, got {d.size}")
    w, h = _number(fs, path, "image_width"), _number(fs, path, "image_height")
    if not (0 < w <= 1e6 and 0 < h <= 1e6) or w != int(w) or h != int(h):
        raise ValueError(f"{path}: image_width/image_height must be positive integers, got {w}, {h}")
    rms = _number(fs, path, "avg_reprojection_error", required=False)
    rv, tv = _matrix(fs, path, "plane_rvec", required=False), _matrix(fs, path, "plane_tvec", required=False)
    if (rv is None) != (tv is None):
        raise ValueError(f"{path}: plane_rvec and plane_tvec must be given together")
    if rv is not None and (rv.size != 3 or tv.size != 3):
        raise ValueError(f"{path}: plane_rvec and plane_tvec must be 3x1")
    std = _matrix(fs, path, "intrinsics_std_dev", required=False)
    pve = _matrix(fs, path, "per_view_reprojection_errors", required=False)
    prms = _number(fs, path, "plane_reprojection_error", required=False)
    try:
        return CameraModel(K, d, (int(w), int(h)),
                           plane_rvec=None if rv is None else rv.ravel(),
                           plane_tvec=None if tv is None else tv.ravel() * MM,
                           rms=math.nan if rms is None or rms < 0 else float(rms),
                           std_intrinsics=None if std is None else std.ravel(),
                           per_view_errors=None if pve is None else pve.ravel(),
                           plane_rms=math.nan if prms is None else float(prms))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def read_camera(path) -> CameraModel:
    """Read a camera file written by :func:`write_camera` or by OpenCV's calibration sample.

    A negative ``avg_reprojection_error`` (a camera not calibrated from
    views) is read as NaN.

    Raises
    ------
    InputFileNotFoundError
        The file does not exist (also a ``FileNotFoundError``).
    InputFileError
        A folder, an unreadable file, not an OpenCV FileStorage file, or a
        key missing or malformed (the message names the file and the key).
    """
    path = Path(path)
    try:
        read_input_bytes(path, what="camera file")
    except InputFileNotFoundError:
        raise InputFileNotFoundError(f"camera file not found: {path}", path=path) from None
    fs = _open_storage(path)
    try:
        return _camera_from_storage(fs, path)
    except InputFileError:
        raise
    except (ValueError, TypeError, OverflowError, cv2.error, SystemError) as exc:
        msg = str(exc).strip().splitlines()
        text = msg[-1] if msg else type(exc).__name__
        raise InputFileError(text if text.startswith(str(path)) else f"{path}: {text}", path=path) from None
    finally:
        fs.release()
