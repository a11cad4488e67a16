"""The calibration-error point warp (data-format.md cause `calibration_error`)."""
import numpy as np
import pytest

from notchfit.vision.warp import apply_point_warp, point_warp_jacobian, unwarp_points


def test_identity_and_scale(rng):
    P = rng.uniform(-0.03, 0.03, (10, 58, 2))
    np.testing.assert_array_equal(apply_point_warp(P, 0.0, 0.0, [0.0, 0.0]), P)
    c = np.array([0.001, -0.002])
    np.testing.assert_allclose(apply_point_warp(P, 0.01, 0.0, c) - c, 1.01 * (P - c), atol=1e-16)


def test_roundtrip_and_nan(rng):
    P = rng.uniform(-0.03, 0.03, (5, 58, 2))
    P[0, 3] = np.nan
    c = np.array([0.004, 0.01])
    W = apply_point_warp(P, -0.008, 0.004, c)
    back = unwarp_points(W, -0.008, 0.004, c)
    np.testing.assert_allclose(back, P, atol=1e-14)
    assert np.isnan(back[0, 3]).all()


def test_jacobian_fd(rng):
    P = rng.uniform(-0.03, 0.03, (58, 2))
    x = np.array([0.01, 0.003, 0.002, -0.004])

    def f(v):
        return apply_point_warp(P, v[0], v[1], v[2:])

    J = point_warp_jacobian(P, x[0], x[1], x[2:])
    for k in range(4):
        h = np.zeros(4)
        h[k] = 1e-7
        np.testing.assert_allclose(J[..., k], (f(x + h) - f(x - h)) / 2e-7, atol=1e-8)


def test_bad_input():
    with pytest.raises(ValueError, match="center"):
        apply_point_warp(np.zeros((3, 2)), 0, 0, [0, 0, 0])


# --------------------------------------------------------------------------------------------
# a tilted bending plane seen in perspective (issue: camera-plane errors beyond an in-plane warp)
# --------------------------------------------------------------------------------------------
from notchfit.vision.warp import apply_camera_plane_warp, apply_plane_tilt, tilt_homography, unapply_plane_tilt, unwarp_camera_plane  # noqa: E402


def _opencv_tilted_plane(P, tilt, c, D):
    """The same scene through OpenCV: a pinhole camera at height D over c looks down the normal of the
    calibrated plane z = 0; points of the tilted plane are projected to pixels (cv2.projectPoints,
    cv2.Rodrigues) and the pixels' rays are intersected with z = 0 again."""
    import cv2

    f = 2000.0                                       # any focal length: it cancels
    K = np.array([[f, 0, 0], [0, f, 0], [0, 0, 1.0]])
    R, _ = cv2.Rodrigues(np.array([tilt[0], tilt[1], 0.0]))
    X = np.c_[P - c, np.zeros(len(P))] @ R.T         # tilted plane, about c
    # camera frame: the camera looks along -z of the plane frame from (c, D); x_cam = x, y_cam = -y, z_cam = D - z
    rvec = cv2.Rodrigues(np.diag([1.0, -1.0, -1.0]))[0]
    tvec = np.array([0.0, 0.0, D])
    uv, _ = cv2.projectPoints(X.reshape(-1, 1, 3), rvec, tvec, K, None)
    uv = uv.reshape(-1, 2)
    # back onto z = 0: the ray through pixel (u, v) meets the plane at depth D: x = u D / f, y = -v D / f
    return c + np.c_[uv[:, 0] * D / f, -uv[:, 1] * D / f]


def test_tilted_plane_equals_opencvs_projection(rng):
    """The homography equals OpenCV's pinhole projection and back-projection of the tilted plane."""
    P = rng.uniform(-0.02, 0.02, (58, 2)) + [0.002, 0.012]
    c = np.array([0.001, 0.01])
    for tilt in [(0.05, 0.0), (0.0, -0.08), (0.03, 0.06)]:
        np.testing.assert_allclose(apply_plane_tilt(P, tilt, c, 0.2), _opencv_tilted_plane(P, tilt, c, 0.2),
                                   atol=1e-12)


def test_tilt_limits_foreshortening_and_perspective():
    """Limits: no tilt is the identity; an axis along x foreshortens y by cos α to first order in
    |P-c|/D; far away (D -> inf) the map is the orthographic foreshortening exactly."""
    P = np.array([[0.0, 0.01], [0.01, 0.0], [-0.004, -0.02]])
    c = np.zeros(2)
    np.testing.assert_array_equal(apply_plane_tilt(P, (0.0, 0.0), c, 0.3), P)
    a = 0.1
    far = apply_plane_tilt(P, (a, 0.0), c, 1e9)
    np.testing.assert_allclose(far, P * [1.0, np.cos(a)], atol=1e-12)
    near = apply_plane_tilt(P, (a, 0.0), c, 0.3)
    # the perspective term: a point raised by y sin α towards the camera is magnified by D / (D - y sin α)
    y = P[:, 1]
    np.testing.assert_allclose(near, P * [1.0, np.cos(a)] * (0.3 / (0.3 - y * np.sin(a)))[:, None], atol=1e-15)


def test_camera_plane_warp_round_trip_and_reduces_to_the_point_warp(rng):
    P = rng.uniform(-0.03, 0.03, (6, 58, 2))
    P[1, 4] = np.nan
    c = np.array([0.003, 0.012])
    W = apply_camera_plane_warp(P, 0.01, -0.004, c, tilt=(0.04, -0.07), distance=0.2)
    back = unwarp_camera_plane(W, 0.01, -0.004, c, tilt=(0.04, -0.07), distance=0.2)
    np.testing.assert_allclose(back, P, atol=1e-13)
    assert np.isnan(back[1, 4]).all()
    np.testing.assert_array_equal(apply_camera_plane_warp(P, 0.01, -0.004, c), apply_point_warp(P, 0.01, -0.004, c))
    np.testing.assert_allclose(unapply_plane_tilt(apply_plane_tilt(P, (0.1, 0.2), c), (0.1, 0.2), c), P, atol=1e-14)


def test_tilt_is_not_an_in_plane_similarity(rng):
    """A 5 degree tilt seen from 0.25 m moves 20 mm-scale points by tens of µm after the best
    similarity (scale, rotation, shift) is removed: the in-plane warp of old cannot stand in for it."""
    P = rng.uniform(-0.02, 0.02, (200, 2))
    Q = apply_plane_tilt(P, (np.radians(5.0), 0.0), np.zeros(2), 0.25)
    A = np.c_[P[:, 0], -P[:, 1], np.ones(200), np.zeros(200)]
    B = np.c_[P[:, 1], P[:, 0], np.zeros(200), np.ones(200)]
    M = np.r_[A, B]
    sol, *_ = np.linalg.lstsq(M, np.r_[Q[:, 0], Q[:, 1]], rcond=None)
    resid = np.r_[Q[:, 0], Q[:, 1]] - M @ sol
    assert np.sqrt(np.mean(resid ** 2)) > 20e-6


def test_tilt_bad_distance():
    with pytest.raises(ValueError, match="distance"):
        tilt_homography((0.1, 0.0), 0.0)
