"""The image scale from the tube's known outer diameter (photos without a calibration).

A fronto-parallel view is assumed: the tube's width in pixels, measured
across straight stretches of its outer edges, is ``2R``. First a rough
width from the downsampled silhouette (slots bridged by a closing; the
thinnest long band of the silhouette is the tube), then the precise one
from full-resolution intensity profiles across the tube (50 % crossings of
both outer edges, stations on the straight edge next to every refined
corner).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["measure_diameter", "rough_radius", "rough_tube_radius"]


def rough_radius(region, close_px: int, *, min_radius_px: float = 2.0, peak_fraction: float = 0.3) -> float:
    """Tube radius in pixels of a downsampled silhouette (NaN if not found).

    The silhouette closed by a disk of ``close_px`` (the slots bridged) has a
    distance-transform ridge along the tube at the tube's radius; a holder's
    ridge lies higher. The radius is the smallest ridge value whose
    histogram count is at least ``peak_fraction`` of the largest count.
    """
    r = max(int(close_px), 1)
    pad = r + 2
    big = cv2.copyMakeBorder(region, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    # a closing by a disk from two distance transforms: dilate (distance to the set <= r), then erode
    dil = (cv2.distanceTransform(1 - big, cv2.DIST_L2, 5) <= r).astype(np.uint8)
    closed = (cv2.distanceTransform(dil, cv2.DIST_L2, 5) > r).astype(np.uint8) | big
    dt = cv2.distanceTransform(closed, cv2.DIST_L2, 5)[pad:-pad, pad:-pad]
    ridge = (dt >= cv2.dilate(dt, np.ones((3, 3), np.uint8)) - 1e-6) & (dt >= min_radius_px)
    v = dt[ridge]
    if len(v) < 10:
        return math.nan
    hi = int(math.ceil(v.max())) + 2
    h, edges = np.histogram(v, bins=np.arange(0, hi + 1, 1.0))
    h = np.convolve(h, [0.25, 0.5, 0.25], mode="same")
    peaks = [i for i in range(1, len(h) - 1) if h[i] >= h[i - 1] and h[i] >= h[i + 1] and h[i] > 0]
    if not peaks:
        return math.nan
    top = max(h[i] for i in peaks)
    i0 = min(i for i in peaks if h[i] >= peak_fraction * top)
    sel = (v >= edges[max(i0 - 1, 0)]) & (v < edges[min(i0 + 2, len(edges) - 1)])
    return float(np.median(v[sel])) + 0.5


def rough_tube_radius(region, *, max_close_px: int, min_ratio: float = 0.5) -> float:
    """Tube radius of a silhouette [px] without knowing the scale.

    :func:`rough_radius` for closing radii 2, 3, 4, 6, ... px up to
    ``max_close_px``; the largest estimate whose closing was at most
    ``1 / min_ratio`` times it. Small closings leave the slots open (the
    estimate is then a link's or the backbone's half width); closings wider
    than half a slot give the tube's radius, and stay there for a while
    (a straight band does not thicken under a closing).
    """
    best = math.nan
    r = 2.0
    while r <= max_close_px:
        est = rough_radius(region, int(round(r)))
        if np.isfinite(est) and est >= min_ratio * round(r) and not est <= best:
            best = est
        r *= 1.4
    return best


def _crossings(t, P, level, t0, sign):
    """Per row: interpolated crossing of ``level`` (rows,) nearest ``t0`` (rows,) where ``sign * (P - level)``
    goes from < 0 to >= 0; NaN where there is none."""
    q = sign * (P - level[:, None])
    with np.errstate(invalid="ignore"):
        cr = (q[:, :-1] < 0) & (q[:, 1:] >= 0)
    d = np.where(cr, np.abs(t[None, :-1] - t0[:, None]), np.inf)
    j = np.argmin(d, axis=1)
    rows = np.arange(len(P))
    q0, q1 = q[rows, j], q[rows, j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = t[j] + (0 - q0) / (q1 - q0) * (t[j + 1] - t[j])
    return np.where(np.isfinite(d[rows, j]), tc, np.nan)


def _line_levels(t, P, t0, win):
    """Per row: straight line (offset at t0, slope) fitted to the samples with t - t0 in ``win``."""
    x = t[None, :] - t0[:, None]
    m = (x >= win[0]) & (x <= win[1]) & np.isfinite(P)
    n = m.sum(1)
    Pz = np.where(m, P, 0.0)
    xz = np.where(m, x, 0.0)
    sx, sy = xz.sum(1), Pz.sum(1)
    sxx, sxy = (xz * xz).sum(1), (xz * Pz).sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        den = n * sxx - sx * sx
        b = np.where(np.abs(den) > 1e-12, (n * sxy - sx * sy) / den, 0.0)
        a0 = (sy - b * sx) / n
    return np.where(n >= 3, a0, np.nan), b


def _edges(t, P, t0, obj_win, bg_win, sign, rising=True):
    """Per row: 50 % crossing near ``t0`` between the object and background levels, each a straight line
    fitted on its side (``obj_win``, ``bg_win`` offsets from ``t0``) and taken at the crossing: shading
    across the tube makes the object level slope toward the edge."""
    a_o, b_o = _line_levels(t, P, t0, obj_win)
    a_b, b_b = _line_levels(t, P, t0, bg_win)
    tc = t0.astype(float)
    s = sign if rising else -sign
    for _ in range(3):
        mid = 0.5 * (a_o + b_o * (tc - t0) + a_b + b_b * (tc - t0))
        tc = _crossings(t, P, np.nan_to_num(mid, nan=np.inf), t0, s)
        tc = np.where(np.isfinite(tc), tc, t0)
    final = _crossings(t, P, np.nan_to_num(0.5 * (a_o + b_o * (tc - t0) + a_b + b_b * (tc - t0)), nan=np.inf), t0, s)
    return final


def measure_diameter(img, off, stations, width0_px: float, contrast: float, blur_px: float, *,
                     step: float = 0.5, window=(0.7, 1.35)):
    """Tube width across the outer edges [px] at a set of stations.

    Parameters
    ----------
    img : ndarray (h, w) float32
        Image region; ``off`` = its (u0, v0) [px].
    stations : ndarray (S, 4)
        Station point on an outer edge (u, v) [px] and the unit normal into
        the tube (nu, nv).
    width0_px : float
        Rough width; the far edge is searched in ``window`` times it.
    contrast : float
        Object minus background level (its sign is the polarity).
    blur_px : float
        Edge blur σ [px] (plateaus are taken beyond 2σ + 2 px of an edge).

    Returns
    -------
    widths : ndarray (S,) [px], NaN where an edge was not found.
    """
    b = blur_px if np.isfinite(blur_px) else 1.5
    a = 4 * b + 4
    t = np.arange(-a - 2, window[1] * width0_px + a + 2, step)
    P0, nrm = stations[:, :2] - off, stations[:, 2:]
    mapx = (P0[:, 0, None] + t[None] * nrm[:, 0, None]).astype(np.float32)
    mapy = (P0[:, 1, None] + t[None] * nrm[:, 1, None]).astype(np.float32)
    P = cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                  borderValue=float("nan")).astype(float)
    sgn = 1.0 if contrast > 0 else -1.0           # object above the background: + 1
    S = len(P)
    zero = np.zeros(S)
    tn = _edges(t, P, zero, (2 * b + 2, a), (-a, -2 * b - 2), sgn)
    srch = (t >= window[0] * width0_px) & (t <= window[1] * width0_px)
    g = -sgn * np.gradient(P, axis=1)              # object -> background: a fall of sgn * p
    gs = np.where(srch[None, :] & np.isfinite(g), g, -np.inf)
    tf0 = t[np.argmax(gs, axis=1)]
    a_o, _ = _line_levels(t, P, tf0, (-a, -2 * b - 2))
    a_b, _ = _line_levels(t, P, tf0, (2 * b + 2, a))
    good = np.isfinite(tn) & (sgn * (a_o - a_b) > 0.5 * abs(contrast)) & np.isfinite(P[:, t <= window[0] * width0_px]).all(1)
    tf = _edges(t, P, tf0, (-a, -2 * b - 2), (2 * b + 2, a), sgn, rising=False)
    return np.where(good, tf - tn, np.nan)
