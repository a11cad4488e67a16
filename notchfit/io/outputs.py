"""Output files: the atomic writers, the output-run transaction, and the readers of outputs.

Writers are atomic: a file is written to a temporary file in the same folder
(with the permissions a plain write would give) and moved into place with
:func:`os.replace`, so a reader never sees half a file. A command writes a
whole run through :class:`OutputRun`: every output is first written into a
hidden staging folder inside ``--out`` and moved into place only once the
run has succeeded, so a crash or an error mid-way leaves the previous
results untouched. Ctrl-C or SIGTERM during the final moves is held until
they are done (:func:`~notchfit.io.interrupts.deferred_interrupts`), so the
results are either all old or all new; only a hard crash (SIGKILL, power)
during that loop of renames can leave a mix of old and new files, each still
whole. An existing output is never replaced without ``force``.

Only one run writes into a folder at a time: :class:`OutputRun` holds the
lock file ``.notchfit-lock`` (created with ``O_EXCL``, holding the pid and
host) from start to end; a second run into the same ``--out`` fails with
:class:`OutputLockedError` (a ``FileExistsError``: exit code 2). A lock
left by a process that no longer runs is removed.

Layout of outputs: a command given one experiment writes into ``DIR``; given a
study it writes the per-experiment tables into ``DIR/<experiment name>/`` and
study-wide files (``diagnosis.json``, ``report.html``) into ``DIR``
(:func:`experiment_output_dir`). The files are described in
docs/data-formats.md.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
import re
import shutil
import socket
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .._version import __version__
from .errors import InputFileError, InputFileNotFoundError, decode_text, read_input_bytes
from .interrupts import deferred_interrupts
from .tables import (DETECTION_COLUMNS, FITS_COLUMNS, POINTWISE_COLUMNS, SIMULATION_COLUMNS,
                     check_point_rows, read_csv_table)

__all__ = [
    "LOCK_NAME",
    "OutputLockedError",
    "OutputRun",
    "STAGE_PREFIX",
    "atomic_write",
    "existing_outputs",
    "experiment_output_dir",
    "find_output",
    "live_lock_holder",
    "prepare_output_dir",
    "provenance",
    "read_detections",
    "read_diagnosis",
    "read_fits",
    "read_json",
    "read_pointwise",
    "read_simulation",
    "write_json_atomic",
    "write_table_atomic",
    "write_text_atomic",
]

STAGE_PREFIX = ".notchfit-stage-"
LOCK_NAME = ".notchfit-lock"
_DIAG_KEYS = ("experiments", "baseline", "discrepancies", "candidates", "cause", "explanation", "gain")


# ----------------------------------------------------------------------------- atomic writers
def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _tmp_path(path: Path, suffix: str = ".tmp") -> Path:
    """A temporary file beside ``path``, with the permissions a plain write would give
    (mkstemp creates 0600 files; outputs such as report.html are meant to be shared)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.fchmod(fd, 0o666 & ~_umask())
    os.close(fd)
    return Path(tmp)


def atomic_write(path, writer, *, suffix: str = ".tmp", make_folder: bool = True) -> Path:
    """Write ``path`` atomically: ``writer(tmp)`` fills a temporary file that then replaces ``path``.

    Parameters
    ----------
    path : path
        The file to write (its folder is created, unless ``make_folder`` is false).
    writer : callable
        ``writer(tmp_path)`` writes the whole content to ``tmp_path``.
    suffix : str
        Ending of the temporary file's name (for writers that choose the
        format by extension, e.g. ``".tmp.yml"``).
    make_folder : bool
        Create the file's folder when absent. False for a worker writing into a
        run's staging folder: after an interrupt the run removes that folder, and
        a task still running must fail instead of bringing it back.

    Returns
    -------
    Path
        ``path``; on any exception the temporary file is removed and an old
        ``path`` is left as it was.
    """
    path = Path(path)
    if make_folder:
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_path(path, suffix)
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
    return atomic_write(path, w)


