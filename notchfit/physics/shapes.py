"""Shape models: a few parameters → the n joint angles (Sec. IV-A).

The seed paper describes the manipulator's shape by a low-dimensional family
of joint-angle vectors and fits it to the 58 measured notch points
(Sec. IV-A, Figs. 12–15): constant curvature ``θ_j = a`` and the "linear
model" ``θ_j = a + b j`` (j = 1..n). This module puts those and richer
families behind one interface, :class:`ShapeModel`:

========================  =============================  ===================
registry name             θ_j                            parameters
========================  =============================  ===================
``cc``                    ``a``                          a
``linear``                ``a + b j``                    a, b
``quadratic``             ``a + b j + c j²``             a, b, c
``pw<k>`` (``pw3``, …)    ``s_g`` on segment g of k      s1 … sk
``free``                  ``θ_j``                        theta_1 … theta_n
``free_smooth[=λ]``       ``θ_j`` + prior λ·Δ²θ          theta_1 … theta_n
========================  =============================  ===================

Every model here is linear in its parameters, ``θ = B · params`` with a
constant basis ``B`` (n × n_params), so :meth:`ShapeModel.jacobian` is
``B``. The piecewise model splits the joints 1..n into k contiguous segments
as evenly as possible (the first ``n mod k`` segments one joint longer).
``free_smooth`` adds the second-difference prior
``λ (θ_{j-1} - 2 θ_j + θ_{j+1})``, j = 2..n-1, as extra residuals in the
units of the whitened point residuals (a Gaussian prior on Δ²θ with
standard deviation ``1/λ`` rad); the linear model is exactly in its null
space.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "DEFAULT_SMOOTH_WEIGHT",
    "MODEL_NAMES",
    "ShapeModel",
    "constant_curvature",
    "free",
    "get_model",
    "line_fit",
    "linear",
    "piecewise",
    "quadratic",
]

#: Default weight λ of the ``free_smooth`` prior [1/rad]: Δ²θ ~ N(0, (0.01 rad)²).
DEFAULT_SMOOTH_WEIGHT = 100.0

#: Registry names understood by :func:`get_model` (``pw<k>`` for any k ≥ 1).
MODEL_NAMES = ("cc", "linear", "quadratic", "pw<k>", "free", "free_smooth", "free_smooth=<λ>")


@dataclass(frozen=True)
class ShapeModel:
    """A joint-angle model ``θ = B · params`` (Sec. IV-A).

    Attributes
    ----------
    name : str
        Registry name (``cc``, ``linear``, ``pw3``, ``free_smooth``, …).
    n_joints : int
        Number of joints ``n``.
    param_names : tuple of str
        Names of the parameters, in order (``a``, ``b``, ``c``, ``s1``…,
        ``theta_1``…).
    basis : ndarray, shape (n, n_params)
        ``∂θ/∂params`` [rad per parameter unit], read-only.
    smooth_weight : float
        Weight λ of the second-difference prior [1/rad]; 0 for none.
    """

    name: str
    n_joints: int
    param_names: tuple
    basis: np.ndarray = field(repr=False, compare=False)
    smooth_weight: float = 0.0

    def __post_init__(self) -> None:
        basis = np.array(self.basis, dtype=float)
        if basis.shape != (self.n_joints, len(self.param_names)):
            raise ValueError(
                f"basis must have shape (n_joints, n_params) = "
                f"({self.n_joints}, {len(self.param_names)}), got {basis.shape}")
        if not (math.isfinite(self.smooth_weight) and self.smooth_weight >= 0):
            raise ValueError(f"smooth_weight must be a finite number >= 0, got {self.smooth_weight!r}")
        basis.setflags(write=False)
        object.__setattr__(self, "basis", basis)
        D = _second_difference(self.n_joints) if self.smooth_weight > 0 else np.zeros((0, self.n_joints))
        prior = self.smooth_weight * D @ basis
        prior.setflags(write=False)
        object.__setattr__(self, "_prior", prior)
        # least-squares projection θ -> params (for initial guesses and summaries)
        object.__setattr__(self, "_pinv", np.linalg.pinv(basis))

    # ------------------------------------------------------------------
    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.param_names)

    @property
    def n_prior(self) -> int:
        """Number of prior residuals (n - 2 for ``free_smooth``, else 0)."""
        return self._prior.shape[0]

    def _check(self, params) -> np.ndarray:
        p = np.asarray(params, dtype=float)
        if p.ndim == 0 or p.shape[-1] != self.n_params:
            raise ValueError(
                f"model {self.name!r} expects parameters of shape (..., {self.n_params}) "
                f"({', '.join(self.param_names)}), got {np.shape(params)}")
        return p

    def theta(self, params) -> np.ndarray:
        """Joint angles ``θ = B · params``.

        Parameters
        ----------
        params : array_like, shape (..., n_params)

        Returns
        -------
        ndarray, shape (..., n) [rad]
        """
        return self._check(params) @ self.basis.T

    def jacobian(self, params=None) -> np.ndarray:
        """``∂θ/∂params``, shape (n, n_params); constant (the basis)."""
        if params is not None:
            self._check(params)
        return self.basis

    def initial(self, theta=None) -> np.ndarray:
        """Starting parameters: the least-squares projection of ``theta``.

        Parameters
        ----------
        theta : array_like, shape (..., n), optional
            A rough joint-angle estimate [rad]; zeros when omitted.

        Returns
        -------
        ndarray, shape (..., n_params)
        """
        if theta is None:
            return np.zeros(self.n_params)
        th = np.asarray(theta, dtype=float)
        if th.ndim == 0 or th.shape[-1] != self.n_joints:
            raise ValueError(f"theta must have shape (..., {self.n_joints}), got {th.shape}")
        return th @ self._pinv.T

    def prior_residuals(self, params) -> np.ndarray:
        """Smoothness-prior residuals ``λ Δ²θ``, shape (..., n_prior) (dimensionless)."""
        return self._check(params) @ self._prior.T

    def prior_jacobian(self) -> np.ndarray:
        """``∂(prior residuals)/∂params``, shape (n_prior, n_params)."""
        return self._prior


def _second_difference(n: int) -> np.ndarray:
    D = np.zeros((max(n - 2, 0), n))
    for i in range(n - 2):
        D[i, i:i + 3] = (1.0, -2.0, 1.0)
    return D


def _check_n(n_joints) -> int:
    if not isinstance(n_joints, (int, np.integer)) or isinstance(n_joints, bool) or n_joints < 1:
        raise ValueError(f"n_joints must be a positive integer, got {n_joints!r}")
    return int(n_joints)


def constant_curvature(n_joints: int) -> ShapeModel:
    """``θ_j = a`` (constant curvature, Sec. IV-A, Fig. 12 left)."""
    n = _check_n(n_joints)
    return ShapeModel("cc", n, ("a",), np.ones((n, 1)))


def linear(n_joints: int) -> ShapeModel:
    """``θ_j = a + b j``, j = 1..n (the paper's linear model, Sec. IV-A, Fig. 12 right)."""
    n = _check_n(n_joints)
    j = np.arange(1, n + 1, dtype=float)
    return ShapeModel("linear", n, ("a", "b"), np.stack([np.ones(n), j], axis=1))


def quadratic(n_joints: int) -> ShapeModel:
    """``θ_j = a + b j + c j²``, j = 1..n."""
    n = _check_n(n_joints)
    j = np.arange(1, n + 1, dtype=float)
    return ShapeModel("quadratic", n, ("a", "b", "c"), np.stack([np.ones(n), j, j * j], axis=1))


def piecewise(n_joints: int, k: int) -> ShapeModel:
    """θ constant over ``k`` contiguous segments of joints (``s1 … sk``).

    Segments follow ``numpy.array_split`` of 1..n: the first ``n mod k`` are
    one joint longer.
    """
    n = _check_n(n_joints)
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or not 1 <= k <= n:
        raise ValueError(f"piecewise model needs 1 <= k <= n_joints={n} segments, got {k!r}")
    basis = np.zeros((n, k))
    for g, idx in enumerate(np.array_split(np.arange(n), k)):
        basis[idx, g] = 1.0
    return ShapeModel(f"pw{k}", n, tuple(f"s{g + 1}" for g in range(k)), basis)


def free(n_joints: int, smooth_weight: float = 0.0) -> ShapeModel:
    """All n joint angles free, optionally with the second-difference prior.

    Parameters
    ----------
    n_joints : int
    smooth_weight : float
        λ [1/rad]; 0 gives ``free``, > 0 gives ``free_smooth``.
    """
    n = _check_n(n_joints)
    sw = float(smooth_weight)
    if sw == 0:
        name = "free"
    elif sw == DEFAULT_SMOOTH_WEIGHT:
        name = "free_smooth"
    else:
        name = f"free_smooth={sw:g}"
    return ShapeModel(name, n, tuple(f"theta_{j}" for j in range(1, n + 1)), np.eye(n), sw)


_PW = re.compile(r"^pw(\d+)$")
_FS = re.compile(r"^free_smooth(?:=(.+))?$")


def get_model(name, n_joints: int) -> ShapeModel:
    """A shape model from its registry name.

    Parameters
    ----------
    name : str or ShapeModel
        ``cc``, ``linear``, ``quadratic``, ``pw<k>`` (e.g. ``pw3``), ``free``,
        ``free_smooth`` (λ = :data:`DEFAULT_SMOOTH_WEIGHT`) or
        ``free_smooth=<λ>`` (λ in 1/rad). A :class:`ShapeModel` is returned
        as is after checking its joint count.
    n_joints : int

    Returns
    -------
    ShapeModel
    """
    n = _check_n(n_joints)
    if isinstance(name, ShapeModel):
        if name.n_joints != n:
            raise ValueError(f"model {name.name!r} has {name.n_joints} joints, expected {n}")
        return name
    if not isinstance(name, str):
        raise ValueError(f"model name must be a string, got {name!r}")
    key = name.strip().lower()
    if key in ("cc", "constant", "constant_curvature"):
        return constant_curvature(n)
    if key == "linear":
        return linear(n)
    if key == "quadratic":
        return quadratic(n)
    if key == "free":
        return free(n)
    m = _PW.match(key)
    if m:
        return piecewise(n, int(m.group(1)))
    m = _FS.match(key)
    if m:
        if m.group(1) is None:
            return free(n, DEFAULT_SMOOTH_WEIGHT)
        try:
            lam = float(m.group(1))
        except ValueError:
            lam = float("nan")
        if not (math.isfinite(lam) and lam > 0):
            raise ValueError(f"free_smooth=<λ> needs a positive number λ [1/rad], got {name!r}")
        return free(n, lam)
    raise ValueError(
        f"unknown shape model {name!r}; expected one of {', '.join(MODEL_NAMES)}")


def line_fit(theta) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares line ``θ_j = a + b j`` (j = 1..n) through joint angles (Sec. IV-A).

    The one implementation of the paper's linear shape summary: every module
    that reports ``a`` and ``b`` of a set of joint angles (fits of other
    models, simulated shapes, diagnosis signatures, figures) calls it.

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]

    Returns
    -------
    a, b : ndarray, shape (...) [rad]
        Closed form: ``b = Σ (j - j̄) θ_j / Σ (j - j̄)²``, ``a = θ̄ - b j̄``;
        for n = 1, ``a = θ_1`` and ``b = 0``. NaN in a row gives NaN.
    """
    th = np.asarray(theta, dtype=float)
    n = th.shape[-1]
    if n < 2:
        return th[..., 0].copy(), np.zeros(th.shape[:-1])
    j = np.arange(1, n + 1, dtype=float)
    jc = j - j.mean()
    b = (th * jc).sum(axis=-1) / (jc @ jc)
    a = th.mean(axis=-1) - b * j.mean()
    return a, b
