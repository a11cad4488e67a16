"""Stage 4b: first corner estimates (position, the two edge directions, usable edge lengths).

All on the downsampled copy: base corners from the unbridged outline (the
closing rounds concave corners), tip corners from the bridged one, slot
corners where each slot's mouth meets the bridged outline, with the edge
directions taken from the unbridged outline in a cone around the rough ones.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .closed import wedge_sides
from .dims import joint_z, slot_depths, slot_widths
from .lines import intersect, pca_line, unit

__all__ = ["CornerSpec", "base_specs", "edge_room", "outline_directions", "slot_specs", "tip_specs"]

# a spec: (point index, corner xy [low-res px], d_in, d_out, L_in [m], L_out [m], face_in, face_out)



@dataclass(frozen=True)
class CornerSpec:
    """A corner to refine, as located on the working copy.

    Attributes
    ----------
    point : int
        Its point index (0-based, geometry.md numbering).
    xy : ndarray (2,)
        First estimate [working-copy px of the crop].
    d_in, d_out : ndarray (2,)
        Directions of the incoming edge (travelling into the corner) and the
        outgoing edge, along the outline.
    len_in, len_out : float
        Usable straight length of each edge [m].
    face_in, face_out : bool
        The edge is a slot face (its background is the slot).
    """

    point: int
    xy: np.ndarray
    d_in: np.ndarray
    d_out: np.ndarray
    len_in: float
    len_out: float
    face_in: bool = False
    face_out: bool = False

@functools.lru_cache(maxsize=32)
def _slot_bounds(geom) -> tuple:
    """Every slot's lower and upper z (n,) x 2, the tip's and the base edge's z [m] (computed once per geometry)."""
    zj, w = joint_z(geom), slot_widths(geom)
    lo, hi = zj - w / 2, zj + w / 2
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi, geom.tip_z, geom.base_edge_z


def edge_room(geom, z: float, up: bool) -> float:
    """Straight edge from z along a side, towards the tip (``up``) or the base, before the next slot [m]."""
    lo, hi, tip_z, base_z = _slot_bounds(geom)
    if up:
        nxt = lo[lo > z + 1e-12]
        return (min(nxt.min(), tip_z) if len(nxt) else tip_z) - z
    prv = hi[hi < z - 1e-12]
    return z - (max(prv.max(), base_z) if len(prv) else base_z)


def outline_directions(mcnt, P, rough, a2, a1=2.0, cone_deg=35.0):
    """Directions of an outline leaving points P (n,2) along ``rough`` (n,2), from its points a1..a2 (n,) away
    within a cone (total least squares); ``rough`` where too few points."""
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


def base_specs(mcnt, mi_right, mi_left, *, sgn, index, geom, low_m, face_len):
    """Base corners (points 2 and 1) at corners of the unbridged outline (the closing rounds concave corners);
    an index None (a corner outside the image) gives no spec."""
    M_ = len(mcnt)
    lp = lambda length_m: max(2, int(round(length_m / low_m)))
    up_len = edge_room(geom, geom.base_edge_z, True)
    out = []
    for mi, side in ((mi_right, +1), (mi_left, -1)):
        if mi is None:                   # outside the image
            continue
        a2_side = max(3, min(lp(0.8 * up_len), 10))
        a2_face = max(3, min(lp(0.8 * face_len), 10))
        sel_in = [(mi - t_) % M_ for t_ in range(1, (a2_face if side > 0 else a2_side) + 1)]
        sel_out = [(mi + t_) % M_ for t_ in range(1, (a2_side if side > 0 else a2_face) + 1)]
        c_in, d_in = pca_line(mcnt[sel_in])
        c_out, d_out = pca_line(mcnt[sel_out])
        d_in = d_in if np.dot(d_in, mcnt[mi] - mcnt[sel_in[-1]]) >= 0 else -d_in
        d_out = d_out if np.dot(d_out, mcnt[sel_out[-1]] - mcnt[mi]) >= 0 else -d_out
        P = intersect(c_in, d_in, c_out, d_out)
        if P is None or np.linalg.norm(P - mcnt[mi]) > 3:
            P = mcnt[mi]
        out.append(CornerSpec(index[("base", 0, side)], P, d_in, d_out, face_len if side > 0 else up_len,
                              up_len if side > 0 else face_len))
    return out


def _chord_dir(cnt, i, before, a1, a2):
    N = len(cnt)
    sel = [(i - t) % N for t in range(a1, a2 + 1)] if before else [(i + t) % N for t in range(a1, a2 + 1)]
    c, dv = pca_line(cnt[sel])
    ref = (cnt[i] - cnt[sel[-1]]) if before else (cnt[sel[-1]] - cnt[i])
    return c, (dv if np.dot(dv, ref) >= 0 else -dv)


