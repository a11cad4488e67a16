"""Section properties of a notched tube: what is left of the tube where a slot is cut.

A slot cut into a tube of outer radius ``R`` and inner radius ``r`` (``r = 0``
for a solid rod) from the side ``σ`` (``+1`` toward ``+x``) to the depth ``g``
(measured from the outer edge on the slot's side, along ``x``) removes the
material with ``σ x > R - g``. What remains is the annular segment beyond the
chord at distance ``d = g - R`` from the tube axis on the other side (``d < 0``
when the cut stops short of the axis, as on the seed tube; ``d > 0`` for the
deep one-sided cuts of asymmetric-notch wrists, where only a thin wall is left).

For a disc of radius ``ρ`` cut by a chord at distance ``d`` from its centre,
the segment beyond the chord (half-angle ``α = acos(d/ρ)``) has (Roark's
Formulas for Stress and Strain, 7th ed., Table A.1, circular segment):

* area ``A = ρ² (α - sin α cos α)``,
* first moment about the centre line ``Q = (2/3) ρ³ sin³α``,
* second moment about the centre line ``I_c = (ρ⁴/4) (α - sin α cos α + 2 sin³α cos α)``.

The annular segment is the outer segment minus the inner one (with
``d/r`` clipped to ``[-1, 1]``: a chord outside the lumen removes all of it or
none). Its centroid ``ȳ = Q/A`` is the neutral axis of bending in the ``x``-``z``
plane, offset from the tube axis away from the slot; its second moment about
the neutral axis is ``I = I_c - A ȳ²`` (parallel axes). These are the closed
forms of the asymmetric-notch wrist literature (York, Swaney, Gilbert &
Webster, "A wrist for needle-sized surgical robots", IEEE ICRA 2015, Eqs. 2–5,
written there with ``φ = 2α``).

A notch of height ``h`` that bends by ``θ`` as a circular arc of its neutral
axis (curvature ``κ = θ/h``) shortens a fibre at distance ``c`` from the
neutral axis, on the slot's side, by ``c θ``; the slot's faces meet at the outer
edge when ``(R + ȳ) θ = h``: the closure angle ``θ_c = h / (R + ȳ)``. The strain
of a fibre at ``c`` is ``ε = κ c = c θ / h``.

All functions broadcast over arrays (per-joint values) and take SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NotchSection", "closure_angle", "notch_section", "segment_moments", "tendon_moment_arm"]


def segment_moments(radius, d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Area and moments of the part of a disc beyond a chord (Roark, Table A.1).

    Parameters
    ----------
    radius : array_like [m]
        Disc radius ``ρ`` (>= 0; 0 gives zeros).
    d : array_like [m]
        Signed distance of the chord from the centre; the part kept is
        ``x > d``. ``d <= -ρ`` keeps the whole disc, ``d >= ρ`` nothing.

    Returns
    -------
    area : ndarray [m²]
    first_moment : ndarray [m³]
        ``∫ x dA`` about the centre line (parallel to the chord).
    second_moment : ndarray [m⁴]
        ``∫ x² dA`` about the centre line.
    """
    rho = np.asarray(radius, dtype=float)
    d = np.asarray(d, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(rho > 0, np.clip(d / np.where(rho > 0, rho, 1.0), -1.0, 1.0), 1.0)
    alpha = np.arccos(c)
    s = np.sin(alpha)
    area = rho**2 * (alpha - s * c)
    first = (2.0 / 3.0) * rho**3 * s**3
    second = 0.25 * rho**4 * (alpha - s * c + 2.0 * s**3 * c)
    return area, first, second


@dataclass(frozen=True)
class NotchSection:
    """The section left by a slot (arrays broadcast over joints).

    Attributes
    ----------
    area : ndarray [m²]
    neutral_offset : ndarray [m]
        ``ȳ``: distance of the neutral axis from the tube axis, away from the
        slot (0 for an uncut tube; negative never occurs for ``g >= 0``).
    second_moment : ndarray [m⁴]
        ``I`` about the neutral axis, for bending in the ``x``-``z`` plane.
    slot_fibre : ndarray [m]
        Distance from the neutral axis to the outer edge on the slot's side,
        ``R + ȳ`` (where the slot's faces meet first).
    back_fibre : ndarray [m]
        Distance from the neutral axis to the outer edge of the backbone,
        ``R - ȳ`` (the most strained fibre of the remaining wall in tension
        when the joint bends toward the slot).
    cut_fibre : ndarray [m]
        Distance from the neutral axis to the cut face, ``ȳ - d``.
    """

    area: np.ndarray
    neutral_offset: np.ndarray
    second_moment: np.ndarray
    slot_fibre: np.ndarray
    back_fibre: np.ndarray
    cut_fibre: np.ndarray


def notch_section(outer_radius, inner_radius, depth) -> NotchSection:
    """Section properties of a tube cut by a slot of depth ``depth`` (module docstring).

    Parameters
    ----------
    outer_radius : array_like [m]
        ``R`` > 0.
    inner_radius : array_like [m]
        ``r``, ``0 <= r < R`` (0: a solid rod).
    depth : array_like [m]
        Cut depth ``g`` from the outer edge on the slot's side, ``0 <= g < 2R``
        (``g = 0``: no cut).

    Returns
    -------
    NotchSection

    Raises
    ------
    ValueError
        For radii or depths outside those ranges.
    """
    R = np.asarray(outer_radius, dtype=float)
    r = np.asarray(inner_radius, dtype=float)
    g = np.asarray(depth, dtype=float)
    if not (np.all(np.isfinite(R)) and np.all(R > 0)):
        raise ValueError(f"outer radius must be > 0, got {R}")
    if not (np.all(np.isfinite(r)) and np.all(r >= 0) and np.all(r < R)):
        raise ValueError(f"inner radius must be in [0, outer radius), got {r}")
    if not (np.all(np.isfinite(g)) and np.all(g >= 0) and np.all(g < 2 * R)):
        raise ValueError(f"slot depth must be in [0, 2 * outer radius), got {g}")
    d = g - R
    Ao, Qo, Io = segment_moments(R, d)
    Ai, Qi, Ii = segment_moments(r, d)
    A = Ao - Ai
    y = (Qo - Qi) / A
    I = (Io - Ii) - A * y**2
    return NotchSection(area=A, neutral_offset=y, second_moment=I, slot_fibre=R + y,
                        back_fibre=R - y, cut_fibre=y - d)


def closure_angle(height, section: NotchSection) -> np.ndarray:
    """Joint angle at which a slot of height ``h`` closes, ``h / (R + ȳ)`` [rad].

    The notch bends as a circular arc of its neutral axis; the outer edge on
    the slot's side, ``R + ȳ`` from the neutral axis, shortens by ``(R + ȳ) θ``
    and the gap ``h`` is gone when that equals ``h`` (module docstring). With
    ``ȳ = 0`` it is the small-angle form of the seed tube's ``2 atan(h / 2R)``.

    Parameters
    ----------
    height : array_like [m]
        Slot height ``h`` along the tube (the geometry's slot width).
    section : NotchSection
    """
    return np.asarray(height, dtype=float) / section.slot_fibre


def tendon_moment_arm(section: NotchSection, tendon_offset) -> np.ndarray:
    """Moment arm of a tendon about the joint's neutral axis [m].

    Parameters
    ----------
    section : NotchSection
    tendon_offset : array_like [m]
        Distance of the tendon from the tube axis toward the slot's side
        (for a tendon along the inner wall on the slot's side, the inner
        radius, less the tendon's radius when its centre line is meant).

    Returns
    -------
    ndarray [m]
        ``offset + ȳ``: the tendon pulls on the slot's side of the neutral
        axis, bending the joint toward the slot.
    """
    return np.asarray(tendon_offset, dtype=float) + section.neutral_offset
