"""Least-squares shape fits of measured notch points (Sec. IV-A, Figs. 12–15).

Measured notch points ``Q_i`` live in a metric plane frame; the virtual points
``Q̃_i(θ)`` of the kinematic model (:mod:`notchfit.notches`) live in the
manipulator frame. The two are related by one proper rigid 2-D transform
``P = Rot(φ) M (x, z) + t`` (``M = diag(-1, 1)`` for a mirrored view), the
same for every sample of an experiment because the base does not move
(``../shared/spec/geometry.md``). For each sample and shape model
(:mod:`notchfit.shapes`) the fitter minimizes

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
   both reach the same optimum. (A generic sparse ``least_squares`` on the
   joint problem was tried first: 0.3–0.6 s and up to 100 evaluations for
   20 samples of the free model, against about 20 ms here.)

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
:func:`pointwise_table`) use the file columns of
``../shared/spec/data-format.md`` (mm, rad).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from .geometry import Geometry, notch_layout
from .notches import from_plane, notch_points, notch_points_and_jacobian, plane_params_jacobian, to_plane
from .shapes import ShapeModel, get_model, linear

__all__ = [
    "ExperimentFit",
    "PlaneTransform",
    "SampleFit",
    "compare_models",
    "estimate_angles",
    "fit_experiment",
    "fit_sample",
    "fit_samples",
    "fit_transform",
    "fits_table",
    "initial_transform",
    "pointwise_table",
    "synthetic_points",
]

_MM = 1e-3
_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


# ==========================================================================
# Result objects
# ==========================================================================
@dataclass(frozen=True)
class PlaneTransform:
    """The rigid plane transform ``P = Rot(φ) M (x, z) + t`` of one experiment.

    Attributes
    ----------
    tx, ty : float
        Where the manipulator origin (joint 1) lands in the plane [m].
    phi : float
        Rotation [rad].
    mirror : bool
        ``M = diag(-1, 1)`` (a view from -y) when true.
    cov : ndarray, shape (3, 3)
        Covariance of (t_x [m], t_y [m], φ [rad]); zeros when fixed, inf when
        not identifiable.
    fixed : bool
        Given by the caller rather than estimated.
    model : str
        The shape model it was estimated jointly with ('' when fixed).
    identifiable : bool
        False when the data cannot separate φ from the shape (see module doc).
    success : bool
    message : str
    nfev : int
        Residual evaluations of the joint fit.
    """

    tx: float
    ty: float
    phi: float
    mirror: bool = False
    cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)), repr=False, compare=False)
    fixed: bool = True
    model: str = ""
    identifiable: bool = True
    success: bool = True
    message: str = ""
    nfev: int = 0

    @property
    def params(self) -> np.ndarray:
        """(t_x [m], t_y [m], φ [rad])."""
        return np.array([self.tx, self.ty, self.phi])

    @property
    def se(self) -> np.ndarray:
        """Standard errors of (t_x [m], t_y [m], φ [rad])."""
        return np.sqrt(np.diag(self.cov))

    def to_plane(self, points) -> np.ndarray:
        """Manipulator-frame (x, z) [m] → plane frame (x, y) [m], shape (..., m, 2)."""
        return to_plane(points, self.tx, self.ty, self.phi, self.mirror)

    def from_plane(self, points) -> np.ndarray:
        """Plane frame (x, y) [m] → manipulator-frame (x, z) [m], shape (..., m, 2)."""
        return from_plane(points, self.tx, self.ty, self.phi, self.mirror)


@dataclass(frozen=True)
class SampleFit:
    """One sample fitted with one shape model (Sec. IV-A).

    Attributes
    ----------
    sample : object
        The sample's id.
    model : str
        Shape model name.
    param_names : tuple of str
    params : ndarray, shape (k,)
        Fitted parameters [rad]; NaN when failed.
    cov : ndarray, shape (k, k)
        Parameter covariance [rad²] (with the transform's uncertainty when
        requested, see the module doc); NaN when failed.
    theta : ndarray, shape (n,)
        Fitted joint angles [rad].
    basis : ndarray, shape (n, k)
        The model's ``∂θ/∂params``.
    predicted : ndarray, shape (m, 2)
        Virtual notch points ``Q̃_i`` in the plane frame [m].
    residuals : ndarray, shape (m, 2)
        ``Q̃_i − Q_i`` [m]; NaN for missing points.
    sigma : ndarray, shape (m,)
        Point uncertainty used [m] (NaN for missing points).
    n_points : int
        Points used.
    k_eff : float
        Effective number of parameters (trace of the hat matrix).
    chi2 : float
        ``Σ ||r_i / σ_i||²`` over the points (prior excluded).
    success : bool
    message : str
    nfev : int
    """

    sample: object
    model: str
    param_names: tuple
    params: np.ndarray = field(repr=False)
    cov: np.ndarray = field(repr=False)
    theta: np.ndarray = field(repr=False)
    basis: np.ndarray = field(repr=False)
    predicted: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    n_points: int = 0
    k_eff: float = float("nan")
    chi2: float = float("nan")
    success: bool = False
    message: str = ""
    nfev: int = 0

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def errors(self) -> np.ndarray:
        """Pointwise error ``||Q_i − Q̃_i||`` (Sec. IV-A) [m], shape (m,), NaN if missing."""
        return np.hypot(self.residuals[:, 0], self.residuals[:, 1])

    @property
    def rms(self) -> float:
        """Root mean square of the pointwise errors [m]."""
        e = self.errors
        e = e[np.isfinite(e)]
        return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")

    @property
    def max_error(self) -> float:
        """Largest pointwise error [m]."""
        e = self.errors
        e = e[np.isfinite(e)]
        return float(e.max()) if e.size else float("nan")

    @property
    def residual_std(self) -> float:
        """Per-coordinate residual standard deviation, dof-corrected [m]:
        ``sqrt(Σ r² / (2 n_points − k_eff))``; estimates the point noise."""
        r = self.residuals[np.isfinite(self.residuals)]
        dof = r.size - self.k_eff
        return float(np.sqrt(np.sum(r * r) / dof)) if dof > 0 else float("nan")

    @property
    def se(self) -> np.ndarray:
        """Standard errors of the parameters [rad]."""
        return np.sqrt(np.diag(self.cov))

    @property
    def aic(self) -> float:
        """``χ² + 2 k_eff`` (Gaussian likelihood with known σ, up to a constant)."""
        return self.chi2 + 2.0 * self.k_eff

    @property
    def bic(self) -> float:
        """``χ² + k_eff ln(2 n_points)``."""
        return self.chi2 + self.k_eff * math.log(max(2 * self.n_points, 1))

    def _ab(self):
        names = self.param_names
        if names[:2] == ("a", "b"):
            return self.params[:2], self.cov[:2, :2]
        if names == ("a",):
            return (np.array([self.params[0], 0.0]),
                    np.array([[self.cov[0, 0], 0.0], [0.0, 0.0]]))
        # least-squares line through θ_j: (a, b) = L θ, L = pinv([1, j])
        L = _line_projector(len(self.theta))
        th_cov = self.basis @ self.cov @ self.basis.T
        return L @ self.theta, L @ th_cov @ L.T

    @property
    def theta_cov(self) -> np.ndarray:
        """Covariance of the fitted joint angles [rad²], shape (n, n)."""
        return self.basis @ self.cov @ self.basis.T

    @property
    def a(self) -> float:
        """``a`` of ``θ_j = a + b j`` [rad]: literal for cc/linear/quadratic, else the
        least-squares line through the fitted θ_j."""
        return float(self._ab()[0][0])

    @property
    def b(self) -> float:
        """``b`` [rad]: literal for linear/quadratic, 0 for cc, else the least-squares
        line through the fitted θ_j."""
        return float(self._ab()[0][1])

    @property
    def se_a(self) -> float:
        """Standard error of :attr:`a` [rad]."""
        return float(np.sqrt(self._ab()[1][0, 0]))

    @property
    def se_b(self) -> float:
        """Standard error of :attr:`b` [rad] (0 for cc, where b is fixed)."""
        return float(np.sqrt(self._ab()[1][1, 1]))


@functools.lru_cache(maxsize=16)
def _line_projector(n: int) -> np.ndarray:
    L = np.linalg.pinv(linear(n).basis)
    L.setflags(write=False)
    return L


@dataclass(frozen=True)
class ExperimentFit:
    """All samples of one experiment fitted with several models.

    Attributes
    ----------
    transform : PlaneTransform
        The shared plane transform.
    models : tuple of str
    samples : tuple
        Sample ids, in order.
    fits : tuple of tuple of SampleFit
        ``fits[model_index][sample_index]``.
    points : ndarray, shape (S, m, 2)
        Measured points in the plane frame [m] (NaN where missing).
    sigma : ndarray, shape (S, m)
        Point uncertainty used [m].
    sigma_estimated : bool
        σ was estimated from the residuals (``sigma=None``).
    geom : Geometry
    loss : str
    f_scale : float
        Robust-loss scale in σ units.
    """

    transform: PlaneTransform
    models: tuple
    samples: tuple
    fits: tuple = field(repr=False)
    points: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    sigma_estimated: bool = False
    geom: Geometry = field(default=None, repr=False)
    loss: str = "linear"
    f_scale: float = 2.0

    def model_fits(self, model: str) -> tuple:
        """The :class:`SampleFit` of every sample for ``model``."""
        try:
            return self.fits[self.models.index(model)]
        except ValueError:
            raise ValueError(f"model {model!r} was not fitted; fitted: {', '.join(self.models)}") from None

    def get(self, model: str, sample) -> SampleFit:
        """The fit of sample id ``sample`` with ``model``."""
        try:
            s = self.samples.index(sample)
        except ValueError:
            raise ValueError(f"no sample {sample!r} in this experiment") from None
        return self.model_fits(model)[s]

    def errors(self, model: str) -> np.ndarray:
        """Pointwise errors ``||Q_i − Q̃_i||`` [m], shape (S, m) (Figs. 13–14)."""
        return np.stack([f.errors for f in self.model_fits(model)])

    def params(self, model: str) -> np.ndarray:
        """Fitted parameters [rad], shape (S, k)."""
        return np.stack([f.params for f in self.model_fits(model)])

    def ab(self, model: str = "linear"):
        """``(a, b, se_a, se_b)`` arrays of shape (S,) [rad] (Fig. 15)."""
        fs = self.model_fits(model)
        return tuple(np.array([getattr(f, k) for f in fs]) for k in ("a", "b", "se_a", "se_b"))

    def theta(self, model: str) -> np.ndarray:
        """Fitted joint angles [rad], shape (S, n)."""
        return np.stack([f.theta for f in self.model_fits(model)])


# ==========================================================================
# Input checks
# ==========================================================================
def _as_points(points, geom: Geometry) -> np.ndarray:
    Q = np.asarray(points, dtype=float)
    m = geom.n_points
    if Q.ndim == 2:
        Q = Q[None]
    if Q.ndim != 3 or Q.shape[1:] != (m, 2):
        raise ValueError(
            f"points must have shape (S, {m}, 2) or ({m}, 2) (plane-frame x, y [m]), "
            f"got {np.shape(points)}")
    if np.isinf(Q).any():
        raise ValueError("points contain inf; mark missing points with NaN")
    Q = Q.copy()
    bad = ~np.isfinite(Q).all(axis=-1)
    Q[bad] = np.nan
    return Q


def _as_sigma(sigma, shape) -> np.ndarray:
    S, m = shape
    s = np.asarray(sigma, dtype=float)
    try:
        s = np.broadcast_to(s, (S, m)).copy()
    except ValueError:
        raise ValueError(
            f"sigma must be a scalar, shape ({m},) or ({S}, {m}) [m], got shape {np.shape(sigma)}") from None
    if (s[np.isfinite(s)] <= 0).any():
        raise ValueError("sigma must be positive (point uncertainty [m]); use NaN to drop a point")
    return s


def _check_loss(loss, f_scale):
    if loss not in _LOSSES:
        raise ValueError(f"loss must be one of {_LOSSES}, got {loss!r}")
    if not (isinstance(f_scale, (int, float)) and math.isfinite(f_scale) and f_scale > 0):
        raise ValueError(f"f_scale must be a positive number (in units of sigma), got {f_scale!r}")


def _loss_weights(z_sq, loss):
    """``ρ'(z)`` of scipy's losses at ``z = (r / f_scale)²``."""
    if loss == "linear":
        return np.ones_like(z_sq)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z_sq)
    if loss == "huber":
        return np.where(z_sq <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z_sq, 1.0)))
    if loss == "cauchy":
        return 1.0 / (1.0 + z_sq)
    if loss == "arctan":
        return 1.0 / (1.0 + z_sq * z_sq)
    raise ValueError(loss)


def _rm(phi, mirror):
    c, s = math.cos(phi), math.sin(phi)
    R = np.array([[c, -s], [s, c]])
    return R @ np.diag([-1.0, 1.0]) if mirror else R


# ==========================================================================
# Closed-form first pass
# ==========================================================================
def _procrustes(src, dst):
    """Rigid fit ``dst ≈ Rot(β) src + o`` per leading index, NaN-aware.

    src : (..., k, 2) model coordinates; dst : (..., k, 2) with NaN rows.
    Returns β (...,), o (..., 2), count (...,).
    """
    ok = np.isfinite(dst).all(axis=-1)
    cnt = ok.sum(axis=-1)
    w = ok.astype(float)
    src = np.broadcast_to(src, dst.shape)
    d = np.where(ok[..., None], dst, 0.0)
    sw = np.maximum(cnt, 1)[..., None]
    cs = (src * w[..., None]).sum(-2) / sw
    cd = d.sum(-2) / sw
    a = (src - cs[..., None, :]) * w[..., None]
    b = (d - cd[..., None, :]) * w[..., None]
    dot = (a * b).sum((-1, -2))
    cross = (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]).sum(-1)
    beta = np.arctan2(cross, dot)
    c, s = np.cos(beta), np.sin(beta)
    rot_cs = np.stack([c * cs[..., 0] - s * cs[..., 1], s * cs[..., 0] + c * cs[..., 1]], -1)
    beta = np.where(cnt >= 2, beta, np.nan)
    o = np.where((cnt >= 2)[..., None], cd - rot_cs, np.nan)
    return beta, o, cnt


def _circ_median(x):
    x = x[np.isfinite(x)]
    ref = np.angle(np.mean(np.exp(1j * x)))
    return float(ref + np.median(np.angle(np.exp(1j * (x - ref)))))


def initial_transform(points, geom: Geometry, mirror: bool = False):
    """Robust closed-form first estimate of the plane transform.

    Each sample's base-link points (link 0, fixed whatever θ) are matched to
    their model coordinates by a 2-D Procrustes fit; the (circular) median
    over samples is returned. Without any sample with two base-link points,
    link 1's pose is used with θ₁ ≈ θ₂ (from link 2's pose).

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Measured plane-frame points [m], NaN where missing.
    geom : Geometry
    mirror : bool

    Returns
    -------
    (tx, ty, phi) : tuple of float
        [m, m, rad].
    """
    Q = _as_points(points, geom)
    lay = notch_layout(geom)
    M = np.array([-1.0, 1.0]) if mirror else np.ones(2)

    def link_pose(link):
        idx = np.nonzero(lay.link == link)[0]
        return _procrustes(lay.local[idx] * M, Q[:, idx])

    beta0, o0, _ = link_pose(0)
    if np.isfinite(beta0).any():
        ok = np.isfinite(beta0)
        return (float(np.median(o0[ok, 0])), float(np.median(o0[ok, 1])), _circ_median(beta0))
    if geom.n_joints >= 2:
        beta1, o1, _ = link_pose(1)
        beta2, _, _ = link_pose(2)
        # β_l = φ − s Σ_{k≤l} θ_k (s = ±1 for mirror), so 2β₁ − β₂ = φ − s(θ₁ − θ₂) ≈ φ
        phi = 2 * beta1 - beta2
        ok = np.isfinite(phi)
        if ok.any():
            return (float(np.median(o1[ok, 0])), float(np.median(o1[ok, 1])), _circ_median(phi[ok]))
    raise ValueError(
        "cannot place the manipulator in the plane: no sample has two points on the base "
        "link (points on link 0) or on links 1 and 2; pass transform=(tx, ty, phi) explicitly")


def estimate_angles(points, geom: Geometry, transform) -> np.ndarray:
    """Closed-form joint-angle estimate from each link's points (first pass).

    The points are mapped into the manipulator frame; walking from the base,
    each link's orientation is the rotation that best maps its link-local
    notch points onto the measured ones about its joint (whose position
    follows from the previous links). Links without points continue the
    previous angle increment.

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Plane-frame points [m].
    geom : Geometry
    transform : PlaneTransform or (tx, ty, phi, mirror)

    Returns
    -------
    ndarray, shape (S, n)
        θ estimates [rad]; NaN for a sample with no points beyond the base.
    """
    Q = _as_points(points, geom)
    T = _as_transform(transform)
    X = T.from_plane(Q)
    lay = notch_layout(geom)
    S, n, p = Q.shape[0], geom.n_joints, geom.p
    phis = np.zeros((S, n + 1))
    q = np.zeros((S, 2))
    seen = np.zeros(S, dtype=bool)
    for link in range(1, n + 1):
        if link >= 2:
            q = q + p * np.stack([np.sin(phis[:, link - 1]), np.cos(phis[:, link - 1])], -1)
        idx = np.nonzero(lay.link == link)[0]
        L = lay.local[idx]                                   # (k, 2)
        d = X[:, idx] - q[:, None, :]                        # (S, k, 2)
        ok = np.isfinite(d).all(-1)
        d0 = np.where(ok[..., None], d, 0.0)
        C = (d0[..., 0] * L[:, 0] + d0[..., 1] * L[:, 1]).sum(-1)
        Sn = (d0[..., 0] * L[:, 1] - d0[..., 1] * L[:, 0]).sum(-1)
        has = ok.any(-1)
        prev = phis[:, link - 1]
        inc = phis[:, link - 1] - phis[:, link - 2] if link >= 2 else np.zeros(S)
        est = np.arctan2(Sn, C)
        # unwrap relative to the extrapolated orientation
        guess = prev + inc
        est = guess + np.angle(np.exp(1j * (est - guess)))
        phis[:, link] = np.where(has, est, guess)
        seen |= has
    theta = np.diff(phis, axis=1)
    theta[~seen] = np.nan
    return theta


def _as_transform(transform, mirror=None) -> PlaneTransform:
    if isinstance(transform, PlaneTransform):
        return transform
    vals = tuple(transform)
    if len(vals) == 4:
        tx, ty, phi, mir = vals
    elif len(vals) == 3:
        tx, ty, phi = vals
        mir = bool(mirror) if mirror is not None else False
    else:
        raise ValueError(f"transform must be (tx, ty, phi[, mirror]) [m, m, rad], got {transform!r}")
    tx, ty, phi = (float(v) for v in (tx, ty, phi))
    if not all(math.isfinite(v) for v in (tx, ty, phi)):
        raise ValueError(f"transform values must be finite, got {transform!r}")
    return PlaneTransform(tx, ty, phi, bool(mir))


# ==========================================================================
# Residuals and Jacobians of many samples at once
# ==========================================================================
def _rho(z, loss):
    """scipy's loss ``ρ(z)`` at ``z = (r / f_scale)²``."""
    if loss == "linear":
        return z
    if loss == "soft_l1":
        return 2.0 * (np.sqrt(1.0 + z) - 1.0)
    if loss == "huber":
        return np.where(z <= 1.0, z, 2.0 * np.sqrt(np.maximum(z, 1.0)) - 1.0)
    if loss == "cauchy":
        return np.log1p(z)
    if loss == "arctan":
        return np.arctan(z)
    raise ValueError(loss)


