"""Notch-corner detector: image -> the numbered notch points in plane mm (docs/geometry.md).

The detector does **not** assume the kinematics (a detector that does looks
perfect on images made by the same model and degrades on real geometry). It
uses only the silhouette of docs/geometry.md ("What a
camera sees") and the geometry's dimensions (outer radius ``R``, slot width
``w`` and depth ``d``, slot sides, where along a side the joints are):

1. **Segment** a copy downsampled to about ``lowres_mm`` per pixel: Otsu
   split, polarity from the image border, a quadratic background surface
   fitted to the background class (uneven light, non-flat background), a
   50 % threshold between background and object levels, the largest region.
   Too little contrast or an implausible area: ``no_manipulator``.
2. **Parse the outline.** A morphological closing (disk of radius ``1.25 w``)
   bridges every slot mouth, including slots whose outer gap is almost
   closed (these segment as holes); each connected part of ``closed - mask``
   of slot size is one slot. On the closed outline, traversed anticlockwise
   *in the manipulator frame* (image orientation x sign of the pixel->plane
   Jacobian x the mirror flag), the two concave ~90° corners ``2R`` apart
   are the base corners (points 2 and 1: the tube lies between them on the
   arc that holds the slots), the two convex ~90° corners ``2R`` apart with
   no slot between them are the tip corners (29, 30). Slots between base-right
   and tip-right are the right-side slots (joints with ``slot_sides = +1``,
   increasing z); between tip-left and base-left the left-side ones. A side
   cut off by the image border is numbered from the base; a side with a
   missing slot is aligned by position along the side; nothing is guessed.
3. **Refine every corner** from straight edges: intensity profiles across
   each of the two edges that meet at the corner (bilinear samples, one
   ``cv2.remap`` for all corners), the 50 % crossing between the edge's
   object and background levels, the crossings undistorted
   (``cv2.undistortPoints``), a robust total-least-squares line per edge,
   the two lines intersected; repeated with profiles re-centred on the
   lines and margins set from the measured edge blur. Profiles whose
   background side is not reached (a slot face next to a nearly closed
   mouth) are dropped, so a slot face is extrapolated from its open part.
   The corner's covariance follows from the two fits' residuals.
4. **Map to the plane** through the plane homography, and check the scale:
   base and tip corners lie on rigid links ``2R`` apart. A wrong camera file
   gives ``ambiguous`` points and a message, not wrong millimetres.

Statuses: ``ok``; ``occluded`` (not visible, cut off, not found: NaN);
``ambiguous`` (found, but its fit or its identity is doubtful: NaN plane
coordinates, the pixel position kept for the overlay). No point is ever
interpolated from a model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import pandas as pd
from scipy.ndimage import maximum_filter1d
from scipy.spatial import cKDTree

from .camera import CameraModel
from .geometry import Geometry, notch_layout
from .imaging import to_gray
from .polygon import polygon_area
from .units import MM

__all__ = ["STATUSES", "Detection", "detect_notches", "detections_table", "draw_overlay"]

STATUSES = ("ok", "ambiguous", "occluded")


@dataclass(frozen=True)
class Detection:
    """Result of :func:`detect_notches` for one image.

    Attributes
    ----------
    points : ndarray (m, 2)
        Notch points in the plane frame [m]; NaN unless the status is ``ok``.
    points_px : ndarray (m, 2)
        The same in the raw image [px] (u = column, v = row); NaN when not
        found (kept for ``ambiguous`` points).
    sigma : ndarray (m,)
        Standard uncertainty of each coordinate of an ok point [m]
        (``sqrt(trace(cov) / 2)``), NaN otherwise.
    status : tuple of str (m,)
        ``ok``, ``ambiguous`` or ``occluded`` per point.
    image_status : str
        ``ok`` (every point ok), ``partial``, or ``no_manipulator``.
    message : str
        Why points are missing (empty when all are ok).
    contour_px : ndarray (K, 2)
        The silhouette outline with the slot mouths bridged [px] (overlays).
    blur_px : float
        Edge blur (Gaussian σ) measured from the profiles [px].
    """

    points: np.ndarray
    points_px: np.ndarray
    sigma: np.ndarray
    status: tuple
    image_status: str
    message: str
    contour_px: np.ndarray
    blur_px: float = math.nan

    @property
    def n_ok(self) -> int:
        return sum(s == "ok" for s in self.status)


def _empty(m, image_status, message, contour=None, status="occluded"):
    nan = np.full((m, 2), np.nan)
    return Detection(nan, nan.copy(), np.full(m, np.nan), (status,) * m, image_status, message,
                     np.zeros((0, 2)) if contour is None else contour)


# ----------------------------------------------------------------------------- small helpers
def _otsu(values, bins=256):
    lo, hi = float(values.min()), float(values.max())
    if not hi > lo:
        return lo
    h, edges = np.histogram(values, bins=bins, range=(lo, hi))
    c = 0.5 * (edges[1:] + edges[:-1])
    w0 = np.cumsum(h).astype(float)
    w1 = w0[-1] - w0
    m0 = np.cumsum(h * c)
    mu0 = m0 / np.maximum(w0, 1)
    mu1 = (m0[-1] - m0) / np.maximum(w1, 1)
    return float(c[int(np.argmax(w0 * w1 * (mu0 - mu1) ** 2))])


def _poly2(x, y):
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)


def _unit(v):
    v = np.asarray(v, float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _pca_line(pts):
    pts = np.asarray(pts, float)
    if len(pts) < 2:
        return None, None
    c = pts.mean(0)
    d = pts - c
    sxx, sxy, syy = (d[:, 0] ** 2).sum(), (d[:, 0] * d[:, 1]).sum(), (d[:, 1] ** 2).sum()
    a = 0.5 * math.atan2(2 * sxy, sxx - syy)
    return c, np.array([math.cos(a), math.sin(a)])


def _intersect(c1, d1, c2, d2):
    A = np.array([[d1[0], -d2[0]], [d1[1], -d2[1]]])
    if abs(np.linalg.det(A)) < 1e-9:
        return None
    s = np.linalg.solve(A, c2 - c1)
    return c1 + s[0] * d1


def _group_median(values, groups, n_groups):
    """Median of ``values`` per group (NaN ignored; NaN for empty groups)."""
    fin = np.isfinite(values)
    v, g = values[fin], groups[fin]
    out = np.full(n_groups, np.nan)
    if not len(v):
        return out
    lo, hi = float(v.min()), float(v.max())
    key = g + (v - lo) * (0.999 / (hi - lo) if hi > lo else 0.0)     # one sort orders groups, then values
    vs = v[np.argsort(key, kind="stable")]
    cnt = np.bincount(g, minlength=n_groups)
    start = np.cumsum(cnt) - cnt
    has = cnt > 0
    out[has] = 0.5 * (vs[start[has] + (cnt[has] - 1) // 2] + vs[start[has] + cnt[has] // 2])
    return out


def _group_lines(pts, groups, n_groups, keep):
    """TLS line per group over the kept points: centroid (G,2), direction (G,2), counts (G,)."""
    wgt = keep.astype(float)
    n = np.bincount(groups, wgt, n_groups)
    ns = np.maximum(n, 1)
    cx = np.bincount(groups, wgt * pts[:, 0], n_groups) / ns
    cy = np.bincount(groups, wgt * pts[:, 1], n_groups) / ns
    dx, dy = pts[:, 0] - cx[groups], pts[:, 1] - cy[groups]
    sxx = np.bincount(groups, wgt * dx * dx, n_groups)
    sxy = np.bincount(groups, wgt * dx * dy, n_groups)
    syy = np.bincount(groups, wgt * dy * dy, n_groups)
    a = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    return np.stack([cx, cy], 1), np.stack([np.cos(a), np.sin(a)], 1), n


def _robust_group_lines(pts, groups, n_groups, *, k_mad=3.0, floor=0.15, n_iter=3):
    """Robust TLS lines: MAD rejection of residuals, ``n_iter`` rounds.

    Returns centroid (G,2), direction (G,2), kept count (G,), residual
    variance s² (G,) [px²], spread along the line S_tt (G,) [px²], keep mask.
    """
    keep = np.ones(len(pts), bool)
    for it in range(n_iter + 1):
        c, d, n = _group_lines(pts, groups, n_groups, keep)
        r = (pts[:, 0] - c[groups, 0]) * (-d[groups, 1]) + (pts[:, 1] - c[groups, 1]) * d[groups, 0]
        if it == n_iter:
            break
        mad = 1.4826 * _group_median(np.where(keep, np.abs(r), np.nan), groups, n_groups)
        lim = np.maximum(k_mad * np.nan_to_num(mad, nan=np.inf), floor)
        new = np.abs(r) <= lim[groups]
        if np.array_equal(new, keep):
            break
        keep = new
    wgt = keep.astype(float)
    s2 = np.bincount(groups, wgt * r * r, n_groups) / np.maximum(n - 2, 1)
    t = (pts[:, 0] - c[groups, 0]) * d[groups, 0] + (pts[:, 1] - c[groups, 1]) * d[groups, 1]
    stt = np.bincount(groups, wgt * t * t, n_groups)
    return c, d, n, s2, stt, keep


# ----------------------------------------------------------------------------- detector
def detect_notches(image, camera: CameraModel, geom: Geometry, *, mirror: bool = False,
                   lowres_mm: float = 0.06, min_snr: float = 4.0, area_range=(0.2, 3.0),
                   corner_turn_deg: float = 50.0, pair_tol: float = 0.3, scale_tol: float = 0.05,
                   max_shift_px: float = 10.0, max_sigma_px: float = 0.3, min_edge_points: int = 5,
                   profile_step_px: float = 0.5, stage1_half_px: float = 7.0,
                   stage1_face_px: float = 12.0, iterations: int = 1,
                   sigma_inflation: float = 1.45) -> Detection:
    """Find the numbered notch corners (docs/geometry.md) in one image.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
        Raw camera image (any numeric dtype).
    camera : CameraModel
        Calibrated camera with the plane pose; must match the image size.
    geom : Geometry
        Dimensions and slot layout (the kinematics is not used).
    mirror : bool
        The experiment's ``mirror`` flag (a reflected view, docs/geometry.md).
    lowres_mm : float
        Pixel size of the downsampled copy used to segment and parse [mm].
    min_snr : float
        Smallest object contrast, in units of the background noise.
    area_range : (float, float)
        Accepted silhouette area relative to the geometry's tube + mount.
    corner_turn_deg : float
        Turn of the bridged outline that makes a base or tip corner [deg].
    pair_tol : float
        Relative tolerance of the ``2R`` spacing used to pair base and tip corners.
    scale_tol : float
        Relative tolerance of the measured base and tip widths (``2R``) in mm;
        beyond it the camera file is taken to be wrong.
    max_shift_px : float
        A corner that moves further than this during refinement is ambiguous [px].
    max_sigma_px : float
        A corner whose standard uncertainty exceeds this is ambiguous [px].
    min_edge_points : int
        Fewest valid edge crossings per edge line.
    profile_step_px : float
        Sample spacing along a profile [px].
    stage1_half_px, stage1_face_px : float
        Half length of the first pass's profiles across outer edges and across
        slot faces (whose first position is the least certain) [px].
    iterations : int
        Refinement passes after the first.
    sigma_inflation : float
        Factor on the line-fit uncertainty: crossings 1 px apart share pixels
        (bilinear sampling) and blur, so the residual-based σ is too small;
        1.45 makes rms(|error| / (√2 σ)) = 1.0 over 90 rendered 1920x1200
        images (``benchmarks/bench_detection.py``).

    Returns
    -------
    Detection

    Raises
    ------
    ValueError
        The image size differs from the camera file's, or the camera has no plane pose.
    """
    lay = notch_layout(geom)
    m = lay.n_points
    gray = to_gray(image)
    camera.check_image(gray)
    if not camera.has_plane:
        raise ValueError("the camera model has no plane pose: calibrate with --plane-image")
    H, W = gray.shape
    c_img = np.array([(W - 1) / 2, (H - 1) / 2])
    px_per_m = camera.plane_scale(camera.pixel_to_plane(c_img))
    det_j = np.linalg.det(camera.ideal_to_plane_jacobian(camera.undistort_pixels(c_img)))
    sgn = float(np.sign(det_j)) * (-1.0 if mirror else 1.0)
    R, w, d = geom.outer_radius, geom.slot_width, geom.slot_depth

    # ---- 1. segmentation at low resolution --------------------------------------------------
    f = max(1, int(round(lowres_mm * MM * px_per_m)))
    hs, ws = H // f, W // f
    if hs < 16 or ws < 16:
        raise ValueError(f"image too small: {W}x{H} px")
    small = cv2.resize(gray[:hs * f, :ws * f], (ws, hs), interpolation=cv2.INTER_AREA) if f > 1 else gray
    sub = small[::3, ::3]
    above = small > _otsu(sub.ravel())
    border = np.concatenate([above[0], above[-1], above[:, 0], above[:, -1]])
    obj0 = ~above if border.mean() > 0.5 else above
    bgm = cv2.erode((~obj0).astype(np.uint8), np.ones((5, 5), np.uint8))[::3, ::3].astype(bool)
    yy, xx = np.nonzero(bgm)
    if len(yy) > 20000:                                     # plenty for a 6-term surface
        sel = np.linspace(0, len(yy) - 1, 20000).astype(int)
        yy, xx = yy[sel], xx[sel]
    if len(yy) < 50:
        return _empty(m, "no_manipulator", "no manipulator found: no background visible")
    A = _poly2(xx * 3.0 / ws - 0.5, yy * 3.0 / hs - 0.5)
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
        return _empty(m, "no_manipulator", "no manipulator found: no object region")
    bg_sub = (c_[0] + c_[1] * X + c_[3] * X * X)[:, ::3] + (c_[2] * Y + c_[5] * Y * Y)[::3] + \
        c_[4] * (Y[::3] * X[:, ::3])
    contrast = float(np.median((sub - bg_sub)[objm]))
    # noise of the low-resolution copy is about 1/f of the full-resolution noise
    if not abs(contrast) >= min_snr * noise * f:
        return _empty(m, "no_manipulator", f"no manipulator found: contrast {abs(contrast):.1f} is below "
                                           f"{min_snr:g} x the background noise {noise * f:.1f}")
    thr_img = (c_[0] + 0.5 * contrast + c_[1] * X + c_[3] * X * X) + (c_[2] * Y + c_[5] * Y * Y) + c_[4] * (Y * X)
    mask = ((small > thr_img) if contrast > 0 else (small < thr_img)).astype(np.uint8)
    ext, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not ext:
        return _empty(m, "no_manipulator", "no manipulator found")
    big_c = max(ext, key=cv2.contourArea)
    x0, y0, bw, bh = cv2.boundingRect(big_c)
    low_m = f / px_per_m                                             # low-res pixel [m]
    exp_area = (2 * R * (geom.tip_z - geom.base_edge_z) - geom.n_joints * w * d
                + 2 * geom.mount_half_width * (geom.base_edge_z - geom.mount_bottom_z)) / low_m ** 2
    ratio = cv2.contourArea(big_c) / exp_area
    if not area_range[0] <= ratio <= area_range[1]:
        return _empty(m, "no_manipulator", f"no manipulator found: the largest region is {ratio:.2f} x the "
                                           "silhouette area of the geometry (wrong geometry or camera file?)")

    # ---- 2. outline parsing -----------------------------------------------------------------
    r_close = int(math.ceil(1.25 * w / low_m)) + 1
    pad = r_close + 2
    X0, Y0 = max(x0 - pad, 0), max(y0 - pad, 0)
    X1, Y1 = min(x0 + bw + pad, ws), min(y0 + bh + pad, hs)
    _, lab_roi, st_roi, _ = cv2.connectedComponentsWithStats(mask[Y0:Y1, X0:X1], connectivity=8)
    big = 1 + int(np.argmax(st_roi[1:, cv2.CC_STAT_AREA]))
    roi = (lab_roi == big).astype(np.uint8)
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r_close + 1, 2 * r_close + 1))
    pz = r_close + 2                         # zero padding: the closing never reaches the image border
    closed = cv2.morphologyEx(cv2.copyMakeBorder(roi, pz, pz, pz, pz, cv2.BORDER_CONSTANT, value=0),
                              cv2.MORPH_CLOSE, ker)[pz:-pz, pz:-pz] | roi
    gaps = (closed & (1 - roi)).astype(np.uint8)
    ng, glab, gst, gcen = cv2.connectedComponentsWithStats(gaps, connectivity=8)
    slot_area = w * d / low_m ** 2
    slot_ids = [k for k in range(1, ng) if 0.15 * slot_area <= gst[k, cv2.CC_STAT_AREA] <= 4 * slot_area]
    cnts, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not cnts:
        return _empty(m, "no_manipulator", "no manipulator outline")
    cnt = max(cnts, key=len).reshape(-1, 2).astype(float)
    area_img = polygon_area(cnt[:, 0], cnt[:, 1], signed=True)
    if area_img * sgn < 0:
        cnt = cnt[::-1].copy()
    N = len(cnt)
    cnt_i = cnt.astype(np.intp)
    ax_, ay_ = cnt[:, 0] + X0, cnt[:, 1] + Y0
    on_border = (ax_ <= 0) | (ay_ <= 0) | (ax_ >= ws - 1) | (ay_ >= hs - 1)
    full = lambda p: (np.asarray(p, float) + [X0, Y0]) * f + (f - 1) / 2.0     # low-res ROI -> px
    contour_px = full(cnt)
    plane_of = lambda idx: camera.pixel_to_plane(contour_px[np.asarray(idx)])

    k = max(3, 2 * r_close)
    a_ = cnt - np.roll(cnt, k, axis=0)
    b_ = np.roll(cnt, -k, axis=0) - cnt
    turn = np.arctan2(a_[:, 0] * b_[:, 1] - a_[:, 1] * b_[:, 0], np.sum(a_ * b_, axis=1)) * sgn
    near_border = maximum_filter1d(on_border.astype(np.uint8), size=2 * k + 3, mode="wrap").astype(bool)
    thr = math.radians(corner_turn_deg)

    def peaks(sign):
        v = np.where(near_border, 0.0, sign * turn)
        mx = maximum_filter1d(v, size=2 * k + 1, mode="wrap")
        out = []
        for i in np.nonzero((v >= mx) & (v > thr))[0]:
            if not out or i - out[-1] > k:
                out.append(int(i))
        if len(out) > 1 and out[0] + N - out[-1] <= k:
            out.pop()
        return out

    concave, convex = peaks(-1.0), peaks(+1.0)
    best = None
    for i in range(len(concave)):
        for j in range(i + 1, len(concave)):
            pa, pb = plane_of([concave[i], concave[j]])
            e = abs(np.linalg.norm(pa - pb) / (2 * R) - 1)
            if best is None or e < best[0]:
                best = (e, concave[i], concave[j])
    if best is None or best[0] > pair_tol:
        return _empty(m, "partial", "base corners not found (the base is hidden or outside the image)",
                      contour_px)
    ia, ib = best[1], best[2]
    lab_on = glab[cnt_i[:, 1], cnt_i[:, 0]]
    mouths = {}                                # slot region -> (first idx, last idx, bridged?)
    for s in slot_ids:
        idx = np.nonzero(lab_on == s)[0]
        if len(idx):
            if idx[-1] - idx[0] > len(idx) + 2:            # the run wraps around index 0
                g = int(np.argmax(np.diff(idx)))
                idx = np.concatenate([idx[g + 1:], idx[:g + 1] + N])
            mouths[s] = (int(idx[0]) % N, int(idx[-1]) % N, True)
        else:          # mouth (almost) closed: a hole; its mouth is where its long axis meets the outline
            bx, by, bw_, bh_ = gst[s, :4]
            py_, px_ = np.nonzero(glab[by:by + bh_, bx:bx + bw_] == s)
            _, axis = _pca_line(np.stack([px_ + bx, py_ + by], 1))
            rel = cnt - gcen[s]
            along = rel @ axis
            perp = np.abs(rel[:, 0] * axis[1] - rel[:, 1] * axis[0])
            near = np.nonzero(perp < 2.0)[0]
            i0 = int(near[np.argmin(np.abs(along[near]))]) if len(near) else \
                int(np.argmin(np.sum(rel ** 2, axis=1)))
            mouths[s] = (i0, i0, False)
    apos = lambda i, start: (i - start) % N
    n_ab = sum(apos(v[0], ia) < apos(ib, ia) for v in mouths.values())
    if n_ab > len(mouths) - n_ab or (2 * n_ab == len(mouths) and apos(ib, ia) > apos(ia, ib)):
        i_br, i_bl = ia, ib
    else:
        i_br, i_bl = ib, ia
    L_tube = apos(i_bl, i_br)
    pos = lambda i: apos(i, i_br)
    tube_border = [pos(i) for i in np.nonzero(on_border)[0] if 0 < pos(i) < L_tube]
    slots = sorted((pos(v[0]), s) for s, v in mouths.items() if 0 < pos(v[0]) < L_tube)
    msg = []
    tip = None
    if not tube_border:
        cands = sorted((pos(i), i) for i in convex if 0 < pos(i) < L_tube)
        bt = None
        for (pa_, i1), (pb_, i2) in zip(cands[:-1], cands[1:]):
            if any(pa_ < sp < pb_ for sp, _ in slots):
                continue
            qa, qb = plane_of([i1, i2])
            e = abs(np.linalg.norm(qa - qb) / (2 * R) - 1)
            if bt is None or e < bt[0]:
                bt = (e, i1, i2)
        if bt is not None and bt[0] <= pair_tol:
            tip = (bt[1], bt[2])
        else:
            msg.append("tip corners not found")
    if tip is not None:
        right = [s for p_, s in slots if p_ < pos(tip[0])]
        left = [s for p_, s in slots if p_ > pos(tip[1])]
        cut = False
    else:
        lim0 = min(tube_border) if tube_border else L_tube
        lim1 = max(tube_border) if tube_border else 0
        right = [s for p_, s in slots if p_ < lim0]
        left = [s for p_, s in slots if p_ > lim1]
        cut = True
        if tube_border:
            msg.append("the tube is cut off by the image border")
    right_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == +1]
    left_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == -1]
    index = {(lay.kind[i], int(lay.joint[i]), int(lay.side[i])): i for i in range(m)}
    status = ["occluded"] * m

    def assign(found, joints, side, base_i, tip_i):
        """Slot regions ordered from the base -> joints of this side (ordered from the base)."""
        name = "right" if side > 0 else "left"
        if len(found) == len(joints):
            return list(zip(found, joints))
        if cut and len(found) < len(joints):
            return list(zip(found, joints[:len(found)]))
        msg.append(f"{len(found)} slots on the {name} side, {len(joints)} expected")
        if len(found) > len(joints) or tip_i is None:
            return []
        # a slot missing: align by the fractional position along the side (base -> tip)
        zf = np.array([((j - 1) * geom.p - geom.base_edge_z) / (geom.tip_z - geom.base_edge_z) for j in joints])
        spacing = float(np.min(np.diff(zf))) if len(zf) > 1 else 1.0
        span = max(apos(tip_i, base_i) if side > 0 else apos(base_i, tip_i), 1)
        out, taken = [], {}
        for s in found:
            ps = apos(mouths[s][0], base_i) if side > 0 else apos(base_i, mouths[s][0])
            kk = int(np.argmin(np.abs(zf - ps / span)))
            if abs(zf[kk] - ps / span) < 0.3 * spacing and kk not in taken:
                taken[kk] = s
                out.append((s, joints[kk]))
            else:
                for kind in ("proximal", "distal"):
                    status[index[(kind, joints[kk], side)]] = "ambiguous"
        return out

    if (not cut and len(right_j) != len(left_j) and len(right) == len(left_j) and len(left) == len(right_j)):
        # the sides hold each other's number of slots: the view is reflected the other way
        return _empty(m, "partial", f"the slot counts ({len(right)} right, {len(left)} left) fit the opposite "
                                    f"mirror flag: check `mirror` in experiment.toml (given: {bool(mirror)})",
                      contour_px, status="ambiguous")
    right_pairs = assign(right, right_j, +1, i_br, tip[0] if tip else None)
    left_pairs = assign(left[::-1], left_j, -1, i_bl, tip[1] if tip else None)

    # ---- corner specifications: position, the two edge directions, usable edge lengths ----------
    zj = (np.arange(1, geom.n_joints + 1) - 1) * geom.p
    iv_lo, iv_hi = zj - w / 2, zj + w / 2

    def room(z, up):
        """Straight edge from z along a side, up or down, before the next joint's feature [m]."""
        if up:
            nxt = iv_lo[iv_lo > z + 1e-12]
            return (min(nxt.min(), geom.tip_z) if len(nxt) else geom.tip_z) - z
        prv = iv_hi[iv_hi < z - 1e-12]
        return z - (max(prv.max(), geom.base_edge_z) if len(prv) else geom.base_edge_z)

    lp = lambda length_m: max(2, int(round(length_m / low_m)))

    def cdir(i, before, a1, a2):
        sel = [(i - t) % N for t in range(a1, a2 + 1)] if before else [(i + t) % N for t in range(a1, a2 + 1)]
        c, dv = _pca_line(cnt[sel])
        ref = (cnt[i] - cnt[sel[-1]]) if before else (cnt[sel[-1]] - cnt[i])
        return c, (dv if np.dot(dv, ref) >= 0 else -dv)

    outward = lambda dv: sgn * np.array([dv[1], -dv[0]])
    mc, _ = cv2.findContours(roi, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    mcnt = max(mc, key=len).reshape(-1, 2).astype(float)

    def mdir_batch(P, rough, a2, a1=2.0, cone_deg=35.0):
        """Directions of the unbridged outline leaving points P (n,2) along ``rough`` (n,2),
        from its pixels a1..a2 (n,) low-res px away within a cone (total least squares)."""
        a2 = np.maximum(a2, a1 + 2)
        nb = cKDTree(mcnt).query_ball_point(P, a2.max())
        lens = np.array([len(x) for x in nb])
        pi = np.repeat(np.arange(len(P)), lens)
        mi = np.concatenate([np.asarray(x, dtype=np.intp) for x in nb]) if lens.sum() else np.zeros(0, np.intp)
        rel = mcnt[mi] - P[pi]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        cosang = (rel * rough[pi]).sum(1) / np.maximum(dist, 1e-9)
        wgt = ((dist >= a1) & (dist <= a2[pi]) & (cosang > math.cos(math.radians(cone_deg)))).astype(float)
        nP = len(P)
        n = np.bincount(pi, wgt, nP) + 1.0                              # + the point P itself
        sx = np.bincount(pi, wgt * rel[:, 0], nP) / n
        sy = np.bincount(pi, wgt * rel[:, 1], nP) / n
        dx, dy = rel[:, 0] - sx[pi], rel[:, 1] - sy[pi]
        sxx = np.bincount(pi, wgt * dx * dx, nP) + sx * sx
        sxy = np.bincount(pi, wgt * dx * dy, nP) + sx * sy
        syy = np.bincount(pi, wgt * dy * dy, nP) + sy * sy
        ang = 0.5 * np.arctan2(2 * sxy, sxx - syy)
        dv = np.stack([np.cos(ang), np.sin(ang)], 1)
        dv *= np.where((dv * rough).sum(1) < 0, -1.0, 1.0)[:, None]
        return np.where((n >= 4)[:, None], dv, rough)

    specs = []        # (point, corner low-res xy, d_in, d_out, L_in m, L_out m, face_in, face_out)
    # base corners: the closing rounds concave corners, so take them from the unbridged outline
    ma = polygon_area(mcnt[:, 0], mcnt[:, 1], signed=True)
    if ma * sgn < 0:
        mcnt = mcnt[::-1].copy()
    M_ = len(mcnt)
    k2 = 3
    ma_ = mcnt - np.roll(mcnt, k2, axis=0)
    mb_ = np.roll(mcnt, -k2, axis=0) - mcnt
    mturn = np.arctan2(ma_[:, 0] * mb_[:, 1] - ma_[:, 1] * mb_[:, 0], np.sum(ma_ * mb_, axis=1)) * sgn
    up_len, mount_len = room(geom.base_edge_z, True), geom.mount_half_width - R
    for bi, side in ((i_br, +1), (i_bl, -1)):
        # the closing's fillet lies 0.41 r_close outside the true corner (a 90° corner)
        tan = _unit(cnt[(bi + 3) % N] - cnt[(bi - 3) % N])
        expect = cnt[bi] - (math.sqrt(2) - 1) * r_close * outward(tan)
        near = np.nonzero(np.sum((mcnt - expect) ** 2, axis=1) < (0.5 * r_close + 2.0) ** 2)[0]
        if not len(near):
            continue
        # the 90° concave corner (a nearly closed slot mouth nearby turns by ~180°)
        mi = int(near[np.argmin(np.abs(mturn[near] + math.pi / 2))])
        a2_side = max(3, min(lp(0.8 * up_len), 10))
        a2_mount = max(3, min(lp(0.8 * mount_len), 10))
        sel_in = [(mi - t_) % M_ for t_ in range(1, (a2_mount if side > 0 else a2_side) + 1)]
        sel_out = [(mi + t_) % M_ for t_ in range(1, (a2_side if side > 0 else a2_mount) + 1)]
        c_in, d_in = _pca_line(mcnt[sel_in])
        c_out, d_out = _pca_line(mcnt[sel_out])
        d_in = d_in if np.dot(d_in, mcnt[mi] - mcnt[sel_in[-1]]) >= 0 else -d_in
        d_out = d_out if np.dot(d_out, mcnt[sel_out[-1]] - mcnt[mi]) >= 0 else -d_out
        P = _intersect(c_in, d_in, c_out, d_out)
        if P is None or np.linalg.norm(P - mcnt[mi]) > 3:
            P = mcnt[mi]
        specs.append((index[("base", 0, side)], P, d_in, d_out, mount_len if side > 0 else up_len,
                      up_len if side > 0 else mount_len, False, False))
    if tip is not None:
        down = room(geom.tip_z, False)
        for ti, side in ((tip[0], +1), (tip[1], -1)):
            c_in, d_in = cdir(ti, True, 2, 2 + lp(min(0.5e-3, 0.8 * down)))
            c_out, d_out = cdir(ti, False, 2, 2 + lp(min(0.5e-3, 0.8 * down)))
            P = _intersect(c_in, d_in, c_out, d_out)
            specs.append((index[("tip", 0, side)], cnt[ti] if P is None else P, d_in, d_out,
                          down if side > 0 else 2 * R, 2 * R if side > 0 else down, False, False))
    chord = lambda i0, i1: _unit(cnt[i1 % N] - cnt[i0 % N])
    slot_rows = []
    for pairs, side in ((right_pairs, +1), (left_pairs, -1)):
        for s, j in pairs:
            i_first, i_last, bridged = mouths[s]
            z = (j - 1) * geom.p
            lo_len, hi_len = room(z - w / 2, False), room(z + w / 2, True)
            first_len, second_len = (lo_len, hi_len) if side > 0 else (hi_len, lo_len)
            a_f, a_s = lp(min(0.5e-3, 0.8 * first_len)), lp(min(0.5e-3, 0.8 * second_len))
            d_in = chord(i_first - 2 - a_f, i_first - 2)
            d_out = chord(i_last + 2, i_last + 2 + a_s)
            if bridged:
                Pa, Pb = cnt[(i_first - 1) % N], cnt[(i_last + 1) % N]
            else:
                Pa, Pb = cnt[i_first] - 0.25 * d_in, cnt[i_first] + 0.25 * d_out
            slot_rows.append((side, j, Pa, Pb, d_in, d_out, a_f, a_s, first_len, second_len))
    if slot_rows:
        # the bridged outline bends near other concavities (the base fillet): take the edge
        # directions from the unbridged outline, in a cone around the rough ones
        Ps = np.array([r_[2] for r_ in slot_rows] + [r_[3] for r_ in slot_rows])
        rough = np.array([-r_[4] for r_ in slot_rows] + [r_[5] for r_ in slot_rows])
        a2s = np.array([r_[6] for r_ in slot_rows] + [r_[7] for r_ in slot_rows], float)
        dirs = mdir_batch(Ps, rough, a2s)
        ns = len(slot_rows)
        for q_, (side, j, Pa, Pb, _, _, _, _, first_len, second_len) in enumerate(slot_rows):
            d_in, d_out = -dirs[q_], dirs[ns + q_]
            face_a = -outward(d_in)                 # into the tube along the first face
            face_b = outward(d_out)                 # out of the slot along the second face
            kinds = ("proximal", "distal") if side > 0 else ("distal", "proximal")
            specs.append((index[(kinds[0], j, side)], Pa, d_in, face_a, first_len, d, False, True))
            specs.append((index[(kinds[1], j, side)], Pb, face_b, d_out, d, second_len, True, False))

    # ---- 3. sub-pixel refinement ------------------------------------------------------------
    pts_px = np.full((m, 2), np.nan)
    ideal = np.full((m, 2), np.nan)
    cov = np.full((m, 2, 2), np.nan)
    blur = math.nan
    if specs:
        pidx = np.array([s_[0] for s_ in specs])
        C = full(np.array([s_[1] for s_ in specs]))
        Din = _unit(np.array([s_[2] for s_ in specs]))
        Dout = _unit(np.array([s_[3] for s_ in specs]))
        Lin = np.array([s_[4] for s_ in specs]) * px_per_m
        Lout = np.array([s_[5] for s_ in specs]) * px_per_m
        face = np.concatenate([[s_[6] for s_ in specs], [s_[7] for s_ in specs]]).astype(bool)
        C0 = C.copy()
        # a region of interest of the full image (profiles never leave it)
        u0 = max(int(contour_px[:, 0].min()) - 20, 0)
        v0 = max(int(contour_px[:, 1].min()) - 20, 0)
        u1 = min(int(contour_px[:, 0].max()) + 21, W)
        v1 = min(int(contour_px[:, 1].max()) + 21, H)
        img = np.ascontiguousarray(gray[v0:v1, u0:u1])
        off = np.array([u0, v0], float)
        w_px = w * px_per_m
        bl = 1.0
        ok = np.zeros(len(specs), bool)
        for it in range(1 + iterations):
            if it == 0:
                s0, s_end, h, lim = 5.0, 3.0, stage1_half_px, 0.25
            else:
                s0, s_end, h, lim = max(3.0, 3.0 * bl + 1.0), max(2.0, 2.5 * bl + 1.0), max(3.0, 3.0 * bl + 2.0), 0.1
            out = _refine(img, off, camera, C, Din, Dout, Lin, Lout, face, w_px, sgn, s0=s0, s_end=s_end, h=h,
                          step=profile_step_px, lim=lim, min_points=min_edge_points,
                          contrast=contrast, h_face=stage1_face_px if it == 0 else h,
                          blur_prior=bl if it > 0 else math.nan)
            Cn, Xi, Ci, okn, bl_new, Din_n, Dout_n = out
            if np.isfinite(bl_new):
                bl = bl_new
            C = np.where(np.isfinite(Cn).all(1)[:, None], Cn, C)
            Din, Dout = Din_n, Dout_n
            ok = okn
        blur = bl
        shift = np.linalg.norm(C - C0, axis=1)
        sig_px = np.sqrt(np.maximum(np.trace(Ci, axis1=1, axis2=2) / 2, 0)) * sigma_inflation
        lo_b, hi_b = np.array([0.0, 0.0]), np.array([W - 1.0, H - 1.0])
        inimg = np.all((C >= lo_b) & (C <= hi_b), axis=1)
        for q, i in enumerate(pidx):
            if not ok[q] or not inimg[q]:
                status[i] = "occluded"
            elif shift[q] > max_shift_px or not sig_px[q] <= max_sigma_px:
                status[i] = "ambiguous"
                pts_px[i] = C[q]
            else:
                status[i] = "ok"
                pts_px[i] = C[q]
                ideal[i] = Xi[q]
                cov[i] = Ci[q] * sigma_inflation ** 2
    return _finish(camera, geom, m, pts_px, ideal, cov, status, msg, blur, scale_tol, contour_px)


def _finish(camera, geom, m, pts_px, ideal, cov, status, msg, blur, scale_tol, contour_px):
    lay = notch_layout(geom)
    plane = np.full((m, 2), np.nan)
    sigma = np.full(m, np.nan)
    ok = np.array([s == "ok" for s in status])
    if ok.any():
        plane[ok] = camera.ideal_to_plane(ideal[ok])
        J = camera.ideal_to_plane_jacobian(ideal[ok])
        cm = J @ cov[ok] @ np.swapaxes(J, -1, -2)
        sigma[ok] = np.sqrt(np.maximum(np.trace(cm, axis1=-2, axis2=-1) / 2, 0))
    pair = {(lay.kind[i], int(lay.side[i])): i for i in range(m) if lay.kind[i] in ("base", "tip")}
    widths = [np.linalg.norm(plane[pair[(kd, -1)]] - plane[pair[(kd, 1)]])
              for kd in ("base", "tip") if ok[pair[(kd, -1)]] and ok[pair[(kd, 1)]]]
    if widths and np.max(np.abs(np.array(widths) / (2 * geom.outer_radius) - 1)) > scale_tol:
        msg = [*msg, (f"scale check failed: the tube measures {np.mean(widths) * 1e3:.3f} mm across, the "
                      f"geometry says {2 * geom.outer_radius * 1e3:.3f} mm (wrong calibration file, plane "
                      "pose or geometry?)")]
        status = ["ambiguous" if s == "ok" else s for s in status]
        plane[:] = np.nan
        sigma[:] = np.nan
    n_ok = sum(s == "ok" for s in status)
    if n_ok == m:
        ist, text = "ok", ""
    else:
        ist = "partial"
        bad = [str(i + 1) for i in range(m) if status[i] != "ok"]
        text = "; ".join(msg + [f"{m - n_ok} of {m} points not ok: " + ", ".join(bad[:20])
                                + (" ..." if len(bad) > 20 else "")])
    return Detection(plane, pts_px, sigma, tuple(status), ist, text, contour_px, float(blur))


def _refine(img, off, camera, C, Din, Dout, Lin, Lout, face, w_px, sgn, *, s0, s_end, h, step, lim, min_points,
            contrast, h_face=None, blur_prior=math.nan):
    """One pass of edge-profile line fits for all corners at once.

    Edge ``e < K`` is corner e's incoming edge (behind the corner), ``e >= K``
    its outgoing edge. Profiles run from the object (t < 0) to the background
    (t > 0). Returns raw corner px (K,2), ideal px (K,2), ideal covariance
    (K,2,2), ok (K,), blur estimate [px], new raw edge directions (K,2) x 2.
    """
    K = len(C)
    E_dir = np.concatenate([-Din, Dout])
    E_trav = np.concatenate([Din, Dout])
    E_nrm = sgn * np.stack([E_trav[:, 1], -E_trav[:, 0]], axis=1)
    E_len = np.concatenate([Lin, Lout])
    E_C = np.concatenate([C, C])
    h_face = h if h_face is None else h_face
    n_t = int(math.ceil(max(h, h_face) / step))
    t = np.arange(-n_t, n_t + 1) * step
    kt = np.where(face, int(math.ceil(h_face / step)), int(math.ceil(h / step)))       # half window per edge
    # slot faces: the background side is a slot that may be narrower than the profile (a
    # nearly closed mouth); their levels come from the partner edge of the same corner (the
    # outer edge, with open background), and a face profile is used only where the slot is
    # wide enough for the background level to be reached.
    n_s = np.maximum(np.floor(E_len - s_end - s0).astype(int) + 1, 0)
    e_idx = np.repeat(np.arange(2 * K), n_s)
    Np = len(e_idx)
    nan = np.full((K, 2), np.nan)
    if Np == 0:
        return nan, nan.copy(), np.full((K, 2, 2), np.nan), np.zeros(K, bool), math.nan, Din, Dout
    s_val = s0 + (np.arange(Np) - np.repeat(np.cumsum(n_s) - n_s, n_s))
    base = E_C[e_idx] + s_val[:, None] * E_dir[e_idx] - off
    nrm = E_nrm[e_idx]
    mapx = (base[:, 0, None] + t[None, :] * nrm[:, 0, None]).astype(np.float32)
    mapy = (base[:, 1, None] + t[None, :] * nrm[:, 1, None]).astype(np.float32)
    prof = cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=float("nan")).astype(float)
    rows = np.arange(Np)
    kp = kt[e_idx]
    win = np.abs(np.arange(-n_t, n_t + 1))[None, :] <= kp[:, None]
    prof = np.where(win, prof, np.nan)
    lo_v = 0.5 * (prof[rows, n_t - kp] + prof[rows, n_t - kp + 1])
    hi_v = 0.5 * (prof[rows, n_t + kp] + prof[rows, n_t + kp - 1])
    # levels from the profiles that span the edge (object at one end, background at the other)
    span_ok = (lo_v - hi_v) * (1.0 / contrast) > 0.5
    lo = _group_median(np.where(span_ok, lo_v, np.nan), e_idx, 2 * K)
    hi = _group_median(np.where(span_ok, hi_v, np.nan), e_idx, 2 * K)
    partner = np.concatenate([np.arange(K) + K, np.arange(K)])
    lo = np.where(face, lo[partner], lo)
    hi = np.where(face, hi[partner], hi)
    span = (hi - lo)[e_idx]
    with np.errstate(invalid="ignore", divide="ignore"):
        qa = (prof - lo[e_idx, None]) / span[:, None]
        q_lo = (lo_v - lo[e_idx]) / span
        q_hi = (hi_v - lo[e_idx]) / span
    fp = face[e_idx]
    # plateau tolerance: `lim`, or 4 x the plateau noise of the normalised profiles if that is larger
    sel_ = span_ok & ~fp & np.isfinite(q_lo)
    sq = 1.4826 * float(np.median(np.abs(q_lo[sel_]))) if sel_.sum() >= 10 else 0.0
    lim = max(lim, 4.0 * sq)
    valid = (np.isfinite(qa).sum(axis=1) == 2 * kp + 1) & (np.abs(span) > 1e-6) & (np.abs(q_lo) < lim)
    with np.errstate(invalid="ignore"):
        q_peak = np.max(np.where((t[None, :] > 0) & win, np.nan_to_num(qa, nan=-np.inf), -np.inf), axis=1)
    # a face profile must reach the background level inside the slot (its maximum is noise-biased up)
    valid &= np.where(fp, q_peak > 1 - 0.5 * lim, np.abs(q_hi - 1) < lim)
    # ascending 0.5 crossings; the one nearest the profile centre
    with np.errstate(invalid="ignore"):
        cr = (qa[:, :-1] < 0.5) & (qa[:, 1:] >= 0.5)
    tm = np.abs(0.5 * (t[:-1] + t[1:]))
    dist = np.where(cr, tm[None, :], np.inf)
    j = np.argmin(dist, axis=1)
    valid &= np.isfinite(dist[rows, j])
    q0, q1 = qa[rows, j], qa[rows, np.minimum(j + 1, len(t) - 1)]
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = t[j] + (0.5 - q0) / (q1 - q0) * step
    valid &= np.isfinite(tc)
    # blur from the 25 % -> 75 % rise of valid non-face profiles (interpolated crossings; for a
    # Gaussian edge the rise is 1.349 sigma)
    qv = np.nan_to_num(qa[valid & ~fp], nan=-1.0)
    blur = math.nan
    if len(qv) >= 5:
        rr = np.arange(len(qv))
        pos = []
        for lvl in (0.25, 0.75):
            i1 = np.argmax(qv >= lvl, axis=1)
            i0 = np.maximum(i1 - 1, 0)
            a0, a1 = qv[rr, i0], qv[rr, i1]
            with np.errstate(invalid="ignore", divide="ignore"):
                pos.append(t[i0] + np.where(a1 > a0, (lvl - a0) / (a1 - a0), 0.0) * step)
        wd = pos[1] - pos[0]
        wd = wd[np.isfinite(wd) & (wd > 0)]
        if len(wd):
            blur = float(np.median(wd)) / 1.349
    raw = base[valid] + tc[valid, None] * nrm[valid] + off
    grp = e_idx[valid]
    und = camera.undistort_pixels(raw)
    c, dd, n, s2, stt, _ = _robust_group_lines(und, grp, 2 * K)
    # floor on the crossing variance: image noise over the edge slope (a few crossings can scatter
    # less than the noise by chance, and their fit would then claim too much)
    plateau = valid & ~fp
    if plateau.sum() >= 10 and np.isfinite(blur_prior):
        sq = 1.4826 * float(np.median(np.abs(q_lo[plateau])))
        s2 = np.maximum(s2, (sq * math.sqrt(2 * math.pi) * blur_prior) ** 2)
    good_e = (n >= min_points) & (stt > 0)
    k1, k2 = np.arange(K), np.arange(K) + K
    d1, d2 = dd[k1], dd[k2]
    sin = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    okc = good_e[k1] & good_e[k2] & (sin > 0.5)
    n1 = np.stack([-d1[:, 1], d1[:, 0]], 1)
    n2 = np.stack([-d2[:, 1], d2[:, 0]], 1)
    Amat = np.stack([n1, n2], 1)                                     # (K, 2, 2)
    rhs = np.stack([(n1 * c[k1]).sum(1), (n2 * c[k2]).sum(1)], 1)
    det = Amat[:, 0, 0] * Amat[:, 1, 1] - Amat[:, 0, 1] * Amat[:, 1, 0]
    okc &= np.abs(det) > 1e-9
    Ainv = np.zeros_like(Amat)
    sd = np.where(okc, det, 1.0)
    Ainv[:, 0, 0], Ainv[:, 0, 1] = Amat[:, 1, 1] / sd, -Amat[:, 0, 1] / sd
    Ainv[:, 1, 0], Ainv[:, 1, 1] = -Amat[:, 1, 0] / sd, Amat[:, 0, 0] / sd
    X = np.einsum("kij,kj->ki", Ainv, rhs)
    # var(n_k . dX) = s²/n + (lever arm)² s²/S_tt for each line (offset and angle errors)
    lev1 = ((X - c[k1]) * d1).sum(1)
    lev2 = ((X - c[k2]) * d2).sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        v1 = s2[k1] / np.maximum(n[k1], 1) + lev1 ** 2 * s2[k1] / np.where(stt[k1] > 0, stt[k1], np.inf)
        v2 = s2[k2] / np.maximum(n[k2], 1) + lev2 ** 2 * s2[k2] / np.where(stt[k2] > 0, stt[k2], np.inf)
    D = np.zeros((K, 2, 2))
    D[:, 0, 0], D[:, 1, 1] = v1, v2
    cov = Ainv @ D @ np.swapaxes(Ainv, 1, 2)
    X[~okc] = np.nan
    cov[~okc] = np.nan
    Cn = np.full((K, 2), np.nan)
    if okc.any():
        Cn[okc] = camera.distort_pixels(X[okc])
    # raw-image lines of the fitted edges (directions oriented like the previous ones) for the next pass
    ge = np.nonzero(good_e)[0]
    draw_ = np.full((2 * K, 2), np.nan)
    craw = np.full((2 * K, 2), np.nan)
    if len(ge):
        ends = camera.distort_pixels(np.concatenate([c[ge] - 5 * dd[ge], c[ge] + 5 * dd[ge]]))
        draw_[ge] = _unit(ends[len(ge):] - ends[:len(ge)])
        craw[ge] = 0.5 * (ends[len(ge):] + ends[:len(ge)])
    new = []
    for D_old, kk in ((Din, k1), (Dout, k2)):
        dn = draw_[kk]
        good = np.isfinite(dn).all(1)
        flip = np.where((dn * D_old).sum(1) < 0, -1.0, 1.0)
        new.append(np.where(good[:, None], dn * flip[:, None], D_old))
    # a corner with one good line: put it on that line and make a failed slot face perpendicular
    # to it (a link is a rigid rectangle), so that the next pass finds the face
    one = ~okc & (good_e[k1] ^ good_e[k2])
    for k in np.nonzero(one)[0]:
        g_e, b_e = (k1[k], k2[k]) if good_e[k1[k]] else (k2[k], k1[k])
        dg = draw_[g_e]
        Cn[k] = craw[g_e] + np.dot(C[k] - craw[g_e], dg) * dg
        if face[b_e]:
            D_b = new[0 if b_e < K else 1]
            perp = np.array([-dg[1], dg[0]])
            D_b[k] = perp if np.dot(perp, D_b[k]) >= 0 else -perp
    return Cn, X, cov, okc, blur, new[0], new[1]


