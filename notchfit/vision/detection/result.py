"""The detector's result and its table (``detections.csv``, data-format.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...units import MM

__all__ = ["STATUSES", "Detection", "detections_table", "empty_detection"]

STATUSES = ("ok", "ambiguous", "occluded")


@dataclass(frozen=True)
class Detection:
    """Result of :func:`~notchfit.vision.detection.detect_notches` for one image.

    Attributes
    ----------
    points : ndarray (m, 2)
        Notch points in the plane frame [m]; NaN unless the status is ``ok``.
        Without a calibration the plane frame is the image's, scaled to mm by
        the tube's diameter: ``(u, v) * scale`` (x right, y down).
    points_px : ndarray (m, 2)
        The same in the raw image [px] (u = column, v = row); NaN when not
        found (kept for ``ambiguous`` points).
    sigma : ndarray (m,)
        Standard uncertainty of each coordinate of an ok point [m]
        (``sqrt(trace(cov) / 2)``), NaN otherwise (the scale's own
        uncertainty, uncalibrated images, is in ``scale_sigma``).
    status : tuple of str (m,)
        ``ok``, ``ambiguous`` or ``occluded`` per point.
    image_status : str
        ``ok`` (every point ok), ``partial``, or ``no_manipulator``.
    message : str
        Why points are missing (empty when all are ok).
    contour_px : ndarray (K, 2)
        The silhouette outline with the slot mouths bridged [px] (overlays).
    blur_px : float
        Edge blur (Gaussian σ) measured from the profiles [px].
    scale_mm_per_px : float
        Image scale used for the plane coordinates [mm/px] (at the image
        centre for a calibrated camera).
    scale_sigma : float
        Standard uncertainty of ``scale_mm_per_px`` [mm/px]: 0 for a
        calibrated camera (its own uncertainty is the calibration's);
        without a camera file the spread of the diameter measurements, at
        least the disagreement with another band that also confirmed corners
        and with the scale the ok corners' rigid links imply; NaN when no
        corner is ``ok`` (nothing confirms the band measured).
    assumption : str
        How the scale was obtained, in words (empty for a calibrated camera).
    base_side : str
        Image side the base end points to (``top``, ``bottom``, ``left``,
        ``right``), empty when the base was not found.
    """

    points: np.ndarray
    points_px: np.ndarray
    sigma: np.ndarray
    status: tuple
    image_status: str
    message: str
    contour_px: np.ndarray
    blur_px: float = math.nan
    scale_mm_per_px: float = math.nan
    scale_sigma: float = math.nan
    assumption: str = ""
    base_side: str = ""

    @property
    def n_ok(self) -> int:
        """Number of points with status ``ok``."""
        return sum(s == "ok" for s in self.status)


def empty_detection(m, image_status, message, contour=None, status="occluded", **extra) -> Detection:
    """A detection with no point found (every point ``status``, NaN coordinates)."""
    nan = np.full((m, 2), np.nan)
    return Detection(nan, nan.copy(), np.full(m, np.nan), (status,) * m, image_status, message,
                     np.zeros((0, 2)) if contour is None else contour, **extra)


def detections_table(sample, det: Detection):
    """Rows of ``detections.csv`` (data-format.md) for one sample.

    Returns
    -------
    pandas.DataFrame with columns sample, point, x_mm, y_mm, u_px, v_px, sigma_mm, status
    """
    m = len(det.status)
    return pd.DataFrame({
        "sample": np.full(m, sample), "point": np.arange(1, m + 1),
        "x_mm": det.points[:, 0] / MM, "y_mm": det.points[:, 1] / MM,
        "u_px": det.points_px[:, 0], "v_px": det.points_px[:, 1],
        "sigma_mm": det.sigma / MM, "status": list(det.status)})
