"""Notch-corner detector: image -> the numbered notch points in plane mm (geometry.md).

The detector does **not** assume the kinematics (a detector that does looks
perfect on images made by the same model and degrades on real geometry). It
uses the silhouette of geometry.md ("What a camera sees") and the
geometry's dimensions (outer radius ``R``, slot widths and depths, slot
sides, where along a side the joints are). :mod:`.pipeline` runs the stages
in order (they hand each other the records of :mod:`.records`), one module each:

1. :mod:`.segment` — segment a downsampled copy: polarity (dark on light
   or light on dark) from the image border, a quadratic background surface,
   a 50 % threshold, the largest region, holes filled except slot-sized ones
   (shading and a specular streak inside the tube or holder do not split it).
2. :mod:`.outline` — bridge the slot mouths (a closing), find the slots.
3. :mod:`.base` — separate the tube (``2R`` wide) from its holder (wider:
   an opening) and the image border; the base end is where the tube leaves
   them, found in any in-plane orientation (or stated: ``base=``); the free
   end is the tip.
4. :mod:`.numbering`, :mod:`.corners` — number the slots from the base,
   find the tip, first corner estimates (stages 2-4: :mod:`.locate`).
5. :mod:`.subpixel`, :mod:`.refine` — sub-pixel corners from edge profiles and line fits at
   full resolution, only near the corners, started where the tube ends
   (a polished limb the silhouette misses); a face seen a little from the
   side (tilt, perspective) as an ellipse arc tangent to the outer edge.
6. :mod:`.plane` — map to the plane; check rigid-link widths, the base edge
   and every link's corners against its drawn shape (a slot numbered one
   off, a holder corner taken for a base point: not reported).

A specular streak that splits the silhouette is filled across the tube
(:func:`~.segment.band_directions`) and the corners located again. Without a
calibration (``camera=None``) the scale comes from the tube's outer diameter
(:mod:`.width`, a fronto-parallel view is assumed: the band holding the
slots on a coarse copy, profiles across its centreline at full resolution)
and is reported with its uncertainty in the :class:`Detection`. A camera
JPEG's tone curve is undone first with ``tone_gamma``.

Statuses: ``ok``; ``occluded`` (not visible, hidden by the holder, cut off,
not found: NaN); ``ambiguous`` (found, but its fit or its identity is
doubtful: NaN plane coordinates, the pixel position kept for the overlay).
No point is ever interpolated from a model. Every tolerance is a field of
:class:`DetectorOptions`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ...physics.geometry import Geometry
from ...imaging import to_gray
from ...units import MM
from .options import DetectorOptions
from .overlay import draw_overlay, overlay_with_crop
from .pipeline import detect_at
from .pipeline import refinement_image
from .pipeline import segmented as _segmented
from .pipeline import streak_length as _streak_length
from .plane import finish, link_distances, link_tolerance
from .records import Setup
from .result import STATUSES, Detection, detections_table, empty_detection
from .dims import slot_depths, slot_widths
from .segment import Segmentation, band_directions, fill_holes, fill_thin_lines, largest_region
from .subpixel import edge_stations as _stations
from .view import DiameterScale, mirror_without_camera, view_orientation
from .width import SlotGaps, band_centreline, band_width, measure_diameter, plausible_radii, trim_box, tube_band

__all__ = ["STATUSES", "Detection", "DetectorOptions", "detect_notches", "detections_table", "draw_overlay",
           "mirror_without_camera", "overlay_with_crop", "work_factor"]


def _linearised(image, gamma: float):
    """The image in linear light: ``full (v / full) ** gamma`` (``full`` = 255 for 8-bit images, 65535 for
    16-bit, else the largest value); a table look-up for 8-bit images."""
    img = np.asarray(image)
    if gamma == 1.0:
        return img
    if img.dtype == np.uint8:
        table = (255.0 * (np.arange(256, dtype=np.float32) / 255.0) ** gamma).astype(np.float32)
        if img.ndim == 2:
            return table[img]
        return cv2.LUT(img, table)          # a float table: 8 bits would make the dark end too coarse
    full = 65535.0 if img.dtype == np.uint16 else max(float(np.max(img)), 1e-12)
    return (full * np.power(np.clip(img.astype(np.float32) / full, 0, None), gamma)).astype(np.float32)


def _gray(img) -> np.ndarray:
    """The gray image the stages read: a 2-D 8-bit image as it is (each stage converts only the pixels it
    reads: the working copy's blocks, the regions around the corners), anything else :func:`to_gray`'s
    float32 copy (the same values either way)."""
    if img.dtype == np.uint8 and img.ndim == 2 and img.size:
        return img
    return to_gray(img)


def _options(options, overrides) -> DetectorOptions:
    opts = options if options is not None else DetectorOptions()
    return opts.replace(**overrides) if overrides else opts


def detect_notches(image, camera, geom: Geometry, *, mirror: bool = False, base: str | None = None,
                   options: DetectorOptions | None = None, **overrides) -> Detection:
    """Find the numbered notch corners (geometry.md) in one image.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
        Raw camera image (any numeric dtype).
    camera : CameraModel or None
        Calibrated camera with the plane pose, matching the image size; or
        None: the scale then comes from the tube's outer diameter (a
        fronto-parallel view), see :attr:`Detection.assumption`.
    geom : Geometry
        Dimensions and slot layout (the kinematics is not used).
    mirror : bool
        The experiment's ``mirror`` flag (a reflected view, geometry.md). It
        means the same with and without a camera file: without one the plane
        frame is the image's, x right and y down, the handedness of every
        camera file (a calibration board is seen from its printed side). With
        the tube's tip up in the picture, ``mirror = false`` puts the
        manipulator's +x (the right-side slots) on the image's left.
    base : {"top", "bottom", "left", "right"}, optional
        The image side the tube's base is at; found automatically when None
        (the end attached to the holder or the image border).
    options : DetectorOptions, optional
    **overrides
        Single options by name (e.g. ``max_sigma_px=0.2``).

    Returns
    -------
    Detection

    Raises
    ------
    ValueError
        The image size differs from the camera file's, the camera has no
        plane pose, the image is too small, or ``base`` is not a side.
    """
    opts = _options(options, overrides)
    img = np.asarray(image)
    gray = _gray(img)
    colour = img[..., :3] if img.ndim == 3 and img.shape[2] >= 3 else None
    # the silhouette on the file's values, the sub-pixel edges in linear light (pipeline.refinement_image)
    cache = {"colour": colour}
    if opts.tone_gamma != 1.0:
        cache["linear"] = (_gray(_linearised(img, opts.tone_gamma)), {})
    H, W = gray.shape
    if base is not None and base not in ("top", "bottom", "left", "right"):
        raise ValueError(f"base must be top, bottom, left or right, got {base!r}")
    if camera is None:
        return _uncalibrated(gray, geom, opts, mirror=mirror, base=base, cache=cache)
    camera.check_image(gray)
    if not camera.has_plane:
        raise ValueError("the camera model has no plane pose: calibrate with --plane-image")
    px_per_m, sgn = view_orientation(camera, (H, W), mirror)
    f = work_factor(geom, px_per_m, opts)
    extra = {"scale_mm_per_px": 1.0 / (px_per_m * MM), "scale_sigma": 0.0}
    return detect_at(gray, Setup(camera, geom, opts, f, px_per_m, sgn, base), extra=extra,
                     cache=cache).detection


def work_factor(geom: Geometry, px_per_m: float, opts: DetectorOptions) -> int:
    """The block-averaging factor of the working copy, from the tube's size in pixels (options
    ``work_radius_px``, ``work_slot_px``): the file's size does not enter."""
    r = min(geom.outer_radius * px_per_m / opts.work_radius_px,
            float(slot_widths(geom).min()) * px_per_m / opts.work_slot_px)
    return max(1, int(round(r)))



