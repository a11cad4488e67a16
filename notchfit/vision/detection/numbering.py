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
gets none. A side not fully numbered is read again with each slot bounded
by the other side's numbered slots around it (each link is rigid between
its two slots), and with the slivers of slot mouths seen from the side (gaps
smaller than a slot) that the numbered slots pin to one joint; a new
reading counts only where it keeps every number given before. Nothing is
guessed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .base import BaseEnd, image_side
from .chain import ChainNumbers, ChainTolerance, SideCandidates, number_side

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
    pieces : dict
        Slot label -> the labels of the pieces numbered as that one slot (the
        label first), each open at the outline (:func:`_join_pieces`).
    """

    right: list
    left: list
    tip: tuple | None
    status: list
    messages: list = field(default_factory=list)
    mirror_conflict: bool = False
    tipless: bool = False
    pieces: dict = field(default_factory=dict)


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
    pinned : dict
        Side (+1, -1) -> list of (joint, (first, last) outer corner (plane, low-res px)): slots another
        silhouette of the same image numbered (:func:`~.locate.slot_pins`); they bound this side's
        slots along the tube like the other side's own numbered slots (:func:`_cross_ranges`).
    """

    mouth_corners: dict
    slack: dict
    base: tuple
    outline_plane: np.ndarray
    scale: float
    tol: ChainTolerance
    pinned: dict = field(default_factory=dict)


def _side_numbers(labels, side, chain: ChainInput, geom, tip, msg, ranges=None):
    """(label, joint) pairs of one side's slots (``labels`` ordered from the base) by the chain; ``ranges``:
    label -> (lo, hi), the joints the other side's numbered slots leave it (:func:`_cross_ranges`); ``msg``
    None: no message."""
    name = "right" if side > 0 else "left"
    corners = [chain.mouth_corners[s] for s in labels]
    first = np.array([c[0] for c in corners]).reshape(-1, 2)
    last = np.array([c[1] for c in corners]).reshape(-1, 2)
    near, far = (first, last) if side > 0 else (last, first)      # the left side is traversed tip -> base
    tip_pt = None if tip is None else chain.outline_plane[tip[0] if side > 0 else tip[1]]
    jr = None if ranges is None else np.array([ranges[s] for s in labels], int).reshape(-1, 2)
    cands = SideCandidates(side, near, far, chain.base[0 if side > 0 else 1], tip_pt,
                           np.array([chain.slack.get(s, 0.0) for s in labels]), jr)
    res = number_side(cands, geom, chain.tol, scale=chain.scale)
    wide = _lost_link_gaps(cands, geom, chain)
    if wide.any() and res.joints:
        res = _agree_split(res, cands, wide, geom, chain)
        if msg is not None and len(res.joints) < len(labels):
            msg.append(f"{int(wide.sum())} gap(s) on the {name} side as long as a link's edge: a slot bent open or "
                       "a link lost between two closed mouths; numbers only where both readings agree")
    if msg is None:
        return [(labels[k], j) for k, j in sorted(res.joints.items())]
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


def _lost_link_gaps(cands: SideCandidates, geom, chain: ChainInput) -> np.ndarray:
    """(K,) bool: the candidates whose two corners are farther apart than the widest slot cut by more than the
    chain's tolerance, and at least as far as the shortest solid edge between two consecutive slots of their
    side less it, next to a candidate closed at the mouth.

    Such a gap is a slot bent open, or the solid edge of a link lost from the silhouette (as bright as the
    backdrop) between two slots closed at the mouth: its first corner is then the earlier slot's mouth, not
    this slot's, and a reading of it as one slot numbers that corner one joint off. The two corners alone do
    not tell the two apart: the span is within what a slot bent open by its closure angle, plus the
    tolerance, may show.
    """
    near, far = np.asarray(cands.near, float).reshape(-1, 2), np.asarray(cands.far, float).reshape(-1, 2)
    span = np.linalg.norm(far - near, axis=1)
    tol = chain.tol.abs_tol
    w = np.asarray(geom.slot_widths, float)
    on = np.asarray(geom.slot_sides) == cands.side
    z, ws = np.asarray(geom.joint_z, float)[on], w[on]
    if len(z) < 2:
        return np.zeros(len(span), bool)
    # the shortest solid edge between two consecutive slots of this side (closed, their mouths are its ends)
    link = float(np.min(np.diff(z) - 0.5 * (ws[1:] + ws[:-1]))) / chain.scale
    wide = (span > float(w.max()) / chain.scale + tol) & (span >= link - tol)
    # the link's ends are closed mouths only where the joints beside it bend that far: consecutive joints carry
    # nearly the same tendon moment, so a next or previous slot found closed at the mouth (a wedge) is the
    # evidence; beside open slots a wide gap is a slot bent open
    closed = np.array([cands.slack_of(k) > 0 for k in range(len(span))] + [False])
    return wide & (closed[np.arange(len(span)) - 1] | closed[np.arange(len(span)) + 1])


