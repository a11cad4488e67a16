"""Closed-form first pass of the shape fits: input checks, plane transform and joint angles.

Measured notch points ``Q_i`` [m] live in the plane frame; the first pass
places the manipulator in the plane (2-D Procrustes fits of the base link's
points, :func:`initial_transform`) and estimates each sample's joint angles
link by link (:func:`estimate_angles`). Both start the least-squares fits of
:mod:`notchfit.analysis.fitting.core`.
"""

from __future__ import annotations

import numpy as np

from ...physics.geometry import Geometry, notch_layout
from ...physics.kinematics import chain
from .results import as_transform

__all__ = ["as_points", "as_sigma", "estimate_angles", "initial_transform"]


def as_points(points, geom: Geometry) -> np.ndarray:
    """Measured points as a float copy (S, m, 2) [m]; a point with any non-finite coordinate becomes NaN."""
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


def as_sigma(sigma, shape) -> np.ndarray:
    """Point uncertainty broadcast to ``shape`` = (S, m) [m]; NaN drops a point, others must be > 0."""
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
    Q = as_points(points, geom)
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
    follows from the previous links, :func:`notchfit.physics.kinematics.link_origins`
    with the pivot model: per-joint spacing and neutral-axis offsets). Links
    without points continue the previous angle increment.

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
    Q = as_points(points, geom)
    T = as_transform(transform)
    X = T.from_plane(Q)
    lay = notch_layout(geom)
    S, n, ch = Q.shape[0], geom.n_joints, chain(geom)
    phis = np.zeros((S, n + 1))
    q = np.zeros((S, 2))                                     # the pivot of the current link
    seen = np.zeros(S, dtype=bool)
    for link in range(1, n + 1):
        (dx, dz), prev_phi = ch.steps[link - 1], phis[:, link - 1]
        c, s = np.cos(prev_phi), np.sin(prev_phi)
        q = q + np.stack([c * dx + s * dz, -s * dx + c * dz], -1)
        idx = np.nonzero(lay.link == link)[0]
        L = lay.local[idx] - np.array([ch.axis_offset[link - 1], 0.0])   # (k, 2) from the pivot
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
