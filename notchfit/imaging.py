"""Gray-image normalisation shared by calibration, detection, rendering and overlays."""

from __future__ import annotations

import numpy as np

__all__ = ["to_gray", "to_gray8"]


def to_gray(image) -> np.ndarray:
    """A 2-D float32 gray image from a gray, BGR or BGRA image (values unchanged).

    Parameters
    ----------
    image : array_like, shape (H, W), (H, W, 3) or (H, W, 4)

    Returns
    -------
    ndarray, shape (H, W), float32

    Raises
    ------
    ValueError
        For any other shape or an empty image.
    """
    import cv2  # slow optional import: keeps numpy-only users fast

    img = np.asarray(image)
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
        elif img.shape[2] == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        elif img.shape[2] == 1:
            img = img[..., 0]
        else:
            raise ValueError(f"expected a 2-D gray or colour image, got shape {np.shape(image)}")
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"expected a 2-D gray or colour image, got shape {np.shape(image)}")
    return img.astype(np.float32, copy=False)


def to_gray8(image, *, stretch: bool | None = None) -> np.ndarray:
    """An 8-bit gray image.

    Parameters
    ----------
    image : array_like
        Gray, BGR or BGRA, any dtype.
    stretch : bool, optional
        Map the image's min..max to 0..255. ``None`` (default): stretch only
        when the image is not already ``uint8``.

    Returns
    -------
    ndarray, shape (H, W), uint8
    """
    img = np.asarray(image)
    if stretch is None:
        stretch = img.dtype != np.uint8
    if not stretch and img.dtype == np.uint8:
        g = to_gray(img)
        return np.clip(np.round(g), 0, 255).astype(np.uint8) if img.ndim == 3 else img
    g = to_gray(img).astype(float)
    lo, hi = float(np.nanmin(g)), float(np.nanmax(g))
    return np.clip((g - lo) * (255.0 / max(hi - lo, 1e-12)) + 0.5, 0, 255).astype(np.uint8)
