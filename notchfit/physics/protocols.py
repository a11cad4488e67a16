"""Bend/unbend tension protocols like the paper's experiments (Sec. IV, Fig. 11).

A light counter-tension is held on one cable while the other is pulled up to
a peak and released again, one sample about every five seconds, the
manipulator at rest at each sample. The paper's Fig. 11 test: counter-tension
0.45 N on the right cable, the left cable pulled; regime I has 18 samples
(Fig. 13); the supplemental tests use several counter-tensions and peaks of
about 20–32 N.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["BendProtocol", "bend_unbend", "paper_protocols"]


class BendProtocol(NamedTuple):
    """A tension history: unpack as ``time, tension_left, tension_right, sample_ids``.

    Attributes
    ----------
    time : ndarray (S,) [s]
    tension_left, tension_right : ndarray (S,) [N]
    sample_ids : ndarray (S,) int, 1-based
    """

    time: np.ndarray
    tension_left: np.ndarray
    tension_right: np.ndarray
    sample_ids: np.ndarray


def bend_unbend(peak: float = 25.0, counter: float = 0.45, *, pull: str = "left",
                n_up: int = 19, n_down: int = 19, interval: float = 5.0,
                start: float | None = None, t0: float = 0.0) -> BendProtocol:
    """One bend/unbend test: the pulled cable ramps ``start -> peak -> start``.

    The pulled cable's tension takes ``n_up`` equally spaced values from
    ``start`` to ``peak`` (both included), then ``n_down`` values down to
    ``start`` (the last is ``start``); the other cable holds ``counter``.
    38 samples 5 s apart by default, as in the paper's Fig. 11.

    Parameters
    ----------
    peak : float
        Peak tension of the pulled cable [N] (paper: 20–32).
    counter : float
        Counter-tension on the other cable [N] (Fig. 11: 0.45).
    pull : {"left", "right"}
        The pulled cable (left: the manipulator bends toward -x, θ < 0).
    n_up, n_down : int
        Samples on the way up (incl. start and peak) and down (excl. peak);
        ``n_down = 0``: loading only (how real-tube labs often test a wrist).
    interval : float
        Time between samples [s].
    start : float, optional
        Pulled cable's tension at the first and last sample [N]
        (default ``counter``: the manipulator starts straight).
    t0 : float
        Time of the first sample [s].

    Returns
    -------
    BendProtocol
    """
    if pull not in ("left", "right"):
        raise ValueError(f"pull must be 'left' or 'right', got {pull!r}")
    start = counter if start is None else start
    for name, v in (("peak", peak), ("counter", counter), ("start", start), ("interval", interval),
                    ("t0", t0)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v)):
            raise ValueError(f"{name} must be a finite number, got {v!r}")
    if counter < 0 or start < 0:
        raise ValueError(f"tensions must be >= 0 N, got counter={counter}, start={start}")
    if peak <= start:
        raise ValueError(f"peak ({peak} N) must exceed the starting tension ({start} N)")
    if interval <= 0:
        raise ValueError(f"interval must be > 0 s, got {interval}")
    if int(n_up) != n_up or int(n_down) != n_down or n_up < 2 or n_down < 0:
        raise ValueError(f"need integers n_up >= 2 and n_down >= 0, got {n_up}, {n_down}")
    up = np.linspace(start, peak, int(n_up))
    down = np.linspace(peak, start, int(n_down) + 1)[1:]
    pulled = np.concatenate([up, down])
    other = np.full_like(pulled, float(counter))
    S = pulled.size
    time = t0 + interval * np.arange(S, dtype=float)
    ids = np.arange(1, S + 1)
    if pull == "left":
        return BendProtocol(time, pulled, other, ids)
    return BendProtocol(time, other, pulled, ids)


def paper_protocols(counters=(0.2, 0.45, 1.5), peaks=(20.0, 25.0, 32.0),
                    pulls=("left", "right"), **kw) -> dict[str, BendProtocol]:
    """A suite of paper-like tests: each counter-tension (with its peak) and pull direction.

    Parameters
    ----------
    counters, peaks : sequences of float [N]
        Paired: ``counters[i]`` is tested with ``peaks[i]``.
    pulls : sequence of {"left", "right"}
    **kw
        Passed to :func:`bend_unbend`.

    Returns
    -------
    dict
        ``{"L045": BendProtocol, ...}`` (L/R = pulled cable, counter-tension in cN).
    """
    if len(counters) != len(peaks):
        raise ValueError("counters and peaks must pair up (same length)")
    out = {}
    for c, p in zip(counters, peaks):
        for pull in pulls:
            out[f"{pull[0].upper()}{round(100 * c):03d}"] = bend_unbend(p, c, pull=pull, **kw)
    return out
