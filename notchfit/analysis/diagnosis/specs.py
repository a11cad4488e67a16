"""The fitted parameters of the baseline and of each candidate cause.

The baseline is the friction simulator (Sec. IV-B) calibrated: for the paper's
spring law (the seed tube) the linear-range stiffness, the mid-range (plateau)
rate and the sliding friction coefficient — ``k_lin``, ``k_mid``, ``μ_d``
(:mod:`notchfit.analysis.estimation.specs`); for the material law of a real tube
identify's calibrated model — ``E_lin``, ``E_se``, ``strain_lower``, ``μ_d``
shared, plus each tube's rest angles and cut depths
(:mod:`notchfit.analysis.diagnosis.tubes`). Every candidate adds the parameters of
one physical effect the model lacks (its record in :mod:`notchfit.analysis.causes`). A *model* is a tuple of causes: ``()`` the
baseline, ``("joint_hysteresis",)`` one cause, two causes for a pair.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..causes import CAUSES, REGISTRY
from ..estimation.specs import BASELINE, BASELINE_MU_EXCESS, MATERIAL_BASELINE, ParamSpec, StudyScales
from ..estimation.specs import baseline_specs as paper_baseline_specs
from ..estimation.problem import with_values
from ...physics.friction import FrictionParams
from .tubes import material_baseline

__all__ = [
    "BASELINE",
    "BASELINE_MU_EXCESS",
    "CANDIDATES",
    "CAUSES",
    "MATERIAL_BASELINE",
    "PAPER_START",
    "REGISTRATION_BOUNDS",
    "WARP_CENTER_RANGE",
    "WARP_DISTANCE",
    "WARP_PARAMS",
    "WARP_RADIUS",
    "ParamSpec",
    "StudyScales",
    "Thresholds",
    "as_model",
    "baseline_specs",
    "model_key",
    "model_params",
    "specs_for",
]


@dataclass(frozen=True)
class Thresholds:
    """The decision rule's thresholds (:func:`notchfit.analysis.diagnosis.diagnose`), the same for the first
    cause and the second.

    Attributes
    ----------
    none_tol : float
        ``none`` (no second cause) when the held-out mean squared error is below ``1 + none_tol`` times
        the noise floor.
    z_crit : float
        Significance of a held-out improvement (paired z).
    min_excess_removed : float
        Fraction of the excess over the noise floor a candidate must remove.
    """

    none_tol: float = 0.5
    z_crit: float = 3.0
    min_excess_removed: float = 0.3


#: Extension parameters of each cause (:attr:`notchfit.analysis.causes.Cause.params`).
CANDIDATES: dict[str, tuple[ParamSpec, ...]] = {c.id: c.params for c in REGISTRY.values()}
#: Candidates also probed and fitted from the paper's values (:attr:`notchfit.analysis.causes.Cause.paper_start`).
PAPER_START = tuple(c.id for c in REGISTRY.values() if c.paper_start)
#: Bounds of the per-experiment registration corrections fitted with the
#: calibration_error candidate (translation [m], [m], rotation [rad]).
REGISTRATION_BOUNDS = (0.005, 0.005, 0.1)
#: The point-warp parameters (:mod:`notchfit.vision.warp`), not friction parameters: those of the causes that
#: correct the measured points.
WARP_PARAMS = tuple(s.name for c in REGISTRY.values() if c.corrects_points for s in c.params)
#: Radius that normalises the radial warp coefficient [m] (:mod:`notchfit.vision.warp`).
WARP_RADIUS = 0.01
#: Distance from the camera to the bending plane [m] of the tilted-plane term
#: (:func:`notchfit.vision.warp.apply_plane_tilt`): the tilt's perspective term scales with ``|ω| / D``,
#: a wrong distance is absorbed by the tilt and the scale error.
WARP_DISTANCE = 0.25
#: The warp centre is fitted within this distance of the aim point (the straight tube under the registrations,
#: :func:`notchfit.analysis.diagnosis.calibration.calibrate`) [m]; with
#: |k_radial| <= 0.02 the warp stays one-to-one within about 70 mm of its centre.
WARP_CENTER_RANGE = 0.03


def as_model(cause) -> tuple:
    """A model as a tuple of causes: None -> (), ``"a"`` -> ("a",), a sequence -> tuple."""
    if cause is None:
        return ()
    if isinstance(cause, str):
        return (cause,)
    return tuple(cause)


def model_key(model) -> str:
    """The name of a model: ``"baseline"``, a cause id, or ``"a+b"``."""
    m = as_model(model)
    return "+".join(m) if m else "baseline"


def baseline_specs(base: FrictionParams | None = None, geoms=()) -> tuple[ParamSpec, ...]:
    """The baseline's shared parameters: the paper's spring law's ``k_lin``, ``k_mid``, ``μ_d`` (started at
    the base model's values), or for the material law identify's for the study's tubes ``geoms``
    (:func:`notchfit.analysis.diagnosis.tubes.material_baseline`)."""
    base = base or FrictionParams()
    return material_baseline(base, geoms) if base.spring_law == "material" else paper_baseline_specs(base)


def specs_for(cause, base: FrictionParams | None = None, geoms=()) -> tuple[ParamSpec, ...]:
    """The baseline's parameters followed by those of each cause of the model (None: the baseline)."""
    out = baseline_specs(base, geoms)
    for c in as_model(cause):
        out += CANDIDATES[c]
    return out


def model_params(values: dict, base: FrictionParams | None = None) -> tuple[FrictionParams, dict]:
    """Parameter values by name -> (simulator parameters, point-warp values).

    The values replace those of ``base`` (default: the paper's model, Sec. IV-B).
    ``mu_s_excess`` (default :data:`BASELINE_MU_EXCESS`) becomes
    ``mu_s = mu_d + mu_s_excess``; the warp values (:data:`WARP_PARAMS`) are
    returned apart (empty when there are none).
    """
    v = dict(values)
    warp = {k: v.pop(k) for k in WARP_PARAMS if k in v}
    excess = v.pop("mu_s_excess", BASELINE_MU_EXCESS)
    base = base or FrictionParams()
    v.setdefault("mu_d", base.mu_d)
    return with_values(base, v, excess), warp
