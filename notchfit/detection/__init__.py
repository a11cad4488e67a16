"""Notch-corner detector: image -> the numbered notch points in plane mm (geometry.md).

The detector does **not** assume the kinematics (a detector that does looks
perfect on images made by the same model and degrades on real geometry). It
uses the silhouette of geometry.md ("What a camera sees") and the
geometry's dimensions (outer radius ``R``, slot widths and depths, slot
sides, where along a side the joints are). Stages, one module each:

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
   find the tip, first corner estimates.
5. :mod:`.refine` — sub-pixel corners from edge profiles and line fits at
   full resolution, only near the corners.
6. :mod:`.plane` — map to the plane; check rigid-link widths and the base edge.

Without a calibration (``camera=None``) the scale comes from the tube's
outer diameter (:mod:`.width`, a fronto-parallel view is assumed) and is
reported with its uncertainty in the :class:`Detection`.

Statuses: ``ok``; ``occluded`` (not visible, hidden by the holder, cut off,
not found: NaN); ``ambiguous`` (found, but its fit or its identity is
doubtful: NaN plane coordinates, the pixel position kept for the overlay).
No point is ever interpolated from a model. Every tolerance is a field of
:class:`DetectorOptions`.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import Geometry, notch_layout
from ..imaging import to_gray
from ..units import MM
from .options import DetectorOptions
from .overlay import draw_overlay, overlay_with_crop
from .pipeline import run_at_scale
from .result import STATUSES, Detection, detections_table, empty_detection
from .segment import downsample, fill_holes, largest_region, segment
from .view import DiameterScale, view_orientation
from .width import measure_diameter, rough_tube_radius

__all__ = ["STATUSES", "Detection", "DetectorOptions", "detect_notches", "detections_table", "draw_overlay",
           "overlay_with_crop"]


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
        The experiment's ``mirror`` flag (a reflected view, geometry.md).
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
    lay = notch_layout(geom)
    m = lay.n_points
    gray = to_gray(image)
    H, W = gray.shape
    if camera is not None:
        camera.check_image(gray)
        if not camera.has_plane:
            raise ValueError("the camera model has no plane pose: calibrate with --plane-image")
        px_per_m, sgn = view_orientation(camera, (H, W), mirror)
        f = max(1, int(round(opts.lowres_mm * MM * px_per_m)))
    else:
        f = max(1, int(round(max(H, W) / opts.lowres_long_side_px)))
        sgn = view_orientation(DiameterScale(1.0, (W, H)), (H, W), mirror)[1]
    if H // f < 16 or W // f < 16:
        raise ValueError(f"image too small: {W}x{H} px")
    small = downsample(gray, f)
    seg = segment(small, min_snr=opts.min_snr, noise_scale=f)
    if seg.mask is None:
        return empty_detection(m, "no_manipulator", seg.message)
    region, box = largest_region(seg.mask)
    if camera is None:
        return _uncalibrated(gray, seg, region, box, small.shape, geom, opts, f=f, sgn=sgn, base=base)
    low_m = f / px_per_m
    R, w, d = geom.outer_radius, geom.slot_width, geom.slot_depth
    exp_area = (2 * R * (geom.tip_z - geom.base_edge_z) - geom.n_joints * w * d) / low_m ** 2
    ratio = float(region.sum()) / exp_area
    if ratio < opts.area_range[0] or region.mean() > 0.95:
        return empty_detection(m, "no_manipulator", f"no manipulator found: the largest region is {ratio:.2f} x "
                                                    "the tube's silhouette area (wrong geometry or camera file?)")
    det, _ = run_at_scale(gray, seg, region, box, small.shape, camera, geom, opts, f=f, px_per_m=px_per_m,
                          sgn=sgn, base=base, extra={"scale_mm_per_px": 1.0 / (px_per_m * MM), "scale_sigma": 0.0})
    return det


def _stations(ref, n_per_edge):
    """Points on the straight outer edge next to every ok corner, with the unit normal into the tube (S, 4)."""
    sp = ref["specs"]
    K = len(sp.C)
    rows = []
    for k in np.nonzero(ref["ok"])[0]:
        for e, (D, L, face) in enumerate(((-sp.Din[k], sp.Lin[k], sp.face[k]), (sp.Dout[k], sp.Lout[k],
                                                                                 sp.face[K + k]))):
            if face or not np.isfinite(L) or L < 8:
                continue
            trav = sp.Din[k] if e == 0 else sp.Dout[k]
            inward = -ref["sgn"] * np.array([trav[1], -trav[0]])
            for s in np.linspace(0.3, 0.7, n_per_edge) * L:
                P = sp.C[k] + s * D
                rows.append([P[0], P[1], inward[0], inward[1]])
    return np.array(rows).reshape(-1, 4)


def _uncalibrated(gray, seg, region, box, small_shape, geom, opts, *, f, sgn, base):
    """The scale from the tube's diameter: a rough width, a first detection, the measured width, the final one."""
    m = geom.n_points
    H, W = gray.shape
    R = geom.outer_radius
    R_lo = rough_tube_radius(fill_holes(region), max_close_px=int(opts.uncal_close_frac * max(small_shape)))
    if not np.isfinite(R_lo):
        return empty_detection(m, "no_manipulator", "no tube found: no band of constant width in the silhouette")
    px_per_m = R_lo * f / R
    kw = dict(f=f, sgn=sgn, base=base)
    det, ref = run_at_scale(gray, seg, region, box, small_shape, DiameterScale(1 / px_per_m, (W, H)), geom, opts,
                            px_per_m=px_per_m, stations=True, **kw)
    if ref is None or not ref["ok"].any():
        return det
    ref["sgn"] = sgn
    st = _stations(ref, opts.width_stations)
    widths = measure_diameter(ref["img"], ref["off"], st, 2 * R * px_per_m, seg.contrast, ref["blur"]) \
        if len(st) else np.zeros(0)
    widths = widths[np.isfinite(widths)]
    if len(widths) >= 3:
        med = float(np.median(widths))
        mad = 1.4826 * float(np.median(np.abs(widths - med)))
        widths = widths[np.abs(widths - med) <= max(3 * mad, 0.5)]
    if len(widths) < 3:
        return empty_detection(m, "partial", "the tube's width could not be measured (no calibration): fewer "
                                             "than 3 profiles across straight links", det.contour_px)
    wpx = float(np.mean(widths))
    sw = float(np.std(widths, ddof=1) / math.sqrt(len(widths)))
    mm_px = 2 * R / MM / wpx
    px_per_m = wpx / (2 * R)
    text = (f"no calibration: fronto-parallel view assumed; scale {mm_px:.6f} mm/px from the tube's outer "
            f"diameter {2 * R / MM:.3f} mm (geometry) measured as {wpx:.2f} ± {sw:.2f} px over {len(widths)} "
            "profiles; plane frame = image axes (x right, y up); a view tilted by a degrees shrinks one "
            "direction by cos a, and the diameter's tolerance scales every length")
    extra = {"scale_mm_per_px": mm_px, "scale_sigma": mm_px * sw / wpx, "assumption": text}
    det, _ = run_at_scale(gray, seg, region, box, small_shape, DiameterScale(1 / px_per_m, (W, H)), geom, opts,
                          px_per_m=px_per_m, extra=extra, **kw)
    return det
