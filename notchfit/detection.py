"""Notch-corner detector: image -> the numbered notch points in plane mm (geometry.md).

The detector does not assume the kinematics. It uses only the silhouette
described in geometry.md ("What a camera sees") and the geometry's
dimensions (slot width ``w``, depth ``d``, outer radius ``R``, slot sides):

1. **Segment**: Gaussian smoothing, Otsu threshold; the polarity (dark tube on
   a bright background or the reverse) is the one whose class covers less of
   the image border; the largest connected region is the tube with its mount.
2. **Outline in the plane**: its outer contour (``cv2.findContours``) is
   simplified (``cv2.approxPolyDP``) and mapped to the metric plane frame
   (camera undistortion + plane pose, :meth:`CameraModel.pixel_to_plane`);
   a mirrored view is reflected so that the outline is anticlockwise in the
   manipulator's orientation.
3. **Sharp corners**: local maxima of the turn between chords ``corner_k``
   contour points long, above ``min_turn_deg``; flexure joins (a
   turn of at most the slot-closure angle) are not sharp. Corners next to the
   image border are dropped (a cut-off tube yields no invented corners).
4. **Identification**: the mount's bottom edge (the longest edge between
   sharp corners) anchors the numbering: mount corners, then the two concave
   base corners (points 1 and 2). From point 2 anticlockwise (the right side)
   and from point 1 clockwise (the left side), slot notches are quadruples
   convex / concave / concave / convex with face lengths ``≈ d`` and bottom
   ``≈ w``; each is assigned to the slot whose straight-configuration
   spacing from the previous feature matches the measured chord best (so a
   closed or damaged slot is skipped, not mis-numbered). The tip corners are
   the two convex corners ``≈ 2R`` apart between the two sides.
5. **Sub-pixel refinement** (opencv-and-rendering.md: 0.04 px on synthetic
   notched strips): along each of the two straight edges at a corner,
   intensity profiles across the edge (sampled in the image at positions
   given in the plane, bilinear) give the 50 % crossing between the local
   levels; each crossing is mapped to the plane; a total-least-squares line
   is fitted to each edge's crossings (one outlier-rejection pass); the corner
   is the intersection of the two lines (two iterations, re-sampling along
   the refined lines). The corner's σ comes from the two line fits'
   residuals.

Statuses: ``ok``; ``ambiguous`` (found, but the fit is weak: a nearly closed
slot whose faces are closer than the profile length, too few edge samples,
or large residuals; coordinates kept, σ reported); ``occluded`` (not found:
cut off, hidden, or not identified; NaN coordinates). No point is ever
interpolated from the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .camera import CameraModel
from .geometry import Geometry, notch_layout

__all__ = ["Detection", "detect_notches", "draw_overlay", "detections_table"]

STATUSES = ("ok", "ambiguous", "occluded")


@dataclass(frozen=True)
class Detection:
    """Result of :func:`detect_notches` for one image.

    Attributes
    ----------
    points : ndarray (m, 2)
        Notch points in the plane frame [m]; NaN when occluded.
    points_px : ndarray (m, 2)
        The same in the raw image [px] (u = column, v = row); NaN when occluded.
    sigma : ndarray (m,)
        Standard uncertainty of each point [m] (isotropic), NaN when occluded.
    status : tuple of str (m,)
        ``ok``, ``ambiguous`` or ``occluded`` per point.
    image_status : str
        ``ok`` (every point ok), ``partial``, or ``no_manipulator``.
    message : str
        Why points are missing (empty when all are ok).
    contour_px : ndarray (K, 2)
        The simplified silhouette outline [px] (for overlays; empty if none).
    """

    points: np.ndarray
    points_px: np.ndarray
    sigma: np.ndarray
    status: tuple
    image_status: str
    message: str
    contour_px: np.ndarray

    @property
    def n_ok(self) -> int:
        return sum(s == "ok" for s in self.status)

    @property
    def points_mm(self) -> np.ndarray:
        return self.points * 1e3


def _empty(m, image_status, message, contour=None):
    nan = np.full((m, 2), np.nan)
    return Detection(nan, nan.copy(), np.full(m, np.nan), ("occluded",) * m, image_status, message,
                     np.zeros((0, 2)) if contour is None else contour)


def _to_float_gray(image):
    img = np.asarray(image)
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
        elif img.shape[2] == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        else:
            img = img[..., 0]
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"expected a 2-D gray or colour image, got shape {np.shape(image)}")
    return img.astype(np.float32)


def _segment(gray, smooth_sigma, min_area_px):
    """Otsu segmentation -> (object mask uint8 0/1, smoothed image, contrast, largest outer contour)."""
    sm = cv2.GaussianBlur(gray, (0, 0), smooth_sigma) if smooth_sigma > 0 else gray
    lo, hi = float(sm.min()), float(sm.max())
    if hi - lo < 1e-6:
        return None, sm, 0.0, None
    s8 = cv2.convertScaleAbs(sm, alpha=255.0 / (hi - lo), beta=-lo * 255.0 / (hi - lo))
    _, mask = cv2.threshold(s8, 0, 1, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    border = np.concatenate([mask[0], mask[-1], mask[:, 0], mask[:, -1]])
    if border.mean() > 0.5:                        # bright background: the object is the dark class
        mask = 1 - mask
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None, sm, 0.0, None
    cont = max(contours, key=cv2.contourArea)
    if cv2.contourArea(cont) < min_area_px:
        return None, sm, 0.0, None
    fg = cv2.mean(sm, mask=mask)[0]
    bg = cv2.mean(sm, mask=1 - mask)[0]
    return mask, sm, abs(fg - bg), cont


def _turns(poly):
    """Signed turning angle at each vertex of a closed polygon (left turn > 0)."""
    a = poly - np.roll(poly, 1, axis=0)
    b = np.roll(poly, -1, axis=0) - poly
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = (a * b).sum(1)
    return np.arctan2(cross, dot)


def _signed_area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _sharp_corners(pm, border_ok, min_turn, k):
    """Sharp corners of a dense closed outline (anticlockwise, plane coordinates).

    The turn at contour point i is the angle between the chords (i-k -> i)
    and (i -> i+k); corners are local maxima of |turn| within +-k points
    that exceed ``min_turn``. Returns a list of (index, turn, valid).
    """
    K = len(pm)
    a = pm - np.roll(pm, k, axis=0)
    b = np.roll(pm, -k, axis=0) - pm
    t = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(1))
    at = np.abs(t)
    win = np.max(np.stack([np.roll(at, s) for s in range(-k, k + 1)]), axis=0)
    cand = np.nonzero((at >= min_turn) & (at >= win))[0]
    out = []
    last = -10 * k
    for i in cand:                       # plateaus: keep the first of equal maxima
        if i - last <= k:
            continue
        last = i
        lo, hi = i - k, i + k
        ok = bool(np.all(border_ok[np.arange(lo, hi + 1) % K]))
        out.append((int(i), float(t[i]), ok))
    if len(out) > 1 and (out[0][0] + K - out[-1][0]) <= k:
        out.pop()
    return out


def _slot_quad_ok(c, sign, geom, tol_depth, tol_width):
    """corners c (4, 2) [m] with turn signs: convex, concave, concave, convex (+ - - +)."""
    if not (sign[0] > 0 and sign[1] < 0 and sign[2] < 0 and sign[3] > 0):
        return False
    d, w = geom.slot_depth, geom.slot_width
    f1, f2 = np.linalg.norm(c[1] - c[0]), np.linalg.norm(c[3] - c[2])
    bot = np.linalg.norm(c[2] - c[1])
    return (abs(f1 - d) < tol_depth * d and abs(f2 - d) < tol_depth * d and abs(bot - w) < tol_width * w)


def _walk_side(chain, start, step, geom, side, layout, tol_depth, tol_width, stop_at, tol_arc):
    """Find slot quads walking from the base corner ``start`` in direction ``step`` up to ``stop_at``.

    Each quad is assigned to the slot whose straight-configuration distance
    from the previous feature matches the outline arc length between them:
    skipped slots on this side (closed: their gap shrinks to 0..w; or missed)
    widen the admissible interval; a quad that fits no slot, or more than
    one, ends the walk (nothing is guessed). Returns {point index: chain
    index} and the chain index of the last feature.
    """
    pos_mm, sign, valid, arc, total = chain
    n = len(pos_mm)
    joints = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == side]
    p, w, d = geom.p, geom.slot_width, geom.slot_depth
    assigned = {}
    prev_i = start
    prev_z = geom.base_edge_z
    k_next = 0
    i = (start + step) % n
    last = start
    for _ in range(n):
        if i == stop_at or k_next >= len(joints):
            break
        q = [(i + step * r) % n for r in range(4)]
        if stop_at in q[1:]:
            break
        if all(valid[x] for x in q) and _slot_quad_ok(pos_mm[q], sign[q], geom, tol_depth, tol_width):
            L = ((arc[q[0]] - arc[prev_i]) * step) % total
            match = []
            for k in range(k_next, len(joints)):
                dz = (joints[k] - 1) * p - w / 2 - prev_z
                s_skip = k - k_next
                # joints of the other side in between: the flexure kink shortens/lengthens the outer edge
                # by at most R * closure angle each
                n_join = sum(1 for jj in range(1, geom.n_joints + 1)
                             if prev_z < (jj - 1) * p < dz + prev_z and geom.slot_sides[jj - 1] != side)
                slack = n_join * geom.outer_radius * geom.closure_angle
                lo = dz - s_skip * w - slack - tol_arc
                hi = dz + s_skip * (2 * d + w) + slack + tol_arc
                if lo <= L <= hi:
                    match.append(k)
            if len(match) != 1:
                break
            k = match[0]
            j = joints[k]
            zj = (j - 1) * p
            assigned[_point_index(layout, j, side, "proximal")] = q[0]
            assigned[_point_index(layout, j, side, "distal")] = q[3]
            prev_i, prev_z = q[3], zj + w / 2
            k_next = k + 1
            last = q[3]
            i = (q[3] + step) % n
            continue
        if not valid[i]:
            break                                      # the outline leaves the image: stop this side
        i = (i + step) % n
    return assigned, last


def _point_index(layout, j, side, kind):
    for idx in range(len(layout.kind)):
        if layout.joint[idx] == j and layout.side[idx] == side and layout.kind[idx] == kind:
            return idx
    raise KeyError((j, side, kind))


def detect_notches(image, camera: CameraModel, geom: Geometry, *, mirror: bool = False,
                   smooth_sigma: float = 1.5, min_area_px: int = 500, approx_eps_px: float = 1.0,
                   min_turn_deg: float = 35.0, corner_k: int = 5, border_px: float = 3.0,
                   tol_depth: float = 0.3, tol_width: float = 0.6, tol_tip: float = 0.15, tol_arc_mm: float = 0.25,
                   profile_sigma: float = 1.0, profile_half_px: float = 5.0, profile_step_px: float = 0.25,
                   edge_skip_px: float = 5.0, level_erode_px: int = 4,
                   level_sigma_px: float = 16.0, level_factor: int = 4, edge_len_mm: float = 0.6, sample_step_px: float = 0.5,
                   min_samples: int = 8, iterations: int = 2, sigma_corr_px: float = 4.0, max_resid_px: float = 0.5) -> Detection:
    """Find the numbered notch corners in one image.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
        Raw camera image (any numeric dtype).
    camera : CameraModel
        Calibrated camera with the plane pose; must match the image size.
    geom : Geometry
        Slot width/depth, outer radius, slot sides, number of joints.
    mirror : bool
        The experiment's ``mirror`` flag (a view from -y).
    smooth_sigma : float
        Gaussian smoothing before thresholding [px].
    min_area_px : int
        Smallest silhouette accepted as a manipulator [px²].
    approx_eps_px : float
        ``approxPolyDP`` tolerance [px].
    min_turn_deg : float
        A vertex turning more than this is a sharp corner [deg].
    corner_k : int
        Chord length (contour points) of the turn measure; corners closer than
        this merge [px].
    border_px : float
        Corners closer than this to the image border are ignored [px].
    tol_depth, tol_width, tol_tip : float
        Relative tolerances on slot depth, slot width and tip width used to
        recognise slots and the tip face.
    tol_arc_mm : float
        Tolerance on the outline arc length between consecutive slots [mm].
    profile_sigma : float
        Smoothing of the image sampled by the profiles [px] (symmetric: no
        edge bias).
    profile_half_px, profile_step_px : float
        Half length and sampling step of each intensity profile [px].
    edge_skip_px : float
        Profiles start this far from the corner (blur rounding) [px].
    level_erode_px, level_sigma_px, level_factor : int, float, int
        Local object/background levels: masks eroded by ``level_erode_px``,
        masked Gaussian average of width ``level_sigma_px`` computed at
        ``1/level_factor`` scale; the 50 % crossing is between these levels.
    edge_len_mm : float
        Longest stretch of an edge used [mm] (stays on one rigid link).
    sample_step_px : float
        Spacing of profiles along an edge [px].
    min_samples : int
        Fewest valid crossings per edge for status ``ok``.
    sigma_corr_px : float
        Correlation length of neighbouring crossings [px] (inflates the
        line-fit σ by ``sqrt(sigma_corr_px / sample_step_px)``).
    iterations : int
        Re-sampling iterations along the refined lines.
    max_resid_px : float
        Line-fit rms residual above which a corner is ``ambiguous`` [px].

    Returns
    -------
    Detection
    """
    layout = notch_layout(geom)
    m = len(layout.kind)
    gray = _to_float_gray(image)
    camera.check_image(gray)
    if not camera.has_plane:
        raise ValueError("the camera model has no plane pose: calibrate with --plane-image")
    H, W = gray.shape
    obj, sm, contrast, cont = _segment(gray, smooth_sigma, min_area_px)
    if obj is None:
        return _empty(m, "no_manipulator", "no manipulator silhouette found (image flat or object too small)")
    approx = cv2.approxPolyDP(cont, approx_eps_px, True).reshape(-1, 2).astype(float)
    cont = cont.reshape(-1, 2).astype(float)
    if len(approx) < 8 or len(cont) < 16 * corner_k:
        return _empty(m, "no_manipulator", "silhouette has too few corners to be a notched tube", approx)
    px_m = 1.0 / camera.plane_scale(camera.pixel_to_plane(approx.mean(0)))      # plane size of a pixel [m]
    flip = np.array([-1.0, 1.0]) if mirror else np.array([1.0, 1.0])
    pm = camera.pixel_to_plane(cont) * flip                    # proper-rotation copy of the manipulator frame
    if _signed_area(pm) < 0:
        pm, cont = pm[::-1].copy(), cont[::-1].copy()
    border_ok = ((cont[:, 0] > border_px) & (cont[:, 0] < W - 1 - border_px) &
                 (cont[:, 1] > border_px) & (cont[:, 1] < H - 1 - border_px))
    corners = _sharp_corners(pm, border_ok, math.radians(min_turn_deg), int(corner_k))
    if len(corners) < 6:
        return _empty(m, "no_manipulator", f"only {len(corners)} sharp corners on the silhouette", approx)
    cidx = np.array([c[0] for c in corners])
    sign = np.sign([c[1] for c in corners])
    valid = np.array([c[2] for c in corners])
    cpos = pm[cidx]
    nC = len(cidx)
    # anchor: the mount's bottom edge, the longest edge between two valid convex corners
    nxt = np.roll(np.arange(nC), -1)
    elen = np.linalg.norm(cpos[nxt] - cpos, axis=1)
    cand = valid & valid[nxt] & (sign > 0) & (sign[nxt] > 0)
    exp_bottom = 2 * geom.mount_half_width
    cand &= np.abs(elen - exp_bottom) < 0.3 * exp_bottom
    if not cand.any():
        return _empty(m, "partial" if nC else "no_manipulator",
                      "mount not found (its bottom edge is missing or cut off): cannot number the corners", approx)
    b0 = int(np.argmax(np.where(cand, elen, -1)))            # mount bottom-left
    i_tr = (b0 + 2) % nC                                        # mount top-right
    i_p2 = (b0 + 3) % nC
    i_tl = (b0 - 1) % nC
    i_p1 = (b0 - 2) % nC
    R = geom.outer_radius
    exp_base = geom.mount_half_width - R
    ok_base = (sign[i_p2] < 0 and sign[i_p1] < 0 and valid[i_p2] and valid[i_p1]
               and abs(np.linalg.norm(cpos[i_p2] - cpos[i_tr]) - exp_base) < 0.3 * exp_base
               and abs(np.linalg.norm(cpos[i_p1] - cpos[i_tl]) - exp_base) < 0.3 * exp_base)
    if not ok_base:
        return _empty(m, "partial", "base corners not found next to the mount", approx)
    seg = np.linalg.norm(np.diff(pm, axis=0, append=pm[:1]), axis=1)
    arc_all = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    total = float(seg.sum())
    chain = (cpos, sign, valid, arc_all[cidx], total)
    found = {0: i_p1, 1: i_p2}
    # tip: the pair of consecutive valid convex corners about 2R apart that is farthest (along the
    # outline) from the mount
    tip_r = _point_index_kind(layout, "tip", +1)
    tip_l = _point_index_kind(layout, "tip", -1)
    carc = arc_all[cidx]
    best = None
    for i in range(nC):
        j2 = (i + 1) % nC
        if valid[i] and valid[j2] and sign[i] > 0 and sign[j2] > 0:
            e = abs(np.linalg.norm(cpos[j2] - cpos[i]) - 2 * R)
            tube = (carc[i_p1] - carc[i_p2]) % total           # the tube part of the outline, p2 -> p1
            a_i, a_j = (carc[i] - carc[i_p2]) % total, (carc[j2] - carc[i_p2]) % total
            if e < tol_tip * 2 * R and 0 < a_i < a_j < tube:
                far = min(a_i, tube - a_j)
                if best is None or far > best[0]:
                    best = (far, i, j2)
    stop_r, stop_l = (best[1], best[2]) if best is not None else (i_p1, i_p2)
    if best is not None:
        found[tip_r], found[tip_l] = best[1], best[2]
    tol_arc = tol_arc_mm * 1e-3
    right, _ = _walk_side(chain, i_p2, +1, geom, +1, layout, tol_depth, tol_width, stop_r, tol_arc)
    left, _ = _walk_side(chain, i_p1, -1, geom, -1, layout, tol_depth, tol_width, stop_l, tol_arc)
    found.update(right)
    found.update(left)
    # sub-pixel refinement of every found corner along its two edges (to the previous and next sharp corner)
    pts = np.full((m, 2), np.nan)
    sig = np.full(m, np.nan)
    status = ["occluded"] * m
    # work in the region of interest around the silhouette (profiles never leave it)
    x0, y0, bw, bh = cv2.boundingRect(cont.astype(np.int32).reshape(-1, 1, 2))
    pad = int(4 * level_sigma_px)
    u0, v0 = max(x0 - pad, 0), max(y0 - pad, 0)
    u1, v1 = min(x0 + bw + pad, W), min(y0 + bh + pad, H)
    roi = gray[v0:v1, u0:u1]
    ref = cv2.GaussianBlur(roi, (0, 0), profile_sigma) if profile_sigma > 0 else roi
    levels = _level_maps(ref, obj[v0:v1, u0:u1], level_erode_px, level_sigma_px, level_factor) + ((u0, v0),)
    keys = sorted(found)
    C0 = np.array([cpos[found[k]] for k in keys]).reshape(-1, 2)
    A = np.array([cpos[(found[k] - 1) % nC] for k in keys]).reshape(-1, 2)
    B = np.array([cpos[(found[k] + 1) % nC] for k in keys]).reshape(-1, 2)
    results = _refine_corners(ref, levels, camera, flip, C0, A, B, px_m, contrast=contrast,
                              profile_half_px=profile_half_px, profile_step_px=profile_step_px,
                              edge_skip_px=edge_skip_px, edge_len=edge_len_mm * 1e-3,
                              sample_step_px=sample_step_px, iterations=iterations, sigma_corr_px=sigma_corr_px)
    for k, res in zip(keys, results):
        if res is None:
            status[k] = "occluded"
            continue
        p_m, s_m, n1, n2, r1, r2 = res
        pts[k] = p_m * flip
        sig[k] = s_m
        weak = min(n1, n2) < min_samples or max(r1, r2) > max_resid_px * px_m
        status[k] = "ambiguous" if weak else "ok"
    pts_px = np.full((m, 2), np.nan)
    good = np.isfinite(pts[:, 0])
    if good.any():
        pts_px[good] = camera.plane_to_pixel(pts[good])
    n_ok = status.count("ok")
    missing = [str(i + 1) for i in range(m) if status[i] != "ok"]
    if n_ok == m:
        ist, msg = "ok", ""
    else:
        ist = "partial"
        msg = f"{m - n_ok} of {m} points not ok: " + ", ".join(missing[:20]) + (" ..." if len(missing) > 20 else "")
    return Detection(pts, pts_px, sig, tuple(status), ist, msg, approx)


def _point_index_kind(layout, kind, side):
    for idx in range(len(layout.kind)):
        if layout.kind[idx] == kind and layout.side[idx] == side:
            return idx
    raise KeyError((kind, side))


def _sample(img, uv):
    """Bilinear samples of ``img`` at ``uv`` (..., 2) [px]; NaN outside."""
    shp = uv.shape[:-1]
    u = uv[..., 0].astype(np.float32).ravel()
    v = uv[..., 1].astype(np.float32).ravel()
    n = u.size
    cols = 1024
    rows = max(1, -(-n // cols))
    pad = rows * cols - n
    U = np.concatenate([u, np.full(pad, -1, np.float32)]).reshape(rows, cols)
    V = np.concatenate([v, np.full(pad, -1, np.float32)]).reshape(rows, cols)
    out = cv2.remap(img, U, V, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    out = out.astype(float).ravel()[:n]
    H, W = img.shape
    out[(u < 0) | (v < 0) | (u > W - 1) | (v > H - 1) | ~np.isfinite(u) | ~np.isfinite(v)] = np.nan
    return out.reshape(shp)


def _edge_crossings(img, levels, camera, flip, C, E, N, s_from, s_to, px_m, half_px, step_px, sample_px,
                    contrast):
    """50 % crossings of intensity profiles across many edges at once.

    Edge ``i`` starts at ``C[i]`` with direction ``E[i]`` and normal ``N[i]``
    (flipped plane frame [m]); profiles at distances ``s_from .. s_to[i]``
    along it, each ``2 half_px`` long. Returns a list of (K_i, 2) crossing
    arrays [m].
    """
    ne = len(C)
    ds = sample_px * px_m
    ns = np.maximum(np.floor((s_to - s_from) / ds).astype(int) + 1, 0)
    ns[s_to <= s_from] = 0
    nmax = int(ns.max()) if ne else 0
    out = [np.zeros((0, 2)) for _ in range(ne)]
    if nmax == 0:
        return out
    s = s_from + ds * np.arange(nmax)
    t = np.arange(-half_px, half_px + 1e-9, step_px) * px_m
    nt = len(t)
    # profile end points projected exactly; in between the image map is affine to ~1e-4 px over a profile
    ends = (C[:, None, None, :] + s[None, :, None, None] * E[:, None, None, :]
            + t[[0, -1]][None, None, :, None] * N[:, None, None, :])            # (ne, nmax, 2, 2)
    uve = camera.plane_to_pixel(ends.reshape(-1, 2) * flip).reshape(ne, nmax, 2, 2)
    uve = uve - np.asarray(levels[3], float)                  # ROI pixel coordinates
    w = ((t - t[0]) / (t[-1] - t[0]))[None, None, :, None]
    uv = uve[:, :, :1] + w * (uve[:, :, 1:] - uve[:, :, :1])                    # (ne, nmax, nt, 2)
    f = _sample(img, uv)                                                        # (ne, nmax, nt)
    nend = max(2, int(round(1.0 / step_px)))
    lo = f[..., :nend].mean(-1)
    hi = f[..., -nend:].mean(-1)
    fgL, bgL, fac = levels[:3]
    small = (uv[:, :, nt // 2] + 0.5) / fac - 0.5
    mid = 0.5 * (_sample(fgL, small) + _sample(bgL, small))
    use = (np.arange(nmax)[None, :] < ns[:, None]) & np.isfinite(f).all(-1) & np.isfinite(mid) \
        & (np.abs(hi - lo) > 0.4 * contrast)
    g = (f - mid[..., None]) * np.sign(hi - lo)[..., None]
    pos = g > 0
    ch = pos[..., 1:] != pos[..., :-1]                                          # (ne, nmax, nt-1)
    dist = np.where(ch, np.abs(np.arange(nt - 1) + 0.5 - nt // 2), np.inf)
    k = np.argmin(dist, axis=-1)
    dsort = np.sort(dist, axis=-1)
    first = dsort[..., 0]
    second = dsort[..., 1] if nt > 2 else np.full(first.shape, np.inf)
    use &= np.isfinite(first) & ~(second < 2.0 / step_px)                     # noisy: two crossings close by
    g0 = np.take_along_axis(g, k[..., None], -1)[..., 0]
    g1 = np.take_along_axis(g, (k + 1)[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        tt = t[k] + (t[1] - t[0]) * g0 / (g0 - g1)
    X = C[:, None, :] + s[None, :, None] * E[:, None, :] + tt[..., None] * N[:, None, :]
    for i in range(ne):
        out[i] = X[i][use[i]]
    return out


def _level_maps(img, obj, erode_px, sigma_px, factor):
    """Smooth maps of the local object and background levels (masked Gaussian averages, 1/factor scale)."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * erode_px + 1, 2 * erode_px + 1))
    fg = cv2.erode(obj, k).astype(np.float32)
    bg = cv2.erode((1 - obj).astype(np.uint8), k).astype(np.float32)
    H, W = img.shape
    size = (max(1, W // factor), max(1, H // factor))
    fac = W / size[0]
    out = []
    for mk in (fg, bg):
        a = cv2.resize(img * mk, size, interpolation=cv2.INTER_AREA)
        b = cv2.resize(mk, size, interpolation=cv2.INTER_AREA)
        s = sigma_px / fac
        a = cv2.GaussianBlur(a, (0, 0), s)
        b = cv2.GaussianBlur(b, (0, 0), s)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.where(b > 1e-3, a / np.maximum(b, 1e-12), np.nan).astype(np.float32))
    return out[0], out[1], fac


def _fit_line(P):
    """Total least squares line: (centroid, unit direction, signed residuals).

    The direction is the principal axis of the 2×2 scatter matrix, in closed
    form (``2α = atan2(2 s_xy, s_xx − s_yy)``): the same line as an SVD of the
    centred points, several times cheaper for the ~1000 small fits per image.
    """
    cen = P.mean(0)
    Q = P - cen
    sxx = float(Q[:, 0] @ Q[:, 0])
    syy = float(Q[:, 1] @ Q[:, 1])
    sxy = float(Q[:, 0] @ Q[:, 1])
    a = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    d = np.array([math.cos(a), math.sin(a)])
    res = Q @ np.array([-d[1], d[0]])
    return cen, d, res


def _robust_line(P, k=3.0):
    cen, d, res = _fit_line(P)
    ar = np.abs(res)                                # TLS residuals have zero mean
    mad = 1.4826 * np.partition(ar, len(ar) // 2)[len(ar) // 2]
    keep = np.abs(res) <= max(k * mad, 1e-12)
    if keep.sum() >= 3 and keep.sum() < len(P):
        P = P[keep]
        cen, d, res = _fit_line(P)
    return cen, d, res, P


def _intersect(c1, d1, c2, d2):
    det = d2[0] * d1[1] - d1[0] * d2[1]             # det [d1, -d2]
    if abs(det) < 1e-6:
        return None
    r = c2 - c1
    s = (d2[0] * r[1] - r[0] * d2[1]) / det          # Cramer's rule for s d1 - t d2 = r
    return c1 + s * d1


def _refine_corners(img, levels, camera, flip, C0, A, B, px_m, *, contrast, profile_half_px, profile_step_px,
                    edge_skip_px, edge_len, sample_step_px, iterations, sigma_corr_px):
    """Corners as intersections of the two edge lines (neighbour corners A, B), flipped plane frame [m].

    Returns one entry per corner: None (not enough edge) or
    (point [m], sigma [m], n1, n2, rms1 [m], rms2 [m]).
    """
    nc = len(C0)
    if nc == 0:
        return []
    C = C0.copy()
    E1 = (A - C) / np.linalg.norm(A - C, axis=1, keepdims=True)
    E2 = (B - C) / np.linalg.norm(B - C, axis=1, keepdims=True)
    L1, L2 = np.linalg.norm(A - C, axis=1), np.linalg.norm(B - C, axis=1)
    skip = edge_skip_px * px_m
    alive = np.ones(nc, bool)
    fits = [None] * nc
    for _ in range(max(1, iterations)):
        E = np.concatenate([E1, E2])
        N = np.stack([-E[:, 1], E[:, 0]], axis=1)
        s_to = np.minimum(np.concatenate([L1, L2]) - skip, edge_len)
        P = _edge_crossings(img, levels, camera, flip, np.concatenate([C, C]), E, N, skip, s_to, px_m,
                            profile_half_px, profile_step_px, sample_step_px, contrast)
        for i in range(nc):
            if not alive[i]:
                continue
            P1, P2 = P[i], P[nc + i]
            if len(P1) < 3 or len(P2) < 3:
                alive[i] = False
                continue
            c1, d1, r1, P1 = _robust_line(P1)
            c2, d2, r2, P2 = _robust_line(P2)
            if np.dot(d1, E1[i]) < 0:
                d1 = -d1
            if np.dot(d2, E2[i]) < 0:
                d2 = -d2
            x = _intersect(c1, d1, c2, d2)
            if x is None or np.linalg.norm(x - C0[i]) > 10 * px_m:
                alive[i] = False
                continue
            C[i], E1[i], E2[i] = x, d1, d2
            fits[i] = (c1, d1, r1, P1, c2, d2, r2, P2)
    corr = math.sqrt(max(sigma_corr_px / sample_step_px, 1.0))

    def off_sigma(c, cen, d, res, P):
        n = len(P)
        s = (P - cen) @ d
        s_c = (c - cen) @ d
        rv = np.sum(res ** 2) / max(n - 2, 1)
        return math.sqrt(rv * (1.0 / n + s_c ** 2 / max(np.sum(s ** 2), 1e-30)))

    out = []
    for i in range(nc):
        if not alive[i]:
            out.append(None)
            continue
        c1, d1, r1, P1, c2, d2, r2, P2 = fits[i]
        sin = abs(d1[0] * d2[1] - d1[1] * d2[0])
        # crossings spaced sample_step_px apart are correlated over about sigma_corr_px (blur + smoothing)
        sigma = corr * math.hypot(off_sigma(C[i], c1, d1, r1, P1), off_sigma(C[i], c2, d2, r2, P2)) / max(sin, 0.2)
        out.append((C[i].copy(), sigma, len(P1), len(P2), float(np.sqrt(np.mean(r1 ** 2))),
                    float(np.sqrt(np.mean(r2 ** 2)))))
    return out


def detections_table(sample, det: Detection):
    """Rows of ``detections.csv`` (data-format.md) for one sample.

    Returns
    -------
    pandas.DataFrame with columns sample, point, x_mm, y_mm, u_px, v_px, sigma_mm, status
    """
    import pandas as pd

    m = len(det.status)
    return pd.DataFrame({
        "sample": np.full(m, sample), "point": np.arange(1, m + 1),
        "x_mm": det.points[:, 0] * 1e3, "y_mm": det.points[:, 1] * 1e3,
        "u_px": det.points_px[:, 0], "v_px": det.points_px[:, 1],
        "sigma_mm": det.sigma * 1e3, "status": list(det.status)})


def draw_overlay(image, det: Detection, *, scale: float = 1.0) -> np.ndarray:
    """An overlay (Fig. 12 style): the silhouette outline and numbered corners coloured by status (BGR uint8)."""
    g = _to_float_gray(image)
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
    return img
