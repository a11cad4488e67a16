"""Stage 4: number the slots and find the tip (geometry.md numbering).

Along the bridged outline, anticlockwise in the manipulator frame from the
base: the right side's slots, the tip, the left side's slots. The tip
corners are two convex ~90° corners ``2R`` apart with no slot between
them; without them (a tendon loop or a droplet rounds them off) a one-sided
tube's slots are all on its one side, two-sided tubes' sides cannot be told
apart. Each side's slots (joints with ``slot_sides = +1`` on the right,
``-1`` on the left) are numbered by agreement with the rigid-link chain
(:mod:`.chain`), the base and tip corners as anchors where found: a missing
slot, a spurious gap, a side cut off by the image border at either end cost
only the slots they touch, and a slot whose number the chain does not fix
gets none. Nothing is guessed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .base import BaseEnd, image_side
from .chain import ChainTolerance, SideCandidates, number_side

__all__ = ["ChainInput", "Numbering", "number_slots", "orient_corner_pair"]


@dataclass
class Numbering:
    """Slots matched to joints, and the tip.

    Attributes
    ----------
    right, left : list of (slot label, joint)
    tip : (int, int) or None
        Outline indices of the tip-right and tip-left corners.
    status : list of str (m,)
        ``ambiguous`` where a slot's identity is doubtful, else ``occluded`` (to be refined).
    messages : list of str
    mirror_conflict : bool
        The slot counts fit the opposite mirror flag.
    tipless : bool
        A one-sided tube's slots numbered without its tip: no tip pair ``2R``
        apart confirms that the silhouette is the whole tube (half of it, split
        along a highlight, has consistent corners on an inner edge), so each
        corner's link must be ``2R`` wide beside it (``subpixel.link_widths``).
    """

    right: list
    left: list
    tip: tuple | None
    status: list
    messages: list = field(default_factory=list)
    mirror_conflict: bool = False
    tipless: bool = False


def orient_corner_pair(be: BaseEnd, mouths: dict, cnt) -> BaseEnd:
    """Order a pair of base corners found without a holder run: the tube (more slots) lies from right to left."""
    N = len(cnt)
    ia, ib = be.i_right, be.i_left
    apos = lambda i, start: (i - start) % N
    n_ab = sum(apos(v[0], ia) < apos(ib, ia) for v in mouths.values())
    if not (n_ab > len(mouths) - n_ab or (2 * n_ab == len(mouths) and apos(ib, ia) > apos(ia, ib))):
        ia, ib = ib, ia
    tube = (np.arange(N) - ia) % N <= (ib - ia) % N
    side = image_side(0.5 * (cnt[ia] + cnt[ib]) - cnt[tube].mean(0)) if tube.any() else ""
    return dataclasses.replace(be, i_right=int(ia), i_left=int(ib), side=side, i_right_wide=int(ia), i_left_wide=int(ib))


def _tip(cnt, convex, slots, pos, L_tube, dist, two_R, pair_tol):
    """Tip corners: consecutive convex corners on the tube arc, 2R apart, no slot between."""
    cands = sorted((pos(i), i) for i in convex if 0 < pos(i) < L_tube)
    best = None
    for (pa_, i1), (pb_, i2) in zip(cands[:-1], cands[1:]):
        if any(pa_ < sp < pb_ for sp, _ in slots):
            continue
        e = abs(dist(i1, i2) / two_R - 1)
        if best is None or e < best[0]:
            best = (e, i1, i2)
    return (best[1], best[2]) if best is not None and best[0] <= pair_tol else None


@dataclass(frozen=True)
class ChainInput:
    """Where the candidates' corners are, for numbering by the chain (:mod:`.chain`).

    Attributes
    ----------
    mouth_corners : dict
        Slot label -> (first, last) outer corner in outline order (plane, low-res px).
    slack : dict
        Slot label -> extra tolerance (a closed mouth: one point for both corners).
    base : (ndarray or None, ndarray or None)
        The base corners on the right and the left (plane, low-res px).
    outline_plane : ndarray (N, 2)
        The bridged outline in the plane (low-res px): the tip corners.
    scale : float
        Metres per plane unit.
    tol : ChainTolerance
    """

    mouth_corners: dict
    slack: dict
    base: tuple
    outline_plane: np.ndarray
    scale: float
    tol: ChainTolerance


def _side_numbers(labels, side, chain: ChainInput, geom, tip, msg):
    """(label, joint) pairs of one side's slots (``labels`` ordered from the base) by the chain."""
    name = "right" if side > 0 else "left"
    corners = [chain.mouth_corners[s] for s in labels]
    first = np.array([c[0] for c in corners]).reshape(-1, 2)
    last = np.array([c[1] for c in corners]).reshape(-1, 2)
    near, far = (first, last) if side > 0 else (last, first)      # the left side is traversed tip -> base
    tip_pt = None if tip is None else chain.outline_plane[tip[0] if side > 0 else tip[1]]
    cands = SideCandidates(side, near, far, chain.base[0 if side > 0 else 1], tip_pt,
                           np.array([chain.slack.get(s, 0.0) for s in labels]))
    res = number_side(cands, geom, chain.tol, scale=chain.scale)
    n_side = sum(1 for v in geom.slot_sides if v == side)
    if labels and not res.joints:
        msg.append(f"the {name} side's {len(labels)} slots are not numbered: neither its base nor its tip corner "
                   "agrees with them (hidden, cut off or off the drawing), and equal links could be one off")
    elif res.unnumbered:
        msg.append(f"{len(res.unnumbered)} of {len(labels)} slot-like gaps on the {name} side do not fit the "
                   "rigid-link chain in one way only (a spurious gap, or a shift the visible links cannot "
                   "rule out): not numbered")
    elif len(labels) != n_side:
        msg.append(f"{len(labels)} slots on the {name} side, {n_side} expected: numbered by agreement with "
                   "the rigid-link chain")
    return [(labels[k], j) for k, j in sorted(res.joints.items())]


