"""The image scale from the tube's known outer diameter (photos without a calibration).

A fronto-parallel view is assumed: the tube's width in pixels, measured
across straight stretches of its outer edges, is ``2R``. First a rough
width from the downsampled silhouette (slots bridged by a closing; of the
bands the silhouette shows, the tube is the one that holds the geometry's
slots at the scale its width implies: a clamp's bar may be as thin), then
the precise one
from full-resolution intensity profiles across the tube (50 % crossings of
both outer edges, stations on the straight edge next to every refined
corner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ._kernels import level_crossings, line_levels, nearest_crossings
from .subpixel import outer_step

__all__ = ["SlotGaps", "band_centreline", "band_width", "measure_diameter", "radius_candidates", "ridge_peaks", "ridge_series", "ridge_values", "rough_radius", "rough_tube_radius", "slots_along", "trim_box",
           "tube_band", "tube_radius"]


def _close_disk(region, r: int, border=cv2.BORDER_REPLICATE, near=None):
    """A closing by a disk of radius ``r`` (two distance transforms), padded by ``r + 2``: (closed, pad).
    ``near``: :func:`_distance_to` of ``region`` padded by at least ``r + 2`` (``BORDER_REPLICATE``), whose
    middle is the first transform (a series of closings of one region shares it)."""
    pad = r + 2
    big = cv2.copyMakeBorder(region, pad, pad, pad, pad, border, value=0)
    # dilate (distance to the set <= r), then erode
    if near is None:
        d = cv2.distanceTransform(1 - big, cv2.DIST_L2, 5)
    else:
        D, P = near
        d = D[P - pad:D.shape[0] - P + pad, P - pad:D.shape[1] - P + pad]
    dil = (d <= r).astype(np.uint8)
    return (cv2.distanceTransform(dil, cv2.DIST_L2, 5) > r).astype(np.uint8) | big, pad


def _distance_to(region, pad: int):
    """Distance [px] to ``region`` padded by ``pad`` (``BORDER_REPLICATE``), 5x5 chamfer: (distances, pad).
    Its middle padded by less is that smaller padding's transform to the last bit: a replicated pixel beyond
    the smaller pad has one as near inside it (the same pixel, clamped toward the point)."""
    big = cv2.copyMakeBorder(region, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    return cv2.distanceTransform(1 - big, cv2.DIST_L2, 5), pad


def _ridge(dt):
    """Ridge of a distance transform: pixels no lower than their 8 neighbours (the medial axis)."""
    return dt >= cv2.dilate(dt, np.ones((3, 3), np.uint8)) - 1e-6


def ridge_peaks(region, close_px: int, *, min_radius_px: float = 2.0, peak_fraction: float = 0.3,
                near=None) -> list:
    """Band radii [px] of a downsampled silhouette: the peaks of its distance-transform ridge values.

    The silhouette closed by a disk of ``close_px`` (the slots bridged) has a
    distance-transform ridge along every band at the band's half width (the
    tube's radius, a clamp's bar's, a holder's). Peaks of the ridge-value
    histogram whose count is at least ``peak_fraction`` of the largest,
    smallest first. ``near``: see :func:`_close_disk`.
    """
    return _peaks(ridge_values(region, close_px, min_radius_px=min_radius_px, near=near), peak_fraction)


def ridge_values(region, close_px: int, *, min_radius_px: float = 2.0, near=None) -> np.ndarray:
    """The ridge values of :func:`ridge_peaks`, sorted (K,) float32 [px]: the distance transform of the
    silhouette closed by a disk of ``close_px`` on its ridge, at least ``min_radius_px``."""
    r = max(int(close_px), 1)
    closed, pad = _close_disk(region, r, near=near)
    dt = _distance_in_box(closed)[pad:-pad, pad:-pad]
    return np.sort(dt[_ridge(dt) & (dt >= min_radius_px)])


def _peaks(v, peak_fraction: float) -> list:
    """:func:`ridge_peaks` of the sorted ridge values ``v``."""
    if len(v) < 10:
        return []
    hi = int(math.ceil(v[-1])) + 2
    # the histogram of unit bins from 0 (``np.histogram(v, bins=edges)``): v >= 0 lies in bin floor(v)
    edges = np.arange(0, hi + 1, 1.0)
    h = np.bincount(np.floor(v).astype(np.intp), minlength=hi)
    h = np.convolve(h, [0.25, 0.5, 0.25], mode="same")
    peaks = [i for i in range(1, len(h) - 1) if h[i] >= h[i - 1] and h[i] >= h[i + 1] and h[i] > 0]
    if not peaks:
        return []
    top = max(h[i] for i in peaks)
    out = []
    for i0 in peaks:
        if h[i0] >= peak_fraction * top:
            # the values in [edges[i0 - 1], edges[i0 + 2]): a run of the sorted values
            lo, up = np.searchsorted(v, [edges[max(i0 - 1, 0)], edges[min(i0 + 2, len(edges) - 1)]], side="left")
            out.append(float(sorted_median(v[lo:up])) + 0.5)
    return out


def sorted_median(s):
    """``np.median`` of a sorted, non-empty float array without NaN, to the last bit: the middle value, or the
    mean of the two middle values in the array's precision (their sum rounded once, halved exactly)."""
    n = len(s)
    if n % 2:
        return s[n // 2]
    return (s[n // 2 - 1] + s[n // 2]) / s.dtype.type(2)


def _distance_in_box(mask):
    """``cv2.distanceTransform(mask, DIST_L2, 5)`` computed in the mask's :func:`trim_box` only (zero outside
    it, as the full transform is there): the same values on fewer pixels."""
    box = trim_box(mask)
    out = np.zeros(mask.shape, np.float32)
    out[box] = cv2.distanceTransform(np.ascontiguousarray(mask[box]), cv2.DIST_L2, 5)
    return out


def rough_radius(region, close_px: int, *, min_radius_px: float = 2.0, peak_fraction: float = 0.3,
                 near=None) -> float:
    """Tube radius in pixels of a downsampled silhouette (NaN if not found): the smallest of
    :func:`ridge_peaks` (a holder's ridge lies higher than the tube's)."""
    peaks = ridge_peaks(region, close_px, min_radius_px=min_radius_px, peak_fraction=peak_fraction, near=near)
    return peaks[0] if peaks else math.nan


def rough_tube_radius(region, *, max_close_px: int, min_ratio: float = 0.5, series=None) -> float:
    """Tube radius of a silhouette [px] without knowing the scale (no slot pattern used).

    :func:`rough_radius` for closing radii 2, 3, 4, 6, ... px up to
    ``max_close_px``; the largest estimate whose closing was at most
    ``1 / min_ratio`` times it. Small closings leave the slots open (the
    estimate is then a link's or the backbone's half width); closings wider
    than half a slot give the tube's radius, and stay there for a while
    (a straight band does not thicken under a closing). ``series``:
    :func:`ridge_series` of ``region`` where computed already.
    """
    best = math.nan
    for r, v in ridge_series(region, max_close_px) if series is None else series:
        peaks = _peaks(v, 0.3)
        est = peaks[0] if peaks else math.nan
        if np.isfinite(est) and est >= min_ratio * r and not est <= best:
            best = est
    return best


def trim_box(region):
    """The slices that keep ``region``'s box and one empty row or column on each side. A closing's or a
    distance transform's values inside are the same on the trimmed region (a chamfer path between two
    pixels of the box stays in it, and one to the background beyond crosses the empty margin first), on
    fewer pixels; the connected parts and their order are the same."""
    rows, cols = np.flatnonzero(region.any(1)), np.flatnonzero(region.any(0))
    if not len(rows):
        return slice(None), slice(None)
    h, w = region.shape
    return slice(max(rows[0] - 1, 0), min(rows[-1] + 2, h)), slice(max(cols[0] - 1, 0), min(cols[-1] + 2, w))


def _trim(region):
    """``region`` cut to :func:`trim_box`."""
    return region[trim_box(region)]


def ridge_series(region, max_close_px) -> list:
    """(closing radius, :func:`ridge_values`) for r = 2, 3, 4, 6, ... up to ``max_close_px``: computed once
    for every peak fraction that reads them. The closings share the distance to the region (``near``,
    :func:`_distance_to`), computed on the region :func:`_trim` leaves (the values are distances inside it)."""
    r = 2.0
    region = _trim(region)
    near = _distance_to(region, int(math.ceil(max_close_px)) + 2) if max_close_px >= 2 else None
    out = []
    while r <= max_close_px:
        out.append((int(round(r)), ridge_values(region, int(round(r)), near=near)))
        r *= 1.4
    return out


def radius_candidates(region, *, max_close_px: int, min_ratio: float = 0.5, merge: float = 0.12,
                      peak_fraction: float = 0.05, series=None) -> list:
    """Every band radius [px] the silhouette shows under closings up to ``max_close_px`` (a closing at
    most ``1 / min_ratio`` times the radius; a ridge peak ``peak_fraction`` of the highest: a short tube
    beside a long clamp bar counts), estimates within ``merge`` of each other merged. ``series``:
    :func:`ridge_series` of ``region`` where computed already."""
    series = ridge_series(region, max_close_px) if series is None else series
    ests = sorted(e for r, v in series for e in _peaks(v, peak_fraction) if e >= min_ratio * r)
    out = []
    for e in ests:
        if out and e <= out[-1][-1] * (1 + merge):
            out[-1].append(e)
        else:
            out.append([e])
    return [float(np.median(g)) for g in out]


@dataclass(frozen=True)
class SlotGaps:
    """The slot-bridged band and its slot-sized gaps found at one band radius (:func:`_slot_gaps`), in a crop
    of the region that holds its box and one empty row or column on each side (:func:`trim_box`; the
    closing, the gaps and their labels are those of the whole region there, zero outside).

    Attributes
    ----------
    radius_px : float
        The band radius they were found at [px].
    closed, lab : ndarray (h, w)
        The closed band (uint8) and the gaps' labels (int32) in the crop.
    ids : list of int
        The slot-sized gaps' labels.
    offset : (int, int)
        The crop's (x0, y0) in the region [px].
    """

    radius_px: float
    closed: np.ndarray
    lab: np.ndarray
    ids: list
    offset: tuple


def _slot_gaps(region, radius_px, *, slot_width, slot_depth, radius, close_factor, area_range,
               width_range=(0.5, 1.6), streak=0.2):
    """The slot-bridged band and its slot-sized gaps at the scale ``radius_px / radius``: (closed, labels,
    slot labels). A gap is a slot where its area is ``area_range`` times ``w d`` and its widest inscribed
    disk ``width_range`` times ``w`` (a band half the tube's width, made by a streak, shows slots twice
    too wide); thin parts (``streak`` w, a streak joining the slots) are opened away first."""
    s = radius_px / radius
    r = int(math.ceil(close_factor * slot_width * s)) + 1
    closed, pad = _close_disk(region, r, border=cv2.BORDER_CONSTANT)
    closed = closed[pad:-pad, pad:-pad]
    gaps = (closed & (1 - region)).astype(np.uint8)
    k = int(round(streak * slot_width * s))
    if k >= 1:
        gaps = cv2.morphologyEx(gaps, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1,) * 2))
    n, lab = cv2.connectedComponents(gaps, connectivity=8)
    if n <= 1:
        return closed, lab, []
    counts = np.bincount(lab.ravel(), minlength=n)         # the parts' areas [px]
    area = slot_width * slot_depth * s * s
    dtg = cv2.distanceTransform(gaps, cv2.DIST_L2, 5)
    sel = lab > 0
    widest = np.zeros(n)
    np.maximum.at(widest, lab[sel], dtg[sel])
    widest = 2 * widest[1:] + 1
    ids = [k for k in range(1, n) if area_range[0] * area <= counts[k] <= area_range[1] * area
           and width_range[0] * slot_width * s <= widest[k - 1] <= width_range[1] * slot_width * s]
    return closed, lab, ids


def slots_along(region, radius_px: float, *, slot_width: float, slot_depth: float, radius: float,
                close_factor: float, area_range, pitch=(0.0, np.inf), length: float = 0.0, gaps=None) -> int:
    """How many slot-sized gaps lie along the band of half width ``radius_px`` if that band is the tube.

    At the scale ``radius_px / radius``, the slots (``slot_width`` x
    ``slot_depth`` [m]) are bridged by a closing of ``close_factor``
    slot widths; gaps of slot size (:func:`_slot_gaps`) that reach within
    ``radius_px`` of the band's ridge (ridge values within 25 % of
    ``radius_px``) and lie a slot pitch (``pitch`` = (smallest, largest)
    distance to the nearest slot [m]) from another one are counted: a
    clamp's bar or a holder as wide as a tube holds no slot, a band of
    noise or texture no slot pattern. A band whose ridge is shorter than
    ``length`` [m] (30 % of the tube) holds none. ``gaps``: :func:`_slot_gaps`' (closed, labels, slot labels)
    of ``region`` at ``radius_px`` where computed already.
    """
    closed, lab, ids = gaps if gaps is not None else _slot_gaps(
        region, radius_px, slot_width=slot_width, slot_depth=slot_depth, radius=radius, close_factor=close_factor,
        area_range=area_range)
    if not ids:
        return 0
    s = radius_px / radius
    dt = cv2.distanceTransform(closed, cv2.DIST_L2, 5)
    ridge = _ridge(dt) & (np.abs(dt - radius_px) <= 0.25 * radius_px)
    if ridge.sum() < 0.3 * length * s:
        return 0
    near = cv2.distanceTransform((~ridge).astype(np.uint8), cv2.DIST_L2, 5) <= 1.05 * radius_px + 1
    along = sorted(set(np.unique(lab[near & (lab > 0)]).tolist()) & set(ids))
    if len(along) < 2:
        return len(along)
    yy, xx = np.nonzero(np.isin(lab, along))
    labs = lab[yy, xx]
    cen = np.stack([np.bincount(labs, xx, lab.max() + 1)[along], np.bincount(labs, yy, lab.max() + 1)[along]], 1) \
        / np.bincount(labs, minlength=lab.max() + 1)[along][:, None]
    dd = np.linalg.norm(cen[:, None] - cen[None], axis=2) + np.diag(np.full(len(along), np.inf))
    nn = dd.min(1)
    return int(np.sum((nn >= 0.5 * pitch[0] * s) & (nn <= 2.2 * pitch[1] * s)))


def plausible_radii(filled, geom, *, max_close_px: int, min_slot_px: float, max_radius_px: float,
                    series=None) -> list:
    """The band radii [px] of ``filled`` (:func:`radius_candidates`) the tube could have: its slots at
    least ``min_slot_px`` wide at that scale (narrower ones cannot be seen) and the band at most
    ``max_radius_px``. ``series``: :func:`ridge_series` of ``filled`` where computed already."""
    w_min, R = float(np.min(geom.slot_widths)), geom.outer_radius
    return [rc for rc in radius_candidates(filled, max_close_px=max_close_px, series=series)
            if w_min * rc / R >= min_slot_px and rc <= max_radius_px]


def tube_radius(region, geom, *, max_close_px: int, close_factor: float, area_range, filled=None,
                min_slot_px: float = 2.0, max_radius_px: float | None = None):
    """:func:`tube_band`'s radius [px] (NaN: none) and the slots found along it."""
    return tube_band(region, geom, max_close_px=max_close_px, close_factor=close_factor, area_range=area_range,
                     filled=filled, min_slot_px=min_slot_px, max_radius_px=max_radius_px)[:2]


def tube_band(region, geom, *, max_close_px: int, close_factor: float, area_range, filled=None,
              min_slot_px: float = 2.0, max_radius_px: float | None = None):
    """Tube radius of a silhouette [px] without knowing the scale: of the bands it shows
    (:func:`radius_candidates`), the one that holds the geometry's slots (:func:`slots_along`: most slots,
    up to the number of joints; the nearer count, then the wider band, on a tie); the thinnest band
    (:func:`rough_tube_radius`) where no band holds a slot. ``filled``: the silhouette with its holes
    filled (a streak's), for the bands' widths; the slots are counted on ``region``. Bands whose slots
    would be narrower than ``min_slot_px`` or whose radius exceeds ``max_radius_px`` (default: a quarter of
    the region's smaller side; pass the image's when ``region`` is a crop) are not tried.

    Returns
    -------
    radius [px] (NaN: none), slots found along it (at most the number of joints), :class:`SlotGaps` of the
    band (None where no band holds a slot), :func:`ridge_series` of ``filled`` (the bands' widths: read
    again for the other bands the tube could be)
    """
    filled = region if filled is None else filled
    max_radius_px = 0.25 * min(region.shape) if max_radius_px is None else max_radius_px
    box = trim_box(filled)                    # the filled silhouette holds the region: the same box
    region, filled = region[box], filled[box]
    R = geom.outer_radius
    w, d = float(np.median(geom.slot_widths)), float(np.median(geom.slot_depths))
    best = None
    series = ridge_series(filled, max_close_px)
    for rc in plausible_radii(filled, geom, max_close_px=max_close_px, min_slot_px=min_slot_px,
                              max_radius_px=max_radius_px, series=series):
        gaps = _slot_gaps(region, rc, slot_width=w, slot_depth=d, radius=R, close_factor=close_factor,
                          area_range=area_range)
        n = slots_along(region, rc, slot_width=w, slot_depth=d, radius=R, close_factor=close_factor,
                        area_range=area_range, pitch=(float(np.min(geom.pitches)), float(np.max(geom.pitches))),
                        length=geom.tip_z - geom.base_edge_z, gaps=gaps)
        key = (min(n, geom.n_joints), -abs(n - geom.n_joints), rc)
        if n > 0 and (best is None or key > best[0]):
            best = (key, rc, gaps)
    if best is None:
        return rough_tube_radius(filled, max_close_px=max_close_px, series=series), 0, None, series
    return best[1], best[0][0], SlotGaps(best[1], *best[2], (box[1].start or 0, box[0].start or 0)), series


def _crossings(t, P, level, t0, sign):
    """Per row: interpolated crossing of ``level`` (rows,) nearest ``t0`` (rows,) where ``sign * (P - level)``
    goes from < 0 to >= 0; NaN where there is none (compiled: :func:`._kernels.nearest_crossings`)."""
    f = lambda a: np.ascontiguousarray(np.broadcast_to(np.asarray(a, float), (len(P),)))
    return nearest_crossings(np.ascontiguousarray(t, float), np.ascontiguousarray(P, float), f(level), f(t0),
                             float(sign))


def _line_levels(t, P, t0, win):
    """Per row: straight line (offset at t0, slope) fitted to the samples with t - t0 in ``win`` (compiled:
    :func:`._kernels.line_levels`, the numpy formulation's sums to the last bit)."""
    return line_levels(np.ascontiguousarray(t, float), np.ascontiguousarray(P, float),
                       np.ascontiguousarray(np.broadcast_to(np.asarray(t0, float), (len(P),))), float(win[0]),
                       float(win[1]))


def _edges(t, P, t0, obj_win, bg_win, sign, rising=True):
    """Per row: 50 % crossing near ``t0`` between the object and background levels, each a straight line
    fitted on its side (``obj_win``, ``bg_win`` offsets from ``t0``) and taken at the crossing: shading
    across the tube makes the object level slope toward the edge (compiled: :func:`._kernels.level_crossings`)."""
    t0 = np.ascontiguousarray(np.broadcast_to(np.asarray(t0, float), (len(P),)))
    return level_crossings(np.ascontiguousarray(t, float), np.ascontiguousarray(P, float), t0, float(obj_win[0]),
                           float(obj_win[1]), float(bg_win[0]), float(bg_win[1]),
                           float(sign if rising else -sign))


def measure_diameter(img, off, stations, width0_px: float, contrast: float, blur_px: float, *,
                     step: float = 0.5, window=(0.7, 1.35), outer_k: float = 6.0, outer_reach: float = 0.2,
                     min_profiles: int = 8):
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
    outer_k, outer_reach, min_profiles : float, float, int
        A polished limb's mirror strip: the widths are taken to the outermost
        step of the mean profile beyond the crossings (:func:`_outer_width`)
        where it stands out of the backdrop by ``outer_k`` standard errors
        within ``outer_reach`` times ``width0_px`` (0.4 R, as
        ``DetectorOptions.outer_reach_R``) and at least ``min_profiles``
        widths were measured; ``outer_k`` 0: not looked for.

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
    w = np.where(good, tf - tn, np.nan)
    if outer_k > 0:
        w = w + _outer_width(img, P0, nrm, np.where(np.isfinite(w), tn, np.nan), np.where(np.isfinite(w), tf, np.nan),
                             reach_px=outer_reach * width0_px, k_sig=outer_k, blur0=b, step=step,
                             min_profiles=min_profiles)
    return w


def _outer_width(img, P0, nrm, tn, tf, *, reach_px, k_sig, blur0, step, corr_px: float = 4.0,
                 extend: float = 0.25, min_profiles: int = 8):
    """What the tube's outer steps add to the widths between the crossings ``tn``, ``tf`` (S,) [px along the
    profiles from ``P0`` (S, 2) along ``nrm`` (S, 2)], (S,) [px]: a polished limb mirrors the backdrop, so
    the crossings lie on the mirror strips' inner ramps.

    Per edge (a run of stations with the same normal, :func:`.subpixel.edge_stations`) and side, the mean
    of profiles ``corr_px`` apart along the stations' span, extended by ``extend`` of it each way (the
    stations lie on 0.3-0.7 of a straight stretch), outward of the median crossing, each less its own
    backdrop level (the outer ``0.35`` of ``reach_px``, as :func:`.subpixel.outer_steps`): the noise
    averages down along the edge. Its outermost step (:func:`.subpixel.outer_step`) is the tube's edge.
    0 where none is found or fewer than ``min_profiles`` profiles are read.
    """
    out = np.zeros(len(P0))
    s = np.arange(0.0, reach_px + step, step)
    bg = s >= (1.0 - 0.35) * reach_px
    group = np.cumsum(np.r_[True, np.any(nrm[1:] != nrm[:-1], axis=1)])
    for gi in np.unique(group):
        sel = group == gi
        n_, a_ = nrm[sel][0], np.array([-nrm[sel][0][1], nrm[sel][0][0]])
        u = P0[sel] @ a_
        span = float(u.max() - u.min())
        uu = np.arange(u.min() - extend * span, u.max() + extend * span + 1e-9, corr_px)
        if len(uu) < min_profiles:
            continue
        base = float(np.median(P0[sel] @ n_)) * n_
        for t0, d in ((tn, -1.0), (tf, 1.0)):
            tm = t0[sel][np.isfinite(t0[sel])]
            if not len(tm):
                continue
            tt = float(np.median(tm)) + d * s
            pts = base + uu[:, None, None] * a_ + tt[None, :, None] * n_
            Q = cv2.remap(img, pts[..., 0].astype(np.float32), pts[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan")).astype(float)
            Q = Q[np.isfinite(Q).all(1)]
            if len(Q) < min_profiles:
                continue
            Q = Q - np.median(Q[:, bg], axis=1)[:, None]
            found = outer_step(s, Q.mean(0), Q.std(0) / math.sqrt(len(Q)), bg, k_sig=k_sig, blur0=blur0)
            if found is not None:
                out[sel] += found[0]
    return out


def band_centreline(region, radius_px: float, *, slot_width: float, slot_depth: float, radius: float,
                    close_factor: float, area_range, tol: float = 0.06, reach: float = 2.5,
                    gaps: SlotGaps | None = None) -> np.ndarray:
    """Points on the tube's centreline where it has its full width (P, 2) [px of ``region``].

    The ridge of the slot-bridged band (as :func:`slots_along`) within
    ``reach`` radii of a slot (the tube, not another band of its width)
    where its distance transform is within ``tol`` of its median there
    (the full width: away from the slots, the tip and the holder). ``gaps``: the band's :class:`SlotGaps`
    at ``radius_px`` where found already (:func:`tube_band`); the points are the same.
    """
    if gaps is not None and gaps.radius_px == radius_px:
        closed, lab, ids, (x0, y0) = gaps.closed, gaps.lab, gaps.ids, gaps.offset
    else:
        (closed, lab, ids), x0, y0 = _slot_gaps(region, radius_px, slot_width=slot_width, slot_depth=slot_depth,
                                                radius=radius, close_factor=close_factor, area_range=area_range), 0, 0
    slots = np.isin(lab, ids)
    if not slots.any():
        return np.zeros((0, 2))
    dt = cv2.distanceTransform(closed, cv2.DIST_L2, 5)
    near = cv2.distanceTransform((~slots).astype(np.uint8), cv2.DIST_L2, 5) <= reach * radius_px
    ridge = _ridge(dt) & near & (np.abs(dt - radius_px) <= 0.3 * radius_px)
    if not ridge.any():
        return np.zeros((0, 2))
    mode = float(np.median(dt[ridge]))                   # the rough radius may be 20 % off: the tube's own
    yy, xx = np.nonzero(ridge & (np.abs(dt - mode) <= tol * mode))
    return np.stack([xx + x0, yy + y0], 1).astype(float)


def band_width(img, centres, normals, width0_px: float, contrast: float, *, step: float = 0.5,
               reach: float = 0.8, blur_px: float = math.nan, skew_offset: float = 0.08, max_skew_deg: float = 10.0):
    """The tube's width [px] along profiles across it (S,), NaN where not measured; the direction error
    of each profile (its edges' shift along two neighbours ``skew_offset`` widths away, alike for both
    edges and at most ``max_skew_deg``; else left uncorrected) corrected.

    See :func:`band_width_along` for the parameters.
    """
    along = np.stack([-normals[:, 1], normals[:, 0]], 1)
    d = skew_offset * width0_px
    # the three runs read one float copy of the region around all their profiles
    H, W = img.shape
    ends = np.concatenate([centres + s * reach * width0_px * normals for s in (-1.0, 1.0)])
    m = d + 3 * step + 3
    lo = np.maximum(np.floor(ends.min(0) - m), 0).astype(int)
    hi = np.minimum(np.ceil(ends.max(0) + m), [W, H]).astype(int)
    region = (np.asarray(img[lo[1]:hi[1], lo[0]:hi[0]], np.float32), lo) if np.all(hi > lo) else None
    runs = [band_width_along(img, centres + k * d * along, normals, width0_px, contrast, step=step, reach=reach,
                             blur_px=blur_px, region=region) for k in (0.0, -1.0, 1.0)]
    (w, tn, tf), (_, tn_a, tf_a), (_, tn_b, tf_b) = runs
    # the (parallel) edges run at an angle e to the profile's perpendicular: both shift by 2 d tan(e)
    # between the neighbours; the width is w cos(e)
    tan_e = 0.5 * ((tf_b - tf_a) + (tn_b - tn_a)) / (2 * d)
    # the two edges must shift alike (a neighbour that meets a slot or the tube's end does not); a skew
    # beyond ``max_skew_deg`` is not the profile's
    agree = np.abs((tf_b - tf_a) - (tn_b - tn_a)) <= 0.1 * (2 * d) + 1.0
    ok = np.isfinite(tan_e) & agree & (np.abs(tan_e) <= math.tan(math.radians(max_skew_deg)))
    return w / np.sqrt(1.0 + np.where(ok, tan_e, 0.0) ** 2)


def band_width_along(img, centres, normals, width0_px: float, contrast: float, *, step: float = 0.5,
                     reach: float = 0.8, blur_px: float = math.nan, region=None):
    """The tube's width [px] along one profile per centre (S,), NaN where not measured.

    Each profile runs through a centreline point along the normal, ``reach``
    times the rough width ``width0_px`` each way (the rough width may be 25 %
    off). The outer edges are the outermost crossings of the level halfway
    between the background (the profile's ends) and the object (a streak
    inside the tube does not count: it is not outermost), then refined to
    50 % crossings between straight-line levels on each side (shading).

    Parameters
    ----------
    img : ndarray (H, W)
        The full-resolution image.
    centres, normals : ndarray (S, 2)
        Profile centres [px] and unit directions across the tube.
    contrast : float
        Object minus background level (its sign is the polarity).
    blur_px : float
        Edge blur σ [px]; measured from the profiles when NaN.
    region : (ndarray (h, w) float32, (x0, y0)) or None
        A float32 copy of ``img`` from (x0, y0) [px]; the profiles read it where it holds their box.

    Returns
    -------
    widths, near edge, far edge : ndarray (S,) [px] (positions along the profile from its centre)
    """
    t = np.arange(-reach * width0_px, reach * width0_px + step, step)
    pts = centres[:, None, :] + t[None, :, None] * normals[:, None, :]
    H, W = img.shape
    xs, ys = pts[..., 0], pts[..., 1]
    lo = np.maximum(np.floor([xs.min(), ys.min()]) - 2, 0).astype(int)
    hi = np.minimum(np.ceil([xs.max(), ys.max()]) + 3, [W, H]).astype(int)
    if np.any(hi <= lo):
        nan = np.full(len(centres), np.nan)
        return nan, nan, nan
    if region is not None and np.all(lo >= region[1]) and np.all(hi - region[1] <= region[0].shape[::-1]):
        X0, Y0 = region[1]
        roi = region[0][lo[1] - Y0:hi[1] - Y0, lo[0] - X0:hi[0] - X0]
    else:
        roi = np.ascontiguousarray(img[lo[1]:hi[1], lo[0]:hi[0]], dtype=np.float32)
    P = cv2.remap(roi, (pts[..., 0] - lo[0]).astype(np.float32), (pts[..., 1] - lo[1]).astype(np.float32),
                  cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan")).astype(float)
    sg = 1.0 if contrast > 0 else -1.0
    Q = np.where(np.isfinite(P), sg * P, -1e9)                      # outside the image: not object
    obj = np.percentile(Q[:, np.abs(t) <= 0.45 * width0_px], 80, axis=1)
    edges = []
    for side in (-1.0, 1.0):
        bg = np.median(Q[:, (np.abs(t) >= 0.65 * width0_px) & (side * t > 0)], axis=1)
        inside = Q >= 0.5 * (bg + obj)[:, None]
        order = np.arange(len(t)) if side < 0 else np.arange(len(t))[::-1]
        first = np.argmax(inside[:, order], axis=1)          # the outermost object sample from this side
        edges.append((t[order][first], bg))
    ok = (obj - np.maximum(edges[0][1], edges[1][1])) > 0.5 * abs(contrast)
    b = blur_px if np.isfinite(blur_px) else 1.5
    for it in range(1 if np.isfinite(blur_px) else 2):
        a = 4 * b + 4
        tn = _edges(t, P, edges[0][0], (2 * b + 2, a), (-a, -2 * b - 2), sg)
        tf = _edges(t, P, edges[1][0], (-a, -2 * b - 2), (2 * b + 2, a), sg, rising=False)
        if it == 0 and not np.isfinite(blur_px):
            # the blur from the near edge's 25 % -> 75 % rise (1.349 σ), for the level windows
            a_o, _ = _line_levels(t, P, np.nan_to_num(tn), (2 * b + 2, a))
            a_b, _ = _line_levels(t, P, np.nan_to_num(tn), (-a, -2 * b - 2))
            rise = [_crossings(t, P, np.nan_to_num(a_b + q * (a_o - a_b), nan=np.inf), np.nan_to_num(tn), sg)
                    for q in (0.25, 0.75)]
            d = (rise[1] - rise[0])[ok]
            d = d[np.isfinite(d) & (d > 0)]
            b = float(np.clip(np.median(d) / 1.349, 0.5, 0.1 * width0_px)) if len(d) else b
    w = tf - tn
    ok &= np.isfinite(w) & (w > 0.5 * width0_px) & (w < 1.5 * width0_px)
    return np.where(ok, w, np.nan), tn, tf

