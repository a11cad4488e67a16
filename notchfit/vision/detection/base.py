"""Stage 3: separate the tube from its holder and find the base end.

The tube is at most ``2R`` wide; a holder (mount, chuck, collet, clamp, a
hand) is wider. An opening of the silhouette (slots not bridged, so the
bridging fillets at the tube's junction with the holder do not thicken it)
with a disk of radius ``holder_width_factor * R`` keeps the holder and
removes the tube. Outline points on the holder or on the image
border are *base* points; the tube is the rest. The outline is traversed
anticlockwise in the manipulator frame, so after the base run comes the
tube's right side (``+x``), then the tip, then its left side: the first and
last tube points are where the tube leaves the base on the right and on the
left. The free end is the tip. The concave corners where the tube meets a
holder's face, 2R apart, are the base corners when that face is at the base
edge (checked against the first slot later).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .options import DetectorOptions
from .outline import Outline, corner_window, turn_angles, turn_peaks

__all__ = ["BaseEnd", "base_runs", "find_base", "holder_mask", "holder_masks", "image_side", "raw_base_corners"]

SIDES = ("top", "bottom", "left", "right")


@dataclass(frozen=True)
class BaseEnd:
    """Where the tube leaves its base on the bridged outline.

    Attributes
    ----------
    i_right, i_left : int
        Outline indices of the first tube point on the right side and the
        last on the left side (the tube-holder corners when ``corners``).
    kind : str
        ``holder``, ``border`` or ``corners`` (no holder or border run: two
        concave corners 2R apart, the default mount seen whole).
    corners : bool
        ``i_right``, ``i_left`` are concave corners 2R apart (candidate base corners).
    side : str
        Image side the base points to (``top``/``bottom``/``left``/``right``).
    i_right_wide, i_left_wide : int
        The same ends before they were trimmed to the holder's strict
        opening (which may not reach a slim holder's face).
    """

    i_right: int
    i_left: int
    kind: str
    corners: bool
    side: str
    i_right_wide: int = -1
    i_left_wide: int = -1


def holder_mask(region, radius_px: float, *, regrow: bool = True) -> np.ndarray:
    """The parts of a silhouette wider than ``2 radius_px`` (uint8).

    An opening by a disk of ``radius_px``; with ``regrow``, grown back by
    ``(√2 - 1) radius_px`` inside the silhouette (the opening rounds a
    holder's convex corners off by that much; the growth also climbs the
    tube a little, see :func:`find_base`). The image border is replicated,
    so a holder cut by the border stays wide.
    """
    strict, grown = holder_masks(region, radius_px)
    return grown if regrow else strict


def holder_masks(region, radius_px: float):
    """:func:`holder_mask` without and with the regrowth, from one pair of distance transforms."""
    r = float(max(radius_px, 1.0))
    g = (math.sqrt(2) - 1) * r + 2
    pad = int(math.ceil(r)) + 1
    big = cv2.copyMakeBorder(region, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    # erosion by the disk = the points at least r inside; a dilation by r, then by g, is one by r + g
    core = (cv2.distanceTransform(big, cv2.DIST_L2, cv2.DIST_MASK_5) >= r).astype(np.uint8)
    if not core.any():
        z = np.zeros_like(region)
        return z, z.copy()
    # the distance to the core, needed up to r + g only: in the box around the core that holds every point
    # that near (the 5x5 chamfer distance is at least 0.91 x the larger coordinate difference)
    d = _distance_near(core, r + g)[pad:-pad, pad:-pad]
    inside = region > 0
    return ((d <= r) & inside).astype(np.uint8), ((d <= r + g) & inside).astype(np.uint8)


def _distance_near(mask, reach: float) -> np.ndarray:
    """``cv2.distanceTransform(1 - mask, DIST_L2, DIST_MASK_5)`` wherever it is at most ``reach`` [px], and
    above ``reach`` (inf) everywhere else (h, w) float32, computed only in the box around the mask's pixels
    that holds every point that near: the 5x5 chamfer distance is a path length over the mask's moves, at
    least 1 / 1.1 times the larger coordinate difference, so a shortest path never leaves the box and the
    values up to ``reach`` are the full image's to the last bit."""
    x, y, w, h = cv2.boundingRect(mask)
    m = int(math.ceil(1.1 * reach)) + 3
    X0, Y0 = max(x - m, 0), max(y - m, 0)
    X1, Y1 = min(x + w + m, mask.shape[1]), min(y + h + m, mask.shape[0])
    d = np.full(mask.shape, np.inf, np.float32)
    d[Y0:Y1, X0:X1] = cv2.distanceTransform(np.ascontiguousarray(1 - mask[Y0:Y1, X0:X1]), cv2.DIST_L2,
                                            cv2.DIST_MASK_5)
    return d


def _runs(flag) -> list:
    """Maximal cyclic runs of True in a boolean array: list of (start, length)."""
    N = len(flag)
    if flag.all():
        return [(0, N)]
    if not flag.any():
        return []
    s = int(np.argmin(flag))                  # start scanning at a False point
    f = np.roll(flag, -s)
    d = np.diff(np.concatenate([[0], f.astype(np.int8), [0]]))
    starts, ends = np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]
    return [((int(a) + s) % N, int(b - a)) for a, b in zip(starts, ends)]


