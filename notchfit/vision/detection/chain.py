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
chain). Of the feasible numberings, those matching the most are kept; a candidate gets a number only when
every one of them gives it that number (a spurious gap, a missing slot, a
hidden end link cost only the slots they touch; a shift that the chain cannot
tell apart numbers nothing: never a wrong number). The links repeat, so a
side is numbered only when the base or the tip corners agree with its slots
in every best matching (they fix where the count starts), or when every
joint of the side is matched and no base or tip corner found disagrees. The candidates keep their
own measured corners: the chain decides identities only.

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
    """

    side: int
    near: np.ndarray
    far: np.ndarray
    base: np.ndarray | None = None
    tip: np.ndarray | None = None
    slack: np.ndarray | None = None


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
        The anchor agrees with the slots in every best matching.
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
    lay = notch_layout(geom)
    nodes, joints = _nodes(geom, cands.side, lay)
    M = len(nodes)
    d0, play = _expected(geom, nodes, cands.side, scale, lay)
    # the candidates, with the anchors as candidates 0 (base) and K + 1 (tip) that only their node takes
    K = len(cands.near)
    nan2 = np.full(2, np.nan)
    near = np.vstack([[cands.base if cands.base is not None else nan2], cands.near.reshape(-1, 2),
                      [cands.tip if cands.tip is not None else nan2]])
    far = np.vstack([[cands.base if cands.base is not None else nan2], cands.far.reshape(-1, 2),
                     [cands.tip if cands.tip is not None else nan2]])
    C = K + 2
    allowed = np.zeros((C, M), bool)                 # candidate c may take node u
    allowed[1:K + 1, 1:M - 1] = True
    allowed[0, 0] = cands.base is not None
    allowed[C - 1, M - 1] = cands.tip is not None
    d = np.linalg.norm(far[:, None, :] - near[None, :, :], axis=2)          # (C, C) far of c' -> near of c
    limit = np.maximum(tol.rel_tol * d0, tol.abs_tol) + tol.per_joint * play
    slack = np.zeros(C)
    if cands.slack is not None:
        slack[1:K + 1] = cands.slack
    limit = limit[None, :, None, :] + (slack[:, None] + slack[None, :])[:, None, :, None]
    ok_uu = (np.arange(M)[:, None] < np.arange(M)[None, :])
    ok_cc = (np.arange(C)[:, None] < np.arange(C)[None, :])
    # feasible[c', u', c, u]: c' at u' followed by c at u
    feas = (np.abs(d[:, None, :, None] - d0[None, :, None, :]) <= limit) \
        & ok_cc[:, None, :, None] & ok_uu[None, :, None, :] & allowed[:, :, None, None] & allowed[None, None, :, :]
    feas &= np.isfinite(d)[:, None, :, None]
    # each slot counts 1, an anchor ``anchor_weight``: a holder's face off the base edge or a droplet at the
    # tip is more common than a spurious slot that fits the chain
    wgt = np.ones(C)
    wgt[[0, C - 1]] = anchor_weight
    NEG = -1e9
    fwd = np.where(allowed, wgt[:, None], NEG)
    for c in range(C):
        prev = np.where(feas[:, :, c, :], fwd[:, :, None], NEG).max(axis=(0, 1))
        fwd[c] = np.where(allowed[c], wgt[c] + np.maximum(0.0, prev), NEG)
    bwd = np.where(allowed, wgt[:, None], NEG)
    for c in range(C - 1, -1, -1):
        nxt = np.where(feas[c], bwd[None, None, :, :][0], NEG).max(axis=(1, 2))
        bwd[c] = np.where(allowed[c], wgt[c] + np.maximum(0.0, nxt), NEG)
    best = float(fwd.max())
    if best <= 0:
        return ChainNumbers({}, list(range(K)))
    eps = 1e-6
    on = (np.abs(fwd + bwd - wgt[:, None] - best) < eps) & allowed           # (c, u) on some best matching
    # a candidate is skipped by some best matching when a best matching jumps over it
    edge_best = feas & (np.abs(fwd[:, :, None, None] + bwd[None, None, :, :] - best) < eps)
    firsts = on & (np.abs(fwd - wgt[:, None]) < eps)                          # best matchings start here
    lasts = on & (np.abs(bwd - wgt[:, None]) < eps)
    skipped = np.zeros(C, bool)
    cc = np.arange(C)
    for c1, _, c2, _ in zip(*np.nonzero(edge_best)):
        skipped |= (cc > c1) & (cc < c2)
    if firsts.any():
        skipped |= cc < np.nonzero(firsts.any(1))[0].max()
    if lasts.any():
        skipped |= cc > np.nonzero(lasts.any(1))[0].min()
    out, unnumbered = {}, []
    for k in range(1, K + 1):
        us = np.nonzero(on[k])[0]
        if len(us) == 1 and not skipped[k]:
            out[k - 1] = int(joints[us[0]])
        else:
            unnumbered.append(k - 1)
    # an anchor fixes the count only next to the side's first (last) slot: beyond a missing slot the
    # joints' play can reach a link's length
    from_base = np.nonzero(edge_best[0, 0])
    to_tip = np.nonzero(edge_best[:, :, C - 1, M - 1])
    base_ok = bool(on[0, 0] and not skipped[0] and len(from_base[1]) and np.all(from_base[1] == 1))
    tip_ok = bool(on[C - 1, M - 1] and not skipped[C - 1] and len(to_tip[1]) and np.all(to_tip[1] == M - 2))
    # equal links repeat: a shift by a joint (or the other side's slots, in a mirrored view) fits as well,
    # unless an end of the chain agrees, or every joint of the side is matched and no end found disagrees
    complete = len(out) == M - 2 and not unnumbered
    disagree = (cands.base is not None and not base_ok) or (cands.tip is not None and not tip_ok)
    if not (base_ok or tip_ok or (complete and not disagree)):
        return ChainNumbers({}, list(range(K)), False, False)
    return ChainNumbers(out, unnumbered, base_ok, tip_ok)