def detections_table(sample, det: Detection):
    """Rows of ``detections.csv`` (docs/data-formats.md) for one sample.

    Returns
    -------
    pandas.DataFrame with columns sample, point, x_mm, y_mm, u_px, v_px, sigma_mm, status
    """
    m = len(det.status)
    return pd.DataFrame({
        "sample": np.full(m, sample), "point": np.arange(1, m + 1),
        "x_mm": det.points[:, 0] / MM, "y_mm": det.points[:, 1] / MM,
        "u_px": det.points_px[:, 0], "v_px": det.points_px[:, 1],
        "sigma_mm": det.sigma / MM, "status": list(det.status)})


def draw_overlay(image, det: Detection, *, scale: float = 1.0) -> np.ndarray:
    """An overlay (Fig. 12 style): the bridged outline and numbered corners coloured by status (BGR uint8)."""
    g = to_gray(image)
    lo, hi = float(g.min()), float(g.max())
    g8 = np.round((g - lo) * (255.0 / max(hi - lo, 1e-9))).astype(np.uint8)
    img = cv2.cvtColor(g8, cv2.COLOR_GRAY2BGR)
    if len(det.contour_px):
        cv2.polylines(img, [np.round(det.contour_px).astype(np.int32).reshape(-1, 1, 2)], True, (255, 160, 0), 1)
    colours = {"ok": (0, 200, 0), "ambiguous": (0, 200, 255), "occluded": (0, 0, 255)}
    for i, (uv, st) in enumerate(zip(det.points_px, det.status)):
        if not np.isfinite(uv).all():
            continue
        c = (int(round(uv[0])), int(round(uv[1])))
        cv2.circle(img, c, 4, colours[st], 1, cv2.LINE_AA)
        cv2.putText(img, str(i + 1), (c[0] + 5, c[1] - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colours[st], 1,
                    cv2.LINE_AA)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    return img