def base_runs(ol: Outline, holder, min_tube_run: int, min_base_run: int):
    """Runs of base points (holder or border) on the bridged outline: (start, length, has_holder) each.

    Tube runs shorter than ``min_tube_run`` between base points are the
    holder's rounded corners (base); base runs shorter than ``min_base_run``
    are thick spots of the tube itself (the junction of a slim holder).
    """
    cnt_i = ol.contour.astype(np.intp)
    on_h = holder[cnt_i[:, 1], cnt_i[:, 0]].astype(bool)
    base = on_h | ol.on_border
    # short tube runs between base points are the holder's rounded corners
    for s, L in _runs(~base):
        if L < min_tube_run and not base.all():
            base[(s + np.arange(L)) % len(base)] = True
    return [(s, L, bool(on_h[(s + np.arange(L)) % len(base)].any())) for s, L in _runs(base)
            if L >= min_base_run or not on_h[(s + np.arange(L)) % len(base)].any()]


def image_side(vec) -> str:
    """The image side a vector (du, dv) points to."""
    du, dv = float(vec[0]), float(vec[1])
    if abs(dv) >= abs(du):
        return "bottom" if dv > 0 else "top"
    return "right" if du > 0 else "left"


def _slotted_arc(runs, mouth_idx, holder, cnt):
    """The tube arc holding the slots when both its ends are on one holder: (first, last) index, or None.

    Between consecutive base runs lie arcs of tube-like outline; parts of a
    holder as thin as the tube (a clamp's bar) make such arcs too, but hold
    no slot. The arc with most slot mouths is the tube when it leaves and
    re-enters the same connected holder.
    """
    N = len(cnt)
    if not len(mouth_idx) or len(runs) < 2:
        return None
    _, lab = cv2.connectedComponents(holder, connectivity=8)
    ci = cnt.astype(np.intp)
    order = sorted(runs, key=lambda r: r[0])
    best = None
    for k, (s, L, _) in enumerate(order):
        a = (s + L) % N
        s2 = order[(k + 1) % len(order)][0]
        n = int(np.sum((np.asarray(mouth_idx) - a) % N < (s2 - a) % N))
        if best is None or n > best[0]:
            best = (n, k, a, (s2 - 1) % N)
    n, k, a, e = best
    if n == 0:
        return None
    la = lab[ci[(a - 1) % N, 1], ci[(a - 1) % N, 0]]
    le = lab[ci[(e + 1) % N, 1], ci[(e + 1) % N, 0]]
    return (a, e) if la > 0 and la == le else None


