"""What every sub-command shares: the input-error type, exit codes, common options, running a command.

This module imports nothing from :mod:`notchfit.cli` or from the command
modules, so that :mod:`notchfit.cli` can import the commands and the
commands (and the demo, which runs other commands) can import this without a
cycle.

Exit codes: 0 ok, :data:`EXIT_ITEMS_FAILED` (1) some items failed (listed by
the command), :data:`EXIT_INPUT_ERROR` (2) a usage or input error (a one-line
message on stderr), 128 + the signal number when interrupted (130 Ctrl-C,
143 SIGTERM). :func:`error_exit` is the one place that maps an exception to
its message and exit code (docs/reliability.md); ``--debug`` or
``NOTCHFIT_DEBUG=1`` adds the traceback.
"""

from __future__ import annotations

import argparse
import errno
import os
import signal
import sys
import traceback
from pathlib import Path

from .. import io
from ..io.errors import InputFileError
from ..io.interrupts import received_signal

__all__ = ["EXIT_INPUT_ERROR", "EXIT_ITEMS_FAILED", "INPUT_ERRORS", "InputError", "OneLineParser",
           "add_batch_options", "add_command", "add_points_option", "call", "check_out_dir", "check_points_dir",
           "count_option", "debug_enabled", "error_exit", "execute", "in_words", "jobs_option", "list_failures",
           "new_folders", "remove_empty"]

EXIT_ITEMS_FAILED = 1
EXIT_INPUT_ERROR = 2
EXIT_BROKEN_PIPE = 128 + 13


class InputError(Exception):
    """A usage or input problem that the user must fix (exit code 2)."""


