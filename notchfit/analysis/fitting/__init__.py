"""Least-squares shape fits of measured notch points (Sec. IV-A, Figs. 12–15).

Measured notch points ``Q_i`` live in a metric plane frame; the virtual points
``Q̃_i(θ)`` of the kinematic model (:mod:`notchfit.physics.notches`) live in the
manipulator frame. The two are related by one proper rigid 2-D transform
``P = Rot(φ) M (x, z) + t`` (``M = diag(-1, 1)`` for a mirrored view), the
same for every sample of an experiment because the base does not move
(docs/geometry.md). For each sample and shape model
(:mod:`notchfit.physics.shapes`) the fitter minimizes

    Σ_i ||(Q̃_i(θ(params)) mapped to the plane − Q_i) / σ_i||²  (+ prior)

over the shape parameters; the paper's error metric is the pointwise distance
``e_i = ||Q_i − Q̃_i||`` (Sec. IV-A), reported per point, with its rms and
maximum per sample. (The paper minimizes the *sum* of the distances; the
least-squares fit here is its Gaussian-likelihood counterpart and gives
standard errors, χ², AIC and BIC. A robust loss is available for outliers.)

Procedure of :func:`fit_experiment`
-----------------------------------
1. **First pass (closed form, robust).** Each sample's base-link points
   (link 0: the two base corners and the proximal corner of slot 1) give the
   transform by a 2-D Procrustes fit; the median over samples is the start.
   Without base-link points, link 1's pose and the assumption θ₁ ≈ θ₂ are
   used. The joint angles are then estimated link by link from each link's
   points (:func:`estimate_angles`).
2. **Joint fit of the shared transform.** One least-squares problem over the
   transform (t_x, t_y, φ) and every sample's parameters of the
   ``transform_model`` (default ``free``: all n angles, so that no shape
   assumption biases the transform). Its normal matrix is block-arrow shaped,
   so each Levenberg–Marquardt step is reduced to the 3 transform unknowns by
   a Schur complement and solved exactly, batched over samples, with
   analytic Jacobians (:func:`fit_transform`).
3. **Per-sample fits** of every requested model with the transform fixed:
   a batched Levenberg–Marquardt over all samples at once (analytic
   Jacobians, per-sample damping and convergence), started from the joint
   fit's θ (:func:`fit_samples`). ``solver="scipy"`` runs
   ``scipy.optimize.least_squares`` per sample instead; the tests check that
   both reach the same optimum.

Uncertainty
-----------
Residuals are whitened by the per-point uncertainty σ (scalar or (S, m));
with ``sigma=None`` σ is estimated once per experiment from the pooled
residuals of the ``transform_model`` fit (dof-corrected; a MAD estimate with
a robust loss) and used for every model, so that χ², AIC and BIC are
comparable across models. Covariances are Gauss–Newton, ``(JᵀJ)⁻¹`` of the
whitened problem (σ treated as known, i.e. absolute); with a robust loss the
rows are weighted by ``ρ'``. With the transform estimated,
``include_transform_uncertainty=True`` adds its propagated covariance,
``Cov(p) = A⁻¹ + G Cov(t) Gᵀ`` with ``G = A⁻¹ J_pᵀ J_t`` (implicit-function
sensitivity of the sample's optimum to the transform); the transform
covariance is the Schur complement of the joint problem. Ignoring the
correlation between the transform estimate and the sample's own noise is an
O(1/S) approximation. The effective number of parameters of a model is the
trace of its hat matrix (= n_params without a prior, less with the
``free_smooth`` prior); χ² = Σ (r/σ)² over the points, AIC = χ² + 2k,
BIC = χ² + k ln N with N = 2 · n_points.

Gauge: a rotation of the plane transform about the manipulator origin and
an equal and opposite change of θ₁ move every point on links ≥ 1 identically;
only the base-link points tell them apart. With them (58-point layout) the
problem is well posed; without them the ``free`` model cannot separate φ
from θ₁ and the transform is reported as not identifiable
(``PlaneTransform.identifiable``), whereas low-dimensional models (cc,
linear) still pin it through their shape constraint.

Units: SI inside (m, rad); the tables (:func:`fits_table`,
:func:`pointwise_table`) use the file columns of docs/data-formats.md (mm, rad).

Modules: :mod:`~notchfit.analysis.fitting.results` (result types),
:mod:`~notchfit.analysis.fitting.first_pass` (input checks and the closed-form
start), :mod:`~notchfit.analysis.fitting.lm` (the batched Levenberg–Marquardt),
:mod:`~notchfit.analysis.fitting.core` (the fits), :mod:`~notchfit.analysis.fitting.tables`
(file tables and model comparison), :mod:`~notchfit.analysis.fitting.angles` (the
shape models fitted to measured joint angles, ``angles.csv``). Synthetic points for tests and demos:
:func:`notchfit.studies.synth.synthetic_points`.
"""

from __future__ import annotations

from .angles import AngleFit, ModelAngleFit, angle_fits_table, fit_angles, jointwise_table
from .core import fit_experiment, fit_sample, fit_samples, fit_transform
from .first_pass import estimate_angles, initial_transform
from .results import ExperimentFit, PlaneTransform, SampleFit
from .tables import StudyFit, compare_models, failed_fits, fit_summary, fits_table, pointwise_table

__all__ = [
    "AngleFit",
    "ExperimentFit",
    "ModelAngleFit",
    "angle_fits_table",
    "PlaneTransform",
    "SampleFit",
    "StudyFit",
    "compare_models",
    "estimate_angles",
    "failed_fits",
    "fit_experiment",
    "fit_sample",
    "fit_samples",
    "fit_summary",
    "fit_angles",
    "fit_transform",
    "fits_table",
    "initial_transform",
    "jointwise_table",
    "pointwise_table",
]
