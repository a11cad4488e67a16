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

from .section import NotchSection, notch_section
from .section import closure_angle as section_closure_angle
from ..units import MM

__all__ = [
    "Geometry",
    "NotchLayout",
    "alternating_sides",
    "default_geometry",
    "geometry_from_dict",
    "notch_layout",
]

# geometry-file key -> dataclass field. A per-joint key takes one number (every
# joint alike) or a list: n_joints values, or n_joints - 1 for the spacing.
_PER_JOINT_KEYS = {"slot_width_mm": "slot_width", "slot_depth_mm": "slot_depth"}
_LENGTH_KEYS = {
    "outer_radius_mm": "outer_radius",
    "r_x_mm": "r_x",
    "r_z_mm": "r_z",
    "cable_radius_mm": "cable_radius",
    "channel_radius_mm": "channel_radius",
    "mount_half_width_mm": "mount_half_width",
    "slot_depth_tolerance_mm": "slot_depth_tolerance",
}
_SIGNED_LENGTH_KEYS = {
    "base_edge_z_mm": "base_edge_z",
    "mount_bottom_z_mm": "mount_bottom_z",
    "tip_face_z_mm": "tip_face_z",
}
_POSITIVE_SI_KEYS = {"cable_E_Pa": "cable_E", "cable_A_m2": "cable_A", "cable_L0_m": "cable_L0"}
_REQUIRED_KEYS = ("n_joints", "p_mm", "outer_radius_mm", "slot_width_mm", "slot_depth_mm", "base_edge_z_mm")
_OTHER_KEYS = ("name", "slot_sides", "inner_radius_mm", "rest_angle_rad", "backbone", "tendons", "tendon_path")

BACKBONES = ("axis", "section")
#: Plausibility bounds: a larger value is a typo or a unit error, not a tube.
MAX_JOINTS = 10_000
MAX_LENGTH = 1.0           # [m], any dimension of the tube, its channels and mount
MAX_CABLE_LENGTH = 100.0   # [m], the cable's free length
TENDON_PATHS = ("channel", "lumen")
_TENDON_SIDES = {"left": -1, "right": +1}
#: fields that a channel-routed tendon needs (Sec. II-B)
_CHANNEL_FIELDS = ("r_x", "r_z", "cable_radius", "channel_radius")


def _per_joint(value, n: int, what: str) -> float | tuple[float, ...]:
    """A per-joint value: a float (all alike) or a tuple of ``n`` floats."""
    if isinstance(value, (list, tuple, np.ndarray)):
        vals = tuple(float(v) for v in value)
        if len(vals) != n:
            raise ValueError(f"{what} must have {n} values (or be one number), got {len(vals)}")
        return vals
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a number or a list of numbers, got {value!r}")
    return float(value)


def _finite_positive(name: str, values, *, positive: bool = True) -> None:
    a = np.atleast_1d(np.asarray(values, dtype=float))
    if not np.all(np.isfinite(a)) or (positive and not np.all(a > 0)):
        raise ValueError(f"geometry field {name!r} must be {'positive ' if positive else ''}finite, got {values!r}")