def write_text_atomic(text: str, path) -> Path:
    """Write a UTF-8 text file atomically."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


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


def write_json_atomic(obj, path) -> Path:
    """Write JSON (indented, numpy-aware, NaN written as null) atomically."""
    text = json.dumps(_nan_to_none(obj), indent=2, default=_json_default, allow_nan=False) + "\n"
    return write_text_atomic(text, path)


# ----------------------------------------------------------------------------- output folders
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


def provenance(command: str, input_path, **extra) -> dict:
    """The ``<command>_run.json`` record: what ran on which input (the report finds the study here)."""
    return {"command": command, "input": str(Path(input_path).resolve()), "notchfit": __version__,
            "python": sys.version.split()[0],
            "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), **extra}


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
    clash = existing_outputs(path, outputs)
    if clash:
        shown = ", ".join(clash[:5]) + (" ..." if len(clash) > 5 else "")
        raise FileExistsError(f"{path}: already holds outputs ({shown}); use --force to replace them "
                              "or choose another --out")
    return path


def existing_outputs(path, outputs=None) -> list[str]:
    """The outputs already in folder ``path``, sorted (none when the folder does not exist).

    ``outputs`` as :func:`prepare_output_dir` takes it: the relative paths a
    command writes, or None for any visible entry of the folder.
    """
    path = Path(path)
    if not path.is_dir():
        return []
    if outputs is None:
        return sorted(p.name for p in path.iterdir() if not p.name.startswith("."))
    return sorted(str(o) for o in outputs if (path / o).exists())


class OutputLockedError(FileExistsError):
    """Another live notchfit run is writing into the output folder."""


def _lock_holder(lock: Path) -> tuple[int, str] | None:
    """``(pid, host)`` written in a lock file; None when unreadable or being written."""
    try:
        pid, host = lock.read_text(encoding="utf-8").split()[:2]
        return int(pid), host
    except (OSError, ValueError):
        return None


def _lock_is_stale(lock: Path, *, grace_s: float = 10.0) -> bool:
    holder = _lock_holder(lock)
    if holder is None:       # empty: created a moment ago, or its writer died before writing
        try:
            return time.time() - lock.stat().st_mtime > grace_s
        except OSError:
            return True
    pid, host = holder
    return host == socket.gethostname() and not _pid_alive(pid)


def live_lock_holder(out_dir) -> str | None:
    """Who is writing into ``out_dir`` now (``"pid N on HOST"``), or None when its lock is free or stale."""
    lock = Path(out_dir) / LOCK_NAME
    if not lock.exists() or _lock_is_stale(lock):
        return None
    holder = _lock_holder(lock)
    return f"pid {holder[0]} on {holder[1]}" if holder else "a process starting up"


def acquire_output_lock(out_dir: Path) -> Path:
    """Create ``out_dir/.notchfit-lock`` exclusively (removing a stale one); returns its path.

    Raises
    ------
    OutputLockedError
        A live process holds the lock (the message names its pid).
    """
    lock = Path(out_dir) / LOCK_NAME
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            who = live_lock_holder(out_dir)
            if who is None:
                lock.unlink(missing_ok=True)
                continue
            raise OutputLockedError(f"{out_dir}: another notchfit run ({who}) is writing into this folder; "
                                    f"wait for it to finish or choose another --out (a stale lock is "
                                    f"{lock})") from None
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(f"{os.getpid()} {socket.gethostname()}\n")
        return lock
    raise OutputLockedError(f"{out_dir}: could not take the lock {lock}")


def _make_folders(path: Path) -> list[Path]:
    """Create folder ``path`` and its missing parents; returns those created, deepest first."""
    made = [p for p in [path, *path.parents] if not p.exists()]
    path.mkdir(parents=True, exist_ok=True)
    return made


def _release_lock(lock: Path | None) -> None:
    if lock is not None and _lock_holder(lock) == (os.getpid(), socket.gethostname()):
        lock.unlink(missing_ok=True)


class OutputRun:
    """Write a command's outputs into a staging folder, then move them into place.

    Use as a context manager::

        with OutputRun(out_dir, outputs=["fits.csv"], force=args.force) as run:
            write_table_atomic(df, run.path("fits.csv"))

    Nothing in ``out_dir`` changes until the block ends without an exception;
    then every staged file replaces its counterpart (``os.replace``, atomic
    per file). On an exception the staging folder is removed and the old
    results stay as they were; an output folder the run created is removed
    again when nothing is in it (a failed command leaves nothing behind).

    With ``whole_dirs=True`` each top-level folder of the run replaces its old
    counterpart as a whole (two renames), so no stale file of an earlier run
    survives inside it (``synth --force`` replacing an experiment folder).
    """

    def __init__(self, out_dir, *, outputs=None, force: bool = False, name: str = "run",
                 whole_dirs: bool = False):
        out = Path(out_dir)
        if out.exists() and not out.is_dir():
            raise FileExistsError(f"{out}: exists and is not a folder")
        self.out_dir = out
        self.force = force
        self.whole_dirs = whole_dirs
        self.committed: list[Path] = []
        self.lock: Path | None = None
        self._made = _make_folders(out)
        try:
            self.lock = acquire_output_lock(out)
            self._open(name, outputs)
        except BaseException:
            self._release()
            raise

    def _open(self, name: str, outputs) -> None:
        """Check the folder for outputs this run would replace, and make the staging folder."""
        prepare_output_dir(self.out_dir, force=self.force, outputs=outputs)
        self.stage = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{name}-{os.getpid()}-", dir=self.out_dir))

    def _release(self) -> None:
        """Release the folder's lock; remove the folders this run created if they stayed empty."""
        _release_lock(self.lock)
        self.lock = None
        for d in self._made:                 # deepest first
            try:
                d.rmdir()
            except OSError:
                break

    def path(self, rel) -> Path:
        """The staging path of output ``rel`` (parent folders created)."""
        p = self.stage / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def commit(self) -> list[Path]:
        """Move every staged output into ``out_dir``; returns the paths written.

        Ctrl-C and SIGTERM wait until every move is done (the results are all
        old or all new).
        """
        with deferred_interrupts():
            return self._commit()

    def _commit(self) -> list[Path]:
        files = sorted(p for p in self.stage.rglob("*") if p.is_file())
        if not self.force:
            clash = [str(p.relative_to(self.stage)) for p in files
                     if (self.out_dir / p.relative_to(self.stage)).exists()]
            if clash:
                raise FileExistsError(f"{self.out_dir}: already holds {', '.join(clash[:5])}; "
                                      "use --force to replace")
        if self.whole_dirs:
            self._replace_dirs()
            files = [p for p in files if p.exists()]
        for p in files:
            dest = self.out_dir / p.relative_to(self.stage)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(p, dest)
            self.committed.append(dest)
        shutil.rmtree(self.stage, ignore_errors=True)
        return self.committed

    def _replace_dirs(self) -> None:
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

    def abort(self) -> None:
        """Remove the staging folder (nothing in ``out_dir`` changes) and release the folder's lock;
        a folder this run created is removed again when it holds nothing."""
        with deferred_interrupts():
            shutil.rmtree(self.stage, ignore_errors=True)
            self._release()

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


