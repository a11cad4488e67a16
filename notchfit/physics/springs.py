"""Flexure springs: odd, continuous, piecewise-linear torque laws.

Both spring laws of the seed paper are instances of
:class:`PiecewiseLinearSpring`:

* the dual-rate spring of Sec. III / Fig. 7 (:func:`dual_rate_spring`):
  ``k_1 = 0.36`` up to ``θ_thresh = 0.135 rad``, then ``k_2 = 10`` Nm/rad;
  the paper's ``k_i(θ) = k_2 ± θ_thresh (k_1 - k_2)/θ`` gives exactly
  ``τ = k_1 θ_thresh + k_2 (|θ| - θ_thresh)`` beyond the threshold;
* the friction-model spring of Sec. IV-B / Fig. 17 (:func:`friction_spring`):
  0.4829 Nm/rad below 0.07 rad, a softer mid-range rate up to slot closure
  (0.14 rad), then a hard stop (10 Nm/rad).

Per-joint springs: ``breaks`` and ``rates`` broadcast against the joint axis,
and ``scale`` (shape ``(n,)`` or scalar) multiplies every rate of a joint
(a stiffness gradient along the backbone is a ``scale`` vector).

Springs from material and section (real tubes, :func:`material_spring`): each
notch is a short beam of length ``h_j`` (the slot height) bending as a circular
arc of its neutral axis, so ``M = E I_j κ = E I_j θ / h_j`` and the linear rate
is ``k_j = E I_j / h_j`` (the Euler–Bernoulli moment–curvature relation, e.g.
Gere & Timoshenko, Mechanics of Materials; the asymmetric-notch wrist of York,
Swaney, Gilbert & Webster, ICRA 2015, uses the same). A superelastic (nitinol)
tube softens to a plateau modulus ``E_se`` once its most strained fibre,
``c_j`` from the neutral axis, passes the strain ``ε_lower``: with
``ε = c_j θ / h_j`` (:mod:`notchfit.physics.section`) that is at
``θ = ε_lower h_j / c_j`` — a section-level bilinear law (the whole section
softens at once; the gradual spread of the plateau through the wall is not
modelled). The slot closes at the closure angle of
:attr:`notchfit.physics.geometry.Geometry.closure_angles`, where a stop takes over.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import paper
from .geometry import Geometry
from ..validation import readonly

__all__ = ["PiecewiseLinearSpring", "dual_rate_spring", "friction_spring", "material_spring"]


@dataclass(frozen=True, eq=False)
class PiecewiseLinearSpring:
    """An odd piecewise-linear torsion spring ``τ(θ)``.

    Parameters
    ----------
    breaks : array_like, shape (m,) or (n, m)
        Non-decreasing angles where the rate changes [rad], all > 0 (two equal
        breaks: the piece between them is skipped).
    rates : array_like, shape (m + 1,) or (n, m + 1)
        Rate on each interval ``[0, b_1), [b_1, b_2), …, [b_m, ∞)`` [N m/rad], > 0.
    scale : float or array_like, shape (n,)
        Per-joint factor on every rate (1 by default).
    """

    breaks: np.ndarray
    rates: np.ndarray
    scale: np.ndarray = field(default_factory=lambda: readonly(1.0))

    def __post_init__(self) -> None:
        b, r, s = (np.array(v, dtype=float) for v in (self.breaks, self.rates, self.scale))
        if b.ndim == 0:
            b = b[None]
        if r.shape[-1] != b.shape[-1] + 1:
            raise ValueError(f"need one more rate than breaks, got breaks {b.shape} rates {r.shape}")
        if not (np.isfinite(b).all() and np.isfinite(r).all() and np.isfinite(s).all()):
            raise ValueError("spring breaks, rates and scale must be finite")
        if (b <= 0).any() or (np.diff(b, axis=-1) < 0).any():
            raise ValueError(f"spring breaks must be positive and increasing, got {b}")
        if (r <= 0).any() or (s <= 0).any():
            raise ValueError("spring rates and scale must be positive")
        object.__setattr__(self, "breaks", readonly(b))
        object.__setattr__(self, "rates", readonly(r))
        object.__setattr__(self, "scale", readonly(s))

    # ----------------------------------------------------------------- tables
    def _knots(self):
        """Angles ``a`` (..., m+1) starting at 0 and the torque there (unscaled)."""
        b, r = self.breaks, self.rates
        a = np.concatenate([np.zeros(b.shape[:-1] + (1,)), b], axis=-1)
        tau = np.concatenate(
            [np.zeros(b.shape[:-1] + (1,)), np.cumsum(r[..., :-1] * np.diff(a, axis=-1), axis=-1)],
            axis=-1)
        return a, tau

    def with_scale(self, scale) -> "PiecewiseLinearSpring":
        """The same law with per-joint stiffness factors ``scale``."""
        return PiecewiseLinearSpring(self.breaks, self.rates, scale)

    # -------------------------------------------------------------- evaluation
    def torque(self, theta) -> np.ndarray:
        """Spring torque ``τ(θ)`` [N m], odd and continuous (broadcasts)."""
        th = np.asarray(theta, dtype=float)
        x = np.abs(th)
        a, _ = self._knots()
        upper = np.concatenate([a[..., 1:], np.full(a.shape[:-1] + (1,), np.inf)], axis=-1)
        width = np.clip(x[..., None] - a, 0.0, upper - a)
        return np.sign(th) * self.scale * np.sum(self.rates * width, axis=-1)

    def stiffness(self, theta) -> np.ndarray:
        """Tangent stiffness ``dτ/dθ`` [N m/rad] (right-continuous at the breaks)."""
        x = np.abs(np.asarray(theta, dtype=float))
        idx = np.sum(x[..., None] >= self.breaks, axis=-1)
        rates = np.broadcast_to(self.rates, x.shape + self.rates.shape[-1:])
        return self.scale * np.take_along_axis(rates, idx[..., None], axis=-1)[..., 0]

    def secant(self, theta) -> np.ndarray:
        """Secant stiffness ``k(θ) = τ(θ)/θ`` (the paper's ``K_θ(θ)`` entries)."""
        th = np.asarray(theta, dtype=float)
        safe = np.where(th == 0, 1.0, th)
        k0 = self.scale * self.rates[..., 0]
        return np.where(th == 0, k0, self.torque(th) / safe)

    def angle(self, torque) -> np.ndarray:
        """Inverse law ``θ(τ)`` [rad] (broadcasts)."""
        tq = np.asarray(torque, dtype=float)
        if not np.isfinite(tq).all():
            raise ValueError("torque contains NaN or inf")
        y = np.abs(tq) / self.scale
        _, tk = self._knots()
        upper = np.concatenate([tk[..., 1:], np.full(tk.shape[:-1] + (1,), np.inf)], axis=-1)
        width = np.clip(y[..., None] - tk, 0.0, upper - tk)
        return np.sign(tq) * np.sum(width / self.rates, axis=-1)


def dual_rate_spring(k1: float = paper.DUAL_RATE_K1, k2: float = paper.DUAL_RATE_K2,
                     theta_thresh: float = paper.DUAL_RATE_THRESH,
                     scale=1.0) -> PiecewiseLinearSpring:
    """Dual-rate spring of Sec. III, Fig. 7 (``k_1``, ``k_2`` [N m/rad], ``θ_thresh`` [rad])."""
    return PiecewiseLinearSpring([theta_thresh], [k1, k2], scale)


def friction_spring(k_lin: float = paper.FRICTION_K_LIN, k_mid: float = paper.FRICTION_K_MID,
                    k_stop: float = paper.FRICTION_K_STOP, theta_mid: float = paper.FRICTION_THETA_MID,
                    theta_stop: float = paper.FRICTION_THETA_STOP,
                    scale=1.0) -> PiecewiseLinearSpring:
    """Piecewise-linear spring of the friction model (Sec. IV-B, Fig. 17).

    ``k_lin`` below ``theta_mid``, ``k_mid`` (no value in the paper; 0.25 by
    docs/models.md, a fitted parameter) up to slot closure ``theta_stop``, then
    the hard stop ``k_stop``.
    """
    return PiecewiseLinearSpring([theta_mid, theta_stop], [k_lin, k_mid, k_stop], scale)


def material_spring(geom: Geometry, E_lin: float, E_se: float, strain_lower: float,
                    stop_ratio: float = paper.FRICTION_K_STOP / paper.FRICTION_K_LIN, *,
                    rest_angles=None, strain_ratio: float = 1.0) -> PiecewiseLinearSpring:
    """Per-joint spring of a notched tube from its material and section (module docstring).

    Joint ``j`` (deflection ``δ = θ_j - θ0_j`` from its rest angle; the law is odd in ``δ``):

    * ``k_j = E_lin I_j / h_j`` for ``|δ| < min(ε_lower h_j / c_back,j, r ε_lower h_j / c_cut,j)``:
      the plateau starts where the back fibre (in tension when the joint bends toward its slot)
      reaches ``ε_lower`` or the cut fibre (in compression) reaches ``r ε_lower``; ``r = 1``
      (default) is one threshold for the most strained fibre, ``c_j = max(c_back, c_cut)``; superelastic
      nitinol transforms at 1.2-1.5 times the strain in compression (its tension–compression
      asymmetry: Orgéas & Favier, Acta Mater. 46(15), 1998; Gall et al., Acta Mater. 47(4), 1999);
    * ``E_se I_j / h_j`` beyond, up to slot closure ``θ_c,j - σ_j θ0_j`` (the slot on side
      ``σ_j`` closes at ``θ_j = σ_j θ_c,j``; a rest angle toward the slot uses some of the gap);
    * ``stop_ratio k_j`` once the slot is closed (default: the seed paper's
      ``k_stop / k_lin`` = 10 / 0.4829, Fig. 17, so the stop is as stiff relative
      to the flexure as on the seed tube).

    A softening threshold beyond closure gives no plateau piece (two equal breaks).

    Parameters
    ----------
    geom : Geometry
        Needs ``inner_radius`` (:attr:`Geometry.section`).
    E_lin, E_se : float
        Linear (austenite) and plateau moduli [Pa], > 0.
    strain_lower : float
        Outer-fibre strain where the plateau starts [-], > 0.
    stop_ratio : float
        Stop rate over linear rate [-], > 0.
    rest_angles : array_like (n,) [rad], optional
        ``θ0_j`` in place of the geometry's (a model's identified rest angles).
    strain_ratio : float
        ``r``: the compression fibre's onset strain over the tension fibre's [-], > 0.

    Returns
    -------
    PiecewiseLinearSpring
        breaks (n, 2) [rad], rates (n, 3) [N m/rad].
    """
    for name, v in (("E_lin", E_lin), ("E_se", E_se), ("strain_lower", strain_lower), ("stop_ratio", stop_ratio),
                    ("strain_ratio", strain_ratio)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"material parameter {name} must be positive, got {v!r}")
    sec = geom.section
    h = geom.slot_widths
    if strain_ratio == 1.0:
        onset = strain_lower * h / np.maximum(sec.back_fibre, sec.cut_fibre)
    else:
        onset = np.minimum(strain_lower * h / sec.back_fibre, strain_ratio * strain_lower * h / sec.cut_fibre)
    rest = geom.rest_angles if rest_angles is None else np.asarray(rest_angles, dtype=float)
    stop = geom.closure_angles - geom.sides * rest
    mid = np.minimum(onset, stop)
    k = E_lin * sec.second_moment / h
    rates = np.stack([k, E_se * sec.second_moment / h, stop_ratio * k], axis=-1)
    return PiecewiseLinearSpring(np.stack([mid, stop], axis=-1), rates)
