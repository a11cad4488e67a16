"""The CSV core: validated tables, their columns, and the problems collector.

Readers validate everything and raise :class:`~notchfit.io.errors.InputFileError`
(a ``ValueError``) with a one-line message that names the file, the line and
the problem (``samples.csv: line 7: time_s 12.0 is not after 15.0 (line 6);
samples must be in time order``); they never guess. Several problems of one
file are reported together on that line (:class:`Problems`). Numbers must be
finite and of a plausible magnitude (:data:`MAX_ABS`); integers fit in 64
bits. A decimal comma or a semicolon separator gets a hint. Column layouts are
those of docs/data-formats.md.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputFileError, decode_text, read_input_bytes

__all__ = [
    "DETECTION_COLUMNS",
    "FITS_COLUMNS",
    "POINTWISE_COLUMNS",
    "MAX_ABS",
    "UNIT_LIMITS",
    "POINT_COLUMNS",
    "Problems",
    "SAMPLE_COLUMNS",
    "SIMULATION_COLUMNS",
    "check_point_rows",
    "column_limit",
    "parse_float",
    "parse_int",
    "read_csv_table",
]

SAMPLE_COLUMNS = ("sample", "time_s", "tension_left_N", "tension_right_N",
                  "displacement_left_mm", "displacement_right_mm")
POINT_COLUMNS = ("sample", "point", "x_mm", "y_mm")
DETECTION_COLUMNS = ("sample", "point", "x_mm", "y_mm", "u_px", "v_px", "sigma_mm", "status")
FITS_COLUMNS = ("sample", "model", "a", "b", "base_x_mm", "base_y_mm", "base_phi_rad", "rms_mm", "max_mm",
                "n_points")
POINTWISE_COLUMNS = ("sample", "model", "point", "err_mm")
SIMULATION_COLUMNS = ("sample", "regime", "a", "b")

#: Largest magnitude of any number in a table: beyond it a float no longer resolves a
#: unit's tenth, and the value is a corrupted cell, not a measurement.
MAX_ABS = 1e15
#: Physical bounds by unit suffix (file units): 1 km in mm, 1 MN, 10 Mpx. A larger value is
#: a unit slip or a corrupted cell; it would make the fits and the simulator overflow.
UNIT_LIMITS = {"_mm": 1e6, "_N": 1e6, "_px": 1e7}
_INT64_MAX = 2 ** 63 - 1
_DECIMAL_COMMA = re.compile(r"[-+]?\d+,\d+")


class Problems:
    """Collects the problems found in one file and raises them together.

    Parameters
    ----------
    path : path
        The file, named at the start of the message.
    error : type
        The exception raised (an :class:`~notchfit.io.errors.InputFileError` subclass).
    max_shown : int
        Problems listed before "... and N more".
    """

    def __init__(self, path, *, error: type = InputFileError, max_shown: int = 12):
        self.path = Path(path)
        self.error = error
        self.max_shown = max_shown
        self.items: list[str] = []

        self.first_line: int | None = None

    def add(self, line: int | None, text: str) -> None:
        """Record ``text`` at file line ``line`` (None: the file as a whole)."""
        self.items.append(f"line {line}: {text}" if line is not None else text)
        if self.first_line is None:
            self.first_line = line

    def raise_if_any(self) -> None:
        """Raise ``error`` naming the file and every problem recorded (one line), if there is one."""
        if not self.items:
            return
        shown = self.items[:self.max_shown]
        more = len(self.items) - len(shown)
        if len(shown) == 1:
            msg = f"{self.path}: {shown[0]}"
        else:
            msg = f"{self.path}: {len(self.items)} problems: " + "; ".join(shown)
            if more:
                msg += f"; ... and {more} more"
        raise self.error(msg, path=self.path, line=self.first_line)


def _read_csv_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and ``(line number, fields)`` for every non-blank data row."""
    path = Path(path)
    text = decode_text(path, read_input_bytes(path, what="CSV file"))
    reader = csv.reader(io.StringIO(text, newline=""))
    header, rows, header_line = None, [], 1
    try:
        for fields in reader:
            if not fields or all(not f.strip() for f in fields):
                continue
            if header is None:
                header = [f.strip() for f in fields]
                header_line = reader.line_num
                continue
            rows.append((reader.line_num, [f.strip() for f in fields]))
    except csv.Error as exc:
        raise InputFileError(f"{path}: line {reader.line_num}: malformed CSV ({exc})", path=path,
                             line=reader.line_num) from None
    if header is None:
        raise InputFileError(f"{path}: empty file (expected a header row)", path=path)
    probs = Problems(path)
    if len(header) == 1 and ";" in header[0]:
        probs.add(header_line, "the columns are separated by ';': notchfit reads comma-separated values "
                               "with '.' as the decimal point")
        probs.raise_if_any()
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        probs.add(header_line, f"duplicate column(s) {', '.join(dup)}")
    for line, fields in rows:
        if len(fields) != len(header):
            hint = (" (a decimal comma? use '.' as the decimal point)" if len(fields) > len(header) else "")
            probs.add(line, f"{len(fields)} fields, the header has {len(header)}{hint}")
    probs.raise_if_any()
    return header, rows