class _Problem:
    """Whitened residuals ``(Q̃ − Q)/σ`` of S samples for one model.

    Rows are (S, 2m) in the order x₁, y₁, x₂, …; a missing point's rows have
    weight 0 (residual and Jacobian rows are zero).
    """

    def __init__(self, Q, sig, geom, model: ShapeModel, mirror):
        self.valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
        self.W = np.where(self.valid, 1.0 / np.where(self.valid, sig, 1.0), 0.0)
        self.Q0 = np.where(self.valid[..., None], Q, 0.0)
        self.geom, self.model, self.mirror = geom, model, bool(mirror)
        self.S, self.m = self.W.shape

    def residuals(self, t, P):
        theta = P @ self.model.basis.T
        plane = to_plane(notch_points(theta, self.geom), t[0], t[1], t[2], self.mirror)
        return ((plane - self.Q0) * self.W[..., None]).reshape(self.S, -1)

    def evaluate(self, t, P):
        """r (S, 2m), J_p (S, 2m, k), J_t (S, 2m, 3), plane points (S, m, 2), θ (S, n)."""
        B = self.model.basis
        theta = P @ B.T
        pts, jth = notch_points_and_jacobian(theta, self.geom)
        plane = to_plane(pts, t[0], t[1], t[2], self.mirror)
        W = self.W[..., None]
        r = ((plane - self.Q0) * W).reshape(self.S, -1)
        RM = _rm(t[2], self.mirror)
        jp = np.einsum("ab,smbn->sman", RM, jth, optimize=True) @ B
        Jp = (jp * W[..., None]).reshape(self.S, 2 * self.m, -1)
        Jt = (plane_params_jacobian(pts, t[2], self.mirror) * W[..., None]).reshape(self.S, 2 * self.m, 3)
        return r, Jp, Jt, plane, theta


