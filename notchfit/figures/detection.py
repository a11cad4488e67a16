"""The detector's overlay image (written by ``notchfit detect``, one per sample).

No paper figure here (no ``FIGURES``): :func:`detection_overlay` returns the
image; the command writes it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["detection_overlay"]


def detection_overlay(image, det, sample, *, height: int = 1000) -> np.ndarray:
    """The detection drawn on its image, the whole view beside a crop around the tube, labelled.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3|4)
        The sample's image (any size: 16–24 MP photographs included).
    det : notchfit.detection.Detection
    sample : int
        Sample id for the label.
    height : int
        Height of the composed image [px]: markers, numbers and the label are
        drawn at this scale, so they are readable whatever the photograph's size.

    Returns
    -------
    ndarray, shape (height, W', 3), uint8 (BGR)
        :func:`notchfit.detection.overlay_with_crop` and a ``sample S: k/m ok`` label.
    """
    # slow optional dependency: the overlay is drawn with cv2 (as is notchfit.detection)
    import cv2

    from ..detection import overlay_with_crop

    ov = overlay_with_crop(image, det, height=height)
    cv2.putText(ov, f"sample {sample}: {det.n_ok}/{len(det.status)} ok", (10, 28),
                cv2.FONT_HERSHEY_SIMPLEX, 0.8, (0, 0, 255), 2, cv2.LINE_AA)
    return ov
