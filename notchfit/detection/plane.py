"""Stage 6: map the refined corners to the plane and check them against rigid-link dimensions.

Base and tip corners lie on rigid links ``2R`` apart: a wrong camera file
gives ``ambiguous`` points and a message, not wrong millimetres. The base
corners and the first slot's proximal corner lie on link 0: where the
tube-holder corners are not at that distance from the slot, the holder's
face is not the base edge and the base points are hidden (``occluded``).
"""

from __future__ import annotations

import numpy as np

from ..geometry import notch_layout
from .dims import slot_widths
from .result import Detection

__all__ = ["base_edge_offset", "to_plane_points", "finish"]


def to_plane_points(camera, ideal, cov, ok):
    """Plane points [m] (m, 2) and per-coordinate σ [m] (m,) of the ok points."""
    m = len(ok)
    plane = np.full((m, 2), np.nan)
    sigma = np.full(m, np.nan)
    if ok.any():
        plane[ok] = camera.ideal_to_plane(ideal[ok])
        J = camera.ideal_to_plane_jacobian(ideal[ok])
        cm = J @ cov[ok] @ np.swapaxes(J, -1, -2)
        sigma[ok] = np.sqrt(np.maximum(np.trace(cm, axis1=-2, axis2=-1) / 2, 0))
    return plane, sigma


def base_edge_offset(plane, ok, geom) -> float:
    """Measured minus expected distance from the base corner to the first slot's proximal corner [m].

    Both lie on link 0, on the side of joint 1's slot: the expected distance
    is ``-w_1/2 - z_base``. NaN when either point is not ok.
    """
    lay = notch_layout(geom)
    side = geom.slot_sides[0]
    ib = [i for i in range(lay.n_points) if lay.kind[i] == "base" and lay.side[i] == side][0]
    ip = [i for i in range(lay.n_points) if lay.kind[i] == "proximal" and lay.joint[i] == 1][0]
    if not (ok[ib] and ok[ip]):
        return float("nan")
    expect = -slot_widths(geom)[0] / 2 - geom.base_edge_z
    return float(np.linalg.norm(plane[ib] - plane[ip]) - expect)


def rigid_link_outliers(plane, ok, geom, *, rel_tol: float, abs_tol: float) -> np.ndarray:
    """Ok points that disagree with their own link's rigid shape (m,) bool.

    The corners on one link keep their straight-configuration distances
    whatever the joint angles (the links are rigid; geometry.md). For every
    pair of ok points on a link the measured distance must match within
    ``max(rel_tol d, abs_tol)`` [m]; a point that disagrees with more of its
    link's points than it agrees with is an outlier (a slot numbered one off,
    a holder corner taken for a base point). Two points that disagree are
    both outliers.
    """
    lay = notch_layout(geom)
    bad = np.zeros(len(ok), bool)
    for link in np.unique(lay.link):
        idx = [i for i in np.nonzero(lay.link == link)[0] if ok[i]]
        if len(idx) < 2:
            continue
        votes = {i: [0, 0] for i in idx}
        for a in range(len(idx)):
            for b in range(a + 1, len(idx)):
                i, j = idx[a], idx[b]
                d_exp = float(np.linalg.norm(lay.straight[i] - lay.straight[j]))
                good = abs(float(np.linalg.norm(plane[i] - plane[j])) - d_exp) <= max(rel_tol * d_exp, abs_tol)
                votes[i][0 if good else 1] += 1
                votes[j][0 if good else 1] += 1
        for i, (yes, no) in votes.items():
            bad[i] = no > yes
    return bad


def _drop_link_outliers(plane, sigma, status, msg, geom, link_tol):
    """Mark the rigid-link outliers ambiguous (see :func:`rigid_link_outliers`)."""
    ok = np.array([s == "ok" for s in status])
    bad = rigid_link_outliers(plane, ok, geom, rel_tol=link_tol[0], abs_tol=link_tol[1])
    if bad.any():
        msg = [*msg, "points " + ", ".join(str(i + 1) for i in np.nonzero(bad)[0]) + " do not fit their rigid "
               "links (numbered wrongly or not a notch corner): not used"]
        for i in np.nonzero(bad)[0]:
            status[i] = "ambiguous"
            plane[i] = np.nan
            sigma[i] = np.nan
    return msg


def finish(camera, geom, pts_px, ideal, cov, status, msg, blur, contour_px, *, scale_tol, base_edge_tol,
           check_base=True, link_tol=None, **extra) -> Detection:
    """Plane points, scale and base-edge checks, statuses and the message."""
    m = len(status)
    lay = notch_layout(geom)
    status = list(status)
    ok = np.array([s == "ok" for s in status])
    plane, sigma = to_plane_points(camera, ideal, cov, ok)
    if check_base:
        off = base_edge_offset(plane, ok, geom)
        if np.isfinite(off) and abs(off) > base_edge_tol * slot_widths(geom)[0]:
            msg = [*msg, f"the tube leaves the holder {off * 1e3:+.3f} mm from the geometry's base edge: "
                         "the base corners are hidden (the holder's face is not the base edge)"]
            for i in range(m):
                if lay.kind[i] == "base":
                    status[i] = "occluded"
                    plane[i] = np.nan
                    sigma[i] = np.nan
                    pts_px[i] = np.nan
            ok = np.array([s == "ok" for s in status])
    pair = {(lay.kind[i], int(lay.side[i])): i for i in range(m) if lay.kind[i] in ("base", "tip")}
    widths = {kd: np.linalg.norm(plane[pair[(kd, -1)]] - plane[pair[(kd, 1)]])
              for kd in ("base", "tip") if ok[pair[(kd, -1)]] and ok[pair[(kd, 1)]]}
    off = {kd: abs(v / (2 * geom.outer_radius) - 1) for kd, v in widths.items()}
    bad = [kd for kd, e in off.items() if e > scale_tol]
    if bad and len(bad) < len(widths):
        # one rigid pair agrees with the scale, the other not: that pair is wrong (a tip cut by the
        # border, a glue droplet), not the camera
        for kd in bad:
            msg = [*msg, f"the {kd} corners are {widths[kd] * 1e3:.3f} mm apart, not "
                         f"{2 * geom.outer_radius * 1e3:.3f} mm: not used"]
            for s in (-1, 1):
                i = pair[(kd, s)]
                status[i] = "ambiguous"
                plane[i] = np.nan
                sigma[i] = np.nan
    elif bad:
        mean_w = np.mean(list(widths.values()))
        msg = [*msg, (f"scale check failed: the tube measures {mean_w * 1e3:.3f} mm across, the "
                      f"geometry says {2 * geom.outer_radius * 1e3:.3f} mm (wrong calibration file, plane "
                      "pose or geometry?)")]
        status = ["ambiguous" if s == "ok" else s for s in status]
        plane[:] = np.nan
        sigma[:] = np.nan
    if link_tol is not None and not (bad and len(bad) == len(widths)):
        msg = _drop_link_outliers(plane, sigma, status, msg, geom, link_tol)
    n_ok = sum(s == "ok" for s in status)
    if n_ok == m:
        ist, text = "ok", ""
    else:
        ist = "partial"
        bad = [str(i + 1) for i in range(m) if status[i] != "ok"]
        text = "; ".join(msg + [f"{m - n_ok} of {m} points not ok: " + ", ".join(bad[:20])
                                + (" ..." if len(bad) > 20 else "")])
    return Detection(plane, pts_px, sigma, tuple(status), ist, text, contour_px, float(blur), **extra)
