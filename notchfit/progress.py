"""Progress of the stages that take more than a moment: a bar on a terminal, one line per stage when piped.

The one home of progress reporting (batches, figure loops, the diagnosis's
steps, the demo). Everything goes to stderr, so that stdout keeps a command's
results:

- on a terminal (stderr is a TTY) a tqdm bar that is removed when the stage ends;
- otherwise (a log file, a pipe, a test) one line when the stage starts,
  ``"detect: 162 images ..."``, so that a log says what is running (every
  such line ends with ``" ..."``: a reader can tell them from messages).

``enabled=False`` silences a stage (a batch inside another stage's bar);
``enabled=True`` forces the bar.

No thread is started (not even tqdm's monitor thread): a process that runs
a thread starts its worker processes by ``spawn`` instead of ``fork``
(:mod:`notchfit.batch`), which is slower; an uncounted stage
(:class:`Steps`) moves when its next step starts.
"""

from __future__ import annotations

import sys

from tqdm.auto import tqdm as _tqdm

__all__ = ["Steps", "bar", "on_terminal", "say"]


class _Bar(_tqdm):
    """tqdm without its monitor thread (``monitor_interval = 0``): see the module docstring."""

    monitor_interval = 0


def on_terminal(stream=None) -> bool:
    """Whether ``stream`` (default: stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):     # closed or replaced streams
        return False


def say(text: str) -> None:
    """One progress line on stderr (flushed at once)."""
    print(text, file=sys.stderr, flush=True)


def bar(total: int, desc: str | None, *, enabled: bool | None = None, unit: str = "items"):
    """A progress bar over ``total`` steps (a tqdm object; use it as a context manager).

    Parameters
    ----------
    total : int
    desc : str or None
        The stage's name; without one nothing is printed when piped.
    enabled : bool, optional
        None: a bar on a terminal, else one line ``"desc: total unit ..."``
        at the start; False: silent; True: the bar.
    unit : str
        What is counted, for the piped line (``"images"``, ``"experiments"``).
    """
    show = on_terminal() if enabled is None else bool(enabled)
    if not show and enabled is None and desc:
        what = unit[:-1] if total == 1 and unit.endswith("s") else unit
        say(f"{desc}: {total} {what} ...")
    return _Bar(total=total, desc=desc, disable=not show, leave=False, file=sys.stderr,
                dynamic_ncols=True)


class Steps:
    """A stage made of named steps whose count is not known in advance (the diagnosis).

    On a terminal one line shows the current step and the time since the
    stage started (redrawn when the next step starts); piped, each step is a
    line ``"prefix: step ..."``. A context manager; :meth:`__call__` starts a
    step, so an instance is a ``progress=`` callback.
    """

    def __init__(self, prefix: str, *, enabled: bool | None = None):
        self.prefix = prefix
        self._bar = None
        self._terminal = on_terminal() if enabled is None else bool(enabled)
        self._silent = enabled is False

    def __call__(self, step: str) -> None:
        if self._silent:
            return
        if not self._terminal:
            say(f"{self.prefix}: {step} ...")
            return
        if self._bar is None:
            self._bar = _Bar(total=None, file=sys.stderr, leave=False, dynamic_ncols=True,
                             bar_format="{desc} [{elapsed}]")
        self._bar.set_description_str(f"{self.prefix}: {step}", refresh=False)
        self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
