"""Image files: read one, or summarise it, with the reason when it cannot be used."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

__all__ = ["image_info", "load_image"]


def load_image(path, flags=None) -> np.ndarray:
    """Read an image, raising with the reason when it cannot be used.

    Parameters
    ----------
    path : path
    flags : int, optional
        ``cv2.imdecode`` flags (default ``cv2.IMREAD_UNCHANGED``: gray stays
        2-D, colour is BGR, 16-bit stays 16-bit).

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C)

    Raises
    ------
    FileNotFoundError
        ``image missing: <path>``.
    ValueError
        ``corrupt or unreadable image: <path>`` (OpenCV cannot decode it) or
        an empty image.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image missing: {path}")
    data = np.fromfile(path, dtype=np.uint8)
    if data.size == 0:
        raise ValueError(f"corrupt or unreadable image (empty file): {path}")
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED if flags is None else flags)
    if img is None or img.size == 0:
        raise ValueError(f"corrupt or unreadable image (OpenCV cannot decode it): {path}")
    return img


def image_info(path) -> dict:
    """Shape, dtype and intensity range of an image (a cheap check of a batch of images).

    Returns
    -------
    dict
        ``path, height, width, channels, dtype, min, max``.
    """
    img = load_image(path)
    return {"path": str(path), "height": int(img.shape[0]), "width": int(img.shape[1]),
            "channels": int(img.shape[2]) if img.ndim == 3 else 1, "dtype": str(img.dtype),
            "min": float(img.min()), "max": float(img.max())}