def tip_specs(cnt, tip, *, index, geom, low_m):
    """Tip corners (29 and 30) from the bridged outline."""
    R = geom.outer_radius
    lp = lambda length_m: max(2, int(round(length_m / low_m)))
    down = edge_room(geom, geom.tip_z, False)
    out = []
    for ti, side in ((tip[0], +1), (tip[1], -1)):
        a = lp(min(0.5e-3, 0.8 * down, 0.8 * R))
        c_in, d_in = _chord_dir(cnt, ti, True, 2, 2 + a)
        c_out, d_out = _chord_dir(cnt, ti, False, 2, 2 + a)
        P = intersect(c_in, d_in, c_out, d_out)
        out.append(CornerSpec(index[("tip", 0, side)], cnt[ti] if P is None else P, d_in, d_out,
                              down if side > 0 else 2 * R, 2 * R if side > 0 else down))
    return out


def slot_specs(cnt, mcnt, pairs_by_side, mouths, *, sgn, index, geom, low_m, raw_corners=None, holes=None):
    """Slot corners: proximal and distal corner of every numbered slot.

    ``raw_corners`` (label -> indices into ``mcnt``, from
    :func:`~notchfit.vision.detection.outline.raw_mouth_corners`) gives the corners
    and the outer edges' rough directions where known; otherwise they come
    from the bridged outline at the mouth. ``holes`` (label -> the pixel
    centres of a slot closed at its mouth, (K, 2)): the faces' directions
    are its wedge's sides (:func:`~.closed.wedge_sides`; a slot bent shut
    turns each face by half its closure), not the normal to the outer edge.
    """
    holes = holes or {}
    raw_corners = raw_corners or {}
    M = len(mcnt)
    N = len(cnt)
    zj, w, d = joint_z(geom), slot_widths(geom), slot_depths(geom)
    lp = lambda length_m: max(2, int(round(length_m / low_m)))
    outward = lambda dv: sgn * np.array([dv[1], -dv[0]])
    chord = lambda i0, i1: unit(cnt[i1 % N] - cnt[i0 % N])
    rows = []
    for pairs, side in pairs_by_side:
        for s, j in pairs:
            i_first, i_last, bridged = mouths[s]
            z, wj = zj[j - 1], w[j - 1]
            lo_len, hi_len = edge_room(geom, z - wj / 2, False), edge_room(geom, z + wj / 2, True)
            first_len, second_len = (lo_len, hi_len) if side > 0 else (hi_len, lo_len)
            a_f, a_s = lp(min(0.5e-3, 0.8 * first_len)), lp(min(0.5e-3, 0.8 * second_len))
            d_in = chord(i_first - 2 - a_f, i_first - 2)
            d_out = chord(i_last + 2, i_last + 2 + a_s)
            if s in raw_corners:
                ia, ib = raw_corners[s]
                Pa, Pb = mcnt[ia], mcnt[ib]
                d_in = unit(mcnt[ia] - mcnt[(ia - 2 - a_f) % M])
                d_out = unit(mcnt[(ib + 2 + a_s) % M] - mcnt[ib])
            elif bridged:
                Pa, Pb = cnt[(i_first - 1) % N], cnt[(i_last + 1) % N]
            else:
                Pa, Pb = cnt[i_first] - 0.25 * d_in, cnt[i_first] + 0.25 * d_out
            rows.append((side, j, Pa, Pb, d_in, d_out, a_f, a_s, first_len, second_len,
                         None if bridged or s not in holes else wedge_sides(holes[s])))
    if not rows:
        return []
    # the bridged outline bends near other concavities (the base fillet): take the edge
    # directions from the unbridged outline, in a cone around the rough ones
    Ps = np.array([r[2] for r in rows] + [r[3] for r in rows])
    rough = np.array([-r[4] for r in rows] + [r[5] for r in rows])
    a2s = np.array([r[6] for r in rows] + [r[7] for r in rows], float)
    dirs = outline_directions(mcnt, Ps, rough, a2s)
    ns = len(rows)
    out = []
    for q, (side, j, Pa, Pb, _, _, _, _, first_len, second_len, wedge) in enumerate(rows):
        d_in, d_out = -dirs[q], dirs[ns + q]
        face_a = -outward(d_in)                 # into the tube along the first face
        face_b = outward(d_out)                 # out of the slot along the second face
        if wedge is not None:                   # the wedge's side next to the first link, then the other
            first = 0 if np.dot(wedge[0] - wedge[1], -d_in) > 0 else 1
            face_a, face_b = wedge[first], -wedge[1 - first]
        kinds = ("proximal", "distal") if side > 0 else ("distal", "proximal")
        dj = d[j - 1]
        out.append(CornerSpec(index[(kinds[0], j, side)], Pa, d_in, face_a, first_len, dj, face_out=True))
        out.append(CornerSpec(index[(kinds[1], j, side)], Pb, face_b, d_out, dj, second_len, face_in=True))
    return out
