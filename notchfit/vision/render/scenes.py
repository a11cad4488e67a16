"""Renders of real lab scenes with exact ground truth (issue 15).

A real photograph of a notched tube differs from :func:`~notchfit.vision.render.render_manipulator`'s
scene in ways a detector must survive: the holder (a wide polished chuck
with shading and highlights, a collet, a clamp, or none: the tube enters
from the image border), a length of plain tube between the holder and the
first slot, the tube shaded as a cylinder with a specular streak along it,
a dark tube on a light background or a polished one on a dark background,
defocus, JPEG compression, 12-24 MP sizes and any in-plane orientation.

Ground truth stays exact: the tube and the holder are polygons in the
manipulator frame, projected through the camera and rasterised by the
unbiased scanline coverage (:func:`~notchfit.vision.render.polygon_coverage`), and
each pixel is ``bg (1 - c_t - c_h) + f_t c_t + f_h c_h`` where the tube and
holder levels ``f`` are smooth fields (shading, streaks): an edge stays
where its polygon puts it. The coverage is computed only in a box around
the tube and the holder's visible part; the rest of a large image is
background.

A base point (1, 2) is a visible corner only where the holder's face is at
the geometry's base edge; with a plain length of tube or no holder it is
not a corner, and ``visible`` says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..camera import CameraModel
from ...physics.geometry import Geometry
from ...physics.notches import from_plane, notch_points, to_plane
from . import (RenderedManipulator, _illumination, _link_frames, _smooth_field, _subdivide, manipulator_outline,
               polygon_coverage, union_coverage)
from .solid import SolidPose, limb_corners, piece_outlines

__all__ = ["RenderedScene", "Scene", "holder_outline", "render_scene", "scene_camera", "tube_outline"]

HOLDERS = ("mount", "chuck", "jaws", "collet", "clamp", "none")


@dataclass(frozen=True)
class Scene:
    """What the camera sees besides the tube's silhouette.

    Attributes
    ----------
    holder : str
        ``mount`` (the default geometry's band), ``chuck`` (a wide cylinder
        with chamfered face, shaded, with highlights), ``collet`` (a tapered
        nose), ``clamp`` (a block with an arm to the side) or ``none`` (the
        tube enters from the image border).
    plain_length : float
        Plain tube between the holder's face and the base edge [m] (0: the
        face is at the base edge and the base points are corners).
    holder_half_width : float or None
        Half width of a chuck, collet body or clamp block [m]; default 3 R.
    background, tube_level, holder_level : float
        Levels [DN] at the centre line (dark on light by default; swap for a
        polished tube on a dark background).
    shading : float
        Cylinder shading: the level falls (or rises, toward the background)
        by this fraction of ``tube_level - background`` at the limbs, as
        ``1 - shading (x/R)²``.
    streak : float
        Peak of a specular streak along the tube above the tube's level, as
        a fraction of ``|background - tube_level|`` (may exceed the background).
    streak_pos, streak_width : float
        Streak centre and Gaussian σ across the tube, in units of ``R``.
    highlights : float
        Peak of two bright bands along the holder, as a fraction of the contrast.
    blur_sigma, noise, illumination, texture : float
        As :func:`~notchfit.vision.render.render_manipulator` (defocus is a larger blur).
    jpeg_quality : int or None
        Compress with ``cv2.imencode`` at this quality.
    solid : bool
        Draw the tube as a solid (:mod:`notchfit.vision.render.solid`): the slot and
        tip faces are circles seen through the camera's perspective (a slot
        off the optical axis shows its face as a thin ellipse); the ground
        truth is where each face's circle meets the limb. False: the planar
        silhouette of geometry.md.
    tilt_deg, tilt_axis_deg : float
        Rotation of the tube out of the plane [deg] about an axis through the
        base-edge centre at this angle from ``x`` in the bending plane (0: the
        tip leaves the plane; 90: the bending plane turns about the base
        axis). Needs ``solid``.
    jaw_level, jaw_half_width : float
        ``holder="jaws"``: a chuck body with stepped jaws gripping the tube;
        the jaws' level [DN] (default the holder's: one silhouette; between
        the tube's and the background's: brighter jaws) and their half width
        at the face [m] (default 2.2 R).
    vignetting : float
        Light falloff toward the image corners: the image times
        ``1 - vignetting (r / r_corner)²``.
    gradient : float
        A linear ramp added across the image (a backdrop lit from one side),
        peak to peak as a fraction of the contrast, in a random direction.
    defocus_px, motion_px, motion_deg : float
        A disk blur of this radius [px] (defocus) and a linear motion blur of
        this length [px] at this angle, after the Gaussian ``blur_sigma``.
    iso : float or None
        Sensor noise of a DSLR at this ISO on the 8-bit scale: shot noise
        (``200 * 100 / iso`` electrons per DN) and read noise (``0.015 iso /
        100`` DN), instead of ``noise``.
    sharpen : float
        In-camera sharpening: an unsharp mask of this amount (radius 1 px).
    gamma : float
        Tone curve: the levels are output values; blur and noise act on the
        linear light ``(DN / 255) ** gamma`` (1: a linear camera).
    """

    holder: str = "chuck"
    plain_length: float = 0.0
    holder_half_width: float | None = None
    background: float = 170.0
    tube_level: float = 45.0
    holder_level: float = 60.0
    shading: float = 0.3
    streak: float = 0.0
    streak_pos: float = 0.2
    streak_width: float = 0.06
    highlights: float = 0.0
    blur_sigma: float = 1.0
    noise: float = 0.02
    illumination: float = 0.1
    texture: float = 0.03
    jpeg_quality: int | None = None
    extra: dict = field(default_factory=dict)
    solid: bool = False
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    jaw_level: float | None = None
    jaw_half_width: float | None = None
    vignetting: float = 0.0
    gradient: float = 0.0
    defocus_px: float = 0.0
    motion_px: float = 0.0
    motion_deg: float = 0.0
    iso: float | None = None
    sharpen: float = 0.0
    gamma: float = 1.0

    def __post_init__(self):
        if self.holder not in HOLDERS:
            raise ValueError(f"holder must be one of {HOLDERS}, got {self.holder!r}")
        if self.plain_length < 0:
            raise ValueError("plain_length must be >= 0")
        if self.tilt_deg and not self.solid:
            raise ValueError("a tilt out of the plane needs solid=True")
        if not self.gamma > 0:
            raise ValueError("gamma must be > 0")


@dataclass(frozen=True)
class RenderedScene(RenderedManipulator):
    """A rendered scene and its ground truth: :class:`~notchfit.vision.render.RenderedManipulator`'s
    fields, the camera and the scene.

    ``visible`` is False for points outside the image and for base points
    that are not corners (plain tube, no holder).
    """

    camera: CameraModel
    scene: Scene


def tube_outline(theta, geom: Geometry, base_z: float) -> np.ndarray:
    """The tube's silhouette (no mount) with its base edge at ``base_z`` (≤ the base edge) [m], (K, 2)."""
    poly = manipulator_outline(theta, geom, include_mount=False).copy()
    if base_z > geom.base_edge_z + 1e-12:
        raise ValueError("the tube's drawn base must not be above the geometry's base edge")
    poly[0, 1] = base_z
    poly[-1, 1] = base_z
    return poly


