"""Backbone kinematics (Sec. II-A, Sec. III-C2 and the Appendix).

Two paths compute the same thing:

* the general SE(3) product of exponentials (``hat``, ``exp_twist``,
  ``adjoint``, :func:`link_frames`, :func:`spatial_jacobian`), written as in
  the paper and Murray, Li & Sastry, used as the test oracle;
* a closed-form planar path on cumulative angles (:func:`cumulative_angles`,
  :func:`joint_positions`, :func:`tip_pose`, :func:`planar_jacobian`),
  vectorized over leading axes, used wherever speed matters.

Conventions (CONVENTIONS.md): twists are ``ξ = (v, ω)`` (linear first); joint
``j`` rotates about ``+y`` through ``q_j = (0, 0, (j-1) p)``; a positive angle
carries ``+z`` toward ``+x``. Planar points are ``(x, z)`` pairs.
"""

from __future__ import annotations

import numpy as np

from .geometry import Geometry
from .validation import as_joint_angles

__all__ = [
    "adjoint",
    "body_jacobian",
    "cumulative_angles",
    "exp_twist",
    "hat",
    "hat6",
    "joint_positions",
    "joint_torques_from_tip_wrench",
    "joint_twists",
    "link_frames",
    "planar_jacobian",
    "spatial_jacobian",
    "spatial_wrench_from_world",
    "tip_pose",
    "tool_frame",
    "vee",
    "vee6",
]


# --------------------------------------------------------------------------
# SE(3) machinery (Appendix)
# --------------------------------------------------------------------------
def hat(w) -> np.ndarray:
    """Skew matrix of a 3-vector: ``hat(w) @ v == cross(w, v)``.

    Parameters
    ----------
    w : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    w = np.asarray(w, dtype=float)
    if w.shape[-1] != 3:
        raise ValueError(f"hat expects (..., 3), got {w.shape}")
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def vee(W) -> np.ndarray:
    """Inverse of :func:`hat`: (..., 3, 3) skew -> (..., 3)."""
    W = np.asarray(W, dtype=float)
    return np.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], axis=-1)


def hat6(xi) -> np.ndarray:
    """Twist ``ξ = (v, ω)`` (..., 6) -> se(3) matrix (..., 4, 4)."""
    xi = np.asarray(xi, dtype=float)
    if xi.shape[-1] != 6:
        raise ValueError(f"hat6 expects (..., 6), got {xi.shape}")
    out = np.zeros(xi.shape[:-1] + (4, 4))
    out[..., :3, :3] = hat(xi[..., 3:])
    out[..., :3, 3] = xi[..., :3]
    return out


def vee6(X) -> np.ndarray:
    """Inverse of :func:`hat6`: (..., 4, 4) -> (v, ω) (..., 6)."""
    X = np.asarray(X, dtype=float)
    return np.concatenate([X[..., :3, 3], vee(X[..., :3, :3])], axis=-1)


def exp_twist(xi, theta) -> np.ndarray:
    """``exp(hat(ξ) θ)`` for a twist with unit ``ω`` or ``ω = 0`` (Murray Eq. 2.36).

    Parameters
    ----------
    xi : array_like, shape (6,)
        Twist ``(v, ω)``.
    theta : array_like, shape (...)
        Joint displacement [rad, or m for ω = 0].

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    xi = np.asarray(xi, dtype=float)
    th = np.asarray(theta, dtype=float)[..., None, None]
    v, w = xi[:3], xi[3:]
    g = np.zeros(np.shape(theta) + (4, 4))
    g[..., 3, 3] = 1.0
    nw = np.linalg.norm(w)
    if nw == 0.0:
        g[..., :3, :3] = np.eye(3)
        g[..., :3, 3] = v * th[..., 0]
        return g
    if not np.isclose(nw, 1.0):
        raise ValueError("exp_twist needs a unit rotation axis (or ω = 0)")
    W = hat(w)
    R = np.eye(3) + np.sin(th) * W + (1.0 - np.cos(th)) * (W @ W)
    g[..., :3, :3] = R
    wv = np.cross(w, v)
    g[..., :3, 3] = ((np.eye(3) - R) @ wv) + np.outer(w, w) @ v * th[..., 0]
    return g