@dataclass(frozen=True)
class RoughScale:
    """The tube found on a coarse copy before the scale is known (no calibration).

    Attributes
    ----------
    radius_px : float
        The tube's radius [coarse px].
    factor : int
        Block-averaging factor of the coarse copy.
    region : ndarray (h, w) uint8
        The silhouette the tube was found in, cropped to the object's box.
    offset : (int, int)
        The crop's (x0, y0) in the coarse copy [coarse px].
    seg : Segmentation
        The coarse copy's segmentation.
    others : tuple of float
        Where no band holds a slot: the silhouette's other bands the tube could be [coarse px] (a
        polished tube's reflections and a shadow break its slots up; a detection at each scale decides).
    directions : ndarray (h, w) float32 or None
        :func:`~.segment.band_directions` of ``region`` at ``radius_px`` where the scale search computed
        them already (the width profiles' directions); None: not computed.
    gaps : SlotGaps or None
        The band's slots as the scale search found them at ``radius_px`` (the centreline's); None: not found.
    """

    radius_px: float
    factor: int
    region: np.ndarray
    offset: tuple
    seg: Segmentation
    others: tuple = ()
    directions: np.ndarray | None = None
    gaps: SlotGaps | None = None

    @property
    def px_per_m(self) -> float:
        """The rough scale [full-resolution px per m] for a tube of radius ``R`` (divide by R)."""
        return self.radius_px * self.factor


