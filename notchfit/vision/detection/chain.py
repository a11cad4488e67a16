"""Slot numbers by agreement with the rigid-link chain, not by counting.

The slots found along one side of the tube (slot-sized gaps, ordered from
the base end) are candidates; the geometry's joints on that side are the
numbers. A numbering is a monotone matching of candidates to joints; it is
*feasible* when every pair of consecutive matched slots agrees with the
chain between them: the far corner of one slot and the near corner of the
next lie on one rigid link when no joint lies between them (their distance
is the link's, within ``max(rel_tol d, abs_tol)``), and within the straight
distance plus the most the joints between them can change it otherwise
(:func:`joint_play`). The
base corners (link 0) and the tip corners (link n) found by the outline are
anchors that join the matching like slots (counting half a slot: a holder's
face off the base edge is more common than a spurious gap that fits the
chain). Of the feasible numberings, those matching the most are kept; a
candidate gets a number only when every one of them gives it that number,
so two equally good matchings (a slot split in two by a bridge of texture,
a spurious gap next to a missing slot) cost only the candidates they
dispute. The links repeat, so the numbers stand only when every best
matching holds an end of the chain next to its first (last) slot — the base
or the tip, whichever is seen: beyond a missing slot the joints' play can
reach a link's length — or when every joint of the side is matched. An end
found then disputes the numbers that a matching of its own (joined next to
its first or last slot) gives otherwise (a mirrored view, a spurious gap
next to a missing slot), and tip corners that do not fit the last slot
dispute it (a tendon loop's corner); an end that fits nothing disputes
nothing (a hidden tip, a holder's face). A candidate pinned to one joint by
the other side's numbered slots around it (``SideCandidates.joint_range``)
holds the numbers like an end next to its slot: a shifted matching would
move it out of its range. A spurious gap, a missing or split
slot, a hidden end link cost only the slots they touch; a shift that the
chain cannot tell apart numbers nothing: never a wrong number. The
candidates keep their own measured corners: the chain decides identities
only.

Solved exactly by dynamic programming over (candidate, joint) pairs with
every transition tested at once (numpy), forward and backward, so that the
nodes and skips on some best matching are known.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...physics.geometry import Geometry, notch_layout

__all__ = ["ChainNumbers", "ChainTolerance", "SideCandidates", "joint_play", "number_side"]


@dataclass(frozen=True)
class ChainTolerance:
    """How far a measured distance between corners may differ from the drawn one.

    Attributes
    ----------
    rel_tol : float
        Relative part for corners on one rigid link.
    abs_tol : float
        Absolute part [same unit as the positions].
    per_joint : float
        Factor on what each joint between the two corners can change their
        distance by (:func:`joint_play`).
    """

    rel_tol: float
    abs_tol: float
    per_joint: float


@dataclass(frozen=True)
class SideCandidates:
    """Slots found along one side, ordered from the base end, and the side's anchors.

    Attributes
    ----------
    side : int
        +1 right, -1 left.
    near, far : ndarray (K, 2)
        Each candidate's outer corner nearer the base and nearer the tip
        (plane, any unit shared with the tolerance).
    base : ndarray (2,) or None
        The base corner on this side (link 0), when found.
    tip : ndarray (2,) or None
        The tip corner on this side (link n), when found.
    slack : ndarray (K,), optional
        Extra tolerance for each candidate's corners (a closed mouth gives
        one point for both) [same unit].
    joint_range : ndarray (K, 2) int, optional
        Each candidate's joint lies strictly between these two joint numbers
        (the other side's numbered slots it lies between along the tube,
        :func:`~.numbering.number_slots`); a candidate whose range holds one
        joint of this side is *pinned* to it.
    """

    side: int
    near: np.ndarray
    far: np.ndarray
    base: np.ndarray | None = None
    tip: np.ndarray | None = None
    slack: np.ndarray | None = None
    joint_range: np.ndarray | None = None

    def slack_of(self, k: int) -> float:
        """Candidate ``k``'s extra tolerance [unit]."""
        return 0.0 if self.slack is None else float(self.slack[k])


@dataclass(frozen=True)
class ChainNumbers:
    """The outcome on one side.

    Attributes
    ----------
    joints : dict
        Candidate index -> joint number (1-based), for the candidates every best matching numbers alike.
    unnumbered : list of int
        Candidates that some best matching leaves out or numbers differently.
    base_ok, tip_ok : bool
        The anchor is on every best matching.
    """

    joints: dict
    unnumbered: list = field(default_factory=list)
    base_ok: bool = False
    tip_ok: bool = False


