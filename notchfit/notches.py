"""The kinematic notch-point projector (Sec. IV-A) and the plane transform.

``θ → Q̃`` maps joint angles to the virtual notch points ``Q̃_i`` (numbered
as ``docs/geometry.md`` says) in the manipulator frame, with the
analytic Jacobian ``∂Q̃/∂θ``. :func:`to_plane` maps manipulator-frame points
into the measured plane frame by a proper rigid 2-D transform, optionally
after a mirror (a view from ``-y``).

Shapes: joint angles ``(..., n)``; points ``(..., m, 2)`` as (x, z) in the
manipulator frame or (x, y) in the plane frame; the Jacobian
``(..., m, 2, n)``, which ``.reshape(..., 2 m, n)`` turns into the paper's
``(58·2 × n)`` matrix with rows ``x_1, z_1, x_2, z_2, …``.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from .geometry import Geometry, notch_layout
from .validation import as_joint_angles

__all__ = [
    "from_plane",
    "notch_points",
    "notch_points_and_jacobian",
    "plane_params_jacobian",
    "plane_rotation",
    "to_plane",
]


@functools.lru_cache(maxsize=32)
def _tables(geom: Geometry):
    lay = notch_layout(geom)
    return lay.link, lay.local[:, 0].copy(), lay.local[:, 1].copy()


def _frames(theta, geom: Geometry):
    th = as_joint_angles(theta, geom.n_joints)
    lead = th.shape[:-1]
    n = geom.n_joints
    phi = np.zeros(lead + (n + 1,))
    np.cumsum(th, axis=-1, out=phi[..., 1:])           # phi[l] = orientation of link l
    s, c = np.sin(phi), np.cos(phi)
    q = np.zeros(lead + (n + 1, 2))                     # q[k] = joint k+1 (q[n] = tip)
    np.cumsum(geom.p * s[..., 1:], axis=-1, out=q[..., 1:, 0])
    np.cumsum(geom.p * c[..., 1:], axis=-1, out=q[..., 1:, 1])
    return s, c, q


def _points(s, c, q, geom):
    link, lx, lz = _tables(geom)
    # link l >= 1 has its origin at joint l (q[l-1]); link 0 at the origin (= q[0])
    org = q[..., np.maximum(link - 1, 0), :]
    sl, cl = s[..., link], c[..., link]
    x = org[..., 0] + cl * lx + sl * lz
    z = org[..., 1] - sl * lx + cl * lz
    return np.stack([x, z], axis=-1)


def notch_points(theta, geom: Geometry) -> np.ndarray:
    """Virtual notch points ``Q̃(θ)`` in the manipulator frame (Sec. IV-A).

    Parameters
    ----------
    theta : array_like, shape (..., n)
        Joint angles [rad].
    geom : Geometry

    Returns
    -------
    ndarray, shape (..., m, 2)
        (x, z) of each point [m], m = 58 for the default manipulator.
    """
    s, c, q = _frames(theta, geom)
    return _points(s, c, q, geom)


def notch_points_and_jacobian(theta, geom: Geometry):
    """Notch points and their analytic Jacobian ``∂Q̃/∂θ``.

    A joint ``k`` rotates every point on links ``l ≥ k`` about ``q_k``:
    ``∂Q̃_i/∂θ_k = (z_i - z_{q_k}, -(x_i - x_{q_k}))`` if ``k ≤ link(i)``, else 0.
    Computed by a compiled (numba) kernel that writes both outputs in one pass
    over the configurations; see ``benchmarks/bench_kinematics.py``.

    Parameters
    ----------
    theta : array_like, shape (..., n)

    Returns
    -------
    points : ndarray, shape (..., m, 2) [m]
    jac : ndarray, shape (..., m, 2, n) [m/rad]
    """
    th = np.asarray(theta, dtype=float)
    n = geom.n_joints
    if th.ndim == 0 or th.shape[-1] != n:
        raise ValueError(f"joint angles must have shape (..., {n}), got {np.shape(theta)}")
    if not np.isfinite(th).all():
        raise ValueError("joint angles contain NaN or inf")
    link, lx, lz = _tables(geom)
    lead = th.shape[:-1]
    m = link.shape[0]
    flat = np.ascontiguousarray(th).reshape(-1, n)
    pts = np.empty((flat.shape[0], m, 2))
    jac = np.empty((flat.shape[0], m, 2, n))
    _points_jac_kernel(flat, geom.p, link, lx, lz, pts, jac)
    return pts.reshape(lead + (m, 2)), jac.reshape(lead + (m, 2, n))


@numba.njit(cache=True, nogil=True)
def _points_jac_kernel(th, p, link, lx, lz, pts, jac):  # pragma: no cover - compiled
    nb, n = th.shape
    m = link.shape[0]
    s = np.empty(n + 1)
    c = np.empty(n + 1)
    qx = np.empty(n + 1)
    qz = np.empty(n + 1)
    for b in range(nb):
        phi = 0.0
        s[0], c[0], qx[0], qz[0] = 0.0, 1.0, 0.0, 0.0
        for k in range(n):
            phi += th[b, k]
            s[k + 1] = np.sin(phi)
            c[k + 1] = np.cos(phi)
            qx[k + 1] = qx[k] + p * s[k + 1]
            qz[k + 1] = qz[k] + p * c[k + 1]
        for i in range(m):
            L = link[i]
            o = L - 1 if L > 0 else 0
            x = qx[o] + c[L] * lx[i] + s[L] * lz[i]
            z = qz[o] - s[L] * lx[i] + c[L] * lz[i]
            pts[b, i, 0] = x
            pts[b, i, 1] = z
            for k in range(n):
                if k < L:
                    jac[b, i, 0, k] = z - qz[k]
                    jac[b, i, 1, k] = qx[k] - x
                else:
                    jac[b, i, 0, k] = 0.0
                    jac[b, i, 1, k] = 0.0


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
