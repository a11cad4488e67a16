"""Synthetic renderer: exact ground truth and unbiased edges (issue 6; opencv-and-rendering.md)."""

import numpy as np
import pytest

from notchfit.physics.notches import notch_points, to_plane
from notchfit.vision.render import camera_for_shapes, manipulator_outline, polygon_coverage, render_manipulator


def _shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_polygon_coverage_area_is_exact(rng):
    """Coverage sums to the polygon area (no edge bias; fillPoly is +0.13..0.69 px off per the notes)."""
    for _ in range(5):
        ang = np.sort(rng.uniform(0, 2 * np.pi, 12))
        rad = rng.uniform(8, 20, 12)
        poly = np.column_stack([30 + rad * np.cos(ang), 28 + rad * np.sin(ang)])
        cov = polygon_coverage([poly], (60, 64), supersample=16)
        assert cov.sum() == pytest.approx(_shoelace(poly), abs=0.05)


def test_polygon_coverage_edge_position():
    """A vertical edge at u = 10.3 covers column 10 by exactly 0.2 ([10.3, 10.5]) (pixel = [c - 0.5, c + 0.5])."""
    sq = np.array([[10.3, 2.0], [30.0, 2.0], [30.0, 20.0], [10.3, 20.0]])
    cov = polygon_coverage([sq], (24, 40), supersample=4)
    assert np.allclose(cov[5:15, 10], 0.2) and np.allclose(cov[5:15, 9], 0.0) and np.allclose(cov[5:15, 12], 1.0)
    # a horizontal edge at v = 2.0: the row's sub-row centres decide (S = 4: 2 of 4 inside)
    assert np.allclose(cov[2, 15], 0.5)


def test_outline_vertices_contain_the_notch_points(geom):
    """geometry.md: every numbered notch point is a vertex of the silhouette."""
    for th in (np.zeros(geom.n_joints), np.full(geom.n_joints, 0.13), np.full(geom.n_joints, -0.13)):
        outl = manipulator_outline(th, geom)
        pts = notch_points(th, geom)
        d = np.min(np.linalg.norm(outl[None] - pts[:, None], axis=2), axis=1)
        assert d.max() < 1e-12
        assert _shoelace(outl) > 0
    with pytest.raises(ValueError, match="slot-closure"):
        manipulator_outline(np.full(geom.n_joints, 0.2), geom)


def test_straight_outline_area(geom):
    """Straight tube: area = band + mount - slots (closed form)."""
    th = np.zeros(geom.n_joints)
    outl = manipulator_outline(th, geom)
    R, w, d = geom.outer_radius, geom.slot_width, geom.slot_depth
    band = 2 * R * (geom.tip_z - geom.base_edge_z)
    mount = 2 * geom.mount_half_width * (geom.base_edge_z - geom.mount_bottom_z)
    assert _shoelace(outl) == pytest.approx(band + mount - geom.n_joints * w * d, rel=1e-12)


@pytest.mark.parametrize("mirror", [False, True])
def test_render_returns_exact_ground_truth(geom, mirror):
    """The returned notch points are where the camera projects the true plane points."""
    th = np.linspace(-0.1, 0.12, geom.n_joints)
    cam, planes = camera_for_shapes([th], geom, mm_per_px=0.06, phi=0.3, mirror=mirror, margin_px=20)
    r = render_manipulator(th, geom, cam, plane=planes[0], rng=np.random.default_rng(1))
    truth = to_plane(notch_points(th, geom), *planes[0])
    assert np.allclose(r.points_plane, truth, atol=1e-15)
    assert np.allclose(r.points_px, cam.plane_to_pixel(truth), atol=1e-9)
    assert r.visible.all() and r.image.shape == (cam.image_size[1], cam.image_size[0])
    # the pixels at the projected points are edge pixels (between the two levels)
    vals = r.image[np.rint(r.points_px[:, 1]).astype(int), np.rint(r.points_px[:, 0]).astype(int)]
    assert np.all((vals > 50) & (vals < 195))


def test_rendered_silhouette_area_is_unbiased(geom):
    """No blur/noise: dark area [px] equals the projected outline's area, straight tube through a distorting lens."""
    th = np.zeros(geom.n_joints)
    cam, planes = camera_for_shapes([th], geom, mm_per_px=0.05, margin_px=15,
                                    dist=(-0.2, 0.1, 0.0, 0.0, 0.0))
    r = render_manipulator(th, geom, cam, plane=planes[0], rng=np.random.default_rng(0), blur_sigma=0.0,
                           noise=0.0, illumination=0.0, texture=0.0, dtype=np.float64, supersample=16)
    cov = (200.0 - r.image) / 160.0
    from notchfit.vision.render import _subdivide, outline_in_plane
    poly = cam.plane_to_pixel(_subdivide(outline_in_plane(th, geom, *planes[0]), 1e-6))
    perimeter = np.sum(np.linalg.norm(np.roll(poly, -1, 0) - poly, axis=1))
    # area error / perimeter = mean edge offset [px]
    assert abs(cov.sum() - _shoelace(poly)) / perimeter < 0.005


def test_noise_level_and_seed(geom):
    th = np.zeros(geom.n_joints)
    cam, planes = camera_for_shapes([th], geom, mm_per_px=0.06, margin_px=40)
    kw = dict(plane=planes[0], blur_sigma=1.0, noise=0.02, illumination=0.0, texture=0.0, dtype=np.float64)
    a = render_manipulator(th, geom, cam, rng=np.random.default_rng(5), **kw).image
    b = render_manipulator(th, geom, cam, rng=np.random.default_rng(5), **kw).image
    c = render_manipulator(th, geom, cam, rng=np.random.default_rng(6), **kw).image
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    corner = a[:20, :20]                                           # background only
    assert corner.std() == pytest.approx(0.02 * 160.0, rel=0.2)
    with pytest.raises(ValueError, match="seeded"):
        render_manipulator(th, geom, cam, rng=None, **kw)


def test_background_fields_match_their_direct_per_pixel_formulas():
    """The separable texture and illumination fields equal the per-pixel formulas."""
    from notchfit.vision.render import _illumination, _smooth_field

    H, W = 37, 53
    v, u = np.mgrid[0:H, 0:W].astype(float)
    r = np.random.default_rng(3)
    f = np.zeros((H, W))
    for _ in range(4):
        lam, ang, ph = r.uniform(150.0, 600.0), r.uniform(0, 2 * np.pi), r.uniform(0, 2 * np.pi)
        f += np.cos((np.cos(ang) * u + np.sin(ang) * v) * (2 * np.pi / lam) + ph)
    want = (f - f.mean()) / (f.max() - f.min())
    np.testing.assert_allclose(_smooth_field((H, W), np.random.default_rng(3)), want, atol=2e-6)

    r = np.random.default_rng(4)
    un, vn = u / (W - 1) - 0.5, v / (H - 1) - 0.5
    g = r.normal(size=2)
    cu, cv = r.uniform(-0.3, 0.3, size=2)
    f = g[0] * un + g[1] * vn + np.exp(-((un - cu) ** 2 + (vn - cv) ** 2) / 0.18)
    f = (f - f.min()) / (f.max() - f.min())
    np.testing.assert_allclose(_illumination((H, W), np.random.default_rng(4), 0.3), 0.85 + 0.3 * f, atol=2e-6)
