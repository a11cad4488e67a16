"""The faces of slots and tip seen a little from the side (part of stage 5, the refinement).

A slot or tip face is a circle of radius ``R`` about the tube's axis: straight
when seen exactly from the side, an arc of an ellipse tangent to the limb at
the corner when the view looks a little along the tube. Here the faces'
robust fits with and without that arc (:func:`curved_face_corners`), the
faces left straight measured with the arc a camera file's view gives them
(:func:`known_arc_corners`), and the covariance a face's unseen arc adds to
its corner (:func:`face_view_cov`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .lines import arc_residuals, arcs_allowed, group_median
from .mouth import shut_mouths, with_mouths
from .view import DiameterScale

__all__ = ["curved_face_corners", "face_view_cov", "far_line_corners", "known_arc_corners", "straight_face_corners",
           "view_sines"]

def _face_fits(u, v, gid, G, radius, *, curved: bool, k_mad: float = 3.0, floor: float = 0.15, n_iter: int = 3):
    """Robust least squares ``v = v0 + c u (+ b g(u))``, ``g(u) = sqrt(u (2 radius - u))``, for G groups at once.

    Returns coefficients (G, p), their covariance (G, p, p), residual variance (G,), kept count (G,);
    NaN coefficients for groups with too few points.
    """
    cols = [np.ones_like(u), u] + ([np.sqrt(np.clip(u * (2 * radius - u), 0, None))] if curved else [])
    A = np.stack(cols, 1)
    p = A.shape[1]
    keep = np.ones(len(u), bool)
    for it in range(n_iter + 1):
        w = keep.astype(float)
        M = np.stack([np.stack([np.bincount(gid, w * A[:, i] * A[:, j], G) for j in range(p)], -1)
                      for i in range(p)], -2)
        rhs = np.stack([np.bincount(gid, w * A[:, i] * v, G) for i in range(p)], -1)
        n = np.bincount(gid, w, G)
        good = n > p + 2
        Mg = np.where(good[:, None, None], M, np.eye(p)) + 1e-12 * np.eye(p)
        coef = np.linalg.solve(Mg, np.where(good[:, None], rhs, 0.0)[..., None])[..., 0]
        r = v - np.sum(A * coef[gid], axis=1)
        if it == n_iter:
            break
        mad = 1.4826 * group_median(np.where(keep, np.abs(r), np.nan), gid, G)
        new = np.abs(r) <= np.maximum(k_mad * np.nan_to_num(mad, nan=np.inf), floor)[gid]
        if np.array_equal(new, keep):
            break
        keep = new
    w = keep.astype(float)
    s2 = np.bincount(gid, w * r * r, G) / np.maximum(n - p, 1)
    cov = s2[:, None, None] * np.linalg.inv(Mg)
    coef[~good] = np.nan
    return coef, cov, s2, n


def curved_face_corners(pts, grp, lines, curved, *, radius_px: float, s2_floor: float = 0.0,
                        min_points: int = 5, significance: float = 16.0, start_px: float = 0.0,
                        max_start: float = 0.1, max_sin: float = 0.7, partner=None, lone_sigma: float = 6.0,
                        max_bulge_px: float = 1.0, fit=None, view=None, keep_far: bool = True):
    """Corners where a circular face meets the outer edge, the face seen a little from the side.

    A slot or tip face is a circle of radius ``R`` about the tube's axis. Seen
    exactly from the side it is a straight edge; when the view looks a little
    along the tube (the tube tilted out of the image plane, or off the lens's
    axis) it is an arc of an ellipse: ``R`` across the tube, ``R sin β``
    along it, tangent to the outer edge (the limb) at the corner. A straight
    line fitted to such an arc meets the limb up to ``0.3 R sin β`` off (0.01
    mm at 3° on a 1.62 mm tube). In the limb's frame (``u`` across the tube
    from the limb, ``v`` along it) the face is ``v = v0 + c u + b sqrt(u (2R -
    u))``; the corner is the limb's point at ``v0``. The arc term is kept only
    where it reduces the residual sum of squares by more than
    ``significance`` times the residual variance (else the straight line's
    intersection stands), where the face's crossings start within
    ``max_start`` R of where the profiles start (``start_px`` from the
    corner; the arc cannot be extrapolated from a face seen only far from
    its corner, as next to a nearly closed mouth) and
    ``|b| ≤ max_sin`` (a view within about 44° of the side). A face whose arc
    is significant with ``|b|`` beyond that leaves its corner not ok: a
    straight line would meet the limb about ``0.5 R |b|`` off, on the face's
    far rim (a phone lens seeing a thick tube's slots 20° from the side puts
    a slot's corner nearer its partner's true position than its own).

    Parameters
    ----------
    pts : ndarray (P, 2)
        Undistorted 50 % crossings; ``grp`` (P,) their edge 0..2K-1.
    lines : refine.CornerLines
        The straight-line fits of every edge and their corners; a copy with the corners, covariances and
        ok flags updated is returned (a corner whose face is seen only far from it, in a view where the
        faces' arcs bulge by more than ``max_bulge_px``, is not ok: no line or arc extrapolates to it; with
        ``view``, the pass's :class:`.mouth.MouthView`, a slot with both so is measured at its mouth, and
        with ``keep_far`` and a camera file, the rest are kept with their whole bulge,
        :func:`far_line_corners`).
    curved : ndarray (2K,) bool
    radius_px : float
        Tube radius in ideal pixels.
    partner : ndarray (K,) int, optional
        The corner whose face is seen from about the same side (the slot's
        other corner, the tip's other corner; -1: none): an arc is kept only
        where the partner's arc agrees with it, or, where the partner has
        none, when it is ``lone_sigma`` standard errors from zero.
    fit : ndarray (2K,) bool, optional
        The curved edges worth an arc fit (default all); every curved edge is
        checked for being seen only far from its corner.
    """
    c, dd = lines.c, lines.dd
    X, cov, okc = lines.X.copy(), lines.cov.copy(), lines.ok.copy()
    fits, far, steep = _corner_arcs(pts, grp, lines, curved, radius_px=radius_px, s2_floor=s2_floor,
                                    min_points=min_points, significance=significance, max_sin=max_sin,
                                    max_u0=start_px + max_start * radius_px, fit=curved if fit is None else fit)
    okc[steep] = False
    used = []
    for k, ((v0, var_v0, b, sd_b), limb_e) in fits.items():
        q = -1 if partner is None else int(partner[k])
        if q >= 0:
            # the partner (the slot's other face, the tip face's other end) is seen from about the same
            # side: its arc must agree (a JPEG block or a streak makes a spurious one on one face); an arc
            # without a partner's must be clear by itself
            if q not in fits and abs(b) < lone_sigma * sd_b:
                continue
            if q in fits and abs(abs(b) - abs(fits[q][0][2])) > 3 * math.hypot(sd_b, fits[q][0][3]) + 0.25 * abs(b):
                continue
        d = dd[limb_e]
        nrm = np.array([-d[1], d[0]])
        X[k] = c[limb_e] + v0 * d
        var_n = float(np.dot(nrm, cov[k] @ nrm))        # across the limb: the limb's own uncertainty
        cov[k] = var_v0 * np.outer(d, d) + var_n * np.outer(nrm, nrm)
        used.append(abs(b))
    # where the view is oblique (the faces' arcs bulge by more than ``max_bulge_px``), a face seen only far
    # from its corner cannot be extrapolated to it, by a line or an arc: that corner is not found
    if far and used and float(np.median(used)) * radius_px > max_bulge_px:
        okc[far] = False
        out = replace(lines, X=X, cov=cov, ok=okc)
        if view is not None and partner is not None:
            out = with_mouths(out, shut_mouths(
                pts, grp, far, partner, curved, replace(view, sin_view=float(np.median(used))), s2_floor=s2_floor,
                min_points=min_points, max_start=start_px + max_start * radius_px))
        if keep_far and view is not None and not isinstance(view.camera, DiameterScale):
            # only where a camera file bounds the bulge: without one the view is an assumption
            out = far_line_corners(out, [k for k in far if not out.ok[k]], curved, radius_px=radius_px,
                                   sin_view=float(np.median(used)), camera=view.camera)
        return out
    return replace(lines, X=X, cov=cov, ok=okc)


def far_line_corners(lines, ks, curved, *, radius_px: float, sin_view: float, camera=None, margin: float = 0.5):
    """Corners ``ks`` whose face is seen only far from them, kept at their straight lines' intersection with
    the arc's whole bulge as a systematic error along the limb.

    Seen ``β`` from the side the face is an arc ``R sin β`` deep along the limb, tangent to it at the
    corner; where the face is seen only far from the corner (the limb's mirror strip hides it next to the
    limb), the straight line through its far part meets the limb up to that whole bulge off, to one side
    or the other as its front or back rim is seen. That bound is taken as the standard deviation along the
    limb (``sin β`` the larger of the faces' measured arcs, ``sin_view``, and the camera's view of this
    corner, :func:`view_sines`, where a ``camera`` is given). A corner is kept only where that bulge is
    below ``margin`` times its distance to every other corner's line intersection: moved by its whole
    bulge it stays nearer its own position than any other's (a slot nearly closed, its corners a pixel or
    two apart, stays withheld: there the line's corner can lie nearer the partner).

    Parameters
    ----------
    lines : refine.CornerLines
        With the withheld corners' line intersections ``X`` (K, 2) [ideal px]; ``curved`` (2K,) bool.
    ks : list of int
        The corners seen only far from their face.

    Returns
    -------
    refine.CornerLines
        A copy with ``ks``' kept corners ``ok`` and the bulge's covariance [px²] added to ``cov_view``.
    """
    K = len(lines.X)
    ks = [k for k in ks if np.all(np.isfinite(lines.X[k])) and curved[k] != curved[K + k]]
    if not ks:
        return lines
    ks = np.array(ks)
    d_limb = np.where(curved[ks][:, None], lines.dd[K + ks], lines.dd[ks])
    sin_b = np.full(len(ks), sin_view)
    if camera is not None:
        sin_b = np.fmax(sin_b, view_sines(camera, lines.X[ks], d_limb))
    bulge = radius_px * sin_b
    gap = np.linalg.norm(lines.X[ks, None, :] - lines.X[None, :, :], axis=2)
    gap[np.arange(len(ks)), ks] = np.inf
    keep = bulge < margin * np.nanmin(np.where(np.isfinite(gap), gap, np.inf), axis=1)
    if not keep.any():
        return lines
    ok = lines.ok.copy()
    cov_view = np.zeros_like(lines.cov) if lines.cov_view is None else lines.cov_view.copy()
    for k, b, d in zip(ks[keep], bulge[keep], d_limb[keep]):
        ok[k] = True
        cov_view[k] = cov_view[k] + b * b * np.outer(d, d)
    return replace(lines, ok=ok, cov_view=cov_view)


def _corner_arcs(pts, grp, lines, curved, *, radius_px, max_u0, fit, s2_floor: float = 0.0,
                 min_points: int = 5, significance: float = 16.0, max_sin: float = 0.7):
    """The arc model of every curved face in its limb's frame (``u`` across from the limb, ``v`` along it),
    all faces in one batched fit: {corner: ((v0, var v0, b, sd b), limb edge)} where the arc is significant,
    the corners whose face's crossings start beyond ``max_u0`` from the limb, and the corners whose arc is
    significant but seen more than ``max_sin`` from the side (the tolerances of :func:`curved_face_corners`)."""
    K, c, dd, okc = len(lines.X), lines.c, lines.dd, lines.ok
    cand = [(k, fe, le) for k in range(K) for fe, le in ((k, K + k), (K + k, k))
            if curved[fe] and not curved[le] and okc[k]]
    us, vs, gs, far = [], [], [], []
    order = np.argsort(grp, kind="stable")
    first = np.searchsorted(grp[order], np.arange(2 * K + 1))
    faces = []
    for g, (k, fe, le) in enumerate(cand):
        rel = pts[order[first[fe]:first[fe + 1]]] - c[le]
        if len(rel) >= min_points + 3:
            d = dd[le]
            faces.append((g, k, fe, rel @ np.array([-d[1], d[0]]), rel @ d))
    # u measured from the limb into the tube: its median is positive (all faces' medians in one call)
    med_u = group_median(np.concatenate([f[3] for f in faces]), np.repeat(np.arange(len(faces)),
                                                                          [len(f[3]) for f in faces]),
                         len(faces)) if faces else np.zeros(0)
    for (g, k, fe, u, v), m_u in zip(faces, med_u):
        u = u * (1.0 if m_u >= 0 else -1.0)
        near = u <= radius_px            # the half of a face next to this corner (the tip face is 2R long)
        if not near.any() or u[near].min() > max_u0:
            far.append(k)                # a face seen only far from the corner (a nearly closed mouth)
            continue
        if not fit[fe]:
            continue
        us.append(u[near])
        vs.append(v[near])
        gs.append(np.full(int(near.sum()), g))
    if not us:
        return {}, far, []
    u, v, gid = np.concatenate(us), np.concatenate(vs), np.concatenate(gs)
    G = len(cand)
    line = _face_fits(u, v, gid, G, radius_px, curved=False)
    ell = _face_fits(u, v, gid, G, radius_px, curved=True)
    gain = line[2] * (line[3] - 2) - ell[2] * (ell[3] - 3)
    sig = np.isfinite(ell[0][:, 0]) & np.isfinite(line[0][:, 0]) & (gain > significance * np.maximum(ell[2], s2_floor))
    ok = sig & (np.abs(ell[0][:, 2]) <= max_sin)
    steep = [cand[g][0] for g in np.nonzero(sig & ~ok)[0]]
    fits = {}
    for g in np.nonzero(ok)[0]:
        k, _, le = cand[g]
        fits[k] = ((ell[0][g, 0], max(ell[1][g, 0, 0], s2_floor / ell[3][g]), ell[0][g, 2],
                    math.sqrt(max(ell[1][g, 2, 2], 0.0))), le)
    return fits, far, steep


def face_view_cov(camera, X, dd, curved, use, pts, grp, *, radius_px: float, factor: float = 0.5,
                  significance: float = 9.0, shrink: tuple = (0.5, 0.25, 0.125), assume=None,
                  mirror_factor: float = 1.0) -> np.ndarray:
    """Covariance (K, 2, 2) [ideal px²] along the outer edge of corners whose circular face was fitted as a
    straight line, from how far the camera sees that face from the side.

    The face is a circle of radius ``R`` about the tube's axis; a view ray at
    angle β to its plane sees it as an ellipse ``b = R sin β`` wide along the
    axis, tangent to the outer edge at the corner. A straight line through
    the visible part of that arc meets the outer edge about ``factor b`` off
    the corner (0.46-0.54 measured on the physically based printed tube,
    whose faces are too short for the arc to be told from a line), to one
    side or the other as the face is seen from its front or its back: a
    standard deviation of ``factor b`` along the edge. ``sin β`` is the view
    ray's component along the tube's axis (the outer edge's direction taken
    to the plane, then to the camera's frame). The term is given only where
    the face's crossings allow that arc: where the arc ``v = v0 + c u ± b
    sqrt(u (2R - u))`` fits them worse than the straight line by more than
    ``significance`` times their residual variance (a flat outline, as a
    silhouette drawn in the plane, is a straight line along its whole
    length), the face is straight and the line's corner stands. Without a
    camera file (:class:`~.view.DiameterScale`) the view is an assumption
    (a normal lens facing the plane), so ``sin β`` is only bounded by it: a
    face whose crossings refuse the assumed arc is tried with the arc
    narrowed by each of ``shrink`` in turn, and the widest arc they allow
    gives the term (a longer focal length than assumed sees the face less
    from the side; refusing the assumed arc does not make the face straight).

    Parameters
    ----------
    camera : CameraModel or DiameterScale
        With the plane's pose (``camera_matrix``, ``plane_rotation``, ``plane_homography``).
    X : ndarray (K, 2)
        Ideal corners [px].
    dd : ndarray (2K, 2)
        Unit directions of every corner's incoming (0..K-1) and outgoing (K..2K-1) edge [ideal px].
    curved : ndarray (2K,) bool
        The edges that are circular faces.
    use : ndarray (K,) bool
        The corners to consider.
    pts, grp : ndarray (P, 2), (P,)
        Undistorted edge crossings [px] and their edge 0..2K-1.
    radius_px : float
        The tube's radius [ideal px].
    assume : ndarray (K,) bool, optional
        Corners whose face's crossings are not asked (``CornerSpecs.outside``): the arc is assumed.
    mirror_factor : float
        Those corners' bias in units of ``b`` where a camera file gives the view: their limb mirrors the
        backdrop, so does their face (the same polished surface), so the slot's visible boundary lies up
        to the face's far rim and the line meets the limb up to the whole bulge off (0.7-1.0 ``b`` on the
        physically based polished wrists). Without a camera file the assumed view's ``sin β`` already
        bounds it from above (a normal lens sees the faces more from the side): ``factor`` is kept.
    """
    K = len(X)
    out = np.zeros((K, 2, 2))
    ks = np.nonzero(use & (curved[:K] != curved[K:]))[0]    # one face (not two: the tip seen end-on)
    if not len(ks):
        return out
    fe = np.where(curved[ks], ks, K + ks)
    d_limb = np.where(curved[ks][:, None], dd[K + ks], dd[ks])
    sin_b = view_sines(camera, X[ks], d_limb)
    allowed = arcs_allowed(pts, grp, X[ks], fe, d_limb, sin_b, radius_px, significance)
    if assume is not None:
        allowed |= assume[ks]
    if isinstance(camera, DiameterScale):
        assumed = sin_b
        for f in shrink:
            retry = ~allowed & np.isfinite(assumed)
            if not retry.any():
                break
            ok = retry & arcs_allowed(pts, grp, X[ks], fe, d_limb, f * assumed, radius_px, significance)
            sin_b, allowed = np.where(ok, f * assumed, sin_b), allowed | ok
    mirror = assume is not None and not isinstance(camera, DiameterScale)
    fac = np.where(assume[ks], mirror_factor, factor) if mirror else factor    # a mirroring face: to its far rim
    var = np.where(np.isfinite(sin_b) & allowed, (fac * radius_px * sin_b) ** 2, 0.0)
    out[ks] = var[:, None, None] * d_limb[:, :, None] * d_limb[:, None, :]
    return out


def view_sines(camera, X, d_limb, *, signed: bool = False) -> np.ndarray:
    """(n,) ``sin β``: how far the camera sees a face at each corner ``X`` (n, 2) [ideal px] from the side,
    the view ray's component along the tube's axis (the outer edge's direction ``d_limb`` (n, 2) taken to
    the plane, then to the camera's frame); ``signed``: positive where the ray, from the camera into the
    scene, runs along ``d_limb``."""
    ends = np.concatenate([X, X + 5.0 * d_limb])
    pl = np.c_[ends, np.ones(len(ends))] @ np.linalg.inv(camera.plane_homography).T
    pl = pl[:, :2] / pl[:, 2:]
    axis = (pl[len(X):] - pl[:len(X)]) @ camera.plane_rotation[:, :2].T
    ray = np.c_[X, np.ones(len(X))] @ np.linalg.inv(camera.camera_matrix).T
    with np.errstate(invalid="ignore", divide="ignore"):
        sin_b = np.sum(ray * axis, 1) / (np.linalg.norm(ray, axis=1) * np.linalg.norm(axis, axis=1))
    return sin_b if signed else np.abs(sin_b)


def known_arc_corners(camera, lines, curved, use, pts, grp, *, radius_px: float, s2_floor: float = 0.0,
                      prefer: float = 0.0, min_points: int = 5, max_u0: float = np.inf, view_sd: float = 0.01):
    """Corners of faces left straight lines, measured again with the arc the camera's view gives them.

    With a camera file the face's ellipse is known, not a free parameter:
    seen ``β`` from the side a circular face of radius ``R`` is ``v = v0 +
    c u + sin β sqrt(u (2R - u))`` in its limb's frame (``u`` across the
    tube from the limb, ``v`` along it), ``sin β`` the view ray's signed
    component along ``v`` (:func:`view_sines`): the visible boundary is the
    face's front rim, the one nearer the camera (behind it the camera looks
    into the hollow tube), which bulges into the slot where the ray runs
    towards the slot and into the tube where it runs away from it (the
    physically based printed tube's straight faces are off to the side this
    gives on every face). Fitting that
    edge model (the arc subtracted, ``v0`` and ``c`` robustly fitted) puts
    the corner at the limb's point ``v0`` instead of the straight line's
    intersection about ``0.5 R sin β`` off. The view is known to ``view_sd``
    [rad] (the plane's pose from a board, the tube lying in that plane): its
    effect on ``v0`` (the fit's response to the arc term) is returned as a
    systematic covariance along the limb. Only faces whose crossings fit
    that arc better than a straight line (by ``prefer`` times the line's
    residual variance; both models have the same two free parameters, so
    the better fit is the likelier one): a flat outline, as a silhouette
    drawn in the plane, keeps its line. And only faces seen within
    ``max_u0`` of their corner.

    Parameters
    ----------
    camera : CameraModel
        With the plane's pose (not :class:`~.view.DiameterScale`: there the view is only assumed).
    lines : refine.CornerLines
        The line fits and their corners [ideal px].
    curved : ndarray (2K,) bool
    use : ndarray (K,) bool
        The corners to measure again (their face left a straight line).
    pts, grp : ndarray (P, 2), (P,)
        Undistorted crossings [px] and their edge 0..2K-1.

    Returns
    -------
    X, cov : ndarray (K, 2), (K, 2, 2)
        The corners [ideal px] and their covariance [px²] (unchanged where not measured again).
    cov_view : ndarray (K, 2, 2)
        The covariance the view's uncertainty adds [px²].
    fixed : ndarray (K,) bool
        The corners measured with the known arc.
    """
    K, c, dd = len(lines.X), lines.c, lines.dd
    X, cov, fixed = lines.X.copy(), lines.cov.copy(), np.zeros(K, bool)
    cov_view = np.zeros((K, 2, 2))
    ks = np.nonzero(use & (curved[:K] != curved[K:]))[0]
    if not len(ks):
        return X, cov, cov_view, fixed
    fe = np.where(curved[ks], ks, K + ks)
    le = np.where(curved[ks], K + ks, ks)
    sin_b = view_sines(camera, X[ks], dd[le], signed=True)
    rss, s2, few = arc_residuals(pts, grp, X[ks], fe, dd[le], np.nan_to_num(sin_b), radius_px)
    ok = np.isfinite(sin_b) & ~few & (rss[0] - rss[1] > prefer * s2)
    us, vs, gs, arcs = [], [], [], []
    for g in np.nonzero(ok)[0]:
        rel = pts[grp == fe[g]] - c[le[g]]
        d = dd[le[g]]
        u, v = rel @ np.array([-d[1], d[0]]), rel @ d
        u = u * (1.0 if np.median(u) >= 0 else -1.0)
        near = u <= radius_px
        if near.sum() < min_points + 3 or u[near].min() > max_u0:
            continue
        arcs.append(np.sqrt(np.clip(u[near] * (2 * radius_px - u[near]), 0, None)))
        us.append(u[near])
        vs.append(v[near] - sin_b[g] * arcs[-1])
        gs.append(np.full(int(near.sum()), g))
    if not us:
        return X, cov, cov_view, fixed
    u, gid = np.concatenate(us), np.concatenate(gs)
    coef, cf, _, n = _face_fits(u, np.concatenate(vs), gid, len(ks), radius_px, curved=False)
    # how far v0 moves per unit of the arc's coefficient: a line's intercept fitted to the arc itself
    sens = _face_fits(u, np.concatenate(arcs), gid, len(ks), radius_px, curved=False, floor=np.inf)[0][:, 0]
    for g in np.nonzero(np.isfinite(coef[:, 0]))[0]:
        k, d = ks[g], dd[le[g]]
        nrm = np.array([-d[1], d[0]])
        var_n = float(np.dot(nrm, cov[k] @ nrm))     # across the limb: the limb's own uncertainty
        X[k] = c[le[g]] + coef[g, 0] * d
        cov[k] = max(cf[g, 0, 0], s2_floor / n[g]) * np.outer(d, d) + var_n * np.outer(nrm, nrm)
        cov_view[k] = (sens[g] * view_sd) ** 2 * np.outer(d, d)
        fixed[k] = True
    return X, cov, cov_view, fixed


def straight_face_corners(camera, lines, on_line, curved, pts, grp, *, radius_px: float, s2_floor: float = 0.0,
                          min_points: int = 5, start_px: float = 0.0, view_bias: float = 0.5, outside=None,
                          known_arc: bool = True, max_start: float = 0.1):
    """The corners of curved faces left straight lines (``on_line`` (K,) bool): with a camera file measured
    again with the arc its view gives (:func:`known_arc_corners`, not next to a mirroring limb,
    ``outside``), the rest given the covariance of their unseen arc (:func:`face_view_cov`, ``view_bias``).
    Corners whose ``lines.cov_view`` already holds a view term (a face seen only far from its corner, kept
    with its whole bulge; a slot measured at its mouth) are left as they are.

    Returns the corners (K, 2) [ideal px], their fit covariance and the systematic covariance to add
    (K, 2, 2) [px²].
    """
    X, cov = lines.X, lines.cov
    cov_sys = np.zeros((len(X), 2, 2))
    on_line = on_line.copy()
    if lines.cov_view is not None:
        on_line &= ~np.any(lines.cov_view, axis=(1, 2))     # their view term is in cov_view already
    if on_line.any() and known_arc and not isinstance(camera, DiameterScale):
        # with a camera file the face's arc is known: the face is measured with it, not as a line
        # (not next to a mirroring limb: there the face's crossings are a mirror image's boundary)
        use = on_line if outside is None else on_line & ~outside
        X, cov, cov_sys, fixed = known_arc_corners(camera, lines, curved, use, pts, grp, radius_px=radius_px,
                                                   s2_floor=s2_floor, min_points=min_points,
                                                   max_u0=start_px + max_start * radius_px)
        on_line &= ~fixed
    if on_line.any():
        # a face left straight meets the limb off its corner by about half its arc's bulge, which the
        # camera's view of the plane tells (without a camera file, the view DiameterScale assumes)
        cov_sys = cov_sys + face_view_cov(camera, X, lines.dd, curved, on_line, pts, grp, radius_px=radius_px,
                                          factor=view_bias, assume=outside)
    return X, cov, cov_sys
