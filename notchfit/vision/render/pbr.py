"""Physically based test scenes of the notched tube (Mitsuba 3, variant ``scalar_rgb``).

The renders of :mod:`notchfit.vision.render` and :mod:`notchfit.vision.render.scenes` paint
the silhouette and then shade it with the same assumptions the detector was
written with. This module builds an independent scene for a path tracer, from
what a lab photograph of a wrist shows: a polished nitinol tube (a rough
conductor, with the specular stripe a softbox leaves along it), hanging from a
polished steel chuck with a knurled body, lit by area lights that cast its
shadow on the backdrop (warm-grey card or grid paper); a tendon leaving the tip
with a droplet at its end and hanging in a loop towards the image border; or a
matte white printed tube lying on coloured paper seen by a phone-like wide lens
(with barrel distortion) whose base comes in from the image border. A thin lens
gives depth of field; a camera response (exposure, tone curve, sensor noise,
JPEG) turns the linear radiance into an 8-bit photo.

The tube is a triangle mesh built from notchfit's own solid model
(:func:`notchfit.vision.render.solid.tube_pieces`: each link's solid part and the two
halves of every flexure's backbone, cut by the slot and mitre planes, placed
by the kinematics of :mod:`notchfit.physics.kinematics`), each convex piece meshed as
the convex hull of densely sampled edges. The ground truth of the corners is
computed from the same solid and the same camera
(:func:`notchfit.vision.render.solid.limb_corners`: where the tube's limb meets each
face's circle, projected by :class:`notchfit.vision.camera.CameraModel`), whose pinhole
model is Mitsuba's perspective sensor (checked against a rendered marker).
Lens distortion is applied to the rendered ideal image by resampling at the
camera model's own distortion, so truth and image use one model.

Mitsuba is an optional dependency (``pip install notchfit[pbr]``): it is
imported inside the functions that render. Scene units inside Mitsuba are mm;
everything returned is SI or pixels (CONVENTIONS.md: integer pixel centres).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import cv2
import numpy as np
from scipy.spatial import ConvexHull

from ..camera import CameraModel
from ...physics.geometry import Geometry, notch_layout
from ...physics.notches import notch_points, to_plane
from ...units import MM
from .scenes import scene_camera
from .solid import SolidPose, _edge_points, limb_corners, project, to_plane_3d, tube_pieces

__all__ = ["PbrRender", "PbrScene", "PbrScore", "PbrTruth", "camera_response", "chuck_mesh", "distort_image",
           "hull_mesh", "pbr_camera", "pbr_truth", "render_markers", "render_pbr", "score_detection", "sweep_mesh",
           "tendon_curve", "tube_mesh"]

TUBES = ("polished", "printed")
BACKDROPS = ("grey", "grid", "blue")
HOLDERS = ("chuck", "none")
VARIANT = "scalar_rgb"


@dataclass(frozen=True)
class PbrScene:
    """One physically based scene: the tube's shape, the camera, the set and the photo's processing.

    Attributes
    ----------
    name, kind : str
        A label, and the scene family it belongs to (tables group by it).
    theta : tuple of float
        Joint angles [rad].
    image_size : (W, H)
    px_per_mm : float
        Image scale in the bending plane at the image centre [px/mm].
    angle_deg : float
        Image direction from base to tip (90: hanging down).
    base_at : float
        Where the base edge lands along that direction, as a fraction of the
        image (negative: beyond the border, the tube comes in from outside).
    focal_px : float
        Focal length [px]; the camera stands ``focal_px / px_per_mm`` mm from
        the plane (a short focal length is a wide lens seen up close).
    dist : tuple
        OpenCV distortion ``k1 k2 p1 p2 k3`` of the lens (barrel: ``k1 < 0``).
    tilt_deg, tilt_axis_deg : float
        The tube's tilt out of the bending plane (:class:`SolidPose`).
    tube : {"polished", "printed"}
        A rough conductor (nitinol) or a matte white plastic.
    roughness : float
        GGX alpha of the polished tube.
    backdrop : {"grey", "grid", "blue"}
        Warm-grey card, grid paper (1 mm, bold every 10 mm) or blue paper.
    backdrop_gap : float
        Distance of the backdrop behind the tube's axis [m] (``R``: lying on it).
    holder : {"chuck", "none"}
        A polished steel chuck with a knurled body whose face is at the base
        edge, or none (the tube enters from the border).
    holder_half_width : float
        Chuck radius [m].
    tendon, droplet : bool
        A tendon leaving the tip and hanging in a loop to the border; a glue
        droplet at the tendon's exit.
    aperture : float
        Lens aperture radius [m] (0: a pinhole, no depth of field).
    focus_offset : float
        Focus distance minus the plane's distance [m] (defocus of the tube).
    key_light : (azimuth_deg, off_axis_deg)
        Direction of the softbox from the tube: its azimuth about the camera
        axis (90: from the image top) and its angle off that axis.
    room : float
        Radiance of the room around the set (what the polished metal
        mirrors outside the softbox's stripe), relative to the softbox's 1.
    spp : int
        Samples per pixel.
    exposure_dn : float
        The 60th percentile of the image after the tone curve [DN].
    noise_dn : float
        Sensor noise after the tone curve [DN].
    jpeg_quality : int
        0: no JPEG (PNG-like lossless output).
    seed : int
    """

    name: str
    kind: str
    theta: tuple
    image_size: tuple = (600, 900)
    px_per_mm: float = 90.0
    angle_deg: float = 90.0
    base_at: float = 0.2
    focal_px: float = 6000.0
    dist: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    tube: str = "polished"
    roughness: float = 0.08
    backdrop: str = "grey"
    backdrop_gap: float = 6e-3
    holder: str = "chuck"
    holder_half_width: float = 4e-3
    tendon: bool = False
    droplet: bool = False
    aperture: float = 0.0
    focus_offset: float = 0.0
    key_light: tuple = (120.0, 35.0)
    room: float = 0.03
    spp: int = 16
    exposure_dn: float = 160.0
    noise_dn: float = 1.0
    jpeg_quality: int = 90
    seed: int = 0

    def __post_init__(self):
        if self.tube not in TUBES or self.backdrop not in BACKDROPS or self.holder not in HOLDERS:
            raise ValueError(f"scene {self.name!r}: tube in {TUBES}, backdrop in {BACKDROPS}, holder in {HOLDERS}")
        object.__setattr__(self, "theta", tuple(float(t) for t in self.theta))
        object.__setattr__(self, "image_size", tuple(int(v) for v in self.image_size))
        object.__setattr__(self, "dist", tuple(float(v) for v in self.dist))
        object.__setattr__(self, "key_light", tuple(float(v) for v in self.key_light))
        if not (self.spp >= 1 and self.px_per_mm > 0 and self.focal_px > 0):
            raise ValueError(f"scene {self.name!r}: spp, px_per_mm and focal_px must be positive")

    def to_dict(self) -> dict:
        """Plain values (lists for tuples) for a JSON file."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> "PbrScene":
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()})


