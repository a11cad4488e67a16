"""The physically based renderer (notchfit.vision.render.pbr) against notchfit's own camera model and meshes.

The marker test checks that Mitsuba's perspective sensor and CameraModel project alike (the gallery's
ground truth rests on it); the slow test re-renders a committed gallery scene. Both need Mitsuba 3
(``pip install notchfit[pbr]``) and are skipped with that message without it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from notchfit.io import load_geometry, load_image
from notchfit.vision.render.pbr import PbrScene, PbrTruth, chuck_mesh, hull_mesh, pbr_camera, project, render_markers, render_pbr, sweep_mesh, tube_mesh
from notchfit.vision.render.solid import SolidPose

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"
WRIST = ROOT / "datasets" / "geometry" / "wrist_asymmetric.toml"


def _mitsuba():
    return pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed (pip install notchfit[pbr]): "
                                                 "the physically based renders are not checked")


def _volume(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b - a, c - a)).sum() / 6.0


def test_meshes_are_closed_outward_and_of_the_right_size():
    geom = load_geometry(WRIST)
    pose = SolidPose((0.0, 0.0, 0.3, False))
    th = np.full(geom.n_joints, 0.2)
    V, F = tube_mesh(th, geom, pose, geom.base_edge_z)
    # the pieces' volumes add up to the tube's: a cylinder from the base edge to the tip minus the slots
    R, d, w = geom.outer_radius, geom.slot_depths[0], geom.slot_widths[0]
    seg = R ** 2 * np.arccos((R - d) / R) - (R - d) * np.sqrt(R ** 2 - (R - d) ** 2)   # circle segment cut away
    full = np.pi * R ** 2 * (geom.tip_z - geom.base_edge_z) - geom.n_joints * w * seg
    assert _volume(V, F) == pytest.approx(full, rel=2e-3)     # faceted circles (720) and mitred backbones
    Vc, Fc = chuck_mesh(th, geom, pose, half_width=4e-3, length=5.06e-3, knurl_depth=0.0)   # 1 mm + 67 steps
    assert _volume(Vc, Fc) == pytest.approx(np.pi * 16e-6 * 5.02e-3, rel=2e-3)
    s = np.linspace(0, 1, 200)
    Vs, Fs = sweep_mesh(np.stack([np.cos(3 * s), np.sin(3 * s), s], 1) * 1e-3, 0.05e-3)
    assert _volume(Vs, Fs) > 0                                  # an open sweep: wound outward still
    Vh, Fh = hull_mesh(np.random.default_rng(0).normal(size=(50, 3)))
    assert _volume(Vh, Fh) > 0


@pytest.mark.parametrize("camera_kind", ["dslr", "phone"])
def test_mitsuba_sensor_projects_like_the_camera_model(camera_kind):
    """Rendered disk markers (facing the camera) sit where CameraModel projects their centres: < 0.5 px
    (measured: about 0.01 px without distortion, 0.05 px through the distortion resampling)."""
    _mitsuba()
    geom = load_geometry(WRIST)
    if camera_kind == "dslr":
        sc = PbrScene("m", "m", (0.1,) * 5, image_size=(240, 320), px_per_mm=80.0, focal_px=4800.0)
        radius = 0.04e-3
    else:
        sc = PbrScene("m", "m", (0.1,) * 5, image_size=(240, 300), px_per_mm=18.0, focal_px=260.0,
                      dist=(-0.06, 0.01, 0.0, 0.0, 0.0))
        radius = 0.15e-3
    cam, _ = pbr_camera(sc, geom)
    W, H = cam.image_size
    rng = np.random.default_rng(3)
    uv = rng.uniform([25, 25], [W - 26, H - 26], size=(12, 2))
    XY = cam.pixel_to_plane(uv)
    P = np.concatenate([XY, rng.uniform(-1e-3, 1e-3, (len(XY), 1))], axis=1)   # in front of and behind the plane
    img = render_markers(cam, P, radius=radius, spp=16)
    want = project(cam, P)
    vv, uu = np.mgrid[0:H, 0:W]
    err = []
    for u, v in want:
        m = (uu - u) ** 2 + (vv - v) ** 2 < 10 ** 2
        w = img * m
        err.append(np.hypot((w * uu).sum() / w.sum() - u, (w * vv).sum() / w.sum() - v))
    print(f"{camera_kind}: marker centroid against CameraModel, max {max(err):.3f} px, "
          f"rms {np.sqrt(np.mean(np.square(err))):.3f} px")
    assert max(err) < 0.5, err


@pytest.mark.slow
def test_rerendered_scene_matches_the_committed_one():
    """Re-render a committed gallery scene: same image (JPEG and Monte Carlo noise aside) and same truth."""
    _mitsuba()
    rec = json.loads((GALLERY / "chuck_b.json").read_text())
    scene = PbrScene.from_dict(rec["scene"])
    r = render_pbr(scene, load_geometry(ROOT / rec["geometry"]))
    committed = load_image(GALLERY / rec["image"]).astype(float)
    diff = np.abs(r.image.astype(float) - committed)
    print(f"re-rendered {rec['name']}: mean |difference| {diff.mean():.3f} DN, 99th percentile "
          f"{np.percentile(diff, 99):.1f} DN")
    assert diff.mean() < 0.5 and np.percentile(diff, 99) < 5
    t = PbrTruth.from_dict(rec)
    assert np.allclose(r.truth.points_px, t.points_px, atol=1e-6)
    assert (r.truth.visible == t.visible).all()