def parse_float(text: str, *, allow_empty: bool, allow_nan: bool, limit: float = MAX_ABS) -> float:
    """A float from a CSV cell (``""`` is NaN when ``allow_empty``); raises ValueError saying why not.

    A value whose magnitude exceeds ``limit`` is out of range (not a measurement).
    """
    if text == "":
        if allow_empty:
            return math.nan
        raise ValueError("empty value")
    try:
        v = float(text)
    except ValueError:
        hint = " (a decimal comma? use '.' as the decimal point)" if _DECIMAL_COMMA.fullmatch(text) else ""
        raise ValueError(f"non-numeric value {_short(text)}{hint}") from None
    if math.isnan(v) and not allow_nan:
        raise ValueError(f"value {text!r} is not a number")
    if math.isinf(v):
        raise ValueError(f"value {_short(text)} is not finite")
    if abs(v) > limit:
        raise ValueError(f"value {_short(text)} is out of range (magnitude above {limit:g})")
    return v


def _short(text: str, limit: int = 40) -> str:
    """``repr`` of a cell, cut to ``limit`` characters (a corrupted cell can be a whole line)."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + "..."


def parse_int(text: str) -> int:
    """An integer from a CSV cell (``"3.0"`` is accepted); raises ValueError saying why not."""
    if text == "":
        raise ValueError("empty value (expected an integer)")
    try:
        v = int(text) if len(text) <= 40 else None
    except ValueError:
        try:
            f = float(text)
        except ValueError:
            raise ValueError(f"non-numeric value {_short(text)} (expected an integer)") from None
        if not f.is_integer():
            raise ValueError(f"value {_short(text)} is not an integer") from None
        v = int(f)
    if v is None or abs(v) > _INT64_MAX:
        raise ValueError(f"value {_short(text)} is out of range (integers up to {_INT64_MAX})")
    return v


def column_limit(name: str) -> float:
    """The largest magnitude column ``name`` may hold: :data:`UNIT_LIMITS` by unit suffix, else :data:`MAX_ABS`."""
    return next((v for suffix, v in UNIT_LIMITS.items() if name.endswith(suffix)), MAX_ABS)


def _parse_cell(h: str, s: str, integer, numeric, optional_numeric, nan_ok):
    if h in integer:
        return parse_int(s)
    if h in numeric:
        return parse_float(s, allow_empty=False, allow_nan=False, limit=column_limit(h))
    if h in optional_numeric:
        return parse_float(s, allow_empty=True, allow_nan=False, limit=column_limit(h))
    if h in nan_ok:
        return parse_float(s, allow_empty=True, allow_nan=True, limit=column_limit(h))
    return s


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
    probs = Problems(path)
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
            try:
                v = _parse_cell(h, fields[i], integer, numeric, optional_numeric, nan_ok)
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
        return pd.Series([parse_float(v, allow_empty=True, allow_nan=True) for v in values],
                         dtype="float64")
    except ValueError:
        return pd.Series(values, dtype="str")


def check_point_rows(path, df: pd.DataFrame, lines, n_points: int | None, sample_ids) -> None:
    """Check a ``sample, point, ...`` table (notch_points.csv, detections.csv).

    Point ids in ``1..n_points`` (when given), samples among ``sample_ids``
    (when given), no (sample, point) twice; every problem with its line.
    """
    probs = Problems(path)
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
