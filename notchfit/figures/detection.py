"""The detector's overlay image (written by ``notchfit detect``, one per sample).

No paper figure here (no ``FIGURES``): :func:`detection_overlay` returns the
image; the command writes it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["detection_overlay"]


def detection_overlay(image, det, sample, *, size: int = 1000, full: bool = False) -> np.ndarray:
    """The detection drawn on a crop around the tube (``full``: the whole view beside it), labelled.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3|4)
        The sample's image (any size: 16–24 MP photographs included).
    det : notchfit.vision.detection.Detection
    sample : int
        Sample id for the label.
    size : int
        The crop's longer side (with ``full``: the height of both panels) [px]:
        markers, numbers and the label are drawn at this scale, so they are
        readable whatever the photograph's size.
    full : bool
        The whole view beside the crop (:func:`notchfit.vision.detection.overlay_with_crop`);
        default: the crop alone (:func:`notchfit.vision.detection.overlay.overlay_crop`), a
        few times smaller on disk.

    Returns
    -------
    ndarray, shape (H', W', 3), uint8 (BGR)
        The overlay and a ``sample S: k/m ok`` label.
    """
    # slow optional dependency: the overlay is drawn with cv2 (as is notchfit.vision.detection)
    import cv2

    from ..vision.detection.overlay import overlay_crop, overlay_with_crop

    ov = overlay_with_crop(image, det, height=size) if full else overlay_crop(image, det, size=size)
    cv2.putText(ov, f"sample {sample}: {det.n_ok}/{len(det.status)} ok", (10, 28),
                cv2.FONT_HERSHEY_SIMPLEX, 0.8, (0, 0, 255), 2, cv2.LINE_AA)
    return ov