def holder_outline(scene: Scene, geom: Geometry, face_z: float, length: float = 0.2) -> np.ndarray | None:
    """The holder's silhouette below its face at ``face_z`` [m] (manipulator frame, (K, 2)), None for ``none``."""
    R = geom.outer_radius
    if scene.holder == "none":
        return None
    if scene.holder == "mount":
        if geom.mount_half_width is None:
            raise ValueError(f"holder 'mount' needs a geometry with a mount; {geom.name!r} has none")
        M = geom.mount_half_width
        return np.array([[-M, geom.mount_bottom_z], [M, geom.mount_bottom_z], [M, face_z], [-M, face_z]])
    Hh = scene.holder_half_width or 3.0 * R
    zb = face_z - length
    if scene.holder == "chuck":
        ch = 0.15 * Hh
        return np.array([[-Hh, zb], [Hh, zb], [Hh, face_z - ch], [Hh - ch, face_z], [-Hh + ch, face_z],
                         [-Hh, face_z - ch]])
    if scene.holder == "jaws":
        jl, j2 = jaw_length(geom), scene.jaw_half_width or 2.2 * R
        j1 = max(0.5 * (j2 + Hh), j2 + 0.5 * R)
        zj, zm = face_z - jl, face_z - 0.5 * jl
        return np.array([[-Hh, zb], [Hh, zb], [Hh, zj], [j1, zj], [j1, zm], [j2, zm], [j2, face_z],
                         [-j2, face_z], [-j2, zm], [-j1, zm], [-j1, zj], [-Hh, zj]])
    if scene.holder == "collet":
        nose, taper = 1.8 * R, 2.5 * R
        return np.array([[-Hh, zb], [Hh, zb], [Hh, face_z - taper], [nose, face_z], [-nose, face_z],
                         [-Hh, face_z - taper]])
    # clamp: a block below the face and a bar leaving to +x from its lower part
    blk, bar = 4.5 * R, 3.0 * R
    return np.array([[-Hh, face_z - blk], [length, face_z - blk], [length, face_z - blk + bar],
                     [Hh, face_z - blk + bar], [Hh, face_z], [-Hh, face_z]])