@dataclass(frozen=True)
class PbrTruth:
    """Ground truth of a scene: the camera, the tube's pose and its corners in the image.

    Attributes
    ----------
    camera : CameraModel
        Intrinsics, distortion and the bending plane's pose.
    pose : SolidPose
        The plane transform ``(tx, ty, phi, mirror)`` [m, rad] and the tilt.
    points_px : ndarray (m, 2)
        Every notch point's corner in the image [px] (geometry.md numbering).
    visible : ndarray (m,) of bool
        The point is a corner the image shows (inside the frame, not hidden).
    why : tuple of str (m,)
        Why a point is not visible (empty when it is).
    """

    camera: CameraModel
    pose: SolidPose
    points_px: np.ndarray
    visible: np.ndarray
    why: tuple = field(default_factory=tuple)

    def to_dict(self) -> dict:
        """Plain values for a JSON file (file units: plane translations in mm, pixels, radians)."""
        cam = self.camera
        tx, ty, phi, mirror = self.pose.plane
        return {"camera": {"camera_matrix": np.asarray(cam.camera_matrix).tolist(),
                           "dist_coeffs": np.asarray(cam.dist_coeffs).tolist(), "image_size": list(cam.image_size),
                           "plane_rvec": np.asarray(cam.plane_rvec).tolist(),
                           "plane_tvec_mm": (np.asarray(cam.plane_tvec) / MM).tolist()},
                "pose": {"tx_mm": tx / MM, "ty_mm": ty / MM, "phi_rad": phi, "mirror": bool(mirror),
                         "tilt_rad": self.pose.tilt, "tilt_axis_rad": self.pose.tilt_axis},
                "points": [{"point": i + 1, "u_px": float(u), "v_px": float(v), "visible": bool(ok), "why": w}
                           for i, ((u, v), ok, w) in enumerate(zip(self.points_px, self.visible, self.why))]}

    @classmethod
    def from_dict(cls, d: dict) -> "PbrTruth":
        c, p = d["camera"], d["pose"]
        cam = CameraModel(np.array(c["camera_matrix"], float), np.array(c["dist_coeffs"], float),
                          tuple(c["image_size"]), np.array(c["plane_rvec"], float),
                          np.array(c["plane_tvec_mm"], float) * MM)
        pose = SolidPose((p["tx_mm"] * MM, p["ty_mm"] * MM, float(p["phi_rad"]), bool(p["mirror"])),
                         float(p["tilt_rad"]), float(p["tilt_axis_rad"]))
        pts = d["points"]
        return cls(cam, pose, np.array([[q["u_px"], q["v_px"]] for q in pts], float),
                   np.array([q["visible"] for q in pts], bool), tuple(q["why"] for q in pts))


