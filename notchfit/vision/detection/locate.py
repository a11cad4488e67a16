"""Stages 2-4 on the working copy (:func:`locate`): the outline with the slots bridged, the base end, the
slots numbered, every corner's first estimate."""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter1d

from ...physics.geometry import notch_layout
from .base import find_base, holder_masks, raw_base_corners
from .chain import ChainTolerance
from .corners import base_specs, slot_specs, tip_specs
from .dims import slot_depths, slot_widths
from .numbering import ChainInput, number_slots, orient_corner_pair
from .outline import (bridge_slots, corner_window, crop_region, hole_ends, raw_mouth_corners, slot_mouths,
                      turn_angles, turn_peaks, wedge_pixels)
from .records import Crop, Located, Parsed, Setup
from .result import Detection, empty_detection

__all__ = ["locate", "slot_pins"]


def _one_sided_holes(ol, mouths, be, side: int, *, max_wall: float) -> dict:
    """A one-sided tube's slots all open on one side: a hole (a slot closed at its mouth) takes the end of
    its axis on that side of the tube (the right side comes first after the base, anticlockwise), whatever
    the light says (a thin backbone next to a wide wedge can look more open than a closed mouth)."""
    N = len(ol.contour)
    pos = lambda i: (i - be.i_right) % N
    out = dict(mouths)
    for s, (i0, _, bridged) in mouths.items():
        if bridged:
            continue
        ends = [e[2] for e in hole_ends(ol, s, max_wall=max_wall)]
        if len(ends) == 2:
            i = min(ends, key=pos) if side > 0 else max(ends, key=pos)
            out[s] = (i, i, False)
    return out


def _found(p: Parsed) -> tuple:
    """How much a parse numbered: (slots numbered from slot-sized gaps and the tip, all slots and the tip). A
    sliver numbered is weaker evidence than a slot (a fillet next to the holder can be one): a parse with the
    holder in that numbers every slot from slot-sized gaps wins over one whose last slot is a sliver."""
    slivers = sum(1 for s, _ in p.num.right + p.num.left if s in p.ol.sliver_ids)
    return p.n_found - slivers, p.n_found


def _joined(pieces: dict, mouths: dict, rawc: dict, pos):
    """The mouths and unbridged outer corners with every slot numbered from its pieces (label -> the labels of
    its pieces, ``numbering.Numbering.pieces``) spanning them: from the first corner of the piece first along
    the outline (``pos``: outline index -> position from the base) to the last corner of the last."""
    mouths, rawc = dict(mouths), dict(rawc)
    for first, group in pieces.items():
        a, b = min(group, key=lambda x: pos(mouths[x][0])), max(group, key=lambda x: pos(mouths[x][1]))
        ra, rb = rawc.get(a), rawc.get(b)
        mouths[first] = (mouths[a][0], mouths[b][1], True)
        rawc.pop(first, None)
        if ra is not None and rb is not None:
            rawc[first] = (ra[0], rb[1])
    return mouths, rawc


def _chain_input(ol, mouths, rawc, raw, plane_px, setup: Setup, *, to_plane, pins=None) -> ChainInput:
    """The slot candidates' outer corners and the base corners in the plane (low-res px), and the chain's
    tolerances (options ``chain_rel_tol``, ``chain_abs_w``, ``chain_abs_px``, ``chain_play``); ``pins``: another
    silhouette's numbered slots (:func:`slot_pins`, corners in px), taken to the plane."""
    geom, opts, low_m = setup.geom, setup.opts, setup.low_m
    cnt, mcnt = ol.contour, ol.raw_contour
    N = len(cnt)
    w = slot_widths(geom)
    pts, slack = [], {}
    for s, (i0, i1, bridged) in mouths.items():
        if s in rawc:
            pts += [mcnt[rawc[s][0]], mcnt[rawc[s][1]]]
        elif bridged:
            pts += [cnt[(i0 - 1) % N], cnt[(i1 + 1) % N]]
        else:                                    # a closed mouth: one point for both corners
            pts += [cnt[i0], cnt[i0]]
            slack[s] = 0.5 * float(w.max()) / low_m
    ends = [None if raw is None or raw[e] is None else mcnt[raw[e]] for e in (0, 1)]
    pts += [e for e in ends if e is not None]
    plane = to_plane(np.array(pts, float).reshape(-1, 2))                                # one call for all
    corners = {s: (plane[2 * q], plane[2 * q + 1]) for q, s in enumerate(mouths)}
    rest = iter(plane[2 * len(mouths):])
    base = tuple(None if e is None else next(rest) for e in ends)
    tol = ChainTolerance(opts.chain_rel_tol, max(opts.chain_abs_w * float(w.min()) / low_m, opts.chain_abs_px),
                         opts.chain_play)
    to_low = lambda px: setup.camera.pixel_to_plane(np.asarray(px, float)) / low_m
    pinned = {sd: [(j, tuple(to_low(c))) for j, c in got] for sd, got in (pins or {}).items()}
    return ChainInput(corners, slack, base, plane_px, low_m, tol, pinned)