def jaw_length(geom: Geometry) -> float:
    """How far a chuck's jaws reach out of its body [m] (``holder="jaws"``): 3 R."""
    return 3.0 * geom.outer_radius


def scene_camera(theta, geom: Geometry, *, image_size=(1200, 900), mm_per_px: float = 1 / 130,
                 angle_deg: float = 90.0, base_at: float = 0.12, **synthetic_kw):
    """A fronto-parallel camera and a plane transform placing the tube's base near one image side.

    Parameters
    ----------
    image_size : (W, H)
    mm_per_px : float
    angle_deg : float
        Image direction from base to tip (0: +u, 90: +v, i.e. hanging down).
    base_at : float
        Where the base edge lands: this fraction of the way along the
        direction from the image's entry side.
    **synthetic_kw
        ``focal_px`` (default 4000) and ``dist`` (default none) of the pinhole
        camera, which looks at the plane's front: a view that is not mirrored.

    Returns
    -------
    camera : CameraModel, plane : (tx, ty, phi, mirror)
    """
    W, H = image_size
    f = float(synthetic_kw.get("focal_px", 4000.0))
    K = np.array([[f, 0.0, (W - 1) / 2.0], [0.0, f, (H - 1) / 2.0], [0.0, 0.0, 1.0]])
    # looking at the plane's front (+z toward the camera): plane x along +u, plane y up the image
    Rm = np.diag([1.0, -1.0, -1.0])
    tvec = np.array([0.0, 0.0, f * mm_per_px * 1e-3])
    cam = CameraModel(K, np.asarray(synthetic_kw.get("dist", np.zeros(5)), float), (W, H),
                      cv2.Rodrigues(Rm)[0].ravel(), tvec)
    a = math.radians(angle_deg)
    d_img = np.array([math.cos(a), math.sin(a)])
    # the plane direction that maps to d_img (the camera maps plane -> image by a similarity)
    c = np.array([(W - 1) / 2, (H - 1) / 2])
    p0, p1 = cam.pixel_to_plane(c), cam.pixel_to_plane(c + 100 * d_img)
    dp = (p1 - p0) / np.linalg.norm(p1 - p0)
    phi = math.atan2(-dp[0], dp[1])            # to_plane maps +z to (-sin phi, cos phi)
    half = 0.5 * abs(d_img[0] * W) + 0.5 * abs(d_img[1] * H)
    base_px = c - d_img * half * (1 - 2 * base_at)
    tb = cam.pixel_to_plane(base_px)
    # joint 1 lands a distance -base_edge_z beyond the base edge along +z
    t = tb - np.array([-math.sin(phi), math.cos(phi)]) * geom.base_edge_z
    return cam, (float(t[0]), float(t[1]), float(phi), False)