@dataclass(frozen=True)
class PbrRender:
    """A rendered scene: the 8-bit BGR photo, its JPEG bytes (if any) and the truth."""

    image: np.ndarray
    encoded: bytes | None
    truth: PbrTruth
    seconds: float


# ----------------------------------------------------------------------------- camera and truth
def pbr_camera(scene: PbrScene, geom: Geometry) -> tuple[CameraModel, SolidPose]:
    """The camera (fronto-parallel, centred principal point) and the tube's pose of ``scene``."""
    cam, plane = scene_camera(np.asarray(scene.theta), geom, image_size=scene.image_size,
                              mm_per_px=1.0 / scene.px_per_mm, angle_deg=scene.angle_deg, base_at=scene.base_at,
                              focal_px=scene.focal_px, dist=np.asarray(scene.dist))
    tx, ty, phi, mirror = plane
    # centre the bent tube across the image (scene_camera places the straight one)
    uv = cam.plane_to_pixel(to_plane(notch_points(np.asarray(scene.theta), geom), *plane))
    a = math.radians(scene.angle_deg)
    across = np.array([-math.sin(a), math.cos(a)])
    c = 0.5 * (np.asarray(scene.image_size, float) - 1)
    off = (uv - c) @ across
    shift = cam.pixel_to_plane(c - 0.5 * (off.min() + off.max()) * across) - cam.pixel_to_plane(c)
    plane = (tx + float(shift[0]), ty + float(shift[1]), phi, mirror)
    return cam, SolidPose(plane, math.radians(scene.tilt_deg), math.radians(scene.tilt_axis_deg))


def pbr_truth(scene: PbrScene, geom: Geometry, camera: CameraModel, pose: SolidPose, *,
              margin_px: float = 4.0, clearance_px: float = 4.0) -> PbrTruth:
    """The corners of the solid tube in the image and which of them the photo shows.

    A base point is not a visible corner in these scenes: without a holder the
    tube runs on past it; with the chuck, whose face is seen a little from
    the side, the silhouette's corner lies on the face's rim, away from the
    base edge. A corner within ``clearance_px`` of the tendon's image (its
    radius added) is hidden by it.
    """
    th = np.asarray(scene.theta, float)
    pts = limb_corners(th, geom, camera, pose)
    W, H = camera.image_size
    why = ["" for _ in range(len(pts))]
    for i in range(len(pts)):
        u, v = pts[i]
        if not (margin_px <= u <= W - 1 - margin_px and margin_px <= v <= H - 1 - margin_px):
            why[i] = "outside the image"
    lay = notch_layout(geom)
    for i in np.nonzero(np.array(lay.kind) == "base")[0]:
        if not why[i]:
            why[i] = ("no holder: the tube runs on past its base edge" if scene.holder == "none" else
                      "the chuck's face rim, seen from the side, makes the image corner")
    if scene.tendon:
        path, radius = tendon_curve(th, geom, pose)
        uv = project(camera, path)
        r_px = radius * 1e3 * scene.px_per_mm
        for i in range(len(pts)):
            if not why[i] and _distance_to_polyline(pts[i], uv) < r_px + clearance_px:
                why[i] = "hidden by the tendon"
    vis = np.array([not w for w in why])
    return PbrTruth(camera, pose, pts, vis, tuple(why))