# ----------------------------------------------------------------------------- readers of outputs
def read_detections(path, *, n_points: int | None = None, sample_ids=None) -> pd.DataFrame:
    """Read ``detections.csv`` (``detect``): sample,point,x_mm,y_mm,u_px,v_px,sigma_mm,status."""
    path = Path(path)
    df, lines = read_csv_table(path, required=DETECTION_COLUMNS, integer=("sample", "point"),
                               nan_ok=("x_mm", "y_mm", "u_px", "v_px", "sigma_mm"), text=("status",))
    check_point_rows(path, df, lines, n_points, sample_ids)
    return df


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
    """Read a JSON file; every problem is an :class:`InputFileError` (a syntax error names the line)."""
    path = Path(path)
    try:
        text = decode_text(path, read_input_bytes(path, what="JSON file"))
    except InputFileNotFoundError:
        raise InputFileNotFoundError(f"{path}: file not found", path=path) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputFileError(f"{path}: line {exc.lineno}: bad JSON: {exc.msg} at column {exc.colno}",
                             path=path, line=exc.lineno, column=exc.colno) from None
    except RecursionError:
        raise InputFileError(f"{path}: bad JSON: nested too deeply", path=path) from None


def read_diagnosis(path) -> dict:
    """Read ``diagnosis.json`` and check its top-level keys (docs/data-formats.md)."""
    d = read_json(path)
    if not isinstance(d, dict):
        raise InputFileError(f"{path}: expected a JSON object (diagnosis.json schema), got "
                             f"{type(d).__name__}", path=path)
    missing = [k for k in _DIAG_KEYS if k not in d]
    if missing:
        raise InputFileError(f"{path}: missing key(s) {', '.join(missing)} (diagnosis.json schema)", path=path)
    return d