def adjoint(g) -> np.ndarray:
    """Adjoint ``Ad_g = [[R, p̂ R], [0, R]]`` of g in SE(3) (Appendix).

    Parameters
    ----------
    g : array_like, shape (..., 4, 4)

    Returns
    -------
    ndarray, shape (..., 6, 6)
    """
    g = np.asarray(g, dtype=float)
    R, p = g[..., :3, :3], g[..., :3, 3]
    out = np.zeros(g.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = hat(p) @ R
    return out


def inverse_se3(g) -> np.ndarray:
    """Inverse of a homogeneous transform (..., 4, 4)."""
    g = np.asarray(g, dtype=float)
    out = np.zeros_like(g)
    Rt = np.swapaxes(g[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -(Rt @ g[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def joint_twists(geom: Geometry) -> np.ndarray:
    """Joint twists ``ξ_i = (-ω × q_i, ω)`` = ``((1-i)p, 0, 0, 0, 1, 0)`` (Sec. II-A).

    Returns
    -------
    ndarray, shape (n, 6)
    """
    n = geom.n_joints
    xi = np.zeros((n, 6))
    xi[:, 0] = -np.arange(n) * geom.p
    xi[:, 4] = 1.0
    return xi


def link_frames(theta, geom: Geometry) -> np.ndarray:
    """Link frames ``g_si(θ) = Π_{k≤i} exp(ξ̂_k θ_k) g_si(0)`` for i = 0..n (Sec. II-A).

    ``g_si(0) = [I, q_i]`` with ``q_i = (0, 0, (i-1)p)`` (link 0: identity).
    General SE(3) product of exponentials: the oracle for the planar path.

    Parameters
    ----------
    theta : array_like, shape (n,)

    Returns
    -------
    ndarray, shape (n + 1, 4, 4)
    """
    th = as_joint_angles(theta, geom.n_joints)
    if th.ndim != 1:
        raise ValueError("link_frames takes one configuration (n,)")
    xis = joint_twists(geom)
    out = np.empty((geom.n_joints + 1, 4, 4))
    out[0] = np.eye(4)
    h = np.eye(4)
    for i in range(1, geom.n_joints + 1):
        h = h @ exp_twist(xis[i - 1], th[i - 1])
        g0 = np.eye(4)
        g0[2, 3] = (i - 1) * geom.p
        out[i] = h @ g0
    return out


def tool_frame(theta, geom: Geometry) -> np.ndarray:
    """End-effector frame ``g_st(θ)`` with the tool point ``(0, 0, n p)`` on link n.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    g = link_frames(theta, geom)[-1]
    off = np.eye(4)
    off[2, 3] = geom.p  # from joint n (at (n-1)p) to the tip face (n p)
    return g @ off


def spatial_jacobian(theta, geom: Geometry) -> np.ndarray:
    """Spatial manipulator Jacobian ``J_st^s = [ξ_1, ξ'_2, …, ξ'_n]`` (Appendix).

    ``ξ'_i = Ad_{h_i} ξ_i`` with ``h_i = Π_{k<i} exp(ξ̂_k θ_k)``; Eq. (1).

    Returns
    -------
    ndarray, shape (6, n)
    """
    th = as_joint_angles(theta, geom.n_joints)
    xis = joint_twists(geom)
    J = np.empty((6, geom.n_joints))
    h = np.eye(4)
    for i in range(geom.n_joints):
        J[:, i] = adjoint(h) @ xis[i]
        h = h @ exp_twist(xis[i], th[i])
    return J


def body_jacobian(theta, geom: Geometry) -> np.ndarray:
    """Body Jacobian ``J_st^b = Ad_{g_st}^{-1} J_st^s`` (Eq. 27), tool frame at the tip.

    Returns
    -------
    ndarray, shape (6, n)
    """
    g = tool_frame(theta, geom)
    return adjoint(inverse_se3(g)) @ spatial_jacobian(theta, geom)


def spatial_wrench_from_world(f, tau, g_st) -> np.ndarray:
    """Spatial wrench ``F_s = (f, p̂_st f + τ)`` of a world-frame load at the tool (Eq. 28).

    Parameters
    ----------
    f, tau : array_like, shape (3,)
        Force [N] and torque [N m] in world coordinates, applied at the tool point.
    g_st : array_like, shape (4, 4)
        Tool frame.

    Returns
    -------
    ndarray, shape (6,)
    """
    f = np.asarray(f, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if f.shape != (3,) or tau.shape != (3,):
        raise ValueError("f and tau must be 3-vectors")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(tau))):
        raise ValueError("tip load contains NaN or inf")
    p = np.asarray(g_st, dtype=float)[:3, 3]
    return np.concatenate([f, np.cross(p, f) + tau])


# --------------------------------------------------------------------------
# Planar closed form (hot path)
# --------------------------------------------------------------------------
def cumulative_angles(theta) -> np.ndarray:
    """Link orientation ``φ_i = Σ_{k≤i} θ_k`` (..., n) [rad]."""
    return np.cumsum(as_joint_angles(theta), axis=-1)


def joint_positions(theta, p: float) -> np.ndarray:
    """Positions of joints 1..n and the tip point in the x–z plane.

    Joint 1 is at the origin; segment i (joint i to i+1, length p) points
    along ``(sin φ_i, cos φ_i)``.

    Parameters
    ----------
    theta : array_like, shape (..., n)
    p : float
        Link spacing [m].

    Returns
    -------
    ndarray, shape (..., n + 1, 2)
        ``[..., i, :]`` is joint i+1 (the last row is the tip point) [m].
    """
    phi = cumulative_angles(theta)
    seg = p * np.stack([np.sin(phi), np.cos(phi)], axis=-1)
    out = np.zeros(phi.shape[:-1] + (phi.shape[-1] + 1, 2))
    np.cumsum(seg, axis=-2, out=out[..., 1:, :])
    return out


def tip_pose(theta, geom: Geometry) -> np.ndarray:
    """End-effector coordinates ``X = (x, z, φ)`` of Sec. III-C2 [m, m, rad].

    Returns
    -------
    ndarray, shape (..., 3)
    """
    th = as_joint_angles(theta, geom.n_joints)
    q = joint_positions(th, geom.p)
    return np.concatenate([q[..., -1, :], th.sum(axis=-1, keepdims=True)], axis=-1)


def planar_jacobian(theta, geom: Geometry) -> np.ndarray:
    """Planar Jacobian ``J_X = ∂(x, z, φ)/∂θ`` (Eqs. 18–20).

    ``J_xk = p Σ_{i≥k} cos φ_i``, ``J_zk = -p Σ_{i≥k} sin φ_i``, ``J_φk = 1``.

    Returns
    -------
    ndarray, shape (..., 3, n)
    """
    th = as_joint_angles(theta, geom.n_joints)
    phi = np.cumsum(th, axis=-1)
    rev = lambda a: np.flip(np.cumsum(np.flip(a, -1), axis=-1), -1)  # noqa: E731
    Jx = geom.p * rev(np.cos(phi))
    Jz = -geom.p * rev(np.sin(phi))
    return np.stack([Jx, Jz, np.ones_like(th)], axis=-2)


def joint_torques_from_tip_wrench(theta, geom: Geometry, f_x=0.0, f_z=0.0, m_y=0.0) -> np.ndarray:
    """Joint torques ``J_X^T (f_x, f_z, m_y)`` of an in-plane load applied at the tip.

    The load acts *on* the manipulator (world frame); a positive ``f_x``
    bends the chain toward +x (positive θ). Equals ``J_st^s(θ)^T F_s`` with
    ``F_s`` from Eq. (28) (tested).

    Parameters
    ----------
    theta : array_like, shape (..., n)
    f_x, f_z : float or array_like broadcasting with theta[..., 0]
        Force [N]. m_y: moment about +y [N m].

    Returns
    -------
    ndarray, shape (..., n) [N m]
    """
    J = planar_jacobian(theta, geom)
    f_x, f_z, m_y = (np.asarray(v, dtype=float)[..., None] for v in (f_x, f_z, m_y))
    return J[..., 0, :] * f_x + J[..., 1, :] * f_z + m_y
