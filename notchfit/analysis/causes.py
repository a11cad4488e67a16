"""One record per candidate cause of a discrepancy: everything every place needs to know about it.

A *cause* is a physical effect the friction simulator (Sec. IV-B) lacks and a
study may hide (docs/diagnosis.md, "Causes"; the ids of docs/data-formats.md).
Its :class:`Cause` record holds, in one place:

* ``params`` — the parameters the diagnosis fits for it (:class:`~notchfit.analysis.estimation.ParamSpec`);
* ``laws`` — the recipe/truth fields of each law that can produce it in a
  synthetic study (the first is its default law, :mod:`notchfit.studies.recipes`);
* ``label`` and ``explanation`` — what it means for the robot, in a phrase (the
  report) and in a sentence (the diagnosis's explanation);
* ``figure`` — the kind of view that makes its case
  (:mod:`notchfit.figures.diagnosis`: ``loop``, ``asymmetry``, ``backbone``, ``plane``);
* ``targets`` — the discrepancy signatures it should move and the value a
  perfect model gives them (what it removes, :mod:`notchfit.analysis.diagnosis.pairs`);
* ``signature`` — the heuristic score from the held-out baseline's signatures
  that orders the search (:func:`notchfit.analysis.diagnosis.decision.rank_candidates`),
  with the reason in words;
* ``requires`` — what a study must have for the cause to act on it or for its
  protocol to reveal it, with the reason given when it does not
  (:mod:`notchfit.analysis.diagnosis.scope`); :data:`REVEAL` says which experiment
  would supply what is missing.

Every other module reads :data:`CAUSES` / :data:`REGISTRY`; ``tests/test_causes.py``
fails when a record is incomplete or a module keeps a table of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

from .estimation.specs import ParamSpec

__all__ = ["CAUSES", "FIGURE_KINDS", "REGISTRY", "REQUIREMENTS", "REVEAL", "Cause", "ScoreTerm", "cause",
           "suggested_experiment"]

#: The views a cause's figure can take (:mod:`notchfit.figures.diagnosis`).
FIGURE_KINDS = ("loop", "asymmetry", "backbone", "plane")
#: What a cause may require of a study (:func:`notchfit.analysis.diagnosis.scope.applicable_causes`):
#: ``points`` measured notch points (an image-to-plane mapping); ``unloading`` a trial whose tension
#: falls again (a loop opens only between loading and unloading). A tip load needs neither: the
#: simulator's tip-load torques (Eqs. 18-20) hold on any pivot chain, and they change with the bend
#: while a rest angle does not, so one pull direction can show them.
REQUIREMENTS = ("points", "unloading")
#: The experiment that would supply a missing requirement (``{cause}``: the cause in words).
REVEAL = {
    "points": "measure notch points from calibrated images (not only joint angles) to test {cause}",
    "unloading": "unload one trial (the tension back to zero after its peak) to test {cause}",
}


@dataclass(frozen=True)
class ScoreTerm:
    """One term of a cause's signature score: ``weight * f(value - reference)``.

    ``kind`` ``"excess"``: ``f = max(·, 0)``; ``"abs"``: ``f = |·|``. A signature
    the study does not measure contributes nothing.
    """

    signature: str
    weight: float
    reference: float = 0.0
    kind: str = "excess"

    def of(self, values: dict) -> float:
        """The term for signature ``values`` (``{name: value}``)."""
        if self.signature not in values:
            return 0.0
        d = values[self.signature] - self.reference
        return self.weight * (abs(d) if self.kind == "abs" else max(d, 0.0))


@dataclass(frozen=True)
class Cause:
    """A candidate cause (module docstring).

    Attributes
    ----------
    id : str
    params : tuple of ParamSpec
        The extension parameters the diagnosis fits.
    laws : tuple of tuple of str
        Recipe/truth fields of each law that produces it (first: the default).
    label, explanation : str
        A phrase (report) and a sentence beginning "Physically:" (diagnosis).
    figure : str
        One of :data:`FIGURE_KINDS`.
    targets : tuple of (signature, ideal value, words)
        The signatures it moves toward a perfect model's value.
    signature : tuple of ScoreTerm
        Its score from the baseline's signatures (summed).
    reason : str
        Why the signatures point to it, in words.
    rank_tie : int
        Order among causes of equal score.
    requires : dict
        ``{requirement: reason skipped}`` (:data:`REQUIREMENTS`).
    paper_start : bool
        Also probe and fit from the base model's (the paper's) values, not only from the
        baseline's optimum, whose compensation of the missing effect can hold the fit in
        another basin. Measured on the seven reduced hidden-effect studies (seed 1, 14 fold
        fits per candidate): the second start ended lower in 8 of 14 external_load fits (by
        up to 97 % of the cost), 4 of 14 joint_hysteresis (45 %), 2 of 14
        stiffness_gradient (4 %); for the others by at most 1-4 %, not worth a second fit.
    corrects_points : bool
        The cause corrects the measured points (a warp of the image-to-plane mapping),
        fitted with a registration correction per experiment, not a change of the model.
    second_if_significant : bool
        Tried as a second cause only when it was significant alone (its effect can be
        decided by the load-cell noise, docs/diagnosis.md).
    identifiable : bool
        ``identify --free`` may name its parameters (fields of the simulator's model that
        act on any tube's chain).
    """

    id: str
    params: tuple
    laws: tuple
    label: str
    explanation: str
    figure: str
    targets: tuple
    signature: tuple
    reason: str
    rank_tie: int
    requires: dict
    paper_start: bool = False
    corrects_points: bool = False
    second_if_significant: bool = False
    identifiable: bool = False

    def score(self, values: dict) -> float:
        """The signature score (:attr:`signature`) for ``{signature: value}``."""
        return sum(t.of(values) for t in self.signature)


_LOOP = ("loop_area_ratio", 1.0, "the loop area, measured over predicted")
_BEND = ("residual_bend", 0.0, "the bend left after unloading [rad]")

#: The candidate causes, in the order of docs/diagnosis.md.
REGISTRY: dict[str, Cause] = {c.id: c for c in (
    Cause("proximal_friction",
          params=(ParamSpec("proximal_beta", 0.0, 1.5, 0.05, probes=(0.02, 0.05, 0.1, 0.2, 0.4)),),
          laws=(("proximal_beta",),),
          label="friction between the load cell and the tube's base (sheath, pulleys): the tension that "
                "reaches the tube lags the measured one",
          explanation="Physically: friction between the load cell and the manipulator base (sheath, pulleys) "
                      "means the tension reaching the base lags the measured one: a capstan band that sticks "
                      "until the measured tension has changed by a factor e^β.",
          figure="loop",
          targets=(("unloading_hold", 0.0, "the extra tension the shape holds while unloading [N]"), _LOOP),
          signature=(ScoreTerm("unloading_hold", 0.5), ScoreTerm("loop_area_ratio", 0.5, 1.0)),
          reason="the shape holds longer while unloading and the loop is wider", rank_tie=3,
          requires={"unloading": "no trial unloads: the tension lag of a capstan band shows only when the tension "
                                 "falls (while loading alone it is a smaller tension, which the stiffness absorbs)"},
          identifiable=True),
    Cause("static_friction",
          params=(ParamSpec("mu_s_excess", 0.0, 0.8, 0.05, probes=tuple(round(0.05 * i, 2) for i in range(17))),),
          laws=(("mu_s_excess",),),
          label="the cables stick in their channels longer than the paper's static friction allows",
          explanation="Physically: the cables stick in their channels longer than μ_s ≈ μ_d allows; a larger "
                      "static coefficient holds the shape while the tension falls.",
          figure="loop",
          targets=(("loading_stalls", 0.0, "the stalls on the upper loading ramp"),),
          signature=(ScoreTerm("unloading_hold", 0.4), ScoreTerm("loop_area_ratio", 0.5, 1.0),
                     ScoreTerm("loading_stalls", 20.0)),
          reason="the shape stalls on some loading steps: the cables stick longer than μ_s ≈ μ_d allows",
          rank_tie=4, requires={}, second_if_significant=True),
    Cause("joint_hysteresis",
          params=(ParamSpec("hysteresis_torque", 0.0, 0.6, 0.025, scale="torque", probes=(0.008, 0.02, 0.05, 0.12)),
                  ParamSpec("hysteresis_onset", 0.0, 5.0, 0.0, scale="angle", probes=(0.0, 1.2)),
                  ParamSpec("hysteresis_yield", 0.0, 1.0, 0.0, scale="angle")),
          # the play of the candidate family (with onset and yield the whole family), or the
          # generator's laws that no candidate fits: Bouc-Wen loops and a two-branch superelastic plateau
          laws=(("hysteresis_torque",), ("hysteresis_torque", "hysteresis_onset", "hysteresis_yield"),
                ("bouc_wen_torque", "bouc_wen_stiffness"), ("superelastic_gap",)),
          label="the superelastic flexures are hysteretic: a joint keeps its angle until the torque on it "
                "changes by a threshold (a play, or loops confined to large bends, or elastic-plastic loops)",
          explanation="Physically: the superelastic Nitinol flexures are hysteretic; each joint holds its angle "
                      "until the torque on it changes by the loop's width.",
          figure="loop", targets=(_BEND, _LOOP),
          signature=(ScoreTerm("residual_bend", 50.0), ScoreTerm("unloading_hold", 0.2)),
          reason="a bend remains after unloading", rank_tie=2,
          requires={"unloading": "no trial unloads: a hysteresis loop opens only between loading and unloading "
                                 "(on loading alone it cannot be told from the rest angles and the stiffness)"},
          paper_start=True,
          identifiable=True),
    Cause("external_load",
          params=(ParamSpec("tip_force_x", -3.0, 3.0, 0.0, probes=(-0.3, 0.0, 0.3)),
                  ParamSpec("tip_force_z", -3.0, 3.0, 0.0, probes=(-0.3, 0.0, 0.3))),
          laws=(("tip_force_x", "tip_force_z"),),
          label="a steady external load (payload, gravity, contact) bends both pull directions the same way",
          explanation="Physically: a steady force acts on the end effector (payload, gravity, contact); it bends "
                      "both pull directions the same way, breaking the model's mirror symmetry.",
          figure="asymmetry",
          targets=(("direction_asymmetry", 0.0, "the tip-angle error common to both pull directions [rad]"), _BEND),
          signature=(ScoreTerm("direction_asymmetry", 400.0, kind="abs"),),
          reason="the error does not mirror between pull directions", rank_tie=1, requires={},
          paper_start=True),
    Cause("stiffness_gradient",
          params=(ParamSpec("stiffness_gradient", -0.9, 0.9, 0.0, probes=(-0.5, -0.25, 0.0, 0.25, 0.5)),),
          laws=(("stiffness_gradient",),),
          label="the joint stiffness changes along the backbone",
          explanation="Physically: the joint stiffness varies along the backbone (slot dimensions or material), "
                      "changing the shape's base-to-tip distribution even without friction.",
          figure="backbone",
          targets=(("b_loading_error", 0.0, "the base-to-tip slope b of the loading shapes [rad]"),
                   ("backbone_residual", 0.0, "the error of the base third against the tip third [rad]")),
          signature=(ScoreTerm("b_loading_error", 200.0, kind="abs"),),
          reason="the shape differs along the backbone while loading", rank_tie=5, requires={},
          paper_start=True, identifiable=True),
    Cause("calibration_error",
          # scale_error, k_radial [-]; the warp centre [m] (centred on the data when fitted); the bending
          # plane's tilt against the calibrated plane [rad], seen in perspective (vision.warp)
          params=(ParamSpec("scale_error", -0.2, 0.2, 0.0, probes=(-0.02, 0.0, 0.02)),
                  ParamSpec("k_radial", -0.02, 0.02, 0.0, probes=(-0.005, 0.0, 0.005)),
                  ParamSpec("warp_center_x", -0.2, 0.2, 0.0),
                  ParamSpec("warp_center_y", -0.2, 0.2, 0.0),
                  ParamSpec("plane_tilt_x", -0.35, 0.35, 0.0),
                  ParamSpec("plane_tilt_y", -0.35, 0.35, 0.0)),
          # a wrong scale and lens distortion; a tilted bending plane (with the camera's distance);
          # both at once
          laws=(("scale_error", "k_radial"), ("plane_tilt_x", "plane_tilt_y"),
                ("scale_error", "k_radial", "plane_tilt_x", "plane_tilt_y")),
          label="the image-to-plane mapping is wrong (scale, lens distortion, or a bending plane tilted "
                "against the calibrated one)",
          explanation="Physically: the image-to-plane mapping is wrong (scale, lens distortion, or the bending "
                      "plane tilted against the calibrated one and seen in perspective); a camera-plane "
                      "correction fitted across all samples removes a residual pattern that no joint "
                      "configuration can.",
          figure="plane", targets=(),
          signature=(ScoreTerm("spatial_pattern", 3.0, 1.2),),
          reason="free-θ fits leave a spatial residual pattern", rank_tie=0,
          requires={"points": "the experiments are measured as joint angles: there is no image-to-plane "
                              "mapping for a calibration warp to correct"},
          corrects_points=True),
)}
#: The cause ids, in the order of docs/diagnosis.md.
CAUSES = tuple(REGISTRY)


def suggested_experiment(cid: str, requirement: str) -> str | None:
    """The experiment that would let a study reveal cause ``cid`` where it lacks ``requirement``
    (:data:`REVEAL`; None where no experiment can)."""
    text = REVEAL.get(requirement)
    return text.format(cause=cid.replace("_", " ")) if text else None


def cause(cid: str) -> Cause:
    """The record of cause ``cid``.

    Raises
    ------
    ValueError
        An unknown id (the message lists the known ones).
    """
    try:
        return REGISTRY[cid]
    except KeyError:
        raise ValueError(f"unknown cause {cid!r}; known: {', '.join(CAUSES)}") from None