def _tube_levels(uv, theta, geom, cam, plane, scene: Scene):
    """Tube level at pixels uv (P, 2): cylinder shading across the nearest link plus the streak."""
    R = geom.outer_radius
    xz = from_plane(cam.pixel_to_plane(uv), *plane)
    phi, org, piv = _link_frames(np.asarray(theta, float), geom)
    n = geom.n_joints
    best_x = np.full(len(uv), np.inf)
    best_d = np.full(len(uv), np.inf)
    for link in range(n + 1):
        c, s = math.cos(phi[link]), math.sin(phi[link])
        dx, dz = xz[:, 0] - org[link, 0], xz[:, 1] - org[link, 1]
        x = c * dx - s * dz + piv[link, 0]
        lz = s * dx + c * dz + piv[link, 1]
        lo = -np.inf if link == 0 else piv[link, 1]
        hi = geom.tip_z if link == n else piv[link + 1, 1]
        out = np.maximum(lo - lz, 0) + np.maximum(lz - hi, 0)
        take = out < best_d
        best_d[take], best_x[take] = out[take], x[take]
    xr = np.clip(best_x / R, -1.0, 1.0)
    con = scene.tube_level - scene.background
    lev = scene.tube_level - scene.shading * con * xr ** 2
    if scene.streak:
        lev = lev + scene.streak * abs(con) * np.exp(-0.5 * ((xr - scene.streak_pos) / scene.streak_width) ** 2)
    return lev


