"""Resumable output runs: every finished item kept on disk as it completes; a stopped run continued.

A command whose items take long (``detect``: one image each) writes through
:class:`ResumableRun`, an :class:`~notchfit.io.outputs.OutputRun` whose working
folder has a fixed name, ``OUT/.notchfit-resume-<command>/``:

- ``run.json``: the command, its input folder (resolved), whether ``--force``
  was given, when the run started;
- ``stage/``: the outputs in their final layout (moved into ``OUT`` when the
  run succeeds, as an output run's staging folder is);
- ``items/<id>.json``: one record per finished item: its key, the content hash
  (SHA-256) of its input file, a hash of the options that shape its result,
  its summary, and the files it owns with their sizes; ``items/<id>.<ext>``
  the item's own files (a table that the run assembles at the end).

An item's files are written first, its record last, each through a temporary
file that is flushed to the disk (``fsync``) and then renamed: a record on the
disk means a whole item, whatever stopped the run (Ctrl-C, SIGKILL, a power cut,
a full disk). When the run stops with finished items, the folder stays (the
lock is released) and the exception carries a note saying how many are kept
(the command line prints it). ``resume=True`` continues the run: the records
of items whose input file changed (content hash), whose options changed, or
whose files are missing or cut short are dropped and those items are done
again, as are items that failed (they are never recorded). A run that
succeeds replaces the old outputs as an output run does and removes the
folder.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import shutil
from pathlib import Path

from .._version import __version__
from .interrupts import deferred_interrupts
from .outputs import (OutputRun, _json_default, _nan_to_none, atomic_write, prepare_output_dir,
                      write_json_atomic)

__all__ = ["ContentHash", "NothingToResumeError", "RESUME_PREFIX", "ResumableRun", "check_resumable",
           "file_sha256", "options_sha256", "write_bytes_synced"]

RESUME_PREFIX = ".notchfit-resume-"
_RECORD = ".json"


class NothingToResumeError(ValueError):
    """``--resume`` on a folder that holds no interrupted run of the command (exit code 2)."""


class ContentHash(str):
    """An item's content hash (hex) given as it is, for an item whose input is data rather than one
    file (an experiment's points or tensions as read: :func:`options_sha256` of them)."""


def check_resumable(out_dir, name: str, outputs=None) -> None:
    """Raise :class:`NothingToResumeError` unless ``out_dir`` holds an interrupted ``name`` run
    (a command checks it before it reads its input; :class:`ResumableRun` checks it again)."""
    if not (Path(out_dir) / f"{RESUME_PREFIX}{name}").is_dir():
        raise NothingToResumeError(_nothing_to_resume(Path(out_dir), name, outputs))


def file_sha256(path) -> str:
    """SHA-256 of a file's content (hex)."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def options_sha256(options) -> str:
    """SHA-256 (hex) of JSON-able ``options`` (keys sorted; numpy values, paths and dataclasses allowed)."""
    text = json.dumps(_nan_to_none(options), sort_keys=True, default=_json_default, allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def write_bytes_synced(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and flush it to the disk (``fsync``) before the rename."""
    def w(tmp):
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return atomic_write(path, w)


def _item_id(key: str) -> str:
    return hashlib.sha1(key.encode("utf-8")).hexdigest()[:20]


class ResumableRun(OutputRun):
    """An output run whose finished items survive an interrupt or a kill (see the module docstring).

    Parameters
    ----------
    out_dir : path
    name : str
        The command (names the working folder ``.notchfit-resume-<name>``).
    input_path : path
        The command's input; a run is resumed only with the same input.
    resume : bool
        Continue the interrupted run in ``out_dir``; :class:`NothingToResumeError`
        when there is none (a finished run, another command's folder, no folder),
        before anything is created.
    outputs : sequence of str, optional
        As for :class:`OutputRun` (existing ones are refused without ``force``).
    force : bool
        Replace existing outputs; without ``resume``, also start again over an
        interrupted run. A resumed run keeps the ``force`` of the run it continues.
    unit : str
        What an item is, for the note on an interrupted run (``"images"``).

    Without ``resume``, an interrupted run with finished items in ``out_dir`` is
    refused (``FileExistsError``: ``--resume`` continues it, ``--force`` starts
    again).
    """

    def __init__(self, out_dir, *, name: str, input_path, resume: bool = False, outputs=None,
                 force: bool = False, unit: str = "items"):
        self.input = str(Path(input_path).resolve())
        self.resume, self.unit, self.total = resume, unit, None
        self.records: dict[str, dict] = {}
        self.folder = Path(out_dir) / f"{RESUME_PREFIX}{name}"
        if resume:
            check_resumable(out_dir, name, outputs)
        self._name = name
        super().__init__(out_dir, outputs=outputs, force=force, name=name)

    def _open(self, name: str, outputs) -> None:
        folder = self.folder
        if folder.is_dir():
            records = list((folder / "items").glob(f"*{_RECORD}"))
            if self.resume:
                self.force = self.force or self._check_manifest()
            elif records and not self.force:
                raise FileExistsError(
                    f"{self.out_dir}: holds an interrupted {name} run ({len(records)} {self.unit} finished): "
                    f"add --resume to continue it, or --force to start again")
            else:
                shutil.rmtree(folder)
        prepare_output_dir(self.out_dir, force=self.force, outputs=outputs)
        self.stage = folder / "stage"
        if folder.is_dir():
            self.records = self._load_records()
            return
        (folder / "items").mkdir(parents=True)
        self.stage.mkdir()
        write_json_atomic({"command": name, "input": self.input, "force": self.force, "notchfit": __version__,
                           "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")},
                          folder / "run.json")

    def _check_manifest(self) -> bool:
        """The resumed run's ``force``, after checking that it ran this command on this input."""
        where = self.folder / "run.json"
        try:
            m = json.loads(where.read_text(encoding="utf-8"))
            command, input_, force = m["command"], m["input"], bool(m["force"])
        except (OSError, ValueError, KeyError, TypeError):
            raise NothingToResumeError(f"{self.out_dir}: the interrupted {self._name} run's record {where} is "
                                       "unreadable; run without --resume (and with --force) to start "
                                       "again") from None
        if command != self._name or input_ != self.input:
            raise NothingToResumeError(f"{self.out_dir}: the interrupted {command} run there worked on "
                                       f"{input_}, not on {self.input}; give that input to continue it, or "
                                       "run without --resume (and with --force) to start again")
        return force

    def _load_records(self) -> dict[str, dict]:
        records = {}
        for p in sorted((self.folder / "items").glob(f"*{_RECORD}")):
            try:
                rec = json.loads(p.read_text(encoding="utf-8"))
                records[rec["key"]] = rec
            except (OSError, ValueError, KeyError, TypeError):
                p.unlink(missing_ok=True)          # not a whole record: its item is done again
        return records

    # ------------------------------------------------------------------ items
    def reconcile(self, wanted: dict) -> set[str]:
        """Keep the records still valid for this run; drop the others and every stray file.

        Parameters
        ----------
        wanted : dict
            ``{key: (input, options hash)}`` of every item of this run; ``input``
            the path of the item's input file (its content hashed here), or the
            item's content hash itself (:class:`ContentHash`).

        Returns
        -------
        set of str
            The keys whose record is kept (their items need not run again): same
            options hash, every file whole, and the input file's content hash
            unchanged.
        """
        self.total = len(wanted)
        for key, rec in list(self.records.items()):
            want = wanted.get(key)
            if want is None or not self._still_valid(rec, *want):
                self._drop(key)
        owned = {self.folder / rel for rec in self.records.values() for rel in rec["files"]}
        owned |= {self.folder / "items" / f"{_item_id(k)}{_RECORD}" for k in self.records}
        for sub in ("stage", "items"):
            for p in sorted((self.folder / sub).rglob("*"), reverse=True):
                if p.is_file() and p not in owned:
                    p.unlink()
                elif p.is_dir() and not any(p.iterdir()):
                    p.rmdir()
        return set(self.records)

    def _still_valid(self, rec: dict, input_path, options_hash: str) -> bool:
        if rec.get("options_sha256") != options_hash:
            return False
        for rel, size in rec["files"].items():
            try:
                if (self.folder / rel).stat().st_size != size:
                    return False
            except OSError:
                return False
        if isinstance(input_path, ContentHash):
            return input_path == rec.get("input_sha256")
        try:
            return file_sha256(input_path) == rec.get("input_sha256")
        except OSError:
            return False

    def _drop(self, key: str) -> None:
        rec = self.records.pop(key)
        (self.folder / "items" / f"{_item_id(key)}{_RECORD}").unlink(missing_ok=True)
        for rel in rec["files"]:
            (self.folder / rel).unlink(missing_ok=True)

    def keep(self, key: str, *, input_sha256: str, options_sha256: str, value: dict,
             stage_files: dict | None = None, own_files: dict | None = None) -> None:
        """Record a finished item: its files (each synced to the disk), then its record.

        Parameters
        ----------
        key : str
        input_sha256, options_sha256 : str
            The item's input content hash and options hash (:func:`file_sha256`,
            :func:`options_sha256`).
        value : dict
            The item's summary (JSON-able), given back by :meth:`record`.
        stage_files : dict, optional
            ``{output path relative to the output folder: bytes}``: the item's
            outputs, written into the staging folder.
        own_files : dict, optional
            ``{extension: bytes}``: files of the item's own (:meth:`own_file`),
            not outputs.
        """
        files = {}
        for rel, data in (stage_files or {}).items():
            write_bytes_synced(self.path(rel), data)
            files[f"stage/{Path(rel).as_posix()}"] = len(data)
        for ext, data in (own_files or {}).items():
            p = self.own_file(key, ext)
            write_bytes_synced(p, data)
            files[f"items/{p.name}"] = len(data)
        rec = {"key": key, "input_sha256": input_sha256, "options_sha256": options_sha256, "files": files,
               "value": value}
        text = json.dumps(_nan_to_none(rec), default=_json_default, allow_nan=False)
        write_bytes_synced(self.folder / "items" / f"{_item_id(key)}{_RECORD}", text.encode("utf-8"))
        self.records[key] = rec

    def own_file(self, key: str, ext: str) -> Path:
        """Where item ``key`` keeps its own file of extension ``ext`` (e.g. ``".csv"``)."""
        return self.folder / "items" / f"{_item_id(key)}{ext}"

    def record(self, key: str) -> dict | None:
        """The record of finished item ``key`` (``value`` is its summary), or None."""
        return self.records.get(key)

    def kept_note(self) -> str:
        """``"40 of 82 images finished are kept in OUT: ..."`` (what an interrupted run says)."""
        of = f" of {self.total}" if self.total is not None else ""
        return (f"{len(self.records)}{of} {self.unit} finished are kept in {self.out_dir}: the same command "
                "with --resume continues the run")

    # ------------------------------------------------------------------ end of the run
    def _commit(self) -> list[Path]:
        committed = super()._commit()
        shutil.rmtree(self.folder, ignore_errors=True)
        self.records.clear()
        return committed

    def abort(self) -> None:
        """Release the lock; the working folder stays when it holds finished items (else removed)."""
        with deferred_interrupts():
            if not self.records:
                shutil.rmtree(self.folder, ignore_errors=True)
            self._release()

    def __exit__(self, exc_type, exc, tb):
        if exc is not None and self.records:
            exc.add_note(self.kept_note())
        return super().__exit__(exc_type, exc, tb)


def _nothing_to_resume(out: Path, name: str, outputs) -> str:
    if not out.is_dir():
        return f"--out {out}: no such folder: no interrupted {name} run to resume"
    done = [o for o in (outputs or ()) if (out / o).exists()]
    if done:
        return (f"{out}: its {name} run finished ({', '.join(map(str, done[:3]))}); nothing to resume "
                "(without --resume, --force runs it again)")
    return f"{out}: holds no interrupted {name} run to resume"
