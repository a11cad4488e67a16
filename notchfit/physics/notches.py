"""The kinematic notch-point projector (Sec. IV-A) and the plane transform.

``θ → Q̃`` maps joint angles to the virtual notch points ``Q̃_i`` (numbered
as ``docs/geometry.md`` says) in the manipulator frame, with the
analytic Jacobian ``∂Q̃/∂θ``. :func:`to_plane` maps manipulator-frame points
into the measured plane frame by a proper rigid 2-D transform, optionally
after a mirror (a view from ``-y``).

Real tubes: joints sit at the geometry's per-joint ``z_j`` and bend about
its neutral axes ``x_na,j`` (:func:`notchfit.physics.kinematics.chain`); ``model="pivot"``
(default, revolute joints at mid-notch on the neutral axis) or ``"arc"``
(each notch a circular arc of its neutral axis, docs/models.md "Real tubes:
kinematics"). One-sided tubes number their ``4 + 2 n`` points by the same rule
(docs/geometry.md).

Shapes: joint angles ``(..., n)``; points ``(..., m, 2)`` as (x, z) in the
manipulator frame or (x, y) in the plane frame; the Jacobian
``(..., m, 2, n)``, which ``.reshape(..., 2 m, n)`` turns into the paper's
``(58·2 × n)`` matrix with rows ``x_1, z_1, x_2, z_2, …``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from .geometry import Geometry, notch_layout
from .kinematics import _check_model, chain, link_origins

__all__ = [
    "from_plane",
    "notch_points",
    "notch_points_and_jacobian",
    "plane_params_jacobian",
    "PointProjector",
    "plane_rotation",
    "point_projector",
    "points_kernel",
    "to_plane",
]


@functools.lru_cache(maxsize=32)
def _tables(geom: Geometry):
    """Link of each point, its link-local (x, z) from the link's pivot, and the chain's steps and heights.

    A plain tuple ``(link, lx, lz, per_joint)``: the compiled kernels take it as one argument, and numba
    reads an exact tuple of arrays as fast as separate arguments (a named tuple costs microseconds per
    call from Python, too much for the one-configuration calls)."""
    lay = notch_layout(geom)
    ch = chain(geom)
    lx = lay.local[:, 0] - np.where(lay.link > 0, ch.axis_offset[np.maximum(lay.link - 1, 0)], 0.0)
    per_joint = np.ascontiguousarray(np.stack([ch.steps[:, 0], ch.steps[:, 1], ch.heights]))
    return lay.link, lx, lay.local[:, 1].copy(), per_joint


def _points(phi, O, geom):
    link, lx, lz = _tables(geom)[:3]
    org = O[..., link, :]
    sl, cl = np.sin(phi)[..., link], np.cos(phi)[..., link]
    x = org[..., 0] + cl * lx + sl * lz
    z = org[..., 1] - sl * lx + cl * lz
    return np.stack([x, z], axis=-1)


def notch_points(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """Virtual notch points ``Q̃(θ)`` in the manipulator frame (Sec. IV-A).

    A point on link ``l`` with link-local ``(x, z)`` (from the link's pivot
    ``a_l``) is at ``O_l + R(φ_l)(x, z)`` (:func:`notchfit.physics.kinematics.link_origins`).

    Parameters
    ----------
    theta : array_like, shape (..., n)
        Joint angles [rad].
    geom : Geometry
    model : {"pivot", "arc"}
        Mid-notch revolute joints on the neutral axis, or circular-arc notches.

    Returns
    -------
    ndarray, shape (..., m, 2)
        (x, z) of each point [m], m = 4 + 2 n (58 for the default manipulator).
    """
    phi, O = link_origins(theta, geom, model)
    return _points(phi, O, geom)


def notch_points_and_jacobian(theta, geom: Geometry, model: str = "pivot", *,
                              series_below: float = 1e-3):
    """Notch points and their analytic Jacobian ``∂Q̃/∂θ``.

    A joint ``k`` rotates every point on links ``l ≥ k`` about ``O_k`` (the
    image of its pivot, :func:`notchfit.physics.kinematics.link_origins`) and, for
    the arc model, translates them by ``R(φ_{k-1}) dδ_k/dθ_k``
    (:func:`notchfit.physics.kinematics.arc_translation`):
    ``∂Q̃_i/∂θ_k = (z_i - O_kz, -(x_i - O_kx)) + R(φ_{k-1}) dδ_k/dθ_k`` if
    ``k ≤ link(i)``, else 0. Computed by a compiled (numba) kernel that writes
    both outputs in one pass over the configurations; see
    ``benchmarks/bench_kinematics.py``.

    Parameters
    ----------
    theta : array_like, shape (..., n)
    geom : Geometry
    model : {"pivot", "arc"}
    series_below : float
        ``|θ/2|`` below which the arc model uses the series of ``sinc``.

    Returns
    -------
    points : ndarray, shape (..., m, 2) [m]
    jac : ndarray, shape (..., m, 2, n) [m/rad]
    """
    _check_model(model)
    th = np.asarray(theta, dtype=float)
    n = geom.n_joints
    if th.ndim == 0 or th.shape[-1] != n:
        raise ValueError(f"joint angles must have shape (..., {n}), got {np.shape(theta)}")
    if not np.isfinite(th).all():
        raise ValueError("joint angles contain NaN or inf")
    tables = _tables(geom)
    lead = th.shape[:-1]
    m = tables[0].shape[0]
    flat = np.ascontiguousarray(th).reshape(-1, n)
    pts = np.empty((flat.shape[0], m, 2))
    jac = np.empty((flat.shape[0], m, 2, n))
    _points_jac_kernel(flat, tables, model == "arc", series_below, pts, jac)
    return pts.reshape(lead + (m, 2)), jac.reshape(lead + (m, 2, n))


@numba.njit(cache=True, nogil=True)
def _arc_kernel(t, h, series_below):  # pragma: no cover - compiled
    """δ(θ) and dδ/dθ of one notch (the scalar twin of kinematics.arc_translation)."""
    u = 0.5 * t
    su, cu = np.sin(u), np.cos(u)
    if abs(u) < series_below:
        sc = 1.0 - u * u / 6.0 + u ** 4 / 120.0
        dsc = -u / 3.0 + u ** 3 / 30.0
    else:
        sc = su / u
        dsc = (cu - sc) / u
    f = sc - cu
    df = dsc + su
    return h * f * su, h * f * cu, 0.5 * h * (df * su + f * cu), 0.5 * h * (df * cu - f * su)


class _Chain(NamedTuple):
    """Work arrays of one configuration's chain, filled by :func:`_chain_kernel`: the links' ``sin φ_l``,
    ``cos φ_l`` and origins ``(ox, oz)`` (n + 1) [m], and the arc model's shifts ``dδ/dθ`` in the base frame
    ``(ddx, ddz)`` (n) [m/rad] (zero for the pivot model). Made in compiled code (:func:`_new_chain`)."""

    s: np.ndarray
    c: np.ndarray
    ox: np.ndarray
    oz: np.ndarray
    ddx: np.ndarray
    ddz: np.ndarray


@numba.njit(cache=True, nogil=True)
def _new_chain(n):  # pragma: no cover - compiled
    """A fresh :class:`_Chain` of ``n`` joints."""
    return _Chain(np.empty(n + 1), np.empty(n + 1), np.empty(n + 1), np.empty(n + 1), np.zeros(n), np.zeros(n))


@numba.njit(cache=True, nogil=True)
def _chain_kernel(th, per_joint, arc, series_below, ch):  # pragma: no cover
    """Link orientations, origins and arc shifts of one configuration ``th`` (n,) into ``ch`` (:class:`_Chain`).

    ``per_joint`` (3, n): the pivot steps ``a_k - a_{k-1}`` (x, z) and the notch heights.
    """
    s, c, ox, oz, ddx, ddz = ch
    n = th.shape[0]
    dx, dz, h = per_joint[0], per_joint[1], per_joint[2]
    phi = 0.0
    s[0], c[0], ox[0], oz[0] = 0.0, 1.0, 0.0, 0.0
    for k in range(n):
        ex, ez = dx[k], dz[k]
        if arc:
            d0, d1, e0, e1 = _arc_kernel(th[k], h[k], series_below)
            ex += d0
            ez += d1
            ddx[k] = c[k] * e0 + s[k] * e1
            ddz[k] = -s[k] * e0 + c[k] * e1
        ox[k + 1] = ox[k] + (c[k] * ex + s[k] * ez)
        oz[k + 1] = oz[k] + (-s[k] * ex + c[k] * ez)
        phi += th[k]
        s[k + 1] = np.sin(phi)
        c[k + 1] = np.cos(phi)


@numba.njit(cache=True, nogil=True)
def _points_jac_kernel(th, tables, arc, series_below, pts, jac):  # pragma: no cover
    """Points ``pts`` (B, m, 2) [m] and Jacobians ``jac`` (B, m, 2, n) [m/rad] of the configurations ``th``
    (B, n), with the :func:`_tables` ``(link, lx, lz, per_joint)``."""
    link, lx, lz, per_joint = tables
    nb, n = th.shape
    m = link.shape[0]
    ch = _new_chain(n)
    s, c, ox, oz, ddx, ddz = ch
    for b in range(nb):
        _chain_kernel(th[b], per_joint, arc, series_below, ch)
        for i in range(m):
            L = link[i]
            x = ox[L] + c[L] * lx[i] + s[L] * lz[i]
            z = oz[L] - s[L] * lx[i] + c[L] * lz[i]
            pts[b, i, 0] = x
            pts[b, i, 1] = z
            for k in range(n):
                if k < L:
                    jac[b, i, 0, k] = z - oz[k + 1] + ddx[k]
                    jac[b, i, 1, k] = ox[k + 1] - x + ddz[k]
                else:
                    jac[b, i, 0, k] = 0.0
                    jac[b, i, 1, k] = 0.0


@numba.njit(cache=True, nogil=True)
def _chain_points(ch, link, lx, lz, pts):  # pragma: no cover - compiled
    """The notch points into ``pts`` (m, 2) [m] from the filled chain ``ch`` (:class:`_Chain`)."""
    s, c, ox, oz = ch.s, ch.c, ch.ox, ch.oz
    for i in range(link.shape[0]):
        L = link[i]
        pts[i, 0] = ox[L] + c[L] * lx[i] + s[L] * lz[i]
        pts[i, 1] = oz[L] - s[L] * lx[i] + c[L] * lz[i]


@numba.njit(cache=True, nogil=True)
def points_kernel(th, per_joint, link, lx, lz, s, c, ox, oz, dd, pts):  # pragma: no cover - compiled
    """The notch points of one configuration (pivot model) into ``pts`` (m, 2) [m].

    The tables are :class:`PointProjector`'s; ``s, c, ox, oz`` (n + 1) and
    ``dd`` (n) are work arrays (:meth:`PointProjector.work`). Callable from other compiled code; inside
    notchfit the real-time predictor projects with the projector's ``tables`` and work arrays of its own.
    """
    ch = _Chain(s, c, ox, oz, dd, dd)
    _chain_kernel(th, per_joint, False, 0.0, ch)
    _chain_points(ch, link, lx, lz, pts)


@numba.njit(cache=True, nogil=True)
def _points_one(th, tables, pts):  # pragma: no cover - compiled
    """:func:`points_kernel` with the :attr:`PointProjector.tables` ``(link, lx, lz, per_joint)`` and work
    arrays made in compiled code."""
    link, lx, lz, per_joint = tables
    ch = _new_chain(th.shape[0])
    _chain_kernel(th, per_joint, False, 0.0, ch)
    _chain_points(ch, link, lx, lz, pts)


@dataclass(frozen=True, eq=False)
class PointProjector:
    """``θ (n,) -> Q̃ (m, 2)`` of one configuration at a time (pivot model), compiled.

    The same points as :func:`notch_points` (tested to 1e-15 m) without its
    array overhead, for one shape per call (real-time use). Made by
    :func:`point_projector`.

    Attributes
    ----------
    link : ndarray (m,) int
        Link of each point.
    lx, lz : ndarray (m,) [m]
        Link-local coordinates from the link's pivot.
    per_joint : ndarray (3, n)
        Pivot steps (x, z) and notch heights (:func:`notchfit.physics.kinematics.chain`).
    """

    link: np.ndarray
    lx: np.ndarray
    lz: np.ndarray
    per_joint: np.ndarray

    @property
    def tables(self) -> tuple:
        """``(link, lx, lz, per_joint)`` in one plain tuple, as the compiled kernels take them."""
        return self.link, self.lx, self.lz, self.per_joint

    def work(self) -> tuple:
        """Fresh work arrays ``s, c, ox, oz, dd`` for :func:`points_kernel`."""
        n = self.per_joint.shape[1]
        return tuple(np.empty(n + 1) for _ in range(4)) + (np.zeros(n),)

    def __call__(self, theta) -> np.ndarray:
        """Points (m, 2) [m] of joint angles ``theta`` (n,) [rad]."""
        out = np.empty((self.link.shape[0], 2))
        _points_one(np.ascontiguousarray(theta, dtype=float), self.tables, out)
        return out


def point_projector(geom: Geometry) -> PointProjector:
    """The compiled one-configuration projector of ``geom`` (:class:`PointProjector`)."""
    link, lx, lz, per_joint = _tables(geom)
    return PointProjector(link, lx, lz, per_joint)


# --------------------------------------------------------------------------
# Plane frame
# --------------------------------------------------------------------------
def plane_rotation(phi) -> np.ndarray:
    """2-D rotation ``[[cos φ, -sin φ], [sin φ, cos φ]]`` (..., 2, 2)."""
    phi = np.asarray(phi, dtype=float)
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def to_plane(points, tx, ty, phi, mirror: bool = False) -> np.ndarray:
    """Map manipulator-frame (x, z) points into the plane frame (x, y).

    ``P = Rot(φ) · M · (x, z) + (t_x, t_y)`` with ``M = diag(-1, 1)`` when
    ``mirror`` (a view from -y, Fig. 12) and the identity otherwise. The
    manipulator origin (joint 1) maps to ``(t_x, t_y)``; with ``φ = 0`` and no
    mirror the backbone points along +y.

    Parameters
    ----------
    points : array_like, shape (..., m, 2) [m]
    tx, ty : float [m]; phi : float [rad]
    mirror : bool

    Returns
    -------
    ndarray, shape (..., m, 2) [m]
    """
    pts = np.asarray(points, dtype=float)
    x = -pts[..., 0] if mirror else pts[..., 0]
    z = pts[..., 1]
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * x - s * z + tx, s * x + c * z + ty], axis=-1)


def from_plane(points, tx, ty, phi, mirror: bool = False) -> np.ndarray:
    """Inverse of :func:`to_plane`: plane-frame (x, y) -> manipulator (x, z)."""
    pts = np.asarray(points, dtype=float)
    dx, dy = pts[..., 0] - tx, pts[..., 1] - ty
    c, s = np.cos(phi), np.sin(phi)
    x = c * dx + s * dy
    z = -s * dx + c * dy
    return np.stack([-x if mirror else x, z], axis=-1)


def plane_params_jacobian(points, phi, mirror: bool = False) -> np.ndarray:
    """``∂ to_plane / ∂(t_x, t_y, φ)`` at manipulator-frame ``points``.

    The derivative with respect to the points themselves is the constant
    matrix ``Rot(φ) M`` (see :func:`plane_rotation`).

    Returns
    -------
    ndarray, shape (..., m, 2, 3)
    """
    pts = np.asarray(points, dtype=float)
    x = -pts[..., 0] if mirror else pts[..., 0]
    z = pts[..., 1]
    c, s = np.cos(phi), np.sin(phi)
    out = np.zeros(pts.shape[:-1] + (2, 3))
    out[..., 0, 0] = 1.0
    out[..., 1, 1] = 1.0
    out[..., 0, 2] = -s * x - c * z
    out[..., 1, 2] = c * x - s * z
    return out
