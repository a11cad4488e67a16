"""Ctrl-C and SIGTERM during a run: an exception the CLI reports, and sections they cannot cut.

The command line installs :func:`handle_interrupts` around a command: SIGINT
(Ctrl-C) and SIGTERM then raise :class:`Interrupted` (a
``KeyboardInterrupt``) in the main thread, so every ``finally`` and
``__exit__`` runs — :class:`~notchfit.io.outputs.OutputRun` removes its
staging folder, :func:`notchfit.batch.run_batch` stops its worker processes —
and the CLI exits with 128 + the signal number (130, 143) and one line.

A signal that arrives inside :func:`deferred_interrupts` (the final moves of
an output run) is held until the section ends, so the earlier results are
never left half replaced. :func:`received_signal` tells the CLI that a
signal caused whatever exception surfaced (numba kernels turn a
``KeyboardInterrupt`` into a ``SystemError``).
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["Interrupted", "deferred_interrupts", "handle_interrupts", "received_signal"]

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_state = {"depth": 0, "pending": None, "received": None}


class Interrupted(KeyboardInterrupt):
    """The run was interrupted by signal ``signum`` (SIGINT or SIGTERM)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def _handler(signum, frame):
    _state["received"] = signum
    if _state["depth"]:
        _state["pending"] = signum
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def handle_interrupts():
    """SIGINT and SIGTERM raise :class:`Interrupted` inside the block (main thread only; restored after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.getsignal(s) for s in _SIGNALS}
    _state.update(received=None, pending=None, depth=0)
    for s in _SIGNALS:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextlib.contextmanager
def deferred_interrupts():
    """A signal received inside the block is raised as :class:`Interrupted` when the block ends."""
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        pending = _state["pending"]
        if _state["depth"] == 0 and pending is not None:
            _state["pending"] = None
            raise Interrupted(pending)


def received_signal() -> int | None:
    """The signal received during the current :func:`handle_interrupts` block, if any."""
    return _state["received"]