def _object_box(mask, pad: int):
    """The largest region's box grown by ``pad`` and clipped to the mask: (x0, y0, x1, y1)."""
    _, (x0, y0, bw, bh) = largest_region(mask)
    h, w = mask.shape
    return max(x0 - pad, 0), max(y0 - pad, 0), min(x0 + bw + pad, w), min(y0 + bh + pad, h)


def _rough_scale(gray, geom, opts, cache):
    """The tube's radius on a coarse copy (:class:`RoughScale`), or (None, message). Again with thin
    background lines filled across the tube (a streak may have split the silhouette). The coarse copy's
    size follows the file's (the tube's size is not known yet); the work is done in the box around the
    object, so a small tube in a large frame costs little."""
    H, W = gray.shape
    R = geom.outer_radius
    fc = max(1, int(round(max(H, W) / (opts.lowres_long_side_px / 2.5))))
    shape_c, seg_c = _segmented(gray, fc, opts, cache)
    if seg_c.mask is None:
        return None, seg_c.message
    max_close = int(opts.uncal_close_frac * max(shape_c))
    x0, y0, x1, y1 = _object_box(seg_c.mask, max_close + 4)
    mask = np.ascontiguousarray(seg_c.mask[y0:y1, x0:x1])

    def radius(m_):
        reg = largest_region(m_)[0]
        return (*tube_band(reg, geom, max_close_px=max_close, close_factor=opts.close_slot_factor,
                           area_range=opts.rough_slot_area_range, filled=fill_holes(reg),
                           max_radius_px=0.25 * min(shape_c)), reg)

    R_lo, n_slots, gaps, series, reg = radius(mask)
    directions = None
    if np.isfinite(R_lo):
        # a streak splits the tube into two bands of half its width, each with the slots beside it: the
        # filled silhouette's band is the tube when it holds as many slots and is wider
        across = band_directions(mask, opts.close_slot_factor * float(slot_widths(geom).max()) / R * R_lo + 1, R_lo)
        # a closing adds pixels only between the mask's: computed in its box (the same pixels, fewer to close)
        box = trim_box(mask)
        filled = mask.copy()
        filled[box] = fill_thin_lines(np.ascontiguousarray(mask[box]), _streak_length(geom, opts) / R * R_lo,
                                      across=across[box])
        # nothing filled: the same silhouette, the same bands and slots (not searched again)
        R2, n2, gaps2, series2, reg2 = ((R_lo, n_slots, gaps, series, reg) if np.array_equal(filled, mask)
                                        else radius(filled))
        if np.isfinite(R2) and (n2 > n_slots or (n2 == n_slots and R2 > R_lo)):
            R_lo, gaps, series, reg = R2, gaps2, series2, reg2
        elif np.array_equal(reg, mask):
            directions = across            # the width profiles' directions: the same band, the same radius
    if not np.isfinite(R_lo):
        return None, "no tube found: no band of constant width in the silhouette"
    others = () if n_slots else tuple(
        rc for rc in plausible_radii(fill_holes(reg), geom, max_close_px=max_close, min_slot_px=2.0,
                                     max_radius_px=0.25 * min(shape_c), series=series) if rc != R_lo)
    return RoughScale(float(R_lo), fc, reg, (x0, y0), seg_c, others, directions, gaps), ""


