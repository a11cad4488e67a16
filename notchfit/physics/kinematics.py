"""Backbone kinematics (Sec. II-A, Sec. III-C2 and the Appendix).

Two paths compute the same thing:

* the general SE(3) product of exponentials (``hat``, ``exp_twist``,
  ``adjoint``, :func:`link_frames`, :func:`spatial_jacobian`), written as in
  the paper and Murray, Li & Sastry, used as the test oracle;
* a closed-form planar path on cumulative angles (:func:`cumulative_angles`,
  :func:`joint_positions`, :func:`tip_pose`, :func:`planar_jacobian`),
  vectorized over leading axes, used wherever speed matters.

Conventions (CONVENTIONS.md): twists are ``ξ = (v, ω)`` (linear first); joint
``j`` rotates about ``+y`` through ``q_j = (x_na,j, 0, z_j)`` (``z_j =
geom.joint_z[j-1]``, ``x_na,j = geom.neutral_axis_x[j-1]``: ``(0, 0, (j-1) p)``
for the seed tube); a positive angle carries ``+z`` toward ``+x``. Planar
points are ``(x, z)`` pairs.

Real tubes (docs/models.md, "Real tubes: kinematics"): every function that
places links takes ``model="pivot"`` (default: a revolute joint at mid-notch
on the neutral axis, the paper's model) or ``model="arc"`` (the exact model:
each notch bends as a circular arc of its neutral axis, of length ``h_j`` =
the slot height, centred at ``z_j``; the links between notches are rigid).
The arc is the pivot followed by the translation :func:`arc_translation`.
The angles are absolute (``θ = 0`` is the straight tube; a rest angle is a
mechanics matter).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .geometry import Geometry
from ..validation import as_joint_angles

__all__ = [
    "KINEMATIC_MODELS",
    "Chain",
    "adjoint",
    "arc_translation",
    "chain",
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


# --------------------------------------------------------------------------
# Where the joints are (real tubes)
# --------------------------------------------------------------------------
KINEMATIC_MODELS = ("pivot", "arc")


@dataclass(frozen=True)
class Chain:
    """The straight-configuration constants of a geometry's kinematic chain.

    Attributes
    ----------
    pivots : ndarray, shape (n, 2)
        ``a_j = (x_na,j, z_j)``: mid-notch on joint ``j``'s bending axis [m].
    steps : ndarray, shape (n, 2)
        ``a_j - a_{j-1}`` with ``a_0 = (0, 0)`` (the base frame's origin) [m].
    heights : ndarray, shape (n,)
        Notch (slot) heights ``h_j`` [m]: the arc length of the ``"arc"`` model.
    tip : ndarray, shape (2,)
        The tool point ``(0, z_tip)`` (tube axis at the tip face) relative to
        ``a_n`` [m]; ``(0, p)`` for the seed tube.
    axis_offset : ndarray, shape (n,)
        ``x_na,j`` (0 for ``backbone = "axis"``): subtract from a link-local x
        measured from the tube axis to measure it from the link's pivot [m].
    uniform_axis : bool
        Seed-like chain (one spacing, joints on the tube axis, tip one
        spacing beyond the last joint): the paper's closed forms apply as
        written (Eqs. 18–20).
    """

    pivots: np.ndarray
    steps: np.ndarray
    heights: np.ndarray
    tip: np.ndarray
    axis_offset: np.ndarray
    uniform_axis: bool


def _tip_offset(geom: Geometry) -> float:
    """z of the tip face above the last joint [m] (``p`` exactly for a default tip)."""
    if geom.tip_face_z is None:
        return float(geom.pitches[-1])
    return float(geom.tip_face_z - geom.joint_z[-1])


@functools.lru_cache(maxsize=32)
def chain(geom: Geometry) -> Chain:
    """Joint positions, steps and notch heights of ``geom`` (read-only arrays, cached).

    Joint ``j`` sits at ``z_j = geom.joint_z[j-1]`` (per-joint spacing) and
    bends about ``x = geom.neutral_axis_x[j-1]`` (0 for ``backbone = "axis"``;
    the neutral axis of the wall left by the slot for ``"section"``, York et
    al., ICRA 2015, Eqs. 2–5, see :mod:`notchfit.physics.section`).
    """
    xna = np.asarray(geom.neutral_axis_x, dtype=float)
    piv = np.stack([xna, geom.joint_z], axis=-1)
    steps = np.diff(np.concatenate([np.zeros((1, 2)), piv]), axis=0)
    p = geom.pitches
    if np.all(p == p[0]):
        steps[1:, 1] = p[0]                  # exactly p, as (j - 1) p - (j - 2) p may not be
    tip = np.array([-xna[-1], _tip_offset(geom)])
    uniform = bool(np.all(p == p[0]) and not np.any(xna) and geom.tip_face_z is None)
    out = Chain(pivots=piv, steps=steps, heights=geom.slot_widths, tip=tip, axis_offset=xna,
                uniform_axis=uniform)
    for a in (out.pivots, out.steps, out.heights, out.tip, out.axis_offset):
        a.flags.writeable = False
    return out


def _check_model(model: str) -> None:
    if model not in KINEMATIC_MODELS:
        raise ValueError(f"model must be one of {KINEMATIC_MODELS}, got {model!r}")


def _sinc_and_derivative(u, series_below: float):
    """``sinc u = sin u / u`` and its derivative ``(cos u - sinc u) / u`` (series near 0)."""
    u = np.asarray(u, dtype=float)
    small = np.abs(u) < series_below
    us = np.where(small, 1.0, u)
    sc = np.where(small, 1.0 - u * u / 6.0 + u**4 / 120.0, np.sin(us) / us)
    dsc = np.where(small, -u / 3.0 + u**3 / 30.0, (np.cos(us) - np.sin(us) / us) / us)
    return sc, dsc


def arc_translation(theta, height, derivative: bool = False, *, series_below: float = 1e-3):
    """Translation that turns a mid-notch pivot into a circular-arc notch.

    A notch of height ``h`` whose neutral axis bends by ``θ`` as a circular arc
    (constant curvature ``κ = θ/h``; Webster & Jones, IJRR 29(13) 2010, Eq. 1
    for the arc's end point) moves the distal end, in the notch's proximal
    frame (origin at the proximal end of the arc, ``z`` along the tube), to the
    chord ``c(θ) = h ((1 - cos θ)/θ, sin θ/θ) = h sinc(θ/2) (sin(θ/2), cos(θ/2))``
    and turns it by ``θ``. A revolute joint at mid-notch on the neutral axis
    moves it to ``(h/2)(sin θ, 1 + cos θ) = h cos(θ/2) (sin(θ/2), cos(θ/2))``
    with the same rotation. So the arc is the pivot followed by

        δ(θ) = h (sinc(θ/2) - cos(θ/2)) (sin(θ/2), cos(θ/2))

    in the proximal frame: a stretch along the chord of ``h θ²/12 + O(h θ⁴)``
    (the pivot chain is short by that much per notch), with ``δ_x = h θ³/24 +
    O(h θ⁵)`` across the tube. ``θ → 0`` is handled by the series of
    ``sinc`` (no 0/0).

    Parameters
    ----------
    theta : array_like, shape (...)
        Joint angles [rad].
    height : array_like, broadcasting with theta
        Notch heights ``h`` [m].
    derivative : bool
        Also return ``dδ/dθ``.
    series_below : float
        ``|θ/2|`` below which ``sinc`` and its derivative use their Taylor series.

    Returns
    -------
    delta : ndarray, shape (..., 2) [m]
        ``(δ_x, δ_z)``.
    ddelta : ndarray, shape (..., 2) [m/rad]
        ``dδ/dθ``, only with ``derivative=True``.
    """
    u = 0.5 * np.asarray(theta, dtype=float)
    h = np.asarray(height, dtype=float)
    sc, dsc = _sinc_and_derivative(u, series_below)
    su, cu = np.sin(u), np.cos(u)
    f = sc - cu
    delta = np.stack([h * f * su, h * f * cu], axis=-1)
    if not derivative:
        return delta
    df = dsc + su
    dd = np.stack([0.5 * h * (df * su + f * cu), 0.5 * h * (df * cu - f * su)], axis=-1)
    return delta, dd


def _rot(c, s, v):
    """``R(φ) v`` for ``R = [[c, s], [-s, c]]`` (a positive angle carries +z toward +x)."""
    return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1]], axis=-1)


def link_origins(theta, geom: Geometry, model: str = "pivot", derivative: bool = False):
    """Orientation and origin of every link in the plane (the planar chain).

    Link ``l`` maps a straight-configuration point ``P`` on it to
    ``O_l + R(φ_l)(P - a_l)`` with ``φ_l = θ_1 + … + θ_l``, ``a_l`` its
    proximal pivot (:func:`chain`; ``a_0 = 0``, link 0 is the base) and

        O_0 = 0,   O_l = O_{l-1} + R(φ_{l-1}) (a_l - a_{l-1} + δ_l(θ_l)),

    ``δ = 0`` for ``model="pivot"`` and :func:`arc_translation` for ``"arc"``.
    ``O_l`` is where ``a_l`` goes: the pivot of joint ``l`` (pivot model).

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    geom : Geometry
    model : {"pivot", "arc"}
    derivative : bool
        Also return ``R(φ_{l-1}) dδ_l/dθ_l`` (zero for the pivot model).

    Returns
    -------
    phi : ndarray, shape (..., n + 1) [rad]
    origins : ndarray, shape (..., n + 1, 2) [m]
    dshift : ndarray, shape (..., n, 2) [m/rad], only with ``derivative=True``
    """
    _check_model(model)
    th = as_joint_angles(theta, geom.n_joints)
    ch = chain(geom)
    lead = th.shape[:-1]
    phi = np.zeros(lead + (geom.n_joints + 1,))
    np.cumsum(th, axis=-1, out=phi[..., 1:])
    s, c = np.sin(phi[..., :-1]), np.cos(phi[..., :-1])
    step = np.broadcast_to(ch.steps, th.shape + (2,))
    if model == "arc":
        d, dd = arc_translation(th, ch.heights, derivative=True)
        step = step + d
    out = np.zeros(lead + (geom.n_joints + 1, 2))
    np.cumsum(_rot(c, s, step), axis=-2, out=out[..., 1:, :])
    if not derivative:
        return phi, out
    dshift = _rot(c, s, dd) if model == "arc" else np.zeros(th.shape + (2,))
    return phi, out, dshift


def joint_twists(geom: Geometry) -> np.ndarray:
    """Joint twists ``ξ_i = (-ω × q_i, ω)`` = ``(-z_i, 0, x_na,i, 0, 1, 0)`` (Sec. II-A).

    ``q_i = (x_na,i, 0, z_i)`` (:func:`chain`); ``((1-i)p, 0, 0, 0, 1, 0)`` for
    the seed tube.

    Returns
    -------
    ndarray, shape (n, 6)
    """
    n = geom.n_joints
    xi = np.zeros((n, 6))
    ch = chain(geom)
    if ch.uniform_axis:
        xi[:, 0] = -np.arange(n) * geom.pitches[0]
    else:
        xi[:, 0] = -ch.pivots[:, 1]
        xi[:, 2] = ch.pivots[:, 0]
    xi[:, 4] = 1.0
    return xi


def _arc_se3(theta, h) -> tuple[np.ndarray, np.ndarray]:
    """``T(δ)`` (4, 4) and the spatial twist ``(δ', 0)`` (6,) of one notch's arc translation."""
    d, dd = arc_translation(theta, h, derivative=True)
    T = np.eye(4)
    T[0, 3], T[2, 3] = d
    return T, np.array([dd[0], 0.0, dd[1], 0.0, 0.0, 0.0])


def _notch_transforms(theta, geom: Geometry, model: str):
    """Per joint: ``A_k = T(δ_k) exp(ξ̂_k θ_k)`` (4, 4) and its spatial velocity ``dA_k A_k^{-1}`` (6,)."""
    _check_model(model)
    th = as_joint_angles(theta, geom.n_joints)
    if th.ndim != 1:
        raise ValueError("the SE(3) path takes one configuration (n,)")
    xis, h = joint_twists(geom), chain(geom).heights
    for k in range(geom.n_joints):
        E = exp_twist(xis[k], th[k])
        if model == "pivot":
            yield E, xis[k]
            continue
        T, vel = _arc_se3(th[k], h[k])
        d = T[:3, 3]
        twist = xis[k] + vel
        twist[:3] += np.cross(d, xis[k][3:])     # Ad_{T(δ)} ξ = (v + δ × ω, ω)
        yield T @ E, twist


def link_frames(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """Link frames ``g_si(θ) = A_1(θ_1) ⋯ A_i(θ_i) g_si(0)`` for i = 0..n (Sec. II-A).

    ``A_k = exp(ξ̂_k θ_k)`` (pivot model, the paper's product of
    exponentials) or ``T(δ_k(θ_k)) exp(ξ̂_k θ_k)`` (arc model,
    :func:`arc_translation`); ``g_si(0) = [I, (0, 0, z_i)]`` (link 0: identity),
    so link-local coordinates are measured from the tube axis at joint ``i``'s
    height, as in :func:`notchfit.physics.geometry.notch_layout`. General SE(3): the
    oracle for the planar path.

    Parameters
    ----------
    theta : array_like, shape (n,)
    geom : Geometry
    model : {"pivot", "arc"}

    Returns
    -------
    ndarray, shape (n + 1, 4, 4)
    """
    zj = np.arange(geom.n_joints) * geom.pitches[0] if chain(geom).uniform_axis else geom.joint_z
    out = np.empty((geom.n_joints + 1, 4, 4))
    out[0] = np.eye(4)
    h = np.eye(4)
    for i, (A, _) in enumerate(_notch_transforms(theta, geom, model), start=1):
        h = h @ A
        g0 = np.eye(4)
        g0[2, 3] = zj[i - 1]
        out[i] = h @ g0
    return out


def tool_frame(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """End-effector frame ``g_st(θ)`` with the tool point ``(0, 0, z_tip)`` on link n.

    ``z_tip = geom.tip_z`` (``n p`` for the seed tube): the tube axis at the tip face.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    g = link_frames(theta, geom, model)[-1]
    off = np.eye(4)
    off[2, 3] = _tip_offset(geom)  # from joint n to the tip face (p for the seed tube)
    return g @ off


def spatial_jacobian(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """Spatial manipulator Jacobian ``J_st^s = [ξ_1, ξ'_2, …, ξ'_n]`` (Appendix).

    ``ξ'_i = Ad_{h_i} ξ_i`` with ``h_i = A_1 ⋯ A_{i-1}``; Eq. (1). For the arc
    model ``ξ_i`` is the spatial velocity of ``A_i = T(δ_i) exp(ξ̂_i θ_i)``,
    ``(v_i + δ_i × ω + dδ_i/dθ_i, ω)``.

    Returns
    -------
    ndarray, shape (6, n)
    """
    J = np.empty((6, geom.n_joints))
    h = np.eye(4)
    for i, (A, twist) in enumerate(_notch_transforms(theta, geom, model)):
        J[:, i] = adjoint(h) @ twist
        h = h @ A
    return J


def body_jacobian(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """Body Jacobian ``J_st^b = Ad_{g_st}^{-1} J_st^s`` (Eq. 27), tool frame at the tip.

    Returns
    -------
    ndarray, shape (6, n)
    """
    g = tool_frame(theta, geom, model)
    return adjoint(inverse_se3(g)) @ spatial_jacobian(theta, geom, model)


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


def joint_positions(theta, geom, model: str = "pivot") -> np.ndarray:
    """Positions of joints 1..n and the tip point in the x–z plane.

    Parameters
    ----------
    theta : array_like, shape (..., n)
    geom : Geometry or float
        A geometry: joint ``j`` is the mid-notch point of its bending axis
        (the pivot ``O_j`` of :func:`link_origins`; for ``model="arc"`` the
        midpoint of the arc, ``h (1 - cos(θ/2))/θ, h sin(θ/2)/θ`` from the
        arc's proximal end), the tip point is ``(0, z_tip)`` on link n. A float
        ``p`` [m]: the paper's chain, joint 1 at the origin and segment i
        (length p) along ``(sin φ_i, cos φ_i)``.
    model : {"pivot", "arc"}
        Only with a geometry.

    Returns
    -------
    ndarray, shape (..., n + 1, 2)
        ``[..., i, :]`` is joint i+1 (the last row is the tip point) [m].
    """
    if not isinstance(geom, Geometry):
        phi = cumulative_angles(theta)
        seg = geom * np.stack([np.sin(phi), np.cos(phi)], axis=-1)
        out = np.zeros(phi.shape[:-1] + (phi.shape[-1] + 1, 2))
        np.cumsum(seg, axis=-2, out=out[..., 1:, :])
        return out
    phi, O = link_origins(theta, geom, model)
    ch = chain(geom)
    out = np.empty(O.shape)
    s, c = np.sin(phi[..., -1]), np.cos(phi[..., -1])
    out[..., -1, :] = O[..., -1, :] + _rot(c, s, np.broadcast_to(ch.tip, O.shape[:-2] + (2,)))
    if model == "pivot":
        out[..., :-1, :] = O[..., 1:, :]
        return out
    q = 0.25 * (phi[..., 1:] - phi[..., :-1])
    sc, _ = _sinc_and_derivative(q, 1e-3)
    # the mid-arc point: a half-height arc (chord (h/2) sinc(θ/4) (sin, cos)(θ/4), Webster & Jones
    # 2010) from the notch's proximal end a_j - (0, h_j/2)
    half = 0.5 * ch.heights[..., None] * (sc[..., None] * np.stack([np.sin(q), np.cos(q)], -1))
    local = ch.steps - np.stack([np.zeros_like(ch.heights), 0.5 * ch.heights], -1) + half
    prev = O[..., :-1, :]
    out[..., :-1, :] = prev + _rot(np.cos(phi[..., :-1]), np.sin(phi[..., :-1]), local)
    return out


def tip_pose(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """End-effector coordinates ``X = (x, z, φ)`` of Sec. III-C2 [m, m, rad].

    The tool point is ``(0, z_tip)`` on link n (:func:`tool_frame`).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    th = as_joint_angles(theta, geom.n_joints)
    if model == "pivot" and chain(geom).uniform_axis:
        q = joint_positions(th, geom.pitches[0])
    else:
        q = joint_positions(th, geom, model)
    return np.concatenate([q[..., -1, :], th.sum(axis=-1, keepdims=True)], axis=-1)


def planar_jacobian(theta, geom: Geometry, model: str = "pivot") -> np.ndarray:
    """Planar Jacobian ``J_X = ∂(x, z, φ)/∂θ`` (Eqs. 18–20).

    Seed-like chain, pivot model: ``J_xk = p Σ_{i≥k} cos φ_i``,
    ``J_zk = -p Σ_{i≥k} sin φ_i``, ``J_φk = 1`` as printed. In general joint
    ``k`` turns the tip ``X`` about ``O_k`` (:func:`link_origins`) and, for the
    arc model, moves it by ``R(φ_{k-1}) dδ_k/dθ_k``:
    ``(J_xk, J_zk) = (z - O_kz, O_kx - x) + R(φ_{k-1}) dδ_k/dθ_k``.

    Returns
    -------
    ndarray, shape (..., 3, n)
    """
    th = as_joint_angles(theta, geom.n_joints)
    _check_model(model)
    if model == "pivot" and chain(geom).uniform_axis:
        p = geom.pitches[0]
        phi = np.cumsum(th, axis=-1)
        rev = lambda a: np.flip(np.cumsum(np.flip(a, -1), axis=-1), -1)  # noqa: E731
        Jx = p * rev(np.cos(phi))
        Jz = -p * rev(np.sin(phi))
        return np.stack([Jx, Jz, np.ones_like(th)], axis=-2)
    tip = tip_pose(th, geom, model)[..., None, :2]
    _, O, dshift = link_origins(th, geom, model, derivative=True)
    d = tip - O[..., 1:, :]
    Jx = d[..., 1] + dshift[..., 0]
    Jz = -d[..., 0] + dshift[..., 1]
    return np.stack([Jx, Jz, np.ones_like(th)], axis=-2)


def joint_torques_from_tip_wrench(theta, geom: Geometry, f_x=0.0, f_z=0.0, m_y=0.0,
                                  model: str = "pivot") -> np.ndarray:
    """Joint torques ``J_X^T (f_x, f_z, m_y)`` of an in-plane load applied at the tip.

    The load acts *on* the manipulator (world frame); a positive ``f_x``
    bends the chain toward +x (positive θ). Equals ``J_st^s(θ)^T F_s`` with
    ``F_s`` from Eq. (28) (tested), for either kinematic model (the virtual
    work of the load through :func:`planar_jacobian`).

    Parameters
    ----------
    theta : array_like, shape (..., n)
    f_x, f_z : float or array_like broadcasting with theta[..., 0]
        Force [N]. m_y: moment about +y [N m].
    model : {"pivot", "arc"}

    Returns
    -------
    ndarray, shape (..., n) [N m]
    """
    J = planar_jacobian(theta, geom, model)
    f_x, f_z, m_y = (np.asarray(v, dtype=float)[..., None] for v in (f_x, f_z, m_y))
    return J[..., 0, :] * f_x + J[..., 1, :] * f_z + m_y
