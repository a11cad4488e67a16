"""The detector's overlay image (written by ``notchfit detect``, one per sample).

No paper figure here (no ``FIGURES``): :func:`detection_overlay` returns the
image; the command writes it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["detection_overlay"]


def detection_overlay(image, det, sample) -> np.ndarray:
    """The detection drawn on its image, with a ``sample S: k/m ok`` label.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3|4)
        The sample's image.
    det : notchfit.detection.Detection
    sample : int
        Sample id for the label.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8 (BGR)
        :func:`notchfit.detection.draw_overlay` and the label.
    """
    # slow optional dependency: the overlay is drawn with cv2 (as is notchfit.detection)
    import cv2

    from ..detection import draw_overlay

    ov = draw_overlay(image, det)
    cv2.putText(ov, f"sample {sample}: {det.n_ok}/{len(det.status)} ok", (10, 25),
                cv2.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 255), 2, cv2.LINE_AA)
    return ov
