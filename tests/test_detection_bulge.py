"""Corners whose face is seen only far from them, in a view that looks along the tube: kept at the straight
lines' intersection with the arc's whole bulge ``R sin β`` as a systematic error along the limb
(:func:`notchfit.vision.detection.faces.far_line_corners`).

On the physically based gallery's polished chucks (tests/data/pbr) the limb mirrors the backdrop, and the
mirror strip hides the slot face next to the corner: the face is seen only from about 0.1 R on, and its
arc cannot be extrapolated to the limb. Such corners were withheld (``occluded``) though their straight
lines meet 0.5–2.9 px from the truth.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from notchfit.io import load_geometry, load_image
from notchfit.units import MM
from notchfit.vision.detection import detect_notches
from notchfit.vision.detection.faces import far_line_corners
from notchfit.vision.detection.refine import CornerLines
from notchfit.vision.render.pbr import PbrTruth, score_detection

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"


def _lines(X, dd_limb):
    """Two slot corners at ``X`` (2, 2) [px], each with its limb (incoming edge) along ``dd_limb`` (2, 2) and
    its face (outgoing edge) across it; both withheld."""
    K = len(X)
    dd = np.concatenate([dd_limb, dd_limb[:, ::-1] * np.array([-1.0, 1.0])])
    return CornerLines(np.asarray(X, float), np.tile(0.01 * np.eye(2), (K, 1, 1)), np.zeros(K, bool),
                       np.concatenate([X, X]), dd, np.ones(2 * K, bool), np.full(2 * K, 0.01))


def test_a_corner_is_kept_with_its_whole_bulge_along_the_limb():
    curved = np.array([False, False, True, True])          # the outgoing edges are the faces
    d = np.array([[0.0, 1.0], [0.0, -1.0]])
    out = far_line_corners(_lines(np.array([[100.0, 50.0], [100.0, 90.0]]), d), [0, 1], curved,
                           radius_px=60.0, sin_view=0.1)
    assert out.ok.all()
    # bulge R sin β = 6 px, all of it along the limb (y)
    np.testing.assert_allclose(out.cov_view[0], [[0.0, 0.0], [0.0, 36.0]], atol=1e-12)
    assert np.all(out.X == np.array([[100.0, 50.0], [100.0, 90.0]]))     # the corners are not moved


def test_a_nearly_closed_slot_stays_withheld():
    # its corners 4 px apart: a 6 px bulge could put one nearer the other's position than its own
    curved = np.array([False, False, True, True])
    d = np.array([[0.0, 1.0], [0.0, -1.0]])
    out = far_line_corners(_lines(np.array([[100.0, 50.0], [100.0, 54.0]]), d), [0, 1], curved,
                           radius_px=60.0, sin_view=0.1)
    assert not out.ok.any() and out.cov_view is None


# the corners the rule for faces seen only far from their corner withheld before (with the camera file)
FAR = {"chuck_c": [9, 11], "chuck_a": [7]}


@pytest.mark.parametrize("name", sorted(FAR))
def test_far_face_corners_on_a_polished_chuck_lie_within_three_sigma(name):
    rec = json.loads((GALLERY / f"{name}.json").read_text())
    truth = PbrTruth.from_dict(rec)
    geom = load_geometry(ROOT / rec["geometry"])
    det = detect_notches(load_image(GALLERY / rec["image"]), truth.camera, geom, mirror=truth.pose.plane[3])
    score = score_detection(det, truth, rec["px_per_mm"])
    assert score.wrong == 0 and score.invented == 0
    err = np.linalg.norm(np.asarray(det.points_px, float) - truth.points_px, axis=1)
    sig = np.asarray(det.sigma, float) / (det.scale_mm_per_px * MM)
    for i in FAR[name]:
        assert det.status[i] == "ok"
        assert err[i] <= 3 * sig[i]