def _distance_to_polyline(p, uv) -> float:
    a, b = uv[:-1], uv[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


# ----------------------------------------------------------------------------- meshes (plane frame, m)
def hull_mesh(P) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull of points (N, 3) as a triangle mesh, every face wound outward: (V, F)."""
    hull = ConvexHull(P)
    V = P[hull.vertices]
    remap = np.full(len(P), -1)
    remap[hull.vertices] = np.arange(len(hull.vertices))
    F = remap[hull.simplices]
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    flip = np.einsum("ij,ij->i", n, hull.equations[:, :3]) < 0
    F[flip] = F[flip][:, ::-1]
    return V, F


def _outward(V, F) -> np.ndarray:
    """``F`` wound so that the signed volume of the (closed or nearly closed) mesh is positive.

    The plane frame ``(X, Y, Z) = (to_plane(x, z), y)`` is a reflection of the
    manipulator frame, so a mesh built in a link's frame comes out inside-out.
    """
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b - a, c - a)).sum()
    return F if vol > 0 else F[:, ::-1].copy()


def _merge(meshes) -> tuple[np.ndarray, np.ndarray]:
    Vs, Fs, k = [], [], 0
    for V, F in meshes:
        Vs.append(V)
        Fs.append(F + k)
        k += len(V)
    return np.concatenate(Vs), np.concatenate(Fs)


def tube_mesh(theta, geom: Geometry, pose: SolidPose, base_z: float, *, n_curve: int = 720):
    """The solid tube from ``base_z`` to the tip face as one triangle mesh in the plane frame: (V [m], F).

    Each convex piece of :func:`~notchfit.vision.render.solid.tube_pieces` (a link's
    solid part, a half backbone) is the hull of its sampled edges, placed by
    the link's frame (bend, tilt, plane pose).
    """
    th = np.asarray(theta, float)
    out = []
    for pc in tube_pieces(th, geom, base_z):
        P = _edge_points(pc.planes, geom.outer_radius, n_curve)
        if len(P) < 4:
            continue
        out.append(hull_mesh(to_plane_3d(pc.link, P, th, geom, pose)))
    return _merge(out)


def _grid_faces(n_rows: int, n_cols: int, *, wrap: bool) -> np.ndarray:
    """Triangles of a (n_rows, n_cols) vertex grid, columns closing around when ``wrap``."""
    r, c = np.meshgrid(np.arange(n_rows - 1), np.arange(n_cols if wrap else n_cols - 1), indexing="ij")
    r, c = r.ravel(), c.ravel()
    c1 = (c + 1) % n_cols
    a, b, d, e = r * n_cols + c, r * n_cols + c1, (r + 1) * n_cols + c, (r + 1) * n_cols + c1
    return np.concatenate([np.stack([a, b, e], 1), np.stack([a, e, d], 1)])


def _fan(ring_idx, centre_idx, *, reverse: bool) -> np.ndarray:
    k = len(ring_idx)
    F = np.stack([np.full(k, centre_idx), ring_idx, np.roll(ring_idx, -1)], 1)
    return F[:, ::-1] if reverse else F


def chuck_mesh(theta, geom: Geometry, pose: SolidPose, *, half_width: float, length: float,
               knurl_pitch: float = 0.6e-3, knurl_depth: float = 0.12e-3, plain: float = 1.0e-3,
               n_around: int = 720):
    """A chuck: a cylinder of radius ``half_width`` on the tube's axis, its flat face at the base edge,
    a diamond knurl on its body from ``plain`` above the face on: (V [m], F), closed, faces outward.

    The body is ``length`` long, rounded down to a whole number of knurl steps (``knurl_pitch / 10``).

    The knurl is two sets of V grooves along opposite helices ``pitch`` apart.
    """
    face = geom.base_edge_z
    step = knurl_pitch / 10                   # the knurl's sampling along the axis; the body ends within a step
    rows = np.concatenate([[0.0, plain], plain + np.arange(1, int((length - plain) / step) + 1) * step])
    z = face - rows
    psi = np.linspace(0, 2 * math.pi, n_around, endpoint=False)
    Z, PS = np.meshgrid(z, psi, indexing="ij")
    s = half_width * PS
    a, b = (s + (face - Z)) / knurl_pitch, (s - (face - Z)) / knurl_pitch
    g = np.minimum(np.abs(a - np.round(a)), np.abs(b - np.round(b)))
    r = half_width - knurl_depth * np.clip(1 - g / 0.25, 0, 1) * ((face - Z) > plain)
    side = np.stack([r * np.cos(PS), r * np.sin(PS), Z], -1).reshape(-1, 3)
    caps = np.array([[0.0, 0.0, z[0]], [0.0, 0.0, z[-1]]])
    P = np.concatenate([side, caps])
    nz = len(z)
    F = [_grid_faces(nz, n_around, wrap=True)[:, ::-1],
         _fan(np.arange(n_around), len(side), reverse=False),
         _fan(np.arange((nz - 1) * n_around, nz * n_around), len(side) + 1, reverse=True)]
    F = np.concatenate(F)
    V = to_plane_3d(0, P, np.asarray(theta, float), geom, pose)
    return V, _outward(V - V.mean(0), F)


def sweep_mesh(path, radius: float, *, n_around: int = 16):
    """A tube of ``radius`` along a 3-D polyline (K, 3) (parallel-transport frames), open ends: (V, F)."""
    P = np.asarray(path, float)
    T = np.gradient(P, axis=0)
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    n = np.cross(T[0], [0.0, 0.0, 1.0] if abs(T[0, 2]) < 0.9 else [1.0, 0.0, 0.0])
    n /= np.linalg.norm(n)
    N = np.empty_like(P)
    for k in range(len(P)):
        n = n - (n @ T[k]) * T[k]
        n /= np.linalg.norm(n)
        N[k] = n
    B = np.cross(T, N)
    ang = np.linspace(0, 2 * math.pi, n_around, endpoint=False)
    V = P[:, None] + radius * (np.cos(ang)[None, :, None] * N[:, None] + np.sin(ang)[None, :, None] * B[:, None])
    V = V.reshape(-1, 3)
    return V, _outward(V - V.mean(0), _grid_faces(len(P), n_around, wrap=True))


def tendon_curve(theta, geom: Geometry, pose: SolidPose, *, step: float = 0.02e-3):
    """The tendon's centre line in the plane frame (K, 3) [m] and its radius [m].

    It leaves the tip face from the lumen on the tendon's side, runs straight
    for 0.6 R, turns a full loop of radius 1.4 R (drifting out of the plane by
    0.6 R so that it passes itself) and one radian more, and runs straight on
    for 60 R, out of the image.
    """
    R = geom.outer_radius
    side = geom.tendon_sides[0] if geom.tendon_sides else 1
    r_t = geom.cable_radius or 0.06 * R
    r_in = geom.inner_radius if geom.inner_radius else 0.8 * R
    rho, straight, run = 1.4 * R, 0.6 * R, 60 * R
    turn = 2 * math.pi + 1.0
    s = np.arange(0.0, straight + rho * turn + run, step)
    kappa = np.where((s > straight) & (s < straight + rho * turn), side / rho, 0.0)
    heading = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s))])
    x = side * (r_in - r_t) + np.concatenate([[0.0], np.cumsum(np.sin(heading[1:]) * np.diff(s))])
    z = geom.tip_z + np.concatenate([[0.0], np.cumsum(np.cos(heading[1:]) * np.diff(s))])
    y = 0.6 * R * np.clip((s - straight) / (rho * turn), 0, 1)
    pts = np.stack([x, y, z], 1)
    return to_plane_3d(geom.n_joints, pts, np.asarray(theta, float), geom, pose), r_t


# ----------------------------------------------------------------------------- image formation
def distort_image(ideal, camera: CameraModel, margin: int) -> np.ndarray:
    """Resample an ideal pinhole image (H + 2 margin, W + 2 margin, C) at the camera's distortion.

    Output pixel ``(u, v)`` takes the ideal image at the camera model's
    undistorted position of ``(u, v)`` (bilinear), so that the result is what
    :meth:`CameraModel.plane_to_pixel` predicts.
    """
    W, H = camera.image_size
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    ideal_uv = camera.undistort_pixels(np.stack([uu, vv], -1).reshape(-1, 2)).reshape(H, W, 2)
    mx, my = (ideal_uv[..., 0] + margin).astype(np.float32), (ideal_uv[..., 1] + margin).astype(np.float32)
    return cv2.remap(np.ascontiguousarray(ideal, np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def camera_response(linear, scene: PbrScene, rng) -> np.ndarray:
    """Linear RGB radiance (H, W, 3) -> an 8-bit BGR photo (exposure, sRGB tone curve, noise, rounding)."""
    lin = np.clip(np.asarray(linear, np.float64), 0, None)
    lum = lin.mean(axis=2)
    target = ((scene.exposure_dn / 255.0 + 0.055) / 1.055) ** 2.4
    scale = target / max(float(np.percentile(lum, 60)), 1e-12)
    x = np.clip(lin * scale, 0, 1)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255.0
    srgb += rng.normal(0.0, scene.noise_dn, srgb.shape)
    return np.clip(np.round(srgb), 0, 255).astype(np.uint8)[..., ::-1].copy()


# ----------------------------------------------------------------------------- the Mitsuba scene (mm)
def _mesh(mi, name, V, F, bsdf):
    """An in-memory Mitsuba mesh (flat facets) from plane-frame vertices [m] and faces."""
    import drjit as dr  # slow optional dependency (comes with mitsuba)

    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    props["face_normals"] = True
    m = mi.Mesh(name, vertex_count=len(V), face_count=len(F), has_vertex_normals=False,
                has_vertex_texcoords=False, props=props)
    p = mi.traverse(m)
    p["vertex_positions"] = dr.scalar.ArrayXf((np.asarray(V) / MM).astype(np.float32).ravel())
    p["faces"] = dr.scalar.ArrayXu(np.asarray(F, np.uint32).ravel())
    p.update()
    return m


def _backdrop_texture(scene: PbrScene, size_mm, rng, *, texel_mm: float = 0.025, max_texels: int = 4096):
    """The backdrop's reflectance (h, w, 3) in [0, 1]: warm grey with a gradient, grid paper, or blue paper."""
    if scene.backdrop == "grey":
        g = np.linspace(0.92, 1.08, 64)[:, None, None] * np.linspace(1.04, 0.96, 64)[None, :, None]
        return (g * np.array([0.55, 0.50, 0.44])).astype(np.float32)
    nx, ny = (min(int(s / texel_mm), max_texels) for s in size_mm)
    if scene.backdrop == "blue":
        fib = cv2.GaussianBlur(rng.normal(0, 1, (ny, nx)).astype(np.float32), (0, 0), 3.0)
        fib /= max(float(fib.std()), 1e-6)
        return (np.array([0.07, 0.17, 0.50], np.float32) * (1 + 0.04 * fib[..., None])).astype(np.float32)
    x = (np.arange(nx) + 0.5) * size_mm[0] / nx
    y = (np.arange(ny) + 0.5) * size_mm[1] / ny

    def lines(t, period, width):
        return np.abs(t - period * np.round(t / period)) < width / 2

    ink = np.maximum(lines(x, 1.0, 0.06)[None, :] | lines(y, 1.0, 0.06)[:, None],
                     2 * (lines(x, 10.0, 0.18)[None, :] | lines(y, 10.0, 0.18)[:, None])).astype(np.float32)
    paper, line = np.array([0.86, 0.86, 0.82], np.float32), np.array([0.50, 0.72, 0.70], np.float32)
    t = np.clip(ink * 0.6, 0, 1)[..., None]
    return (paper * (1 - t) + line * t).astype(np.float32)


def _materials(scene: PbrScene) -> dict:
    """The BSDFs: tube, chuck, tendon, droplet."""
    if scene.tube == "polished":      # nitinol: a grey conductor between nickel and titanium (RGB eta, k)
        tube = {"type": "roughconductor", "distribution": "ggx", "alpha": scene.roughness,
                "eta": {"type": "rgb", "value": [2.2, 2.0, 1.8]}, "k": {"type": "rgb", "value": [3.6, 3.3, 3.0]}}
    else:
        tube = {"type": "roughplastic", "distribution": "ggx", "alpha": 0.3,
                "diffuse_reflectance": {"type": "rgb", "value": [0.80, 0.80, 0.78]}}
    steel = {"type": "roughconductor", "distribution": "ggx", "alpha": 0.05,
             "eta": {"type": "rgb", "value": [2.9, 2.9, 2.6]}, "k": {"type": "rgb", "value": [3.1, 3.0, 2.9]}}
    tendon = {"type": "roughplastic", "alpha": 0.2, "diffuse_reflectance": {"type": "rgb", "value": 0.05}}
    drop = {"type": "roughplastic", "alpha": 0.05, "diffuse_reflectance": {"type": "rgb", "value": 0.7}}
    return {"tube": tube, "steel": steel, "tendon": tendon, "drop": drop}


def _light(mi, origin, target, half_size, radiance):
    T = mi.ScalarTransform4f()
    return {"type": "rectangle", "to_world": T.look_at(origin=list(origin), target=list(target), up=[0, 0, 1])
            @ T.scale([half_size, half_size, 1.0]), "emitter": {"type": "area", "radiance": {"type": "rgb",
                                                                                              "value": radiance}}}


def _camera_frame(camera: CameraModel):
    """Camera centre [mm], viewing direction and image-up direction in the plane frame."""
    Rc = camera.plane_rotation
    C = -Rc.T @ np.asarray(camera.plane_tvec, float) / MM
    return C, Rc.T @ np.array([0.0, 0.0, 1.0]), -Rc.T @ np.array([0.0, 1.0, 0.0])


def _sensor(mi, scene: PbrScene, camera: CameraModel, margin: int) -> dict:
    """Mitsuba's perspective (or thin-lens) sensor for the camera model's pinhole (square pixels, centred)."""
    K = camera.camera_matrix
    W, H = camera.image_size
    if abs(K[0, 0] - K[1, 1]) > 1e-9 * K[0, 0] or K[0, 1] or \
            abs(K[0, 2] - (W - 1) / 2) > 1e-9 or abs(K[1, 2] - (H - 1) / 2) > 1e-9:
        raise ValueError("Mitsuba's perspective sensor needs square pixels, no skew and a centred principal point")
    C, fwd, up = _camera_frame(camera)
    Wf, Hf = W + 2 * margin, H + 2 * margin
    s = {"type": "perspective", "fov_axis": "x", "fov": math.degrees(2 * math.atan(Wf / 2 / K[0, 0])),
         "to_world": mi.ScalarTransform4f().look_at(origin=C.tolist(), target=(C + fwd).tolist(), up=up.tolist()),
         "film": {"type": "hdrfilm", "width": Wf, "height": Hf, "pixel_format": "rgb"},
         "sampler": {"type": "multijitter", "sample_count": scene.spp}}
    if scene.aperture > 0:
        s.update(type="thinlens", aperture_radius=scene.aperture / MM,
                 focus_distance=float(abs(C @ fwd)) + scene.focus_offset / MM)
    return s


def _distortion_margin(camera: CameraModel, pad: int = 3) -> int:
    """Extra ideal pixels around the image that distorted border pixels reach (0 without distortion)."""
    if not np.any(camera.dist_coeffs):
        return 0
    W, H = camera.image_size
    t = np.linspace(0, 1, 64)
    border = np.concatenate([np.stack([t * (W - 1), 0 * t], 1), np.stack([t * (W - 1), 0 * t + H - 1], 1),
                             np.stack([0 * t, t * (H - 1)], 1), np.stack([0 * t + W - 1, t * (H - 1)], 1)])
    ideal = camera.undistort_pixels(border)
    over = max(float(-ideal.min()), float((ideal[:, 0] - (W - 1)).max()), float((ideal[:, 1] - (H - 1)).max()), 0.0)
    return int(math.ceil(over)) + pad


def scene_dict(mi, scene: PbrScene, geom: Geometry, camera: CameraModel, pose: SolidPose, margin: int) -> dict:
    """The Mitsuba scene of ``scene`` (a dict for ``mi.load_dict``); lengths in mm."""
    th = np.asarray(scene.theta, float)
    rng = np.random.default_rng(scene.seed)
    mats = _materials(scene)
    C, fwd, up = _camera_frame(camera)
    D = abs(C @ fwd)
    W, H = camera.image_size
    view = np.array([W, H]) / scene.px_per_mm * (D + scene.backdrop_gap / MM) / D * 1.6 + 4.0
    reach = 1.5 * math.hypot(W, H) / scene.px_per_mm * MM + 2 * scene.holder_half_width
    base_z = geom.base_edge_z - (reach if scene.holder == "none" else 4 * geom.outer_radius)
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": 4, "hide_emitters": True},
         "sensor": _sensor(mi, scene, camera, margin),
         "tube": _mesh(mi, "tube", *tube_mesh(th, geom, pose, base_z), mats["tube"]),
         "room": {"type": "constant", "radiance": {"type": "rgb", "value": scene.room}}}
    tex = _backdrop_texture(scene, view, rng)
    T = mi.ScalarTransform4f()
    centre = [float(C[0]), float(C[1]), -scene.backdrop_gap / MM]
    d["backdrop"] = {"type": "rectangle", "to_world": T.translate(centre) @ T.scale([view[0] / 2, view[1] / 2, 1.0]),
                     "bsdf": {"type": "diffuse", "reflectance": {"type": "bitmap", "bitmap": mi.Bitmap(tex),
                                                                 "raw": True, "filter_type": "bilinear"}}}
    az, off = (math.radians(a) for a in scene.key_light)
    dl = 6.0 * max(view)
    key = np.array([math.sin(off) * math.cos(az), math.sin(off) * math.sin(az), math.cos(off)]) * dl
    tgt = [float(C[0]), float(C[1]), 0.0]
    d["key"] = _light(mi, np.array(tgt) + key, tgt, 0.25 * dl, [1.0, 0.97, 0.92])
    fill = np.array([-key[0], -key[1], key[2]]) * 1.2
    d["fill"] = _light(mi, np.array(tgt) + fill, tgt, 0.2 * dl, [0.06, 0.06, 0.065])
    if scene.holder == "chuck":
        d["chuck"] = _mesh(mi, "chuck", *chuck_mesh(th, geom, pose, half_width=scene.holder_half_width,
                                                    length=reach), mats["steel"])
    if scene.tendon:
        path, r_t = tendon_curve(th, geom, pose)
        d["tendon"] = _mesh(mi, "tendon", *sweep_mesh(path, r_t), mats["tendon"])
    if scene.droplet:
        x = (geom.tendon_sides[0] if geom.tendon_sides else 0) * (geom.inner_radius or 0.0) * 0.6
        c = to_plane_3d(geom.n_joints, np.array([[x, 0.0, geom.tip_z + 0.05 * geom.outer_radius]]), th, geom, pose)
        d["droplet"] = {"type": "sphere", "center": (c[0] / MM).tolist(), "radius": 0.28 * geom.outer_radius / MM,
                        "bsdf": mats["drop"]}
    return d