def _nodes(geom: Geometry, side: int, lay):
    """The side's chain nodes, base to tip: (near point index, far point index) each; the base and tip
    anchors are nodes whose near and far points are their corner. Returns (node list, joint of each node,
    0 = base and n + 1 = tip)."""
    idx = {(lay.kind[i], int(lay.joint[i]), int(lay.side[i])): i for i in range(lay.n_points)}
    nodes = [(idx[("base", 0, side)],) * 2]
    joints = [0]
    for j in range(1, geom.n_joints + 1):
        if geom.slot_sides[j - 1] == side:
            nodes.append((idx[("proximal", j, side)], idx[("distal", j, side)]))
            joints.append(j)
    nodes.append((idx[("tip", 0, side)],) * 2)
    joints.append(geom.n_joints + 1)
    return nodes, np.array(joints)


def joint_play(geom: Geometry, side: int) -> np.ndarray:
    """How much each joint's bend can change a distance along the ``side`` edge, shape (n,) [m].

    A joint whose slot opens on that side closes it by at most its width
    ``w_j``; a joint whose slot opens on the other side turns the edge about
    its bending axis by at most its closure angle: ``(R + |x_na|) θ_close``.
    """
    same = np.asarray(geom.slot_sides) == side
    other = (geom.outer_radius + np.abs(geom.neutral_axis_x)) * geom.closure_angles
    return np.where(same, geom.slot_widths, other)


def _expected(geom: Geometry, nodes, side: int, scale: float, lay):
    """Drawn distance from each node's far point to each later node's near point (M, M) and what the joints
    between them can change it by (M, M) [unit]; 0 for points on one link."""
    far = lay.straight[[n[1] for n in nodes]] / scale
    near = lay.straight[[n[0] for n in nodes]] / scale
    d = np.linalg.norm(far[:, None, :] - near[None, :, :], axis=2)
    links_far = lay.link[[n[1] for n in nodes]]
    links_near = lay.link[[n[0] for n in nodes]]
    cs = np.concatenate([[0.0], np.cumsum(joint_play(geom, side))]) / scale   # joints 1..k: cs[k]
    play = cs[np.maximum(links_near[None, :], links_far[:, None])] - cs[links_far[:, None]]
    return d, play


@dataclass(frozen=True)
class _Best:
    """The best matchings of one dynamic programme: their score, the (candidate, node) pairs on some best
    matching (C, M), the candidates some best matching jumps over or leaves out before its first (after its
    last) node (C,), the transitions on some best matching (C, M, C, M), and the pairs some best matching
    begins (ends) with (C, M)."""

    score: float
    on: np.ndarray
    skipped: np.ndarray
    edges: np.ndarray
    firsts: np.ndarray
    lasts: np.ndarray


def _best(feas, allowed, wgt, *, start, end, eps: float = 1e-6) -> _Best:
    """Best monotone matchings by dynamic programming, forward and backward, every transition tested at once.

    ``feas[c', u', c, u]``: candidate c' at node u' may be followed by c at u; ``allowed`` (C, M): c may take
    u; ``wgt`` (C,): what a matched candidate counts; ``start``, ``end`` (C, M): where a matching may begin
    and end (a matching that must hold an anchor begins or ends at it)."""
    NEG = -1e9
    C, M = allowed.shape
    gain = np.where(feas, 0.0, NEG)
    # a row not yet filled holds NEG and any term through it is at most NEG, which the start (end) term, itself
    # at least NEG, already bounds: each step reads only the rows filled before it, (candidate, node) pairs
    # flattened into one axis (one reduction instead of two)
    into = gain.reshape(C * M, C, M)                     # [(c', u'), c, u]
    out_of = gain.reshape(C, M, C * M)                   # [c, u, (c', u')]
    begin, finish = np.where(start, 0.0, NEG), np.where(end, 0.0, NEG)
    fwd = np.full((C, M), NEG)
    flat = fwd.reshape(-1)
    for c in range(C):
        n = c * M
        prev = (flat[:n, None] + into[:n, c, :]).max(axis=0) if n else begin[c]
        fwd[c] = np.where(allowed[c], wgt[c] + np.maximum(begin[c], prev), NEG)
    bwd = np.full((C, M), NEG)
    flat = bwd.reshape(-1)
    for c in range(C - 1, -1, -1):
        n = (c + 1) * M
        nxt = (out_of[c, :, n:] + flat[None, n:]).max(axis=1) if n < C * M else finish[c]
        bwd[c] = np.where(allowed[c], wgt[c] + np.maximum(finish[c], nxt), NEG)
    ends = fwd[end]
    score = float(ends.max()) if ends.size else NEG
    if score <= 0:
        z = np.zeros((C, M), bool)
        return _Best(score, z, np.ones(C, bool), np.zeros((C, M, C, M), bool), z, z)
    valid = (fwd > NEG / 2) & (bwd > NEG / 2)
    on = valid & (np.abs(fwd + bwd - wgt[:, None] - score) < eps)
    edges = feas & valid[:, :, None, None] & valid[None, None, :, :] \
        & (np.abs(fwd[:, :, None, None] + gain + bwd[None, None, :, :] - score) < eps)
    firsts = on & start & (np.abs(fwd - wgt[:, None]) < eps)
    lasts = on & end & (np.abs(bwd - wgt[:, None]) < eps)
    cc = np.arange(C)
    jumps = edges.any(axis=(1, 3))                       # (c1, c2): some best matching goes from c1 to c2
    skipped = (jumps[:, None, :] & (cc[:, None, None] < cc[None, :, None])
               & (cc[None, :, None] < cc[None, None, :])).any(axis=(0, 2))
    if firsts.any():
        skipped |= cc < np.nonzero(firsts.any(1))[0].max()
    if lasts.any():
        skipped |= cc > np.nonzero(lasts.any(1))[0].min()
    return _Best(score, on, skipped, edges, firsts, lasts)


