"""The baseline of a real tube: identify's calibrated model, with its per-tube unknowns.

On a real tube (an asymmetric-notch tube, a section backbone) the diagnosis
baseline is the model ``notchfit identify`` calibrates (docs/models.md,
"Identification"): the material (``E_lin``, ``E_se``, ``strain_lower``) and
the friction (``μ_d``) shared by every tube, and per tube its rest angles and,
with the material law, its cut-depth offsets under the cutting-tolerance prior.
The per-tube unknowns are identify's own: this module asks
:func:`notchfit.analysis.identify.problem.make_problem` for their blocks,
bounds, starts and prior (and :func:`notchfit.analysis.identify.specs.specs_for`
for the shared parameters), so both engines fit one model of one study and
tell one story about it. A candidate cause is fitted on top of that model.

The seed tube (joints on the axis, the paper's spring law) keeps the paper's
baseline (``k_lin``, ``k_mid``, ``μ_d``): it has no per-tube unknowns.

A fitted model carries the per-tube values beside its shared ones
(:attr:`notchfit.analysis.diagnosis.calibration.Calibration.tubes`); a start dictionary
may hold them under :data:`TUBES` to start a fit from another's optimum.
"""

from __future__ import annotations

import numpy as np

from ...physics.friction import FrictionParams
from ..estimation.problem import with_values
from ..identify.problem import make_problem
from ..identify.specs import DEPTH, DEPTH_COMMON, DEPTH_RANGE, DEPTH_TOLERANCE, REST, REST_RANGE, default_free
from ..identify.specs import specs_for as identify_specs

__all__ = ["TUBES", "has_tube_unknowns", "material_baseline", "mean_tubes", "tube_blocks", "tube_params"]

#: The key of a start dictionary that holds per-tube start values ``{tube: {block: (n,) values}}``.
TUBES = "tubes"


def material_baseline(base: FrictionParams, geoms=()) -> tuple:
    """The shared parameters of identify's default model for tubes ``geoms`` with the material law (E_lin,
    E_se, strain_lower, μ_d, and strain_ratio where a notch's cut face governs; identify's bounds, probes and
    starts)."""
    geoms = list(geoms)
    free = tuple(f for f in default_free([base] * (len(geoms) or 1), geoms) if f not in (REST, DEPTH))
    return identify_specs(free, [base])


def has_tube_unknowns(preps) -> bool:
    """Whether the study's tubes have per-tube unknowns (a section backbone: rest angles and depths)."""
    return any(p.geom.backbone == "section" for p in preps)


def tube_blocks(preps, base: FrictionParams, specs, excess: float, *, start: dict | None = None,
                sim_kw: dict | None = None, rest_range: float = REST_RANGE, depth_range: float = DEPTH_RANGE,
                depth_sigma: float = DEPTH_TOLERANCE, depth_common: float | None = DEPTH_COMMON):
    """Identify's per-tube unknowns of ``preps``: blocks, start, bounds and prior rows.

    Parameters
    ----------
    preps : sequence of Observations
    base : FrictionParams
        The study's base model (every tube's).
    specs : sequence of ParamSpec
        The shared baseline parameters (the prior's columns start after them).
    excess : float
        μ_s − μ_d of the model.
    start : dict, optional
        ``{tube: {block: (n,) values}}``: start values (clipped into the bounds) in place of identify's
        (the rest angles from the samples taken at rest, the depths at the drawing).
    rest_range, depth_range, depth_sigma, depth_common :
        Identify's tolerances (:func:`notchfit.analysis.identify.problem.make_problem`).

    Returns
    -------
    blocks : tuple of Block
    x0, lo, hi : ndarray
        Of the blocks' unknowns, in order.
    prior : ndarray (r, len(specs) + len(x0))
        The priors' rows (rest angles, cut depths) over the shared parameters and the blocks.
    prior_offset : ndarray (r,)
        The priors' means, whitened (the rest angles measured at zero force; zeros for the depths).
    """
    real = any(p.geom.backbone == "section" for p in preps)
    depth = real and base.spring_law == "material"
    tubes = {p.tube: base for p in preps}
    pb = make_problem(preps, tubes, specs, rest=real, depth=depth, excess=excess, sim_kw=sim_kw,
                      rest_range=rest_range, depth_range=depth_range, depth_sigma=depth_sigma,
                      depth_common=depth_common)
    k = len(specs)
    x0, lo, hi = pb.x0[k:].copy(), pb.lo[k:], pb.hi[k:]
    i = 0
    for b in pb.blocks:
        given = (start or {}).get(b.owner, {}).get(b.name)
        if given is not None and np.size(given) == b.size:
            span = hi[i:i + b.size] - lo[i:i + b.size]
            x0[i:i + b.size] = np.clip(given, lo[i:i + b.size] + 1e-9 * span, hi[i:i + b.size] - 1e-9 * span)
        i += b.size
    offset = np.zeros(pb.prior.shape[0]) if pb.prior_offset is None else np.asarray(pb.prior_offset, float)
    return pb.blocks, x0, lo, hi, pb.prior, offset


def tube_params(params: FrictionParams, tube: dict | None) -> FrictionParams:
    """``params`` with one tube's rest angles and cut-depth offsets (``{block: (n,) values}``; None: as drawn)."""
    return with_values(params, {}, 0.0, **(tube or {})) if tube else params


def mean_tubes(tubes_per_fit) -> dict:
    """The mean of several fits' per-tube values (each ``{tube: {block: values}}``), over the fits that
    have the tube."""
    out: dict = {}
    for tubes in tubes_per_fit:
        for t, blocks in (tubes or {}).items():
            for name, v in blocks.items():
                out.setdefault(t, {}).setdefault(name, []).append(np.asarray(v, float))
    return {t: {n: np.mean(vs, axis=0) for n, vs in blocks.items()} for t, blocks in out.items()}
