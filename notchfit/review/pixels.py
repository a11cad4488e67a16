"""Image pixels <-> plane millimetres for a corner a person places, as the detect run mapped them.

With a camera file the camera model maps (lens distortion, the plane's
pose: :meth:`notchfit.vision.camera.CameraModel.pixel_to_plane`); without one the
detect run took a fronto-parallel view at a scale from the tube's diameter
(:class:`notchfit.vision.detection.view.DiameterScale`), whose scale is read back
from the sample's own detections (``x = s u``, ``y = -s v``: a least-squares
``s`` over its corners).
"""

from __future__ import annotations

import numpy as np

from ..units import MM

__all__ = ["DiameterView", "pixel_views"]


class DiameterView:
    """A fronto-parallel view at ``m_per_px``: plane ``(u, -v) * m_per_px`` [m] (no lens model)."""

    def __init__(self, m_per_px: float):
        self.m_per_px = float(m_per_px)

    def pixel_to_plane(self, uv) -> np.ndarray:
        """Pixels (..., 2) -> plane [m]."""
        uv = np.asarray(uv, float)
        return np.stack([uv[..., 0], -uv[..., 1]], -1) * self.m_per_px

    def plane_to_pixel(self, xy) -> np.ndarray:
        """Plane [m] (..., 2) -> pixels."""
        xy = np.asarray(xy, float) / self.m_per_px
        return np.stack([xy[..., 0], -xy[..., 1]], -1)

    def plane_scale(self, xy=None) -> float:
        """Scale [px per m]."""
        return 1.0 / self.m_per_px


def diameter_scale(uv, xy_mm) -> float:
    """The scale [m/px] that maps detected pixels ``uv`` (k, 2) to plane ``xy_mm`` (k, 2) as ``(u, -v) s``;
    NaN when no corner has both."""
    uv, xy = np.asarray(uv, float), np.asarray(xy_mm, float) * MM
    ok = np.isfinite(uv).all(-1) & np.isfinite(xy).all(-1)
    if not ok.any():
        return float("nan")
    a = np.stack([uv[ok, 0], -uv[ok, 1]], -1)
    return float((a * xy[ok]).sum() / (a * a).sum())


def pixel_views(camera, uv, xy_mm) -> list:
    """One pixel <-> plane map per sample.

    Parameters
    ----------
    camera : CameraModel or None
        The experiment's camera (with its plane pose); None: the diameter scale.
    uv : array (S, m, 2) [px]
        Detected pixels (NaN = none).
    xy_mm : array (S, m, 2) [mm]
        Their plane coordinates from detections.csv.

    Returns
    -------
    list of length S
        The camera for every sample, or a :class:`DiameterView` at the
        sample's scale (the experiment's median when the sample has no
        detected corner; None when no sample has one).
    """
    if camera is not None:
        return [camera] * len(uv)
    scales = np.array([diameter_scale(a, b) for a, b in zip(uv, xy_mm)])
    fallback = float(np.nanmedian(scales)) if np.isfinite(scales).any() else float("nan")
    return [DiameterView(s if np.isfinite(s) else fallback) if np.isfinite(fallback) else None for s in scales]