def render_scene(theta, geom: Geometry, camera: CameraModel, *, plane, scene: Scene = Scene(), rng,
                 supersample: int = 16, max_segment_px: float = 0.5, margin: float = 2.0) -> RenderedScene:
    """Render the tube at joint angles ``θ`` in a real-looking scene (8-bit image).

    Parameters
    ----------
    theta : array_like (n,) [rad]
    geom : Geometry
    camera : CameraModel (with a plane pose)
    plane : (tx, ty, phi, mirror)
    scene : Scene
    rng : numpy.random.Generator
    supersample : int
        Sub-rows per pixel of the rasteriser.

    Returns
    -------
    RenderedScene
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError("pass a seeded numpy.random.Generator as rng")
    th = np.asarray(theta, float)
    W, H = camera.image_size
    scale = camera.plane_scale()
    reach = 1.5 * math.hypot(W, H) / scale                     # beyond every image border [m]
    face_z = geom.base_edge_z - (reach if scene.holder == "none" else scene.plain_length)
    pose = SolidPose(tuple(plane), math.radians(scene.tilt_deg), math.radians(scene.tilt_axis_deg))
    tube, holder = _outlines(th, geom, camera, pose, scene, face_z, reach, max_segment_px / scale)
    # coverage box: the tube's visible part and the holder near it, plus the blur margin
    pad = int(math.ceil(4 * scene.blur_sigma + scene.defocus_px + scene.motion_px)) + 3
    allp = np.concatenate(tube + ([holder] if holder is not None else []))
    allp = np.clip(allp, [-pad, -pad], [W - 1 + pad, H - 1 + pad])
    lo = np.maximum(np.floor(allp.min(0)) - pad, 0).astype(int)
    hi = np.minimum(np.ceil(allp.max(0)) + pad, [W - 1, H - 1]).astype(int)
    shape = (hi[1] - lo[1] + 1, hi[0] - lo[0] + 1)
    ct, ch = _coverages(tube, holder, shape, supersample, tuple(lo), solid=scene.solid)
    bg = np.float32(scene.background)
    img_box = np.full(shape, bg, np.float32)
    vv, uu = np.nonzero(ct > 0)
    if len(vv):
        lev = _tube_levels(np.stack([uu + lo[0], vv + lo[1]], 1).astype(float), th, geom, camera, plane, scene)
        img_box[vv, uu] += (lev.astype(np.float32) - bg) * ct[vv, uu]
    if ch.any():
        img_box += _holder_levels(ch, lo, camera, plane, scene, geom, face_z) * ch
    delta = np.zeros((H, W), np.float32)
    delta[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] = img_box - bg
    img = _form_scene(delta, rng=rng, scene=scene)
    pts_px = _truth(th, geom, camera, pose, scene, face_z)
    pts_plane = to_plane(notch_points(th, geom), *plane) if not scene.solid else camera.pixel_to_plane(pts_px)
    vis = (pts_px[:, 0] >= margin) & (pts_px[:, 0] <= W - 1 - margin) & \
          (pts_px[:, 1] >= margin) & (pts_px[:, 1] <= H - 1 - margin)
    if scene.holder == "none" or scene.plain_length > 0:
        vis[:2] = False              # no corner at the base edge
    return RenderedScene(img, pts_px, pts_plane, th.copy(), tuple(plane), vis, camera, scene)


def _outlines(th, geom, camera, pose, scene, face_z, reach, max_seg):
    """The tube (a list of polygons: its planar outline, or a solid's convex pieces) and the holder in pixels."""
    hold = holder_outline(scene, geom, face_z, reach)
    holder = None if hold is None else camera.plane_to_pixel(_subdivide(to_plane(hold, *pose.plane), max_seg))
    if scene.solid:
        base_z = face_z if scene.holder == "none" else face_z - 4 * geom.outer_radius   # on into the holder
        return piece_outlines(th, geom, camera, pose, base_z), holder
    q = _subdivide(to_plane(tube_outline(th, geom, face_z), *pose.plane), max_seg)
    return [camera.plane_to_pixel(q)], holder


def _coverages(tube, holder, shape, supersample, offset, *, solid):
    """Coverage of the visible tube and of the holder (float32 each); a solid's tube is drawn behind the
    holder (the union's coverage minus the holder's), a planar one beside it."""
    ch = (np.zeros(shape) if holder is None else
          polygon_coverage([holder], shape, supersample=supersample, offset=offset))
    if solid:
        cu = union_coverage(tube + ([holder] if holder is not None else []), shape, supersample=supersample,
                            offset=offset)
        ct = np.clip(cu - ch, 0.0, 1.0)
    else:
        ct = polygon_coverage(tube, shape, supersample=supersample, offset=offset)
    return ct.astype(np.float32), ch.astype(np.float32)


def _truth(th, geom, camera, pose, scene, face_z):
    """Exact notch points in the image (m, 2) [px]: the planar silhouette's corners, or a solid's face
    corners (limb meets circle; at the base, the limb line meets the holder's face)."""
    if not scene.solid:
        return camera.plane_to_pixel(to_plane(notch_points(th, geom), *pose.plane))
    pts = limb_corners(th, geom, camera, pose)
    if scene.holder == "none":
        return pts
    far = limb_corners(th, geom, camera, pose, z_shift=geom.outer_radius)
    face = camera.plane_to_pixel(to_plane(np.array([[-1e-3, face_z], [1e-3, face_z]]), *pose.plane))
    for i in range(2):              # points 1, 2: base-left, base-right: pts + s (far - pts) on the face line
        A = np.stack([far[i] - pts[i], face[0] - face[1]], 1)
        pts[i] = pts[i] + np.linalg.solve(A, face[0] - pts[i])[0] * (far[i] - pts[i])
    return pts


def _holder_levels(ch, lo, camera, plane, scene, geom, face_z):
    """Holder level at the box pixels: cylinder shading across it and two highlight bands."""
    Hh = scene.holder_half_width or 3.0 * geom.outer_radius
    vv, uu = np.nonzero(ch > 0)
    out = np.zeros(ch.shape, np.float32)
    xz = from_plane(camera.pixel_to_plane(np.stack([uu + lo[0], vv + lo[1]], 1).astype(float)), *plane)
    xr = np.clip(xz[:, 0] / Hh, -1, 1)
    level = np.full(len(xr), scene.holder_level)
    if scene.holder == "jaws" and scene.jaw_level is not None:
        level[xz[:, 1] > face_z - jaw_length(geom)] = scene.jaw_level
    con = level - scene.background
    lev = level - scene.shading * con * xr ** 2
    if scene.highlights:
        for c0 in (-0.45, 0.35):
            lev = lev + scene.highlights * abs(con) * np.exp(-0.5 * ((xr - c0) / 0.08) ** 2)
    out[vv, uu] = lev - scene.background
    return out


def _disk_kernel(radius: float, sub: int = 8) -> np.ndarray:
    """A normalised disk (pillbox) of ``radius`` [px], each tap its covered fraction (``sub``² samples)."""
    n = int(math.ceil(radius))
    t = (np.arange((2 * n + 1) * sub) + 0.5) / sub - n - 0.5
    inside = (t[None, :] ** 2 + t[:, None] ** 2 <= radius * radius).astype(np.float32)
    k = inside.reshape(2 * n + 1, sub, 2 * n + 1, sub).mean(axis=(1, 3))
    return k / k.sum()


def _line_kernel(length: float, angle_deg: float, sub: int = 16) -> np.ndarray:
    """A normalised straight motion blur of ``length`` [px] at ``angle_deg`` (bilinear splats)."""
    n = int(math.ceil(length / 2)) + 1
    k = np.zeros((2 * n + 1, 2 * n + 1), np.float64)
    s = (np.arange(int(length * sub) + 1) / max(int(length * sub), 1) - 0.5) * length
    a = math.radians(angle_deg)
    x, y = n + s * math.cos(a), n + s * math.sin(a)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, wgt in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        np.add.at(k, (y0 + dy, x0 + dx), wgt)
    return (k / k.sum()).astype(np.float32)


def _optics(img, scene: Scene):
    """Gaussian blur, defocus (disk) and motion (line), in linear light when the camera has a tone curve."""
    lin = scene.gamma != 1.0
    if lin:
        img = np.power(np.clip(img, 0, 255) / np.float32(255), np.float32(scene.gamma))
    if scene.blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigmaX=float(scene.blur_sigma), borderType=cv2.BORDER_REFLECT)
    if scene.defocus_px > 0:
        img = cv2.filter2D(img, -1, _disk_kernel(scene.defocus_px), borderType=cv2.BORDER_REFLECT)
    if scene.motion_px > 0:
        img = cv2.filter2D(img, -1, _line_kernel(scene.motion_px, scene.motion_deg), borderType=cv2.BORDER_REFLECT)
    if lin:
        img = np.float32(255) * np.power(np.maximum(img, 0), np.float32(1 / scene.gamma))
    return img


