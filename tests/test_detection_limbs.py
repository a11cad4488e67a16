"""The refinement's first estimates where the silhouette misses a polished limb (issue 25).

A polished tube mirrors the backdrop in a strip along its outer edge, so its silhouette (the dark body)
ends some pixels inside the tube: the refinement looks outward along each outer edge for where the tube
ends (:func:`~notchfit.vision.detection.subpixel.outer_offsets`), bounded by how much narrower than the
tube the silhouette is (:func:`~notchfit.vision.detection.subpixel.width_deficits`), and starts there.
Synthetic images with known answers, then one gallery render.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from notchfit.io import load_geometry, load_image
from notchfit.vision.camera import CameraModel
from notchfit.vision.detection import DetectorOptions, detect_notches
from notchfit.vision.detection.refine import CornerSpecs, face_view_cov
from notchfit.vision.detection.subpixel import (outer_offsets, outer_starts, ray_exits, unexplained_cov,
                                                width_deficits)
from notchfit.vision.render.pbr import PbrTruth, score_detection

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"


def _strip_image(strip_px: float, strip_level: float, *, seed: int = 0, shadow: bool = False):
    """A backdrop (level 100, noise 3) with a tube's dark body (level 40) filling x < 100, y > 50 and a strip
    ``strip_px`` wide along its right edge and its top edge at ``strip_level`` (the limb mirroring the
    backdrop): the tube's true corner is (100 + strip, 50 - strip). With ``shadow`` there is no strip, but a
    darker band (level 70) 8 px wide outside the right edge (a cast shadow on the backdrop)."""
    rng = np.random.default_rng(seed)
    H = W = 200
    img = np.full((H, W), 100.0)
    yy, xx = np.mgrid[0:H, 0:W]
    if shadow:
        img[(xx >= 100) & (xx < 108) & (yy >= 50)] = 70.0
    else:
        s = int(strip_px)
        img[(xx < 100 + s) & (yy >= 50 - s)] = strip_level
    img[(xx < 100) & (yy >= 50)] = 40.0
    img += rng.normal(0.0, 3.0, img.shape)
    return img.astype(np.float32)


def _corner_specs():
    """The body's corner (100, 50) as the silhouette gives it: the right edge comes up to it (incoming,
    travelling -y), the top edge leaves it (outgoing, travelling -x); the object lies to the traversal's left."""
    C = np.array([[99.5, 49.5]])
    return CornerSpecs(C, np.array([[0.0, -1.0]]), np.array([[-1.0, 0.0]]), np.array([120.0]), np.array([90.0]),
                       np.array([False, False]))


def _sgn():
    """The orientation sign for which the profiles' normals point out of the body at (100, 50)."""
    sp = _corner_specs()
    for sgn in (1.0, -1.0):
        n_in = sgn * np.array([sp.Din[0, 1], -sp.Din[0, 0]])
        if n_in[0] > 0:                      # the right edge's normal points to +x (the backdrop)
            return sgn
    raise AssertionError


def test_the_tube_end_outside_a_silhouette_that_misses_a_mirroring_strip():
    """A strip 10 px wide beside the body, only 6 grey levels above the backdrop (noise 3 per pixel): the mean
    profile along each edge shows where the tube ends; the first estimate moves from the body's corner to
    within 1.5 px of the tube's (110, 40)."""
    img = _strip_image(10, 106.0)
    sp, sgn = _corner_specs(), _sgn()
    offs = outer_offsets(img, np.zeros(2), sp, sgn, reach_px=24.0, s0=5.0)
    assert offs == pytest.approx([10.0, 10.0], abs=1.5)
    C = outer_starts(sp, offs, sgn, min_move=3.0, deficit=np.array([20.0, 20.0]))
    assert np.linalg.norm(C[0] - [109.5, 39.5]) < 1.5


