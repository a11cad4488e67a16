"""The mouth of a slot bent shut, measured on the limb.

A slot bent shut closes about its backbone until its two faces touch at the mouth, on the tube's outer edge
(the limb) on the slot's side. There the limb of one link meets the limb of the next at the slot's bend angle
(a kink), and both of the slot's corners lie at that kink, apart by the gap left between the faces at the
mouth. Near the kink the gap is narrower than the image resolves, so a face is seen only far from its corner
and cannot be extrapolated to it (:func:`.refine.curved_face_corners`). The kink itself is measured: the two
limbs are straight edges seen up to the mouth, and they meet there (:func:`limb_meeting`). The gap is
bounded too, from the light the backdrop sends through it (:func:`gap_width`): inside the tube, along the
limbs' inward offset across the mouth, the gap is the integral of the image's step toward the backdrop
divided by the contrast, whatever the blur (in a view a little from the side the tube's material hides
part of it, which the bound allows for). Each corner lies half the gap from the kink along the limb, toward
its own link; the kink is reported for both with that half-gap in its covariance (nothing is placed by a
model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from .lines import line_pairs, robust_group_lines

__all__ = ["Mouth", "MouthView", "gap_width", "limb_meeting", "shut_mouth", "shut_mouths", "with_mouths"]


@dataclass(frozen=True)
class MouthView:
    """The image a refinement pass measures (what :func:`gap_width` samples).

    Attributes
    ----------
    img : ndarray (h, w) float32
        A region of the raw image; ``off`` (2,) its position [px].
    camera : object
        Maps ideal pixels to raw ones (``distort_pixels``).
    blur : float
        The edges' Gaussian σ [px].
    radius_px : float
        The tube's radius [ideal px].
    sin_view : float
        How far from the side the slots' faces are seen (``sin β``, from their arcs).
    """

    img: np.ndarray
    off: np.ndarray
    camera: object
    blur: float
    radius_px: float = math.nan
    sin_view: float = 0.0


@dataclass(frozen=True)
class Mouth:
    """A slot's mouth measured where its faces meet the limb.

    Attributes
    ----------
    X : ndarray (2,)
        Where the two links' limbs meet [ideal px].
    cov : ndarray (2, 2)
        Its covariance from the limbs' fits [ideal px²].
    cov_gap : ndarray (2, 2)
        What the unresolved gap adds for either corner of the slot: half the gap along the limb [ideal px²].
    gap_min, gap_max : float
        The narrowest and the widest gap between the faces at the mouth the image allows [px].
    """

    X: np.ndarray
    cov: np.ndarray
    cov_gap: np.ndarray
    gap_min: float
    gap_max: float


def limb_meeting(pa, pb, *, s2_floor: float = 0.0, min_points: int = 5):
    """Where two straight edges meet, from their crossings (robust total-least-squares lines,
    :func:`.lines.robust_group_lines`), and the covariance of that point from each line's offset and angle
    errors (``s² / n + lever² s² / S_tt`` across each line, the residual variance at least ``s2_floor``).

    Parameters
    ----------
    pa, pb : ndarray (Na, 2), (Nb, 2)
        The two edges' crossings [px].

    Returns
    -------
    (X (2,), cov (2, 2), directions (2, 2)) or None (too few points, parallel lines).
    """
    if len(pa) < min_points or len(pb) < min_points:
        return None
    pts = np.concatenate([pa, pb])
    grp = np.repeat([0, 1], [len(pa), len(pb)])
    c, d, n, s2, stt, _ = robust_group_lines(pts, grp, 2)
    if np.any(n < min_points) or np.any(stt <= 0):
        return None
    X, cov, _, det = line_pairs(c, d, n, np.maximum(s2, s2_floor), stt, np.array([0]), np.array([1]))
    if abs(det[0]) < 1e-6:
        return None
    return X[0], cov[0], d


def gap_width(view: MouthView, X, d, into, *, depths=None, reach: float = 3.0, step: float = 0.25,
              min_snr: float = 4.0):
    """The light the backdrop sends through a slot's gap at its mouth, as a width [px] at each depth inside
    the tube: (depths (J,), widths (J,), their standard error), or None where the samples leave the image
    or the backdrop outside the mouth is not ``min_snr`` times the tube's own scatter brighter (or darker)
    than the tube.

    At depth ``u`` the image is sampled along the limbs' inward offset by ``u`` (a line parallel to each
    limb, the two meeting on the bisector), from ``reach`` blur σ beyond the wedge on one link to as far on
    the other: every sample lies ``u`` from its limb, so the limb's blurred edge adds the same light to all
    of them, and a straight baseline through the two ends is the tube. The backdrop's level is sampled just
    outside the mouth. The width is the area between the samples and the baseline over the backdrop's
    contrast: blur moves light, it does not remove it. A face seen a little from the side hides part of
    the gap behind the tube's material (a ray through the gap crosses the whole chord), so the width is the
    gap that shows, at most the gap itself.

    Parameters
    ----------
    X : ndarray (2,)
        The mouth [ideal px]; ``d`` (2, 2) the two limbs' unit directions away from it; ``into`` (2,) the
        unit vector into the tube along their bisector.
    depths : ndarray (J,), optional
        [px]; default 1.5, 2 and 2.5 blur σ (clear of the limb's steepest light, as near the mouth as that
        allows: the gap hides least there).
    """
    b = max(float(view.blur), 0.5) if np.isfinite(view.blur) else 1.0
    d, into = np.asarray(d, float), np.asarray(into, float)
    u = np.array([1.5 * b, 2.0 * b, 2.5 * b]) if depths is None else np.asarray(depths, float)
    # the offset lines meet on the bisector (``into``), u / cos(half the bend) from the mouth
    apex = X + (u / max(abs(float(d[0] @ np.array([into[1], -into[0]]))), 1e-3))[:, None] * into
    length = reach * b + 3.0
    s = np.arange(step / 2, length + 2.0 * b, step)
    rows = np.concatenate([apex[:, None, :] + s[None, ::-1, None] * d[0], apex[:, None, :] + s[None, :, None] * d[1]],
                          axis=1)                                  # (J, 2S, 2): along link a, then link b
    outside = X - (3.0 * b + 1.5) * into + np.linspace(-2.0, 2.0, 9)[:, None] * np.array([-into[1], into[0]])
    raw = view.camera.distort_pixels(np.concatenate([rows.reshape(-1, 2), outside])) - view.off
    m = raw.astype(np.float32).reshape(1, -1, 2)
    val = cv2.remap(view.img, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=float("nan")).ravel().astype(float)
    n_row = rows.shape[1]
    prof, bg = val[:len(u) * n_row].reshape(len(u), n_row), float(np.median(val[len(u) * n_row:]))
    if not np.isfinite(prof).all() or not np.isfinite(bg):
        return None
    pos = np.concatenate([-s[::-1], s])
    ends = np.abs(pos) >= length                                   # the tube on both links
    g, sd = np.empty(len(u)), np.empty(len(u))
    for j in range(len(u)):
        coef = np.polyfit(pos[ends], prof[j, ends], 1)
        res = prof[j, ends] - np.polyval(coef, pos[ends])
        contrast = bg - float(np.mean(prof[j, ends]))
        if abs(contrast) < min_snr * max(float(np.std(res)), 1e-6):      # no backdrop to see through it
            return None
        g[j] = float(np.sum(prof[j] - np.polyval(coef, pos))) * step / contrast
        # the baseline's noise over the summed samples (independent within a blur σ)
        sd[j] = float(np.std(res)) * math.sqrt(n_row * step * b) / abs(contrast)
    return u, g, sd


def shut_mouth(pa, pb, toward, view: MouthView, *, s2_floor: float = 0.0, min_points: int = 5, max_start: float,
               max_resolved: float = 2.0) -> Mouth | None:
    """The mouth of a slot bent shut from its two limbs' crossings ``pa``, ``pb`` [ideal px] and the image:
    where the limbs meet (:func:`limb_meeting`), each limb seen within ``max_start`` px of that point (a limb
    is not extrapolated from afar either), and how wide the gap there can be.

    The gap is at most what shows at a depth ``u`` (:func:`gap_width`, plus two standard errors) plus what
    the tube's material hides there when its faces are seen ``β`` from the side (``view.sin_view``; a ray
    through the gap crosses the chord ``2 sqrt(u (2R - u))``: ``2 sin β sqrt(u (2R - u))``), at the
    depth that bounds it most tightly (the gap only widens inward). It is at least what shows (less two
    standard errors) less the faces' opening over that depth (a straight slot's faces open at the angle
    its links are bent by). Either corner lies half the gap from the kink along the limb, toward its own
    link; with the gap anywhere between the bounds, the gap's covariance along the limb is the mean square
    of half of it. A slot whose gap is surely wider than ``max_resolved`` blur σ is open at its mouth:
    its two corners are apart in the image, and one point is not the measurement of both (None). None
    too where the limbs do not meet near both ends or the samples leave the image.

    ``toward`` (2,): a point inside the tube beside the mouth (the faces' crossings' centre) [ideal px].
    """
    met = limb_meeting(pa, pb, s2_floor=s2_floor, min_points=min_points)
    if met is None:
        return None
    X, cov, d = met
    for i, p in enumerate((pa, pb)):
        along = (p - X) @ d[i]
        if np.min(np.abs(along)) > max_start:
            return None
        d[i] *= 1.0 if np.mean(along) >= 0 else -1.0            # away from the mouth, along its own link
    nrm = np.stack([-d[:, 1], d[:, 0]], 1)
    nrm *= np.where(nrm @ (np.asarray(toward) - X) < 0, -1.0, 1.0)[:, None]
    into = nrm.sum(0)
    if np.linalg.norm(into) < 1e-9:
        return None
    into /= np.linalg.norm(into)
    got = gap_width(view, X, d, into)
    if got is None:
        return None
    u, g, sd = got
    hidden = 2.0 * abs(view.sin_view) * np.sqrt(np.clip(u * (2 * view.radius_px - u), 0.0, None))
    g_max = float(np.min(np.maximum(g, 0.0) + 2.0 * sd + hidden))
    # the faces of a straight slot open at the angle the links are bent by: at depth u the gap is that much
    # wider than at the mouth
    opening = 2.0 * math.tan(0.5 * math.acos(float(np.clip(-d[0] @ d[1], -1.0, 1.0))))
    g_min = min(max(float(np.max(g - 2.0 * sd - opening * u)), 0.0), g_max)
    if g_min > max_resolved * (view.blur if np.isfinite(view.blur) else 1.0):
        return None
    along = np.array([-into[1], into[0]])
    # either corner lies g / 2 from the kink, g anywhere between the bounds: the mean square of g / 2
    ms = (g_min ** 2 + g_min * g_max + g_max ** 2) / 12.0
    return Mouth(X, cov, ms * np.outer(along, along), g_min, g_max)


def shut_mouths(pts, grp, corners, partner, curved, view: MouthView, *, s2_floor: float = 0.0, min_points: int = 5,
                max_start: float) -> dict:
    """{corner: :class:`Mouth`} for the ``corners`` (refinement indices 0..K-1) whose slot partner is among
    them too: both faces of the slot seen only far from the limb (:func:`shut_mouth`).

    Parameters
    ----------
    pts, grp : ndarray (P, 2), (P,)
        Undistorted crossings [px] and their edge 0..2K-1 (edge ``k`` corner k's incoming edge, ``K + k``
        its outgoing one).
    partner : ndarray (K,) int
        The slot's other corner (-1: none); ``curved`` (2K,) bool the face edges.
    """
    K = len(partner)
    todo = set(int(k) for k in corners)
    out = {}
    for k in sorted(todo):
        q = int(partner[k])
        if q < 0 or q not in todo or q in out or curved[k] == curved[K + k] or curved[q] == curved[K + q]:
            continue
        limb = [K + j if curved[j] else j for j in (k, q)]
        face = [j if curved[j] else K + j for j in (k, q)]
        inner = pts[np.isin(grp, face)]
        if not len(inner):
            continue
        got = shut_mouth(pts[grp == limb[0]], pts[grp == limb[1]], inner.mean(0), view, s2_floor=s2_floor,
                         min_points=min_points, max_start=max_start)
        if got is not None:
            out[k] = out[q] = got
    return out


def with_mouths(lines, mouths: dict):
    """A copy of ``lines`` (:class:`.refine.CornerLines`) with the corners of ``mouths`` ({corner: :class:`Mouth`})
    measured at their mouths: ``ok``, at the kink with its fit's covariance, and the unresolved gap in
    ``cov_view``."""
    X, cov, ok = lines.X.copy(), lines.cov.copy(), lines.ok.copy()
    cov_view = np.zeros_like(cov) if lines.cov_view is None else lines.cov_view.copy()
    for k, m in mouths.items():
        X[k], cov[k], cov_view[k], ok[k] = m.X, m.cov, m.cov_gap, True
    return replace(lines, X=X, cov=cov, ok=ok, cov_view=cov_view)