def _lm(prob: _Problem, t, P, *, joint: bool, loss: str, f_scale: float, ftol: float,
        xtol: float, max_iter: int, mu0: float = 1e-4, mu_max: float = 1e10):
    """Levenberg–Marquardt on the block-arrow problem (batched over samples).

    ``joint``: the transform ``t`` (in m, m, rad) is a shared unknown; the
    normal equations are reduced to it by the Schur complement of the
    per-sample blocks, with one damping factor. Otherwise every sample is an
    independent problem with its own damping and convergence test. A robust
    loss is handled by iteratively reweighted Gauss–Newton steps (weights
    ``ρ'``) whose acceptance is tested on the true robust cost, so the fixed
    point is that of ``scipy.optimize.least_squares`` with the same loss.
    The prior rows are not robustified.

    Returns t, P, converged (S,), iterations, r, Jp, Jt, plane, theta at the end.
    """
    D = prob.model.prior_jacobian()
    DtD = D.T @ D
    S, k = P.shape
    f2 = f_scale * f_scale
    tscale = np.array([_MM, _MM, 1.0])               # step tests with t in mm

    def cost_of(r, P):
        return 0.5 * (f2 * _rho(r * r / f2, loss).sum(-1) + ((P @ D.T) ** 2).sum(-1))

    t = np.asarray(t, dtype=float).copy()
    P = np.asarray(P, dtype=float).copy()
    r, Jp, Jt, plane, theta = prob.evaluate(t, P)
    cost = cost_of(r, P)
    done = np.zeros(S, dtype=bool)
    mu = np.full(S, mu0)
    eye = np.eye(k)
    it = 0
    for it in range(1, max_iter + 1):
        w = _loss_weights(r * r / f2, loss)
        JpW = Jp * w[..., None]
        A = np.einsum("sri,srj->sij", JpW, Jp) + DtD
        g = np.einsum("sri,sr->si", JpW, r) + P @ DtD
        dA = np.diagonal(A, axis1=1, axis2=2)
        dA = np.maximum(dA, np.maximum(1e-12 * dA.max(-1, keepdims=True), 1e-30))
        if joint:
            JtW = Jt * w[..., None]
            Bm = np.einsum("sri,srj->sij", JpW, Jt)
            C = np.einsum("sri,srj->ij", JtW, Jt)
            gt = np.einsum("sri,sr->i", JtW, r)
            dC = np.maximum(np.diag(C), 1e-12 * np.diag(C).max())

            def step(mu_):
                Am = A + mu_ * dA[:, :, None] * eye
                AiB = np.linalg.solve(Am, Bm)
                Aig = np.linalg.solve(Am, g[..., None])[..., 0]
                Sc = C + mu_ * np.diag(dC) - np.einsum("sia,sib->ab", Bm, AiB)
                rhs = gt - np.einsum("sia,si->a", Bm, Aig)
                dt_ = -np.linalg.solve(Sc, rhs)
                return dt_, -(Aig + AiB @ dt_)

            dt, dP = step(mu[0])
            dt0, dP0 = step(1e-12)
            # Newton decrement of the undamped Gauss–Newton step
            decr = np.full(S, -0.5 * (gt @ dt0 + np.sum(g * dP0)))
        else:
            dt = np.zeros(3)
            Am = A + mu[:, None, None] * dA[:, :, None] * eye
            dP = -np.linalg.solve(Am, g[..., None])[..., 0]
            dP[done] = 0.0
            dP0 = -np.linalg.solve(A + 1e-12 * dA[:, :, None] * eye, g[..., None])[..., 0]
            decr = -0.5 * np.sum(g * dP0, axis=-1)
        # at a minimum to precision: the Gauss–Newton model predicts no decrease
        done |= decr <= ftol * (cost + f2) + 1e-14
        if done.all():
            break
        t_new, P_new = t + dt, P + dP
        r_new = prob.residuals(t_new, P_new)
        cost_new = cost_of(r_new, P_new)
        if joint:
            accept = np.full(S, cost_new.sum() <= cost.sum())
            dec = np.full(S, cost.sum() - cost_new.sum())
            ref = np.full(S, cost.sum())
            step = np.full(S, np.linalg.norm(np.concatenate([dt / tscale, dP.ravel()])))
            xnorm = np.full(S, np.linalg.norm(np.concatenate([t / tscale, P.ravel()])))
        else:
            accept = (cost_new <= cost) & ~done
            dec, ref = cost - cost_new, cost
            step = np.linalg.norm(dP, axis=-1)
            xnorm = np.linalg.norm(P, axis=-1)
        small = (dec <= ftol * ref + 1e-14) | (step <= xtol * (xnorm + xtol))
        small &= mu < 1.0                      # a tiny step is meaningful only when barely damped
        if accept.any():
            if joint:
                t = t_new
            P = np.where(accept[:, None], P_new, P)
            newly = accept & small
            r_acc, Jp_acc, Jt_acc, plane_acc, th_acc = prob.evaluate(t, P)
            r, Jp, Jt, plane, theta = r_acc, Jp_acc, Jt_acc, plane_acc, th_acc
            cost = cost_of(r, P)
            done |= newly
        mu = np.where(accept, np.maximum(mu / 3.0, 1e-12), mu * 4.0)
        done |= (mu > mu_max) & ~done          # no decrease possible: at a minimum to precision
        if done.all():
            break
    return t, P, done, it, r, Jp, Jt, plane, theta