def test_no_move_where_the_silhouette_is_as_wide_as_the_tube():
    """A matte tube with a cast shadow beside it: outside its edge the backdrop darkens (a step the search
    finds), but the silhouette is as wide as the tube (deficit 0): the shadow is the backdrop's own and the
    first estimate stays; a plain edge with nothing outside gives no offset at all."""
    sp, sgn = _corner_specs(), _sgn()
    shadow = _strip_image(0, 100.0, shadow=True)
    offs = outer_offsets(shadow, np.zeros(2), sp, sgn, reach_px=24.0, s0=5.0)
    assert offs[0] > 5.0                                      # the shadow's edge is seen
    C = outer_starts(sp, offs, sgn, min_move=3.0, deficit=np.array([0.5, 0.5]))
    assert np.array_equal(C, sp.C)
    plain = _strip_image(0, 100.0)
    assert np.all(outer_offsets(plain, np.zeros(2), sp, sgn, reach_px=24.0, s0=5.0) < 3.0)


def test_ray_exits_and_width_deficits_on_a_band():
    """A band 40 px wide (y from 10 to 50) as the silhouette of a tube 60 px in diameter: from a point on its
    lower edge inward the far edge is 40 px away; the deficit is 20 px."""
    poly = np.array([[0.0, 10.0], [300.0, 10.0], [300.0, 50.0], [0.0, 50.0]])
    assert ray_exits(poly, np.array([[100.0, 50.0]]), np.array([[0.0, -1.0]]), min_s=5.0)[0] == pytest.approx(40.0)
    assert np.isinf(ray_exits(poly, np.array([[100.0, 50.0]]), np.array([[0.0, 1.0]]), min_s=5.0)[0])
    # a corner on the lower edge at x = 100: incoming edge along -x ... the lower edge travelled from +x
    sp = CornerSpecs(np.array([[100.0, 50.0]]), np.array([[-1.0, 0.0]]), np.array([[0.0, 1.0]]),
                     np.array([80.0]), np.array([30.0]), np.array([False, True]))
    for sgn in (1.0, -1.0):
        n_in = sgn * np.array([sp.Din[0, 1], -sp.Din[0, 0]])
        if n_in[1] > 0:                                       # object -> background: out of the band, +y
            break
    d = width_deficits(sp, sgn, poly, 60.0)
    assert d[0] == pytest.approx(20.0)


def _ray_exits_all_pairs(poly, P, u, min_s):
    """Every ray against every side of the polygon: the straightforward reference."""
    A = np.asarray(poly, float)
    E = np.roll(A, -1, axis=0) - A
    W = A[None] - P[:, None]
    cross = lambda a, b: a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    den = cross(u[:, None], E[None])
    with np.errstate(invalid="ignore", divide="ignore"):
        s, r = cross(W, E[None]) / den, cross(W, u[:, None]) / den
    hit = (np.abs(den) > 1e-12) & (r >= 0) & (r <= 1) & (s > min_s)
    return np.where(hit, s, np.inf).min(axis=1)


def test_ray_exits_equal_all_pairs_to_the_last_bit():
    """Only the sides near a ray's line are intersected: the same distances as over all sides, also for
    integer outlines whose vertices lie exactly on a ray."""
    rng = np.random.default_rng(3)
    for trial in range(60):
        N, n = int(rng.integers(3, 600)), int(rng.integers(1, 40))
        t = np.sort(rng.uniform(0, 2 * np.pi, N))
        rad = 200 + 60 * rng.standard_normal(N) * (trial % 2)
        poly = np.c_[500 + rad * np.cos(t), 400 + rad * np.sin(t)]
        a = rng.uniform(0, 2 * np.pi, n)
        u = np.c_[np.cos(a), np.sin(a)]
        P = poly[rng.integers(0, N, n)] + rng.normal(0, 2, (n, 2))
        if trial % 3 == 0:
            poly, P = np.round(poly), np.round(P)
            u = np.array([[1.0, 0.0], [0.0, -1.0], [np.sqrt(0.5), np.sqrt(0.5)]])[rng.integers(0, 3, n)]
        np.testing.assert_array_equal(ray_exits(poly, P, u, min_s=20.0), _ray_exits_all_pairs(poly, P, u, 20.0))


