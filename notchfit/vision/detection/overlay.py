"""Overlays a person can read at any resolution (Fig. 12 style)."""

from __future__ import annotations

import cv2
import numpy as np

from ...imaging import to_gray8
from .result import Detection

__all__ = ["draw_overlay", "overlay_crop", "overlay_with_crop"]

COLOURS = {"ok": (0, 200, 0), "ambiguous": (0, 200, 255), "occluded": (0, 0, 255)}


def _marks(img, det: Detection, unit_px: float, offset=(0.0, 0.0), zoom: float = 1.0):
    """Outline and numbered corners drawn in place; sizes in multiples of ``unit_px``."""
    th = max(1, int(round(unit_px)))
    off = np.asarray(offset, float)
    if len(det.contour_px):
        c = np.round((det.contour_px - off) * zoom).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(img, [c], True, (255, 160, 0), th, cv2.LINE_AA)
    font = 0.35 * unit_px
    for i, (uv, st) in enumerate(zip(det.points_px, det.status)):
        if not np.isfinite(uv).all():
            continue
        c = tuple(int(round(x)) for x in (uv - off) * zoom)
        cv2.circle(img, c, int(round(4 * unit_px)), COLOURS[st], th, cv2.LINE_AA)
        cv2.putText(img, str(i + 1), (c[0] + int(5 * unit_px), c[1] - int(5 * unit_px)),
                    cv2.FONT_HERSHEY_SIMPLEX, font, COLOURS[st], th, cv2.LINE_AA)


def draw_overlay(image, det: Detection, *, scale: float = 1.0, marker_scale: float | None = None) -> np.ndarray:
    """The image with the bridged outline and numbered corners coloured by status (BGR uint8).

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
    det : Detection
    scale : float
        Resize factor of the returned image.
    marker_scale : float, optional
        Size of markers and text relative to a 1000-px-high image's; default:
        proportional to the image's size, so that they stay readable once
        the image is viewed whole (1 below 1000 px).

    Returns
    -------
    ndarray (round(H scale), round(W scale), 3) uint8
    """
    g8 = to_gray8(image, stretch=True)
    img = cv2.cvtColor(g8, cv2.COLOR_GRAY2BGR)
    unit_px = marker_scale if marker_scale is not None else max(1.0, max(g8.shape) / 1000.0)
    _marks(img, det, unit_px)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    return img


def _crop_box(det: Detection, shape, margin: float, max_aspect: float = 2.0):
    """``(u0, v0, u1, v1)`` [px]: the box of the found corners (else the outline) enlarged by ``margin``
    of its size and to at most ``max_aspect`` between its sides (a partial detection along a line
    gives a view, not a sliver), inside the image; None when there is nothing to frame."""
    H, W = shape
    pts = det.points_px[np.isfinite(det.points_px).all(1)]
    if len(pts) < 2:
        pts = det.contour_px
    if len(pts) < 2:
        return None
    lo, hi = pts.min(0), pts.max(0)
    ext = np.maximum(hi - lo, 20.0)
    ext = np.maximum(ext, ext.max() / max_aspect)
    mid = 0.5 * (lo + hi)
    lo, hi = np.maximum(mid - (0.5 + margin) * ext, 0), np.minimum(mid + (0.5 + margin) * ext, [W - 1, H - 1])
    return int(lo[0]), int(lo[1]), int(hi[0]) + 1, int(hi[1]) + 1


def overlay_crop(image, det: Detection, *, size: int = 1000, margin: float = 0.15) -> np.ndarray:
    """A crop around the tube, its longer side ``size`` px, with the outline and numbered corners (BGR uint8).

    The crop is the box of the detected corners (or the outline) enlarged by
    ``margin`` of its size; markers and numbers are drawn at the crop's zoom
    (1 unit per 1000 px), so they are readable at 100 % whatever the tube's
    direction. The whole view, its longer side ``size``, is returned when
    nothing was found.
    """
    g8 = to_gray8(image, stretch=True)
    box = _crop_box(det, g8.shape, margin)
    if box is None:
        return draw_overlay(image, det, scale=size / max(g8.shape), marker_scale=1.0)
    u0, v0, u1, v1 = box
    z = size / max(v1 - v0, u1 - u0, 1)
    crop = cv2.resize(g8[v0:v1, u0:u1], (max(1, round((u1 - u0) * z)), max(1, round((v1 - v0) * z))),
                      interpolation=cv2.INTER_AREA if z < 1 else cv2.INTER_LINEAR)
    crop = cv2.cvtColor(crop, cv2.COLOR_GRAY2BGR)
    _marks(crop, det, max(1.0, size / 1000.0), offset=(u0 - 0.5 + 0.5 / z, v0 - 0.5 + 0.5 / z), zoom=z)
    return crop


def overlay_with_crop(image, det: Detection, *, height: int = 1000, margin: float = 0.15) -> np.ndarray:
    """The whole view beside a crop around the tube, both ``height`` px high (BGR uint8).

    The whole view marks the crop's box in magenta; markers and numbers are
    drawn at the crop's zoom, so they are readable in both panels.
    """
    g8 = to_gray8(image, stretch=True)
    H, W = g8.shape
    s_full = height / H
    full = cv2.cvtColor(cv2.resize(g8, (max(1, round(W * s_full)), height), interpolation=cv2.INTER_AREA),
                        cv2.COLOR_GRAY2BGR)
    _marks(full, det, max(1.0, height / 1000.0), zoom=s_full)
    box = _crop_box(det, g8.shape, margin)
    if box is None:
        return full
    u0, v0, u1, v1 = box
    z = height / max(v1 - v0, 1)
    crop = cv2.resize(g8[v0:v1, u0:u1], (max(1, round((u1 - u0) * z)), height),
                      interpolation=cv2.INTER_AREA if z < 1 else cv2.INTER_LINEAR)
    crop = cv2.cvtColor(crop, cv2.COLOR_GRAY2BGR)
    _marks(crop, det, max(1.0, height / 1000.0), offset=(u0 - 0.5 + 0.5 / z, v0 - 0.5 + 0.5 / z), zoom=z)
    cv2.rectangle(full, (int(u0 * s_full), int(v0 * s_full)), (int(u1 * s_full), int(v1 * s_full)), (255, 0, 255), 1)
    sep = np.full((height, 8, 3), 255, np.uint8)
    return np.concatenate([full, sep, crop], axis=1)