def _psd_inverse(A, rcond: float = 1e-13):
    """Inverse of a stack of symmetric positive semi-definite matrices (..., k, k).

    Diagonally scaled batched inverse; a matrix that is singular to ``rcond``
    gets its pseudo-inverse instead (one by one, rare). Avoids batched
    eigendecompositions, which are slow under BLAS threading.
    """
    A = np.asarray(A, dtype=float)
    d = np.sqrt(np.maximum(np.diagonal(A, axis1=-2, axis2=-1), 1e-300))
    As = A / (d[..., :, None] * d[..., None, :])
    flat = As.reshape(-1, *As.shape[-2:])
    out = np.empty_like(flat)
    try:
        out[:] = np.linalg.inv(flat)
        bad = ~np.isfinite(out).all((-1, -2)) | (np.abs(out).max((-1, -2)) * rcond > 1.0)
    except np.linalg.LinAlgError:
        bad = np.ones(len(flat), dtype=bool)
    for i in np.nonzero(bad)[0]:
        out[i] = np.linalg.pinv(flat[i], rcond=rcond, hermitian=True)
    out = out.reshape(As.shape)
    return out / (d[..., :, None] * d[..., None, :])


def _schur_cov(Jp, Jt, r, w_rho, DtD, tol):
    """Transform covariance from the joint normal matrix (Schur complement)."""
    JpW = Jp * w_rho[..., None]
    A = np.einsum("sri,srj->sij", JpW, Jp) + DtD
    Bm = np.einsum("sri,srj->sij", JpW, Jt)
    C = np.einsum("sri,srj->ij", Jt * w_rho[..., None], Jt)
    Ainv = _psd_inverse(A)
    Mt = C - np.einsum("sia,sij,sjb->ab", Bm, Ainv, Bm)
    # identifiable when the shape parameters leave the transform some information of
    # its own: the Schur diagonal relative to the full diagonal (the fraction of each
    # transform parameter's information not explained away by the shapes), and no
    # near-degenerate combination of the three (correlation-normalized eigenvalues)
    kept = np.diag(Mt) / np.maximum(np.diag(C), 1e-300)
    d = np.sqrt(np.maximum(np.diag(Mt), 1e-300))
    eig = np.linalg.eigvalsh(Mt / np.outer(d, d))
    identifiable = bool(kept.min() > tol and eig.min() > tol)
    return (np.linalg.inv(Mt) if identifiable else np.full((3, 3), np.inf)), identifiable