def test_unexplained_missing_width_widens_sigma_across_that_edge():
    """A silhouette 14 px narrower than the tube beside a corner whose outer edge search found 2 px: 14 - 2 x 2
    - 2 (the working copy's pixel) = 8 px of limb nobody saw; the edge may lie anywhere over them: variance
    8² / 12 across that edge (here the corner's incoming edge, along x), nothing along it."""
    sp, sgn = _corner_specs(), _sgn()
    cov = unexplained_cov(sp, sgn, np.array([2.0, 0.0]), np.array([14.0, np.nan]), resolution=2.0)
    assert cov[0] == pytest.approx(np.array([[64.0 / 12.0, 0.0], [0.0, 0.0]]), abs=1e-9)
    assert np.all(unexplained_cov(sp, sgn, np.array([7.0, 6.0]), np.array([14.0, 14.0]), resolution=2.0) == 0)


def test_face_next_to_a_mirroring_limb_keeps_its_view_term():
    """Next to a polished limb found outside the silhouette a face's crossings are the boundary of the
    strip's mirror image, straight whatever the face's arc: with ``assume`` the view's term 0.5 R sin β is
    kept where the straight crossings would rule it out (test_detection_stages has the geometry)."""
    cam = CameraModel.synthetic(focal_px=1000.0, tilt_deg=(0.0, 0.0), dist=(0.0, 0.0, 0.0, 0.0, 0.0))
    K_ = cam.camera_matrix
    R, X = 40.0, np.array([[K_[0, 2] + 500.0, K_[1, 2]]])
    dd = np.array([[1.0, 0.0], [0.0, 1.0]])
    u = np.arange(3.0, 70.0)
    pts = X[0] + np.stack([np.zeros_like(u), u], 1) + np.random.default_rng(6).normal(0, 0.05, (len(u), 2))
    args = (cam, X, dd, np.array([False, True]), np.array([True]), pts, np.ones(len(u), int))
    assert face_view_cov(*args, radius_px=R)[0, 0, 0] == 0.0
    assert face_view_cov(*args, radius_px=R, assume=np.array([True]))[0, 0, 0] > 0.5 * (0.5 * R * 0.4) ** 2


def test_polished_limb_corners_found_on_the_gallery_chuck():
    """``chuck_a`` (a polished wrist hanging from a chuck, 80 px/mm): its silhouette ends 8-11 px inside the
    slot side's limb. Starting from where the tube ends, the first slot's two corners are found (within 3 px,
    their σ covering the error); starting from the silhouette, neither is."""
    rec = json.loads((GALLERY / "chuck_a.json").read_text())
    truth = PbrTruth.from_dict(rec)
    geom = load_geometry(ROOT / rec["geometry"])
    img = load_image(GALLERY / rec["image"])
    found = {}
    for reach in (0.0, DetectorOptions().outer_reach_R):
        det = detect_notches(img, truth.camera, geom, mirror=truth.pose.plane[3],
                             options=DetectorOptions(outer_reach_R=reach))
        assert score_detection(det, truth, rec["px_per_mm"]).wrong == 0
        found[reach] = det
    old, new = found[0.0], found[DetectorOptions().outer_reach_R]
    for i in (2, 3):                                          # point 3 and 4: slot 1's corners
        assert old.status[i] != "ok"
        assert new.status[i] == "ok", new.message
        err = np.linalg.norm(np.asarray(new.points_px[i]) - truth.points_px[i])
        sig_px = new.sigma[i] / (new.scale_mm_per_px * 1e-3)
        assert err < 3.0 and err < 3.0 * np.sqrt(2.0) * sig_px, (i, err, sig_px)