@dataclass(frozen=True)
class Geometry:
    """A planar notched-tube manipulator (SI units: m, Pa, m²).

    The defaults are the seed paper's tube. Per-joint quantities (``p``,
    ``slot_width``, ``slot_depth``, ``rest_angle``) are one number for every
    joint alike or a tuple, base to tip; the array properties
    (:attr:`pitches`, :attr:`joint_z`, :attr:`slot_widths`, ...) give them per
    joint either way. docs/geometry.md describes the designs this expresses
    (the seed tube; one-sided asymmetric-notch wrists; tip-first or base-first
    depth gradients; pre-curved tubes).

    Attributes
    ----------
    n_joints : int
        Number of flexure joints ``n`` (27 in the paper, Sec. II-A).
    p : float or tuple of n_joints - 1 floats
        Joint-to-joint spacing [m] (1.21 mm, Sec. II-A); ``p = h + c`` where a
        design gives notch height ``h`` and uncut length ``c``.
    r_x, r_z : float or None
        Cable offset from the tube axis and channel half-length [m] (Sec. II-B);
        required for ``tendon_path = "channel"``.
    outer_radius : float
        Tube outer radius ``R`` [m].
    slot_width, slot_depth : float or tuple of n_joints floats
        Slot (notch) height ``h`` along z and cut depth ``g`` along x from the
        outer edge on the slot's side [m].
    slot_sides : tuple of int, length n_joints
        Side each joint's slot opens to: -1 left (-x), +1 right (+x).
    base_edge_z : float
        z of the base edge on link 0 [m] (< 0).
    mount_half_width, mount_bottom_z : float or None
        The rectangular mount below the base edge that the synthetic images
        draw [m]; None for a tube without one.
    cable_radius, channel_radius : float or None
        Cable and channel radii [m] (Fig. 4).
    cable_E, cable_A, cable_L0 : float or None
        Cable Young's modulus [Pa], cross-section [m²], free length [m]
        (Sec. III-B); None when not known (no cable stretch is modelled).
    name : str
        A label.
    inner_radius : float or None
        Tube inner radius [m] (0: a solid rod); needed for section properties.
    rest_angle : float or tuple of n_joints floats
        Joint angle with no load [rad] (a pre-curved tube), 0 by default.
    backbone : {"axis", "section"}
        ``"axis"``: joints bend about the tube axis (the seed paper).
        ``"section"``: joint ``j`` bends about the neutral axis of the section
        its slot leaves (:mod:`notchfit.physics.section`), at mid-slot height.
    tendons : tuple of str
        The tendons the tube has: ``("left", "right")`` or one of them; empty
        for a geometry that describes no tendon (written for detection alone:
        the detector needs the dimensions and the slots only). A geometry file
        without any tendon key (``tendons``, ``tendon_path``, the channel and
        cable radii) is such a geometry; what needs a tendon then says so.
    slot_depth_tolerance : float or None
        Standard deviation of a cut depth about the drawing's [m] (the cutting and
        measuring tolerance; ``slot_depth_tolerance_mm``); None: not given (``identify``
        then assumes its default of 15 µm).
    tendon_path : {"channel", "lumen"}
        ``"channel"``: in channels at ``±r_x`` (the seed tube); ``"lumen"``: free
        in the lumen along the inner wall on its side.
    tip_face_z : float or None
        z of the tip face [m]; None: one spacing after the last joint
        (``n p`` for a uniform spacing).
    """

    n_joints: int = 27
    p: float | tuple = 1.21e-3
    r_x: float | None = 2.5e-3
    r_z: float | None = 0.2e-3
    outer_radius: float = 3.0e-3
    slot_width: float | tuple = 0.42e-3
    slot_depth: float | tuple = 2.4e-3
    slot_sides: tuple[int, ...] = ()
    base_edge_z: float = -1.0e-3
    mount_half_width: float | None = 6.0e-3
    mount_bottom_z: float | None = -8.0e-3
    cable_radius: float | None = 0.127e-3
    channel_radius: float | None = 0.25e-3
    cable_E: float | None = 1.8e11
    cable_A: float | None = 5.1e-8
    cable_L0: float | None = 0.22
    name: str = "moses2015"
    inner_radius: float | None = None
    rest_angle: float | tuple = 0.0
    backbone: str = "axis"
    tendons: tuple[str, ...] = ("left", "right")
    tendon_path: str = "channel"
    tip_face_z: float | None = None
    slot_depth_tolerance: float | None = None

    def __post_init__(self) -> None:
        n = self.n_joints
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or not 1 <= n <= MAX_JOINTS:
            raise ValueError(f"n_joints must be an integer from 1 to {MAX_JOINTS}, got {n!r}")
        self._normalise(n)
        self._check_dimensions()
        self._check_tendons()

    def _normalise(self, n: int) -> None:
        """Per-joint values as float or tuple; sides and tendons as tuples."""
        set_ = functools.partial(object.__setattr__, self)
        if not self.slot_sides:
            set_("slot_sides", alternating_sides(n))
        if any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) for s in self.slot_sides):
            raise ValueError(f"slot_sides entries must be the integers -1 or +1, got {self.slot_sides!r}")
        sides = tuple(int(s) for s in self.slot_sides)
        if len(sides) != n:
            raise ValueError(f"slot_sides must have n_joints={n} entries, got {len(sides)}")
        if any(s not in (-1, 1) for s in sides):
            raise ValueError(f"slot_sides entries must be -1 (left) or +1 (right), got {sides}")
        set_("slot_sides", sides)
        for f in ("slot_width", "slot_depth", "rest_angle"):
            set_(f, _per_joint(getattr(self, f), n, f))
        if isinstance(self.p, (list, tuple, np.ndarray)) and n < 2:
            raise ValueError("a list of spacings p needs at least two joints")
        set_("p", _per_joint(self.p, n - 1, "p (joint to joint spacing)"))
        tendons = (self.tendons,) if isinstance(self.tendons, str) else tuple(self.tendons)
        if len(set(tendons)) != len(tendons) or any(t not in _TENDON_SIDES for t in tendons):
            raise ValueError(f"tendons must be 'left', 'right' or both, got {self.tendons!r}")
        set_("tendons", tuple(t for t in ("left", "right") if t in tendons))

    def _check_dimensions(self) -> None:
        R = self.outer_radius
        _finite_positive("outer_radius", R)
        for f in ("p", "slot_width", "slot_depth"):
            _finite_positive(f, getattr(self, f))
        _finite_positive("rest_angle", self.rest_angle, positive=False)
        for f in (*_CHANNEL_FIELDS, "cable_E", "cable_A", "cable_L0", "mount_half_width", "inner_radius",
                  "slot_depth_tolerance"):
            if getattr(self, f) is not None:
                _finite_positive(f, getattr(self, f), positive=f != "inner_radius")
        for f in ("base_edge_z", "mount_bottom_z", "tip_face_z"):
            if getattr(self, f) is not None:
                _finite_positive(f, getattr(self, f), positive=False)
        self._check_magnitudes()
        if np.any(self.slot_depths >= 2 * R):
            raise ValueError("slot_depth must be smaller than the tube diameter 2*outer_radius")
        w = self.slot_widths
        if self.n_joints > 1 and np.any(0.5 * (w[:-1] + w[1:]) >= self.pitches):
            raise ValueError("slot_width must be smaller than the link spacing p (neighbouring slots overlap)")
        if self.n_joints == 1 and w[0] >= self.pitches[0]:
            raise ValueError("slot_width must be smaller than the link spacing p")
        if self.inner_radius is not None and not self.inner_radius < R:
            raise ValueError("inner_radius must be smaller than outer_radius")
        if self.channel_radius is not None and self.cable_radius is not None \
                and self.channel_radius < self.cable_radius:
            raise ValueError("channel_radius must be at least cable_radius")
        if (self.mount_half_width is None) != (self.mount_bottom_z is None):
            raise ValueError("give both mount_half_width and mount_bottom_z, or neither")
        if self.base_edge_z >= 0 or (self.mount_bottom_z is not None and self.mount_bottom_z >= self.base_edge_z):
            raise ValueError("need mount_bottom_z < base_edge_z < 0")
        if self.tip_face_z is not None and self.tip_face_z <= self.joint_z[-1] + 0.5 * w[-1]:
            raise ValueError("tip_face_z must lie beyond the last slot")
        if self.backbone not in BACKBONES:
            raise ValueError(f"backbone must be one of {BACKBONES}, got {self.backbone!r}")
        if self.backbone == "section" and self.inner_radius is None:
            raise ValueError("backbone = 'section' needs inner_radius (0 for a solid rod)")
        if np.any(np.abs(self.rest_angles) >= self.closure_angles):
            raise ValueError("rest_angle must be smaller in magnitude than the slot's closure angle")

    def _check_magnitudes(self) -> None:
        """Lengths within :data:`MAX_LENGTH` (the cable's within :data:`MAX_CABLE_LENGTH`), channels and mount
        consistent with the tube."""
        for f in ("p", "outer_radius", "slot_width", "slot_depth", "inner_radius", "r_x", "r_z", "cable_radius",
                  "channel_radius", "mount_half_width", "base_edge_z", "mount_bottom_z", "tip_face_z",
                  "slot_depth_tolerance"):
            v = getattr(self, f)
            if v is not None and np.any(np.abs(np.asarray(v, dtype=float)) > MAX_LENGTH):
                raise ValueError(f"geometry field {f!r} is larger than {MAX_LENGTH} m: a unit error?")
        if self.cable_L0 is not None and self.cable_L0 > MAX_CABLE_LENGTH:
            raise ValueError(f"cable_L0 is larger than {MAX_CABLE_LENGTH} m: a unit error?")
        R = self.outer_radius
        if self.r_x is not None and self.r_x > R:
            raise ValueError("r_x must not exceed outer_radius (the channels run inside the tube wall)")
        if self.mount_half_width is not None and self.mount_half_width <= R:
            raise ValueError("mount_half_width must be larger than outer_radius (the tube enters the mount)")

    def _check_tendons(self) -> None:
        if not self.tendons:
            return                        # no tendon described: a geometry for detection alone
        if self.tendon_path not in TENDON_PATHS:
            raise ValueError(f"tendon_path must be one of {TENDON_PATHS}, got {self.tendon_path!r}")
        if self.tendon_path == "channel":
            missing = [f for f in _CHANNEL_FIELDS if getattr(self, f) is None]
            if missing:
                raise ValueError(f"tendon_path = 'channel' needs {', '.join(missing)}")
        elif self.inner_radius is None or self.inner_radius <= 0:
            raise ValueError("tendon_path = 'lumen' needs inner_radius > 0")

    # ------------------------------------------------------------------ per joint
    @property
    def sides(self) -> np.ndarray:
        """Slot side of each joint, -1 left / +1 right (n,)."""
        return np.array(self.slot_sides, dtype=np.intp)

    @property
    def pitches(self) -> np.ndarray:
        """Joint-to-joint spacing (n - 1,) [m] (at least one value: ``p`` for n = 1)."""
        if isinstance(self.p, tuple):
            return np.array(self.p)
        return np.full(max(self.n_joints - 1, 1), self.p)

    @property
    def joint_z(self) -> np.ndarray:
        """z of each joint in the straight configuration (n,) [m]: ``(j - 1) p``."""
        p = self.pitches
        if np.all(p == p[0]):          # equal spacings: exactly (j - 1) p, as for a scalar p
            return np.arange(self.n_joints) * p[0]
        return np.concatenate([[0.0], np.cumsum(p)])

    @property
    def slot_widths(self) -> np.ndarray:
        """Slot (notch) height ``h_j`` of each joint (n,) [m]."""
        return np.broadcast_to(np.asarray(self.slot_width, dtype=float), (self.n_joints,)).copy()

    @property
    def slot_depths(self) -> np.ndarray:
        """Cut depth ``g_j`` of each joint (n,) [m]."""
        return np.broadcast_to(np.asarray(self.slot_depth, dtype=float), (self.n_joints,)).copy()

    @property
    def rest_angles(self) -> np.ndarray:
        """Joint angle with no load ``θ0_j`` (n,) [rad]."""
        return np.broadcast_to(np.asarray(self.rest_angle, dtype=float), (self.n_joints,)).copy()

    @property
    def tip_z(self) -> float:
        """z of the tip face in the straight configuration [m] (``n p`` by default)."""
        if self.tip_face_z is not None:
            return float(self.tip_face_z)
        p = self.pitches
        if np.all(p == p[0]):
            return self.n_joints * float(p[0])
        return float(self.joint_z[-1] + p[-1])

    @property
    def n_points(self) -> int:
        """Number of notch points: 4 + 2 per slot (58 for the default)."""
        return 4 + 2 * self.n_joints

    @property
    def cable_stiffness(self) -> float:
        """Linear cable stiffness ``k_c = E A / L0`` [N/m] (Sec. III-B)."""
        if None in (self.cable_E, self.cable_A, self.cable_L0):
            raise ValueError(f"geometry {self.name!r} gives no cable_E/cable_A/cable_L0 (no cable stiffness)")
        return self.cable_E * self.cable_A / self.cable_L0

    @property
    def tendon_sides(self) -> tuple[int, ...]:
        """The tendons as sides: -1 left, +1 right (pulling bends toward that side)."""
        return tuple(_TENDON_SIDES[t] for t in self.tendons)

    # ------------------------------------------------------------------ section
    @functools.cached_property
    def section(self) -> NotchSection:
        """Section properties left by each joint's slot (read-only arrays (n,), :mod:`notchfit.physics.section`).

        Computed once per geometry (the spring law, the closure angles, the
        moment arms and the kinematics all read it).
        """
        if self.inner_radius is None:
            raise ValueError(f"geometry {self.name!r} has no inner_radius: section properties are unknown")
        sec = notch_section(self.outer_radius, self.inner_radius, self.slot_depths)
        for f in dataclasses.fields(sec):
            getattr(sec, f.name).flags.writeable = False
        return sec

    @property
    def neutral_axis_x(self) -> np.ndarray:
        """x of each joint's bending axis in the straight configuration (n,) [m].

        0 for ``backbone = "axis"``; for ``"section"`` the neutral axis of the
        remaining wall, ``-σ_j ȳ_j`` (away from the slot's side ``σ_j``).
        """
        if self.backbone == "axis":
            return np.zeros(self.n_joints)
        return -self.sides * self.section.neutral_offset

    @property
    def closure_angles(self) -> np.ndarray:
        """Joint angle at which each slot closes at its outer edge (n,) [rad].

        ``backbone = "axis"``: the faces of a slot of height ``w`` meet at
        ``x = ±R`` when ``R tan(θ/2) = w/2``: ``θ = 2 atan(w / 2R)`` (0.1397 rad
        for the seed tube, "closes at about 0.14 rad"). ``"section"``: the
        notch bends as an arc of its neutral axis, ``θ = h / (R + ȳ)``
        (:func:`notchfit.physics.section.closure_angle`).
        """
        if self.backbone == "axis":
            R = self.outer_radius
            return np.array([2.0 * math.atan(w / (2.0 * R)) for w in self.slot_widths])
        return section_closure_angle(self.slot_widths, self.section)

    @property
    def closure_angle(self) -> float:
        """The closure angle of every joint when all are alike [rad] (:attr:`closure_angles`).

        Raises ``ValueError`` for joints with different closure angles.
        """
        c = self.closure_angles
        if not np.all(c == c[0]):
            raise ValueError("the joints close at different angles: use Geometry.closure_angles")
        return float(c[0])

    def moment_arms(self, side: int) -> np.ndarray:
        """Moment arm of the tendon on ``side`` about each joint's bending axis (n,) [m].

        The tendon runs at ``x = side * offset``: ``offset = r_x`` in a channel
        (Sec. II-B), the inner radius less the cable radius along the inner wall
        of the lumen. Its arm about an axis at ``x_na`` is ``offset - side x_na``,
        so pulling it bends the joint toward ``side``.
        """
        if side not in (-1, 1):
            raise ValueError(f"side must be -1 (left) or +1 (right), got {side!r}")
        if not self.tendons:
            raise ValueError(f"geometry {self.name!r} describes no tendon (a geometry for detection alone): give "
                             "r_x_mm, r_z_mm, cable_radius_mm and channel_radius_mm, or tendon_path = \"lumen\" "
                             "with inner_radius_mm")
        if self.tendon_path == "channel":
            offset = self.r_x
        else:
            offset = self.inner_radius - (self.cable_radius or 0.0)
        return offset - side * self.neutral_axis_x

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
        Keys of docs/geometry.md. Required: ``n_joints``, ``p_mm``,
        ``outer_radius_mm``, ``slot_width_mm``, ``slot_depth_mm``,
        ``base_edge_z_mm``. Optional: the cable and channel keys (required by
        ``tendon_path = "channel"``, the default), the mount, ``name``,
        ``slot_sides`` (``"alternating"`` or a list of -1/+1),
        ``inner_radius_mm``, ``rest_angle_rad``, ``backbone``, ``tendons``,
        ``tendon_path``, ``tip_face_z_mm``, ``slot_depth_tolerance_mm``. ``p_mm``, ``slot_width_mm``,
        ``slot_depth_mm`` and ``rest_angle_rad`` take one number or a list
        (``n_joints`` values, ``n_joints - 1`` for ``p_mm``), base to tip.
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

    known = set(_REQUIRED_KEYS) | set(_PER_JOINT_KEYS) | set(_LENGTH_KEYS) | set(_SIGNED_LENGTH_KEYS) \
        | set(_POSITIVE_SI_KEYS) | set(_OTHER_KEYS)
    missing = [k for k in _REQUIRED_KEYS if k not in data]
    if missing:
        raise fail(f"missing geometry field(s) {', '.join(missing)}")
    unknown = sorted(set(data) - known)
    if unknown:
        raise fail(f"unknown geometry field(s) {', '.join(unknown)}", unknown[0])
    n = data["n_joints"]
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_JOINTS:
        raise fail(f"n_joints must be an integer from 1 to {MAX_JOINTS}, got {n!r}", "n_joints")
    kw: dict = {"name": str(data.get("name", Path(origin).stem)), "n_joints": n}

    def number(key, positive, scale=1.0):
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise fail(f"{key} must be a finite number, got {v!r}", key)
        if positive and v <= 0:
            raise fail(f"{key} must be positive, got {float(v)}", key)
        return float(v) * scale

    def numbers(key, count, positive, scale):
        v = data[key]
        if not isinstance(v, list):
            return number(key, positive, scale)
        if len(v) != count:
            raise fail(f"{key} must have {count} values (or be one number), got {len(v)}", key)
        for x in v:
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise fail(f"{key} must hold finite numbers, got {x!r}", key)
            if positive and x <= 0:
                raise fail(f"{key} must hold positive numbers, got {float(x)}", key)
        return tuple(float(x) * scale for x in v)

    kw["p"] = numbers("p_mm", n - 1, True, MM)
    for key, field in _PER_JOINT_KEYS.items():
        kw[field] = numbers(key, n, True, MM)
    if "rest_angle_rad" in data:
        kw["rest_angle"] = numbers("rest_angle_rad", n, False, 1.0)
    for key, field in _LENGTH_KEYS.items():
        kw[field] = number(key, True, MM) if key in data else None
    if "inner_radius_mm" in data:
        kw["inner_radius"] = number("inner_radius_mm", False, MM)
    for key, field in _SIGNED_LENGTH_KEYS.items():
        kw[field] = number(key, False, MM) if key in data else None
    for key, field in _POSITIVE_SI_KEYS.items():
        kw[field] = number(key, True) if key in data else None
    kw["slot_sides"] = _sides_from_file(data.get("slot_sides", "alternating"), n, fail)
    for key in ("backbone", "tendon_path"):
        if key in data:
            if not isinstance(data[key], str):
                raise fail(f"{key} must be a string, got {data[key]!r}", key)
            kw[key] = data[key]
    if not any(k in data for k in ("tendons", "tendon_path", "r_x_mm", "r_z_mm", "cable_radius_mm",
                                   "channel_radius_mm")):
        kw["tendons"] = ()                # written for detection alone: no tendon described
    if "tendons" in data:
        t = data["tendons"]
        if not (isinstance(t, list) and all(isinstance(x, str) for x in t)):
            raise fail(f'tendons must be a list such as ["left", "right"], got {t!r}', "tendons")
        kw["tendons"] = tuple(t)
    try:
        return Geometry(**kw)
    except ValueError as exc:
        raise fail(str(exc)) from None


