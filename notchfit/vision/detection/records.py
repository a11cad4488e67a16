"""The records the detector's stages hand each other for one image at one scale (:mod:`.pipeline` runs
them in order): what every stage knows (:class:`Setup`), a cropped silhouette (:class:`Crop`), its parse
(:class:`Parsed`), the corners located on the working copy (:class:`Located`), their refinement
(:class:`Refinement`), one silhouette variant located (:class:`Variant`) and one run's outcome
(:class:`Refined`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plane import PlaneInput
from .refine import CornerSpecs
from .result import Detection

__all__ = ["Crop", "Located", "Parsed", "Refined", "Refinement", "Setup", "Variant"]


@dataclass(frozen=True)
class Setup:
    """What every stage of one detection at one scale knows: the camera, the tube, the options, the scale.

    Attributes
    ----------
    camera : CameraModel or DiameterScale
        Maps pixels to the plane.
    geom : Geometry
    opts : DetectorOptions
    f : int
        Block-averaging factor of the working copy.
    px_per_m : float
        Image scale in the plane [px/m].
    sgn : float
        Orientation sign of the outline (object on the left of the traversal when +1).
    base : str or None
        The image side the base is known to point to (None: found).
    """

    camera: object
    geom: object
    opts: object
    f: int
    px_per_m: float
    sgn: float
    base: str | None = None

    @property
    def low_m(self) -> float:
        """Size of one working-copy pixel in the plane [m]."""
        return self.f / self.px_per_m


@dataclass(frozen=True)
class Crop:
    """One cropped working-copy silhouette and how its slots are bridged (:func:`.locate.locate` hands it to
    ``locate._parse``).

    Attributes
    ----------
    roi : ndarray (h, w) bool
        The silhouette's box on the working copy.
    offset : (int, int)
        Its position on the working copy [low-res px].
    shape : (int, int)
        The working copy's shape (rows, cols).
    r_close : int
        Radius of the closing that bridges the slots [low-res px].
    slot_area : float
        A slot's expected area [low-res px²].
    holders : (ndarray, ndarray)
        The grown and strict holder masks on ``roi``.
    gray : ndarray (h, w) or None
        The working copy's intensities on ``roi`` (which side of a hole is its mouth).
    dark : bool
        The object is darker than the background.
    """

    roi: np.ndarray
    offset: tuple
    shape: tuple
    r_close: int
    slot_area: float
    holders: tuple
    gray: np.ndarray | None = None
    dark: bool = True


@dataclass(frozen=True)
class Parsed:
    """One cropped silhouette parsed (``locate._parse``): its bridged outline, base end, slot numbers.

    Attributes
    ----------
    ol : Outline
    be : BaseEnd
    num : Numbering
    mouths : dict
        Slot label -> (first, last, bridged) outline indices.
    raw : (int or None, int or None) or None
        The base corners on the unbridged outline.
    full : callable
        Low-res crop coordinates -> full-resolution pixels.
    contour_px : ndarray (N, 2)
        The bridged outline [px].
    rawc : dict
        Slot label -> its outer corners on the unbridged outline.
    """

    ol: object
    be: object
    num: object
    mouths: dict
    raw: tuple | None
    full: object
    contour_px: np.ndarray
    rawc: dict

    @property
    def n_found(self) -> int:
        """Slots numbered, and 1 for the tip."""
        return len(self.num.right) + len(self.num.left) + (self.num.tip is not None)


@dataclass(frozen=True)
class Located:
    """What stages 2-4 hand to the refinement (:func:`.locate.locate`).

    Attributes
    ----------
    specs : list of CornerSpec
        The corners to refine, with their first estimates on the working copy.
    contour_px : ndarray (N, 2)
        The bridged outline [px] (overlays).
    status : list of str (m,)
    messages : list of str
    side : str
        The image side the base points to.
    full : callable
        Low-res crop coordinates -> full-resolution pixels.
    tube_px : ndarray (T, 2)
        The tube's part of the outline [px] (diameter stations).
    confirm_width : bool
        Slots numbered without the tip (``Numbering.tipless``): each corner's link must be 2R wide.
    """

    specs: list
    contour_px: np.ndarray
    status: list
    messages: list
    side: str
    full: object
    tube_px: np.ndarray
    confirm_width: bool = False

    @property
    def points(self) -> set:
        """The point indices of the located corners."""
        return {s.point for s in self.specs}


@dataclass
class Refinement:
    """Stage 5's outcome for K corners (:func:`.subpixel.refine_corners`).

    Attributes
    ----------
    pidx : ndarray (K,) int
        Point index of each corner.
    C, Xi : ndarray (K, 2)
        Raw and ideal (undistorted) corners [px].
    cov : ndarray (K, 2, 2)
        Reported covariance of the ideal corners [px²] (before ``sigma_inflation``).
    ok : ndarray (K,) bool
    shift : ndarray (K,)
        How far each corner moved during refinement [px].
    blur : float
        Edge blur σ [px].
    sig_px : ndarray (K,)
        The fit's standard uncertainty (inflated) [px]: decides ``ambiguous``.
    specs : CornerSpecs
    img, off : the image region refined and its offset (u0, v0) [px]
    kf : float
        Profile length factor.
    plane_input : PlaneInput or None
        Set by :func:`.pipeline.refine_and_finish`.
    wide : ndarray (K,) bool or None
        Corners with an edge too wide for one step (:func:`.refine.wide_edges`): ambiguous.
    rim : ndarray (K,) bool or None
        Base corners withheld as a holder's rim seen from the side (:func:`.subpixel.holder_backdrops`):
        not ``ok``, though their limb edge is still the tube's.
    """

    pidx: np.ndarray
    C: np.ndarray
    Xi: np.ndarray
    cov: np.ndarray
    ok: np.ndarray
    shift: np.ndarray
    blur: float
    sig_px: np.ndarray
    specs: CornerSpecs
    img: np.ndarray
    off: np.ndarray
    kf: float
    plane_input: PlaneInput | None = None
    wide: np.ndarray | None = None
    rim: np.ndarray | None = None


@dataclass(frozen=True)
class Refined:
    """Stages 5-6's outcome for one run (:func:`.pipeline.refine_and_finish`, :func:`.pipeline.detect_at`).

    Attributes
    ----------
    detection : Detection
    refinement : Refinement or None
        The refined corners (None when nothing was located); its ``plane_input`` carries the corners the
        detection was mapped from (the merged ones where several silhouette variants were refined).
    """

    detection: Detection
    refinement: Refinement | None = None


@dataclass(frozen=True)
class Variant:
    """One silhouette variant located (:func:`.pipeline.locate_variants`).

    Attributes
    ----------
    name : str
        ``"threshold"``, ``"streaks"`` or ``"colour"`` (:data:`.pipeline.VARIANTS`).
    mask : ndarray (h, w) uint8
        Its working-copy silhouette.
    outcome : Located or Detection
        The corners located on it, or the Detection of a failure.
    """

    name: str
    mask: np.ndarray
    outcome: Located | Detection