def _feasible(cands: SideCandidates, geom: Geometry, tol: ChainTolerance, scale: float):
    """The candidates with the anchors as candidates 0 (base) and K + 1 (tip): which node each may take
    (C, M), which transitions agree with the chain (C, M, C, M), and each node's joint (M,)."""
    lay = notch_layout(geom)
    nodes, joints = _nodes(geom, cands.side, lay)
    M = len(nodes)
    d0, play = _expected(geom, nodes, cands.side, scale, lay)
    K = len(cands.near)
    nan2 = np.full(2, np.nan)
    base = cands.base if cands.base is not None else nan2
    tip = cands.tip if cands.tip is not None else nan2
    near = np.vstack([[base], cands.near.reshape(-1, 2), [tip]])
    far = np.vstack([[base], cands.far.reshape(-1, 2), [tip]])
    C = K + 2
    allowed = np.zeros((C, M), bool)                 # candidate c may take node u
    allowed[1:K + 1, 1:M - 1] = True
    allowed[0, 0] = cands.base is not None
    allowed[C - 1, M - 1] = cands.tip is not None
    if cands.joint_range is not None and K:
        lo, hi = np.asarray(cands.joint_range).reshape(-1, 2).T
        allowed[1:K + 1] &= (joints[None, :] > lo[:, None]) & (joints[None, :] < hi[:, None])
    d = np.linalg.norm(far[:, None, :] - near[None, :, :], axis=2)          # (C, C) far of c' -> near of c
    limit = np.maximum(tol.rel_tol * d0, tol.abs_tol) + tol.per_joint * play
    slack = np.zeros(C)
    if cands.slack is not None:
        slack[1:K + 1] = cands.slack
    limit = limit[None, :, None, :] + (slack[:, None] + slack[None, :])[:, None, :, None]
    ok_uu = np.arange(M)[:, None] < np.arange(M)[None, :]
    ok_cc = np.arange(C)[:, None] < np.arange(C)[None, :]
    feas = (np.abs(d[:, None, :, None] - d0[None, :, None, :]) <= limit) \
        & ok_cc[:, None, :, None] & ok_uu[None, :, None, :] & allowed[:, :, None, None] & allowed[None, None, :, :]
    feas &= np.isfinite(d)[:, None, :, None]
    return allowed, feas, joints