def _parse(crop: Crop, setup: Setup, *, exclude_holder: bool, pins=None) -> Parsed | Detection:
    """Bridge, base end, slot numbering on one cropped silhouette: Parsed, or the Detection of a failure;
    ``pins``: another silhouette's numbered slots (:func:`slot_pins`)."""
    camera, geom, opts, f, low_m, sgn = setup.camera, setup.geom, setup.opts, setup.f, setup.low_m, setup.sgn
    r_close, small_shape, gray, dark = crop.r_close, crop.shape, crop.gray, crop.dark
    lay = notch_layout(geom)
    m = lay.n_points
    R_lo = geom.outer_radius / low_m
    holder, strict = crop.holders
    ol = bridge_slots(crop.roi, crop.offset, small_shape, r_close=r_close, slot_area=crop.slot_area,
                      slot_area_range=opts.slot_area_range, sgn=sgn, holder=strict if exclude_holder else None,
                      holder_strict=strict, sliver_area=opts.sliver_area_px)
    if ol is None:
        return empty_detection(m, "no_manipulator", "no manipulator outline")
    X0, Y0 = ol.offset
    full = lambda p: (np.asarray(p, float) + [X0, Y0]) * f + (f - 1) / 2.0     # low-res box -> px
    cnt = ol.contour
    contour_px = full(cnt)
    plane_px = camera.pixel_to_plane(contour_px) / low_m
    dist = lambda i, j: float(np.linalg.norm(plane_px[i] - plane_px[j]))
    mouths = slot_mouths(ol, max_wall=0.5 * R_lo, gray=gray, dark=dark, reach=float(slot_depths(geom).max()) / low_m)
    strong = {s: v for s, v in mouths.items() if s not in ol.sliver_ids}      # slot-sized gaps: the ends' evidence
    be, why = find_base(ol, (holder, strict), R_lo=R_lo, dist=dist, sgn=sgn, min_tube_run_R=opts.min_tube_run_R,
                        min_base_run_R=opts.min_base_run_R, corner_turn_deg=opts.corner_turn_deg,
                        pair_tol=opts.pair_tol, base=setup.base, mouth_idx=[v[0] for v in strong.values()])
    if be is None:
        return empty_detection(m, "partial", why, contour_px)
    if be.kind == "corners":
        be = orient_corner_pair(be, strong, cnt)
    if len(set(geom.slot_sides)) == 1:
        mouths = _one_sided_holes(ol, mouths, be, geom.slot_sides[0], max_wall=0.5 * R_lo)
    raw = None
    hs, ws = small_shape
    at_border = lambda xy: min(xy[0] + X0, xy[1] + Y0, ws - 1 - xy[0] - X0, hs - 1 - xy[1] - Y0) <= 0.25 * R_lo + 2
    if be.kind != "border":
        pdist = lambda a, b: float(np.linalg.norm(np.diff(camera.pixel_to_plane(full(np.array([a, b]))),
                                                          axis=0))) / low_m
        grow = (math.sqrt(2) - 1) * opts.holder_width_factor * R_lo + 2       # the holder mask's regrowth
        for ends, search in (((be.i_right, be.i_left), 1.5 * r_close + 3),
                             ((be.i_right_wide, be.i_left_wide), 1.5 * r_close + 3 + grow)):
            found = raw_base_corners(ol.raw_contour, cnt[ends[0]], cnt[ends[1]], search=search,
                                     k=max(4, int(0.25 * R_lo)), sgn=sgn, dist=pdist, pair_tol=opts.pair_tol,
                                     R_lo=R_lo, at_border=at_border)
            if found is not None and None not in found:
                raw = found
                break
            raw = raw or found                   # one corner, the other outside the image: if no pair is found
    k = corner_window(r_close, R_lo)
    near_border = maximum_filter1d(ol.on_border.astype(np.uint8), size=2 * k + 3, mode="wrap").astype(bool)
    convex = turn_peaks(turn_angles(cnt, k, sgn), k, math.radians(opts.corner_turn_deg), +1.0, exclude=near_border)
    w_lo = float(slot_widths(geom).min()) / low_m
    rawc = raw_mouth_corners(ol, mouths, k=max(3, min(int(0.25 * R_lo), int(0.3 * w_lo))), sgn=sgn)
    chain = _chain_input(ol, mouths, rawc, raw, plane_px, setup,
                         to_plane=lambda p: camera.pixel_to_plane(full(p)) / low_m, pins=pins)
    num = number_slots(cnt, ol.on_border, be, mouths, convex, geom, dist=dist, pair_tol=opts.pair_tol, chain=chain,
                       weak=set(ol.sliver_ids))
    mouths, rawc = _joined(num.pieces, mouths, rawc, lambda i: (i - be.i_right) % len(cnt))
    if num.mirror_conflict:
        n_r = sum(1 for s in geom.slot_sides if s > 0)
        return empty_detection(
            m, "partial", f"the slot counts fit the opposite mirror flag ({n_r} right-side slots expected): "
                          "check `mirror` in experiment.toml", contour_px, status="ambiguous")
    return Parsed(ol, be, num, mouths, raw, full, contour_px, rawc)


