"""The detector's orchestration for one image at one scale: from the gray image and a :class:`~.records.Setup`
to a :class:`~.result.Detection` (see the package docstring).

The silhouette variants in order (:data:`VARIANTS`: the threshold, with thin streaks filled, by colour),
each located (:func:`.locate.locate`) until one gives every slot and the tip; the variants that located a
corner not yet ``ok`` refined (:func:`refine_and_finish`: :func:`.subpixel.refine_corners`, then
:func:`.plane.finish`), their corners merged point by point (:func:`.plane.merge_plane_inputs`) and
mapped to the plane once more. The stages live in their own modules, the records they hand each other
in :mod:`.records`."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from ...physics.geometry import notch_layout
from .base import holder_mask
from .dims import slot_depths, slot_widths
from .locate import locate, slot_pins
from .plane import PlaneInput, finish, link_tolerance, merge_plane_inputs
from .records import Located, Refined, Setup, Variant
from .result import Detection, empty_detection
from .segment import (Segmentation, band_directions, chroma_distance, close_disk, downsample, fill_thin_lines,
                      largest_region, local_segmentation, remove_thin)
from .segment import segment as _segment
from .subpixel import link_widths, refine_corners, statuses

__all__ = ["VARIANTS", "colour_segmentation", "detect_at", "fill_streaks", "locate_variants", "pinned_pass",
           "refine_and_finish", "segmented", "shared_pins", "streak_length", "variant_mask"]


def refinement_image(gray, f, opts, cache: dict):
    """The image the sub-pixel stage reads and its object-minus-background contrast: the image in linear
    light where the caller undid a tone curve (``cache["linear"]``: a blurred edge's 50 % crossing is the
    edge only in linear light), else ``gray`` itself. The silhouette, the slots and their numbers are found
    on the file's values (``gray``): the noise of a tone-mapped image is about even across its levels, so
    one noise estimate and one threshold hold from the shadows to the highlights."""
    if "linear" not in cache:
        return gray, segmented(gray, f, opts, cache)[1].contrast
    lin, own = cache["linear"]
    return lin, segmented(lin, f, opts, own)[1].contrast


def segmented(gray, f, opts, cache: dict):
    """Downsampled copy (cached per factor), its segmentation and largest region."""
    H, W = gray.shape
    if H // f < 16 or W // f < 16:
        raise ValueError(f"image too small: {W}x{H} px")
    if f not in cache:
        small = downsample(gray, f)
        seg = _segment(small, min_snr=opts.min_snr, noise_scale=f, level=opts.segment_level,
                       full=gray if f > 1 else None)
        cache[f] = (small.shape, seg)
    return cache[f]


def colour_segmentation(cache, f: int, opts) -> Segmentation | None:
    """The segmentation of the working copy's distance from the backdrop's colour (:func:`chroma_distance`):
    a shadow or shading on a coloured card keeps its colour, a neutral metal tube does not. None for a gray
    image. Kept in ``cache`` by factor: without a camera file every rough scale tried reads it again."""
    colour = cache.get("colour")
    if colour is None:
        return None
    key = ("colour", f, opts.min_snr, opts.segment_level)           # the same for every rough scale tried
    if key not in cache:
        cache[key] = _segment(chroma_distance(downsample(colour, f)), min_snr=opts.min_snr, noise_scale=f,
                              level=opts.segment_level)
    return cache[key]


def streak_length(geom, opts) -> float:
    """Longest background line filled across the tube [m]: ``streak_fill_R`` R, but short enough that a
    segment 25° off the direction across the tube cannot span a slot (1.5 w)."""
    return min(opts.streak_fill_R * geom.outer_radius, 1.5 * float(slot_widths(geom).min()))


def fill_streaks(mask, length_px, *, holder_radius, bridge_px, radius_px):
    """:func:`fill_thin_lines` across the tube (a streak along it, not a slot's mouth), except next to the
    holder (the corners where the tube meets it stay sharp); computed in the box around the largest region."""
    _, (x0, y0, bw, bh) = largest_region(mask)
    pad = int(2 * max(bridge_px, radius_px, length_px)) + 4
    X0, Y0 = max(x0 - pad, 0), max(y0 - pad, 0)
    X1, Y1 = min(x0 + bw + pad, mask.shape[1]), min(y0 + bh + pad, mask.shape[0])
    crop = np.ascontiguousarray(mask[Y0:Y1, X0:X1])
    filled = mask.copy()
    filled[Y0:Y1, X0:X1] = fill_thin_lines(crop, length_px, across=band_directions(crop, bridge_px, radius_px))
    region, _ = largest_region(filled)
    holder = holder_mask(region, holder_radius, regrow=False)
    if holder.any():
        near = cv2.dilate(holder, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * int(length_px) + 5,) * 2))
        filled = np.where(near > 0, mask, filled).astype(np.uint8)
    return filled


#: The silhouettes :func:`detect_at` tries, in order: the threshold, with thin streaks filled, by colour, against
#: the local background (a soft shadow as dark as the tube is not tube, :func:`.segment.local_segmentation`).
VARIANTS = ("threshold", "streaks", "colour", "local")


def variant_mask(name: str, seg: Segmentation, setup: Setup, cache: dict):
    """The working-copy silhouette of one variant (:data:`VARIANTS`), or None (no colour image, or no
    region by colour)."""
    geom, opts, f, low_m = setup.geom, setup.opts, setup.f, setup.low_m
    R = geom.outer_radius
    if name == "threshold":
        return seg.mask
    if name == "streaks":
        return fill_streaks(seg.mask, streak_length(geom, opts) / low_m,
                            holder_radius=opts.holder_width_factor * R / low_m, radius_px=R / low_m,
                            bridge_px=opts.close_slot_factor * float(slot_widths(geom).max()) / low_m + 1)
    if name == "local":
        # thin lines stay, as on the threshold's silhouette: a wire taken off the tip face would leave the
        # tip's corners to be refined across it
        seg_c = local_segmentation(seg, opts.local_bg_R * R / low_m, min_snr=opts.min_snr, noise_scale=f,
                                   level=opts.segment_level)
        return None if seg_c.mask is None else seg_c.mask
    seg_c = colour_segmentation(cache, f, opts)
    if seg_c is None or seg_c.mask is None:
        return None
    # a wire or a tendon is as neutral as the tube, and a grid line as coloured: thin lines go
    thin = min(2 * R - float(slot_depths(geom).max()), R) / low_m
    mask = remove_thin(seg_c.mask, thin_px=thin, max_length_px=1.5 * float(slot_widths(geom).max()) / low_m)
    # and gaps of a pixel or two closed (a backbone whose highlight mirrors the card)
    return close_disk(mask, opts.colour_close_px) if opts.colour_close_px > 0 else mask


def locate_variants(seg: Segmentation, shape, setup: Setup, cache: dict, *, wanted: set) -> list[Variant]:
    """Stages 2-4 on each silhouette variant in turn (:data:`VARIANTS`), until one locates every point in
    ``wanted``; a largest region far smaller than the tube's silhouette (option ``area_range``) is a
    failed variant."""
    geom, opts, low_m = setup.geom, setup.opts, setup.low_m
    m = geom.n_points
    exp_area = (2 * geom.outer_radius * (geom.tip_z - geom.base_edge_z)
                - float(np.sum(slot_widths(geom) * slot_depths(geom)))) / low_m ** 2
    tried = []
    for name in VARIANTS:
        mask = variant_mask(name, seg, setup, cache)
        if mask is None:
            continue
        region, box = largest_region(mask)
        area = np.count_nonzero(region)                  # a 0/1 mask: its sum; the fraction is its mean
        ratio = area / exp_area
        if ratio < opts.area_range[0] or area / region.size > 0.95:
            got = empty_detection(m, "no_manipulator", f"no manipulator found: the largest region is "
                                  f"{ratio:.2f} x the tube's silhouette area (wrong geometry or camera file?)")
        else:
            got = locate(region, box, shape, setup, small=seg.image, dark=seg.contrast < 0)
        tried.append(Variant(name, mask, got))
        if isinstance(got, Located) and wanted <= got.points:
            return tried
    return pinned_pass(tried, seg, shape, setup)


def shared_pins(pins: list, geom, agree_px: float) -> dict:
    """The union of several silhouettes' numbered slots (:func:`.locate.slot_pins`), side -> list of (joint,
    corners [px]); a joint two silhouettes place more than ``agree_px`` apart is left out (one of them is not
    that slot's, or not at its place)."""
    by = {}
    for p in pins:
        for sd, got in p.items():
            for j, c in got:
                by.setdefault((sd, j), []).append(c)
    out = {}
    for (sd, j), cs in sorted(by.items()):
        if all(np.max(np.linalg.norm(c - cs[0], axis=1)) <= agree_px for c in cs[1:]):
            out.setdefault(sd, []).append((j, cs[0]))
    return out


def pinned_pass(tried: list, seg: Segmentation, shape, setup: Setup) -> list[Variant]:
    """Each located variant once more with the slots the other variants numbered as pins (:func:`shared_pins`,
    option ``pin_agree_w`` slot widths): one silhouette can show one side's slots whole and the other side's
    broken, another the reverse, and each side's numbered slots bound the other side's along the tube
    (:func:`.numbering.number_slots`). A variant is read again only where the others numbered a slot it did not;
    the new reading replaces the first only where it locates every corner the first did and more. Variants numbered without the tip (``confirm_width``) give no pins: their silhouette may be
    half the tube."""
    geom = setup.geom
    if len(set(geom.slot_sides)) < 2:
        return tried                             # pins bound the other side's slots: a one-sided tube has none
    pins = {t.name: slot_pins(t.outcome, geom) for t in tried
            if isinstance(t.outcome, Located) and not t.outcome.confirm_width}
    agree = setup.opts.pin_agree_w * float(slot_widths(geom).min()) * setup.px_per_m
    out = []
    for t in tried:
        others = shared_pins([p for n, p in pins.items() if n != t.name], geom, agree)
        own = {(sd, j) for sd, got in pins.get(t.name, {}).items() for j, _ in got}
        if not isinstance(t.outcome, Located) or not {(sd, j) for sd, got in others.items() for j, _ in got} - own:
            out.append(t)
            continue
        region, box = largest_region(t.mask)
        got = locate(region, box, shape, setup, small=seg.image, dark=seg.contrast < 0, pins=others)
        better = isinstance(got, Located) and got.points > t.outcome.points
        out.append(Variant(t.name, t.mask, got) if better else t)
    return out


def detect_at(gray, setup: Setup, *, extra, stations=False, cache=None) -> Refined:
    """Stages 1-6 at a known scale. When the silhouette does not give every slot and the tip, it is located
    again with thin background lines across the tube filled (a specular streak that splits it), then by
    colour; every variant that located a corner not yet ``ok`` on an earlier one is refined, and their
    corners are merged point by point (:func:`~.plane.merge_plane_inputs`). Returns the Detection and the
    refinement (None when nothing was located) of the variant that located the most corners, carrying the
    merged corners.

    ``extra``: the Detection's scale fields (:func:`~.plane.finish`); ``stations``: the refinement's region
    also holds the tube's outline (diameter stations, no calibration); ``cache``: the working copies'
    segmentations by factor, and the colour image under ``"colour"``."""
    geom, opts = setup.geom, setup.opts
    m = geom.n_points
    cache = {} if cache is None else cache
    shape, seg = segmented(gray, setup.f, opts, cache)
    if seg.mask is None:
        return Refined(empty_detection(m, "no_manipulator", seg.message))
    lay = notch_layout(geom)
    wanted = {i for i in range(m) if lay.kind[i] != "base"}
    tried = locate_variants(seg, shape, setup, cache, wanted=wanted)
    found = [t.outcome for t in tried if isinstance(t.outcome, Located)]
    # slot counts that fit the opposite mirror flag are strong evidence: they win over an incomplete result
    conflict = [t.outcome for t in tried if isinstance(t.outcome, Detection)
                and "opposite mirror flag" in t.outcome.message]
    if not found or (conflict and not any(wanted <= t.points for t in found)):
        return Refined((conflict or [tried[0].outcome])[0])
    order = sorted((t for t in tried if isinstance(t.outcome, Located)), key=lambda t: -len(t.outcome.specs))

    def refined(t: Variant) -> Refined:
        # corners found on the colour silhouette are confirmed by the tube's width on it: a polished limb that
        # mirrors the backdrop is missing from it, and an edge inside the tube then passes for the outer edge
        # (and so are slots numbered without the tip, which would confirm the tube's width)
        ctx = t.outcome
        img, contrast = refinement_image(gray, setup.f, opts, cache)
        return refine_and_finish(img, contrast, ctx, setup, extra=extra, stations=stations,
                                 width_mask=t.mask if t.name == "colour" or ctx.confirm_width else None)

    # the variants are refined and the corners merged point by point: each numbers each side on its own
    # evidence (the threshold one side, the colour distance the other), and a corner two variants place
    # apart is not used; a variant that located only corners already ok adds nothing and is not refined
    runs, names, done = [refined(order[0])], [order[0].name], set()
    for t in order[1:]:
        ref = runs[-1].refinement
        if ref is not None and ref.plane_input is not None:
            done |= {i for i, st in enumerate(ref.plane_input.status) if st == "ok"}
        if t.outcome.points - done:
            runs.append(refined(t))
            names.append(t.name)
    keep = [q for q, run in enumerate(runs) if run.refinement is not None and run.refinement.plane_input is not None]
    if len(keep) < 2:
        return runs[0]
    merged = merge_plane_inputs([runs[q].refinement.plane_input for q in keep], [names[q] for q in keep],
                                agree_px=opts.variant_agree_w * float(slot_widths(geom).min()) * setup.px_per_m)
    det = finish(setup.camera, geom, merged, scale_tol=opts.scale_tol, base_edge_tol=opts.base_edge_tol,
                 link_tol=link_tolerance(geom, opts), **extra)
    return Refined(det, dataclasses.replace(runs[keep[0]].refinement, plane_input=merged))


def refine_and_finish(gray, contrast: float, ctx: Located, setup: Setup, *, extra=None, stations=None,
                      width_mask=None) -> Refined:
    """Stages 5-6 for located corners (:func:`~.locate.locate`): the Detection, and the Refinement (None when
    there are no corners).

    ``width_mask``: a working-copy silhouette on which each ok slot corner's link must be ``2R`` wide
    (within ``width_tol``, :func:`link_widths`), else the corner is ambiguous."""
    camera, geom, opts = setup.camera, setup.geom, setup.opts
    m = geom.n_points
    extra = extra or {}
    status, msg = list(ctx.status), list(ctx.messages)
    ref = None
    pts_px, ideal, cov = np.full((m, 2), np.nan), np.full((m, 2), np.nan), np.full((m, 2, 2), np.nan)
    blur = math.nan
    specs = ctx.specs
    if specs:
        far = ctx.tube_px if stations else None
        ref = refine_corners(gray, specs, setup, full=ctx.full, contrast=contrast, extra_px=far,
                             outline_px=ctx.contour_px)
        status, pts_px, ideal, cov = statuses(ref, m, status, gray.shape, opts)
        if width_mask is not None:
            wid = link_widths(ref, width_mask, setup.f, camera, setup.px_per_m, geom.outer_radius)
            for k in np.nonzero(np.abs(wid / (2 * geom.outer_radius) - 1) > opts.width_tol)[0]:
                i = ref.pidx[k]
                if status[i] == "ok":
                    status[i] = "ambiguous"
                    ideal[i], cov[i] = np.nan, np.nan
        blur = ref.blur
        ref.plane_input = PlaneInput(pts_px.copy(), ideal.copy(), cov.copy(), list(status), list(msg), blur,
                                     ctx.contour_px, ctx.side)
    det = finish(camera, geom, PlaneInput(pts_px, ideal, cov, status, msg, blur, ctx.contour_px, ctx.side),
                 scale_tol=opts.scale_tol, base_edge_tol=opts.base_edge_tol, link_tol=link_tolerance(geom, opts),
                 **extra)
    return Refined(det, ref)
