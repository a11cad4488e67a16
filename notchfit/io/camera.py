"""Camera files (OpenCV FileStorage YAML) and calibration-board definitions (TOML).

The camera file's keys are those of docs/data-formats.md: ``camera_matrix``,
``distortion_coefficients`` (1xN), ``image_width``, ``image_height``,
``avg_reprojection_error`` [px], and ``plane_rvec``, ``plane_tvec`` (3x1,
``plane_tvec`` in mm) when the bending plane is known. The models they hold
are :class:`~notchfit.vision.camera.CameraModel` and :class:`~notchfit.vision.camera.Board`.

Camera files are written with ``cv2.FileStorage`` (so OpenCV's own reader
reads them) but read by a parser of the FileStorage YAML subset written here:
OpenCV's parser is not safe on damaged input (it can abort the process).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..vision.camera import DIST_LENGTHS, Board, CameraModel
from ..units import MM
from .errors import InputFileError, InputFileNotFoundError, decode_text, located, read_input_bytes
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


# ----------------------------------------------------------------------------- FileStorage YAML subset
# Camera files are untrusted input: OpenCV's own FileStorage parser can abort the whole process
# on a damaged file (a heap corruption on a matrix without `cols`, found by the slow fuzz job), so
# they are parsed here, in Python, and never handed to cv2.FileStorage. The subset is what
# cv2.FileStorage writes: a `%YAML:1.x` (OpenCV 4) or `%YAML 1.x` (OpenCV 5) header, an optional
# `---`, top-level `key: scalar` lines, `key: !!opencv-matrix` maps of rows, cols, dt and data (a
# flow list that may span lines), comments; other keys (nested maps, sequences) are skipped.
_HEADER = re.compile(r"%YAML[: ]1\.\d+\Z")
_KEY = re.compile(r"([A-Za-z_][\w.-]*)[ ]*:(?:[ ]+(.*))?\Z")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_SPECIAL = {".nan": math.nan, ".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf}
_DT = re.compile(r"(\d*)([ucwsifdh])\Z")
_MATRIX_FIELDS = ("rows", "cols", "dt", "data")
_MATRIX_TAG = "!!opencv-matrix"
#: Largest matrix read from a camera file [elements] (a calibration's per-view errors are hundreds).
MAX_MATRIX_ELEMENTS = 1_000_000


@dataclass(frozen=True)
class _Entry:
    """A top-level ``key: text`` of the file, with the indented ``(line, content)`` lines that follow."""

    key: str
    line: int
    text: str
    more: tuple = ()


def _err(path: Path, line: int | None, problem: str, key: str | None = None) -> InputFileError:
    return InputFileError(located(path, line, problem), path=path, line=line, key=key)


def _scan_line(raw: str) -> tuple[str, int]:
    """The line without its comment (``#`` at the start or after a blank, outside quotes) and
    its balance of ``[``/``{`` minus ``]``/``}`` outside quotes."""
    quote, depth, prev = None, 0, " "
    for i, ch in enumerate(raw):
        if quote:
            if ch == quote and not (quote == '"' and prev == "\\"):
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and prev in " \t":
            return raw[:i].rstrip(), depth
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        prev = ch
    return raw.rstrip(), depth


def _logical_lines(path: Path, text: str) -> list[tuple[int, int, str]]:
    """``(line number, indent, content)`` of the lines that carry content: blank lines and
    comments dropped, a flow collection ``[ ... ]`` that spans lines joined into its first line."""
    out: list[tuple[int, int, str]] = []
    depth = 0
    for no, raw in enumerate(text.split("\n"), 1):
        raw = raw.rstrip("\r")
        body, delta = _scan_line(raw)
        stripped = body.lstrip(" ")
        if not stripped:
            continue
        if stripped[0] == "\t":
            raise _err(path, no, "a tab in the indentation (YAML indents with spaces)")
        if depth == 0 and (body == "..." or (body == "---" and len(out) > 1)):
            break               # the end of the (first) document
        if depth > 0:
            first, indent, content = out[-1]
            out[-1] = (first, indent, f"{content} {stripped}")
        else:
            out.append((no, len(body) - len(stripped), stripped))
        depth += delta
        if depth < 0:
            raise _err(path, no, "a closing bracket without its opening one")
    if depth > 0:
        raise _err(path, out[-1][0], "a list or map opened with [ or { is not closed")
    return out


def _parse_entries(path: Path, text: str) -> dict[str, _Entry]:
    """The top-level entries of a FileStorage YAML text, by key (the header checked, duplicates refused)."""
    first = next(((no, ln.rstrip()) for no, ln in enumerate(text.split("\n"), 1) if ln.strip()), None)
    if first is None or not _HEADER.match(first[1]):
        raise _err(path, first and first[0],
                   "not an OpenCV FileStorage YAML camera file (the first line must be %YAML:1.0)")
    lines = _logical_lines(path, text)
    body = lines[2:] if len(lines) > 1 and lines[1][2] == "---" else lines[1:]
    found: list[tuple[str, int, str, list]] = []
    seen: dict[str, int] = {}
    for no, indent, content in body:
        if indent > 0 or content.startswith("- ") or content == "-":
            if not found:
                raise _err(path, no, f"an indented line before the first key: {content[:40]!r}")
            found[-1][3].append((no, content))
            continue
        m = _KEY.match(content)
        if not m:
            raise _err(path, no, f"expected 'key: value', got {content[:40]!r}")
        key = m.group(1)
        if key in seen:
            raise _err(path, no, f"key {key!r} appears twice (lines {seen[key]} and {no})", key)
        seen[key] = no
        found.append((key, no, (m.group(2) or "").strip(), []))
    return {key: _Entry(key, no, text, tuple(more)) for key, no, text, more in found}


def _number(path: Path, line: int, key: str, s: str) -> float:
    """A YAML number (``4000.``, ``3.e-04``, ``-1``, ``.Nan``, ``-.Inf``) of key ``key`` on ``line``."""
    s = s.strip()
    if _NUMBER.match(s):
        return float(s)
    if s.lower() in _SPECIAL:
        return _SPECIAL[s.lower()]
    raise _err(path, line, f"{key}: {s[:40]!r} is not a number", key)


def _numbers(path: Path, line: int, key: str, text: str) -> list[float]:
    """The numbers of a flow list ``[ a, b, ... ]``."""
    if not (text.startswith("[") and text.endswith("]")):
        raise _err(path, line, f"{key}: expected a list [ ... ] of numbers, got {text[:40]!r}", key)
    inner = text[1:-1].strip()
    items = [s.strip() for s in inner.split(",")] if inner else []
    if items and not items[-1]:
        items.pop()                 # a trailing comma
    if len(items) > MAX_MATRIX_ELEMENTS:
        raise _err(path, line, f"{key}: more than {MAX_MATRIX_ELEMENTS:,} values", key)
    return [_number(path, line, key, s) for s in items]


def _count(path: Path, key: str, fields: dict, name: str) -> int:
    line, text = fields[name]
    if not re.fullmatch(r"\d{1,7}", text) or not 1 <= int(text) <= MAX_MATRIX_ELEMENTS:
        raise _err(path, line, f"{key}: {name} must be a positive integer, got {text[:40]!r}", key)
    return int(text)


def _opencv_matrix(path: Path, e: _Entry) -> np.ndarray:
    """The matrix of a ``!!opencv-matrix`` entry: shape (rows, cols), or (rows, cols, channels)."""
    fields: dict[str, tuple[int, str]] = {}
    for no, content in e.more:
        m = _KEY.match(content)
        if not m or m.group(1) not in _MATRIX_FIELDS:
            raise _err(path, no, f"{e.key}: expected one of rows, cols, dt, data, got {content[:40]!r}", e.key)
        if m.group(1) in fields:
            raise _err(path, no, f"{e.key}: {m.group(1)} given twice", e.key)
        fields[m.group(1)] = (no, (m.group(2) or "").strip())
    missing = [f for f in _MATRIX_FIELDS if f not in fields]
    if missing:
        raise _err(path, e.line, f"{e.key}: the matrix lacks {', '.join(missing)}", e.key)
    rows, cols = _count(path, e.key, fields, "rows"), _count(path, e.key, fields, "cols")
    dt_line, dt = fields["dt"]
    dt_match = _DT.match(dt.strip("\"'"))
    if not dt_match or int(dt_match.group(1) or 1) not in range(1, 5):
        raise _err(path, dt_line, f"{e.key}: dt must be a number type such as d or f, got {dt[:20]!r}", e.key)
    channels = int(dt_match.group(1) or 1)
    data_line, data = fields["data"]
    values = _numbers(path, data_line, e.key, data)
    if len(values) != rows * cols * channels:
        raise _err(path, data_line, f"{e.key}: data holds {len(values)} values, rows x cols x channels = "
                                    f"{rows} x {cols} x {channels}", e.key)
    shape = (rows, cols) if channels == 1 else (rows, cols, channels)
    return np.array(values, dtype=float).reshape(shape)


def _matrix(path: Path, entries: dict, key: str, required: bool = True) -> np.ndarray | None:
    """The finite matrix (or flow list of numbers) under ``key``; None when absent and not required."""
    e = entries.get(key)
    if e is None:
        if required:
            raise _err(path, None, f"missing key {key!r}", key)
        return None
    if e.text == _MATRIX_TAG:
        m = _opencv_matrix(path, e)
    elif e.text.startswith("[") and not e.more:
        m = np.array(_numbers(path, e.line, key, e.text), dtype=float)
    else:
        raise _err(path, e.line, f"{key}: not a matrix (expected {_MATRIX_TAG} with rows, cols, dt, data)", key)
    if not np.isfinite(m).all():
        raise _err(path, e.line, f"{key}: holds non-finite values", key)
    return m


def _scalar(path: Path, entries: dict, key: str, required: bool = True) -> float | None:
    """The finite number under ``key``; None when absent and not required."""
    e = entries.get(key)
    if e is None:
        if required:
            raise _err(path, None, f"missing key {key!r}", key)
        return None
    if e.more or not e.text:
        raise _err(path, e.line, f"{key}: must be a number on its line", key)
    v = _number(path, e.line, key, e.text)
    if not math.isfinite(v):
        raise _err(path, e.line, f"{key}: must be a finite number, got {e.text[:40]!r}", key)
    return v


def _line(entries: dict, key: str) -> int | None:
    return entries[key].line if key in entries else None


def _camera_from_entries(path: Path, entries: dict) -> CameraModel:
    K = _matrix(path, entries, "camera_matrix")
    if K.shape != (3, 3):
        raise _err(path, _line(entries, "camera_matrix"), f"camera_matrix must be 3x3, got {K.shape}",
                   "camera_matrix")
    d = _matrix(path, entries, "distortion_coefficients").ravel()
    if d.size not in DIST_LENGTHS:
        raise _err(path, _line(entries, "distortion_coefficients"), "distortion_coefficients must hold 4, 5, "
                   f"8, 12 or 14 values, got {d.size}", "distortion_coefficients")
    w, h = _scalar(path, entries, "image_width"), _scalar(path, entries, "image_height")
    if not (0 < w <= 1e6 and 0 < h <= 1e6) or w != int(w) or h != int(h):
        raise _err(path, _line(entries, "image_width"), "image_width/image_height must be positive integers "
                   f"up to 1e6, got {w:g}, {h:g}", "image_width")
    rms = _scalar(path, entries, "avg_reprojection_error", required=False)
    rv = _matrix(path, entries, "plane_rvec", required=False)
    tv = _matrix(path, entries, "plane_tvec", required=False)
    if (rv is None) != (tv is None):
        raise _err(path, _line(entries, "plane_rvec") or _line(entries, "plane_tvec"),
                   "plane_rvec and plane_tvec must be given together")
    if rv is not None and (rv.size != 3 or tv.size != 3):
        bad = "plane_rvec" if rv.size != 3 else "plane_tvec"
        raise _err(path, _line(entries, bad), f"{bad}: must be 3x1, got {rv.size if rv.size != 3 else tv.size} "
                   "values", bad)
    std = _matrix(path, entries, "intrinsics_std_dev", required=False)
    pve = _matrix(path, entries, "per_view_reprojection_errors", required=False)
    prms = _scalar(path, entries, "plane_reprojection_error", required=False)
    try:
        return CameraModel(K, d, (int(w), int(h)),
                           plane_rvec=None if rv is None else rv.ravel(),
                           plane_tvec=None if tv is None else tv.ravel() * MM,
                           rms=math.nan if rms is None or rms < 0 else float(rms),
                           std_intrinsics=None if std is None else std.ravel(),
                           per_view_errors=None if pve is None else pve.ravel(),
                           plane_rms=math.nan if prms is None else float(prms))
    except ValueError as exc:
        raise _err(path, None, str(exc)) from None


def read_camera(path) -> CameraModel:
    """Read a camera file written by :func:`write_camera`, by ``cv2.FileStorage`` or by OpenCV's
    calibration sample (the keys of docs/data-formats.md; other keys are ignored).

    The file is parsed in Python (the FileStorage YAML subset above), never
    by ``cv2.FileStorage``, whose parser can abort the process on a damaged
    file. A negative ``avg_reprojection_error`` (a camera not calibrated
    from views) is read as NaN.

    Raises
    ------
    InputFileNotFoundError
        The file does not exist (also a ``FileNotFoundError``).
    InputFileError
        A folder, an unreadable file, not UTF-8, not a FileStorage YAML file,
        or a key missing or malformed (the message names the file, the line
        and the key).
    """
    path = Path(path)
    try:
        data = read_input_bytes(path, what="camera file")
    except InputFileNotFoundError:
        raise InputFileNotFoundError(f"camera file not found: {path}", path=path) from None
    return _camera_from_entries(path, _parse_entries(path, decode_text(path, data)))