def _band_widths(gray, geom, opts, rough: RoughScale):
    """The tube's width [px] across its centreline where it has its full width (profiles at full
    resolution, at most ``4 width_stations`` of them)."""
    R_lo, fc, reg = rough.radius_px, rough.factor, rough.region
    w_, d_ = float(np.median(slot_widths(geom))), float(np.median(slot_depths(geom)))
    pts = band_centreline(reg, R_lo, slot_width=w_, slot_depth=d_, radius=geom.outer_radius,
                          close_factor=opts.close_slot_factor, area_range=opts.rough_slot_area_range, gaps=rough.gaps)
    if len(pts) < 3:
        return np.zeros(0)
    pts = pts[np.linspace(0, len(pts) - 1, min(len(pts), 4 * opts.width_stations)).astype(int)]
    across = rough.directions
    if across is None:
        across = band_directions(reg, opts.close_slot_factor * float(slot_widths(geom).max()) / geom.outer_radius
                                 * R_lo + 1, R_lo)
    ang = across[pts[:, 1].astype(int), pts[:, 0].astype(int)]
    fine = np.isfinite(ang)
    centres = (pts[fine] + rough.offset) * fc + (fc - 1) / 2.0
    normals = np.stack([np.cos(ang[fine]), np.sin(ang[fine])], 1)
    return band_width(gray, centres, normals, 2 * R_lo * fc, rough.seg.contrast)


def _scale_extra(widths, R):
    """The scale from measured widths (outliers beyond 3 MAD dropped): (px per m, Detection extras), or None."""
    widths = widths[np.isfinite(widths)]
    if len(widths) >= 3:
        med = float(np.median(widths))
        mad = 1.4826 * float(np.median(np.abs(widths - med)))
        widths = widths[np.abs(widths - med) <= max(3 * mad, 0.5)]
    if len(widths) < 3:
        return None
    wpx = float(np.mean(widths))
    # the spread of the profiles, not its standard error: what moves a profile's width (shading, the
    # perspective along the tube, a tilt, a profile near a slot) varies slowly along the tube and does
    # not average out over neighbouring profiles
    sw = float(np.std(widths, ddof=1))
    mm_px = 2 * R / MM / wpx
    text = (f"no calibration: fronto-parallel view assumed; scale {mm_px:.6f} mm/px from the tube's outer "
            f"diameter {2 * R / MM:.3f} mm (geometry) measured as {wpx:.2f} ± {sw:.2f} px over {len(widths)} "
            "profiles; plane frame = image axes in mm (x right, y down, as a calibration board lying upright gives them); a view tilted by a degrees shrinks one "
            "direction by cos a, and the diameter's tolerance scales every length")
    return wpx / (2 * R), {"scale_mm_per_px": mm_px, "scale_sigma": mm_px * sw / wpx, "assumption": text}


def _uncalibrated(gray, geom, opts, *, mirror, base, cache):
    """The scale from the tube's diameter: a rough width on a coarse copy, the width across the tube's
    centreline at full resolution, one detection at that scale (a detection at the rough scale and
    widths next to its corners where the centreline gives too few)."""
    m = geom.n_points
    H, W = gray.shape
    sgn = view_orientation(DiameterScale(1.0, (W, H)), (H, W), mirror)[1]
    rough, why = _rough_scale(gray, geom, opts, cache)
    if rough is None:
        return empty_detection(m, "no_manipulator", why)
    bands = [rough] + [dataclasses.replace(rough, radius_px=float(rc), directions=None, gaps=None) for rc in rough.others]
    dets = [_at_rough_scale(gray, geom, opts, band, sgn=sgn, base=base, cache=cache) for band in bands]
    return _unconfirmed_scale(_links_agree(_most_confirmed(dets), geom))


def _links_agree(det: Detection, geom: Geometry) -> Detection:
    """The scale's σ at least its disagreement with the ok corners' own links: the corners on one link keep
    their straight-configuration distances (geometry.md), so the median of measured over expected distance,
    over every pair of ok corners on a link, is the scale the links give (a band measured too wide by a
    polished tube's halo gives widths that agree with each other, and corners that pass the rigid-link
    check's tolerance, 15 %, at a scale several % off)."""
    ok = np.array([s == "ok" for s in det.status])
    ratios = [d_meas / d_exp for pairs in link_distances(det.points, ok, geom).values()
              for _, _, d_meas, d_exp in pairs]
    if not ratios:
        return det
    off = det.scale_mm_per_px * abs(float(np.median(ratios)) - 1)
    return dataclasses.replace(det, scale_sigma=off) if off > det.scale_sigma else det