# ==========================================================================
# Joint fit of the shared transform
# ==========================================================================
def fit_transform(points, geom: Geometry, model="free", *, mirror: bool = False, sigma=2e-5,
                  loss: str = "linear", f_scale: float = 2.0, x0=None, theta0=None,
                  ftol: float = 1e-10, xtol: float = 1e-10, max_iter: int = 100,
                  identifiability_tol: float = 1e-8):
    """Jointly fit the shared plane transform and every sample's shape.

    One least-squares problem over (t_x, t_y, φ) and each sample's parameters
    of ``model``. Its normal matrix is block-arrow shaped (each residual
    depends on the transform and on its own sample only), so each
    Levenberg–Marquardt step is reduced to the three transform unknowns by a
    Schur complement and solved exactly, batched over samples (analytic
    Jacobians throughout). Samples with too few points for ``model`` are
    left out.

    Parameters
    ----------
    points : array_like, shape (S, m, 2)
        Plane-frame points [m], NaN where missing.
    geom : Geometry
    model : str or ShapeModel
    mirror : bool
    sigma : float or array_like, shape (S, m)
        Point uncertainty [m].
    loss, f_scale : str, float
        Loss (as ``scipy.optimize.least_squares``) and its scale in σ units.
    x0 : (tx, ty, phi), optional
        Start [m, m, rad]; :func:`initial_transform` when omitted.
    theta0 : array_like, shape (S, n), optional
        Start angles; :func:`estimate_angles` when omitted.
    ftol, xtol : float
        Relative tolerances on the cost decrease and on the step.
    max_iter : int
        Iteration limit.
    identifiability_tol : float
        Smallest allowed fraction of each transform parameter's information
        that survives eliminating the shapes (Schur-complement diagonal over
        the full diagonal; about 1e-3 for φ with the three base-link points,
        1e-14 without them under the ``free`` model) and smallest
        eigenvalue of the correlation-normalized Schur complement; below
        either the transform is reported as not identifiable (infinite
        covariance).

    Returns
    -------
    transform : PlaneTransform
    params : ndarray, shape (S, k)
        The samples' parameters at the joint optimum (NaN for left-out samples).
    """
    _check_loss(loss, f_scale)
    Q = _as_points(points, geom)
    S, m = Q.shape[:2]
    sig = _as_sigma(sigma, (S, m))
    model = get_model(model, geom.n_joints)
    k = model.n_params
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    use = 2 * valid.sum(1) > k
    if not use.any():
        raise ValueError(f"no sample has enough points to fit model {model.name!r} "
                         f"({k} parameters)")
    t0 = initial_transform(Q, geom, mirror) if x0 is None else tuple(float(v) for v in x0)[:3]
    if theta0 is None:
        theta0 = estimate_angles(Q, geom, (*t0, mirror))
    theta0 = np.nan_to_num(np.asarray(theta0, dtype=float)[use])
    prob = _Problem(Q[use], sig[use], geom, model, mirror)
    t, P, conv, nit, r, Jp, Jt, _, _ = _lm(prob, np.array(t0), model.initial(theta0), joint=True,
                                           loss=loss, f_scale=f_scale, ftol=ftol, xtol=xtol,
                                           max_iter=max_iter)
    w = _loss_weights(r * r / f_scale ** 2, loss)
    DtD = model.prior_jacobian().T @ model.prior_jacobian()
    cov, identifiable = _schur_cov(Jp, Jt, r, w, DtD, identifiability_tol)
    ok = bool(conv.all())
    msg = (f"converged in {nit} iterations" if ok else
           f"not converged in {max_iter} iterations")
    if not identifiable:
        msg += (f"; the transform is not identifiable from these points with model "
                f"{model.name!r} (the rotation trades off against θ₁: base-link points missing?)")
    T = PlaneTransform(float(t[0]), float(t[1]), float(t[2]), bool(mirror), cov=cov, fixed=False,
                       model=model.name, identifiable=identifiable, success=ok, message=msg,
                       nfev=int(nit))
    params = np.full((S, k), np.nan)
    params[use] = P
    return T, params


# ==========================================================================
# Per-sample fits with the transform fixed
# ==========================================================================
def _failed(sample, model, m, n, sig, n_points, message):
    k = model.n_params
    nan = float("nan")
    return SampleFit(sample, model.name, model.param_names, np.full(k, nan), np.full((k, k), nan),
                     np.full(n, nan), model.basis, np.full((m, 2), nan), np.full((m, 2), nan), sig,
                     n_points, nan, nan, False, message, 0)


