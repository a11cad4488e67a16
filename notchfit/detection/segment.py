"""Stage 1: segment the object (tube + holder) on a downsampled copy.

Otsu split, polarity from the image border (dark on light or light on dark),
a quadratic background surface fitted to the background class (uneven
light, non-flat background), a 50 % threshold between the background
surface and the object level, the largest region with its holes filled
except slot-sized ones (a nearly closed slot mouth segments as a hole;
shading and a specular streak inside the tube or the holder make larger
holes).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .lines import otsu, poly2

__all__ = ["Segmentation", "downsample", "fill_holes", "fill_thin_lines", "largest_region", "segment"]


@dataclass(frozen=True)
class Segmentation:
    """The object mask of a downsampled image.

    Attributes
    ----------
    mask : ndarray (h, w) uint8
        1 on the object (every region), 0 on the background.
    contrast : float
        Object level minus background level (negative: dark object) [DN].
    noise : float
        Background noise of the downsampled copy [DN].
    message : str
        Why no object was found (empty otherwise).
    """

    mask: np.ndarray | None
    contrast: float
    noise: float
    message: str = ""


def downsample(gray, factor: int) -> np.ndarray:
    """Block average by an integer ``factor`` (float32; the trailing rows/columns that do not fill a block are dropped)."""
    f = int(factor)
    H, W = gray.shape
    hs, ws = H // f, W // f
    g = gray[:hs * f, :ws * f]
    if f == 1:
        return np.asarray(g, np.float32)
    return cv2.resize(np.asarray(g, np.float32), (ws, hs), interpolation=cv2.INTER_AREA)


def segment(small, *, min_snr: float = 4.0, noise_scale: float = 1.0, max_fit_points: int = 20000) -> Segmentation:
    """Object mask of a downsampled image.

    Parameters
    ----------
    small : ndarray (h, w) float
    min_snr : float
        Smallest |contrast| in units of the full-resolution background noise.
    noise_scale : float
        Full-resolution noise over the downsampled copy's noise (the
        downsampling factor: noise averages down about as 1/factor).
    max_fit_points : int
        Background samples used for the surface fit.

    Returns
    -------
    Segmentation
    """
    hs, ws = small.shape
    sub = small[::3, ::3]
    above = small > otsu(sub.ravel())
    border = np.concatenate([above[0], above[-1], above[:, 0], above[:, -1]])
    obj0 = ~above if border.mean() > 0.5 else above
    bgm = cv2.erode((~obj0).astype(np.uint8), np.ones((5, 5), np.uint8))[::3, ::3].astype(bool)
    yy, xx = np.nonzero(bgm)
    if len(yy) > max_fit_points:
        sel = np.linspace(0, len(yy) - 1, max_fit_points).astype(int)
        yy, xx = yy[sel], xx[sel]
    if len(yy) < 50:
        return Segmentation(None, 0.0, 0.0, "no manipulator found: no background visible")
    A = poly2(xx * 3.0 / ws - 0.5, yy * 3.0 / hs - 0.5)
    vals = sub[yy, xx].astype(float)
    coef = np.linalg.solve(A.T @ A + 1e-9 * np.eye(6), A.T @ vals)
    res = vals - A @ coef
    keep = np.abs(res) <= 3 * 1.4826 * np.median(np.abs(res)) + 1e-9
    Ak = A[keep]
    coef = np.linalg.solve(Ak.T @ Ak + 1e-9 * np.eye(6), Ak.T @ vals[keep])
    res = vals - A @ coef
    noise = 1.4826 * float(np.median(np.abs(res - np.median(res)))) + 1e-6
    X = (np.arange(ws, dtype=np.float32) / ws - 0.5)[None, :]
    Y = (np.arange(hs, dtype=np.float32) / hs - 0.5)[:, None]
    c_ = coef.astype(np.float32)
    objm = cv2.erode(obj0.astype(np.uint8), np.ones((3, 3), np.uint8))[::3, ::3].astype(bool)
    if objm.sum() < 10:
        return Segmentation(None, 0.0, noise, "no manipulator found: no object region")
    bg_sub = (c_[0] + c_[1] * X + c_[3] * X * X)[:, ::3] + (c_[2] * Y + c_[5] * Y * Y)[::3] + \
        c_[4] * (Y[::3] * X[:, ::3])
    contrast = float(np.median((sub - bg_sub)[objm]))
    if not abs(contrast) >= min_snr * noise * noise_scale:
        return Segmentation(None, contrast, noise,
                            f"no manipulator found: contrast {abs(contrast):.1f} is below {min_snr:g} x the "
                            f"background noise {noise * noise_scale:.1f}")
    thr = (c_[0] + 0.5 * contrast + c_[1] * X + c_[3] * X * X) + (c_[2] * Y + c_[5] * Y * Y) + c_[4] * (Y * X)
    mask = ((small > thr) if contrast > 0 else (small < thr)).astype(np.uint8)
    return Segmentation(mask, contrast, noise)


def largest_region(mask) -> tuple[np.ndarray, tuple]:
    """The largest 8-connected region of a mask (uint8, full size), and its bounding box (x, y, w, h)."""
    ext, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not ext:
        return np.zeros_like(mask), (0, 0, 0, 0)
    x0, y0, bw, bh = cv2.boundingRect(max(ext, key=cv2.contourArea))
    _, lab, st, _ = cv2.connectedComponentsWithStats(np.ascontiguousarray(mask[y0:y0 + bh, x0:x0 + bw]),
                                                     connectivity=8)
    big = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
    out = np.zeros_like(mask)
    out[y0:y0 + bh, x0:x0 + bw] = lab == big
    return out, (int(x0), int(y0), int(bw), int(bh))


def fill_holes(region, *, keep_area=(0.0, 0.0)) -> np.ndarray:
    """Fill the holes of a region (background parts enclosed by it).

    Holes whose area [px²] lies in ``keep_area`` stay open: nearly closed
    slots look like that.
    """
    cnts, hier = cv2.findContours(region, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    if hier is None:
        return region
    holes = [c for c, h in zip(cnts, hier[0]) if h[3] >= 0
             and not keep_area[0] <= cv2.contourArea(c) <= keep_area[1]]
    if not holes:
        return region
    out = region.copy()
    cv2.drawContours(out, holes, -1, 1, thickness=-1)
    return out


def fill_thin_lines(mask, length_px: float, n_dirs: int = 8) -> np.ndarray:
    """The mask with background lines thinner than ``length_px`` filled, in any direction (uint8).

    A union of closings by line segments of ``length_px`` at ``n_dirs``
    orientations. A specular streak along a dark tube, cut by deep slots into
    pieces that join the slots, disconnects the tube's halves; it is
    narrower than a slot, so a segment shorter than the slot width fills it
    and no slot.
    """
    L = int(max(3, round(length_px)))
    L += 1 - L % 2
    pad = L
    big = cv2.copyMakeBorder(mask, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    out = big.copy()
    c = L // 2
    for k in range(n_dirs):
        a = np.pi * k / n_dirs
        ker = np.zeros((L, L), np.uint8)
        d = np.array([np.cos(a), np.sin(a)]) * (L // 2)
        cv2.line(ker, (int(round(c - d[0])), int(round(c - d[1]))), (int(round(c + d[0])), int(round(c + d[1]))), 1)
        out |= cv2.morphologyEx(big, cv2.MORPH_CLOSE, ker)
    return out[pad:-pad, pad:-pad]