def _most_confirmed(dets: list) -> Detection:
    """Of detections at the scales of different bands, the one with the most corners ``ok`` (the first on a
    tie). A corner is ok where its link's lengths agree within their tolerance, so another band's
    detection with corners ok at a scale that differs is as well confirmed: the scale's σ is at least
    that difference."""
    best = max(dets, key=lambda d: d.n_ok)                # max keeps the first of equals
    if not best.n_ok:
        return best
    other = [abs(d.scale_mm_per_px - best.scale_mm_per_px) for d in dets if d.n_ok and d is not best]
    if not other or max(other) <= best.scale_sigma:
        return best
    return dataclasses.replace(best, scale_sigma=float(max(other)))


def _at_rough_scale(gray, geom, opts, rough, *, sgn, base, cache):
    """One detection from the band ``rough`` found: its width measured along the centreline, or next to
    the corners of a detection at the rough scale."""
    H, W = gray.shape
    R = geom.outer_radius
    scale = _scale_extra(_band_widths(gray, geom, opts, rough), R)
    if scale is not None:
        px_per_m, extra = scale
        cam = DiameterScale(1 / px_per_m, (W, H))
        det = detect_at(gray, Setup(cam, geom, opts, work_factor(geom, px_per_m, opts), px_per_m, sgn, base),
                        cache=cache, extra=extra).detection
        if det.n_ok == 0:
            # nothing confirms the band's width (shaded limbs pull its crossings inside, a profile across a
            # slot measures less): the widths next to the corners of a detection at the rough scale
            alt = _scale_via_corners(gray, geom, opts, rough, sgn=sgn, base=base, cache=cache)
            det = alt if alt.n_ok else det
    else:
        det = _scale_via_corners(gray, geom, opts, rough, sgn=sgn, base=base, cache=cache)
    return det


def _unconfirmed_scale(det: Detection) -> Detection:
    """No corner ``ok``: nothing confirms that the band measured was the tube (a holder's bar or half a tube
    split by a streak is as straight), so the scale's σ is not stated (NaN)."""
    if det.n_ok or not np.isfinite(det.scale_sigma):
        return det
    return dataclasses.replace(det, scale_sigma=math.nan)


def _scale_via_corners(gray, geom, opts, rough, *, sgn, base, cache):
    """A detection at the rough scale, widths next to its refined corners, the corners mapped again."""
    m = geom.n_points
    H, W = gray.shape
    R = geom.outer_radius
    px_per_m = rough.px_per_m / R
    f = work_factor(geom, px_per_m, opts)
    # the rough scale can be a few % off: no scale or base-edge check before the measured scale, and no search
    # outside the silhouette's edges (how much narrower than the tube it is needs the scale; the widths are
    # measured from the silhouette's edges)
    rough_setup = Setup(DiameterScale(1 / px_per_m, (W, H)), geom,
                        opts.replace(scale_tol=math.inf, base_edge_tol=math.inf, outer_reach_R=0.0), f, px_per_m,
                        sgn, base)
    run = detect_at(gray, rough_setup, extra={}, stations=True, cache=cache)
    det, ref = run.detection, run.refinement
    if ref is None or not ref.ok.any():
        return det
    st = _stations(ref, opts.width_stations, sgn)
    widths = measure_diameter(ref.img, ref.off, st, 2 * R * px_per_m, refinement_image(gray, f, opts, cache)[1],
                              ref.blur) if len(st) else np.zeros(0)
    scale = _scale_extra(widths, R)
    if scale is None:
        return empty_detection(m, "partial", "the tube's width could not be measured (no calibration): fewer "
                                             "than 3 profiles across straight links", det.contour_px)
    rough_ppm = px_per_m
    px_per_m, extra = scale
    cam = DiameterScale(1 / px_per_m, (W, H))
    if abs(px_per_m / rough_ppm - 1) <= opts.rescale_tol and ref.plane_input is not None:
        # the corners in pixels do not depend on the scale beyond the profile lengths: map them again
        p = ref.plane_input
        return finish(cam, geom, p, scale_tol=opts.scale_tol, base_edge_tol=opts.base_edge_tol,
                      link_tol=link_tolerance(geom, opts), **extra)
    setup = Setup(cam, geom, opts, work_factor(geom, px_per_m, opts), px_per_m, sgn, base)
    return detect_at(gray, setup, extra=extra, cache=cache).detection