def number_slots(cnt, on_border, be: BaseEnd, mouths: dict, convex, geom, *, dist, pair_tol,
                 chain: ChainInput) -> Numbering:
    """Match the slots on the tube arc to joints and find the tip.

    Parameters
    ----------
    cnt : ndarray (N, 2)
        Bridged outline, anticlockwise in the manipulator frame.
    on_border : ndarray (N,) bool
    be : BaseEnd
    mouths : dict
        From :func:`~notchfit.vision.detection.outline.slot_mouths`.
    convex : list of int
        Convex corner candidates on the outline.
    geom : Geometry
    dist : callable (i, j) -> distance between outline points [plane units of ``chain``]
    chain : ChainInput
        The candidates' corners: each side's slots are numbered by agreement
        with the rigid-link chain (:func:`~notchfit.vision.detection.chain.number_side`).
    """
    N = len(cnt)
    m = geom.n_points
    two_R = 2 * geom.outer_radius / chain.scale
    i_br, i_bl = be.i_right, be.i_left
    apos = lambda i, start: (i - start) % N
    L_tube = apos(i_bl, i_br)
    pos = lambda i: apos(i, i_br)
    tube_border = [pos(i) for i in np.nonzero(on_border)[0] if 0 < pos(i) < L_tube]
    slots = sorted((pos(v[0]), s) for s, v in mouths.items() if 0 <= pos(v[0]) < L_tube)
    msg = []
    tip = None
    tipless = False
    if not tube_border:
        tip = _tip(cnt, convex, slots, pos, L_tube, dist, two_R, pair_tol)
        if tip is None:
            msg.append("tip corners not found")
    if tip is not None:
        right = [s for p_, s in slots if p_ < pos(tip[0])]
        left = [s for p_, s in slots if p_ > pos(tip[1])]
        cut = False
    elif tube_border:
        right = [s for p_, s in slots if p_ < min(tube_border)]
        left = [s for p_, s in slots if p_ > max(tube_border)]
        cut = True
        msg.append("the tube is cut off by the image border")
    elif len(set(geom.slot_sides)) == 1:
        # a one-sided tube: every slot opens on its one side, the tip is not needed to tell the sides apart
        # (a gap on the backbone's side is a candidate that the chain does not take)
        right, left = ([s for _, s in slots], []) if geom.slot_sides[0] > 0 else ([], [s for _, s in slots])
        cut = tipless = True
    else:
        # no tip and no border between the sides: which side a slot is on cannot be told
        msg.append("the slots' sides cannot be told apart without the tip")
        right, left, cut = [], [], True
    right_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == +1]
    left_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == -1]
    status = ["occluded"] * m
    if not cut and len(right_j) != len(left_j) and len(right) == len(left_j) and len(left) == len(right_j):
        return Numbering([], [], tip, status, msg, mirror_conflict=True)
    right_pairs = _side_numbers(right, +1, chain, geom, tip, msg) if right_j else []
    left_pairs = _side_numbers(left[::-1], -1, chain, geom, tip, msg) if left_j else []
    return Numbering(right_pairs, left_pairs, tip, status, msg, tipless=tipless)
