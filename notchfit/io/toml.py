"""TOML files: the one loader, whose errors name the file and the line, and a writer.

Every TOML file notchfit reads (``experiment.toml``, geometry files,
friction-model parameter files, board definitions, synthetic-study recipes,
reference values; docs/data-formats.md) goes through :func:`load_toml`.
A problem is reported as ``<file>: line <n>: <problem>``, or
``<file>: <problem>`` when no line applies (a missing key), always as a
:class:`TomlError` (an :class:`~notchfit.io.errors.InputFileError`, so a
``ValueError``) — the same form the CSV readers use. A folder, an unreadable
file, text that is not UTF-8 and nesting too deep to parse are TomlErrors too.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputFileError, InputFileNotFoundError, decode_text, located, read_input_bytes

__all__ = ["TomlError", "TomlFile", "TomlFileNotFoundError", "load_toml", "located", "toml_dumps"]


class TomlError(InputFileError):
    """A problem in a TOML file; the message names the file and, where known, the line."""


class TomlFileNotFoundError(TomlError, InputFileNotFoundError):
    """A TOML file that does not exist (both a :class:`TomlError` and a ``FileNotFoundError``)."""


@dataclass(frozen=True)
class TomlFile:
    """A parsed TOML file and its text (to find the line a key is written on).

    Attributes
    ----------
    path : Path
    data : dict
        What :mod:`tomllib` parsed.
    text : str
        The file's text.
    """

    path: Path
    data: dict
    text: str

    def line_of(self, *keys: str) -> int | None:
        """The line (1-based) where the key path ``keys`` is written, or None.

        ``line_of("mirror")`` finds a top-level key, ``line_of("uncertainty",
        "point_mm")`` a key of the ``[uncertainty]`` table (or a dotted key),
        ``line_of("uncertainty")`` the table's header.
        """
        return _key_line(self.text, tuple(str(k) for k in keys))

    def error(self, problem: str, *keys: str) -> TomlError:
        """A :class:`TomlError` for ``problem``, at the line of ``keys`` when it is found."""
        line = self.line_of(*keys) if keys else None
        return TomlError(located(self.path, line, problem), path=self.path, line=line,
                         key=".".join(str(k) for k in keys) or None)

    def locate(self, message: str) -> TomlError:
        """A :class:`TomlError` for a checker's ``message``, at the line of the key it names.

        ``message`` is ``"<path>: <problem>"`` or a bare problem, from code that
        checks the parsed values and knows no lines (``"slot_depth must be
        smaller than the tube diameter"``). The key is the top-level key of the
        file named earliest in the problem, as written or without its unit
        suffix (``slot_depth_mm`` is named by ``slot_depth``); a message that
        already names a line is kept as it is.
        """
        prefix = f"{self.path}: "
        problem = message[len(prefix):] if message.startswith(prefix) else message
        if problem.startswith("line "):
            return TomlError(located(self.path, None, problem), path=self.path)
        best = None
        for key in self.data:
            for name in {str(key), _UNIT_SUFFIX.sub("", str(key))}:
                m = re.search(rf"(?<![\w.]){re.escape(name)}(?!\w)", problem)
                if m and (best is None or m.start() < best[0]):
                    best = (m.start(), key)
        return self.error(problem, best[1]) if best else TomlError(located(self.path, None, problem),
                                                                      path=self.path)


#: Unit suffixes of file keys (docs/data-formats.md): ``p_mm`` is the field ``p`` in mm.
_UNIT_SUFFIX = re.compile(r"_(?:mm|rad|deg|N|Pa|s|Nm|Nm_per_rad|Nms_per_rad|m_per_s)$")


def load_toml(path, *, what: str = "file") -> TomlFile:
    """Read and parse a TOML file.

    Parameters
    ----------
    path : str or path
    what : str
        What the file is, for the not-found message (``"geometry file"``).

    Returns
    -------
    TomlFile

    Raises
    ------
    TomlFileNotFoundError
        ``"<path>: <what> not found"``.
    TomlError
        ``"<path>: line <n>: bad TOML: ..."`` for a syntax error; a folder,
        an unreadable file, text that is not UTF-8 (a byte-order mark is
        accepted), nesting too deep.
    """
    path = Path(path)
    try:
        text = decode_text(path, read_input_bytes(path, what=what))
    except InputFileNotFoundError as exc:
        raise TomlFileNotFoundError(str(exc), path=path) from None
    except InputFileError as exc:
        raise TomlError(str(exc), path=path, line=exc.line, column=exc.column) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise _syntax_error(path, str(exc), text) from None
    except RecursionError:
        raise TomlError(located(path, None, "bad TOML: arrays or tables nested too deeply"),
                        path=path) from None
    return TomlFile(path=path, data=data, text=text)


def _syntax_error(path: Path, msg: str, text: str = "") -> TomlError:
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", msg)
    if m is None:
        return TomlError(located(path, None, f"bad TOML: {msg}; the file is not valid TOML"), path=path)
    reason, line, column = msg[:m.start()], int(m.group(1)), int(m.group(2))
    lines = text.splitlines()
    row = lines[line - 1] if 0 < line <= len(lines) else ""
    hint = ""
    if re.match(r"\d,\d", row[column - 2:column + 1]):
        hint = " (a decimal comma? TOML numbers are written with a point: 1.5, not 1,5)"
    return TomlError(located(path, line, f"bad TOML: {reason} at column {column}{hint}; the file is not valid "
                                         "TOML"), path=path, line=line, column=column)


# ----------------------------------------------------------------------------- key lines
_BARE_OR_QUOTED = re.compile(r'"(?:[^"\\]|\\.)*"|\'[^\']*\'|[A-Za-z0-9_-]+')
_HEADER = re.compile(r"^\s*\[\[?([^\[\]]+)\]\]?\s*(?:#.*)?$")
_ASSIGN = re.compile(r'^\s*((?:"(?:[^"\\]|\\.)*"|\'[^\']*\'|[A-Za-z0-9_.\s-])+?)\s*=')


def _dotted(name: str) -> tuple[str, ...]:
    parts = []
    for tok in _BARE_OR_QUOTED.findall(name):
        try:
            parts.append(json.loads(tok) if tok.startswith('"') else tok.strip("'"))
        except ValueError:      # an escape JSON does not know: only the line lookup is affected
            parts.append(tok.strip('"'))
    return tuple(parts)


def _key_line(text: str, keys: tuple[str, ...]) -> int | None:
    table: tuple[str, ...] = ()
    for number, line in enumerate(text.splitlines(), start=1):
        header = _HEADER.match(line)
        if header:
            table = _dotted(header.group(1))
            if table == keys:
                return number
            continue
        assign = _ASSIGN.match(line)
        if assign and table + _dotted(assign.group(1)) == keys:
            return number
    return None


# ----------------------------------------------------------------------------- writer
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


def _key(k) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


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