def _agree_split(res: ChainNumbers, cands: SideCandidates, wide, geom, chain: ChainInput) -> ChainNumbers:
    """``res`` (the chain's numbers of ``cands``) kept where a second reading agrees, in which each ``wide``
    candidate (:func:`_lost_link_gaps`) is two slots closed at the mouth, one at each of its corners (each
    known to half the widest slot, as a closed mouth found from its wedge); the wide candidates get no number
    (which reading holds is not known)."""
    idx, near, far, slack, jr = [], [], [], [], []
    half = 0.5 * float(np.max(geom.slot_widths)) / chain.scale
    for k in range(len(cands.near)):
        parts = (cands.near[k], cands.far[k]) if wide[k] else (None,)
        for p in parts:
            idx.append(k if p is None else -1)
            near.append(cands.near[k] if p is None else p)
            far.append(cands.far[k] if p is None else p)
            slack.append(cands.slack_of(k) if p is None else half)
            if cands.joint_range is not None:
                jr.append(cands.joint_range[k])
    split = dataclasses.replace(cands, near=np.array(near), far=np.array(far), slack=np.array(slack),
                                joint_range=np.array(jr, int).reshape(-1, 2) if jr else None)
    other = number_side(split, geom, chain.tol, scale=chain.scale).joints
    new = {k: q for q, k in enumerate(idx) if k >= 0}
    keep = {k: j for k, j in res.joints.items() if not wide[k] and other.get(new[k]) == j}
    return dataclasses.replace(res, joints=keep, unnumbered=[k for k in range(len(cands.near)) if k not in keep])


def number_slots(cnt, on_border, be: BaseEnd, mouths: dict, convex, geom, *, dist, pair_tol,
                 chain: ChainInput, weak=frozenset()) -> Numbering:
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
    weak : set
        Labels of ``mouths`` that are slivers (:attr:`~.outline.Outline.sliver_ids`): they are not
        evidence for the tip or the sides, and they get numbers only where every slot-sized gap
        keeps its own.

    A side whose slots are not all numbered is read once more with the other
    side's numbered slots as bounds (:func:`_cross_ranges`); its new numbers
    stand only where every number given before is kept.
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
    strong = [(p_, s) for p_, s in slots if s not in weak]
    msg = []
    tip = None
    tipless = False
    if not tube_border:
        tip = _tip(cnt, convex, strong, pos, L_tube, dist, two_R, pair_tol)
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
    n_r, n_l = (sum(1 for s in side if s not in weak) for side in (right, left))
    if not cut and len(right_j) != len(left_j) and n_r == len(left_j) and n_l == len(right_j):
        return Numbering([], [], tip, status, msg, mirror_conflict=True)
    sides = {+1: right, -1: left[::-1]}                                  # each ordered from the base
    joints = {+1: right_j, -1: left_j}
    ctx = _Reading(chain, geom, tip, frozenset(weak), mouths, pos)
    pairs = {sd: _side_numbers(ctx.strong(sides[sd]), sd, chain, geom, tip, msg) if joints[sd] else [] for sd in sides}
    cross = None
    if right_j and left_j and (tip is not None or tube_border):
        arcs = _arcs(chain.outline_plane, i_br, L_tube, pos, tip, tube_border)
        margin = 0.5 * _shortest_solid(geom) / chain.scale
        cross = lambda sd, labels: _cross_ranges(labels, _other_spans(pairs[-sd], chain, -sd), chain,
                                                 arcs[0 if sd < 0 else 1], -sd, margin, geom.n_joints)
    pieces = _bounded_readings(sides, joints, pairs, cross, ctx, msg)
    return Numbering(pairs[+1], pairs[-1], tip, status, msg, tipless=tipless, pieces=pieces)