def fit_samples(points, geom: Geometry, model, transform, *, sigma=2e-5, loss: str = "linear",
                f_scale: float = 2.0, theta0=None, samples=None, transform_cov=None,
                min_points=None, solver: str = "lm", ftol: float = 1e-10, xtol: float = 1e-10,
                max_iter: int = 100) -> tuple:
    """Fit each sample's shape parameters with the plane transform fixed.

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Plane-frame points [m], NaN where missing.
    geom : Geometry
    model : str or ShapeModel
    transform : PlaneTransform or (tx, ty, phi, mirror)
    sigma : float or array_like, shape (S, m) or (m,)
        Point uncertainty [m]; NaN drops a point.
    loss, f_scale : str, float
        Loss and its scale in σ units.
    theta0 : array_like, shape (S, n), optional
        Start angles; :func:`estimate_angles` when omitted.
    samples : sequence, optional
        Ids stored in the results (default 0..S-1).
    transform_cov : ndarray, shape (3, 3), optional
        Covariance of (t_x, t_y, φ) to propagate into the parameter
        covariance (module doc); ignored when not finite.
    min_points : int, optional
        Fewest points to attempt a fit; default ``ceil((k + 1) / 2)``, i.e.
        more residuals than parameters.
    solver : {"lm", "scipy"}
        ``lm``: batched Levenberg–Marquardt over all samples at once
        (:func:`_lm`, the fast default); ``scipy``: one
        ``scipy.optimize.least_squares`` (``trf``) call per sample, with
        the same analytic Jacobian (a cross-check). They reach the same
        optimum except with a robust loss and a smoothness prior: ``lm``
        applies the loss to the point residuals only, scipy to the prior
        rows as well.
    ftol, xtol, max_iter
        Tolerances and iteration limit.

    Returns
    -------
    tuple of SampleFit
        A sample with too few points, or whose fit fails, has
        ``success=False`` and a message; it never raises for the others.
    """
    _check_loss(loss, f_scale)
    model = get_model(model, geom.n_joints)
    T = _as_transform(transform)
    Q = _as_points(points, geom)
    S, m = Q.shape[:2]
    n, k = geom.n_joints, model.n_params
    sig = _as_sigma(sigma, (S, m))
    samples = tuple(range(S)) if samples is None else tuple(samples)
    if len(samples) != S:
        raise ValueError(f"got {len(samples)} sample ids for {S} samples")
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    sig = np.where(valid, sig, np.nan)
    npts = valid.sum(1)
    need = math.ceil((k + 1) / 2) if min_points is None else int(min_points)
    if theta0 is None:
        theta0 = estimate_angles(Q, geom, T)
    theta0 = np.asarray(theta0, dtype=float).reshape(S, n)
    theta0 = np.where(np.isfinite(theta0).all(1, keepdims=True), theta0, 0.0)
    out = [None] * S
    for s in range(S):
        if npts[s] == 0:
            out[s] = _failed(samples[s], model, m, n, sig[s], 0, "no valid points (all missing)")
        elif npts[s] < need:
            out[s] = _failed(samples[s], model, m, n, sig[s], int(npts[s]),
                             f"only {npts[s]} valid points for {k} parameters of model "
                             f"{model.name!r} (need at least {need})")
    use = np.array([o is None for o in out])
    if not use.any():
        return tuple(out)
    ui = np.nonzero(use)[0]
    prob = _Problem(Q[use], sig[use], geom, model, T.mirror)
    t = T.params
    P0 = model.initial(theta0[use])
    if solver == "lm":
        _, P, conv, nit, *_ = _lm(prob, t, P0, joint=False, loss=loss, f_scale=f_scale,
                                  ftol=ftol, xtol=xtol, max_iter=max_iter)
        msgs = [f"converged in at most {nit} iterations" if c else
                f"not converged in {max_iter} iterations" for c in conv]
        nfev = np.full(len(ui), nit)
    elif solver == "scipy":
        P, conv, msgs, nfev = _scipy_fits(prob, t, P0, loss, f_scale, ftol, xtol, max_iter)
    else:
        raise ValueError(f"solver must be 'lm' or 'scipy', got {solver!r}")
    r, Jp, Jt, plane, theta = prob.evaluate(t, P)
    w = _loss_weights(r * r / f_scale ** 2, loss)
    D = model.prior_jacobian()
    JpW = Jp * w[..., None]
    JtJ = np.einsum("sri,srj->sij", JpW, Jp)
    Ainv = _psd_inverse(JtJ + D.T @ D)
    cov = Ainv.copy()
    k_eff = np.einsum("sij,sji->s", Ainv, JtJ)
    if transform_cov is not None and np.isfinite(transform_cov).all() and np.any(transform_cov):
        G = Ainv @ np.einsum("sri,srj->sij", JpW, Jt)
        cov = cov + G @ np.asarray(transform_cov, dtype=float) @ np.swapaxes(G, 1, 2)
    resid = plane - Q[use]
    chi2 = (r * r).sum(-1)
    for j, s in enumerate(ui):
        ok = bool(conv[j] and np.isfinite(P[j]).all())
        msg = msgs[j]
        if model.n_prior == 0 and k_eff[j] < k - 0.5:
            # a parameter the points do not determine (e.g. only base-link points, or a
            # free-model joint whose links lost all their points)
            ok = False
            msg = (f"the {npts[s]} valid points determine only {k_eff[j]:.0f} of the {k} "
                   f"parameters of model {model.name!r}")
        out[s] = SampleFit(samples[s], model.name, model.param_names, P[j], cov[j], theta[j],
                           model.basis, plane[j], resid[j], sig[s], int(npts[s]), float(k_eff[j]),
                           float(chi2[j]), ok, msg, int(nfev[j]))
    return tuple(out)


def _scipy_fits(prob: _Problem, t, P0, loss, f_scale, ftol, xtol, max_iter):
    """Reference per-sample fits with ``scipy.optimize.least_squares`` (analytic Jacobian)."""
    D = prob.model.prior_jacobian()
    npr = D.shape[0]
    P = np.empty_like(P0)
    conv, msgs, nfev = [], [], []
    for s in range(P0.shape[0]):
        sub = _Problem(np.where(prob.valid[s:s + 1, :, None], prob.Q0[s:s + 1], np.nan),
                       np.where(prob.valid[s:s + 1], 1.0 / np.where(prob.W[s:s + 1] > 0,
                                                                    prob.W[s:s + 1], 1.0), np.nan),
                       prob.geom, prob.model, prob.mirror)
        rows = np.repeat(sub.valid[0], 2)
        cache = {}

        def fun(x, sub=sub, rows=rows, cache=cache):
            r, Jp, *_ = sub.evaluate(t, x[None])
            J = Jp[0][rows]
            r = r[0][rows]
            if npr:
                r = np.concatenate([r, D @ x])
                J = np.concatenate([J, D])
            cache["x"], cache["J"] = x.copy(), J
            return r

        def jac(x, fun=fun, cache=cache):
            if not np.array_equal(cache.get("x"), x):
                fun(x)
            return cache["J"]

        res = least_squares(fun, P0[s], jac=jac, method="trf", x_scale="jac", loss=loss,
                            f_scale=f_scale, ftol=max(ftol, 1e-15), xtol=max(xtol, 1e-15),
                            gtol=1e-12, max_nfev=max_iter)
        P[s] = res.x
        conv.append(res.status > 0)
        msgs.append(str(res.message))
        nfev.append(res.nfev)
    return P, np.array(conv), msgs, np.array(nfev)


def fit_sample(points, geom: Geometry, model, transform, *, sigma=2e-5, sample=0, theta0=None,
               **kw) -> SampleFit:
    """Fit one sample (points (m, 2)) with the transform fixed; see :func:`fit_samples`."""
    Q = _as_points(points, geom)
    if Q.shape[0] != 1:
        raise ValueError(f"fit_sample takes one sample, points of shape ({geom.n_points}, 2)")
    sig = np.asarray(sigma, dtype=float)
    return fit_samples(Q, geom, model, transform, sigma=sig if sig.ndim == 0 else sig[None],
                       samples=(sample,), theta0=None if theta0 is None else np.asarray(theta0)[None],
                       **kw)[0]


