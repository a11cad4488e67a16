"""Seeded random lab scenes: many renderers' recipes, not one (issue 15).

A detector tuned to one scene fails on the next photograph. :func:`draw_scene`
draws everything a lab photograph varies in, from a seeded generator: the
holder (a chuck as dark as the tube, a chuck whose jaws are as dark or
brighter, a collet, a clamp, none), a plain length of tube before the first
slot, either polarity, the tube's and holder's levels, cylinder shading, a
specular streak, highlights, a backdrop lit unevenly (a ramp, a hot spot,
vignetting), the lens's perspective (a working distance of 150-500 mm) and a
tilt of the tube out of the plane (up to ``max_tilt_deg``), Gaussian blur,
defocus and motion blur, ISO 100-3200 sensor noise, in-camera sharpening,
JPEG quality 75-95, any in-plane angle, and the joint angles from a little
past straight to just short of each slot's closure (one common bend, random
per joint, or every joint near closure), for any of the given geometries
(per-notch dimensions included). :func:`score` compares a detection with
the exact ground truth.

Lengths that are physical (blur, defocus and motion in px) are given at
130 px/mm (a DSLR at about 0.6x) and scaled with ``px_per_mm``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...physics.geometry import Geometry, notch_layout
from ...physics.notches import notch_points, to_plane
from .scenes import RenderedScene, Scene, render_scene, scene_camera
from . import pivot_closure_angles

__all__ = ["KINDS", "SceneDraw", "draw_scene", "render_draw", "score"]

#: holder kinds drawn, with their weights
KINDS = {"chuck": 3, "jaws as dark as the tube": 2, "jaws brighter than the tube": 2, "collet": 1, "clamp": 1,
         "no holder": 1}
REF_PX_PER_MM = 130.0


@dataclass(frozen=True)
class SceneDraw:
    """One drawn scene: what to render and the labels to group results by.

    Attributes
    ----------
    kind : str
        Holder kind (a key of :data:`KINDS`).
    geom : Geometry
    theta : ndarray (n,) [rad]
    camera : CameraModel
    plane : (tx, ty, phi, mirror)
    scene : Scene
    labels : dict
        Drawn values worth grouping by (``polarity``, ``tilt_deg``,
        ``closure`` = the largest θ_j over its closure angle, ``streak``, ...).
    """

    kind: str
    geom: Geometry
    theta: np.ndarray
    camera: object
    plane: tuple
    scene: Scene
    labels: dict


def _bend(rng, geom: Geometry, max_closure: float, max_total: float, holder_half_width: float) -> np.ndarray:
    """Joint angles between a little past straight (against the slots) and ``max_closure`` of each
    slot's closure: one common fraction, a random one per joint, or every joint near closure; scaled
    down until the whole bend is at most ``max_total`` [rad] and the corners of links 2 and beyond
    stay 2.5 slot widths clear of the holder (a band ``holder_half_width`` wide below the base edge:
    a tube curled back onto its holder is not a scene one photographs)."""
    lo, hi = geom.rest_angles, pivot_closure_angles(geom) * geom.sides * max_closure
    how = rng.integers(3)
    if how == 0:
        f = np.full(geom.n_joints, rng.uniform(-0.2, 1.0))
    elif how == 1:
        f = rng.uniform(-0.2, 1.0, geom.n_joints)
    else:
        f = rng.uniform(0.85, 1.0, geom.n_joints)
    th = lo + f * (hi - lo)
    th *= min(1.0, max_total / max(abs(float(th.sum())), 1e-12))
    far = notch_layout(geom).link >= 2
    for _ in range(50):
        q = notch_points(th, geom)[far]
        gap = np.hypot(np.maximum(np.abs(q[:, 0]) - holder_half_width, 0), np.maximum(q[:, 1] - geom.base_edge_z, 0))
        if gap.min() >= 2.5 * float(geom.slot_widths.max()):
            break
        th *= 0.9
    return th


def _levels(rng, kind: str) -> dict:
    """Background, tube, holder and jaw levels [DN]; a polished tube on a dark background one time in five."""
    bg, tube = rng.uniform(120, 210), rng.uniform(15, 70)
    dark_bg = kind != "jaws brighter than the tube" and rng.uniform() < 0.2
    if dark_bg:
        bg, tube = rng.uniform(15, 50), rng.uniform(150, 230)
    holder = tube + rng.uniform(0.0, 0.3) * (bg - tube)
    out = dict(background=bg, tube_level=tube, holder_level=holder)
    if kind.startswith("jaws"):
        frac = rng.uniform(0.0, 0.15) if kind == "jaws as dark as the tube" else rng.uniform(0.3, 0.6)
        out["jaw_level"] = tube + frac * (bg - tube)
    return out


def _scene(rng, kind: str, geom: Geometry, px_per_mm: float, max_tilt_deg: float) -> Scene:
    k = px_per_mm / REF_PX_PER_MM
    R = geom.outer_radius
    holder = {"chuck": "chuck", "collet": "collet", "clamp": "clamp", "no holder": "none"}.get(kind, "jaws")
    streak = rng.uniform() < 0.6
    return Scene(
        holder=holder, solid=True, **_levels(rng, kind),
        plain_length=0.0 if holder in ("none", "collet") or rng.uniform() < 0.6 else rng.uniform(0.3e-3, 2e-3),
        holder_half_width=rng.uniform(2.5e-3, 6e-3), jaw_half_width=rng.uniform(1.5, 3.0) * R,
        shading=rng.uniform(0.0, 0.4), streak=rng.uniform(0.3, 1.3) if streak else 0.0,
        streak_pos=rng.uniform(-0.5, 0.5), streak_width=rng.uniform(0.04, 0.12), highlights=rng.uniform(0, 0.5),
        illumination=rng.uniform(0, 0.2), texture=rng.uniform(0, 0.05), vignetting=rng.uniform(0, 0.4),
        gradient=rng.uniform(0, 0.4), blur_sigma=k * rng.uniform(0.8, 2.5),
        defocus_px=k * rng.uniform(1.0, 3.0) if rng.uniform() < 0.3 else 0.0,
        motion_px=k * rng.uniform(1.0, 4.0) if rng.uniform() < 0.3 else 0.0, motion_deg=rng.uniform(0, 180),
        iso=float(np.exp(rng.uniform(np.log(100), np.log(3200)))), sharpen=rng.uniform(0, 0.8),
        jpeg_quality=int(rng.integers(75, 96)),
        tilt_deg=rng.uniform(0, max_tilt_deg), tilt_axis_deg=rng.uniform(0, 180))


def _fits(cam, plane, theta, geom, size, margin_px) -> bool:
    """Every notch point and the tip lie ``margin_px`` inside the image."""
    uv = cam.plane_to_pixel(to_plane(notch_points(theta, geom), *plane))
    W, H = size
    return bool(np.all((uv >= margin_px) & (uv <= np.array([W - 1, H - 1]) - margin_px)))


def draw_scene(rng, geometries, *, size=(960, 640), px_per_mm: float = 50.0, max_tilt_deg: float = 4.0,
               max_closure: float = 0.98, max_total_bend: float = 2.6, kinds=None,
               max_tries: int = 50) -> SceneDraw:
    """Draw one lab scene (see the module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
    geometries : sequence of Geometry
        One is drawn per scene.
    size : (W, H) [px]
    px_per_mm : float
        Scale in the plane [px/mm].
    max_tilt_deg : float
        Largest tilt of the tube out of the plane [deg].
    max_closure : float
        Largest joint angle as a fraction of its slot's closure angle.
    max_total_bend : float
        Largest sum of the joint angles [rad] (a tube curled further would
        run into its holder or itself).
    kinds : sequence of str, optional
        Holder kinds to draw from (default all of :data:`KINDS`, weighted).
    max_tries : int
        Placements tried before giving up (the tube must fit in the image).

    Returns
    -------
    SceneDraw
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError("pass a seeded numpy.random.Generator as rng")
    names = list(kinds) if kinds is not None else list(KINDS)
    wts = np.array([KINDS[k] for k in names], float)
    kind = names[int(rng.choice(len(names), p=wts / wts.sum()))]
    geom = geometries[int(rng.integers(len(geometries)))]
    scene = _scene(rng, kind, geom, px_per_mm, max_tilt_deg)
    theta = _bend(rng, geom, max_closure, max_total_bend, scene.holder_half_width)
    focal = rng.uniform(150, 500) * px_per_mm                    # working distance 150-500 mm
    for _ in range(max_tries):
        angle = rng.uniform(0, 360)
        cam, plane = scene_camera(theta, geom, image_size=size, mm_per_px=1 / px_per_mm, angle_deg=angle,
                                  base_at=rng.uniform(0.03, 0.3), focal_px=focal)
        if _fits(cam, plane, theta, geom, size, margin_px=0.5 * geom.outer_radius * 1e3 * px_per_mm + 5):
            break
    else:
        raise ValueError(f"the tube does not fit a {size[0]}x{size[1]} image at {px_per_mm:g} px/mm")
    closure = float(np.max(geom.sides * theta / pivot_closure_angles(geom)))
    labels = {"polarity": "light on dark" if scene.background < scene.tube_level else "dark on light",
              "tilt_deg": scene.tilt_deg, "closure": closure, "streak": scene.streak, "angle_deg": angle,
              "geometry": geom.name, "plain_length_mm": scene.plain_length * 1e3, "jpeg": scene.jpeg_quality,
              "iso": scene.iso, "defocus_px": scene.defocus_px, "motion_px": scene.motion_px}
    return SceneDraw(kind, geom, theta, cam, plane, scene, labels)


def render_draw(draw: SceneDraw, rng) -> RenderedScene:
    """Render a drawn scene (:func:`~notchfit.vision.render.scenes.render_scene`)."""
    return render_scene(draw.theta, draw.geom, draw.camera, plane=draw.plane, scene=draw.scene, rng=rng)


def score(det, rendered: RenderedScene, px_per_mm: float) -> dict:
    """A detection against the ground truth.

    Returns
    -------
    dict with ``found`` (real corners reported ok), ``corners`` (real corners
    in the image), ``invented`` (points reported ok that are not real
    corners), ``errors_mm`` (ndarray: error of every ok real corner [mm]).
    """
    ok = np.array([s == "ok" for s in det.status])
    vis = np.asarray(rendered.visible, bool)
    err = np.linalg.norm(det.points_px[ok & vis] - rendered.points_px[ok & vis], axis=1) / px_per_mm
    return {"found": int((ok & vis).sum()), "corners": int(vis.sum()), "invented": int((ok & ~vis).sum()),
            "errors_mm": err}
