"""Stage 2: the silhouette's outline with the slot mouths bridged, and the slots.

A morphological closing (a disk a little wider than half a slot) bridges
every slot mouth, including slots whose outer gap is almost closed (these
segment as holes); each connected part of ``closed - region`` of slot size
is one slot. Outlines are traversed anticlockwise in the manipulator frame
(orientation sign ``sgn``) and their turn angle marks corners.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import maximum_filter1d
from scipy.spatial import cKDTree

from ...polygon import polygon_area
from .closed import wedge_mouth
from .segment import close_disk, components_with_stats, fill_holes, window_max_at

__all__ = ["Outline", "bridge_slots", "hole_ends", "wedge_pixels", "crop_region",
           "corner_window", "oriented_contour", "raw_mouth_corners", "slot_mouths", "turn_angles", "turn_peaks"]


@dataclass(frozen=True)
class Outline:
    """The bridged silhouette of one region (coordinates in the region's box, low-res px).

    Attributes
    ----------
    offset : (x0, y0)
        Position of the box in the downsampled image.
    region : ndarray (h, w) uint8
        The silhouette (holes of slot size kept).
    closed : ndarray (h, w) uint8
        The silhouette with the slot mouths bridged.
    gap_labels : ndarray (h, w) int
        Connected parts of ``closed - region`` (0: none).
    gap_stats, gap_centroids : ndarrays from ``cv2.connectedComponentsWithStats``
    slot_ids : list of int
        Gap labels of slot size.
    contour : ndarray (N, 2)
        Outer outline of ``closed``, anticlockwise in the manipulator frame.
    on_border : ndarray (N,) bool
        Outline points on the downsampled image's border.
    raw_contour : ndarray (M, 2)
        Outer outline of ``region`` (unbridged), same orientation.
    r_close : int
        Radius of the bridging disk [low-res px].
    sliver_ids : tuple of int
        Gap labels smaller than a slot but not smaller than ``sliver_area``:
        a slot seen from the side shows the backdrop only through a sliver of
        its mouth (its faces hide the rest). Weak candidates: a sliver gets a
        number only where the slot-sized gaps' numbers all stand
        (:func:`~.numbering.number_slots`).
    """

    offset: tuple
    region: np.ndarray
    closed: np.ndarray
    gap_labels: np.ndarray
    gap_stats: np.ndarray
    gap_centroids: np.ndarray
    slot_ids: list
    contour: np.ndarray
    on_border: np.ndarray
    raw_contour: np.ndarray
    r_close: int
    sliver_ids: tuple = ()


def oriented_contour(mask, sgn: float) -> np.ndarray:
    """Longest outer contour of a mask (K, 2) float, anticlockwise in the manipulator frame."""
    cnts, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not cnts:
        return np.zeros((0, 2))
    cnt = max(cnts, key=len).reshape(-1, 2).astype(float)
    if polygon_area(cnt[:, 0], cnt[:, 1], signed=True) * sgn < 0:
        cnt = cnt[::-1].copy()
    return cnt


def crop_region(region, box, image_shape, pad: int, keep_holes=(0.0, 0.0)):
    """The region's box plus ``pad`` (clipped to the image), holes filled except slot-sized ones.

    Returns the crop (uint8) and its offset (x0, y0) in the downsampled image.
    """
    hs, ws = image_shape
    x0, y0, bw, bh = box
    X0, Y0 = max(x0 - pad, 0), max(y0 - pad, 0)
    X1, Y1 = min(x0 + bw + pad, ws), min(y0 + bh + pad, hs)
    return fill_holes(np.ascontiguousarray(region[Y0:Y1, X0:X1]), keep_area=keep_holes), (X0, Y0)


def bridge_slots(roi, offset, image_shape, *, r_close: int, slot_area: float, slot_area_range, sgn: float,
                 holder=None, holder_strict=None, sliver_area: float = np.inf):
    """Bridge the slot mouths of a region and find the slot-sized gaps.

    Parameters
    ----------
    roi : ndarray (h, w) uint8
        The silhouette around its box (:func:`crop_region`).
    offset : (x0, y0)
        The crop's position in the downsampled image.
    image_shape : (hs, ws)
        The downsampled image's size.
    r_close : int
        Radius of the closing disk [low-res px].
    slot_area : float
        ``w d`` in low-res px².
    slot_area_range : (float, float)
        Accepted gap area relative to ``slot_area``.
    sgn : float
        Orientation sign (see :func:`~notchfit.vision.detection.view.view_orientation`).
    holder : ndarray (h, w) uint8, optional
        The holder: left out of the closing, so that the corners where the
        tube meets it are not filled (their fillets would reach the first slot).
    holder_strict : ndarray (h, w) uint8, optional
        The holder's strict opening: gaps touching it are not slots.
    sliver_area : float
        Smallest gap kept as a sliver of a slot's mouth (:attr:`Outline.sliver_ids`) [low-res px²];
        none by default.

    Returns
    -------
    Outline or None (no outline)
    """
    hs, ws = image_shape
    X0, Y0 = offset
    src = roi if holder is None else (roi & (1 - cv2.dilate(holder, np.ones((3, 3), np.uint8))))
    closed = close_disk(src, r_close) | roi
    gaps = (closed & (1 - roi)).astype(np.uint8)
    ng, glab, gst, gcen = components_with_stats(gaps)
    lo, hi = slot_area_range
    least = min(sliver_area, lo * slot_area)
    slot_ids = [k for k in range(1, ng) if least <= gst[k, cv2.CC_STAT_AREA] <= hi * slot_area]
    if holder_strict is not None and holder_strict.any() and slot_ids:
        # a concavity of the holder's outline (a chuck's stepped jaws) is no slot: most of the object
        # around it is holder, where a slot has the tube's faces
        ids = np.array(slot_ids)
        is_slot = np.zeros(ng, np.uint8)
        is_slot[ids] = 255
        grown = cv2.dilate(is_slot.take(glab), np.ones((3, 3), np.uint8))
        ring = cv2.findNonZero(cv2.bitwise_and(grown, roi))       # the object pixels around the slots (x, y)
        ring = np.zeros((0, 2), np.intp) if ring is None else ring.reshape(-1, 2).astype(np.intp)
        ry, rx = ring[:, 1], ring[:, 0]
        lab_g = window_max_at(glab, ry, rx)                         # the gap next to each (the largest label)
        held = cv2.dilate(holder_strict, np.ones((5, 5), np.uint8))[ry, rx] > 0
        n_ring = np.bincount(lab_g, minlength=ng)[ids]
        n_held = np.bincount(lab_g[held], minlength=ng)[ids]
        slot_ids = [int(k) for k, a, b in zip(ids, n_held, n_ring) if not a > 0.5 * b]
    cnt = oriented_contour(closed, sgn)
    if not len(cnt):
        return None
    ax_, ay_ = cnt[:, 0] + X0, cnt[:, 1] + Y0
    on_border = (ax_ <= 0) | (ay_ <= 0) | (ax_ >= ws - 1) | (ay_ >= hs - 1)
    slivers = tuple(k for k in slot_ids if gst[k, cv2.CC_STAT_AREA] < lo * slot_area)
    return Outline((X0, Y0), roi, closed, glab, gst, gcen, [k for k in slot_ids if k not in slivers], cnt, on_border,
                   oriented_contour(roi, sgn), int(r_close), slivers)


def turn_angles(cnt, k: int, sgn: float) -> np.ndarray:
    """Signed turn of a closed outline over ``k`` points each way (N,) [rad]; > 0 convex."""
    a_ = cnt - np.roll(cnt, k, axis=0)
    b_ = np.roll(cnt, -k, axis=0) - cnt
    return np.arctan2(a_[:, 0] * b_[:, 1] - a_[:, 1] * b_[:, 0], np.sum(a_ * b_, axis=1)) * sgn


def turn_peaks(turn, k: int, thr: float, sign: float, exclude=None) -> list:
    """Indices of local extrema of ``sign * turn`` above ``thr``, at least ``k`` apart (cyclic)."""
    v = sign * turn
    if exclude is not None:
        v = np.where(exclude, 0.0, v)
    N = len(v)
    mx = maximum_filter1d(v, size=2 * k + 1, mode="wrap")
    out = []
    for i in np.nonzero((v >= mx) & (v > thr))[0]:
        if not out or i - out[-1] > k:
            out.append(int(i))
    if len(out) > 1 and out[0] + N - out[-1] <= k:
        out.pop()
    return out


def _hole_pixels(ol: Outline, s: int) -> np.ndarray:
    """The pixel centres (x, y) of gap ``s`` (K, 2) float [low-res px, the outline's box]."""
    bx, by, bw_, bh_ = ol.gap_stats[s, :4]
    py_, px_ = np.nonzero(ol.gap_labels[by:by + bh_, bx:bx + bw_] == s)
    return np.stack([px_ + bx, py_ + by], 1).astype(float)


def wedge_pixels(ol: Outline, mouths: dict, *, max_wall: float) -> dict:
    """The pixel centres of every slot closed at its mouth whose point is narrower than a pixel (a hole
    with one end of its axis beyond ``max_wall`` from the outline, :func:`slot_mouths`): label -> (K, 2)
    [low-res px]."""
    return {s: _hole_pixels(ol, s) for s, (_, _, bridged) in mouths.items()
            if not bridged and len(hole_ends(ol, s, max_wall=max_wall)) < 2}


def hole_ends(ol: Outline, s: int, gray=None, dark: bool = True, max_wall: float = np.inf) -> list:
    """The two ends of a hole's long axis (across the tube) on the outline: [(level, -wall, index)], where
    ``wall`` is the distance from the hole to that outline point and ``level`` the most background-like
    value of ``gray`` on the way (-inf without ``gray``); ends beyond ``max_wall`` are left out."""
    cnt = ol.contour
    pts = _hole_pixels(ol, s)
    c, axis = pts.mean(0), np.linalg.svd(pts - pts.mean(0), full_matrices=False)[2][0]
    rel = cnt - c
    along, perp = rel @ axis, np.abs(rel[:, 0] * axis[1] - rel[:, 1] * axis[0])
    tree = cKDTree(pts)
    out = []
    for sign in (1.0, -1.0):
        cand = np.nonzero((perp < 2.0) & (sign * along > 0))[0]
        if not len(cand):
            continue
        i = int(cand[np.argmin(sign * along[cand])])
        wall, j = tree.query(cnt[i])
        if wall > max_wall:
            continue
        level = -np.inf
        if gray is not None:
            t = np.linspace(0.0, 1.0, max(int(wall * 2), 2))
            q = pts[j] + t[:, None] * (cnt[i] - pts[j])
            vals = gray[np.clip(np.rint(q[:, 1]).astype(int), 0, gray.shape[0] - 1),
                        np.clip(np.rint(q[:, 0]).astype(int), 0, gray.shape[1] - 1)]
            level = float(np.max(-vals if not dark else vals))
        out.append((level, -float(wall), i))
    return out


def slot_mouths(ol: Outline, *, max_wall: float = np.inf, gray=None, dark: bool = True, reach=None) -> dict:
    """Where each slot meets the bridged outline: label -> (first index, last index, bridged?).

    A slot whose mouth is (almost) closed is a hole; its mouth is one end of
    its long axis (across the tube): the end whose path to the outline is
    brightest in ``gray`` (the downsampled image in the outline's box; a
    dark object when ``dark``), else the nearer one; ends further than
    ``max_wall`` [low-res px] from the outline are not mouths. Where one end
    is further (with ``reach``, the slot's depth [low-res px]), a hole that
    tapers is a wedge pointed at its mouth, whose point is narrower than a
    pixel (:func:`~.closed.wedge_mouth`: a slot bent shut closes about its
    backbone): its mouth is where its axis meets the outline past the
    narrow end, up to ``reach`` away.
    """
    cnt = ol.contour
    N = len(cnt)
    cnt_i = cnt.astype(np.intp)
    lab_on = ol.gap_labels[cnt_i[:, 1], cnt_i[:, 0]]
    mouths = {}
    for s in list(ol.slot_ids) + list(ol.sliver_ids):
        idx = np.nonzero(lab_on == s)[0]
        if s in ol.sliver_ids and not len(idx):
            continue                                       # a sliver is a mouth on the outline, not a hole
        if len(idx):
            if idx[-1] - idx[0] > len(idx) + 2:            # the run wraps around index 0
                g = int(np.argmax(np.diff(idx)))
                idx = np.concatenate([idx[g + 1:], idx[:g + 1] + N])
            mouths[s] = (int(idx[0]) % N, int(idx[-1]) % N, True)
        else:
            ends = hole_ends(ol, s, gray, dark, max_wall)
            i0 = max(ends)[2] if ends else None
            if len(ends) == 1 and reach is not None:
                # one end of the axis beyond ``max_wall``: the point of a wedge narrower than a pixel
                w = wedge_mouth(cnt, _hole_pixels(ol, s), reach=reach)
                i0 = i0 if w is None else w
            if i0 is not None:
                mouths[s] = (i0, i0, False)
    return mouths


def corner_window(r_close: int, R_lo: float) -> int:
    """Outline points each way over which a base or tip corner's turn is measured.

    Twice the bridging radius (the bridged fillets must not count as
    corners), but at most ``0.6 R`` so that the tip face (``2R``) holds two
    windows.
    """
    return max(3, min(2 * r_close, int(0.6 * R_lo)))




def raw_mouth_corners(ol: Outline, mouths: dict, *, k: int, sgn: float, thr_deg: float = 50.0) -> dict:
    """The outer corners of each bridged slot on the unbridged outline: label -> (first, last) index.

    Along the unbridged outline, the points next to a slot's gap run from
    one outer edge down the slot's faces and back; its outer corners are the
    first and last convex corners of that run (the bridged outline's mouth
    can start early where the closing also fills beside a short stub of tube):
    of the convex corners along that run, the ones nearest the bridged mouth's
    two ends (a streak cut by the slot adds corners deeper inside).
    """
    mcnt = ol.raw_contour
    M = len(mcnt)
    if M < 3:
        return {}
    mi = np.clip(np.rint(mcnt).astype(np.intp), 0, [ol.gap_labels.shape[1] - 1, ol.gap_labels.shape[0] - 1])
    on = window_max_at(ol.gap_labels, mi[:, 1], mi[:, 0])        # the gap next to each outline point
    turn = turn_angles(mcnt, k, sgn)
    all_peaks = np.array(turn_peaks(turn, k, np.radians(thr_deg), +1.0), dtype=np.intp)
    is_peak = np.zeros(M, bool)
    is_peak[all_peaks] = True
    out = {}
    for s, (_, _, bridged) in mouths.items():
        if not bridged:
            continue
        idx = np.nonzero(on == s)[0]
        if len(idx) < 3:
            continue
        gaps = np.diff(np.concatenate([idx, [idx[0] + M]]))   # cyclic gaps; the run starts after the largest
        g = int(np.argmax(gaps))
        run = np.concatenate([idx[g + 1:], idx[:g + 1]]) % M
        peaks = run[is_peak[run]].tolist()
        if len(peaks) < 2:
            continue
        cnt = ol.contour
        ends = (cnt[(mouths[s][0] - 1) % len(cnt)], cnt[(mouths[s][1] + 1) % len(cnt)])
        pk = np.array(peaks)
        ia = int(pk[np.argmin(np.sum((mcnt[pk] - ends[0]) ** 2, axis=1))])
        ib = int(pk[np.argmin(np.sum((mcnt[pk] - ends[1]) ** 2, axis=1))])
        if ia != ib and np.flatnonzero(run == ia)[0] < np.flatnonzero(run == ib)[0]:   # ia first along the run
            out[s] = (ia, ib)
    return out