# ==========================================================================
# The experiment
# ==========================================================================
def fit_experiment(points, geom: Geometry, models=("cc", "linear"), *, mirror: bool = False,
                   sigma=None, loss: str = "linear", f_scale: float = 2.0, transform=None,
                   transform_model="free", samples=None, include_transform_uncertainty: bool = True,
                   sigma_default: float = 2e-5, min_points=None, solver: str = "lm",
                   ftol: float = 1e-10, xtol: float = 1e-10, max_iter: int = 100) -> ExperimentFit:
    """Fit every sample of one experiment with each shape model (Sec. IV-A).

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Measured notch points in the plane frame [m]; NaN (or a missing
        point) is dropped from the residuals.
    geom : Geometry
    models : sequence of str or ShapeModel
        Registry names (:func:`notchfit.shapes.get_model`).
    mirror : bool
        The experiment's ``mirror`` flag (a view from -y, Fig. 12).
    sigma : float or array_like (S, m) or (m,), optional
        Point uncertainty [m]. ``None``: estimated from the pooled residuals
        of the ``transform_model`` fit (module doc).
    loss : str
        ``linear`` (least squares), ``soft_l1``, ``huber``, ``cauchy`` or ``arctan``.
    f_scale : float
        Robust-loss scale in units of σ.
    transform : PlaneTransform or (tx, ty, phi), optional
        Fixed plane transform [m, m, rad]; estimated jointly when omitted.
    transform_model : str
        Shape model used for the joint transform estimate (default ``free``),
        and for the σ estimate.
    samples : sequence, optional
        Sample ids (default 0..S-1).
    include_transform_uncertainty : bool
        Add the estimated transform's propagated covariance to every
        sample's parameter covariance.
    sigma_default : float
        σ [m] used to whiten the first pass when ``sigma`` is None.
    min_points : int, optional
        See :func:`fit_samples`.
    solver : {"lm", "scipy"}
        Per-sample solver, see :func:`fit_samples`.
    ftol, xtol, max_iter
        Tolerances and iteration limit (joint and per-sample fits).

    Returns
    -------
    ExperimentFit
        A sample that cannot be fitted (all NaN, too few points) has
        ``success=False`` and a message; the others are unaffected.
    """
    _check_loss(loss, f_scale)
    Q = _as_points(points, geom)
    S, m = Q.shape[:2]
    if samples is None:
        samples = tuple(range(S))
    samples = tuple(samples)
    if len(samples) != S:
        raise ValueError(f"got {len(samples)} sample ids for {S} samples")
    if len(set(samples)) != S:
        raise ValueError("sample ids must be unique")
    if isinstance(models, (str, ShapeModel)):
        models = (models,)
    shape_models = [get_model(mm, geom.n_joints) for mm in models]
    names = tuple(sm.name for sm in shape_models)
    if not names:
        raise ValueError("models must name at least one shape model")
    if len(set(names)) != len(names):
        raise ValueError(f"models must be distinct, got {names}")
    tmodel = get_model(transform_model, geom.n_joints)
    settings = dict(ftol=ftol, xtol=xtol, max_iter=max_iter)
    sigma_estimated = sigma is None
    sig = _as_sigma(sigma_default if sigma is None else sigma, (S, m))
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    theta_start = None

    if transform is None:
        T, Pt = fit_transform(Q, geom, tmodel, mirror=mirror, sigma=sig, loss=loss,
                              f_scale=f_scale, **settings)
        theta_start = Pt @ tmodel.basis.T
        if sigma_estimated:
            s_hat = _estimate_sigma(Q, valid, Pt, tmodel, geom, T, loss)
            sig = np.where(np.isfinite(sig), s_hat, np.nan)
            if loss != "linear":     # refit: f_scale is in units of the (now known) σ
                T, Pt = fit_transform(Q, geom, tmodel, mirror=mirror, sigma=sig, loss=loss,
                                      f_scale=f_scale, x0=T.params,
                                      theta0=np.nan_to_num(theta_start), **settings)
                theta_start = Pt @ tmodel.basis.T
            # the transform covariance was computed with the nominal σ: rescale
            T = _rescale_cov(T, (s_hat / sigma_default) ** 2 if loss == "linear" else 1.0)
    else:
        T = _as_transform(transform, mirror)
        if T.mirror != bool(mirror):
            raise ValueError(f"transform.mirror={T.mirror} disagrees with mirror={bool(mirror)}")
        if sigma_estimated:
            fits_t = fit_samples(Q, geom, tmodel, T, sigma=sig, loss=loss, f_scale=f_scale,
                                 min_points=min_points, solver=solver, **settings)
            Pt = np.stack([f.params for f in fits_t])
            s_hat = _estimate_sigma(Q, valid, Pt, tmodel, geom, T, loss)
            sig = np.where(np.isfinite(sig), s_hat, np.nan)
            theta_start = np.stack([f.theta for f in fits_t])
    if theta_start is None or not np.isfinite(theta_start).all():
        est = estimate_angles(Q, geom, T)
        theta_start = est if theta_start is None else np.where(np.isfinite(theta_start), theta_start, est)

    tcov = T.cov if (include_transform_uncertainty and not T.fixed) else None
    fits = tuple(fit_samples(Q, geom, sm, T, sigma=sig, loss=loss, f_scale=f_scale,
                             theta0=theta_start, samples=samples, transform_cov=tcov,
                             min_points=min_points, solver=solver, **settings)
                 for sm in shape_models)
    return ExperimentFit(T, names, samples, fits, Q, np.where(valid, sig, np.nan),
                         sigma_estimated, geom, loss, float(f_scale))


def _rescale_cov(T: PlaneTransform, factor: float) -> PlaneTransform:
    if factor == 1.0:
        return T
    return PlaneTransform(T.tx, T.ty, T.phi, T.mirror, cov=T.cov * factor, fixed=T.fixed,
                          model=T.model, identifiable=T.identifiable, success=T.success,
                          message=T.message, nfev=T.nfev)



def _estimate_sigma(Q, valid, P, model, geom, T, loss) -> float:
    """Pooled per-coordinate noise estimate [m] from a fit's residuals."""
    ok = np.isfinite(P).all(1)
    if not ok.any():
        raise ValueError("cannot estimate sigma: no sample could be fitted; pass sigma explicitly")
    th = P[ok] @ model.basis.T
    pred = T.to_plane(notch_points(th, geom))
    r = (pred - Q[ok])[valid[ok]]
    r = r[np.isfinite(r)]
    dof = r.size - ok.sum() * model.n_params - (0 if T.fixed else 3)
    if dof <= 0:
        raise ValueError("cannot estimate sigma: no residual degrees of freedom; pass sigma explicitly")
    if loss == "linear":
        s = math.sqrt(float(np.sum(r * r)) / dof)
    else:
        s = 1.4826 * float(np.median(np.abs(r))) * math.sqrt(r.size / dof)
    if not s > 0:
        raise ValueError("cannot estimate sigma: the residuals are zero; pass sigma explicitly")
    return s


