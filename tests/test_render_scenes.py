"""Renders of real lab scenes (issue 15): exact ground truth, unbiased edges, placement."""

import numpy as np
import pytest

from notchfit.geometry import Geometry
from notchfit.notches import notch_points, to_plane
from notchfit.render.scenes import Scene, holder_outline, render_scene, scene_camera, tube_outline
from notchfit.polygon import polygon_area
from notchfit.render import polygon_coverage

WRIST = Geometry(n_joints=5, p=1.6e-3, outer_radius=0.81e-3, slot_width=0.8e-3, slot_depth=1.3e-3,
                 slot_sides=(1,) * 5, mount_half_width=2.5e-3, name="wrist", inner_radius=0.7e-3,
                 tendons=("right",), tendon_path="lumen", r_x=None, r_z=None, cable_radius=None, channel_radius=None)
TH = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
FLAT = dict(shading=0.0, streak=0.0, blur_sigma=0.0, noise=0.0, illumination=0.0, texture=0.0)


@pytest.mark.parametrize("angle", [90.0, 0.0, 215.0])
def test_ground_truth_is_the_projection_and_the_base_is_where_stated(angle):
    cam, plane = scene_camera(TH, WRIST, image_size=(500, 400), mm_per_px=1 / 30, angle_deg=angle)
    r = render_scene(TH, WRIST, cam, plane=plane, scene=Scene(holder="chuck"), rng=np.random.default_rng(1))
    truth = to_plane(notch_points(TH, WRIST), *plane)
    np.testing.assert_allclose(r.points_plane, truth, atol=1e-15)
    np.testing.assert_allclose(r.points_px, cam.plane_to_pixel(truth), atol=1e-9)
    assert r.visible.all() and r.image.dtype == np.uint8 and r.image.shape == (400, 500)
    # base edge midpoint toward the entry side, the tip away from it
    d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))])
    base_mid = r.points_px[:2].mean(0)
    assert np.dot(r.points_px[2:].mean(0) - base_mid, d) > 0


def test_coverage_is_exact_without_blur():
    """Dark area [px] = tube + holder polygon areas inside the image (no edge bias), flat levels."""
    cam, plane = scene_camera(TH, WRIST, image_size=(500, 400), mm_per_px=1 / 40, angle_deg=90.0)
    sc = Scene(holder="collet", plain_length=0.4e-3, background=200.0, tube_level=40.0, holder_level=40.0, **FLAT)
    r = render_scene(TH, WRIST, cam, plane=plane, scene=sc, rng=np.random.default_rng(0))
    cov = (200.0 - r.image.astype(float)) / 160.0
    face = WRIST.base_edge_z - sc.plain_length
    tube = cam.plane_to_pixel(to_plane(tube_outline(TH, WRIST, face), *plane))
    hold = cam.plane_to_pixel(to_plane(holder_outline(sc, WRIST, face, length=0.05), *plane))
    # the image holds exactly the two polygons' coverage (the tube's is its area: it is inside the image)
    ct = polygon_coverage([tube], r.image.shape, supersample=16)
    ch = polygon_coverage([hold], r.image.shape, supersample=16)
    assert abs(ct.sum() - polygon_area(tube[:, 0], tube[:, 1])) < 0.05
    perimeter = np.sum(np.linalg.norm(np.roll(tube, -1, 0) - tube, axis=1))
    assert abs(cov.sum() - ct.sum() - ch.sum()) / perimeter < 0.01     # 8-bit rounding only
    assert np.abs(cov - ct - ch).max() < 0.5 / 160 + 1e-9


def test_base_points_are_corners_only_at_the_base_edge():
    cam, plane = scene_camera(TH, WRIST, image_size=(500, 400), mm_per_px=1 / 40)
    for kw, vis in ((dict(holder="chuck"), True), (dict(holder="chuck", plain_length=1e-3), False),
                    (dict(holder="none"), False)):
        r = render_scene(TH, WRIST, cam, plane=plane, scene=Scene(**kw), rng=np.random.default_rng(2))
        assert bool(r.visible[0]) is vis and bool(r.visible[1]) is vis and r.visible[2:].all()


def test_seeded_and_jpeg():
    cam, plane = scene_camera(TH, WRIST, image_size=(300, 300), mm_per_px=1 / 25)
    a = render_scene(TH, WRIST, cam, plane=plane, scene=Scene(jpeg_quality=70), rng=np.random.default_rng(5))
    b = render_scene(TH, WRIST, cam, plane=plane, scene=Scene(jpeg_quality=70), rng=np.random.default_rng(5))
    c = render_scene(TH, WRIST, cam, plane=plane, scene=Scene(), rng=np.random.default_rng(5))
    assert np.array_equal(a.image, b.image) and not np.array_equal(a.image, c.image)
    with pytest.raises(ValueError, match="holder"):
        Scene(holder="vice")
    with pytest.raises(ValueError, match="seeded"):
        render_scene(TH, WRIST, cam, plane=plane, rng=None)
