"""Stage 6: map the refined corners to the plane and check them against rigid-link dimensions.

Base and tip corners lie on rigid links ``2R`` apart: a wrong camera file
gives ``ambiguous`` points and a message, not wrong millimetres. The base
corners and the first slot's proximal corner lie on link 0: where the
tube-holder corners are not at that distance from the slot, the holder's
face is not the base edge and the base points are hidden (``occluded``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...physics.geometry import notch_layout
from .dims import slot_widths
from .result import Detection

__all__ = ["PlaneInput", "base_edge_offset", "finish", "link_distances", "rigid_link_check", "to_plane_points"]


@dataclass(frozen=True)
class PlaneInput:
    """The refined corners stage 6 maps to the plane (:func:`finish`), kept to map them again at another
    scale (no calibration).

    Attributes
    ----------
    pts_px, ideal : ndarray (m, 2)
        Raw and ideal (undistorted) corners [px], NaN where not found.
    cov : ndarray (m, 2, 2)
        Covariance of the ideal corners [px²].
    status : list of str (m,)
    messages : list of str
    blur : float
        Edge blur σ [px].
    contour_px : ndarray (N, 2) or None
        The bridged outline [px] (overlays).
    side : str
        The image side the base points to.
    """

    pts_px: np.ndarray
    ideal: np.ndarray
    cov: np.ndarray
    status: list
    messages: list
    blur: float
    contour_px: np.ndarray
    side: str


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


def link_distances(plane, ok, geom) -> dict:
    """Every pair of ok points on one link with its measured and straight-configuration distance:
    ``{link: [(i, j, d_measured, d_expected), ...]}`` (i < j) [m]; the links are rigid, so the two agree
    whatever the joint angles (geometry.md)."""
    lay = notch_layout(geom)
    out = {}
    for link in np.unique(lay.link):
        idx = [int(i) for i in np.nonzero(lay.link == link)[0] if ok[i]]
        out[link] = [(i, j, float(np.linalg.norm(plane[i] - plane[j])),
                      float(np.linalg.norm(lay.straight[i] - lay.straight[j])))
                     for a, i in enumerate(idx) for j in idx[a + 1:]]
    return out


def rigid_link_check(plane, ok, geom, *, rel_tol: float, abs_tol: float, need_partner=()):
    """Ok points that disagree with their own link's rigid shape, and points left unconfirmed (m,) bool x 2.

    The corners on one link keep their straight-configuration distances
    whatever the joint angles (the links are rigid; geometry.md). For every
    pair of ok points on a link the measured distance must match within
    ``max(rel_tol d, abs_tol)`` [m]. While a pair disagrees, the point of a
    disagreeing pair with the largest sum of normalised misfits over its
    pairs is an outlier (a slot numbered one off, a holder corner taken for a
    base point); of two points that disagree a base or tip point is the
    outlier, else both are. A point of
    ``need_partner`` (numbered by position, a base or a tip point) is
    unconfirmed unless another point of its link agrees with it (for a base
    or tip point, a slot corner: the pair's other point is no confirmation).
    """
    lay = notch_layout(geom)
    m = len(ok)
    bad, unconfirmed = np.zeros(m, bool), np.zeros(m, bool)
    for link, pairs in link_distances(plane, ok, geom).items():
        idx = [int(i) for i in np.nonzero(lay.link == link)[0] if ok[i]]
        mis = {(i, j): abs(d_meas - d_exp) / max(rel_tol * d_exp, abs_tol) for i, j, d_meas, d_exp in pairs}
        live = set(idx)
        while True:
            pairs = [p for p, e in mis.items() if p[0] in live and p[1] in live]
            worst = [p for p in pairs if mis[p] > 1]
            if not worst:
                break
            score = {i: sum(mis[p] for p in pairs if i in p) for i in live}
            cands = {i for p in worst for i in p}
            top = max(score[i] for i in cands)
            drop = [i for i in cands if score[i] >= top - 1e-9]
            ends = [i for i in drop if lay.kind[i] in ("base", "tip")]
            drop = ends or drop                  # a holder's face off the base edge: its corner goes first
            live -= set(drop)
            bad[drop] = True
        for i in need_partner:
            end_i = lay.kind[i] in ("base", "tip")      # a base or tip point needs a slot corner, not its pair
            if i in live and not any((min(i, j), max(i, j)) in mis and mis[(min(i, j), max(i, j))] <= 1
                                     for j in live if j != i and not (end_i and lay.kind[j] == lay.kind[i])):
                unconfirmed[i] = True
    return bad, unconfirmed


def _drop_link_outliers(plane, sigma, status, msg, geom, link_tol, need_partner):
    """Mark the rigid-link outliers and unconfirmed points ambiguous (see :func:`rigid_link_check`)."""
    ok = np.array([s == "ok" for s in status])
    bad, unconf = rigid_link_check(plane, ok, geom, rel_tol=link_tol[0], abs_tol=link_tol[1],
                                   need_partner=need_partner)
    if bad.any():
        msg = [*msg, "points " + ", ".join(str(i + 1) for i in np.nonzero(bad)[0]) + " do not fit their rigid "
               "links (numbered wrongly or not a notch corner): not used"]
    if unconf.any():
        msg = [*msg, "points " + ", ".join(str(i + 1) for i in np.nonzero(unconf)[0]) + " could not be "
               "confirmed by another corner of their link: not used"]
    # a slot corner off its link by a link's length means the side's slots are numbered one off: every
    # slot corner of that side is doubtful (the links between slots all have one length)
    lay = notch_layout(geom)
    slot = np.array([k in ("proximal", "distal") for k in lay.kind])
    for side in (-1, 1):
        if np.any(bad & slot & (lay.side == side)):
            side_pts = slot & (lay.side == side) & ok & ~bad
            if side_pts.any():
                msg = [*msg, f"the {'right' if side > 0 else 'left'} side's slot numbering is doubtful: its slot "
                             "corners are not used"]
                bad |= side_pts
    # the slots' numbers come from their agreement with the rigid-link chain (numbering.py): a slot that
    # the chain numbers in one way only keeps its number without an end link found whole
    drop = bad | unconf
    for i in np.nonzero(drop)[0]:
        status[i] = "ambiguous"
        plane[i] = np.nan
        sigma[i] = np.nan
    return msg


def finish(camera, geom, p: PlaneInput, *, scale_tol, base_edge_tol, check_base=True, link_tol=None, need_partner=(),
           **extra) -> Detection:
    """Plane points, scale, base-edge and rigid-link checks, statuses and the message.

    ``p.pts_px`` is the detection's pixel array (base points hidden by the base-edge check are set NaN in it);
    ``p.side`` is the detection's ``base_side``.

    ``need_partner``: points whose identity must be confirmed by a rigid-link
    partner (:func:`rigid_link_check`); base and tip points always need one.
    """
    pts_px, ideal, cov, msg, blur = p.pts_px, p.ideal, p.cov, p.messages, p.blur
    m = len(p.status)
    lay = notch_layout(geom)
    status = list(p.status)
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
        ends = [i for i in range(m) if lay.kind[i] in ("base", "tip")]
        msg = _drop_link_outliers(plane, sigma, status, msg, geom, link_tol, sorted(set(need_partner) | set(ends)))
    n_ok = sum(s == "ok" for s in status)
    if n_ok == m:
        ist, text = "ok", ""
    else:
        ist = "partial"
        bad = [str(i + 1) for i in range(m) if status[i] != "ok"]
        text = "; ".join(msg + [f"{m - n_ok} of {m} points not ok: " + ", ".join(bad[:20])
                                + (" ..." if len(bad) > 20 else "")])
    return Detection(plane, pts_px, sigma, tuple(status), ist, text, p.contour_px, float(blur), base_side=p.side,
                     **extra)


def link_tolerance(geom, opts):
    """(relative, absolute [m]) tolerance of the rigid-link check, or None at a rough scale (no checks)."""
    if not math.isfinite(opts.scale_tol):
        return None
    return opts.link_rel_tol, opts.link_abs_w * float(slot_widths(geom).min())


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
