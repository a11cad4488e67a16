"""Stage 4: number the slots and find the tip (geometry.md numbering).

Along the bridged outline, anticlockwise in the manipulator frame from the
base: the right side's slots, the tip, the left side's slots. The tip
corners are two convex ~90° corners ``2R`` apart with no slot between
them. Slots are numbered from the base on each side (joints with
``slot_sides = +1`` on the right, ``-1`` on the left); a side cut off by
the image border at the tip is numbered from the base; a side with a
missing slot is aligned by position along the side; a base outside the
image with slots missing cannot be numbered. Nothing is guessed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .base import BaseEnd, image_side
from .dims import joint_z

__all__ = ["Numbering", "number_slots", "orient_corner_pair"]


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
    unnumbered : bool
        The base is outside the image and slots are missing: nothing can be
        numbered from the base (no point is reported).
    guessed : list of int
        Points of slots numbered by their position along a side (a slot
        missing): each must be confirmed by a rigid-link partner.
    """

    right: list
    left: list
    tip: tuple | None
    status: list
    messages: list = field(default_factory=list)
    mirror_conflict: bool = False
    unnumbered: bool = False
    guessed: list = field(default_factory=list)


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


def _assign(found, joints, side, base_i, tip_i, *, cut_tip, cut_base, geom, mouths, N, status, index, msg):
    """Slot regions ordered from the base -> joints of this side (ordered from the base)."""
    name = "right" if side > 0 else "left"
    if len(found) == len(joints):
        return list(zip(found, joints))
    if cut_base and len(found) < len(joints):
        msg.append(f"{len(found)} slots on the {name} side, {len(joints)} expected, and the base is outside "
                   "the image: the slots cannot be numbered from the base")
        return []
    if cut_tip and len(found) < len(joints):
        return list(zip(found, joints[:len(found)]))
    msg.append(f"{len(found)} slots on the {name} side, {len(joints)} expected")
    if len(found) > len(joints) or tip_i is None:
        return []
    apos = lambda i, start: (i - start) % N
    zj = joint_z(geom)
    zf = np.array([(zj[j - 1] - geom.base_edge_z) / (geom.tip_z - geom.base_edge_z) for j in joints])
    spacing = float(np.min(np.diff(zf))) if len(zf) > 1 else 1.0
    span = max(apos(tip_i, base_i) if side > 0 else apos(base_i, tip_i), 1)
    out, taken = [], {}
    msg.append(f"the {name} side's slots numbered by their position")
    for s in found:
        ps = apos(mouths[s][0], base_i) if side > 0 else apos(base_i, mouths[s][0])
        kk = int(np.argmin(np.abs(zf - ps / span)))
        if abs(zf[kk] - ps / span) < 0.3 * spacing and kk not in taken:
            taken[kk] = s
            out.append((s, joints[kk]))
        else:
            for kind in ("proximal", "distal"):
                status[index[(kind, joints[kk], side)]] = "ambiguous"
    return out


def number_slots(cnt, on_border, be: BaseEnd, mouths: dict, convex, geom, lay, *, dist, two_R, pair_tol,
                 base_at_border: bool) -> Numbering:
    """Match the slots on the tube arc to joints and find the tip.

    Parameters
    ----------
    cnt : ndarray (N, 2)
        Bridged outline, anticlockwise in the manipulator frame.
    on_border : ndarray (N,) bool
    be : BaseEnd
    mouths : dict
        From :func:`~notchfit.detection.outline.slot_mouths`.
    convex : list of int
        Convex corner candidates on the outline.
    geom, lay : Geometry and its NotchLayout
    dist : callable (i, j) -> distance [same unit as two_R]
    base_at_border : bool
        The base end is the image border (the tube enters from outside).
    """
    N = len(cnt)
    m = lay.n_points
    i_br, i_bl = be.i_right, be.i_left
    apos = lambda i, start: (i - start) % N
    L_tube = apos(i_bl, i_br)
    pos = lambda i: apos(i, i_br)
    tube_border = [pos(i) for i in np.nonzero(on_border)[0] if 0 < pos(i) < L_tube]
    slots = sorted((pos(v[0]), s) for s, v in mouths.items() if 0 <= pos(v[0]) < L_tube)
    msg = []
    tip = None
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
    else:
        # no tip and no border between the sides: which side a slot is on cannot be told
        msg.append("the slots' sides cannot be told apart without the tip")
        right, left, cut = [], [], True
    right_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == +1]
    left_j = [j for j in range(1, geom.n_joints + 1) if geom.slot_sides[j - 1] == -1]
    index = {(lay.kind[i], int(lay.joint[i]), int(lay.side[i])): i for i in range(m)}
    status = ["occluded"] * m
    if not cut and len(right_j) != len(left_j) and len(right) == len(left_j) and len(left) == len(right_j):
        return Numbering([], [], tip, status, msg, mirror_conflict=True)
    kw = dict(cut_tip=cut, cut_base=base_at_border, geom=geom, mouths=mouths, N=N, status=status,
              index=index, msg=msg)
    right_pairs = _assign(right, right_j, +1, i_br, tip[0] if tip else None, **kw)
    left_pairs = _assign(left[::-1], left_j, -1, i_bl, tip[1] if tip else None, **kw)
    lost = base_at_border and (len(right) < len(right_j) or len(left) < len(left_j))
    by_position = cut is False or tip is not None        # a side cut off at the tip is numbered in order
    guessed = [index[(kind, j, side)] for pairs, found, joints, side in ((right_pairs, right, right_j, +1),
                                                                          (left_pairs, left, left_j, -1))
               if len(found) != len(joints) and by_position for _, j in pairs for kind in ("proximal", "distal")]
    return Numbering(right_pairs, left_pairs, tip, status, msg, unnumbered=lost, guessed=guessed)
