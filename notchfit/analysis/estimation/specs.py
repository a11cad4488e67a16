"""Fitted parameters: bounds, starts, probes, the study's scales, and the baselines of both engines.

A fitted parameter is a :class:`ParamSpec`: a :class:`notchfit.physics.friction.FrictionParams`
field (or a point-warp parameter, or ``mu_s_excess`` = μ_s − μ_d) with its
bounds, start value, probe values for the multi-start search, whether it is
fitted in log space, and the study scale its bounds are given in
(:class:`StudyScales`). Both engines fit from these specs: ``diagnose``'s
baseline and candidates (:mod:`notchfit.analysis.causes` holds each cause's specs) and
``identify``'s free parameters.

Parameters whose size is set by the tube (hysteresis torques, onset angles)
are fitted in units of the study's scale, so that one set of bounds and probes
serves the seed tube and a 1.6 mm wrist alike.

Baselines (docs/models.md, "The baseline of the diagnosis"):

* the paper's spring law (``spring_law = "rates"``): ``k_lin``, ``k_mid`` [N m/rad], ``μ_d``;
* the material law of a real tube: the linear and plateau moduli ``E_lin``,
  ``E_se`` [Pa] and ``μ_d`` (:data:`MATERIAL_BASELINE`, the diagnosis's before it
  took identify's model), or with the transformation strain ``strain_lower``
  (:data:`MATERIAL`, identify's and the diagnosis's, with bounds from the nitinol
  literature: docs/models.md, "Identification").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...physics.cables import pulled_side
from ...physics.friction import FrictionParams

__all__ = ["BASELINE", "BASELINE_MU_EXCESS", "CAPSTAN_MU", "MATERIAL", "MATERIAL_BASELINE", "ParamSpec",
           "StudyScales", "baseline_specs"]


@dataclass(frozen=True)
class StudyScales:
    """Sizes of a study that scale the fitted parameters.

    Attributes
    ----------
    torque : float
        Largest drive torque ``a_j T`` of the pulled tendon at the base joint [N m].
    angle : float
        Where the flexures' plateau starts: the median first break of the base
        model's joint springs [rad] (the paper's ``θ_mid`` = 0.07 rad; the
        superelastic strain threshold of a material spring), the deflection
        around which superelastic loops open.
    """

    torque: float = 1.0
    angle: float = 1.0

    @classmethod
    def of(cls, obs, base: FrictionParams | None = None) -> StudyScales:
        """The scales of observed experiments (:class:`notchfit.analysis.estimation.Observations`) and their base model."""
        torque = 0.0
        for p in obs:
            side = pulled_side(p.tension_left, p.tension_right)
            arm = float(np.abs(p.geom.moment_arms(side))[0])
            torque = max(torque, arm * float(np.max(p.pulled_tension)))
        base = base or FrictionParams()
        angle = float(np.median(base.joint_spring(obs[0].geom).breaks[:, 0])) if obs else 1.0
        return cls(torque=torque if torque > 0 else 1.0, angle=angle if angle > 0 else 1.0)

    def factor(self, kind: str) -> float:
        """The scale of a parameter kind (``""``: 1)."""
        return {"": 1.0, "torque": self.torque, "angle": self.angle}[kind]


@dataclass(frozen=True)
class ParamSpec:
    """A fitted parameter: bounds, start value, and whether it is fitted in log space.

    Attributes
    ----------
    name : str
        A :class:`notchfit.physics.friction.FrictionParams` field, ``mu_s_excess``
        (μ_s − μ_d) or a point-warp parameter.
    lower, upper, start : float
        Bounds and start value [SI unit of the parameter, or units of the
        study's ``scale`` when it is set].
    log : bool
        Fit ``log(value)`` (positive stiffnesses and moduli).
    probes : tuple of float
        Start values tried (one residual evaluation each) before the
        least-squares fit starts from the best: the friction models are only
        piecewise smooth and have local minima along some axes. In units of
        ``scale``. Probes of several parameters are tried in every combination.
    scale : {"", "torque", "angle"}
        The study scale (:class:`StudyScales`) the bounds, start and probes are
        given in; the optimiser works in that unit.
    """

    name: str
    lower: float
    upper: float
    start: float
    log: bool = False
    probes: tuple = ()
    scale: str = ""

    def to_x(self, v: float, sc: float = 1.0) -> float:
        """Value [SI] -> optimiser coordinate (``sc``: the study's scale of this parameter)."""
        return math.log(v) if self.log else v / sc

    def from_x(self, x: float, sc: float = 1.0) -> float:
        """Optimiser coordinate -> value [SI]."""
        return math.exp(x) if self.log else x * sc

    @property
    def x_bounds(self) -> tuple[float, float]:
        """Bounds in optimiser coordinates."""
        return (math.log(self.lower), math.log(self.upper)) if self.log else (self.lower, self.upper)

    def x_of_spec_value(self, v: float) -> float:
        """Optimiser coordinate of a value given like the bounds (start, probes)."""
        return math.log(v) if self.log else v


#: Baseline of the paper's spring law (docs/models.md): k_lin, k_mid [N m/rad], μ_d [-].
BASELINE = (
    ParamSpec("k_lin", 0.05, 5.0, 0.4829, log=True),
    ParamSpec("k_mid", 0.01, 5.0, 0.25, log=True),
    ParamSpec("mu_d", 0.0, 0.8, 0.29),
)
#: Baseline of the material law of a real tube in the diagnosis: the linear and plateau moduli [Pa], μ_d.
MATERIAL_BASELINE = (
    ParamSpec("E_lin", 5e9, 200e9, 40e9, log=True),
    ParamSpec("E_se", 0.2e9, 60e9, 4e9, log=True),
    ParamSpec("mu_d", 0.0, 0.8, 0.29),
)
#: Material of superelastic nitinol as identify fits it (docs/models.md, "Identification"):
#: E_lin 30-80 GPa in the literature (bounds 15-150 GPa leave room for cut depths a few per cent
#: off the drawing), E_se a few GPa, the transformation onset strain 1-2 % (bounds 0.4-4 %).
MATERIAL = (
    ParamSpec("E_lin", 15e9, 150e9, 50e9, log=True, probes=(35e9, 70e9)),
    ParamSpec("E_se", 0.2e9, 30e9, 4e9, log=True, probes=(1.5e9, 6e9)),
    ParamSpec("strain_lower", 0.004, 0.04, 0.012, log=True, probes=(0.008, 0.018)),
)
#: μ_d of a tendon on the cut edges (capstan law): ~0.05-0.3 for a steel or polymer tendon on nitinol.
CAPSTAN_MU = ParamSpec("mu_d", 0.0, 0.8, 0.1, probes=(0.03, 0.2))
#: μ_s − μ_d held at the paper's 0.01 in the baseline (docs/models.md).
BASELINE_MU_EXCESS = 0.01


def baseline_specs(base: FrictionParams | None = None) -> tuple[ParamSpec, ...]:
    """The diagnosis baseline's fitted parameters for the base model's spring law (start at its values)."""
    base = base or FrictionParams()
    specs = MATERIAL_BASELINE if base.spring_law == "material" else BASELINE
    out = []
    for s in specs:
        v = getattr(base, s.name)
        if isinstance(v, float) and s.lower <= v <= s.upper:
            s = ParamSpec(s.name, s.lower, s.upper, v, s.log, s.probes, s.scale)
        out.append(s)
    return tuple(out)