def render_pbr(scene: PbrScene, geom: Geometry) -> PbrRender:
    """Render ``scene`` with Mitsuba 3 (``scalar_rgb``) and return the 8-bit photo and its truth.

    Raises
    ------
    ModuleNotFoundError
        Mitsuba is not installed (``pip install notchfit[pbr]``).
    """
    import mitsuba as mi  # slow optional dependency: only the physically based renders need it

    mi.set_variant(VARIANT)
    camera, pose = pbr_camera(scene, geom)
    truth = pbr_truth(scene, geom, camera, pose)
    margin = _distortion_margin(camera)
    sc = mi.load_dict(scene_dict(mi, scene, geom, camera, pose, margin))
    t0 = time.perf_counter()
    linear = np.array(mi.render(sc, seed=scene.seed, spp=scene.spp), dtype=np.float32)[..., :3]
    seconds = time.perf_counter() - t0
    if margin:
        linear = distort_image(linear, camera, margin)
    photo = camera_response(linear, scene, np.random.default_rng(scene.seed))
    encoded = None
    if scene.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", photo, [cv2.IMWRITE_JPEG_QUALITY, int(scene.jpeg_quality)])
        encoded = buf.tobytes()
        photo = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return PbrRender(photo, encoded, truth, seconds)


def render_markers(camera: CameraModel, points, *, radius: float = 0.05e-3, spp: int = 16) -> np.ndarray:
    """Render small emitting disks at plane points (P, 3) [m], each facing the camera: linear gray (H, W).

    A disk parallel to the image plane images to a circle centred on its
    centre's projection, so the intensity centroid of each blob checks that
    Mitsuba's sensor and :class:`CameraModel` project alike (distortion
    included, through :func:`distort_image`).
    """
    import mitsuba as mi  # slow optional dependency: only the physically based renders need it

    mi.set_variant(VARIANT)
    C, fwd, up = _camera_frame(camera)
    margin = _distortion_margin(camera)
    T = mi.ScalarTransform4f()
    d = {"type": "scene", "integrator": {"type": "direct", "hide_emitters": False},
         "sensor": _sensor(mi, PbrScene("markers", "markers", (), spp=spp), camera, margin)}
    for k, p in enumerate(np.asarray(points, float) / MM):
        d[f"m{k}"] = {"type": "disk", "to_world": T.look_at(origin=p.tolist(), target=(p - fwd).tolist(),
                                                            up=up.tolist()) @ T.scale(radius / MM),
                      "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}}}
    img = np.array(mi.render(mi.load_dict(d), seed=0, spp=spp), dtype=np.float32)[..., :3]
    if margin:
        img = distort_image(img, camera, margin)
    return img.mean(axis=2)


@dataclass(frozen=True)
class PbrScore:
    """A detection scored against a gallery scene's truth.

    Attributes
    ----------
    ok : int
        Corners the image shows that were reported ``ok`` with their own number.
    present : int
        Corners the image shows.
    wrong : int
        Points reported ``ok`` that lie nearer another point's true corner than their own
        (a wrong identity: the guarantee is that there are none).
    invented : int
        Points reported ``ok`` whose corner the image does not show.
    located : int
        Corners the image shows that were located within ``located_px`` of the truth but withheld
        (a status other than ``ok``, the position kept).
    errors_px : ndarray (ok,)
        Distance of each ok corner from the truth [px].
    z : ndarray (2 ok,)
        Each coordinate's error over its reported σ.
    px_per_mm : float
    """

    ok: int
    present: int
    wrong: int
    invented: int
    located: int
    errors_px: np.ndarray
    z: np.ndarray
    px_per_mm: float

    @property
    def errors_mm(self) -> np.ndarray:
        return self.errors_px / self.px_per_mm

    def __str__(self) -> str:
        e = self.errors_mm
        rms = float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan
        return (f"{self.ok}/{self.present} corners ok, {self.wrong} wrong identities, {self.invented} invented, "
                f"{self.located} located but withheld, rms {rms:.4f} mm")


def score_detection(det, truth: PbrTruth, px_per_mm: float, *, wrong_px: float = 3.0,
                    located_px: float = 5.0) -> PbrScore:
    """Score a :class:`~notchfit.vision.detection.Detection` against ``truth``.

    An ok point is a wrong identity when it is farther than ``wrong_px`` from
    its own true corner and nearer to another's (two corners of a closed slot
    mouth a pixel apart do not count a small error as a wrong number). σ is
    converted to pixels with the detection's own scale, so calibrated and
    uncalibrated detections score alike.
    """
    okm = np.array([s == "ok" for s in det.status])
    found = np.asarray(det.points_px, float)
    true = truth.points_px
    d = np.linalg.norm(found[:, None, :] - true[None, :, :], axis=2)
    d = np.where(np.isfinite(d), d, np.inf)
    own = np.arange(len(true))
    d_own = d[own, own]
    d_other = np.where(np.eye(len(true), dtype=bool), np.inf, d).min(axis=1)
    wrong = okm & (d_own > wrong_px) & (d_other < d_own)
    good = okm & ~wrong & truth.visible
    err = d_own[good]
    sig_px = np.asarray(det.sigma, float)[good] / (det.scale_mm_per_px * MM)
    z = ((found[good] - true[good]) / sig_px[:, None]).ravel()
    located = ~okm & truth.visible & (d_own <= located_px)
    return PbrScore(int(good.sum()), int(truth.visible.sum()), int(wrong.sum()),
                    int((okm & ~wrong & ~truth.visible).sum()), int(located.sum()), err, z, float(px_per_mm))
