"""The detector's stages run in order for one image at one scale (see the package docstring)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d

from ...physics.geometry import notch_layout
from .base import find_base, holder_masks, raw_base_corners
from .chain import ChainTolerance
from .corners import base_specs, slot_specs, tip_specs
from .dims import slot_depths, slot_widths
from .lines import unit
from .numbering import ChainInput, number_slots, orient_corner_pair
from .outline import (bridge_slots, corner_window, crop_region, hole_ends, raw_mouth_corners, slot_mouths, turn_angles,
                      turn_peaks)
from .plane import PlaneInput, finish
from .refine import CornerSpecs, ProfileLayout, refine_pass
from .result import Detection, empty_detection

__all__ = ["Crop", "Located", "Parsed", "PlaneInput", "Refinement", "Setup", "link_tolerance", "locate",
           "merge_plane_inputs", "refine_and_finish", "refine_corners"]


@dataclass(frozen=True)
class Setup:
    """What every stage of one detection at one scale knows: the camera, the tube, the options, the scale.

    Attributes
    ----------
    camera : CameraModel or DiameterScale
        Maps pixels to the plane.
    geom : Geometry
    opts : DetectorOptions
    f : int
        Block-averaging factor of the working copy.
    px_per_m : float
        Image scale in the plane [px/m].
    sgn : float
        Orientation sign of the outline (object on the left of the traversal when +1).
    base : str or None
        The image side the base is known to point to (None: found).
    """

    camera: object
    geom: object
    opts: object
    f: int
    px_per_m: float
    sgn: float
    base: str | None = None

    @property
    def low_m(self) -> float:
        """Size of one working-copy pixel in the plane [m]."""
        return self.f / self.px_per_m


@dataclass(frozen=True)
class Crop:
    """One cropped working-copy silhouette and how its slots are bridged (:func:`locate` -> :func:`_parse`).

    Attributes
    ----------
    roi : ndarray (h, w) bool
        The silhouette's box on the working copy.
    offset : (int, int)
        Its position on the working copy [low-res px].
    shape : (int, int)
        The working copy's shape (rows, cols).
    r_close : int
        Radius of the closing that bridges the slots [low-res px].
    slot_area : float
        A slot's expected area [low-res px²].
    holders : (ndarray, ndarray)
        The grown and strict holder masks on ``roi``.
    gray : ndarray (h, w) or None
        The working copy's intensities on ``roi`` (which side of a hole is its mouth).
    dark : bool
        The object is darker than the background.
    """

    roi: np.ndarray
    offset: tuple
    shape: tuple
    r_close: int
    slot_area: float
    holders: tuple
    gray: np.ndarray | None = None
    dark: bool = True


@dataclass(frozen=True)
class Parsed:
    """One cropped silhouette parsed (:func:`_parse`): its bridged outline, base end, slot numbers.

    Attributes
    ----------
    ol : Outline
    be : BaseEnd
    num : Numbering
    mouths : dict
        Slot label -> (first, last, bridged) outline indices.
    raw : (int or None, int or None) or None
        The base corners on the unbridged outline.
    full : callable
        Low-res crop coordinates -> full-resolution pixels.
    contour_px : ndarray (N, 2)
        The bridged outline [px].
    rawc : dict
        Slot label -> its outer corners on the unbridged outline.
    """

    ol: object
    be: object
    num: object
    mouths: dict
    raw: tuple | None
    full: object
    contour_px: np.ndarray
    rawc: dict

    @property
    def n_found(self) -> int:
        """Slots numbered, and 1 for the tip."""
        return len(self.num.right) + len(self.num.left) + (self.num.tip is not None)


@dataclass(frozen=True)
class Located:
    """What stages 2-4 hand to the refinement (:func:`locate`).

    Attributes
    ----------
    specs : list of CornerSpec
        The corners to refine, with their first estimates on the working copy.
    contour_px : ndarray (N, 2)
        The bridged outline [px] (overlays).
    status : list of str (m,)
    messages : list of str
    side : str
        The image side the base points to.
    full : callable
        Low-res crop coordinates -> full-resolution pixels.
    tube_px : ndarray (T, 2)
        The tube's part of the outline [px] (diameter stations).
    confirm_width : bool
        Slots numbered without the tip (``Numbering.tipless``): each corner's link must be 2R wide.
    """

    specs: list
    contour_px: np.ndarray
    status: list
    messages: list
    side: str
    full: object
    tube_px: np.ndarray
    confirm_width: bool = False

    @property
    def points(self) -> set:
        """The point indices of the located corners."""
        return {s.point for s in self.specs}


@dataclass
class Refinement:
    """Stage 5's outcome for K corners (:func:`refine_corners`).

    Attributes
    ----------
    pidx : ndarray (K,) int
        Point index of each corner.
    C, Xi : ndarray (K, 2)
        Raw and ideal (undistorted) corners [px].
    cov : ndarray (K, 2, 2)
        Reported covariance of the ideal corners [px²] (before ``sigma_inflation``).
    ok : ndarray (K,) bool
    shift : ndarray (K,)
        How far each corner moved during refinement [px].
    blur : float
        Edge blur σ [px].
    sig_px : ndarray (K,)
        The fit's standard uncertainty (inflated) [px]: decides ``ambiguous``.
    specs : CornerSpecs
    img, off : the image region refined and its offset (u0, v0) [px]
    kf : float
        Profile length factor.
    plane_input : PlaneInput or None
        Set by :func:`refine_and_finish`.
    wide : ndarray (K,) bool or None
        Corners with an edge too wide for one step (:func:`.refine.wide_edges`): ambiguous.
    """

    pidx: np.ndarray
    C: np.ndarray
    Xi: np.ndarray
    cov: np.ndarray
    ok: np.ndarray
    shift: np.ndarray
    blur: float
    sig_px: np.ndarray
    specs: CornerSpecs
    img: np.ndarray
    off: np.ndarray
    kf: float
    plane_input: PlaneInput | None = None
    wide: np.ndarray | None = None


def _one_sided_holes(ol, mouths, be, side: int, *, max_wall: float) -> dict:
    """A one-sided tube's slots all open on one side: a hole (a slot closed at its mouth) takes the end of
    its axis on that side of the tube (the right side comes first after the base, anticlockwise), whatever
    the light says (a thin backbone next to a wide wedge can look more open than a closed mouth)."""
    N = len(ol.contour)
    pos = lambda i: (i - be.i_right) % N
    out = dict(mouths)
    for s, (i0, _, bridged) in mouths.items():
        if bridged:
            continue
        ends = [e[2] for e in hole_ends(ol, s, max_wall=max_wall)]
        if len(ends) == 2:
            i = min(ends, key=pos) if side > 0 else max(ends, key=pos)
            out[s] = (i, i, False)
    return out


def _chain_input(ol, mouths, rawc, raw, plane_px, setup: Setup, *, to_plane) -> ChainInput:
    """The slot candidates' outer corners and the base corners in the plane (low-res px), and the chain's
    tolerances (options ``chain_rel_tol``, ``chain_abs_w``, ``chain_abs_px``, ``chain_play``)."""
    geom, opts, low_m = setup.geom, setup.opts, setup.low_m
    cnt, mcnt = ol.contour, ol.raw_contour
    N = len(cnt)
    w = slot_widths(geom)
    pts, slack = [], {}
    for s, (i0, i1, bridged) in mouths.items():
        if s in rawc:
            pts += [mcnt[rawc[s][0]], mcnt[rawc[s][1]]]
        elif bridged:
            pts += [cnt[(i0 - 1) % N], cnt[(i1 + 1) % N]]
        else:                                    # a closed mouth: one point for both corners
            pts += [cnt[i0], cnt[i0]]
            slack[s] = 0.5 * float(w.max()) / low_m
    ends = [None if raw is None or raw[e] is None else mcnt[raw[e]] for e in (0, 1)]
    pts += [e for e in ends if e is not None]
    plane = to_plane(np.array(pts, float).reshape(-1, 2))                                # one call for all
    corners = {s: (plane[2 * q], plane[2 * q + 1]) for q, s in enumerate(mouths)}
    rest = iter(plane[2 * len(mouths):])
    base = tuple(None if e is None else next(rest) for e in ends)
    tol = ChainTolerance(opts.chain_rel_tol, max(opts.chain_abs_w * float(w.min()) / low_m, opts.chain_abs_px),
                         opts.chain_play)
    return ChainInput(corners, slack, base, plane_px, low_m, tol)


def _parse(crop: Crop, setup: Setup, *, exclude_holder: bool) -> Parsed | Detection:
    """Bridge, base end, slot numbering on one cropped silhouette: Parsed, or the Detection of a failure."""
    camera, geom, opts, f, low_m, sgn = setup.camera, setup.geom, setup.opts, setup.f, setup.low_m, setup.sgn
    r_close, small_shape, gray, dark = crop.r_close, crop.shape, crop.gray, crop.dark
    lay = notch_layout(geom)
    m = lay.n_points
    R_lo = geom.outer_radius / low_m
    holder, strict = crop.holders
    ol = bridge_slots(crop.roi, crop.offset, small_shape, r_close=r_close, slot_area=crop.slot_area,
                      slot_area_range=opts.slot_area_range, sgn=sgn, holder=strict if exclude_holder else None,
                      holder_strict=strict)
    if ol is None:
        return empty_detection(m, "no_manipulator", "no manipulator outline")
    X0, Y0 = ol.offset
    full = lambda p: (np.asarray(p, float) + [X0, Y0]) * f + (f - 1) / 2.0     # low-res box -> px
    cnt = ol.contour
    contour_px = full(cnt)
    plane_px = camera.pixel_to_plane(contour_px) / low_m
    dist = lambda i, j: float(np.linalg.norm(plane_px[i] - plane_px[j]))
    mouths = slot_mouths(ol, max_wall=0.5 * R_lo, gray=gray, dark=dark)
    be, why = find_base(ol, (holder, strict), R_lo=R_lo, dist=dist, sgn=sgn, min_tube_run_R=opts.min_tube_run_R,
                        min_base_run_R=opts.min_base_run_R, corner_turn_deg=opts.corner_turn_deg,
                        pair_tol=opts.pair_tol, base=setup.base, mouth_idx=[v[0] for v in mouths.values()])
    if be is None:
        return empty_detection(m, "partial", why, contour_px)
    if be.kind == "corners":
        be = orient_corner_pair(be, mouths, cnt)
    if len(set(geom.slot_sides)) == 1:
        mouths = _one_sided_holes(ol, mouths, be, geom.slot_sides[0], max_wall=0.5 * R_lo)
    raw = None
    hs, ws = small_shape
    at_border = lambda xy: min(xy[0] + X0, xy[1] + Y0, ws - 1 - xy[0] - X0, hs - 1 - xy[1] - Y0) <= 0.25 * R_lo + 2
    if be.kind != "border":
        pdist = lambda a, b: float(np.linalg.norm(np.diff(camera.pixel_to_plane(full(np.array([a, b]))),
                                                          axis=0))) / low_m
        grow = (math.sqrt(2) - 1) * opts.holder_width_factor * R_lo + 2       # the holder mask's regrowth
        for ends, search in (((be.i_right, be.i_left), 1.5 * r_close + 3),
                             ((be.i_right_wide, be.i_left_wide), 1.5 * r_close + 3 + grow)):
            found = raw_base_corners(ol.raw_contour, cnt[ends[0]], cnt[ends[1]], search=search,
                                     k=max(4, int(0.25 * R_lo)), sgn=sgn, dist=pdist, pair_tol=opts.pair_tol,
                                     R_lo=R_lo, at_border=at_border)
            if found is not None and None not in found:
                raw = found
                break
            raw = raw or found                   # one corner, the other outside the image: if no pair is found
    k = corner_window(r_close, R_lo)
    near_border = maximum_filter1d(ol.on_border.astype(np.uint8), size=2 * k + 3, mode="wrap").astype(bool)
    convex = turn_peaks(turn_angles(cnt, k, sgn), k, math.radians(opts.corner_turn_deg), +1.0, exclude=near_border)
    w_lo = float(slot_widths(geom).min()) / low_m
    rawc = raw_mouth_corners(ol, mouths, k=max(3, min(int(0.25 * R_lo), int(0.3 * w_lo))), sgn=sgn)
    chain = _chain_input(ol, mouths, rawc, raw, plane_px, setup,
                         to_plane=lambda p: camera.pixel_to_plane(full(p)) / low_m)
    num = number_slots(cnt, ol.on_border, be, mouths, convex, geom, dist=dist, pair_tol=opts.pair_tol, chain=chain)
    if num.mirror_conflict:
        n_r = sum(1 for s in geom.slot_sides if s > 0)
        return empty_detection(
            m, "partial", f"the slot counts fit the opposite mirror flag ({n_r} right-side slots expected): "
                          "check `mirror` in experiment.toml", contour_px, status="ambiguous")
    return Parsed(ol, be, num, mouths, raw, full, contour_px, rawc)


def locate(region, box, small_shape, setup: Setup, *, small=None, dark=True) -> Located | Detection:
    """Stages 2-4 on the downsampled copy: outline, base end, numbering, first corner estimates.

    The slots are bridged with the holder left out of the closing (its
    fillets would reach a slot near the holder); where that numbers fewer
    slots (a holder barely wider than the tube, whose opening bites into
    the tube's base), with the holder in.

    Returns
    -------
    Located, or the Detection of a failure
    """
    geom, opts, sgn, low_m = setup.geom, setup.opts, setup.sgn, setup.low_m
    lay = notch_layout(geom)
    m = lay.n_points
    R = geom.outer_radius
    R_lo = R / low_m
    w_max = float(slot_widths(geom).max())
    slot_area = float(np.median(slot_widths(geom) * slot_depths(geom))) / low_m ** 2
    keep = (opts.slot_area_range[0] * slot_area, opts.slot_area_range[1] * slot_area)
    r_close = int(math.ceil(opts.close_slot_factor * w_max / low_m)) + 1
    roi, offset = crop_region(region, box, small_shape, r_close + 2, keep_holes=keep)
    strict, grown = holder_masks(roi, opts.holder_width_factor * R_lo)
    holders = (grown, strict)
    gray = None if small is None else small[offset[1]:offset[1] + roi.shape[0], offset[0]:offset[0] + roi.shape[1]]
    crop = Crop(roi, offset, small_shape, r_close, slot_area, holders, gray, dark)
    res = fail = None
    for exclude in ((True, False) if holders[1].any() else (False,)):
        got = _parse(crop, setup, exclude_holder=exclude)
        if isinstance(got, Detection):
            fail = fail or got                   # the first failure, where no variant parses
            continue
        if res is None or got.n_found > res.n_found:
            res = got
        if got.n_found == geom.n_joints + 1:
            break
    if res is None:
        return fail
    ol, be, num, mouths, raw, full = res.ol, res.be, res.num, res.mouths, res.raw, res.full
    cnt = ol.contour
    index = {(lay.kind[i], int(lay.joint[i]), int(lay.side[i])): i for i in range(m)}
    specs = []
    if raw is not None:
        # the holder face searched beside a base corner: up to R (less on a narrow mount)
        face_len = R if geom.mount_half_width is None else min(geom.mount_half_width - R, R)
        specs += base_specs(ol.raw_contour, raw[0], raw[1], sgn=sgn, index=index, geom=geom, low_m=low_m,
                            face_len=face_len)
    else:
        num.messages.insert(0, "base corners hidden: the tube enters from the " +
                            ("image border" if be.kind == "border" else "holder without a corner at the base edge"))
    if num.tip is not None:
        specs += tip_specs(cnt, num.tip, index=index, geom=geom, low_m=low_m)
    rawc = res.rawc
    specs += slot_specs(cnt, ol.raw_contour, ((num.right, +1), (num.left, -1)), mouths, sgn=sgn, index=index,
                        geom=geom, low_m=low_m, raw_corners=rawc)
    tube = (np.arange(len(cnt)) - be.i_right) % len(cnt) <= (be.i_left - be.i_right) % len(cnt)
    return Located(specs, res.contour_px, num.status, num.messages, be.side, full, res.contour_px[tube], num.tipless)


def _roi(gray, C, Din, Dout, Lin, Lout, extra, margin):
    """A region of the full image holding every corner's edges (and ``extra`` points) plus ``margin``."""
    H, W = gray.shape
    pts = np.concatenate([C, C - Din * Lin[:, None], C + Dout * Lout[:, None], extra])
    pts = pts[np.isfinite(pts).all(1)]
    u0 = max(int(pts[:, 0].min() - margin), 0)
    v0 = max(int(pts[:, 1].min() - margin), 0)
    u1 = min(int(pts[:, 0].max() + margin) + 1, W)
    v1 = min(int(pts[:, 1].max() + margin) + 1, H)
    return np.ascontiguousarray(gray[v0:v1, u0:u1], dtype=np.float32), np.array([u0, v0], float)


def _curved_edges(pidx, geom, specs) -> np.ndarray:
    """(2K,) bool: the edges that are circular faces of the tube (slot faces, the tip face)."""
    lay = notch_layout(geom)
    K = len(specs)
    out = np.concatenate([[s.face_in for s in specs], [s.face_out for s in specs]]).astype(bool)
    for k, i in enumerate(pidx):
        if lay.kind[i] == "tip":              # tip-right: the outgoing edge is the tip face; tip-left: incoming
            out[K + k if lay.side[i] > 0 else k] = True
    return out


def _holder_faces(pidx, geom) -> np.ndarray:
    """(2K,) bool: the edges along the holder's face (base-right: incoming, base-left: outgoing)."""
    lay = notch_layout(geom)
    K = len(pidx)
    out = np.zeros(2 * K, bool)
    for k, i in enumerate(pidx):
        if lay.kind[i] == "base":
            out[k if lay.side[i] > 0 else K + k] = True
    return out


def _partners(pidx, geom) -> np.ndarray:
    """(K,) index of the corner on the same slot (or the other tip corner), -1 where it is not refined."""
    lay = notch_layout(geom)
    out = np.full(len(pidx), -1)
    seen = {}
    for a, i in enumerate(pidx):
        if lay.kind[i] == "base":
            continue
        key = ("tip", 0, 0) if lay.kind[i] == "tip" else ("slot", int(lay.joint[i]), int(lay.side[i]))
        if key in seen:
            out[a], out[seen[key]] = seen[key], a
        else:
            seen[key] = a
    return out


def refine_corners(gray, specs, setup: Setup, *, full, contrast, extra_px=None):
    """Stage 5 for all corners: first pass with long profiles, then passes sized by the measured blur.

    Returns
    -------
    Refinement
    """
    camera, geom, opts, px_per_m, sgn = setup.camera, setup.geom, setup.opts, setup.px_per_m, setup.sgn
    kf = max(1.0, setup.f / 2.0)
    pidx = np.array([s.point for s in specs])
    sp = CornerSpecs(full(np.array([s.xy for s in specs])), unit(np.array([s.d_in for s in specs])),
                     unit(np.array([s.d_out for s in specs])), np.array([s.len_in for s in specs]) * px_per_m,
                     np.array([s.len_out for s in specs]) * px_per_m,
                     np.concatenate([[s.face_in for s in specs], [s.face_out for s in specs]]).astype(bool),
                     _curved_edges(pidx, geom, specs), _partners(pidx, geom), _holder_faces(pidx, geom))
    radius_px = geom.outer_radius * px_per_m
    C0 = sp.C.copy()
    margin = 2 * max(opts.stage1_half_px, opts.stage1_face_px) * kf + 10
    extra = np.zeros((0, 2)) if extra_px is None else extra_px
    img, off = _roi(gray, sp.C, sp.Din, sp.Dout, sp.Lin, sp.Lout, extra, margin)
    bl = 1.0
    for it in range(1 + opts.iterations):
        if it == 0:
            s0, s_end, h, lim = 5.0 * kf, 3.0, opts.stage1_half_px * kf, 0.25
            h_face = opts.stage1_face_px * kf
        else:
            s0, s_end, h, lim = max(3.0, 3.0 * bl + 1.0), max(2.0, 2.5 * bl + 1.0), max(3.0, 3.0 * bl + 2.0), 0.1
            h_face = h
        res = refine_pass(img, off, camera, sp, sgn, ProfileLayout(s0, s_end, h, opts.profile_step_px, h_face),
                          lim=lim, min_points=opts.min_edge_points, contrast=contrast,
                          blur_prior=bl if it > 0 else math.nan,
                          radius_px=radius_px if it == opts.iterations else math.nan)
        if np.isfinite(res.blur):
            bl = res.blur
        sp.C = np.where(np.isfinite(res.C).all(1)[:, None], res.C, sp.C)
        sp.Din, sp.Dout = res.Din, res.Dout
    shift = np.linalg.norm(sp.C - C0, axis=1)
    sig_px = np.sqrt(np.maximum(np.trace(res.cov, axis1=1, axis2=2) / 2, 0)) * opts.sigma_inflation
    # the reported covariance adds what the edges' own profiles show (two rims of a face seen from the side)
    return Refinement(pidx, sp.C, res.X, res.cov + res.cov_sys / opts.sigma_inflation ** 2, res.ok, shift, bl,
                      sig_px, sp, img, off, kf, wide=res.wide)


def statuses(ref: Refinement, m, status, shape, opts):
    """Per-point status, raw px, ideal px and covariance from the refinement."""
    H, W = shape
    pts_px = np.full((m, 2), np.nan)
    ideal = np.full((m, 2), np.nan)
    cov = np.full((m, 2, 2), np.nan)
    C = ref.C
    inimg = np.all((C >= 0) & (C <= np.array([W - 1.0, H - 1.0])), axis=1)
    for q, i in enumerate(ref.pidx):
        if not ref.ok[q] or not inimg[q]:
            status[i] = "occluded"
        elif ref.shift[q] > opts.max_shift_px * ref.kf or not ref.sig_px[q] <= opts.max_sigma_px \
                or (ref.wide is not None and ref.wide[q]):
            status[i] = "ambiguous"
            pts_px[i] = C[q]
        else:
            status[i] = "ok"
            pts_px[i] = C[q]
            ideal[i] = ref.Xi[q]
            cov[i] = ref.cov[q] * opts.sigma_inflation ** 2
    return status, pts_px, ideal, cov


def link_widths(ref: Refinement, mask, f: int, camera, px_per_m: float, radius: float) -> np.ndarray:
    """The tube's width [m] beside each refined slot corner, across its outer edge, on a working-copy mask
    (K,); NaN for other corners.

    From the point ``0.3 R`` along the corner's outer edge away from its
    slot, along the normal into the object, to where the mask ends; mapped to
    the plane. A link is ``2R`` wide there: a corner whose outer edge is an
    edge inside the tube (the boundary of a highlight, where the limb mirrors
    the backdrop) finds it narrower.
    """
    sp = ref.specs
    K = len(ref.C)
    out = np.full(K, np.nan)
    h, w = mask.shape
    R_px = radius * px_per_m
    lo = lambda P: np.rint((np.asarray(P) - (f - 1) / 2.0) / f).astype(int)
    inside = lambda q: bool(0 <= q[0] < w and 0 <= q[1] < h and mask[q[1], q[0]])
    t = np.arange(0.3 * R_px, 3.0 * R_px, 0.5 * f)
    for k in range(K):
        if sp.face[k] == sp.face[K + k] or not np.all(np.isfinite(ref.C[k])):
            continue
        d = sp.Dout[k] if sp.face[k] else -sp.Din[k]
        P = ref.C[k] + 0.3 * R_px * d
        for n in (np.array([-d[1], d[0]]), np.array([d[1], -d[0]])):
            if not inside(lo(P + 0.3 * R_px * n)):
                continue
            ray = lo(P[None, :] + t[:, None] * n[None, :])
            hit = [j for j, q in enumerate(ray) if not inside(q)]
            if hit:
                ends = camera.pixel_to_plane(np.array([P, P + t[hit[0]] * n]))
                out[k] = float(np.linalg.norm(ends[1] - ends[0]))
            break
    return out


def link_tolerance(geom, opts):
    """(relative, absolute [m]) tolerance of the rigid-link check, or None at a rough scale (no checks)."""
    if not math.isfinite(opts.scale_tol):
        return None
    return opts.link_rel_tol, opts.link_abs_w * float(slot_widths(geom).min())


def refine_and_finish(gray, seg, ctx: Located, setup: Setup, *, extra=None, stations=None, width_mask=None):
    """Stages 5-6 for located corners (:func:`locate`). Returns (Detection, Refinement or None).

    ``width_mask``: a working-copy silhouette on which each ok slot corner's link must be ``2R`` wide
    (within ``width_tol``, :func:`link_widths`), else the corner is ambiguous."""
    camera, geom, opts = setup.camera, setup.geom, setup.opts
    m = geom.n_points
    extra = extra or {}
    status, msg = list(ctx.status), list(ctx.messages)
    ref = None
    pts_px, ideal, cov = np.full((m, 2), np.nan), np.full((m, 2), np.nan), np.full((m, 2, 2), np.nan)
    blur = math.nan
    specs = ctx.specs
    if specs:
        far = ctx.tube_px if stations else None
        ref = refine_corners(gray, specs, setup, full=ctx.full, contrast=seg.contrast, extra_px=far)
        status, pts_px, ideal, cov = statuses(ref, m, status, gray.shape, opts)
        if width_mask is not None:
            wid = link_widths(ref, width_mask, setup.f, camera, setup.px_per_m, geom.outer_radius)
            for k in np.nonzero(np.abs(wid / (2 * geom.outer_radius) - 1) > opts.width_tol)[0]:
                i = ref.pidx[k]
                if status[i] == "ok":
                    status[i] = "ambiguous"
                    ideal[i], cov[i] = np.nan, np.nan
        blur = ref.blur
        ref.plane_input = PlaneInput(pts_px.copy(), ideal.copy(), cov.copy(), list(status), list(msg), blur,
                                     ctx.contour_px, ctx.side)
    det = finish(camera, geom, PlaneInput(pts_px, ideal, cov, status, msg, blur, ctx.contour_px, ctx.side),
                 scale_tol=opts.scale_tol, base_edge_tol=opts.base_edge_tol, link_tol=link_tolerance(geom, opts),
                 **extra)
    return det, ref



def merge_plane_inputs(inputs, names, *, agree_px: float) -> PlaneInput:
    """The refined corners of several silhouette variants, point by point (each variant numbers each side of
    the tube on its own evidence: its base or tip corner agrees with that side's slots).

    A point ``ok`` on one variant is taken from it; ``ok`` on several, from the one with the smallest
    covariance when all put it within ``agree_px`` [px] of each other, else it is ``ambiguous`` (two
    variants gave that number to different corners: neither is trusted). A point ``ok`` nowhere keeps the
    first variant's status (``ambiguous`` from another where the first has it ``occluded``). The overlay's
    outline, the base side and the blur are the first variant's.

    Parameters
    ----------
    inputs : list of PlaneInput
        One per variant, the first the variant that located the most corners.
    names : list of str
        The variants' names (the message says which gave what).
    agree_px : float
        Largest distance between two variants' positions of one corner [px].

    Returns
    -------
    PlaneInput
    """
    first = inputs[0]
    pts_px, ideal, cov = first.pts_px.copy(), first.ideal.copy(), first.cov.copy()
    status = list(first.status)
    msg = list(first.messages)
    taken, disputed = {}, []
    for i in range(len(status)):
        oks = [k for k, p in enumerate(inputs) if p.status[i] == "ok"]
        if not oks:
            amb = [k for k, p in enumerate(inputs) if p.status[i] == "ambiguous"]
            if status[i] == "occluded" and amb:
                status[i], pts_px[i] = "ambiguous", inputs[amb[0]].pts_px[i]
            continue
        P = np.array([inputs[k].pts_px[i] for k in oks])
        if np.max(np.linalg.norm(P[:, None] - P[None], axis=2)) > agree_px:
            status[i], pts_px[i], ideal[i], cov[i] = "ambiguous", P[0], np.nan, np.nan
            disputed.append(i)
            continue
        k = min(oks, key=lambda q: float(np.trace(inputs[q].cov[i])))
        status[i], pts_px[i], ideal[i], cov[i] = "ok", inputs[k].pts_px[i], inputs[k].ideal[i], inputs[k].cov[i]
        if k:
            taken.setdefault(names[k], []).append(i + 1)
    for name, pts in taken.items():
        msg.append(f"points {', '.join(map(str, pts))} from the {name} silhouette")
    if disputed:
        msg.append(f"points {', '.join(str(i + 1) for i in disputed)} are placed differently by two silhouettes: "
                   "not used")
    return PlaneInput(pts_px, ideal, cov, status, msg, first.blur, first.contour_px, first.side)