# ==========================================================================
# Tables (data-format.md: fits.csv, pointwise.csv) and model comparison
# ==========================================================================
def fits_table(result: ExperimentFit, *, include_theta: bool = True) -> pd.DataFrame:
    """One row per sample and model, the ``fits.csv`` layout of data-format.md.

    Columns: ``sample, model, a, b,`` then model-specific parameters (``c``,
    ``s1…sk``; NaN for models without them), ``theta_1…theta_n`` (the fitted
    joint angles of every model, when ``include_theta``), then
    ``base_x_mm, base_y_mm, base_phi_rad, rms_mm, max_mm, n_points``, then
    ``se_a, se_b, chi2, k_eff, aic, bic, sigma_mm, success, message``.

    ``a``, ``b`` [rad] are the literal parameters for cc (b = 0 exactly, se_b
    = 0: the model fixes it), linear and quadratic; for the piecewise and free
    models they are the least-squares line ``a + b j`` through the fitted
    θ_j, with its propagated standard errors. ``rms_mm``/``max_mm`` are the
    rms and maximum of the pointwise error ``||Q_i − Q̃_i||`` (Sec. IV-A).
    """
    n = result.geom.n_joints
    extra = []
    for name in result.models:
        for pn in get_model(name, n).param_names:
            if pn not in ("a", "b") and not pn.startswith("theta_") and pn not in extra:
                extra.append(pn)
    theta_cols = [f"theta_{j}" for j in range(1, n + 1)] if include_theta else []
    T = result.transform
    rows = []
    for name, fs in zip(result.models, result.fits):
        for f in fs:
            row = {"sample": f.sample, "model": name, "a": f.a, "b": f.b}
            pmap = dict(zip(f.param_names, f.params))
            for pn in extra:
                row[pn] = pmap.get(pn, np.nan)
            for j, c in enumerate(theta_cols):
                row[c] = f.theta[j]
            sig = f.sigma[np.isfinite(f.sigma)]
            row.update({
                "base_x_mm": T.tx / _MM, "base_y_mm": T.ty / _MM, "base_phi_rad": T.phi,
                "rms_mm": f.rms / _MM, "max_mm": f.max_error / _MM, "n_points": f.n_points,
                "se_a": f.se_a, "se_b": f.se_b, "chi2": f.chi2, "k_eff": f.k_eff,
                "aic": f.aic, "bic": f.bic,
                "sigma_mm": float(np.median(sig)) / _MM if sig.size else np.nan,
                "success": f.success, "message": f.message,
            })
            rows.append(row)
    cols = (["sample", "model", "a", "b"] + extra + theta_cols
            + ["base_x_mm", "base_y_mm", "base_phi_rad", "rms_mm", "max_mm", "n_points",
               "se_a", "se_b", "chi2", "k_eff", "aic", "bic", "sigma_mm", "success", "message"])
    df = pd.DataFrame(rows, columns=cols)
    df["n_points"] = df["n_points"].astype(int)
    df["success"] = df["success"].astype(bool)
    return df


def pointwise_table(result: ExperimentFit) -> pd.DataFrame:
    """``pointwise.csv`` of data-format.md: ``sample, model, point, err_mm``.

    One row per sample, model and point (point 1-based, geometry.md
    numbering); ``err_mm = ||Q_i − Q̃_i||`` (Sec. IV-A, Figs. 13–14), NaN for
    a missing point or a failed fit.
    """
    m = result.geom.n_points
    frames = []
    for name in result.models:
        E = result.errors(name) / _MM                       # (S, m)
        frames.append(pd.DataFrame({
            "sample": np.repeat(np.array(result.samples, dtype=object), m),
            "model": name,
            "point": np.tile(np.arange(1, m + 1), len(result.samples)),
            "err_mm": E.ravel(),
        }))
    df = pd.concat(frames, ignore_index=True)
    df["sample"] = df["sample"].infer_objects()
    return df


def compare_models(result: ExperimentFit) -> pd.DataFrame:
    """Model comparison over the whole experiment (Sec. IV-A).

    Sums over the successfully fitted samples: ``n_samples``, ``n_failed``,
    ``n_points``, ``k_eff`` (effective parameters), ``chi2``, ``aic``
    (χ² + 2k), ``bic`` (χ² + k ln N, N the number of coordinates), the rms
    and maximum pointwise error [mm] over all points, and ``delta_aic``,
    ``delta_bic`` relative to the best model. The shared transform adds the
    same 3 parameters to every model and is left out.

    Returns
    -------
    DataFrame, one row per model.
    """
    rows = []
    for name, fs in zip(result.models, result.fits):
        ok = [f for f in fs if f.success]
        e = np.concatenate([f.errors for f in ok]) if ok else np.array([])
        e = e[np.isfinite(e)]
        npts = sum(f.n_points for f in ok)
        k = sum(f.k_eff for f in ok)
        chi2 = sum(f.chi2 for f in ok)
        rows.append({
            "model": name, "n_samples": len(ok), "n_failed": len(fs) - len(ok),
            "n_points": npts, "k_eff": k, "chi2": chi2,
            "aic": chi2 + 2 * k, "bic": chi2 + k * math.log(max(2 * npts, 1)),
            "rms_mm": float(np.sqrt(np.mean(e * e))) / _MM if e.size else np.nan,
            "max_mm": float(e.max()) / _MM if e.size else np.nan,
        })
    df = pd.DataFrame(rows)
    df["delta_aic"] = df["aic"] - df["aic"].min()
    df["delta_bic"] = df["bic"] - df["bic"].min()
    return df


# ==========================================================================
# Synthetic data (tests, benchmarks, demos)
# ==========================================================================
def synthetic_points(theta, geom: Geometry, transform=(0.0, 0.0, 0.0), *, mirror: bool = False,
                     noise: float = 0.0, rng=None):
    """Measured-like notch points from known joint angles (ground truth returned).

    Parameters
    ----------
    theta : array_like, shape (S, n) or (n,)
        True joint angles [rad].
    geom : Geometry
    transform : (tx, ty, phi)
        True plane transform [m, m, rad].
    mirror : bool
    noise : float
        Standard deviation of the isotropic Gaussian point noise per
        coordinate [m].
    rng : numpy.random.Generator
        Required when ``noise > 0``.

    Returns
    -------
    points : ndarray, shape (S, m, 2)
        Noisy plane-frame points [m].
    truth : dict
        ``theta`` (S, n), ``points`` (noise-free, (S, m, 2)), ``transform``
        (tx, ty, phi), ``mirror``, ``noise``.
    """
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    T = _as_transform(transform, mirror)
    clean = T.to_plane(notch_points(th, geom))
    if noise < 0 or not math.isfinite(noise):
        raise ValueError(f"noise must be a finite standard deviation >= 0 [m], got {noise!r}")
    if noise > 0:
        if rng is None:
            raise ValueError("synthetic_points needs rng (numpy.random.Generator) when noise > 0")
        pts = clean + rng.normal(0.0, noise, clean.shape)
    else:
        pts = clean.copy()
    return pts, {"theta": th, "points": clean, "transform": (T.tx, T.ty, T.phi),
                 "mirror": T.mirror, "noise": float(noise)}
