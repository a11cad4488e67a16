"""Progress of the stages that take more than a moment: a bar on a terminal, one line per stage when piped.

The one home of progress reporting (batches, figure loops, the diagnosis's
steps, the demo). Everything goes to stderr, so that stdout keeps a command's
results:

- on a terminal (stderr is a TTY) a tqdm bar that is removed when the stage ends;
- otherwise (a log file, a pipe, a test) one line when the stage starts,
  ``"detect: 162 images ..."``, so that a log says what is running, and while a
  counted stage runs, every :data:`PIPED_EVERY_S` seconds a line with the count,
  the rate and the time left (``"detect: 40 of 162 images, 2.1 images/s, about
  58 s left ..."``). Every such line ends with ``" ..."``: a reader can tell
  them from messages.

``enabled=False`` silences a stage (a batch inside another stage's bar);
``enabled=True`` forces the bar.

No thread is started (not even tqdm's monitor thread): a process that runs
a thread starts its worker processes by ``spawn`` instead of ``fork``
(:mod:`notchfit.batch`), which is slower; an uncounted stage
(:class:`Steps`) moves when its next step starts.
"""

from __future__ import annotations

import sys
import time

from tqdm.auto import tqdm as _tqdm

__all__ = ["PIPED_EVERY_S", "Steps", "bar", "duration", "on_terminal", "say"]

#: Seconds between the progress lines of a counted stage when stderr is not a terminal.
PIPED_EVERY_S = 30.0


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


def bar(total: int, desc: str | None, *, enabled: bool | None = None, unit: str = "items",
        every_s: float = PIPED_EVERY_S):
    """A progress bar over ``total`` steps (use it as a context manager; ``update(n)`` counts).

    Parameters
    ----------
    total : int
    desc : str or None
        The stage's name; without one nothing is printed when piped.
    enabled : bool, optional
        None: a bar on a terminal (with the rate and the time left), else one
        line ``"desc: total unit ..."`` at the start and one line with the
        count, rate and time left every ``every_s`` seconds; False: silent;
        True: the bar.
    unit : str
        What is counted, for the piped lines (``"images"``, ``"experiments"``).
    every_s : float
        Seconds between the piped lines [s].
    """
    show = on_terminal() if enabled is None else bool(enabled)
    if not show and enabled is None and desc:
        what = unit[:-1] if total == 1 and unit.endswith("s") else unit
        say(f"{desc}: {total} {what} ...")
        return _Lines(total, desc, unit, every_s)
    return _Bar(total=total, desc=desc, disable=not show, leave=False, file=sys.stderr,
                dynamic_ncols=True)


def duration(seconds: float) -> str:
    """``"42 s"``, ``"3 min 05 s"``, ``"2 h 07 min"``: a time span in words for progress lines."""
    s = int(round(max(seconds, 0.0)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class _Lines:
    """The piped form of :func:`bar`: a line with the count, the rate and the time left every
    ``every_s`` seconds (the time left assumes the rate so far holds)."""

    def __init__(self, total: int, desc: str, unit: str, every_s: float):
        self.total, self.desc, self.unit, self.every_s = total, desc, unit, every_s
        self.n = 0
        self.t0 = self.last = time.monotonic()

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.monotonic()
        if now - self.last < self.every_s or self.n >= self.total or now <= self.t0:
            return
        self.last = now
        rate = self.n / (now - self.t0)
        say(f"{self.desc}: {self.n} of {self.total} {self.unit}, {rate:.3g} {self.unit}/s, "
            f"about {duration((self.total - self.n) / rate)} left ...")

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


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
