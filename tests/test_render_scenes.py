"""Renders of real lab scenes (issue 15): exact ground truth, unbiased edges, placement."""

import numpy as np
import pytest

from notchfit.physics.geometry import Geometry
from notchfit.physics.notches import notch_points, to_plane
from notchfit.vision.render.scenes import Scene, holder_outline, render_scene, scene_camera, tube_outline
from notchfit.polygon import polygon_area
from notchfit.vision.render import polygon_coverage

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


# ----------------------------------------------------------------------------- solid tube, variety
def test_union_coverage_is_exact_for_overlapping_and_oversized_polygons():
    """Two overlapping rectangles: the union's coverage is A + B - (A and B), pixel by pixel; a polygon
    reaching far beyond the output (a holder drawn to beyond the image) merges with the others row by row."""
    from notchfit.vision.render import union_coverage

    a = np.array([[10.3, 10.7], [40.2, 10.7], [40.2, 40.9], [10.3, 40.9]])
    b = a + [15.1, 9.3]
    cov = lambda *p: polygon_coverage(list(p), (70, 80), supersample=16)
    both = np.array([[25.4, 20.0], [40.2, 20.0], [40.2, 40.9], [25.4, 40.9]])          # a and b overlap here
    np.testing.assert_allclose(union_coverage([a, b], (70, 80), supersample=16), cov(a) + cov(b) - cov(both),
                               atol=1e-9)
    huge = np.array([[-5000.0, 30.2], [9000.0, 30.2], [9000.0, 9000.0], [-5000.0, 9000.0]])
    cut = np.array([[10.3, 30.2], [40.2, 30.2], [40.2, 40.9], [10.3, 40.9]])
    np.testing.assert_allclose(union_coverage([a, huge], (70, 80), supersample=16),
                               cov(a) + cov(huge) - cov(cut), atol=1e-9)


def test_solid_tube_seen_square_on_is_the_planar_silhouette():
    """Orthographic view, no tilt: the union of the solid's convex pieces covers exactly the planar
    outline of geometry.md (mitred flexures included), and each face corner is the notch point."""
    from notchfit.vision.render.solid import SolidPose, limb_corners, piece_outlines

    cam, plane = scene_camera(TH, WRIST, image_size=(600, 500), mm_per_px=1 / 40, angle_deg=70, focal_px=1e8)
    pose = SolidPose(plane)
    polys = piece_outlines(TH, WRIST, cam, pose, WRIST.base_edge_z)
    from notchfit.vision.render import union_coverage
    solid = union_coverage(polys, (500, 600), supersample=16)
    planar = polygon_coverage([cam.plane_to_pixel(to_plane(tube_outline(TH, WRIST, WRIST.base_edge_z), *plane))],
                              (500, 600), supersample=16)
    assert np.abs(solid - planar).max() < 1e-3
    np.testing.assert_allclose(limb_corners(TH, WRIST, cam, pose), cam.plane_to_pixel(to_plane(notch_points(TH, WRIST),
                                                                                               *plane)), atol=1e-6)


def test_tilted_solid_face_bulges_by_r_sin_tilt_and_its_corner_is_on_the_outline():
    """A straight tube tilted 5° about x, seen orthographically: each slot face's edge is an ellipse arc of
    semi-axis R sin 5° (the lower face's middle is R sin 5° above its corners), and the ground-truth
    corner (limb meets circle) is a vertex of the rendered outline."""
    from notchfit.vision.render.solid import SolidPose, limb_corners, piece_outlines

    th = np.zeros(WRIST.n_joints)
    mm = 1 / 40
    cam, plane = scene_camera(th, WRIST, image_size=(600, 500), mm_per_px=mm, angle_deg=90, focal_px=1e8)
    pose = SolidPose(plane, np.radians(5.0), 0.0)
    polys = piece_outlines(th, WRIST, cam, pose, WRIST.base_edge_z)
    truth = limb_corners(th, WRIST, cam, pose)
    verts = np.concatenate(polys)
    assert np.min(np.linalg.norm(verts[None] - truth[:, None], axis=2), axis=1).max() < 0.01
    # slot 1's lower face (point 3, the corner at x = R): on the tube's axis the outline of link 0 reaches
    # R sin 5 deg further into the slot than at the corner
    u_axis = 0.5 * (truth[0, 0] + truth[1, 0])
    link0 = polys[0]
    R_px = WRIST.outer_radius * 1e3 / mm
    top = link0[np.abs(link0[:, 0] - u_axis) < 0.5, 1].max()
    assert abs((top - truth[2, 1]) - R_px * np.sin(np.radians(5.0))) < 1e-3


