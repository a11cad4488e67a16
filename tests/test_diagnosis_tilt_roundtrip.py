"""Round trip of the tilted bending plane (notchfit.vision.warp): warp known points, fit the camera-plane
family back, recover the tilt within its standard error; and why a fold that sees one side of the warp
centre cannot (the radial term takes the perspective gradient).

The tilted plane seen in perspective is the plane-to-plane homography induced by a plane (Hartley and
Zisserman, Multiple View Geometry, 2nd ed., Sec. 13.1: ``H = R − t nᵀ / d``); to first order in the tilt
it moves a point by the perspective term ``(v·d) d``, ``v ⟂ ω`` of size ``|ω| / D``, which over points on one
side of the centre a radial stretch ``k |d|² d`` and a scale nearly reproduce.
"""
import numpy as np
from scipy.optimize import least_squares

from notchfit.vision.warp import apply_camera_plane_warp

D, RHO, SIGMA = 0.25, 0.01, 0.02e-3
TILT, SCALE, CENTRE = np.array([0.10, -0.08]), 0.005, np.array([0.0, 0.015])


def _points(x_mm):
    """A grid over the tube's workspace [m]: x in ``x_mm``, y 2-30 mm."""
    x, y = np.meshgrid(np.linspace(*x_mm, 9), np.linspace(2.0, 30.0, 12))
    return np.column_stack([x.ravel(), y.ravel()]) * 1e-3


def _model(p, Q, radial: bool):
    """The family: registration (tx, ty, φ) of the true points, then tilt, scale, centre (and k)."""
    wx, wy, s, cx, cy, tx, ty, phi = p[:8]
    k = p[8] if radial else 0.0
    c, sn = np.cos(phi), np.sin(phi)
    P = Q @ np.array([[c, sn], [-sn, c]]) + (tx, ty)
    return apply_camera_plane_warp(P, s, k, (cx, cy), tilt=(wx, wy), radius=RHO, distance=D)


def _fit(Q, measured, radial: bool):
    """Least squares from the untilted start; the tilt and its standard errors (σ-weighted, (JᵀJ)⁻¹)."""
    p0 = np.r_[0.0, 0.0, 0.0, CENTRE + 1e-3, 0.0, 0.0, 0.0, [0.0] if radial else []]
    res = least_squares(lambda p: ((_model(p, Q, radial) - measured) / SIGMA).ravel(), p0, x_scale="jac",
                        xtol=1e-12, ftol=1e-12)
    cov = np.linalg.pinv(res.jac.T @ res.jac)
    return res.x[:2], np.sqrt(np.diag(cov))[:2]


def _measured(Q, seed):
    rng = np.random.default_rng(seed)
    return apply_camera_plane_warp(Q, SCALE, 0.0, CENTRE, tilt=TILT, radius=RHO, distance=D) + \
        rng.normal(0.0, SIGMA, Q.shape)


def test_a_known_tilt_is_recovered_within_its_standard_error():
    """Points on both sides of the centre, warped by a 5.7° / 4.6° tilt, scale 0.5 %, camera at 250 mm: the fit
    of tilt, scale, centre and registration returns the tilt within three standard errors, also with the
    radial term free; the errors are small against the tilt."""
    Q = _points((-20.0, 20.0))
    for seed in (1, 2, 3):
        for radial in (False, True):
            w, se = _fit(Q, _measured(Q, seed), radial)
            assert np.all(np.abs(w - TILT) < 3.0 * se), (seed, radial, w, se)
            assert np.all(se < 0.2 * np.abs(TILT))


def test_on_one_side_of_the_centre_the_radial_term_takes_the_tilt():
    """Points left of the centre only (a training set pulled one way): without the radial term the tilt is
    still recovered; with it free its standard error is nearly twice that (the radial stretch stands in for
    the perspective gradient) and seven times that of points on both sides (0.017 against 0.0025 rad for
    ω_y, seed 1): the identifiability the camera-plane candidate lacks in such a fold (docs/diagnosis.md)."""
    both, one = _points((-20.0, 20.0)), _points((-20.0, -4.0))
    _, se_both = _fit(both, _measured(both, 1), True)
    w_plane, se_plane = _fit(one, _measured(one, 1), False)
    _, se_radial = _fit(one, _measured(one, 1), True)
    assert np.all(np.abs(w_plane - TILT) < 3.0 * se_plane)
    assert np.max(se_radial / se_plane) > 1.5
    assert np.max(se_radial / se_both) > 5.0
