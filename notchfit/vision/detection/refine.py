"""Stage 5: sub-pixel corners from straight edges (edge profiles -> 50 % crossings -> line fits).

For every corner, intensity profiles across each of the two edges that meet
there (bilinear samples, one ``cv2.remap`` for all corners), the 50 %
crossing between the edge's object and background levels, the crossings
undistorted, a robust total-least-squares line per edge, the two lines
intersected. Profiles whose background side is not reached (a slot face
next to a nearly closed mouth) are dropped, so a slot face is extrapolated
from its open part. The corner covariance follows from the two fits'
residuals. This is about 30x more accurate than ``cv2.cornerSubPix`` on
blurred L-corners (the project's rendering notes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ._kernels import profile_crossings, profile_levels, profile_maps
from .edges import Crossings, Profiles, choose_edges
from .faces import curved_face_corners, face_view_cov, straight_face_corners
from .lines import group_layout, group_median, line_pairs, robust_group_lines, unit
from .mouth import MouthView

__all__ = ["CornerLines", "CornerSpecs", "PassResult", "ProfileLayout", "Profiles", "corner_lines",
           "curved_face_corners", "edge_crossings", "edge_spread", "face_view_cov", "refine_pass", "sample_profiles",
           "wide_edges"]


@dataclass
class CornerSpecs:
    """Corners to refine (K of them), in raw image pixels.

    Attributes
    ----------
    C : ndarray (K, 2)
        Corner positions [px].
    Din, Dout : ndarray (K, 2)
        Unit directions of the incoming edge (travelling into the corner)
        and the outgoing edge (leaving it), along the outline.
    Lin, Lout : ndarray (K,)
        Usable straight length of each edge from the corner [px].
    face : ndarray (2K,) bool
        Edge e < K is corner e's incoming edge, e >= K its outgoing edge;
        True for slot faces (whose background is the slot).
    curved : ndarray (2K,) bool, optional
        Edges that are the tube's circular faces (slot faces, the tip face):
        seen a little from the side they are arcs of an ellipse that meets
        the outer edge tangentially (:func:`curved_face_corners`).
    partner : ndarray (K,) int, optional
        The slot's or the tip's other corner (-1: none).
    holder_face : ndarray (2K,) bool, optional
        Edges along a holder's face (the base corners'): their object side
        is the holder, whose shading and highlights are its own.
    outside : ndarray (K,) bool, optional
        Corners whose outer edge lies outside the silhouette (a polished limb
        that mirrors the backdrop, :func:`.subpixel.outer_offsets`): next to
        them a face's crossings are the boundary of that mirror image, so
        they cannot tell the face's arc (:func:`face_view_cov`'s ``assume``).
    """

    C: np.ndarray
    Din: np.ndarray
    Dout: np.ndarray
    Lin: np.ndarray
    Lout: np.ndarray
    face: np.ndarray
    curved: np.ndarray | None = None
    partner: np.ndarray | None = None
    holder_face: np.ndarray | None = None
    outside: np.ndarray | None = None


@dataclass(frozen=True)
class CornerLines:
    """Robust edge lines of K corners and their intersections (:func:`corner_lines`).

    Attributes
    ----------
    X : ndarray (K, 2)
        Corners [ideal px] (NaN where not ok).
    cov : ndarray (K, 2, 2)
        Their covariance [px²].
    ok : ndarray (K,) bool
    c, dd : ndarray (2K, 2)
        Every edge's line: centroid [px] and unit direction (edge e < K: corner e's incoming edge, else its
        outgoing edge).
    good_e : ndarray (2K,) bool
        Edges with enough points for a line.
    s2 : ndarray (2K,)
        Residual variance of each line before the noise floor [px²].
    cov_view : ndarray (K, 2, 2), optional
        Beyond the fits: the gap a slot bent shut leaves unresolved at its mouth [px²] (:mod:`.mouth`), the
        whole bulge of a face seen only far from its corner (:func:`.faces.far_line_corners`).
    """

    X: np.ndarray
    cov: np.ndarray
    ok: np.ndarray
    c: np.ndarray
    dd: np.ndarray
    good_e: np.ndarray
    s2: np.ndarray
    cov_view: np.ndarray | None = None


@dataclass(frozen=True)
class ProfileLayout:
    """Where the profiles of one refinement pass lie (:func:`sample_profiles`) [px].

    Attributes
    ----------
    s0, s_end : float
        Profiles from ``s0`` after the corner to ``s_end`` before the edge's end.
    h : float
        Half length of a profile.
    step : float
        Sample spacing along a profile.
    h_face : float or None
        Half length on slot faces (None: ``h``).
    """

    s0: float
    s_end: float
    h: float
    step: float
    h_face: float | None = None


@dataclass(frozen=True)
class PassResult:
    """One refinement pass's corners (:func:`refine_pass`).

    Attributes
    ----------
    C, X : ndarray (K, 2)
        Raw and ideal (undistorted) corners [px] (NaN where not ok).
    cov : ndarray (K, 2, 2)
        Covariance of the ideal corners from the fit [px²].
    ok : ndarray (K,) bool
    blur : float
        Edge blur σ [px] (NaN where not measured).
    Din, Dout : ndarray (K, 2)
        The incoming and outgoing edge directions for the next pass.
    cov_sys : ndarray (K, 2, 2)
        The covariance of the edges' own offsets (:func:`edge_spread`, :func:`face_view_cov`) to add to the
        reported one [px²].
    wide : ndarray (K,) bool, optional
        Corners with an edge whose profiles rise too much wider than the image's clean edges for one step
        (:func:`wide_edges`): where on that rise the edge lies is not measured.
    wide_edge : ndarray (2K,) bool, optional
        Those edges (edge e < K: corner e's incoming edge, else its outgoing edge).
    spread_edge : ndarray (2K,), optional
        The variance of each edge's offset that its profiles' rise shows (:func:`edge_spread`) [px²], part of
        ``cov_sys``.
    """

    C: np.ndarray
    X: np.ndarray
    cov: np.ndarray
    ok: np.ndarray
    blur: float
    Din: np.ndarray
    Dout: np.ndarray
    cov_sys: np.ndarray
    wide: np.ndarray | None = None
    wide_edge: np.ndarray | None = None
    spread_edge: np.ndarray | None = None


_MAP_WIDTH = 4096           # samples per row of the remap maps (OpenCV wants sides below 32767)


def sample_profiles(img, off, sp: CornerSpecs, sgn, layout: ProfileLayout, *, h_curved=0.0) -> Profiles | None:
    """Profiles every 1 px along each edge, from ``layout.s0`` px after the corner to ``layout.s_end`` px
    before its end; half length ``layout.h``, ``layout.h_face`` on slot faces, at least ``h_curved`` on
    curved edges (the arc of a face seen from the side leaves its chord)."""
    s0, s_end, h, step = layout.s0, layout.s_end, layout.h, layout.step
    h_face = h if layout.h_face is None else layout.h_face
    K = len(sp.C)
    E_dir = np.concatenate([-sp.Din, sp.Dout])
    E_trav = np.concatenate([sp.Din, sp.Dout])
    E_nrm = sgn * np.stack([E_trav[:, 1], -E_trav[:, 0]], axis=1)
    E_len = np.concatenate([sp.Lin, sp.Lout])
    E_C = np.concatenate([sp.C, sp.C])
    kt = np.where(sp.face, int(math.ceil(h_face / step)), int(math.ceil(h / step)))
    if sp.curved is not None and h_curved > 0:
        kt = np.where(sp.curved, np.maximum(kt, int(math.ceil(h_curved / step))), kt)
    n_t = int(kt.max())
    t = np.arange(-n_t, n_t + 1) * step
    n_s = np.maximum(np.floor(E_len - s_end - s0).astype(int) + 1, 0)
    e_idx = np.repeat(np.arange(2 * K), n_s)
    Np = len(e_idx)
    if Np == 0:
        return None
    s_val = s0 + (np.arange(Np) - np.repeat(np.cumsum(n_s) - n_s, n_s))
    base = E_C[e_idx] + s_val[:, None] * E_dir[e_idx] - off
    nrm = E_nrm[e_idx]
    kp = kt[e_idx]
    n_w = 2 * kp + 1
    mapx, mapy = profile_maps(base, nrm, t, kp, n_t, _MAP_WIDTH)
    prof = cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    return Profiles(prof.ravel()[:int(n_w.sum())], base, nrm, e_idx, t, kp, n_t, np.cumsum(n_w) - n_w)


def edge_crossings(pr: Profiles, face, contrast, *, lim, step, extrapolate=True, own_level=None,
                   band_tol: float = 0.15, holder_face=None):
    """50 % crossings of the profiles between per-edge object and background levels.

    Returns
    -------
    Crossings
        The rises are :func:`_rise_widths` of the profiles normalised to 0 on the object, 1 on the background.
    """
    K2 = len(face)
    K = K2 // 2
    prof, e_idx, kp, n_t, t = pr.values, pr.edge, pr.half, pr.n_t, pr.t
    rows = np.arange(len(e_idx))
    rise_step = step
    # a specular streak along the tube near its edge, brighter than the background (darker for a light
    # object), at the far end of the object side: the object's level is the most object-like part of that
    # side (3-sample mean) there
    cs = 1.0 if contrast > 0 else -1.0
    lo_v, hi_v, ext, least = profile_levels(prof, pr.start, kp, n_t, len(t), cs)
    banded = least < cs * hi_v - band_tol * abs(contrast)
    if holder_face is not None:
        banded &= ~holder_face[e_idx]                    # a holder's shading and highlights are its own
    lo_v = np.where(banded, cs * ext, lo_v)
    # levels from the profiles that span the edge; slot faces take their partner's (open background)
    span_ok = (lo_v - hi_v) * (1.0 / contrast) > 0.5
    by_edge = group_layout(e_idx, K2)                   # the profiles by edge, for every median below
    lo = group_median(np.where(span_ok, lo_v, np.nan), e_idx, K2, layout=by_edge)
    hi = group_median(np.where(span_ok, hi_v, np.nan), e_idx, K2, layout=by_edge)
    if extrapolate:
        # the object level's slope toward the edge (shading across a cylinder), from 2 px further in,
        # carried to the edge: the 50 % level is halfway between the levels *at* the edge
        step = t[1] - t[0]
        i2 = np.minimum(n_t - kp + int(round(2.0 / step)), n_t - 1)
        lo_w = 0.5 * (pr.at(rows, i2) + pr.at(rows, i2 + 1))
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = (lo_w - lo_v) / ((i2 - (n_t - kp)) * step)
        use = span_ok & np.isfinite(slope) & ~banded
        med = group_median(np.where(use, slope, np.nan), e_idx, K2, layout=by_edge)
        # only a slope the profiles agree on (3 standard errors of the median): flat levels stay exact
        mad = 1.4826 * group_median(np.where(use, np.abs(slope - med[e_idx]), np.nan), e_idx, K2, layout=by_edge)
        n_use = np.bincount(e_idx, use.astype(float), K2)
        sig = np.abs(med) > 3 * 1.2533 * mad / np.sqrt(np.maximum(n_use, 1))
        reach = np.full(K2, np.nan)
        reach[e_idx] = kp * step                 # every profile of an edge has the edge's half length
        lo_edge = lo + np.where(sig, np.nan_to_num(med), 0.0) * reach
    else:
        lo_edge = lo
    partner = np.concatenate([np.arange(K) + K, np.arange(K)])
    hi = np.where(face, hi[partner], hi)
    fp = face[e_idx]
    # a slot face's object level is its own (shading across the tube changes it along the face);
    # its background level is its partner's, whose background is open
    # a curved face (the tip face, across the tube's shading) also takes its own level, profile by profile
    fo = fp if own_level is None else (fp | own_level[e_idx])
    lo_p = np.where(fo, lo_v, np.where(face, lo[partner], lo)[e_idx])          # plateau: validity
    lo_c = np.where(fo, lo_v, np.where(face, lo_edge[partner], lo_edge)[e_idx])  # at the edge: crossing
    span = hi[e_idx] - lo_p
    with np.errstate(invalid="ignore", divide="ignore"):
        q_lo = (lo_v - lo_p) / span
        q_hi = (hi_v - lo_p) / span
    # the normalised profiles, their crossings nearest the centre (on a tie the first) and their rises
    order = np.argsort(np.abs(0.5 * (t[:-1] + t[1:])), kind="stable")
    n_fin, q_peak, tc, found, rise = profile_crossings(prof, pr.start, kp, lo_c, hi[e_idx] - lo_c, t, order,
                                                       step, rise_step)
    sel_ = span_ok & ~fp & np.isfinite(q_lo)
    sq = 1.4826 * float(np.median(np.abs(q_lo[sel_]))) if sel_.sum() >= 10 else 0.0
    lim = max(lim, 4.0 * sq)
    valid = (n_fin == 2 * kp + 1) & (np.abs(span) > 1e-6) & (np.abs(q_lo) < lim) & found & np.isfinite(tc)
    # a brighter band inside the object (a specular streak along the tube, near its edge) makes the far end
    # of the object side more background-like than its part next to the edge: that profile's level is not
    # the object's
    with np.errstate(invalid="ignore"):
        valid &= np.where(fp, q_peak > 1 - 0.5 * lim, np.abs(q_hi - 1) < lim)
    return Crossings(tc, valid, q_lo, rise)


def _rise_widths(qa, t, step) -> np.ndarray:
    """The 25 % -> 75 % rise of every profile [px] (NaN where it does not rise)."""
    rr = np.arange(len(qa))
    pos = []
    for lvl in (0.25, 0.75):
        with np.errstate(invalid="ignore"):
            i1 = np.argmax(qa >= lvl, axis=1)            # NaN (outside the window) is below every level
        i0 = np.maximum(i1 - 1, 0)
        a0, a1 = np.nan_to_num(qa[rr, i0], nan=-1.0), np.nan_to_num(qa[rr, i1], nan=-1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            pos.append(t[i0] + np.where(a1 > a0, (lvl - a0) / (a1 - a0), 0.0) * step)
    wd = pos[1] - pos[0]
    return np.where(np.isfinite(wd) & (wd > 0), wd, np.nan)


def edge_spread(qa, valid, t, step, edge, n_edges: int, *, min_excess: float = 1.25, widths=None,
                layout=None) -> np.ndarray:
    """Variance of each edge line's offset that its own profiles show beyond their noise [px²] (n_edges,).

    A face seen a little from the side shows two edges a few pixels apart (its
    near and far rims), a shadow or a reflection a second edge beside the
    first: the profiles' rise is wider than that of the image's clean edges.
    The 50 % crossing then lies anywhere between the two, an offset shared by
    every profile of the edge that no line fit averages away. Where an edge's
    median rise exceeds ``min_excess`` times the median over all edges, the
    excess width ``Δ = sqrt(rise² - rise_all²)`` is taken as the spread of
    two edges and ``Δ² / 12`` (a uniform offset over it) returned; 0 elsewhere.
    ``widths``: the valid profiles' rise widths when already measured (``qa``, the normalised profiles
    (Np, T), is then not read and may be None). ``layout``: :func:`.lines.group_layout` of ``edge``.
    """
    wd = np.full(len(valid), np.nan)
    wd[valid] = _rise_widths(qa[valid], t, step) if widths is None else widths
    per_edge = group_median(wd, edge, n_edges, layout=layout)
    fin = wd[np.isfinite(wd)]
    if len(fin) < 5:
        return np.zeros(n_edges)
    ref = float(np.median(fin))
    excess2 = np.where(per_edge > min_excess * ref, per_edge ** 2 - ref ** 2, 0.0)
    return np.nan_to_num(excess2, nan=0.0) / 12.0


def wide_edges(widths, edge, n_edges: int, *, max_spread: float = 12.0, quantile: float = 0.25,
               min_edges: int = 4, layout=None) -> np.ndarray:
    """(n_edges,) bool: edges whose profiles rise over a ramp, not a step: their median 25 % -> 75 % rise
    exceeds the image's sharp edges' by more than ``max_spread`` blur σ.

    A silhouette's edge (a limb, a face's rim) is as sharp as the optics
    make it; :func:`edge_spread` takes a rise a little wider than that as two
    steps (the rims of a face seen from the side) and widens the corner's σ.
    A rise many blur widths wider is shading, not an edge (a polished limb
    that mirrors the backdrop it stands against, the tube's dark body 15 px
    inside it): the 50 % crossing lies only where the levels put it, and the
    corner is not measured. The image's sharp edges are the ``quantile`` of
    the edges' median rises (ramps may be most of a silhouette's edges, not a
    quarter of them), σ = rise / 1.349; the excess is ``sqrt(rise² -
    rise_sharp²)``.

    Parameters
    ----------
    widths : ndarray (P,)
        The valid profiles' rises [px] (NaN where they do not rise); ``edge`` (P,) their edge
        (``layout``: its :func:`.lines.group_layout`, when already made).
    """
    per_edge = group_median(np.asarray(widths, float), edge, n_edges, layout=layout)
    fin = per_edge[np.isfinite(per_edge)]
    if len(fin) < min_edges:
        return np.zeros(n_edges, bool)
    sharp = float(np.quantile(fin, quantile))
    with np.errstate(invalid="ignore"):
        excess = np.sqrt(np.maximum(per_edge ** 2 - sharp ** 2, 0.0))
        return np.nan_to_num(excess, nan=0.0) > max_spread * sharp / 1.349


def edge_blur(qa, valid, t, step, widths=None) -> float:
    """Gaussian σ of the edges from the 25 % -> 75 % rise of valid profiles (1.349 σ) [px] (``widths``: the
    valid profiles' rises when already measured; ``qa`` is then not read and may be None)."""
    if valid.sum() < 5:
        return math.nan
    wd = _rise_widths(qa[valid], t, step) if widths is None else widths
    wd = wd[np.isfinite(wd)]
    return float(np.median(wd)) / 1.349 if len(wd) else math.nan


def corner_lines(pts, grp, K, *, min_points, s2_floor=0.0, s2_edge=None):
    """Robust edge lines per group and their pairwise intersections with covariance.

    ``s2_edge`` (2K,): a variance of each line's offset shared by all its
    points (:func:`edge_spread`), added as it is (no fit averages it away).

    Returns
    -------
    CornerLines
    """
    c, dd, n, s2_fit, stt, _ = robust_group_lines(pts, grp, 2 * K)
    s2 = np.maximum(s2_fit, s2_floor)
    good_e = (n >= min_points) & (stt > 0)
    k1, k2 = np.arange(K), np.arange(K) + K
    extra = (s2_edge[k1], s2_edge[k2]) if s2_edge is not None else (0.0, 0.0)
    X, cov, sin, det = line_pairs(c, dd, n, s2, stt, k1, k2, *extra)
    okc = good_e[k1] & good_e[k2] & (sin > 0.5) & (np.abs(det) > 1e-9)
    X[~okc] = np.nan
    cov[~okc] = np.nan
    return CornerLines(X, cov, okc, c, dd, good_e, s2_fit)


def _next_directions(camera, sp: CornerSpecs, c, dd, good_e, okc, Cn):
    """Raw-image edge directions for the next pass; a corner with one good line is put on it."""
    K = len(sp.C)
    k1, k2 = np.arange(K), np.arange(K) + K
    ge = np.nonzero(good_e)[0]
    draw_ = np.full((2 * K, 2), np.nan)
    craw = np.full((2 * K, 2), np.nan)
    if len(ge):
        ends = camera.distort_pixels(np.concatenate([c[ge] - 5 * dd[ge], c[ge] + 5 * dd[ge]]))
        draw_[ge] = unit(ends[len(ge):] - ends[:len(ge)])
        craw[ge] = 0.5 * (ends[len(ge):] + ends[:len(ge)])
    new = []
    for D_old, kk in ((sp.Din, k1), (sp.Dout, k2)):
        dn = draw_[kk]
        good = np.isfinite(dn).all(1)
        flip = np.where((dn * D_old).sum(1) < 0, -1.0, 1.0)
        new.append(np.where(good[:, None], dn * flip[:, None], D_old))
    # a link is a rigid rectangle: make a failed slot face perpendicular to the good line
    one = ~okc & (good_e[k1] ^ good_e[k2])
    for k in np.nonzero(one)[0]:
        g_e, b_e = (k1[k], k2[k]) if good_e[k1[k]] else (k2[k], k1[k])
        dg = draw_[g_e]
        Cn[k] = craw[g_e] + np.dot(sp.C[k] - craw[g_e], dg) * dg
        if sp.face[b_e]:
            D_b = new[0 if b_e < K else 1]
            perp = np.array([-dg[1], dg[0]])
            D_b[k] = perp if np.dot(perp, D_b[k]) >= 0 else -perp
    return new[0], new[1]


def _keep_consensus(ch, edge, valid, und, rises, lines, fit_args, blur):
    """The local edges keep the crossings that agree with one straight edge (:meth:`.edges.EdgeChoice.consensus`);
    the lines are fitted again (``fit_args``: :func:`corner_lines`' ``min_points`` and ``s2_floor``). Returns the
    valid profiles (Np,), their undistorted crossings and rises, and the lines."""
    keep = ch.consensus(und, edge, blur=blur, min_points=fit_args["min_points"])[valid]
    if keep.all():
        return valid, und, rises, lines
    valid = valid.copy()
    valid[np.nonzero(valid)[0][~keep]] = False
    und, rises = und[keep], rises[keep]
    return valid, und, rises, corner_lines(und, edge[valid], len(lines.X), **fit_args)


def _edge_offsets(und, edge, rises, lines: CornerLines, *, min_points, s2_floor, max_spread):
    """The covariance (K, 2, 2) [px²] of the offsets an edge's own profiles show (two rims, a shadow's edge:
    :func:`edge_spread`), to add to the reported uncertainty, not to the fit's (which decides whether the
    corner is found); the edges (2K,) bool too wide for one step (:func:`wide_edges`); and the edges' offset
    variances (2K,) [px²] (:func:`edge_spread`).
    ``und``, ``edge``, ``rises``: the valid crossings [px], their edges and their profiles' rises [px]."""
    K = len(lines.X)
    cov_sys = np.zeros((K, 2, 2))
    by_edge = group_layout(edge, 2 * K)
    s2_edge = edge_spread(None, np.ones(len(edge), bool), None, None, edge, 2 * K, widths=rises, layout=by_edge)
    w_e = wide_edges(rises, edge, 2 * K, max_spread=max_spread, layout=by_edge)
    if s2_edge.any():
        cov_sys = corner_lines(und, edge, K, min_points=min_points, s2_floor=s2_floor, s2_edge=s2_edge).cov - lines.cov
    return cov_sys, w_e, s2_edge


def refine_pass(img, off, camera, sp: CornerSpecs, sgn, layout: ProfileLayout, *, lim, min_points, contrast,
                blur_prior=math.nan, radius_px=math.nan, curved_reach: float = 0.12,
                arc_gate: float = 2.0, view_bias: float = 0.5, local_edges: bool = True, max_spread: float = 12.0,
                known_arc: bool = True):
    """One pass of edge-profile line fits for all corners at once.

    Parameters
    ----------
    img : ndarray (h, w) float32
        A region of the raw image; ``off`` = (u0, v0) its position [px].
    camera : CameraModel or DiameterScale
        Undistorts the crossings before the line fits.
    sp : CornerSpecs
    sgn : float
        Orientation sign (object on the left of the traversal when +1 ...).
    layout : ProfileLayout
    lim : float
        Plateau tolerance (normalised to the step).
    blur_prior : float
        Edge blur from a previous pass [px]; when given, the noise floor of
        the crossings follows from it and the object level is carried to the
        edge along its slope (shading).
    radius_px : float
        The tube's radius [ideal px]: with it, corners on the curved edges
        of ``sp.curved`` come from :func:`curved_face_corners`, whose
        profiles reach at least ``curved_reach`` R each way (an arc seen 7°
        from the side leaves its chord by 0.12 R). Only faces whose line fit
        leaves ``arc_gate`` times the straight edges' residual variance are
        fitted again as arcs. A curved face left a straight line adds
        :func:`face_view_cov` (``view_bias``) to the returned systematic
        covariance when the camera knows the plane's pose.
    known_arc : bool
        With a camera file, faces left straight take their view's arc (:func:`.faces.straight_face_corners`).
    local_edges : bool
        Edges the image-wide levels do not describe take each profile's own step (:func:`.edges.choose_edges`).
    max_spread : float
        On the last pass (``radius_px`` given), a corner with an edge whose rise exceeds the clean edges' by
        more than ``max_spread`` blur σ is flagged ``wide`` (:func:`wide_edges`).

    Returns
    -------
    PassResult
    """
    K = len(sp.C)
    s0, step = layout.s0, layout.step
    h_curved = curved_reach * radius_px if np.isfinite(radius_px) else 0.0
    pr = sample_profiles(img, off, sp, sgn, layout, h_curved=h_curved)
    nan = np.full((K, 2), np.nan)
    if pr is None:
        return PassResult(nan, nan.copy(), np.full((K, 2, 2), np.nan), np.zeros(K, bool), math.nan, sp.Din,
                          sp.Dout, np.zeros((K, 2, 2)))
    cr = edge_crossings(pr, sp.face, contrast, lim=lim, step=step, own_level=sp.curved,
                        holder_face=sp.holder_face, extrapolate=bool(np.isfinite(blur_prior)))
    if local_edges:
        # the edge model's hook: edges the image-wide levels do not describe take each profile's own step
        cr = ch = choose_edges(pr, 2 * K, cr, face=sp.face, contrast=contrast, blur0=blur_prior if np.isfinite(blur_prior) else 1.0)
    tc, valid, q_lo, rises = cr.tc, cr.valid, cr.noise, cr.rise
    fp = sp.face[pr.edge]
    rises = rises[valid]
    blur = edge_blur(None, valid & ~fp, pr.t, step, widths=rises[~fp[valid]])
    raw = pr.base[valid] + tc[valid, None] * pr.normal[valid] + off
    und = camera.undistort_pixels(raw)
    # floor on the crossing variance: image noise over the edge slope (a few crossings can scatter
    # less than the noise by chance, and their fit would then claim too much)
    plateau = valid & ~fp
    s2_floor = 0.0
    if plateau.sum() >= 10 and np.isfinite(blur_prior):
        sq = 1.4826 * float(np.median(np.abs(q_lo[plateau])))
        s2_floor = (sq * math.sqrt(2 * math.pi) * blur_prior) ** 2
    lines = corner_lines(und, pr.edge[valid], K, min_points=min_points, s2_floor=s2_floor)
    if local_edges and ch.local.any():
        valid, und, rises, lines = _keep_consensus(ch, pr.edge, valid, und, rises, lines,
                                                    {"min_points": min_points, "s2_floor": s2_floor},
                                                    blur_prior if np.isfinite(blur_prior) else blur)
    X, cov, okc, c, dd, good_e, s2_line = lines.X, lines.cov, lines.ok, lines.c, lines.dd, lines.good_e, lines.s2
    # the last pass's (the one whose corners are reported): what the edges' own profiles show
    cov_sys, wide, spread = _edge_offsets(und, pr.edge[valid], rises, lines, min_points=min_points, s2_floor=s2_floor,
                                          max_spread=max_spread) if np.isfinite(radius_px) else \
        (np.zeros((K, 2, 2)), np.zeros(2 * K, bool), np.zeros(2 * K))
    # an arc shows as a face line's residuals well above the straight edges' (the noise): faces that are
    # straight lines within the noise are not fitted again
    straight = good_e & ~sp.curved if sp.curved is not None else good_e
    noise2 = float(np.median(s2_line[straight])) if straight.any() else 0.0
    curved = None if sp.curved is None else sp.curved & (s2_line > arc_gate * max(noise2, s2_floor))
    if curved is not None and np.isfinite(radius_px) and sp.curved.any():
        arcs = curved_face_corners(und, pr.edge[valid], lines, sp.curved, fit=curved, radius_px=radius_px,
                                   s2_floor=s2_floor, min_points=min_points, start_px=s0, partner=sp.partner,
                                   view=MouthView(img, off, camera, blur, radius_px))
        okc = arcs.ok
        cov_sys = cov_sys if arcs.cov_view is None else cov_sys + arcs.cov_view
        X, cov, cov_face = straight_face_corners(camera, arcs, okc & np.all(arcs.X == X, axis=1), sp.curved,
                                                 und, pr.edge[valid], radius_px=radius_px, s2_floor=s2_floor,
                                                 min_points=min_points, start_px=s0, view_bias=view_bias,
                                                 outside=sp.outside, known_arc=known_arc)
        cov_sys = cov_sys + cov_face
    Cn = np.full((K, 2), np.nan)
    if okc.any():
        Cn[okc] = camera.distort_pixels(X[okc])
    Din, Dout = _next_directions(camera, sp, c, dd, good_e, okc, Cn)
    return PassResult(Cn, X, cov, okc, blur, Din, Dout, np.nan_to_num(cov_sys), wide[:K] | wide[K:], wide, spread)
