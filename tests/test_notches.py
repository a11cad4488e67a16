"""The notch-point projector (Sec. IV-A, geometry.md) and the plane transform."""
import numpy as np
import pytest

from notchfit.physics import kinematics as K
from notchfit.physics.geometry import notch_layout
from notchfit.physics.notches import (from_plane, notch_points, notch_points_and_jacobian, plane_params_jacobian,
                                     point_projector, points_kernel, to_plane)


def _poe_points(theta, geom):
    """Oracle: every point through the general SE(3) link frames."""
    g = K.link_frames(theta, geom)
    lay = notch_layout(geom)
    out = []
    for link, loc in zip(lay.link, lay.local):
        v = g[link] @ np.array([loc[0], 0.0, loc[1] - (0.0 if link else 0.0), 1.0])
        out.append(v[[0, 2]])
    return np.array(out)


def test_straight_configuration(geom):
    np.testing.assert_allclose(notch_points(np.zeros(27), geom), notch_layout(geom).straight,
                               atol=1e-15)


def test_projector_equals_poe(geom, geom5, rng):
    for g in (geom, geom5):
        th = rng.uniform(-0.14, 0.14, g.n_joints)
        np.testing.assert_allclose(notch_points(th, g), _poe_points(th, g), atol=1e-12)


def test_jacobian_fd(geom, geom5, rng):
    for g in (geom, geom5):
        th = rng.uniform(-0.14, 0.14, g.n_joints)
        pts, J = notch_points_and_jacobian(th, g)
        h = 1e-7
        fd = np.stack([(notch_points(th + h * e, g) - notch_points(th - h * e, g)) / (2 * h)
                       for e in np.eye(g.n_joints)], axis=-1)
        np.testing.assert_allclose(J, fd, atol=1e-9)
        assert J.reshape(-1, g.n_joints).shape == (2 * g.n_points, g.n_joints)


def test_vectorized(geom, rng):
    th = rng.uniform(-0.14, 0.14, (7, 2, 27))
    pts, J = notch_points_and_jacobian(th, geom)
    assert pts.shape == (7, 2, 58, 2) and J.shape == (7, 2, 58, 2, 27)
    p1, J1 = notch_points_and_jacobian(th[3, 1], geom)
    np.testing.assert_allclose(pts[3, 1], p1)
    np.testing.assert_allclose(J[3, 1], J1)


def _gap(pts, lay, j):
    idx = np.flatnonzero(lay.joint == j)
    return np.linalg.norm(pts[idx[0]] - pts[idx[1]])


def test_slot_gap_closes_on_concave_side(geom):
    lay = notch_layout(geom)
    th = np.full(27, 0.1)  # bends toward +x: the right side is concave
    pts = notch_points(th, geom)
    w = geom.slot_width
    assert _gap(pts, lay, 2) < 0.5 * w      # right slot (even joint) closes
    assert _gap(pts, lay, 3) > 1.5 * w      # left slot (odd joint) opens
    # at the closure angle the right slot's outer corners meet
    pts_c = notch_points(np.full(27, geom.closure_angle), geom)
    assert _gap(pts_c, lay, 2) < 1e-12


def test_mirror_symmetry(geom, rng):
    """θ -> -θ mirrors x; the mirrored point set is the same outline renumbered."""
    th = rng.uniform(-0.14, 0.14, 27)
    a, b = notch_points(th, geom), notch_points(-th, geom)
    # the chain (joint positions) mirrors exactly
    qa, qb = K.joint_positions(th, geom.p), K.joint_positions(-th, geom.p)
    np.testing.assert_allclose(qa[:, 0], -qb[:, 0], atol=1e-15)
    np.testing.assert_allclose(qa[:, 1], qb[:, 1], atol=1e-15)
    # tip corners swap sides: point 29 (right) of θ mirrors point 30 (left) of -θ
    np.testing.assert_allclose(a[28] * [-1, 1], b[29], atol=1e-15)


def test_plane_transform_roundtrip_and_jacobian(geom, rng):
    pts = notch_points(rng.uniform(-0.1, 0.1, 27), geom)
    for mirror in (False, True):
        tx, ty, phi = 0.01, -0.02, 0.3
        P = to_plane(pts, tx, ty, phi, mirror)
        np.testing.assert_allclose(from_plane(P, tx, ty, phi, mirror), pts, atol=1e-15)
        # rigid: distances preserved
        np.testing.assert_allclose(np.linalg.norm(P[0] - P[30]), np.linalg.norm(pts[0] - pts[30]))
        J = plane_params_jacobian(pts, phi, mirror)
        h = 1e-7
        for k, d in enumerate(np.eye(3) * h):
            fd = (to_plane(pts, tx + d[0], ty + d[1], phi + d[2], mirror)
                  - to_plane(pts, tx - d[0], ty - d[1], phi - d[2], mirror)) / (2 * h)
            np.testing.assert_allclose(J[..., k], fd, atol=1e-9)
    # the mirror flips the orientation (determinant -1)
    e = np.array([[1.0, 0], [0, 1.0], [0, 0]])
    Pm = to_plane(e, 0, 0, 0, True)
    assert np.linalg.det(Pm[:2]) == pytest.approx(-1.0)


@pytest.mark.parametrize("bad", [np.zeros((3, 26)), np.array([np.nan] * 27)])
def test_bad_input(geom, bad):
    with pytest.raises(ValueError, match="joint angles"):
        notch_points(bad, geom)


def test_public_points_kernel_with_the_callers_work_arrays_equals_the_projector(geom, geom5, rng):
    """``points_kernel`` (the compiled API, its work arrays the caller's) computes what the projector
    and :func:`notch_points` compute, and leaves the chain in the work arrays (``s, c`` of the link angles)."""
    for g in (geom, geom5):
        proj = point_projector(g)
        for theta in rng.uniform(-0.15, 0.15, (4, g.n_joints)):
            s, c, ox, oz, dd = proj.work()
            out = np.empty((g.n_points, 2))
            points_kernel(theta, proj.per_joint, proj.link, proj.lx, proj.lz, s, c, ox, oz, dd, out)
            np.testing.assert_array_equal(out, proj(theta))
            assert np.abs(out - notch_points(theta, g)).max() <= 1e-15
            phi = np.r_[0.0, np.cumsum(theta)]
            np.testing.assert_allclose(s, np.sin(phi), atol=1e-15)
            np.testing.assert_allclose(c, np.cos(phi), atol=1e-15)
