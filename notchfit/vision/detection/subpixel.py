"""Stage 5 for all located corners at full resolution (:func:`refine_corners`): the refinement passes
(:func:`.refine.refine_pass`), each corner's status (:func:`statuses`), the tube's width beside it
(:func:`link_widths`) and the diameter stations next to it (:func:`edge_stations`)."""

from __future__ import annotations

import math

import numpy as np

from ...physics.geometry import notch_layout
from .lines import unit
from .records import Refinement, Setup
from .refine import CornerSpecs, ProfileLayout, refine_pass

__all__ = ["edge_stations", "link_widths", "refine_corners", "statuses"]


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


def edge_stations(ref, n_per_edge, sgn):
    """Points on the straight outer edge next to every ok corner, with the unit normal into the tube (S, 4)."""
    sp = ref.specs
    K = len(sp.C)
    rows = []
    for k in np.nonzero(ref.ok)[0]:
        for e, (D, L, face) in enumerate(((-sp.Din[k], sp.Lin[k], sp.face[k]), (sp.Dout[k], sp.Lout[k],
                                                                                 sp.face[K + k]))):
            if face or not np.isfinite(L) or L < 8:
                continue
            trav = sp.Din[k] if e == 0 else sp.Dout[k]
            inward = -sgn * np.array([trav[1], -trav[0]])
            for s in np.linspace(0.3, 0.7, n_per_edge) * L:
                P = sp.C[k] + s * D
                rows.append([P[0], P[1], inward[0], inward[1]])
    return np.array(rows).reshape(-1, 4)
