"""Slots closed at the mouth: where a wedge inside the silhouette meets the outline.

A slot bent shut closes about the backbone: its faces touch at the mouth and the gap between them widens
toward the backbone, so the slot shows as a wedge of backdrop inside the silhouette (a hole), pointed at
its mouth. Near the point the gap is narrower than a working pixel and the hole ends short of the outline,
by up to the slot's depth on a slot bent fully shut. The mouth is therefore found from the wedge's own
shape, not from a gap in the outline nor from the light along the way: the hole's long axis (across the
tube), its width measured along that axis, and the outline point where the axis leaves the narrow end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Wedge", "wedge_of", "wedge_mouth", "wedge_sides"]


@dataclass(frozen=True)
class Wedge:
    """The shape of one hole seen as a wedge (working px).

    Attributes
    ----------
    centre : ndarray (2,)
        The hole's centroid (x, y).
    axis : ndarray (2,)
        Unit vector along the hole's long axis, from its wide end toward its narrow end (the mouth).
    length : float
        The hole's extent along the axis.
    taper : float
        Width at the wide end minus width at the narrow end, from a straight-line fit of the width
        along the axis.
    tip : float
        Position of the narrow end along the axis, from the centroid.
    """

    centre: np.ndarray
    axis: np.ndarray
    length: float
    taper: float
    tip: float


def wedge_of(pts) -> Wedge | None:
    """The hole's long axis and its width along it (a least-squares line through the widths of slices one
    working pixel thick); None for fewer than 6 pixels.

    Parameters
    ----------
    pts : ndarray (K, 2)
        The hole's pixel centres (x, y) [working px].
    """
    pts = np.asarray(pts, float)
    if len(pts) < 6:
        return None
    c = pts.mean(0)
    axis = np.linalg.svd(pts - c, full_matrices=False)[2][0]
    t = (pts - c) @ axis
    k = np.floor(t - t.min()).astype(int)
    width = np.bincount(k).astype(float)                     # pixels per slice 1 px thick: the width
    pos = t.min() + np.arange(len(width)) + 0.5
    used = width > 0
    if used.sum() < 3:
        return None
    slope = np.polyfit(pos[used], width[used], 1)[0]
    length = float(t.max() - t.min())
    if slope > 0:                                            # wider toward +axis: the mouth is at -axis
        axis, t = -axis, -t
    return Wedge(c, axis, length, abs(float(slope)) * length, float(t.max()))


def wedge_mouth(contour, pts, *, reach: float, min_taper: float = 1.5, max_off: float = 2.0):
    """The outline index of a closed slot's mouth: where the wedge's axis, past its narrow end, meets the
    outline within ``reach`` [working px] (the slot's depth: the gap's unresolved point is no longer);
    None when the hole does not taper by ``min_taper`` px over its length (a hole of even width points
    nowhere) or the axis meets no outline point within ``max_off`` px of it.

    Parameters
    ----------
    contour : ndarray (N, 2)
        The bridged outline [working px, the hole's frame].
    pts : ndarray (K, 2)
        The hole's pixel centres.
    """
    w = wedge_of(pts)
    if w is None or w.taper < min_taper:
        return None
    rel = np.asarray(contour, float) - w.centre
    along = rel @ w.axis
    perp = np.abs(rel[:, 0] * w.axis[1] - rel[:, 1] * w.axis[0])
    cand = np.nonzero((perp < max_off) & (along > w.tip - 1.0) & (along < w.tip + reach))[0]
    if not len(cand):
        return None
    return int(cand[np.argmin(along[cand])])


def wedge_sides(pts) -> tuple | None:
    """The directions of a wedge's two sides, each from its narrow end toward its wide end: the slot's two
    faces, which meet at the mouth of a slot bent shut ((2,), (2,) unit vectors, the first on the side of
    ``-n`` and the second on the side of ``+n``, with ``n`` the axis turned by +90°); None for a hole
    that is no wedge (:func:`wedge_of`).

    Each side is a least-squares line through the hole's outermost pixel centre across each slice one
    working pixel thick along the axis.
    """
    pts = np.asarray(pts, float)
    w = wedge_of(pts)
    if w is None:
        return None
    n = np.array([-w.axis[1], w.axis[0]])
    t, u = (pts - w.centre) @ w.axis, (pts - w.centre) @ n
    k = np.floor(t - t.min()).astype(int)
    lo = np.full(k.max() + 1, np.inf)
    hi = np.full(k.max() + 1, -np.inf)
    np.minimum.at(lo, k, u)
    np.maximum.at(hi, k, u)
    pos = t.min() + np.arange(len(lo)) + 0.5
    used = np.isfinite(lo)
    if used.sum() < 3:
        return None
    out = []
    for edge in (lo, hi):
        slope = np.polyfit(pos[used], edge[used], 1)[0]
        d = -(w.axis + slope * n)                           # toward the wide end (-axis)
        out.append(d / np.linalg.norm(d))
    return out[0], out[1]
