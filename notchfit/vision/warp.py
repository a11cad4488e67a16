"""Calibration error of the image-to-plane mapping, as a point warp in the plane frame.

The ``calibration_error`` cause (docs/data-formats.md) is a wrong image-to-plane
mapping: an uncorrected radial lens distortion and a wrong scale. Seen in the
plane frame it is a radial warp about the point ``c`` where the optical axis
meets the plane:

``P' = c + (1 + s) (1 + k |P - c|² / ρ²) (P - c)``

with scale error ``s``, radial coefficient ``k`` and a normalising radius
``ρ`` (10 mm by default, so ``k`` is the relative stretch 10 mm from ``c``).
No joint configuration explains it: a scale error stretches every link
length ``p``, a radial term bends straight edges. The synthetic generator
applies it to true points; the diagnosis fits it (the "point-warp calibration
correction") on predicted points, and :func:`unwarp_points` corrects
measured data.

A **tilted bending plane** is the other camera-plane error: the tube bends in
a plane turned by a small rotation ``ω = (ω_x, ω_y)`` (an in-plane axis times
the angle ``|ω|``) about ``c`` against the calibrated plane, and a camera at
distance ``D`` on the calibrated plane's normal through ``c`` sees it in
perspective. Mapped back onto the calibrated plane the true point ``P``
lands at the central projection of ``X = c + R(ω) (P − c, 0)``:

``q = c + D / (D − X_z) · (X_xy − c)``

a plane-to-plane homography (:func:`tilt_homography`): foreshortening by
``cos |ω|`` across the axis and a perspective term ``∝ |ω| |P − c| / D``;
neither is a joint configuration or an in-plane warp. An offset plane (a
wrong ``D``) is a scale error. :func:`apply_camera_plane_warp` composes both
in the order light takes: the tilted plane is projected, then the wrong
image-to-plane mapping (scale and radial terms) warps the result.
"""

from __future__ import annotations

import numpy as np

__all__ = ["apply_camera_plane_warp", "apply_plane_tilt", "apply_point_warp", "point_warp_jacobian",
           "tilt_homography", "unapply_plane_tilt", "unwarp_camera_plane", "unwarp_points"]


def _check(points, center):
    P = np.asarray(points, dtype=float)
    c = np.asarray(center, dtype=float)
    if P.shape[-1] != 2 or c.shape != (2,):
        raise ValueError(f"points must be (..., 2) and center (2,), got {P.shape} and {c.shape}")
    return P, c


def apply_point_warp(points, scale_error: float, k_radial: float, center, radius: float = 0.01):
    """Warp plane-frame points: ``c + (1+s)(1 + k r²/ρ²)(P - c)``.

    Parameters
    ----------
    points : array_like, shape (..., 2) [m]
        Plane-frame points; NaN stays NaN.
    scale_error : float
        Relative scale error ``s`` [-].
    k_radial : float
        Radial coefficient ``k`` at distance ``radius`` [-].
    center : array_like, shape (2,) [m]
        Centre ``c`` of the distortion in the plane frame.
    radius : float
        Normalising radius ``ρ`` [m].

    Returns
    -------
    ndarray, shape (..., 2) [m]
    """
    P, c = _check(points, center)
    d = P - c
    r2 = np.sum(d * d, axis=-1, keepdims=True) / radius**2
    return c + (1.0 + scale_error) * (1.0 + k_radial * r2) * d


def point_warp_jacobian(points, scale_error: float, k_radial: float, center, radius: float = 0.01):
    """Derivatives of :func:`apply_point_warp` with respect to ``(s, k, c_x, c_y)``.

    Returns
    -------
    ndarray, shape (..., 2, 4)
    """
    P, c = _check(points, center)
    d = P - c
    r2 = np.sum(d * d, axis=-1, keepdims=True) / radius**2
    g = 1.0 + k_radial * r2                            # (..., 1)
    out = np.empty(P.shape[:-1] + (2, 4))
    out[..., 0] = g * d
    out[..., 1] = (1.0 + scale_error) * r2 * d
    # d/dc of c + (1+s) g(d) d with d = P - c: I - (1+s)(g I + d ∂g/∂d)
    dg = 2.0 * k_radial * d / radius**2               # ∂g/∂d, (..., 2)
    for a in range(2):
        e = np.zeros(2)
        e[a] = 1.0
        out[..., a + 2] = e - (1.0 + scale_error) * (g * e + d * dg[..., a:a + 1])
    return out


