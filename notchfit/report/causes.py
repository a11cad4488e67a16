"""What the report says about a cause: its label and its meaning for the robot, through one function.

Every section reads a cause's words through :func:`cause_text` only, so the
report follows the one record per cause wherever that record lives.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CauseText", "cause_text"]

#: What each cause means for the robot, in a phrase (the ids of docs/data-formats.md).
_MEANING = {
    "proximal_friction": "friction between the load cell and the tube's base (sheath, pulleys): the tension that "
                         "reaches the tube lags the measured one",
    "static_friction": "the cables stick in their channels longer than the paper's static friction allows",
    "joint_hysteresis": "the superelastic flexures are hysteretic: a joint keeps its angle until the torque on it "
                        "changes by a threshold (a play, or loops confined to large bends, or elastic-plastic loops)",
    "external_load": "a steady external load (payload, gravity, contact) bends both pull directions the same way",
    "stiffness_gradient": "the joint stiffness changes along the backbone",
    "calibration_error": "the image-to-plane mapping is wrong (scale or lens distortion)",
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
