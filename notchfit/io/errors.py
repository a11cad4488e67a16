"""The one error type of the readers, and the checks every reader makes before parsing.

Every reader of :mod:`notchfit.io` reports a problem with an input file as an
:class:`InputFileError` (a ``ValueError``): its message is one line that
names the file and, where they are known, the line, the column or the key,
then the problem (``study/L045/samples.csv: line 7: column sample: value
'1e30' is out of range``). The command line prints that line and exits with
code 2 (docs/reliability.md). The attributes carry the same facts for a
program.

A file that does not exist is an :class:`InputFileNotFoundError`, both an
``InputFileError`` and a ``FileNotFoundError``. :func:`read_input_bytes` and
:func:`decode_text` are the checks every reader makes first: a folder where a
file is expected, a file that cannot be read (permissions), text that is not
UTF-8 (a Latin-1 export), a byte-order mark.
"""

from __future__ import annotations

import errno
from pathlib import Path

__all__ = ["InputFileError", "InputFileNotFoundError", "decode_text", "located", "read_input_bytes"]


def located(path, line: int | None, problem: str, *, column: int | None = None) -> str:
    """``"<path>: line <line>[, column <c>]: <problem>"``, or ``"<path>: <problem>"`` without a line."""
    if line is None:
        return f"{path}: {problem}"
    col = f", column {column}" if column is not None else ""
    return f"{path}: line {line}{col}: {problem}"


def _rebuild(cls, args, attrs):
    exc = cls(*args)
    exc.__dict__.update(attrs)
    return exc


class InputFileError(ValueError):
    """A problem with an input file: the message names the file (and line/column/key) and the problem.

    Parameters
    ----------
    message : str
        The whole one-line message (already naming the file).
    path, line, column, key : optional
        The same facts for a program (None where not known).
    """

    def __init__(self, message: str = "", *, path=None, line: int | None = None, column: int | None = None,
                 key: str | None = None):
        super().__init__(message)
        self.path = None if path is None else Path(path)
        self.line = line
        self.column = column
        self.key = key

    def __reduce__(self):
        # keeps the attributes when the error crosses a process boundary (run_batch workers)
        return _rebuild, (type(self), self.args, dict(self.__dict__))


class InputFileNotFoundError(InputFileError, FileNotFoundError):
    """An input file that does not exist (both an :class:`InputFileError` and a ``FileNotFoundError``)."""


def read_input_bytes(path, *, what: str = "file") -> bytes:
    """The bytes of input file ``path``, or an :class:`InputFileError` saying why they cannot be read.

    Parameters
    ----------
    path : path
    what : str
        What the file is, for the messages (``"geometry file"``).

    Raises
    ------
    InputFileNotFoundError
        ``"<path>: <what> not found"``.
    InputFileError
        A folder given where a file is expected, no permission to read it,
        or another operating-system error (with its reason).
    """
    path = Path(path)
    try:
        if path.is_dir():
            raise InputFileError(f"{path}: is a folder, not a file (expected the {what})", path=path)
        if not path.exists():
            raise InputFileNotFoundError(f"{path}: {what} not found", path=path)
        return path.read_bytes()
    except InputFileError:
        raise
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read the {what}: {_os_reason(exc)}", path=path) from None


def _os_reason(exc: OSError) -> str:
    if isinstance(exc, PermissionError):
        return "permission denied"
    if exc.errno is not None and exc.errno in errno.errorcode:
        return exc.strerror or errno.errorcode[exc.errno]
    return str(exc)


def decode_text(path, data: bytes) -> str:
    """UTF-8 text of a file's bytes (a leading byte-order mark is dropped).

    Raises
    ------
    InputFileError
        Naming the line and column of the first byte that is not UTF-8, with
        the hint that the file was probably saved in a legacy encoding.
    """
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise InputFileError(located(path, line, f"byte 0x{data[exc.start]:02x} is not UTF-8 text; save the "
                                                 "file as UTF-8 (it looks like Latin-1 or another legacy "
                                                 "encoding)", column=column),
                             path=path, line=line, column=column) from None