def unwarp_points(points, scale_error: float, k_radial: float, center, radius: float = 0.01,
                  *, tol: float = 1e-15, max_iter: int = 50):
    """Inverse of :func:`apply_point_warp` (Newton on the radial distance).

    ``|d'| = (1+s)(|d| + k |d|³/ρ²)`` is solved for ``|d|`` per point; the
    direction is unchanged. Requires the warp to be monotone over the data
    (``1 + 3 k r²/ρ² > 0``), which holds for any realistic distortion.

    Returns
    -------
    ndarray, shape (..., 2) [m]
    """
    P, c = _check(points, center)
    if 1.0 + scale_error <= 0:
        raise ValueError("scale_error must be > -1")
    d1 = P - c
    rho1 = np.linalg.norm(d1, axis=-1) / (1.0 + scale_error)   # target of r (1 + k r²/ρ²)
    r = rho1.copy()
    for _ in range(max_iter):
        f = r + k_radial * r**3 / radius**2 - rho1
        fp = 1.0 + 3.0 * k_radial * r**2 / radius**2
        if np.any(fp[np.isfinite(fp)] <= 0):
            raise ValueError("the warp is not monotone over these points; cannot invert")
        step = f / fp
        r = r - step
        if np.all(~np.isfinite(step) | (np.abs(step) <= tol * np.maximum(1.0, rho1))):
            break
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(rho1 > 0, r / (rho1 * (1.0 + scale_error)), 1.0 / (1.0 + scale_error))
    return c + d1 * scale[..., None]


def _rotation(tilt) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector ``(ω_x, ω_y, 0)`` (Rodrigues' formula)."""
    w = np.array([float(tilt[0]), float(tilt[1]), 0.0])
    a = float(np.linalg.norm(w))
    if a == 0.0:
        return np.eye(3)
    k = w / a
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * (K @ K)


def tilt_homography(tilt, distance: float) -> np.ndarray:
    """Homography (3, 3) of a tilted plane seen in perspective, in coordinates about its centre.

    ``(q − c) ~ H (P − c, 1)``: the true plane turned by the rotation vector
    ``(ω_x, ω_y, 0)`` about ``c``, projected from a centre at height
    ``distance`` on the calibrated plane's normal through ``c``.

    Parameters
    ----------
    tilt : (2,) [rad]
        Rotation vector ``ω`` of the bending plane against the calibrated one.
    distance : float [m]
        Distance ``D`` from the projection centre (the camera) to ``c``.

    Returns
    -------
    ndarray (3, 3)
    """
    if not distance > 0:
        raise ValueError(f"distance must be > 0, got {distance}")
    R = _rotation(tilt)
    D = float(distance)
    return np.array([[D * R[0, 0], D * R[0, 1], 0.0],
                     [D * R[1, 0], D * R[1, 1], 0.0],
                     [-R[2, 0], -R[2, 1], D]])


def _homography(P, c, H):
    d = P - c
    num = d @ H[:2, :2].T + H[:2, 2]
    den = d @ H[2, :2] + H[2, 2]
    return c + num / den[..., None]


def apply_plane_tilt(points, tilt, center, distance: float = 0.25):
    """Where points of a tilted bending plane appear on the calibrated plane (:func:`tilt_homography`).

    Parameters
    ----------
    points : array_like (..., 2) [m]
        True points in the (tilted) bending plane's own frame; NaN stays NaN.
    tilt : (2,) [rad]
        Rotation vector of the bending plane against the calibrated one.
    center : array_like (2,) [m]
        Where the camera's axis meets the plane (the rotation's fixed point).
    distance : float [m]
        Camera to plane distance (0.25 m: a lab camera over a 20-40 mm tube).

    Returns
    -------
    ndarray (..., 2) [m]
    """
    P, c = _check(points, center)
    return _homography(P, c, tilt_homography(tilt, distance))


def unapply_plane_tilt(points, tilt, center, distance: float = 0.25):
    """Inverse of :func:`apply_plane_tilt` (the inverse homography)."""
    P, c = _check(points, center)
    return _homography(P, c, np.linalg.inv(tilt_homography(tilt, distance)))


def apply_camera_plane_warp(points, scale_error: float, k_radial: float, center, *, tilt=(0.0, 0.0),
                            radius: float = 0.01, distance: float = 0.25):
    """The whole camera-plane error: the tilted plane projected, then the scale and radial warp.

    ``apply_point_warp(apply_plane_tilt(P, tilt, c, D), s, k, c, ρ)``; with
    ``tilt = (0, 0)`` it is :func:`apply_point_warp` exactly.

    Returns
    -------
    ndarray (..., 2) [m]
    """
    return apply_point_warp(apply_plane_tilt(points, tilt, center, distance), scale_error, k_radial,
                            center, radius)


def unwarp_camera_plane(points, scale_error: float, k_radial: float, center, *, tilt=(0.0, 0.0),
                        radius: float = 0.01, distance: float = 0.25):
    """Inverse of :func:`apply_camera_plane_warp`: measured points back to the bending plane."""
    return unapply_plane_tilt(unwarp_points(points, scale_error, k_radial, center, radius), tilt, center,
                              distance)