def _choose_run(runs, cnt, base: str | None, mouth_idx=()):
    """The base run: the stated side's, else the only one on a holder, else the only one."""
    if base is not None:
        want = {"top": (0, -1), "bottom": (0, 1), "left": (-1, 0), "right": (1, 0)}[base]
        score = [float(np.dot(cnt[(s + np.arange(L)) % len(cnt)].mean(0), want)) for s, L, _ in runs]
        return runs[int(np.argmax(score))], ""
    held = [r for r in runs if r[2]]
    if len(held) == 1:
        return held[0], ""
    if len(runs) == 1:
        return runs[0], ""
    return None, ("the tube meets the holder or the image border at both ends: state the base side "
                  "(base = \"top\" | \"bottom\" | \"left\" | \"right\" in experiment.toml)")


def _near_corner_pair(cnt, concave, i_r, i_l, window, R_lo, pair_tol, dist):
    """Concave corners within ``window`` outline points of the run ends whose spacing is 2R."""
    N = len(cnt)
    cyc = lambda a, b: min((a - b) % N, (b - a) % N)
    near_r = [i for i in concave if cyc(i, i_r) <= window]
    near_l = [i for i in concave if cyc(i, i_l) <= window]
    best = None
    for a in near_r:
        for b in near_l:
            if a == b:
                continue
            e = abs(dist(a, b) / (2 * R_lo) - 1)
            if best is None or e < best[0]:
                best = (e, a, b)
    return (best[1], best[2]) if best is not None and best[0] <= pair_tol else None


def _trim_run(ol: Outline, strict, s: int, L: int, tol: float = 2.0):
    """Shrink a base run's ends to the outline points within ``tol`` of the strict opening or the border."""
    N = len(ol.contour)
    if strict is None or not strict.any():
        return s, L
    d = _distance_near(strict, tol)
    ci = ol.contour.astype(np.intp)
    base = (d[ci[:, 1], ci[:, 0]] <= tol) | ol.on_border
    idx = (s + np.arange(L)) % N
    inside = np.nonzero(base[idx])[0]
    if not len(inside):
        return s, L
    a, b = int(inside[0]), int(inside[-1])
    return (s + a) % N, b - a + 1


def find_base(ol: Outline, holder, *, R_lo: float, dist, sgn: float, mouth_idx=(), base: str | None = None,
              min_tube_run_R: float = DetectorOptions.min_tube_run_R,
              min_base_run_R: float = DetectorOptions.min_base_run_R,
              corner_turn_deg: float = DetectorOptions.corner_turn_deg, pair_tol: float = DetectorOptions.pair_tol):
    """Find where the tube leaves its base.

    The tolerances are the detector options of the same names (:class:`.DetectorOptions`).

    Parameters
    ----------
    ol : Outline
    holder : (ndarray, ndarray) uint8
        :func:`holder_mask` of the outline's region, regrown and strict.
    R_lo : float
        Tube radius [low-res px].
    dist : callable (i, j) -> float
        Distance between outline points i and j in low-res px of the plane
        (the calibrated scale: a tilted view is corrected).
    sgn : float
        Orientation sign.
    base : str, optional
        The stated image side of the base.
    mouth_idx : sequence of int
        Outline indices of the slot mouths (to tell the tube from holder
        parts as thin as it).

    Returns
    -------
    BaseEnd or None, and a message (why not).
    """
    if base is not None and base not in SIDES:
        raise ValueError(f"base must be one of {SIDES}, got {base!r}")
    cnt = ol.contour
    N = len(cnt)
    holder, strict = holder
    runs = base_runs(ol, holder, int(min_tube_run_R * R_lo), int(min_base_run_R * R_lo))
    k = corner_window(ol.r_close, R_lo)
    turn = turn_angles(cnt, k, sgn)
    thr = math.radians(corner_turn_deg)
    if runs and not (len(runs) == 1 and runs[0][1] >= N):
        run, msg = _choose_run(runs, cnt, base)
        arc = _slotted_arc(runs, mouth_idx, holder, cnt) if run is None else None
        if run is None and arc is None:
            return None, msg
        if run is not None:
            s, L, has_h = run
            wide = ((s + L) % N, (s - 1) % N)
            s, L = _trim_run(ol, strict, s, L)
            i_r, i_l = (s + L) % N, (s - 1) % N
        else:
            (i_r, i_l), has_h = arc, True
            wide = (i_r, i_l)
        concave = turn_peaks(turn, k, thr, -1.0)
        pair = _near_corner_pair(cnt, concave, i_r, i_l, int(2 * R_lo) + k, R_lo, pair_tol, dist)
        if pair is not None:
            i_r, i_l = pair
        kind = "holder" if has_h else "border"
    else:
        near_border = np.zeros(N, bool)
        concave = turn_peaks(turn, k, thr, -1.0, exclude=near_border)
        pair = None
        best = None
        for a in range(len(concave)):
            for b in range(a + 1, len(concave)):
                e = abs(dist(concave[a], concave[b]) / (2 * R_lo) - 1)
                if best is None or e < best[0]:
                    best = (e, concave[a], concave[b])
        if best is None or best[0] > pair_tol:
            return None, "base corners not found (the base is hidden or outside the image)"
        pair = (best[1], best[2])
        i_r, i_l = pair           # which is right is decided from the slots (orient_corner_pair)
        kind = "corners"
        wide = (i_r, i_l)
    tube = (np.arange(N) - i_r) % N <= (i_l - i_r) % N
    mid_base = 0.5 * (cnt[i_r] + cnt[i_l])
    side = image_side(mid_base - cnt[tube].mean(0)) if tube.any() else ""
    if base is not None and side and side != base and kind != "corners":
        return None, f"the base found in the image is at the {side}, but base = {base!r} was stated"
    return BaseEnd(int(i_r), int(i_l), kind, pair is not None, side, int(wide[0]), int(wide[1])), ""