@dataclass(frozen=True)
class _Reading:
    """What a side's further readings need: the chain input, the geometry, the tip, the sliver labels, the
    mouths and the outline position from the base (``pos``: index -> position)."""

    chain: ChainInput
    geom: object
    tip: tuple | None
    weak: frozenset
    mouths: dict
    pos: object

    def strong(self, labels) -> list:
        """The slot-sized gaps among ``labels``."""
        return [lab for lab in labels if lab not in self.weak]


def _bounded_readings(sides: dict, joints: dict, pairs: dict, cross, ctx: _Reading, msg: list) -> dict:
    """Each side read again where its slots are not all numbered, its numbers (``pairs``, side -> list of
    (label, joint), updated in place) kept: first the slot-sized gaps bounded by the other side's numbered
    slots (``cross``: (side, labels) -> ranges, :func:`_cross_ranges`; None for a one-sided tube or no tip),
    then with the slivers that the numbered slots around them (this side's, the other side's) pin to one joint,
    pieces of one slot joined (:func:`_join_pieces`). Returns the joined pieces (label -> labels)."""
    geom, tip = ctx.geom, ctx.tip
    for sd in sides:
        strong = ctx.strong(sides[sd])
        if cross is not None and len(pairs[sd]) < len(strong) and (pairs[-sd] or ctx.chain.pinned.get(-sd)):
            pairs[sd] = _only_added(pairs[sd], _side_numbers(strong, sd, ctx.chain, geom, tip, None,
                                                             cross(sd, strong)),
                                    msg, "slots between the other side's numbered slots")
    pieces = {}
    for sd in sides:
        if len(pairs[sd]) == len(joints[sd]) or len(ctx.strong(sides[sd])) == len(sides[sd]):
            continue                               # every joint numbered, or no sliver on this side
        rng = _own_ranges(sides[sd], pairs[sd], geom.n_joints)
        if cross is not None and (pairs[-sd] or ctx.chain.pinned.get(-sd)):
            other = cross(sd, sides[sd])
            rng = {lab: (max(rng[lab][0], other[lab][0]), min(rng[lab][1], other[lab][1])) for lab in rng}
        at = lambda lab: [j for j in joints[sd] if rng[lab][0] < j < rng[lab][1]]
        keep = [lab for lab in sides[sd] if lab not in ctx.weak or len(at(lab)) == 1]
        if len(keep) > len(ctx.strong(sides[sd])):
            with_pieces, groups = _join_pieces(keep, at, ctx.mouths, ctx.pos, ctx.chain, geom)
            got = _only_added(pairs[sd], _side_numbers([g[0] for g in groups], sd, with_pieces, geom, tip, None, rng),
                              msg, "slivers of slot mouths seen from the side")
            pieces.update({g[0]: g for g in groups if len(g) > 1 and g[0] in dict(got)})
            pairs[sd] = got
    return pieces


def _join_pieces(labels, at, mouths, pos, chain: ChainInput, geom):
    """Consecutive candidates (``labels``, ordered from the base) pinned to one joint (``at``: label -> the
    joints its range holds) are pieces of that joint's slot, split by shading or a bridge of texture, when
    all are open at the outline and together no wider than the slot: one candidate, labelled by its first,
    from the first corner of the piece first along the outline to the last corner of the last. Returns the
    chain input with the joined corners and the groups (tuples of labels)."""
    groups = []
    for lab in labels:
        j = at(lab)
        prev = groups[-1] if groups else None
        if prev is not None and len(j) == 1 and at(prev[0]) == j and all(mouths[x][2] for x in prev + (lab,)):
            groups[-1] = prev + (lab,)
        else:
            groups.append((lab,))
    corners = dict(chain.mouth_corners)
    out = []
    for g in groups:
        if len(g) > 1:
            a, b = min(g, key=lambda x: pos(mouths[x][0])), max(g, key=lambda x: pos(mouths[x][1]))
            span = (corners[a][0], corners[b][1])
            wide = float(np.asarray(geom.slot_widths)[at(g[0])[0] - 1]) / chain.scale + chain.tol.abs_tol
            if np.linalg.norm(np.subtract(span[1], span[0])) > wide:
                out += [(x,) for x in g]
                continue
            corners[g[0]] = span
        out.append(g)
    return dataclasses.replace(chain, mouth_corners=corners), out


