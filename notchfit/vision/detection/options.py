"""Every tolerance of the notch-corner detector, in one frozen dataclass."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

__all__ = ["DetectorOptions"]


@dataclass(frozen=True)
class DetectorOptions:
    """Tolerances of :func:`notchfit.vision.detection.detect_notches` (defaults are the tested ones).

    Attributes
    ----------
    tone_gamma : float
        The images' tone curve: the sub-pixel edges are measured in linear
        light, ``(v / full) ** tone_gamma`` (camera JPEGs: about 2.2, the sRGB
        curve; 1: linear images, as the renders). A 50 % crossing in
        tone-mapped values is not the edge: with 2 px of blur and gamma 2.2 the
        corners are 0.008 mm rms off at 100 px/mm. The silhouette, the slots and
        their numbers are found on the file's values, whose noise is about even
        across the levels.
    work_radius_px, work_slot_px : float
        The downsampled copy used to segment and parse is chosen from the
        tube's size in pixels, not from the file's: the block-averaging factor
        is the largest that leaves the tube's radius at least about
        ``work_radius_px`` and the narrowest slot at least about
        ``work_slot_px`` pixels (rounded; 1 at most: full resolution). A 2 MP
        phone photo of a large printed tube is then worked on as coarsely as
        a 16 MP photograph of a thin wrist.
    lowres_long_side_px : int
        Long side of the downsampled copy when there is no calibration (the
        scale is not known before the tube is found) [px].
    min_snr : float
        Smallest object contrast, in units of the background noise.
    segment_level : float
        Threshold of the downsampled copy between the background (0) and the
        object level (1).
    area_range : (float, float)
        Accepted silhouette area relative to the geometry's tube + mount
        (calibrated images with the default mount only; a holder of another
        size makes the check pass by construction).
    close_slot_factor : float
        Radius of the disk that bridges slot mouths, in slot widths.
    slot_area_range : (float, float)
        Accepted area of one bridged slot, relative to ``w d``.
    sliver_area_px : float
        Smallest smaller gap kept as a sliver of a slot's mouth seen from the
        side [working px², where the narrowest slot is about ``work_slot_px``
        wide]: a weak candidate that is numbered only where the slot-sized
        gaps' numbers all stand; smaller gaps are the outline's pixel noise.
    holder_width_factor : float
        The holder is the part of the silhouette that a disk of radius
        ``holder_width_factor * R`` fits into (an opening): the tube (``2R``
        wide, slots bridged) never holds it.
    min_tube_run_R : float
        Runs of the outline shorter than this many ``R`` between holder parts
        belong to the holder (its rounded corners).
    min_base_run_R : float
        Holder runs of the outline shorter than this many ``R`` are thick
        spots of the tube (where it meets a holder too slim to be found).
    corner_turn_deg : float
        Turn of the bridged outline that makes a base or tip corner [deg].
    pair_tol : float
        Relative tolerance of the ``2R`` spacing used to pair base and tip corners.
    base_edge_tol : float
        The tube-holder corners are the base points (1, 2) only where the
        base edge is: their distance to the first slot on link 0 must match
        the geometry within this many slot widths.
    link_rel_tol, link_abs_w : float
        Rigid-link check: the distance between two ok corners of one link
        must match the geometry within ``link_rel_tol`` of it or
        ``link_abs_w`` slot widths, whichever is larger (a tube as built
        differs from its drawing by a few %; a slot numbered one off or a
        holder corner taken for a base point is off by a link).
    chain_rel_tol, chain_abs_w, chain_abs_px, chain_play : float
        Numbering by the rigid-link chain (:mod:`~notchfit.vision.detection.chain`,
        on the working copy): two corners on one link agree when their
        distance matches the drawing within ``chain_rel_tol`` of it or
        ``chain_abs_w`` narrowest slot widths or ``chain_abs_px`` working
        pixels, whichever is largest; every joint between two corners adds
        ``chain_play`` times what its bend can change the distance by
        (:func:`~notchfit.vision.detection.chain.joint_play`).
    scale_tol : float
        Relative tolerance of the measured base and tip widths (``2R``) in mm;
        beyond it the camera file is taken to be wrong.
    max_shift_px : float
        A corner that moves further than this during refinement is ambiguous
        [px]; multiplied by ``factor / 2`` like the profile lengths.
    max_sigma_px : float
        A corner whose standard uncertainty exceeds this is ambiguous [px].
    colour_close_px : int
        The colour silhouette is closed by a disk of this radius [working
        px] (gaps of a pixel or two where a highlight mirrors the card).
    local_bg_R : float
        Radius of the disk of the local background (the silhouette variant
        that leaves out soft shadows, :func:`.segment.local_segmentation`)
        [tube radii]: wider than the tube's half-width, so the tube drops
        out of the background, and narrower than a soft shadow's penumbra.
    variant_agree_w : float
        A corner found ``ok`` on two silhouette variants (threshold, streaks
        filled, colour) is kept only where they put it within this fraction
        of the narrowest slot's width; else it is ambiguous (two variants gave
        its number to different corners; the nearest other corner is a slot
        width away).
    width_tol : float
        Corners found on the colour silhouette: the tube's width beside a
        slot corner, across its outer edge, must be ``2R`` within this
        relative tolerance (a corner on an edge inside the tube finds it
        narrower).
    min_edge_points : int
        Fewest valid edge crossings per edge line.
    profile_step_px : float
        Sample spacing along a profile [px].
    stage1_half_px, stage1_face_px : float
        Half length of the first pass's profiles across outer edges and
        across slot faces (whose first position is the least certain) [px],
        for a downsampling factor of 2 or less; multiplied by ``factor / 2``
        above it (the first corner estimates are as coarse as the copy).
    outer_reach_R : float
        How far outside the silhouette's outer edges the refinement looks
        for the tube's end before its first pass [R] (a polished limb that
        mirrors the backdrop, or a shaded one, is left out of the silhouette;
        :func:`.subpixel.outer_offsets`); 0: not at all.
    iterations : int
        Refinement passes after the first.
    sigma_inflation : float
        Factor on the line-fit uncertainty: crossings 1 px apart share pixels
        (bilinear sampling) and blur, so the residual-based σ is too small;
        1.45 makes ``rms(|error| / (√2 σ)) = 1.0`` over rendered images
        (``benchmarks/bench_detection.py``).
    width_stations : int
        Profiles across the tube per straight link edge when the scale comes
        from the tube's diameter (no calibration).
    rescale_tol : float
        Without a calibration: when the measured scale is within this
        relative distance of the rough one, the corners found at the rough
        scale are mapped again instead of being searched for again.
    rough_slot_area_range : (float, float)
        Without a calibration: accepted slot area relative to ``w d`` at the
        scale a candidate band implies (narrower than ``slot_area_range``:
        a streak that splits the tube makes half-width bands whose slots
        look four times too big).
    uncal_close_frac : float
        Without a calibration: the largest closing tried to bridge the
        slots for the first scale estimate, as a fraction of the downsampled
        image's long side.
    streak_fill_R : float
        Background lines across the tube thinner than this many ``R`` are
        filled when a bright streak splits the silhouette (a retry).
    holder_backdrop_tol : float
        A base corner is measured only where its holder's face stands against
        the backdrop its tube's limb does: the levels beyond the two edges
        must agree within this fraction of the holder edge's own step (a
        holder's end face seen from the side lies between its rim and the
        backdrop and hides the base edge, :func:`.subpixel.holder_backdrops`);
        0: not checked.
    outer_step_k : float
        After the refinement, an outer edge whose mean profile steps once
        more outside it (a polished limb's mirror strip, the refined edge its
        inner ramp) is moved to that outer step when both the step's foot and
        its level stand out of the backdrop by this many standard errors
        (:func:`.subpixel.outer_steps`); 0: not looked for.
    """

    tone_gamma: float = 1.0
    work_radius_px: float = 13.0
    work_slot_px: float = 6.5
    lowres_long_side_px: int = 750
    min_snr: float = 4.0
    segment_level: float = 0.35
    area_range: tuple = (0.2, 3.0)
    close_slot_factor: float = 1.25
    slot_area_range: tuple = (0.15, 4.0)
    sliver_area_px: float = 3.0
    holder_width_factor: float = 1.15
    min_tube_run_R: float = 2.0
    min_base_run_R: float = 2.0
    corner_turn_deg: float = 50.0
    pair_tol: float = 0.3
    base_edge_tol: float = 0.25
    link_rel_tol: float = 0.15
    link_abs_w: float = 0.5
    chain_rel_tol: float = 0.08
    chain_abs_w: float = 0.25
    chain_abs_px: float = 2.5
    chain_play: float = 1.0
    scale_tol: float = 0.05
    max_shift_px: float = 10.0
    max_sigma_px: float = 0.3
    width_tol: float = 0.06
    variant_agree_w: float = 0.25
    colour_close_px: int = 1
    local_bg_R: float = 1.2
    min_edge_points: int = 5
    profile_step_px: float = 0.5
    stage1_half_px: float = 7.0
    stage1_face_px: float = 12.0
    outer_reach_R: float = 0.4
    iterations: int = 1
    sigma_inflation: float = 1.45
    width_stations: int = 5
    rescale_tol: float = 0.05
    rough_slot_area_range: tuple = (0.3, 2.5)
    uncal_close_frac: float = 0.1
    streak_fill_R: float = 0.6
    holder_backdrop_tol: float = 0.25
    outer_step_k: float = 6.0
    pin_agree_w: float = 1.0

    def replace(self, **changes) -> "DetectorOptions":
        """A copy with some options changed."""
        return dataclasses.replace(self, **changes)