def _lighting(img, rng, scene: Scene, contrast):
    """A linear ramp across the image (random direction) and vignetting, in place."""
    H, W = img.shape
    u = (np.arange(W, dtype=np.float32) - (W - 1) / 2) / np.float32(max(W, H) / 2)
    v = (np.arange(H, dtype=np.float32) - (H - 1) / 2) / np.float32(max(W, H) / 2)
    if scene.gradient:
        a = rng.uniform(0, 2 * math.pi)
        ru, rv = math.cos(a) * u, math.sin(a) * v
        span = float(np.abs(ru).max() + np.abs(rv).max()) or 1.0
        img += np.float32(0.5 * scene.gradient * contrast / span) * (ru[None, :] + rv[:, None])
    if scene.vignetting:
        r2 = (u * u)[None, :] + (v * v)[:, None]
        img *= 1 - np.float32(scene.vignetting) * r2 / r2.max()
    return img


def _form_scene(delta, *, rng, scene: Scene):
    """background + delta -> texture, illumination, ramp, vignetting, optics, noise, sharpening, uint8, JPEG."""
    H, W = delta.shape
    contrast = abs(scene.background - scene.tube_level)
    img = delta + np.float32(scene.background)
    if scene.texture > 0:
        img += np.float32(scene.texture * contrast) * _smooth_field((H, W), rng)
    if scene.illumination > 0:
        img *= _illumination((H, W), rng, scene.illumination)
    img = _optics(_lighting(img, rng, scene, contrast), scene)
    if scene.iso is not None:
        e_per_dn, read = 200.0 * 100.0 / scene.iso, 0.015 * scene.iso / 100.0
        sd = np.sqrt(np.maximum(img, 0) / np.float32(e_per_dn) + np.float32(read * read))
        img += rng.standard_normal(size=(H, W), dtype=np.float32) * sd
    elif scene.noise > 0:
        img += rng.normal(0.0, scene.noise * contrast, size=(H, W)).astype(np.float32)
    if scene.sharpen > 0:
        img += np.float32(scene.sharpen) * (img - cv2.GaussianBlur(img, (0, 0), 1.0, borderType=cv2.BORDER_REFLECT))
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if scene.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(scene.jpeg_quality)])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out
