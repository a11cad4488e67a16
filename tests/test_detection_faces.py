"""A slot face whose arc the camera file gives: measured with that arc, not as a straight line (issue 25)."""

import math

import cv2
import numpy as np
import pytest

from notchfit.vision.camera import CameraModel
from notchfit.vision.detection.faces import view_sines
from notchfit.vision.detection.refine import CornerSpecs, ProfileLayout, refine_pass
from notchfit.vision.render import polygon_coverage

R = 40.0                                   # tube radius [px]
X = np.array([120.4, 90.6])                # the slot's outer corner: limb u = 120.4, face meeting it at v = 90.6
SHAPE = (170, 160)


def _camera(view_px: float) -> CameraModel:
    """A camera (focal 1000 px, no distortion) facing the plane, its principal point ``view_px`` below the
    corner: the view ray there runs ``view_px`` / 1000 along the tube, up (towards the slot) where positive."""
    K = np.array([[1000.0, 0.0, 80.0], [0.0, 1000.0, X[1] + view_px], [0.0, 0.0, 1.0]])
    return CameraModel(K, np.zeros(5), SHAPE[::-1], np.zeros(3), np.array([0.0, 0.0, 0.1]))


def _face_image(b: float, seed: int = 2) -> np.ndarray:
    """A dark tube (limb at u = 120.4, 2R wide) below a slot, its face ``v = 90.6 - b sqrt(u (2R - u))``
    (u from the limb): the front rim of a face seen ``asin b`` from the side; blur 1 px, noise 1 DN."""
    u = np.linspace(0, 2 * R, 400)
    arc = np.stack([X[0] - u, X[1] - b * np.sqrt(u * (2 * R - u))], 1)
    poly = np.concatenate([[[X[0], 175.0]], arc, [[X[0] - 2 * R, 175.0]]])
    img = 200.0 - 160.0 * polygon_coverage([poly], SHAPE, supersample=16)
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + np.random.default_rng(seed).normal(0, 1.0, img.shape)
    return img.astype(np.float32)


def _refine(img, cam, known_arc=True):
    """refine_pass as the pipeline runs it (long profiles, then short ones), the face marked curved; its free
    arc is not fitted (``arc_gate``), as where the arc is not significant or a partner's disagrees."""
    sp = CornerSpecs(np.array([X]) + [[0.6, -0.5]], np.array([[0.0, -1.0]]), np.array([[-1.0, 0.0]]),
                     np.array([40.0]), np.array([40.0]), np.array([False, True]), curved=np.array([False, True]))
    for it, h in enumerate((10.0, 5.0)):
        res = refine_pass(img, np.zeros(2), cam, sp, -1.0, ProfileLayout(s0=4, s_end=3, h=h, step=0.5, h_face=h),
                          lim=0.25, min_points=5, contrast=-160.0, blur_prior=1.0 if it else math.nan,
                          radius_px=R if it else math.nan, known_arc=known_arc, arc_gate=math.inf)
        assert res.ok[0]
        sp.C = res.C.copy()
        sp.Din, sp.Dout = res.Din, res.Dout
    return res


@pytest.mark.parametrize("view_px", [60.0, -60.0])
def test_a_face_seen_from_the_side_is_measured_with_the_arc_its_view_gives(view_px):
    """The view ray at the corner runs 0.06 along the tube (3.4°), towards the slot or away from it; the
    face is the front rim, bulging 0.06 R = 2.4 px into the slot or into the tube. With the camera's arc
    the corner lands within 0.1 px of the truth; the straight line's intersection (as before) misses it by
    ``0.5 R sin β`` = 1.2 px, which its along-edge σ then carries instead of the view's uncertainty."""
    cam = _camera(view_px)
    b = float(view_sines(cam, X[None], np.array([[0.0, -1.0]]), signed=True)[0])
    assert b == pytest.approx(view_px / math.hypot(1000.0, math.hypot(40.4, view_px)), rel=1e-6)
    img = _face_image(b)
    arc, line = _refine(img, cam), _refine(img, cam, known_arc=False)
    assert np.linalg.norm(arc.X[0] - X) < 0.1, arc.X[0]
    assert np.linalg.norm(line.X[0] - X) > 1.0, line.X[0]
    # the view's uncertainty (0.01 rad) along the limb, in place of the line's assumed half bulge
    assert math.sqrt(arc.cov_sys[0, 1, 1]) < 0.5 * math.sqrt(line.cov_sys[0, 1, 1])


def test_a_flat_face_keeps_its_line_whatever_the_view():
    """A face drawn straight (a flat outline, as a silhouette drawn in the plane) seen where the camera would
    give it an arc: its crossings refuse the arc, so the line's corner stands, to the bit."""
    cam = _camera(60.0)
    img = _face_image(0.0)
    arc, line = _refine(img, cam), _refine(img, cam, known_arc=False)
    assert np.linalg.norm(line.X[0] - X) < 0.1
    assert np.array_equal(arc.X, line.X)
