"""Result types of the shape fits (Sec. IV-A): the plane transform, one sample's fit, an experiment's fits.

Thin frozen dataclasses with derived quantities as properties: the paper's
pointwise error ``e_i = ||Q_i − Q̃_i||`` and its rms and maximum, χ², AIC,
BIC, and the shape summary ``a``, ``b`` of ``θ_j = a + b j`` with standard
errors. Lengths in m, angles in rad.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ...physics.geometry import Geometry
from ...physics.notches import from_plane, to_plane
from ...physics.shapes import line_fit

__all__ = ["ExperimentFit", "PlaneTransform", "SampleFit", "as_transform"]


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
        False when the data cannot separate φ from the shape (the gauge, see
        :mod:`notchfit.analysis.fitting`).
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
        requested, see :mod:`notchfit.analysis.fitting`); NaN when failed.
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
        # the least-squares line through θ_j (shapes.line_fit); its covariance through the
        # same (linear) map written as a matrix
        L = _line_projector(len(self.theta))
        return np.array(line_fit(self.theta)), L @ self.theta_cov @ L.T

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
    """The (2, n) matrix of :func:`notchfit.physics.shapes.line_fit`: ``(a, b) = L θ``.

    ``line_fit`` is linear in θ, so its values on the unit vectors are the
    matrix's columns; used to propagate a covariance of θ to (a, b).
    """
    L = np.stack(line_fit(np.eye(n)))
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


def as_transform(transform, mirror=None) -> PlaneTransform:
    """A :class:`PlaneTransform` from itself or from ``(tx, ty, phi[, mirror])`` [m, m, rad].

    ``mirror`` is used when the tuple has three values (default False).
    """
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
