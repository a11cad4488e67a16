"""Stage 5 for all located corners at full resolution (:func:`refine_corners`): the refinement passes
(:func:`.refine.refine_pass`), each corner's status (:func:`statuses`), the tube's width beside it
(:func:`link_widths`) and the diameter stations next to it (:func:`edge_stations`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import ndimage

from ...physics.geometry import notch_layout
from .edges import dense_profiles
from .lines import unit
from .records import Refinement, Setup
from .refine import CornerSpecs, ProfileLayout, refine_pass, sample_profiles

__all__ = ["edge_stations", "holder_backdrops", "limb_edges", "link_widths", "outer_offsets", "outer_starts", "outer_step", "ray_exits", "refine_corners",
           "statuses", "unexplained_cov", "width_deficits"]


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


def _outward(sp: CornerSpecs, sgn) -> np.ndarray:
    """Unit normals (2K, 2) of every edge from the object to the background (edge e < K: corner e's incoming
    edge, else its outgoing edge), as the refinement's profiles run."""
    trav = np.concatenate([sp.Din, sp.Dout])
    return sgn * np.stack([trav[:, 1], -trav[:, 0]], axis=1)


def _edge_normals(nrm: np.ndarray, k: int, *, min_det: float = 0.5):
    """Corner ``k``'s two edge normals as the rows of a (2, 2) matrix (``nrm`` from :func:`_outward`), which
    maps a corner's move to its edges' offsets; None where the edges are too nearly parallel for the corner
    to follow them (|det| ≤ ``min_det``: less than 30° apart)."""
    A = np.stack([nrm[k], nrm[len(nrm) // 2 + k]])
    return A if abs(np.linalg.det(A)) > min_det else None


def limb_edges(sp: CornerSpecs) -> np.ndarray:
    """(2K,) bool: the corners' outer edges along the tube: not slot faces (their backdrop is the slot) nor
    a holder's face."""
    out = ~np.asarray(sp.face, bool)
    return out if sp.holder_face is None else out & ~sp.holder_face


def outer_offsets(img, off, sp: CornerSpecs, sgn, *, reach_px: float, s0: float, s_end: float = 3.0,
                  k_sig: float = 6.0, corr_px: float = 4.0, bg_frac: float = 0.35, min_profiles: int = 8,
                  step: float = 1.0, only=None) -> np.ndarray:
    """How far outside each outer edge of the silhouette the tube ends [px] (2K,), 0 where it is not seen.

    A silhouette is the tube's body against the backdrop; a polished limb
    mirrors the backdrop, so a strip along the outer edge (about 0.1-0.3 R,
    brighter, darker or as bright as the backdrop) is left out of it, and a
    shaded limb is left out the same way. Outward of the silhouette's edge,
    everything up to the backdrop is tube. Along a straight edge the mean of
    its profiles shows even a faint limb (the noise averages down over the
    edge's length): the backdrop level is the mean profile's median over its
    outer ``bg_frac`` of ``reach_px``, and the tube ends at the outermost
    sample nearer the silhouette whose mean departs from it by more than
    ``k_sig`` standard errors (the profiles' spread at that sample over
    ``sqrt(n / corr_px)``: neighbouring profiles share blur and a JPEG's
    blocks). That is the outer foot of the tube's last step, a blur width or
    two beyond its half-way point: a first estimate, which the refinement's
    first pass, with profiles several blur widths long, takes from there. An
    edge whose backdrop window itself is not flat (a grid line, a shadow's
    edge along it) gives 0. Only :func:`limb_edges` are searched.

    Parameters
    ----------
    img, off : the image region [image units] and its offset (u0, v0) [px].
    sp : CornerSpecs
        The corners' first estimates and edges [px].
    sgn : float
        Orientation sign of the outline (the profiles' normals point from the object to the background).
    reach_px : float
        How far outside the silhouette to look [px].
    s0, s_end : float
        The profiles start ``s0`` after the corner and end ``s_end`` before the edge's end [px].
    only : ndarray (2K,) bool, optional
        The edges to search (default every outer edge).
    """
    out = np.zeros(2 * len(sp.C))
    means = _edge_means(img, off, sp, sgn, only, ProfileLayout(s0, s_end, reach_px, step), corr_px=corr_px,
                        min_profiles=min_profiles)
    if means is None:
        return out
    edges, t, m, se = means
    bg = t >= (1.0 - bg_frac) * reach_px
    near = (t > 0) & ~bg
    level = np.median(m[:, bg], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.abs(m - level[:, None]) / se
    flat = ~np.any(z[:, bg] > k_sig, axis=1)        # else the backdrop beside the edge is not one level
    dep = near[None, :] & (z > k_sig)
    last = np.where(dep.any(axis=1), t[dep.shape[1] - 1 - np.argmax(dep[:, ::-1], axis=1)], 0.0)
    out[edges] = np.where(flat, last, 0.0)
    return out


def _edge_means(img, off, sp: CornerSpecs, sgn, only, layout: ProfileLayout, *, corr_px: float,
                min_profiles: int):
    """The mean profile across each outer edge (:func:`limb_edges`; of those in ``only`` (2K,) bool where
    given) over its usable length (``layout``: from
    ``s0`` to ``s_end``, ``h`` [px] either side of its line, every ``step``), and the mean's standard
    error (the profiles' spread over ``sqrt(n / corr_px)``: neighbouring profiles share blur and a JPEG's
    blocks): (edges (E,), t (T,) [px], mean (E, T), standard error (E, T)); None where no edge has
    ``min_profiles`` whole profiles."""
    K = len(sp.C)
    search = limb_edges(sp) if only is None else limb_edges(sp) & only
    if not search.any() or layout.h < 3 * layout.step:
        return None
    sub = CornerSpecs(sp.C, sp.Din, sp.Dout, np.where(search[:K], sp.Lin, 0.0), np.where(search[K:], sp.Lout, 0.0),
                      sp.face)
    pr = sample_profiles(img, off, sub, sgn, layout)
    if pr is None:
        return None
    P = dense_profiles(pr.values, pr.start, pr.half, pr.n_t)
    full = np.isfinite(P).all(axis=1)
    # every edge's mean profile and its standard error at once (the profiles come edge by edge)
    e_r, P = pr.edge[full], P[full]
    n = np.bincount(e_r, minlength=2 * K).astype(float)
    edges = np.nonzero(search & (n >= min_profiles))[0]
    if not len(edges):
        return None
    first, ends = np.searchsorted(e_r, edges), np.searchsorted(e_r, edges, side="right")
    cs1 = np.vstack([np.zeros(P.shape[1]), np.cumsum(P, axis=0)])
    cs2 = np.vstack([np.zeros(P.shape[1]), np.cumsum(P * P, axis=0)])
    ne = n[edges][:, None]
    m = (cs1[ends] - cs1[first]) / ne
    var = np.maximum((cs2[ends] - cs2[first]) / ne - m * m, 0.0)
    se = np.sqrt(var) / np.sqrt(np.maximum(ne / corr_px, 1.0))
    return edges, pr.t, m, se


def ray_exits(poly, P, u, *, min_s: float = 1.0, margin: float = 1.0) -> np.ndarray:
    """Distance (n,) [px] from each point ``P`` (n, 2) along the unit direction ``u`` (n, 2) to the nearest
    crossing of the closed polygon ``poly`` (N, 2) beyond ``min_s`` (inf: none).

    Only the sides whose ends are not both more than ``margin`` [px] on one side of a ray's line can cross
    it; the crossings are computed for those (ray, side) pairs alone, with the same arithmetic as over all
    pairs, so the distances are the same to the last bit.
    """
    A = np.asarray(poly, float)
    B = np.roll(A, -1, axis=0)
    P, u = np.asarray(P, float), np.asarray(u, float)
    # signed distance of every vertex from every ray's line (n, N), as a filter only
    d = (u[:, 1:] * A[:, 0] - u[:, :1] * A[:, 1]) - (P[:, 0] * u[:, 1] - P[:, 1] * u[:, 0])[:, None]
    hi, lo = d > -margin, d < margin                                  # not clearly below / above the line
    i, j = np.nonzero((hi | np.roll(hi, -1, axis=1)) & (lo | np.roll(lo, -1, axis=1)))
    E = B[j] - A[j]                                                   # (m, 2)
    W = A[j] - P[i]
    cross = lambda a, b: a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    den = cross(u[i], E)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = cross(W, E) / den
        r = cross(W, u[i]) / den
    hit = (np.abs(den) > 1e-12) & (r >= 0) & (r <= 1) & (s > min_s)
    out = np.full(len(P), np.inf)
    np.minimum.at(out, i[hit], s[hit])
    return out


def width_deficits(sp: CornerSpecs, sgn, outline_px, diameter_px: float, *, min_frac: float = 0.3) -> np.ndarray:
    """How much narrower than the tube (``diameter_px``) the silhouette ``outline_px`` (N, 2) is across each
    outer edge along the tube (:func:`limb_edges`) (2K,) [px], halfway along its usable length (at most a
    radius from the corner): from the edge inward to the outline's far side, at least ``min_frac``
    diameters away (the edge's own side is crossed next to the start); NaN where no ray crosses it or for
    other edges."""
    K = len(sp.C)
    nrm = _outward(sp, sgn)
    along = np.concatenate([-sp.Din, sp.Dout])
    L = np.nan_to_num(np.concatenate([sp.Lin, sp.Lout]))
    P = np.concatenate([sp.C, sp.C]) + np.minimum(0.5 * L, 0.5 * diameter_px)[:, None] * along
    out = np.full(2 * K, np.nan)
    e = np.nonzero(limb_edges(sp))[0]
    if len(e):
        w = ray_exits(outline_px, P[e], -nrm[e], min_s=min_frac * diameter_px)
        out[e] = np.where(np.isfinite(w), diameter_px - w, np.nan)
    return out


def outer_starts(sp: CornerSpecs, offsets, sgn, *, min_move: float, deficit=None) -> np.ndarray:
    """First estimates (K, 2) [px] with each corner's outer edges moved out by ``offsets`` (2K,)
    (:func:`outer_offsets`) where that exceeds ``min_move`` [px] (the silhouette's own resolution): the corner
    is where the moved lines meet. A first estimate only: the refinement measures the corner. ``deficit``
    (2K,) [px]: how much narrower than the tube the silhouette is across each edge (:func:`width_deficits`);
    an edge moves at most that: a silhouette as wide as the tube misses no limb, and
    what lies outside it is the backdrop's own (a cast shadow)."""
    K = len(sp.C)
    nrm = _outward(sp, sgn)
    if deficit is not None:
        offsets = np.minimum(offsets, np.where(np.isfinite(deficit), np.maximum(deficit, 0.0), 0.0))
    d = np.where(offsets > min_move, offsets, 0.0)
    C = sp.C.copy()
    for k in np.nonzero((d[:K] > 0) | (d[K:] > 0))[0]:
        A = _edge_normals(nrm, k)
        if A is not None:
            C[k] = sp.C[k] + np.linalg.solve(A, np.array([d[k], d[K + k]]))
    return C


def unexplained_cov(sp: CornerSpecs, sgn, offsets, deficit, *, resolution: float) -> np.ndarray:
    """Covariance (K, 2, 2) [px²] of each corner from the part of its silhouette's missing width that its
    outer edges' search did not find.

    Where the silhouette is narrower than the tube by ``deficit`` (2K,) [px] across an outer edge and the
    tube was seen to end ``offsets`` (2K,) [px] outside it (:func:`outer_offsets`; the other side's limb
    taken to miss as much, the same surface in the same light), the rest, less the silhouette's
    ``resolution`` [px], is a limb neither the silhouette nor the search saw (a polished limb as bright as
    the backdrop it mirrors): that edge lies anywhere over it, a uniform offset of variance ``rest² / 12``
    along its normal, carried to the corner by the two edges' intersection. 0 where nothing is missing.
    """
    K = len(sp.C)
    rest = np.nan_to_num(deficit, nan=0.0) - 2.0 * np.clip(offsets, 0.0, None) - resolution
    var = np.where(rest > 0, rest, 0.0) ** 2 / 12.0
    out = np.zeros((K, 2, 2))
    nrm = _outward(sp, sgn)
    for k in np.nonzero((var[:K] > 0) | (var[K:] > 0))[0]:
        A = _edge_normals(nrm, k)
        if A is not None:
            J = np.linalg.inv(A)
            out[k] = J @ np.diag([var[k], var[K + k]]) @ J.T
    return out


def holder_backdrops(img, off, sp: CornerSpecs, sgn, radius_px: float, blur_px: float, *, tol: float) -> np.ndarray:
    """(K,) bool: base corners whose holder face does not stand against the backdrop their tube's limb does.

    A base corner is where the tube's limb meets the holder's face, both seen
    against the backdrop: beyond either edge lies the same backdrop. Where
    the holder's face is seen a little from the side (a chuck's end face
    below the camera's axis), a band of that face lies between the holder's
    rim and the backdrop; the tube's base edge is in that band, hidden or
    shown against the face, and the corner of the rim and the limb is no
    point of the tube (its refined position lies a band's width off the base
    edge while its fit is as good as any). On either edge, the image's level
    just beyond the edge's rise (``3 blur_px + 1`` to that plus ``0.1 R``
    outward, ``radius_px`` the tube's radius [px]) is read along the edge:
    next to the corner (up to ``R``) on the holder's face, over its far half
    on the limb (away from the holder). Where the two levels differ by more
    than ``tol`` of the holder edge's own step (its level inside minus beyond),
    the holder's edge is not the holder against the backdrop: True.

    Parameters
    ----------
    img, off : the image region [image units] and its offset (u0, v0) [px].
    sp : CornerSpecs
        The refined corners and their edges; ``holder_face`` marks the base corners' holder edges.
    sgn : float
        Orientation sign of the outline (the edge normals point from the object to the background).
    """
    K = len(sp.C)
    out = np.zeros(K, bool)
    if sp.holder_face is None or not sp.holder_face.any():
        return out
    nrm = _outward(sp, sgn)
    along = np.concatenate([-sp.Din, sp.Dout])
    L = np.nan_to_num(np.concatenate([sp.Lin, sp.Lout]))
    gap = 3.0 * (blur_px if np.isfinite(blur_px) else 1.0) + 1.0
    t_out = gap + np.linspace(0.0, max(0.1 * radius_px, 2.0), 5)
    for k in np.nonzero(sp.holder_face[:K] | sp.holder_face[K:])[0]:
        if not np.all(np.isfinite(sp.C[k])):
            continue
        h, e = (k, K + k) if sp.holder_face[k] else (K + k, k)
        s_h = np.linspace(gap, max(min(L[h], radius_px), gap + 1.0), 12)
        s_e = np.linspace(0.5 * L[e], max(L[e], 0.5 * L[e] + 1.0), 12)
        level = lambda ed, s, t: _levels(img, off, sp.C[k] + s[:, None] * along[ed] + t * nrm[ed])
        beyond_h, beyond_e = level(h, s_h, t_out[:, None, None]), level(e, s_e, t_out[:, None, None])
        inside_h = level(h, s_h, -t_out[:, None, None])
        step = abs(inside_h - beyond_h)
        out[k] = bool(np.isfinite(step) and abs(beyond_h - beyond_e) > tol * step)
    return out


def _levels(img, off, P) -> float:
    """The median image level at the points ``P`` (..., 2) [px] (bilinear; NaN where all lie outside ``img``)."""
    Q = P.reshape(-1, 2) - off
    h, w = img.shape
    inside = (Q[:, 0] >= 0) & (Q[:, 0] <= w - 1) & (Q[:, 1] >= 0) & (Q[:, 1] <= h - 1)
    if not inside.any():
        return math.nan
    v = ndimage.map_coordinates(img, [Q[inside, 1], Q[inside, 0]], order=1)
    return float(np.median(v))


def outer_steps(img, off, sp: CornerSpecs, sgn, *, reach_px: float, s0: float, s_end: float, max_move,
                k_sig: float = 6.0, corr_px: float = 4.0, bg_frac: float = 0.35, min_profiles: int = 8,
                step: float = 0.5, blur0: float = 1.0, only=None):
    """The tube's outermost step beyond each refined outer edge: its offset [px] (2K,) and variance [px²]
    (2K,), 0 where the refined edge is that step.

    A polished limb mirrors the backdrop: across it the image steps from the
    backdrop to a strip nearly as bright (the mirror image, 10-15 px wide on
    a 1.6 mm tube at 130 px/mm), then ramps down to the tube's dark body.
    The refined edge's 50 % crossing between the body's level and the
    backdrop's lies on that inner ramp, a strip's width inside the tube;
    everything outward of it up to the outer step is tube. Per edge, the
    mean of its profiles over its usable length (the noise averages down
    along the edge, as in :func:`outer_offsets`): the backdrop level over
    the outer ``bg_frac`` of ``reach_px``, and the outermost sample that
    departs from it by more than ``k_sig`` standard errors (the outer step's
    foot). The level just inside that step is the mean's median over
    ``[foot - 2 g, foot - g]`` with ``g = 3 σ + 1`` [px], σ the step's own
    blur (its 25 -> 75 % rise / 1.349, from ``blur0`` [px] and measured
    once more); the step's half-way crossing, searched from the backdrop
    inward, is the tube's edge where both the step and that level stand out
    by ``k_sig`` standard errors and the crossing lies more than ``2 g``
    outside the refined edge (a single step's own foot is nearer). Its
    variance is the mean's standard error there over the mean's slope,
    squared. A move beyond ``max_move`` (2K,) [px] (the silhouette's missing
    width across the edge, :func:`width_deficits`: a matte tube misses none,
    and a cast shadow beside it is the backdrop's) is not taken.
    """
    offs, var = np.zeros(2 * len(sp.C)), np.zeros(2 * len(sp.C))
    means = _edge_means(img, off, sp, sgn, only, ProfileLayout(s0, s_end, reach_px, step), corr_px=corr_px,
                        min_profiles=min_profiles)
    if means is None:
        return offs, var
    edges, t, m, se = means
    for j, e in enumerate(edges):
        found = outer_step(t, m[j], se[j], t >= (1.0 - bg_frac) * reach_px, k_sig=k_sig, blur0=blur0)
        if found is not None and found[0] <= max_move[e]:
            offs[e], var[e] = found
    return offs, var


def outer_step(t, m, se, bg, *, k_sig: float = 6.0, blur0: float = 1.0):
    """The outermost step of one mean profile across an edge (:func:`outer_steps`): its half-way crossing
    [px] and variance [px²], or None where there is none more than ``2 g`` outside the refined edge.

    ``t`` (T,) [px] runs outward from the refined edge (0), ``m`` (T,) is the mean profile and ``se`` (T,)
    its standard error, ``bg`` (T,) bool the samples on the backdrop (the outer part of the reach).
    """
    b = float(np.median(m[bg]))
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.abs(m - b) / se
    if np.any(z[bg] > k_sig):
        return None                                     # the backdrop beside the edge is not one level
    dep = np.nonzero((t > 0) & ~bg & (z > k_sig))[0]
    if not len(dep):
        return None
    foot, sig = t[dep[-1]], blur0
    for _ in range(2):
        g = 3.0 * sig + 1.0
        found = _outer_crossing(t, m, se, b, foot, g, k_sig)
        if found is None:
            break
        tc, v, sig = found
    if found is None or not 2.0 * g < tc:
        return None
    return tc, v


def _outer_crossing(t, m, se, b, foot, g, k_sig):
    """The half-way crossing [px] of one mean profile ``m`` (T,) (standard error ``se``) between the backdrop
    level ``b`` and the level over ``[foot - 2 g, foot - g]``, searched from ``foot + g`` inward to ``foot - 2 g``;
    its variance [px²] and the step's blur σ (25 -> 75 % rise / 1.349) [px]; None where that level does
    not stand out by ``k_sig`` standard errors or the mean does not cross."""
    inner = (t >= foot - 2.0 * g) & (t <= foot - g)
    if not inner.any():
        return None
    p = float(np.median(m[inner]))
    if not abs(p - b) > k_sig * float(np.median(se[inner])):
        return None
    idx = np.nonzero((t <= foot + g) & (t >= foot - 2.0 * g))[0][::-1]
    q = (m[idx] - p) / (b - p)                         # 1 on the backdrop, 0 inside the step
    pos = []
    for lvl in (0.5, 0.75, 0.25):
        below = np.nonzero(q < lvl)[0]
        if not len(below) or below[0] == 0:
            return None
        i1, i0 = idx[below[0]], idx[below[0] - 1]      # i0 still at or above the level, i1 below it
        a0, a1 = (m[i0] - p) / (b - p) - lvl, (m[i1] - p) / (b - p) - lvl
        pos.append(t[i0] + (t[i1] - t[i0]) * a0 / (a0 - a1))
    i0, i1 = idx[np.nonzero(q < 0.5)[0][0] - 1], idx[np.nonzero(q < 0.5)[0][0]]
    slope = (m[i0] - m[i1]) / (t[i0] - t[i1])
    if slope == 0:
        return None
    return pos[0], (0.5 * (se[i0] + se[i1]) / slope) ** 2, max(abs(pos[1] - pos[2]) / 1.349, 0.5)


def _move_corners(sp: CornerSpecs, sgn, offs, var, spread):
    """Corners (K, 2) [px] with their edges moved out by ``offs`` (2K,) [px], and the covariance (K, 2, 2)
    [px²] to add: what the edges' offset variances ``var`` (2K,) carry to them, less what the moved edges'
    rises did (``spread`` (2K,) [px²], :func:`.refine.edge_spread`: the ramp is no longer the edge)."""
    K = len(sp.C)
    nrm = _outward(sp, sgn)
    C, cov = sp.C.copy(), np.zeros((K, 2, 2))
    moved = offs != 0
    d = var - np.where(moved, np.nan_to_num(spread), 0.0)
    for k in np.nonzero(moved[:K] | moved[K:])[0]:
        A = _edge_normals(nrm, k)
        if A is not None and np.all(np.isfinite(sp.C[k])):
            J = np.linalg.inv(A)
            C[k] = sp.C[k] + J @ np.array([offs[k], offs[K + k]])
            cov[k] = J @ np.diag([d[k], d[K + k]]) @ J.T
    return C, cov


def refine_corners(gray, specs, setup: Setup, *, full, contrast, extra_px=None, outline_px=None):
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
    cov_missing = np.zeros((len(sp.C), 2, 2))
    K, short = len(sp.C), None
    if opts.outer_reach_R > 0:
        # the silhouette misses a polished or shaded limb: the first estimates start where the tube ends
        short = None if outline_px is None else width_deficits(sp, sgn, outline_px, 2.0 * radius_px)
        # a silhouette within a working-copy pixel of the tube's width misses nothing worth a search
        wanted = None if short is None else np.nan_to_num(short, nan=0.0) > setup.f
        offs = outer_offsets(img, off, sp, sgn, reach_px=opts.outer_reach_R * radius_px, s0=5.0 * kf, only=wanted)
        C1 = outer_starts(sp, offs, sgn, min_move=float(setup.f), deficit=short)
        sp.outside = np.any(C1 != sp.C, axis=1)
        sp.C = C1
        if short is not None:
            # both limbs miss at most the search's reach: a larger deficit is not a link's width
            # (and a slot face's or a holder face's ray does not cross a link)
            sure = np.where((short > 0) & (short <= 2 * opts.outer_reach_R * radius_px), short, np.nan)
            offs_used = np.minimum(offs, np.nan_to_num(sure, nan=0.0))
            cov_missing = unexplained_cov(sp, sgn, offs_used, sure, resolution=float(setup.f))
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
    wide = res.wide
    if opts.outer_step_k > 0 and short is not None:
        # a polished limb's mirror strip: the refined edge is its inner ramp, the tube ends at its outer step
        # (looked for across the edges where the search before the first pass saw tube outside the silhouette)
        allow = np.where(np.isfinite(short), np.maximum(short, 0.0), 0.0) + float(setup.f)
        offs2, var2 = outer_steps(img, off, sp, sgn, reach_px=opts.outer_reach_R * radius_px,
                                  s0=max(3.0, 3.0 * bl + 1.0), s_end=max(2.0, 2.5 * bl + 1.0), max_move=allow,
                                  k_sig=opts.outer_step_k, only=offs > setup.f)
        moved = (offs2[:K] != 0) | (offs2[K:] != 0)
        if moved.any():
            C2, cov2 = _move_corners(sp, sgn, offs2, var2,
                                     np.zeros(2 * K) if res.spread_edge is None else res.spread_edge)
            ok2 = moved & np.isfinite(C2).all(1) & res.ok
            sp.C = np.where(ok2[:, None], C2, sp.C)
            X = res.X.copy()
            X[ok2] = camera.undistort_pixels(sp.C[ok2])
            res = dataclasses.replace(res, X=X, cov_sys=res.cov_sys + np.where(ok2[:, None, None], cov2, 0.0))
            if cov_missing.any():
                # the moved edges' missing width is found: what stays unexplained is the others'
                found = np.concatenate([offs2[:K] != 0, offs2[K:] != 0]) & np.concatenate([ok2, ok2])
                cov_missing = unexplained_cov(sp, sgn, np.where(found, np.inf, offs_used), sure,
                                              resolution=float(setup.f))
            if wide is not None and res.wide_edge is not None:
                # the ramp was the moved edge's: what stays wide is the corner's other edges
                we = res.wide_edge & ~np.concatenate([offs2[:K] != 0, offs2[K:] != 0])
                wide = np.where(ok2, we[:K] | we[K:], wide)
    shift = np.linalg.norm(sp.C - C0, axis=1)
    sig_px = np.sqrt(np.maximum(np.trace(res.cov, axis1=1, axis2=2) / 2, 0)) * opts.sigma_inflation
    # the reported covariance adds what the edges' own profiles show (two rims of a face seen from the side)
    cov_sys = res.cov_sys + cov_missing
    rim = np.zeros(len(pidx), bool)
    if opts.holder_backdrop_tol > 0:
        # a holder's face seen from the side: the corner of its rim and the limb is no point of the tube
        rim = res.ok & holder_backdrops(img, off, sp, sgn, radius_px, bl, tol=opts.holder_backdrop_tol)
    return Refinement(pidx, sp.C, res.X, res.cov + cov_sys / opts.sigma_inflation ** 2, res.ok & ~rim, shift, bl,
                      sig_px, sp, img, off, kf, wide=wide, rim=rim)


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


def link_widths(ref: Refinement, mask, f: int, camera, px_per_m: float, radius: float, *,
                far_reach_R: float = 0.4, far_half_R: float = 0.15) -> np.ndarray:
    """The tube's width [m] beside each refined slot corner, across its outer edge (K,); NaN for other corners.

    From the point ``0.3 R`` along the corner's outer edge away from its
    slot, along the normal into the object, to where the working-copy
    ``mask`` ends; mapped to the plane. A link is ``2R`` wide there: a
    corner whose outer edge is an edge inside the tube (the boundary of a
    highlight, where the limb mirrors the backdrop) finds it narrower.

    The check is of the corner's own edge, not of the silhouette's far side:
    where the mask ends more than a working-copy pixel short of ``2R``, the
    far end is looked for in the image (``ref.img``, ``ref.off``) as the
    refinement looks for a polished or shaded limb (:func:`outer_offsets`:
    the mean of the profiles ``far_half_R`` R either side of the far end, up
    to ``far_reach_R`` R outward): a limb that mirrors the backdrop is left
    out of the silhouette on the far side as on the near one, and the width
    runs to where the tube is seen to end. A corner on an edge inside the
    tube stays as much short of ``2R`` as it lies inside.
    """
    sp = ref.specs
    K = len(ref.C)
    out = np.full(K, np.nan)
    h, w = mask.shape
    R_px = radius * px_per_m
    lo = lambda P: np.rint((np.asarray(P) - (f - 1) / 2.0) / f).astype(int)
    inside = lambda q: bool(0 <= q[0] < w and 0 <= q[1] < h and mask[q[1], q[0]])
    t = np.arange(0.3 * R_px, 3.0 * R_px, 0.5 * f)
    ends = {}
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
                ends[k] = (P, n, float(t[hit[0]]))
            break
    far = _far_limbs(ref, ends, 2.0 * R_px - f, reach_px=far_reach_R * R_px, half_px=far_half_R * R_px)
    for k, (P, n, s) in ends.items():
        pts = camera.pixel_to_plane(np.array([P, P + (s + far.get(k, 0.0)) * n]))
        out[k] = float(np.linalg.norm(pts[1] - pts[0]))
    return out


def _far_limbs(ref: Refinement, ends: dict, short_px: float, *, reach_px: float, half_px: float) -> dict:
    """{corner: how far outside the mask's far end the tube is seen to end [px]} for the corners of ``ends``
    ({corner: (start (2,), unit normal into the tube (2,), distance to the mask's far end [px])}) whose
    distance is below ``short_px``; from :func:`outer_offsets` on a short edge through each far end."""
    img, off = getattr(ref, "img", None), getattr(ref, "off", None)
    ks = [k for k, (_, _, s) in ends.items() if s < short_px]
    if img is None or not ks or reach_px < 3.0:
        return {}
    n = np.array([ends[k][1] for k in ks])
    Pf = np.array([ends[k][0] + ends[k][2] * ends[k][1] for k in ks])
    # an incoming edge through each far end, along the link, its profiles' normal (sgn = 1) along n
    D = np.stack([-n[:, 1], n[:, 0]], axis=1)
    L = np.full(len(ks), 2.0 * half_px)
    sub = CornerSpecs(Pf + half_px * D, D, D, L, np.zeros(len(ks)), np.zeros(2 * len(ks), bool))
    offs = outer_offsets(img, off, sub, 1.0, reach_px=reach_px, s0=0.0, s_end=0.0)
    return {k: float(o) for k, o in zip(ks, offs[:len(ks)])}


def edge_stations(ref, n_per_edge, sgn):
    """Points on the straight outer edge next to every ok corner, with the unit normal into the tube (S, 4).

    A base corner withheld as a holder's rim seen from the side (``ref.rim``) still gives its limb edge's
    stations: the test finds the corner no point of the tube, not the limb, which is the tube's edge
    against the backdrop up to the next corner. Only the tube's limbs give stations, never a slot's or
    the holder's face (:func:`limb_edges`)."""
    sp = ref.specs
    K = len(sp.C)
    limb = limb_edges(sp)
    rows = []
    for k in np.nonzero(ref.ok if ref.rim is None else ref.ok | ref.rim)[0]:
        for e, (D, L, face) in enumerate(((-sp.Din[k], sp.Lin[k], not limb[k]), (sp.Dout[k], sp.Lout[k],
                                                                                  not limb[K + k]))):
            if face or not np.isfinite(L) or L < 8:
                continue
            trav = sp.Din[k] if e == 0 else sp.Dout[k]
            inward = -sgn * np.array([trav[1], -trav[0]])
            for s in np.linspace(0.3, 0.7, n_per_edge) * L:
                P = sp.C[k] + s * D
                rows.append([P[0], P[1], inward[0], inward[1]])
    return np.array(rows).reshape(-1, 4)