def number_side(cands: SideCandidates, geom: Geometry, tol: ChainTolerance, *, scale: float,
                anchor_weight: float = 0.5) -> ChainNumbers:
    """Number one side's candidate slots by the best agreement with the chain (module docstring).

    Parameters
    ----------
    cands : SideCandidates
    geom : Geometry
    tol : ChainTolerance
    scale : float
        Metres per unit of the positions (the drawn distances are divided by it).
    anchor_weight : float
        What a base or tip anchor counts for in a matching (a slot counts 1).

    Returns
    -------
    ChainNumbers
    """
    allowed, feas, joints = _feasible(cands, geom, tol, scale)
    C, M = allowed.shape
    K = C - 2
    # each slot counts 1, an anchor ``anchor_weight``: a holder's face off the base edge or a droplet at the
    # tip is more common than a spurious slot that fits the chain
    wgt = np.ones(C)
    wgt[[0, C - 1]] = anchor_weight
    best = _best(feas, allowed, wgt, start=allowed, end=allowed)
    if best.score <= 0:
        return ChainNumbers({}, list(range(K)))
    unique = {}
    for k in range(1, K + 1):
        us = np.nonzero(best.on[k])[0]
        if len(us) == 1 and not best.skipped[k]:
            unique[k - 1] = int(us[0])
    base_ok = bool(best.on[0, 0] and not best.skipped[0])
    tip_ok = bool(best.on[C - 1, M - 1] and not best.skipped[C - 1])
    # an end on every best matching, next to its first (last) slot in each
    uu = np.arange(M)
    base_next = base_ok and not best.edges[0, 0][:, uu != 1].any()
    tip_next = tip_ok and not best.edges[:, :, C - 1, M - 1][:, uu != M - 2].any()
    # equal links repeat: a matching fits as well shifted by a joint unless an end of the chain agrees next to
    # its first (last) slot (beyond a missing slot the joints' play can reach a link's length), or every
    # joint of the side is matched (checked against the ends found below); ``loose``: no end joined next
    held = base_next or tip_next
    if not held and cands.joint_range is not None:
        # a candidate pinned to one joint by the other side's numbered slots around it (each link is rigid
        # between its two slots, so the order along the tube holds whatever the joints' play): a matching
        # shifted by a joint would move it out of its range
        pinned = np.zeros(C, bool)
        pinned[1:K + 1] = allowed[1:K + 1].sum(axis=1) == 1
        free = allowed & ~pinned[:, None]
        held = _best(feas & free[:, :, None, None] & free[None, None, :, :], free, wgt, start=free,
                     end=free).score < best.score - 1e-6
    if not held:
        loose = feas.copy()
        loose[0, 0, :, 1] = False
        loose[:, M - 2, C - 1, M - 1] = False
        held = _best(loose, allowed, wgt, start=allowed, end=allowed).score < best.score - 1e-6
    # a complete side stands without an end next to its slots only when no base corner found disagrees (a
    # mirrored view: the other side's slots fit the chain as a whole, and the base lies off their first slot)
    complete = len(unique) == M - 2 == K and (cands.base is None or base_ok)
    out = dict(unique) if held or complete else {}
    # an end that joins a matching of its own next to its first (last) slot disputes the numbers it gives
    # otherwise (a loose join is weak evidence: it disputes nothing)
    tight = feas.copy()
    tight[0, 0, :, 2:] = False
    tight[:, :M - 2, C - 1, M - 1] = False
    # (an end next to its first or last slot on every best matching: a matching through it is one of those)
    for a, node, nxt in ((0, 0, base_next), (C - 1, M - 1, tip_next)):
        if allowed[a, node] and out and not nxt:
            out = _agree_with_end(out, tight, allowed, wgt, anchor=a, anchor_weight=anchor_weight)
    last = [k for k, u in out.items() if u == M - 2]
    if cands.tip is not None and last:
        # tip corners that do not fit the last slot within twice the tolerance (the bridged outline rounds a
        # convex corner off a little) dispute it: a tendon loop's corner, or a spurious slot past a missing
        # last one (a base corner found is often a holder's face off the base edge: it disputes nothing)
        lay = notch_layout(geom)
        nodes, _ = _nodes(geom, cands.side, lay)
        d0, play = (a[0, 1] for a in _expected(geom, nodes[-2:], cands.side, scale, lay))
        miss = abs(np.linalg.norm(cands.tip - cands.far[last[0]]) - d0) - cands.slack_of(last[0])
        if miss > 2 * max(tol.rel_tol * d0, tol.abs_tol) + tol.per_joint * play:
            del out[last[0]]
    return ChainNumbers({k: int(joints[u]) for k, u in out.items()}, [k for k in range(K) if k not in out],
                        base_ok, tip_ok)


def _agree_with_end(out: dict, feas, allowed, wgt, *, anchor: int, anchor_weight: float) -> dict:
    """The numbers ``out`` (candidate -> node) that an end found (``anchor``: 0 the base, C - 1 the tip) does
    not dispute: a matching through the end that numbers a candidate otherwise, or gives its node to another
    (a mirrored view, a spurious slot next to a missing one, a slot split in two)."""
    C, M = allowed.shape
    at = np.zeros_like(allowed)
    at[anchor, 0 if anchor == 0 else M - 1] = True
    via = _best(feas, allowed, wgt, start=at if anchor == 0 else allowed, end=allowed if anchor == 0 else at)
    keep = {}
    for k, u in out.items():
        if via.score > anchor_weight:
            others = np.delete(via.on[:, u], k + 1)
            if np.delete(via.on[k + 1], u).any() or others.any():
                continue
        keep[k] = u
    return keep
