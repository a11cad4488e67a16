"""The CSV core: validated tables, their columns, and the problems collector.

Readers validate everything and raise :class:`ValueError` with a message that
names the file, the line and the problem (``samples.csv: line 7: time_s 12.0
is not after 15.0 (line 6); samples must be in time order``); they never
guess. Several problems of one file are reported together
(:class:`Problems`). Column layouts are those of docs/data-formats.md.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = [
    "DETECTION_COLUMNS",
    "FITS_COLUMNS",
    "POINTWISE_COLUMNS",
    "POINT_COLUMNS",
    "Problems",
    "SAMPLE_COLUMNS",
    "SIMULATION_COLUMNS",
    "check_point_rows",
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


class Problems:
    """Collects the problems found in one file and raises them together.

    Parameters
    ----------
    path : path
        The file, named at the start of the message.
    error : type
        The exception raised (a ``ValueError`` subclass).
    max_shown : int
        Problems listed before "... and N more".
    """

    def __init__(self, path, *, error: type = ValueError, max_shown: int = 12):
        self.path = Path(path)
        self.error = error
        self.max_shown = max_shown
        self.items: list[str] = []

    def add(self, line: int | None, text: str) -> None:
        """Record ``text`` at file line ``line`` (None: the file as a whole)."""
        self.items.append(f"line {line}: {text}" if line is not None else text)

    def raise_if_any(self) -> None:
        """Raise ``error`` naming the file and every problem recorded, if there is one."""
        if not self.items:
            return
        shown = self.items[:self.max_shown]
        more = len(self.items) - len(shown)
        if len(shown) == 1:
            msg = f"{self.path}: {shown[0]}"
        else:
            msg = f"{self.path}: {len(self.items)} problems:\n  " + "\n  ".join(shown)
            if more:
                msg += f"\n  ... and {more} more"
        raise self.error(msg)


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
    probs = Problems(path)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        probs.add(header_line, f"duplicate column(s) {', '.join(dup)}")
    for line, fields in rows:
        if len(fields) != len(header):
            probs.add(line, f"{len(fields)} fields, the header has {len(header)}")
    probs.raise_if_any()
    return header, rows


def parse_float(text: str, *, allow_empty: bool, allow_nan: bool) -> float:
    """A float from a CSV cell (``""`` is NaN when ``allow_empty``); raises ValueError saying why not."""
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


def parse_int(text: str) -> int:
    """An integer from a CSV cell (``"3.0"`` is accepted); raises ValueError saying why not."""
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


def _parse_cell(h: str, s: str, integer, numeric, optional_numeric, nan_ok):
    if h in integer:
        return parse_int(s)
    if h in numeric:
        return parse_float(s, allow_empty=False, allow_nan=False)
    if h in optional_numeric:
        return parse_float(s, allow_empty=True, allow_nan=False)
    if h in nan_ok:
        return parse_float(s, allow_empty=True, allow_nan=True)
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
