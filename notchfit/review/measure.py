"""What the review page shows about one sample's corners: the live free-θ fit and the angles by hand.

Both take the sample's current corners (detections with the corrections
applied) in the plane frame [m] and return plain dictionaries the page draws.
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis.fitting import fit_experiment
from ..physics.geometry import Geometry, notch_layout

__all__ = ["hand_angles", "live_fit"]


def live_fit(points, sigma, geom: Geometry, *, mirror: bool = False) -> dict:
    """Fit one sample with the ``free`` shape model (one θ per joint) and its own plane transform.

    The residual of every corner, also of those the fit leaves out (an
    ``ambiguous`` detection, NaN sigma), makes a misplaced corner stand out:
    it is the one the fit disagrees with.

    Parameters
    ----------
    points : array (m, 2) [m]
        Plane-frame corners, NaN = missing.
    sigma : array (m,) [m]
        Uncertainty of each corner; a corner with NaN sigma is not fitted.
    geom : Geometry
    mirror : bool

    Returns
    -------
    dict
        ``ok`` (bool), ``message``, ``residual_mm`` (m,) (None where the
        corner has no position), ``used`` (m,) bool, ``rms_mm``,
        ``theta_deg`` (n,), ``chi2_dof`` (the weighted residual per degree
        of freedom: about 1 when the stated sigmas hold), ``predicted``
        (m, 2) [m] the fitted corners in the plane (None when not fitted).
    """
    Q = np.asarray(points, float)
    sig = np.asarray(sigma, float)
    has = np.isfinite(Q).all(-1)
    used = has & np.isfinite(sig)
    m = len(Q)
    out = {"ok": False, "residual_mm": [None] * m, "used": used.tolist(), "rms_mm": None,
           "theta_deg": None, "chi2_dof": None, "predicted": None}
    if 2 * used.sum() <= geom.n_joints + 3:
        out["message"] = (f"{int(used.sum())} corners: the free fit of {geom.n_joints} joint angles and the "
                          f"plane transform needs more than {(geom.n_joints + 3) // 2}")
        return out
    try:
        fit = fit_experiment(np.where(used[:, None], Q, np.nan)[None], geom, ("free",), mirror=mirror,
                             sigma=np.where(used, sig, np.nan)[None], include_transform_uncertainty=False)
    except ValueError as exc:
        out["message"] = f"fit failed: {exc}"
        return out
    sf = fit.fits[0][0]
    err = np.hypot(*(Q - sf.predicted).T)
    e_used = err[used]
    dof = max(2 * int(used.sum()) - geom.n_joints - 3, 1)
    out.update(ok=bool(sf.success), message=sf.message,
               residual_mm=[None if not np.isfinite(e) else float(e * 1e3) for e in err],
               rms_mm=float(np.sqrt(np.mean(e_used ** 2)) * 1e3),
               theta_deg=[float(math.degrees(t)) for t in sf.theta],
               chi2_dof=float(np.sum((e_used / sig[used]) ** 2) / dof), predicted=sf.predicted)
    return out


def _link_poses(Q, geom: Geometry, mirror: bool):
    """Per link: the rotation α [rad] and the point pair (local centroid, plane centroid) that carry the
    straight tube's corners of that link onto the measured ones (2-D Procrustes), or None (< 2 corners)."""
    lay = notch_layout(geom)
    M = np.array([-1.0, 1.0]) if mirror else np.ones(2)
    local = lay.straight * M
    poses = []
    for k in range(geom.n_joints + 1):
        sel = (lay.link == k) & np.isfinite(Q).all(-1)
        if sel.sum() < 2:
            poses.append(None)
            continue
        a = local[sel] - local[sel].mean(0)
        b = Q[sel] - Q[sel].mean(0)
        alpha = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
        poses.append((alpha, local[sel].mean(0), Q[sel].mean(0)))
    return lay, M, poses


def _place(pose, M, xz) -> list:
    """Straight-tube point ``xz`` [m] of a link, carried into the plane by the link's pose."""
    alpha, lc, qc = pose
    c, s = math.cos(alpha), math.sin(alpha)
    d = np.asarray(xz, float) * M - lc
    return [float(qc[0] + c * d[0] - s * d[1]), float(qc[1] + s * d[0] + c * d[1])]


def hand_angles(points, geom: Geometry, *, mirror: bool = False) -> dict:
    """Joint angles from the corners, as a person measures them by drawing the two cut faces of each notch.

    Each link's corners fix its orientation in the plane (the straight
    tube's corners of that link rotated onto them, least squares); the
    angle of joint j is the turn from link j-1 to link j, i.e. the angle
    between the slot's two cut faces (the rest angle included, the sign of
    docs/geometry.md: with ``P = Rot(φ) M (x, z) + t`` a positive θ turns
    the plane frame clockwise, anticlockwise when mirrored). The faces are
    drawn from the slot's two corners into the tube, one cut depth long,
    perpendicular to their link's axis.

    Parameters
    ----------
    points : array (m, 2) [m]
        Plane-frame corners, NaN = missing.
    geom : Geometry
    mirror : bool

    Returns
    -------
    dict
        ``theta`` (n,) [rad] (NaN where a neighbouring link has fewer than
        two corners) and ``faces``: per joint ``[proximal face, distal face]``,
        each ``[[x, y], [x, y]]`` [m] in the plane, or None.
    """
    Q = np.asarray(points, float)
    lay, M, poses = _link_poses(Q, geom, mirror)
    sign = 1.0 if mirror else -1.0
    n = geom.n_joints
    theta = np.full(n, np.nan)
    faces = [None] * n
    depth = geom.slot_depths
    for j in range(1, n + 1):
        before, after = poses[j - 1], poses[j]
        if before is None or after is None:
            continue
        d = math.remainder(after[0] - before[0], 2 * math.pi)
        theta[j - 1] = sign * d
        pair = []
        for kind, pose in (("proximal", before), ("distal", after)):
            q = int(np.flatnonzero((lay.joint == j) & (np.asarray(lay.kind) == kind))[0])
            x, z = lay.straight[q]
            inner = (x - lay.side[q] * depth[j - 1], z)
            pair.append([_place(pose, M, (x, z)), _place(pose, M, inner)])
        faces[j - 1] = pair
    return {"theta": theta, "faces": faces}
