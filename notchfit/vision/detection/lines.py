"""Small numeric helpers of the detector: Otsu split, lines, grouped robust line fits, line or arc."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["GroupLayout", "arc_residuals", "arcs_allowed", "group_layout", "group_lines", "group_median", "intersect",
           "line_pairs", "otsu", "pca_line", "poly2", "robust_group_lines", "unit"]


def otsu(values, bins=256):
    """Otsu threshold of a 1-D sample (``bins`` histogram bins)."""
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


def poly2(x, y):
    """Design matrix (..., 6) of a quadratic surface in (x, y)."""
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)


def unit(v):
    """Rows of ``v`` (..., 2) scaled to unit length (zero rows unchanged)."""
    v = np.asarray(v, float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def pca_line(pts):
    """Total-least-squares line of points (K, 2): centroid and unit direction (None, None if K < 2)."""
    pts = np.asarray(pts, float)
    if len(pts) < 2:
        return None, None
    c = pts.mean(0)
    d = pts - c
    sxx, sxy, syy = (d[:, 0] ** 2).sum(), (d[:, 0] * d[:, 1]).sum(), (d[:, 1] ** 2).sum()
    a = 0.5 * math.atan2(2 * sxy, sxx - syy)
    return c, np.array([math.cos(a), math.sin(a)])


def intersect(c1, d1, c2, d2):
    """Intersection of the lines ``c1 + s d1`` and ``c2 + t d2`` (None if parallel)."""
    A = np.array([[d1[0], -d2[0]], [d1[1], -d2[1]]])
    if abs(np.linalg.det(A)) < 1e-9:
        return None
    s = np.linalg.solve(A, c2 - c1)
    return c1 + s[0] * d1


@dataclass(frozen=True)
class GroupLayout:
    """Where each item of a grouping sits in a table with one row per group, its values left-aligned.

    Built once by :func:`group_layout` and passed to :func:`group_median` for
    every set of values over the same groups (a refinement pass takes several
    medians per edge of the same profiles): the items are put in group order
    once, each call sorts only the rows of its own values.
    """

    order: np.ndarray | None    # (N,) items in group order; None when the groups are already in order
    rows: np.ndarray            # (N,) each item's group, in group order
    cols: np.ndarray            # (N,) its place within the group
    shape: tuple                # (n_groups, largest group)
    table: bool                 # False: the table would be mostly padding (one group far larger than most)


def group_layout(groups, n_groups: int, *, max_fill: float = 8.0) -> GroupLayout:
    """The table layout of ``groups`` (N,) int in ``range(n_groups)`` for :func:`group_median`.

    ``max_fill``: a table larger than ``max_fill`` times the items (plus 1024) is not used; the medians
    then sort (group, value) pairs with :func:`numpy.lexsort` on each call.
    """
    groups = np.asarray(groups)
    cnt = np.bincount(groups, minlength=n_groups)
    start = np.cumsum(cnt) - cnt
    ordered = bool(np.all(groups[1:] >= groups[:-1]))
    order = None if ordered else np.argsort(groups, kind="stable")
    rows = groups if ordered else groups[order]
    cols = np.arange(len(groups)) - start[rows]
    width = int(cnt.max()) if len(groups) else 0
    return GroupLayout(order, rows, cols, (n_groups, width), n_groups * width <= max_fill * len(groups) + 1024)


def group_median(values, groups, n_groups, *, layout: GroupLayout | None = None):
    """Median of ``values`` (N,) per group (NaN and infinities ignored; NaN for empty groups) (n_groups,).

    ``layout``: :func:`group_layout` of ``groups`` when several value sets share them (``groups`` is then
    not read). Each group's median is that of its own sorted values, as :func:`numpy.median` takes it.
    """
    lay = group_layout(groups, n_groups) if layout is None else layout
    v = np.asarray(values, float)
    v = v if lay.order is None else v[lay.order]
    fin = np.isfinite(v)
    cnt = np.bincount(lay.rows, fin, minlength=n_groups).astype(int)
    out = np.full(n_groups, np.nan)
    has = np.nonzero(cnt > 0)[0]
    if not len(has):
        return out
    lo, hi = (cnt[has] - 1) // 2, cnt[has] // 2
    if lay.table:
        tab = np.full(lay.shape, np.nan)
        tab[lay.rows, lay.cols] = np.where(fin, v, np.nan)
        tab.sort(axis=1)                                  # NaN last in each row
        out[has] = 0.5 * (tab[has, lo] + tab[has, hi])
        return out
    vs = v[fin][np.lexsort((v[fin], lay.rows[fin]))]
    first = np.cumsum(cnt) - cnt
    out[has] = 0.5 * (vs[first[has] + lo] + vs[first[has] + hi])
    return out


def group_lines(pts, groups, n_groups, keep):
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


def robust_group_lines(pts, groups, n_groups, *, k_mad=3.0, floor=0.15, n_iter=3):
    """Robust TLS lines: MAD rejection of residuals, ``n_iter`` rounds.

    Returns centroid (G,2), direction (G,2), kept count (G,), residual
    variance s² (G,) [px²], spread along the line S_tt (G,) [px²], keep mask.
    """
    keep = np.ones(len(pts), bool)
    lay = group_layout(groups, n_groups)
    for it in range(n_iter + 1):
        c, d, n = group_lines(pts, groups, n_groups, keep)
        r = (pts[:, 0] - c[groups, 0]) * (-d[groups, 1]) + (pts[:, 1] - c[groups, 1]) * d[groups, 0]
        if it == n_iter:
            break
        mad = 1.4826 * group_median(np.where(keep, np.abs(r), np.nan), groups, n_groups, layout=lay)
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


def line_pairs(c, dd, n, s2, stt, k1, k2, extra1=0.0, extra2=0.0):
    """Where lines ``k1`` and ``k2`` (K,) of :func:`robust_group_lines` meet, with covariance.

    Each line's error across it is ``s² / n + lever² s² / S_tt`` (offset and angle; ``lever`` the distance
    along the line from its centroid to the point), plus ``extra1``/``extra2`` (a variance shared by all its
    points); ``s2`` (2K,) the residual variances to use.

    Returns
    -------
    X (K, 2), cov (K, 2, 2), sin (K,) of the angle between the lines, det (K,) of the normals' matrix;
    where ``det`` is 0, X and cov are not meaningful.
    """
    d1, d2 = dd[k1], dd[k2]
    sin = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    n1 = np.stack([-d1[:, 1], d1[:, 0]], 1)
    n2 = np.stack([-d2[:, 1], d2[:, 0]], 1)
    Amat = np.stack([n1, n2], 1)
    rhs = np.stack([(n1 * c[k1]).sum(1), (n2 * c[k2]).sum(1)], 1)
    det = Amat[:, 0, 0] * Amat[:, 1, 1] - Amat[:, 0, 1] * Amat[:, 1, 0]
    Ainv = np.zeros_like(Amat)
    sd = np.where(det != 0, det, 1.0)
    Ainv[:, 0, 0], Ainv[:, 0, 1] = Amat[:, 1, 1] / sd, -Amat[:, 0, 1] / sd
    Ainv[:, 1, 0], Ainv[:, 1, 1] = -Amat[:, 1, 0] / sd, Amat[:, 0, 0] / sd
    X = np.einsum("kij,kj->ki", Ainv, rhs)
    lev1 = ((X - c[k1]) * d1).sum(1)
    lev2 = ((X - c[k2]) * d2).sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        v1 = s2[k1] / np.maximum(n[k1], 1) + lev1 ** 2 * s2[k1] / np.where(stt[k1] > 0, stt[k1], np.inf)
        v2 = s2[k2] / np.maximum(n[k2], 1) + lev2 ** 2 * s2[k2] / np.where(stt[k2] > 0, stt[k2], np.inf)
    D = np.zeros((len(k1), 2, 2))
    D[:, 0, 0], D[:, 1, 1] = v1 + extra1, v2 + extra2
    return X, Ainv @ D @ np.swapaxes(Ainv, 1, 2), sin, det


def arcs_allowed(pts, grp, X, fe, d_limb, sin_b, radius_px: float, significance: float,
                 min_points: int = 6) -> np.ndarray:
    """(n,) bool: whether each face's crossings (edge ``fe``, corner ``X``) fit the arc of a face seen
    ``asin(sin_b)`` from the side, bulging either way, not significantly worse than a straight line: the
    residual sums of ``v = v0 + c u (± sin_b g(u))`` in closed form, all faces at once."""
    rss, s2, few = arc_residuals(pts, grp, X, fe, d_limb, sin_b, radius_px, min_points=min_points)
    return (np.minimum(rss[1], rss[2]) <= rss[0] + significance * s2) | few


def arc_residuals(pts, grp, X, fe, d_limb, sin_b, radius_px: float, min_points: int = 6):
    """The residual sums of squares (3, n) [px²] of each face's crossings (edge ``fe``, corner ``X``, limb
    direction ``d_limb``, ``v`` along it, ``u`` across) to ``v = v0 + c u``, ``v = v0 + c u + sin_b g(u)``
    and ``v = v0 + c u - sin_b g(u)`` (``g(u) = sqrt(u (2R - u))``, ``v0`` and ``c`` fitted), the line's
    residual variance (n,) and the faces with too few crossings to tell (n,) bool."""
    n = len(fe)
    slot = np.full(max(int(grp.max()) + 1 if len(grp) else 0, int(fe.max()) + 1), -1)
    slot[fe] = np.arange(n)
    sel = slot[grp]
    keep = sel >= 0
    q, P = sel[keep], pts[keep] - X[sel[keep]]
    d = d_limb[q]
    u = np.abs(P[:, 1] * d[:, 0] - P[:, 0] * d[:, 1])
    v = np.sum(P * d, 1)
    near = u <= 2 * radius_px
    q, u, v = q[near], u[near], v[near]
    g = np.sqrt(np.clip(u * (2 * radius_px - u), 0, None))
    S = lambda w: np.bincount(q, w, n)
    N, Su, Suu = S(np.ones_like(u)), S(u), S(u * u)
    det = N * Suu - Su * Su
    rss = []
    for t in (v, v - sin_b[q] * g, v + sin_b[q] * g):
        St, Sut, Stt = S(t), S(u * t), S(t * t)
        with np.errstate(invalid="ignore", divide="ignore"):
            rss.append(Stt - (Suu * St * St - 2 * Su * St * Sut + N * Sut * Sut) / det)
    s2 = np.maximum(rss[0] / np.maximum(N - 2, 1), 1e-6)
    return np.array(rss), s2, (N < min_points) | ~(det > 0)
