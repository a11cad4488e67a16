"""The calibration-error point warp (data-format.md cause `calibration_error`)."""
import numpy as np
import pytest

from notchfit.warp import apply_point_warp, point_warp_jacobian, unwarp_points


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