def _sides_from_file(sides, n, fail) -> tuple[int, ...]:
    if sides == "alternating":
        return alternating_sides(n)
    if isinstance(sides, list) and all(isinstance(s, int) and not isinstance(s, bool) for s in sides):
        return tuple(sides)
    raise fail(f"slot_sides must be \"alternating\" or a list of -1/+1, got {sides!r}", "slot_sides")


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
    n, R = geom.n_joints, geom.outer_radius
    zj, w, tip = geom.joint_z, geom.slot_widths, geom.tip_z
    rows = []  # (link, x, z_straight, kind, joint, side)
    rows.append((0, -R, geom.base_edge_z, "base", 0, -1))
    rows.append((0, +R, geom.base_edge_z, "base", 0, +1))
    for j in range(1, n + 1):
        if geom.slot_sides[j - 1] == +1:
            rows.append((j - 1, R, zj[j - 1] - w[j - 1] / 2, "proximal", j, +1))
            rows.append((j, R, zj[j - 1] + w[j - 1] / 2, "distal", j, +1))
    rows.append((n, +R, tip, "tip", 0, +1))
    rows.append((n, -R, tip, "tip", 0, -1))
    for j in range(n, 0, -1):
        if geom.slot_sides[j - 1] == -1:
            rows.append((j, -R, zj[j - 1] + w[j - 1] / 2, "distal", j, -1))
            rows.append((j - 1, -R, zj[j - 1] - w[j - 1] / 2, "proximal", j, -1))
    link = np.array([r[0] for r in rows], dtype=np.intp)
    straight = np.array([[r[1], r[2]] for r in rows], dtype=float)
    origin_z = np.where(link > 0, zj[np.maximum(link - 1, 0)], 0.0)
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