def raw_base_corners(mcnt, P_right, P_left, *, search: float, k: int, sgn: float, dist, R_lo: float, at_border=None,
                     pair_tol: float = DetectorOptions.pair_tol):
    """The concave ~90° corners of the unbridged outline nearest two points, if they are 2R apart.

    Parameters
    ----------
    mcnt : ndarray (M, 2)
        Unbridged outline (anticlockwise in the manipulator frame).
    P_right, P_left : ndarray (2,)
        Where the tube leaves the base on the bridged outline.
    search : float
        Search radius around each point [low-res px].
    k : int
        Turn window [outline points].
    dist : callable (xy_a, xy_b) -> plane distance [low-res px]
    R_lo : float
        Tube radius [low-res px].
    at_border : callable (xy) -> bool, optional
        Whether a point is next to the image border: a corner missing there
        is outside the image, and the other one stands alone (it is
        confirmed later by a slot corner of link 0).
    pair_tol : float
        Relative tolerance of the two corners' distance to ``2 R`` (option ``pair_tol``).

    Returns
    -------
    (int, int) or None : indices into ``mcnt`` (right, left); one may be None (outside the image).
    """
    turn = turn_angles(mcnt, k, sgn)
    peaks = np.array(turn_peaks(turn, k, math.radians(60), -1.0), dtype=np.intp)
    out = []
    for P in (P_right, P_left):
        d2 = np.sum((mcnt[peaks] - P) ** 2, axis=1) if len(peaks) else np.zeros(0)
        out.append(int(peaks[np.argmin(d2)]) if len(d2) and d2.min() <= search ** 2 else None)
    if out[0] is not None and out[1] is not None and abs(dist(mcnt[out[0]], mcnt[out[1]]) / (2 * R_lo) - 1) <= pair_tol:
        return out[0], out[1]
    if at_border is not None:
        # one end at the image border (its corner outside): the other end's corner stands alone
        edge = [at_border(P_right), at_border(P_left)]
        if edge[0] != edge[1]:
            kept = (None, out[1]) if edge[0] else (out[0], None)
            if kept != (None, None):
                return kept
    return None