#: Exceptions that a command reports as ``notchfit NAME: error: ...`` with exit code 2 (their
#: message is the explanation). Every other exception is reported too, in one line with its type.
INPUT_ERRORS = (InputError, InputFileError, ValueError, FileNotFoundError, FileExistsError)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr (exit code 2)."""

    def error(self, message):
        self.exit(EXIT_INPUT_ERROR, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def debug_enabled(args=None) -> bool:
    """``--debug`` was given or ``NOTCHFIT_DEBUG`` is set (not empty or 0): show tracebacks."""
    return bool(getattr(args, "debug", False)) or os.environ.get("NOTCHFIT_DEBUG", "") not in ("", "0")


def _interrupt_signal(exc: BaseException) -> int | None:
    """The signal behind ``exc``: one received during the run, or a KeyboardInterrupt in its chain."""
    sig = received_signal()
    if sig is not None:
        return sig
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, KeyboardInterrupt):
            return getattr(exc, "signum", signal.SIGINT)
        exc = exc.__cause__ or exc.__context__
    return None


def _os_message(exc: OSError) -> str:
    what = f"{exc.filename}: " if exc.filename else ""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"{what}no space left on the device (disk full or quota reached); nothing of this run was kept"
    if exc.filename and exc.strerror:
        return f"{what}{exc.strerror[0].lower()}{exc.strerror[1:]}"
    return str(exc)


def _message(exc: BaseException) -> str:
    """The one-line explanation of ``exc``."""
    if isinstance(exc, OSError) and not isinstance(exc, InputFileError) and exc.errno is not None:
        text = _os_message(exc)
    elif isinstance(exc, INPUT_ERRORS):
        text = str(exc)
    elif isinstance(exc, MemoryError):
        text = "out of memory (an input too large for this machine?)"
    elif isinstance(exc, RecursionError):
        text = "input nested too deeply (a recursion limit was reached)"
    else:
        text = f"unexpected {type(exc).__name__}: {exc} (a notchfit bug or an unchecked input; " \
               "rerun with --debug for the traceback)"
    lines = [ln.strip() for ln in str(text).splitlines() if ln.strip()]
    return "; ".join(lines) or type(exc).__name__


def error_exit(command: str, exc: BaseException, *, debug: bool = False) -> int:
    """Report ``exc`` raised by command ``command`` on stderr in one line; returns the exit code.

    ================================  ===========  ==========================================
    exception                         exit code    message
    ================================  ===========  ==========================================
    SIGINT / SIGTERM (also a numba    130 / 143    ``interrupted (SIGINT); ...``
    SystemError caused by one)
    BrokenPipeError (``| head``)      141          none
    anything else                     2            its message (input errors), or its type and
                                                   message (OS errors name the file)
    ================================  ===========  ==========================================
    """
    if isinstance(exc, SystemExit):
        raise exc
    if debug:
        traceback.print_exception(exc)
    sig = _interrupt_signal(exc)
    # a resumable run (notchfit.io.ResumableRun) notes on the exception what it kept
    kept = "; ".join(getattr(exc, "__notes__", ()))
    if sig is not None:
        name = signal.Signals(sig).name
        done = f"{kept};" if kept else "the outputs of this run were discarded,"
        print(f"notchfit {command}: interrupted ({name}); {done} earlier outputs are unchanged", file=sys.stderr)
        return 128 + int(sig)
    if isinstance(exc, BrokenPipeError):
        return EXIT_BROKEN_PIPE
    text = _message(exc)
    if kept:
        text = text.replace("; nothing of this run was kept", "") + f"; {kept}"
    print(f"notchfit {command}: error: {text}", file=sys.stderr)
    return EXIT_INPUT_ERROR


def add_command(subparsers, mod) -> argparse.ArgumentParser:
    """Add command module ``mod`` (``NAME``, ``HELP``, ``DESCRIPTION``, ``add_arguments``, ``run``).

    Parameters
    ----------
    subparsers : argparse subparsers action, or None
        ``None`` makes a stand-alone parser (``prog = "notchfit NAME"``).
    mod : module

    Returns
    -------
    argparse.ArgumentParser
        The command's parser; its defaults carry ``_run`` and ``command``.
    """
    kw = dict(description=getattr(mod, "DESCRIPTION", mod.HELP),
              formatter_class=argparse.RawDescriptionHelpFormatter)
    if subparsers is None:
        parser = OneLineParser(prog=f"notchfit {mod.NAME}", **kw)
    else:
        parser = subparsers.add_parser(mod.NAME, help=mod.HELP, **kw)
    mod.add_arguments(parser)
    # also accepted after the command; SUPPRESS keeps a global `notchfit --debug CMD` from being reset
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of an error (also NOTCHFIT_DEBUG=1)")
    parser.set_defaults(_run=mod.run, command=mod.NAME)
    return parser


def new_folders(path) -> list[Path]:
    """``path`` and those of its parents that do not exist yet, deepest first."""
    if path is None:
        return []
    new = []
    for p in [Path(path), *Path(path).parents]:
        if p.exists() or p.is_symlink():
            break
        new.append(p)
    return new


def remove_empty(folders) -> None:
    """Remove the folders (deepest first) that are empty; stop at the first that is not."""
    for p in folders:
        try:
            p.rmdir()
        except FileNotFoundError:
            continue
        except OSError:
            break


def execute(args) -> int:
    """Run the parsed command ``args._run(args)``; any exception becomes one line and an exit code.

    See :func:`error_exit` (exit 2 for an input error, 130/143 when
    interrupted, 141 on a broken pipe). A command that fails (exit 2 or
    more) leaves no folder behind that it created for ``--out`` and left
    empty.
    """
    created = new_folders(getattr(args, "out", None))
    try:
        code = int(args._run(args) or 0)
    except Exception as exc:  # noqa: BLE001 - the one place that maps exceptions to exit codes
        code = error_exit(args.command, exc, debug=debug_enabled(args))
    except KeyboardInterrupt as exc:
        code = error_exit(args.command, exc, debug=debug_enabled(args))
    if code >= EXIT_INPUT_ERROR:
        remove_empty(created)
    return code


def call(mod, argv) -> int:
    """Run command module ``mod`` on the arguments ``argv`` (without the command name), as the CLI would.

    An error is reported as the CLI reports it and its exit code returned;
    an interruption (Ctrl-C, SIGTERM) is raised instead, so that the caller
    (``notchfit demo``) stops as a whole.
    """
    args = add_command(None, mod).parse_args([str(a) for a in argv])
    try:
        return int(args._run(args) or 0)
    except Exception as exc:  # noqa: BLE001 - reported as the CLI does, unless a signal caused it
        if _interrupt_signal(exc) is not None:
            raise
        return error_exit(args.command, exc, debug=debug_enabled(args))


def count_option(minimum: int = 1):
    """An argparse ``type``: an integer ``>= minimum`` (``--samples 0 0`` is an error, not the default)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{text} is below {minimum}")
        return value
    parse.__name__ = "count"      # argparse names the type in its messages
    return parse


#: Worker processes allowed per CPU: more only adds memory and start-up time to a CPU-bound batch.
MAX_JOBS_PER_CPU = 4


def jobs_option(text: str) -> int:
    """An argparse ``type`` for ``--jobs``: 0 (every CPU) to :data:`MAX_JOBS_PER_CPU` x the CPUs."""
    value = count_option(0)(text)
    cpus = os.cpu_count() or 1
    if value > MAX_JOBS_PER_CPU * cpus:
        raise argparse.ArgumentTypeError(f"{value} worker processes for {cpus} CPUs: at most "
                                         f"{MAX_JOBS_PER_CPU * cpus} (0 = one per CPU)")
    return value


def add_batch_options(parser) -> None:
    """``--jobs N`` and ``--scheduler ADDRESS`` of the commands that run on :func:`notchfit.batch.run_batch`."""
    parser.add_argument("--jobs", type=jobs_option, default=1, help="worker processes (default 1; 0 = all CPUs)")
    parser.add_argument("--scheduler", default=None, help="Dask distributed scheduler address")


def check_points_dir(points) -> Path | None:
    """Check an explicit ``--points DIR`` before anything is read: an existing folder holding a
    detect run's ``detections.csv`` (in it, or in its experiment sub-folders). None stays None
    (the command looks in ``--out``)."""
    if points is None:
        return None
    path = Path(points)
    if not path.exists():
        raise InputError(f"--points {points}: folder not found (the --out folder of a notchfit detect run)")
    if not path.is_dir():
        raise InputError(f"--points {points}: is a file; give the --out folder of a notchfit detect run "
                         "(it holds detections.csv)")
    if not io.find_output(path, "detections.csv"):
        raise InputError(f"--points {points}: holds no detections.csv (neither in it nor in its experiment "
                         "sub-folders): not the --out folder of a notchfit detect run")
    return path


