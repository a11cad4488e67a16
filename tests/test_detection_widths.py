"""A polished tube's limbs and faces in the refinement: the width check beside a refined slot corner
(``subpixel.link_widths``) where the silhouette misses the far limb, and the view term of a face beside a
limb that mirrors the backdrop (``refine.face_view_cov``)."""

import math
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from notchfit.vision.camera import CameraModel
from notchfit.vision.detection.refine import face_view_cov
from notchfit.vision.detection.subpixel import link_widths
from notchfit.vision.detection.view import DiameterScale


def _polished_band(strip_level: float, seed: int = 3):
    """A vertical tube 2R = 80 px wide (full px 60..140) on a backdrop of 200, its body 60, the 8 px (0.2 R)
    along its left limb (60..68) at ``strip_level`` (a polished limb that mirrors the backdrop), blurred
    σ = 1 px, noise σ = 1.5; its working-copy silhouette (factor 2) is the body alone (68..140)."""
    rng = np.random.default_rng(seed)
    img = np.full((200, 200), 200.0)
    img[:, 60:140] = 60.0
    img[:, 60:68] = strip_level
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + rng.normal(0.0, 1.5, img.shape)
    mask = np.zeros((100, 100), np.uint8)
    mask[:, 34:70] = 1                                                 # full px 68..140
    return img.astype(np.float32), mask


@pytest.mark.parametrize("strip_level", [150.0, 240.0])
def test_a_limb_missing_from_the_far_side_of_the_silhouette_is_not_the_corners_fault(strip_level):
    """The silhouette misses the far limb's 8 px strip (darker or brighter than the backdrop it mirrors): a
    corner on the tube's outer edge found the link 10 % narrower than 2R on the silhouette alone and was
    withheld (6 % tolerance); the far end is now looked for in the image, so it finds 2R within 3 %. A corner
    on an edge 8 px inside the tube (a highlight's boundary) stays 10 % short: the check still measures the
    corner's own edge."""
    f, R_px, m_per_px = 2, 40.0, 1e-5
    img, mask = _polished_band(strip_level)
    C = np.array([[139.5, 80.0], [131.5, 80.0]])                       # on the outer edge; 8 px inside it
    specs = SimpleNamespace(face=np.array([True, True, False, False]),  # incoming edge = the slot face
                            Din=np.array([[1.0, 0.0], [1.0, 0.0]]), Dout=np.array([[0.0, -1.0], [0.0, -1.0]]))
    ref = SimpleNamespace(C=C, specs=specs, img=img, off=np.zeros(2))
    w = link_widths(ref, mask, f, DiameterScale(m_per_px, (200, 200)), 1.0 / m_per_px, R_px * m_per_px)
    ratio = w / (2 * R_px * m_per_px)
    assert ratio[0] == pytest.approx(1.0, abs=0.03)
    assert ratio[1] < 0.93
    # the silhouette alone (no image to look in): the outer-edge corner is short by the missing strip
    bare = link_widths(SimpleNamespace(C=C, specs=specs), mask, f, DiameterScale(m_per_px, (200, 200)),
                       1.0 / m_per_px, R_px * m_per_px)
    assert bare[0] / (2 * R_px * m_per_px) < 0.93


def test_a_matte_tube_as_wide_as_its_silhouette_keeps_the_silhouettes_width():
    """No strip missing: the far end is the silhouette's (no search, to the bit the silhouette's width)."""
    f, R_px, m_per_px = 2, 40.0, 1e-5
    img, _ = _polished_band(60.0)
    mask = np.zeros((100, 100), np.uint8)
    mask[:, 30:70] = 1
    C = np.array([[139.5, 80.0]])
    specs = SimpleNamespace(face=np.array([True, False]), Din=np.array([[1.0, 0.0]]), Dout=np.array([[0.0, -1.0]]))
    args = (mask, f, DiameterScale(m_per_px, (200, 200)), 1.0 / m_per_px, R_px * m_per_px)
    w = link_widths(SimpleNamespace(C=C, specs=specs, img=img, off=np.zeros(2)), *args)
    assert w[0] == link_widths(SimpleNamespace(C=C, specs=specs), *args)[0]


def test_a_face_beside_a_mirroring_limb_may_be_off_by_its_whole_bulge():
    """A corner 500 px off the optical axis along the tube (focal 1000 px, the plane facing the camera): its
    face bulges by b = R sin β, sin β ≈ 0.45, R = 40 px. Beside a limb that mirrors the backdrop
    (``assume``), with the camera file's view, the face mirrors it too and the slot's visible boundary may
    be its far rim: σ along the outer edge is the whole bulge b (was b / 2). Without ``assume`` and without
    a camera file (an assumed view, already an upper bound) the term stays b / 2."""
    cam = CameraModel.synthetic(focal_px=1000.0, tilt_deg=(0.0, 0.0), dist=(0.0, 0.0, 0.0, 0.0, 0.0))
    K_ = cam.camera_matrix
    R, X = 40.0, np.array([[K_[0, 2] + 500.0, K_[1, 2]]])
    dd = np.array([[1.0, 0.0], [0.0, 1.0]])                            # limb along x (incoming), face across
    u = np.arange(3.0, 70.0)
    pts = X[0] + np.stack([np.zeros_like(u), u], 1)                    # the mirror image's straight boundary
    args = (X, dd, np.array([False, True]), np.array([True]), pts, np.ones(len(u), int))
    on = np.array([True])
    mirrored = face_view_cov(cam, *args, radius_px=R, assume=on)[0, 0, 0]
    half = face_view_cov(cam, *args, radius_px=R, assume=on, mirror_factor=0.5)[0, 0, 0]
    assert 0.4 < math.sqrt(half) / (0.5 * R) < 0.5                     # b / 2 with sin β in (0.4, 0.5)
    assert mirrored == pytest.approx(4.0 * half, rel=1e-9)
    H, W = 1200, 1600
    scale = DiameterScale(1e-5, (W, H))
    Xs = np.array([[(W - 1) / 2 + 400.0, (H - 1) / 2]])
    ps = Xs[0] + np.stack([np.zeros_like(u), u], 1)
    args_s = (Xs, dd, np.array([False, True]), np.array([True]), ps, np.ones(len(u), int))
    sin_b = 400.0 / math.hypot(400.0, math.hypot(W, H))
    assert face_view_cov(scale, *args_s, radius_px=R, assume=on)[0, 0, 0] == pytest.approx((0.5 * R * sin_b) ** 2,
                                                                                            rel=1e-9)
