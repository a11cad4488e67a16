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
"""

from __future__ import annotations

import numpy as np

__all__ = ["apply_point_warp", "point_warp_jacobian", "unwarp_points"]


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
