"""The fitted parameters of the baseline and of each candidate cause.

The baseline is the paper's friction simulator (Sec. IV-B) with the two
mid-range spring rates and the sliding friction coefficient fitted; every
candidate adds the parameters of one physical effect the paper's model lacks
(docs/diagnosis.md, "Causes").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..friction import FrictionParams

__all__ = [
    "BASELINE",
    "BASELINE_MU_EXCESS",
    "CANDIDATES",
    "CAUSES",
    "REGISTRATION_BOUNDS",
    "WARP_CENTER_RANGE",
    "WARP_PARAMS",
    "WARP_RADIUS",
    "ParamSpec",
    "model_params",
    "specs_for",
]

#: The candidate causes, in the order of docs/diagnosis.md.
CAUSES = ("proximal_friction", "static_friction", "joint_hysteresis", "external_load",
          "stiffness_gradient", "calibration_error")


@dataclass(frozen=True)
class ParamSpec:
    """A fitted parameter: bounds, start value, and whether it is fitted in log space.

    Attributes
    ----------
    name : str
        A :class:`notchfit.friction.FrictionParams` field, ``mu_s_excess``
        (μ_s − μ_d) or a point-warp parameter (:data:`WARP_PARAMS`).
    lower, upper, start : float
        Bounds and start value [SI unit of the parameter].
    log : bool
        Fit ``log(value)`` (positive stiffnesses).
    probes : tuple of float
        Start values tried (one residual evaluation each) before the
        least-squares fit starts from the best: the friction models are only
        piecewise smooth and have local minima along some extension axes.
    """

    name: str
    lower: float
    upper: float
    start: float
    log: bool = False
    probes: tuple = ()

    def to_x(self, v: float) -> float:
        """Value -> optimiser coordinate."""
        return math.log(v) if self.log else v

    def from_x(self, x: float) -> float:
        """Optimiser coordinate -> value."""
        return math.exp(x) if self.log else x

    @property
    def x_bounds(self) -> tuple[float, float]:
        """Bounds in optimiser coordinates."""
        return (self.to_x(self.lower), self.to_x(self.upper))


#: Baseline parameters (docs/models.md): k_lin, k_mid [N m/rad], μ_d [-].
BASELINE = (
    ParamSpec("k_lin", 0.05, 5.0, 0.4829, log=True),
    ParamSpec("k_mid", 0.01, 5.0, 0.25, log=True),
    ParamSpec("mu_d", 0.0, 0.8, 0.29),
)
#: μ_s − μ_d held at the paper's 0.01 in the baseline (docs/models.md).
BASELINE_MU_EXCESS = 0.01

#: Extension parameters of each cause (units: proximal_beta, mu_s_excess,
#: stiffness_gradient, scale_error, k_radial [-]; hysteresis_torque [N m];
#: tip_force_x/z [N]; warp_center_x/y [m]).
CANDIDATES: dict[str, tuple[ParamSpec, ...]] = {
    "proximal_friction": (ParamSpec("proximal_beta", 0.0, 1.5, 0.05,
                                    probes=(0.02, 0.05, 0.1, 0.2, 0.4)),),
    "static_friction": (ParamSpec("mu_s_excess", 0.0, 0.8, 0.05,
                                  probes=tuple(round(0.05 * i, 2) for i in range(17))),),
    "joint_hysteresis": (ParamSpec("hysteresis_torque", 0.0, 0.05, 0.002,
                                   probes=(0.0005, 0.001, 0.002, 0.004, 0.008, 0.016)),),
    "external_load": (ParamSpec("tip_force_x", -3.0, 3.0, 0.0, probes=(-0.3, 0.0, 0.3)),
                      ParamSpec("tip_force_z", -3.0, 3.0, 0.0, probes=(-0.3, 0.0, 0.3))),
    "stiffness_gradient": (ParamSpec("stiffness_gradient", -0.9, 0.9, 0.0,
                                     probes=(-0.5, -0.25, 0.0, 0.25, 0.5)),),
    "calibration_error": (ParamSpec("scale_error", -0.2, 0.2, 0.0, probes=(-0.02, 0.0, 0.02)),
                          ParamSpec("k_radial", -0.02, 0.02, 0.0, probes=(-0.005, 0.0, 0.005)),
                          ParamSpec("warp_center_x", -0.2, 0.2, 0.0),
                          ParamSpec("warp_center_y", -0.2, 0.2, 0.0)),
}
#: Bounds of the per-experiment registration corrections fitted with the
#: calibration_error candidate (translation [m], [m], rotation [rad]).
REGISTRATION_BOUNDS = (0.005, 0.005, 0.1)
#: The point-warp parameters (:mod:`notchfit.warp`), not friction parameters.
WARP_PARAMS = ("scale_error", "k_radial", "warp_center_x", "warp_center_y")
#: Radius that normalises the radial warp coefficient [m] (:mod:`notchfit.warp`).
WARP_RADIUS = 0.01
#: The warp centre is fitted within this distance of the data centroid [m]; with
#: |k_radial| <= 0.02 the warp stays one-to-one within about 70 mm of its centre.
WARP_CENTER_RANGE = 0.03


def specs_for(cause: str | None) -> tuple[ParamSpec, ...]:
    """The baseline's parameters followed by those of ``cause`` (None: the baseline alone)."""
    return BASELINE + (CANDIDATES[cause] if cause else ())


def model_params(values: dict) -> tuple[FrictionParams, dict]:
    """Parameter values by name -> (simulator parameters, point-warp values).

    ``mu_s_excess`` (default :data:`BASELINE_MU_EXCESS`) becomes
    ``mu_s = mu_d + mu_s_excess``; the warp values (:data:`WARP_PARAMS`) are
    returned apart (empty when there are none).
    """
    v = dict(values)
    warp = {k: v.pop(k) for k in WARP_PARAMS if k in v}
    excess = v.pop("mu_s_excess", BASELINE_MU_EXCESS)
    v["mu_s"] = v["mu_d"] + excess
    return FrictionParams(**v), warp