def _own_ranges(labels, pairs, n_joints: int) -> dict:
    """Label -> (lo, hi): the joints between which each of one side's slots (``labels``, ordered from the base)
    lies, from that side's numbered slots before and after it along the outline (a numbered slot: its own
    joint)."""
    num = dict(pairs)
    out = {}
    for q, lab in enumerate(labels):
        if lab in num:
            out[lab] = (num[lab] - 1, num[lab] + 1)
            continue
        before = [num[x] for x in labels[:q] if x in num]
        after = [num[x] for x in labels[q + 1:] if x in num]
        out[lab] = (max(before, default=0), min(after, default=n_joints + 1))
    return out


def _shortest_solid(geom) -> float:
    """The shortest stretch of tube between two consecutive slots, whichever sides they open on [m]."""
    z, w = np.asarray(geom.joint_z), np.asarray(geom.slot_widths)
    return float(np.min(np.diff(z) - 0.5 * (w[1:] + w[:-1]))) if len(z) > 1 else np.inf


def _arcs(plane, i_br, L_tube, pos, tip, tube_border):
    """The right and the left side's stretch of the bridged outline: (points (K, 2) [plane], their arc
    length from the base end along the outline (K,)) each; the tip (or the image border) between them."""
    N = len(plane)
    idx = (i_br + np.arange(L_tube + 1)) % N
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(plane[idx], axis=0), axis=1))])
    end_r = pos(tip[0]) if tip is not None else min(tube_border)
    start_l = pos(tip[1]) if tip is not None else max(tube_border)
    return (plane[idx[:end_r + 1]], s[:end_r + 1]), (plane[idx[start_l:]], s[start_l:])


def _other_spans(pairs, chain: ChainInput, side: int) -> list:
    """The ``side``'s numbered slots as ((first, last) corner (plane), joint): its own (``pairs``, (label,
    joint)) and the slots pinned by another silhouette (``chain.pinned``) at the joints it did not number."""
    own = [(chain.mouth_corners[lab], j, False) for lab, j in pairs]
    have = {j for _, j in pairs}
    return own + [(c, j, True) for j, c in chain.pinned.get(side, []) if j not in have]


def _cross_ranges(labels, other, chain: ChainInput, other_arc, other_side: int, margin: float,
                  n_joints: int) -> dict:
    """Label -> (lo, hi): the joints between which each slot of one side lies along the tube, from the other
    side's numbered slots (``other``: list of ((first, last) corner (plane), joint, pinned), :func:`_other_spans`,
    on ``other_arc``). A slot's corners and the corners of the other side's slot before (after) it lie on one
    rigid link, its solid part between the two slots long: each corner is taken across the tube to the
    nearest point of the other side's edge, and a numbered slot bounds a candidate only where all its
    corners are beyond all the candidate's by ``margin`` along that edge (half the shortest solid stretch:
    the bend of the joint between them and the corners' own errors are left that much). A numbered slot
    pinned by another silhouette whose corner lies farther than ``margin`` from this outline's edge (beyond
    its end, or off it) bounds nothing: where it lies along the edge is not known."""
    pts, s = other_arc
    if not len(pts):
        return {c: (0, n_joints + 1) for c in labels}

    def along(xy, on_edge=False):
        d2 = np.sum((pts - xy) ** 2, axis=1)
        k = int(np.argmin(d2))
        return s[k] if not on_edge or d2[k] <= margin ** 2 else np.nan

    span = lambda corners, on_edge=False: sorted(along(p, on_edge) for p in corners)
    bounds = [(span(c, pinned), j) for c, j, pinned in other]
    bounds = [(sp, j) for sp, j in bounds if np.all(np.isfinite(sp))]
    out = {}
    for c in labels:
        c0, c1 = span(chain.mouth_corners[c])
        lo, hi = 0, n_joints + 1
        for (x0, x1), j in bounds:
            # along the other side's arc: the right side runs base -> tip, the left side tip -> base
            beyond, before = c0 > x1 + margin, c1 < x0 - margin
            if (beyond and other_side > 0) or (before and other_side < 0):
                lo = max(lo, j)
            elif beyond or before:
                hi = min(hi, j)
        out[c] = (lo, hi)
    return out


def _only_added(first: list, second: list, msg: list, what: str) -> list:
    """A side's numbers read again with more evidence (``second``), where they keep every number given before
    (``first``); where they change or drop one, the two readings dispute it and the first stands."""
    before, after = dict(first), dict(second)
    if any(after.get(lab) != j for lab, j in before.items()) or len(after) <= len(before):
        return first
    msg.append(f"{len(after) - len(before)} more numbered: {what}")
    return second
