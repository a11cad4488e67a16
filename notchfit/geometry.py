"""Manipulator geometry as data (docs/geometry.md).

A :class:`Geometry` is a frozen dataclass in SI units; its defaults are the
manipulator of the seed paper (the values of ``datasets/geometry/default.toml``).
Geometry files carry their units in their keys (``p_mm``, ``cable_E_Pa``):
:func:`geometry_from_dict` turns such a mapping into a :class:`Geometry`, and
:func:`notchfit.io.load_geometry` reads the file.

The notch-point layout (which link each of the ``4 + 2 * n_slots`` points is
attached to, and its link-local coordinates) is derived from the geometry by
:func:`notch_layout`; docs/geometry.md fixes the numbering.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .units import MM

__all__ = [
    "Geometry",
    "NotchLayout",
    "alternating_sides",
    "default_geometry",
    "geometry_from_dict",
    "notch_layout",
]

# geometry-file key -> dataclass field
_LENGTH_KEYS = {
    "p_mm": "p",
    "r_x_mm": "r_x",
    "r_z_mm": "r_z",
    "outer_radius_mm": "outer_radius",
    "slot_width_mm": "slot_width",
    "slot_depth_mm": "slot_depth",
    "cable_radius_mm": "cable_radius",
    "channel_radius_mm": "channel_radius",
    "mount_half_width_mm": "mount_half_width",
}
_SIGNED_LENGTH_KEYS = {
    "base_edge_z_mm": "base_edge_z",
    "mount_bottom_z_mm": "mount_bottom_z",
}
_POSITIVE_SI_KEYS = {"cable_E_Pa": "cable_E", "cable_A_m2": "cable_A", "cable_L0_m": "cable_L0"}


@dataclass(frozen=True)
class Geometry:
    """A planar notched-tube manipulator (SI units: m, Pa, m²).

    Attributes
    ----------
    n_joints : int
        Number of flexure joints ``n`` (27 in the paper, Sec. II-A).
    p : float
        Link spacing [m] (1.21 mm).
    r_x, r_z : float
        Cable offset from the backbone and channel half-length [m] (Sec. II-B).
    outer_radius : float
        Tube outer radius ``R`` [m].
    slot_width, slot_depth : float
        Slot width along z and depth along x from the outer edge [m].
    slot_sides : tuple of int, length n_joints
        Side each joint's slot opens to: -1 left (-x), +1 right (+x).
    base_edge_z : float
        z of the base edge on link 0 [m].
    mount_half_width, mount_bottom_z : float
        The mount below the base edge (silhouette only) [m].
    cable_radius, channel_radius : float
        Cable and channel radii [m] (Fig. 4).
    cable_E, cable_A, cable_L0 : float
        Cable Young's modulus [Pa], cross-section [m²], free length [m]
        (Sec. III-B).
    name : str
        A label.
    """

    n_joints: int = 27
    p: float = 1.21e-3
    r_x: float = 2.5e-3
    r_z: float = 0.2e-3
    outer_radius: float = 3.0e-3
    slot_width: float = 0.42e-3
    slot_depth: float = 2.4e-3
    slot_sides: tuple[int, ...] = ()
    base_edge_z: float = -1.0e-3
    mount_half_width: float = 6.0e-3
    mount_bottom_z: float = -8.0e-3
    cable_radius: float = 0.127e-3
    channel_radius: float = 0.25e-3
    cable_E: float = 1.8e11
    cable_A: float = 5.1e-8
    cable_L0: float = 0.22
    name: str = "moses2015"

    def __post_init__(self) -> None:
        n = self.n_joints
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
            raise ValueError(f"n_joints must be a positive integer, got {n!r}")
        if not self.slot_sides:
            object.__setattr__(self, "slot_sides", alternating_sides(n))
        sides = tuple(int(s) for s in self.slot_sides)
        if len(sides) != n:
            raise ValueError(f"slot_sides must have n_joints={n} entries, got {len(sides)}")
        if any(s not in (-1, 1) for s in sides):
            raise ValueError(f"slot_sides entries must be -1 (left) or +1 (right), got {sides}")
        object.__setattr__(self, "slot_sides", sides)
        for f in ("p", "r_x", "r_z", "outer_radius", "slot_width", "slot_depth",
                  "cable_radius", "channel_radius", "cable_E", "cable_A", "cable_L0",
                  "mount_half_width"):
            v = getattr(self, f)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"geometry field {f!r} must be a positive finite number, got {v!r}")
        for f in ("base_edge_z", "mount_bottom_z"):
            v = getattr(self, f)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f"geometry field {f!r} must be a finite number, got {v!r}")
        if self.slot_depth >= 2 * self.outer_radius:
            raise ValueError("slot_depth must be smaller than the tube diameter 2*outer_radius")
        if self.slot_width >= self.p:
            raise ValueError("slot_width must be smaller than the link spacing p")
        if self.channel_radius < self.cable_radius:
            raise ValueError("channel_radius must be at least cable_radius")
        if self.base_edge_z >= 0 or self.mount_bottom_z >= self.base_edge_z:
            raise ValueError("need mount_bottom_z < base_edge_z < 0")

    @property
    def tip_z(self) -> float:
        """z of the tip face in the straight configuration [m] (``n p``)."""
        return self.n_joints * self.p

    @property
    def n_points(self) -> int:
        """Number of notch points: 4 + 2 per slot (58 for the default)."""
        return 4 + 2 * self.n_joints

    @property
    def cable_stiffness(self) -> float:
        """Linear cable stiffness ``k_c = E A / L0`` [N/m] (Sec. III-B)."""
        return self.cable_E * self.cable_A / self.cable_L0

    @property
    def closure_angle(self) -> float:
        """Joint angle at which a slot closes at the outer edge [rad].

        The joint axis is on the backbone (x = 0); the two faces of a slot of
        width ``w`` meet at the outer edge ``x = ±R`` when
        ``R tan(θ/2) = w/2``, i.e. ``θ = 2 atan(w / 2R)`` (0.1397 rad for the
        default: docs/geometry.md's "closes at about 0.14 rad").
        """
        return 2.0 * math.atan(self.slot_width / (2.0 * self.outer_radius))

    def replace(self, **changes) -> "Geometry":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def alternating_sides(n: int) -> tuple[int, ...]:
    """Slot sides of docs/geometry.md: joint j odd opens left (-1), even right (+1)."""
    return tuple(-1 if j % 2 == 1 else 1 for j in range(1, n + 1))


def geometry_from_dict(data: dict, origin: str = "<dict>", *, line_of=None) -> Geometry:
    """Build a :class:`Geometry` from a geometry-file mapping (unit-suffixed keys, mm lengths).

    Parameters
    ----------
    data : dict
        Keys of docs/geometry.md: ``n_joints``, ``p_mm``, ..., ``cable_L0_m``,
        optional ``name`` and ``slot_sides`` (``"alternating"`` or a list of -1/+1).
    origin : str
        Where the mapping came from, at the start of every message.
    line_of : callable, optional
        ``line_of(key) -> int or None``: the line a key is written on, so a
        message about one key names its line (file readers pass it).

    Returns
    -------
    Geometry

    Raises
    ------
    ValueError
        ``"<origin>: [line <n>: ]<problem>"`` for a missing, unknown,
        non-numeric or non-positive field, or an inconsistent geometry.
    """
    def fail(problem: str, key: str | None = None) -> ValueError:
        line = line_of(key) if line_of is not None and key is not None else None
        return ValueError(f"{origin}: line {line}: {problem}" if line is not None else f"{origin}: {problem}")

    required = ["n_joints", *_LENGTH_KEYS, *_SIGNED_LENGTH_KEYS, *_POSITIVE_SI_KEYS]
    known = set(required) | {"name", "slot_sides"}
    missing = [k for k in required if k not in data]
    if missing:
        raise fail(f"missing geometry field(s) {', '.join(missing)}")
    unknown = sorted(set(data) - known)
    if unknown:
        raise fail(f"unknown geometry field(s) {', '.join(unknown)}", unknown[0])
    kw: dict = {"name": str(data.get("name", Path(origin).stem))}
    n = data["n_joints"]
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise fail(f"n_joints must be a positive integer, got {n!r}", "n_joints")
    kw["n_joints"] = n

    def number(key, positive):
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise fail(f"{key} must be a finite number, got {v!r}", key)
        if positive and v <= 0:
            raise fail(f"{key} must be positive, got {float(v)}", key)
        return float(v)

    for key, field in _LENGTH_KEYS.items():
        kw[field] = number(key, True) * MM
    for key, field in _SIGNED_LENGTH_KEYS.items():
        kw[field] = number(key, False) * MM
    for key, field in _POSITIVE_SI_KEYS.items():
        kw[field] = number(key, True)
    sides = data.get("slot_sides", "alternating")
    if sides == "alternating":
        kw["slot_sides"] = alternating_sides(n)
    elif isinstance(sides, list):
        kw["slot_sides"] = tuple(sides)
    else:
        raise fail(f"slot_sides must be \"alternating\" or a list of -1/+1, got {sides!r}", "slot_sides")
    try:
        return Geometry(**kw)
    except ValueError as exc:
        raise fail(str(exc)) from None


@functools.lru_cache(maxsize=1)
def default_geometry() -> Geometry:
    """The seed paper's manipulator: the :class:`Geometry` defaults.

    Equal, field by field, to ``notchfit.io.load_geometry("default")``
    (``datasets/geometry/default.toml``; a test checks it).
    """
    return Geometry()


@dataclass(frozen=True)
class NotchLayout:
    """Where the numbered notch points sit (docs/geometry.md, 'The 58 notch points').

    Attributes
    ----------
    link : ndarray of int, shape (m,)
        Link each point is attached to (0 = base, n = end effector).
    local : ndarray, shape (m, 2)
        Point in its link's frame [m]: (x, z) relative to the link's proximal
        joint (the base origin for link 0), in the straight configuration.
    straight : ndarray, shape (m, 2)
        The point in the manipulator frame at θ = 0 [m].
    kind : tuple of str, length m
        ``base``, ``tip``, ``proximal`` or ``distal``.
    joint : ndarray of int, shape (m,)
        The slot's joint for slot corners, 0 for base and tip corners.
    side : ndarray of int, shape (m,)
        -1 left, +1 right.
    """

    link: np.ndarray
    local: np.ndarray
    straight: np.ndarray
    kind: tuple
    joint: np.ndarray
    side: np.ndarray

    @property
    def n_points(self) -> int:
        return len(self.link)


@functools.lru_cache(maxsize=32)
def notch_layout(geom: Geometry) -> NotchLayout:
    """The notch points of ``geom`` numbered as docs/geometry.md says.

    1 base-left, 2 base-right, then right-side slot corners by increasing z
    (proximal, distal), tip-right, tip-left, then left-side slot corners by
    decreasing z (distal, proximal). Returned arrays are read-only.
    """
    n, p, R, w = geom.n_joints, geom.p, geom.outer_radius, geom.slot_width
    rows = []  # (link, x, z_straight, kind, joint, side)
    rows.append((0, -R, geom.base_edge_z, "base", 0, -1))
    rows.append((0, +R, geom.base_edge_z, "base", 0, +1))
    for j in range(1, n + 1):
        if geom.slot_sides[j - 1] == +1:
            zj = (j - 1) * p
            rows.append((j - 1, R, zj - w / 2, "proximal", j, +1))
            rows.append((j, R, zj + w / 2, "distal", j, +1))
    rows.append((n, +R, n * p, "tip", 0, +1))
    rows.append((n, -R, n * p, "tip", 0, -1))
    for j in range(n, 0, -1):
        if geom.slot_sides[j - 1] == -1:
            zj = (j - 1) * p
            rows.append((j, -R, zj + w / 2, "distal", j, -1))
            rows.append((j - 1, -R, zj - w / 2, "proximal", j, -1))
    link = np.array([r[0] for r in rows], dtype=np.intp)
    straight = np.array([[r[1], r[2]] for r in rows], dtype=float)
    origin_z = np.where(link > 0, (link - 1) * p, 0.0)
    local = straight - np.stack([np.zeros_like(origin_z), origin_z], axis=1)
    out = NotchLayout(
        link=link,
        local=local,
        straight=straight,
        kind=tuple(r[3] for r in rows),
        joint=np.array([r[4] for r in rows], dtype=np.intp),
        side=np.array([r[5] for r in rows], dtype=np.intp),
    )
    for arr in (out.link, out.local, out.straight, out.joint, out.side):
        arr.flags.writeable = False
    return out