def locate(region, box, small_shape, setup: Setup, *, small=None, dark=True, pins=None) -> Located | Detection:
    """Stages 2-4 on the downsampled copy: outline, base end, numbering, first corner estimates.

    ``pins``: slots another silhouette of the image numbered (:func:`slot_pins`): they bound this
    silhouette's slots of the other side along the tube (:func:`.numbering.number_slots`).

    The slots are bridged with the holder left out of the closing (its
    fillets would reach a slot near the holder); where that numbers fewer
    slots (a holder barely wider than the tube, whose opening bites into
    the tube's base), with the holder in.

    Returns
    -------
    Located, or the Detection of a failure
    """
    geom, opts, sgn, low_m = setup.geom, setup.opts, setup.sgn, setup.low_m
    lay = notch_layout(geom)
    m = lay.n_points
    R = geom.outer_radius
    R_lo = R / low_m
    w_max = float(slot_widths(geom).max())
    slot_area = float(np.median(slot_widths(geom) * slot_depths(geom))) / low_m ** 2
    keep = (opts.slot_area_range[0] * slot_area, opts.slot_area_range[1] * slot_area)
    r_close = int(math.ceil(opts.close_slot_factor * w_max / low_m)) + 1
    roi, offset = crop_region(region, box, small_shape, r_close + 2, keep_holes=keep)
    strict, grown = holder_masks(roi, opts.holder_width_factor * R_lo)
    holders = (grown, strict)
    gray = None if small is None else small[offset[1]:offset[1] + roi.shape[0], offset[0]:offset[0] + roi.shape[1]]
    crop = Crop(roi, offset, small_shape, r_close, slot_area, holders, gray, dark)
    res = fail = None
    for exclude in ((True, False) if holders[1].any() else (False,)):
        got = _parse(crop, setup, exclude_holder=exclude, pins=pins)
        if isinstance(got, Detection):
            fail = fail or got                   # the first failure, where no variant parses
            continue
        if res is None or _found(got) > _found(res):
            res = got
        if _found(got)[0] == geom.n_joints + 1:
            break
    if res is None:
        return fail
    ol, be, num, mouths, raw, full = res.ol, res.be, res.num, res.mouths, res.raw, res.full
    cnt = ol.contour
    index = {(lay.kind[i], int(lay.joint[i]), int(lay.side[i])): i for i in range(m)}
    specs = []
    if raw is not None:
        # the holder face searched beside a base corner: up to R (less on a narrow mount)
        face_len = R if geom.mount_half_width is None else min(geom.mount_half_width - R, R)
        specs += base_specs(ol.raw_contour, raw[0], raw[1], sgn=sgn, index=index, geom=geom, low_m=low_m,
                            face_len=face_len)
    else:
        num.messages.insert(0, "base corners hidden: the tube enters from the " +
                            ("image border" if be.kind == "border" else "holder without a corner at the base edge"))
    if num.tip is not None:
        specs += tip_specs(cnt, num.tip, index=index, geom=geom, low_m=low_m)
    rawc = res.rawc
    specs += slot_specs(cnt, ol.raw_contour, ((num.right, +1), (num.left, -1)), mouths, sgn=sgn, index=index,
                        geom=geom, low_m=low_m, raw_corners=rawc,
                        holes=wedge_pixels(ol, mouths, max_wall=0.5 * R_lo))
    tube = (np.arange(len(cnt)) - be.i_right) % len(cnt) <= (be.i_left - be.i_right) % len(cnt)
    return Located(specs, res.contour_px, num.status, num.messages, be.side, full, res.contour_px[tube], num.tipless)


def slot_pins(located: Located, geom) -> dict:
    """The slots a silhouette numbered, as pins for another silhouette of the same image: side (+1, -1) ->
    list of (joint, (2, 2) outer corners [px], nearer the base first). A slot with one corner located gives
    it twice. Numbers by the chain are never guessed (:mod:`.chain`), so they hold on any silhouette; where
    the corners lie is used only to order the other side's slots along the tube."""
    lay = notch_layout(geom)
    origin = located.full(np.zeros((1, 2)))[0]
    factor = located.full(np.ones((1, 2)))[0] - origin
    slots = {}
    for sp in located.specs:
        kind = lay.kind[sp.point]
        if kind in ("proximal", "distal"):
            key = (int(lay.side[sp.point]), int(lay.joint[sp.point]))
            slots.setdefault(key, {})[kind] = np.asarray(sp.xy, float) * factor + origin
    out = {}
    for (sd, j), c in sorted(slots.items()):
        near, far = c.get("proximal", c.get("distal")), c.get("distal", c.get("proximal"))
        out.setdefault(sd, []).append((j, np.array([near, far])))
    return out