def add_points_option(parser, *aliases, help: str) -> None:
    """``--points DIR``: the folder of a ``notchfit detect`` run to take notch points from.

    The one option name for "points from a detect run" (``fit``, ``simulate``,
    ``diagnose``); ``aliases`` are older names that still work (e.g.
    ``"--detections"``). The value is ``args.points`` (a Path or None); the
    command checks it with :func:`check_points_dir` before reading anything.
    """
    parser.add_argument("--points", *aliases, dest="points", type=Path, default=None, metavar="DIR", help=help)


def _input_data_reason(out: Path) -> str | None:
    """Why folder ``out`` holds input data (an experiment, a folder inside one, a study), or None."""
    for folder in [out, *out.parents]:
        if io.is_experiment_dir(folder):
            where = "it holds" if folder == out else f"{folder} above it holds"
            return f"is an input study or experiment folder ({where} experiment.toml)"
    try:
        subs = sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return None
    exp = next((p for p in subs if io.is_experiment_dir(p)), None)
    if exp is not None:
        return f"is an input study folder (its sub-folder {exp.name} holds experiment.toml)"
    return None


def check_out_dir(out, *inputs, option: str = "--out", hint: str | None = None, outputs=None,
                  force: bool = False) -> Path:
    """Check an output folder before anything is read or written; returns it as a Path.

    Refused (:class:`InputError`): the folder equal to or inside an input
    folder (outputs would mix with the raw data, and a study would see the
    output folder as a broken experiment), a folder that is itself input
    data (an experiment, a folder inside one, or a study: it or a sub-folder
    holds ``experiment.toml``), a file where the folder should be, a path
    through a file (``afile/x``), a folder another live notchfit run is
    writing into (its lock), and, without ``force``, a folder that already
    holds one of ``outputs``. A command calls it first, so that it refuses
    before it reads or prints anything.

    Parameters
    ----------
    out : path
    *inputs : path or None
        The command's input folders.
    option : str
        How the messages name the folder (``"--out"``; ``""`` for a positional argument).
    hint : str, optional
        Appended to the message when the folder is input data (what to run instead).
    outputs : sequence of str, optional
        Relative paths whose presence means an earlier run's outputs (e.g. the
        command's run record ``fit_run.json``); none are checked by default.
    force : bool
        The command replaces existing outputs (``--force``).
    """
    out = Path(out)
    label = f"{option} {out}" if option else str(out)
    for parent in [out, *out.parents]:
        if parent.exists():
            if not parent.is_dir():
                what = "is a file" if parent == out else f"cannot be created: {parent} is a file"
                raise InputError(f"{label}: {what}, not a folder")
            break
    target = out.resolve()
    for inp in inputs:
        if inp is None:
            continue
        src = Path(inp).resolve()
        if src.is_dir() and (target == src or src in target.parents):
            where = "is the input folder" if target == src else f"is inside the input folder {inp}"
            raise InputError(f"{label} {where}; outputs would mix with the data: choose a folder "
                             "outside it")
    reason = _input_data_reason(target)
    if reason is not None:
        raise InputError(f"{label}: {reason}, not an output folder; outputs would mix with the data"
                         + (f"; {hint}" if hint else ": choose a folder outside it"))
    elsewhere = f" or choose another {option}" if option else ""
    who = io.live_lock_holder(out)
    if who is not None:
        raise InputError(f"{label}: another notchfit run ({who}) is writing into this folder; wait for it "
                         f"to finish{elsewhere}")
    clash = [] if force or not outputs else io.existing_outputs(out, outputs)
    if clash:
        raise InputError(f"{label}: already holds {', '.join(clash)} of an earlier run; use --force to "
                         f"replace {'it' if len(clash) == 1 else 'them'}{elsewhere}")
    return out


def _input_error_names() -> set[str]:
    """The class names of the input errors (and of their subclasses), which a message need not show."""
    names, todo = set(), list(INPUT_ERRORS)
    while todo:
        cls = todo.pop()
        if cls.__name__ not in names:
            names.add(cls.__name__)
            todo.extend(cls.__subclasses__())
    return names


def in_words(reason: str) -> str:
    """``reason`` without a leading input-error class name (``"InputFileNotFoundError: x.csv: ..."``
    becomes ``"x.csv: ..."``): the message already says what is wrong, in words."""
    name, sep, rest = str(reason).partition(": ")
    return rest if sep and rest and name in _input_error_names() else str(reason)


def list_failures(failed: dict, *, limit: int = 20) -> None:
    """Print ``  FAILED key: reason`` for each failure (stdout; the command exits 1)."""
    for k, v in list(failed.items())[:limit]:
        print(f"  FAILED {k}: {in_words(v)}")
    if len(failed) > limit:
        print(f"  ... and {len(failed) - limit} more")