def test_variety_draws_are_seeded_and_their_truth_exact():
    from notchfit.vision.render.variety import draw_scene, render_draw, score

    a = draw_scene(np.random.default_rng(3), [WRIST], size=(500, 400), px_per_mm=40)
    b = draw_scene(np.random.default_rng(3), [WRIST], size=(500, 400), px_per_mm=40)
    assert a.scene == b.scene and np.array_equal(a.theta, b.theta) and a.kind == b.kind
    ra, rb = render_draw(a, np.random.default_rng(4)), render_draw(b, np.random.default_rng(4))
    assert np.array_equal(ra.image, rb.image) and ra.visible[2:].all()
    assert a.labels["closure"] <= 0.98 + 1e-9 and a.scene.solid
    # a detection that reports exactly the truth scores perfectly
    from notchfit.vision.detection.result import Detection

    ok = ra.visible
    det = Detection(ra.points_plane, np.where(ok[:, None], ra.points_px, np.nan), np.zeros(len(ok)),
                    tuple("ok" if v else "occluded" for v in ok), "ok", "", np.zeros((0, 2)))
    s = score(det, ra, 40.0)
    assert s["found"] == s["corners"] == ok.sum() and s["invented"] == 0 and np.allclose(s["errors_mm"], 0)


def test_image_formation_noise_vignetting_and_kernels():
    """ISO noise: sigma^2 = level / (200 * 100 / ISO) + read^2 on a flat field; vignetting darkens the
    corners by the stated fraction; the defocus and motion kernels are normalised and as wide as stated."""
    from notchfit.vision.render.scenes import _disk_kernel, _form_scene, _line_kernel

    flat = np.zeros((400, 400), np.float32)
    sc = Scene(background=150.0, tube_level=50.0, texture=0.0, illumination=0.0, blur_sigma=0.0, iso=1600.0)
    img = _form_scene(flat, rng=np.random.default_rng(0), scene=sc).astype(float)
    expect = np.sqrt(150.0 / (200 * 100 / 1600.0) + (0.015 * 16) ** 2 + 1 / 12)      # + the rounding
    assert abs(img.std() / expect - 1) < 0.05
    sc = Scene(background=150.0, tube_level=50.0, texture=0.0, illumination=0.0, blur_sigma=0.0, noise=0.0,
               vignetting=0.3)
    img = _form_scene(flat, rng=np.random.default_rng(0), scene=sc).astype(float)
    assert abs(img[0, 0] / 150.0 - 0.7) < 0.01 and abs(img[199, 199] / 150.0 - 1.0) < 0.01
    k = _disk_kernel(3.0)
    assert abs(k.sum() - 1) < 1e-6 and abs((k > 0).sum() - np.pi * 9) < 12
    m = _line_kernel(6.0, 30.0)
    yy, xx = np.mgrid[0:m.shape[0], 0:m.shape[1]] - (m.shape[0] - 1) / 2
    along = xx * np.cos(np.radians(30)) + yy * np.sin(np.radians(30))
    assert abs(m.sum() - 1) < 1e-6 and abs(np.sqrt((m * along ** 2).sum()) - 6.0 / np.sqrt(12)) < 0.1
