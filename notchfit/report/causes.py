"""What the report says about a cause: its label and its meaning for the robot, through one function.

Every section reads a cause's words through :func:`cause_text` only, so the
report follows the one record per cause wherever that record lives.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..analysis.causes import REGISTRY

__all__ = ["CauseText", "cause_text"]

#: What each cause means for the robot, in a phrase: the cause records' labels, and the two verdicts.
_MEANING = {
    **{c.id: c.label for c in REGISTRY.values()},
    "none": "nothing beyond the measurement noise: the calibrated model explains the data",
    "unexplained": "a significant error that none of the candidate effects removes",
}


@dataclass(frozen=True)
class CauseText:
    """A cause's ``label`` (words, for headings) and ``meaning`` (a phrase, no final stop)."""

    label: str
    meaning: str


def cause_text(cause: str) -> CauseText:
    """The words for cause id ``cause`` (a pair ``a+b`` is labelled "a + b"; an unknown id by itself)."""
    parts = str(cause).split("+")
    label = " + ".join(p.replace("_", " ") for p in parts)
    return CauseText(label, "; ".join(_MEANING.get(p, "") for p in parts if _MEANING.get(p)))
