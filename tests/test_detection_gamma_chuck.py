"""A base corner withheld as a holder's rim must not cost the tube's diameter its limb (issue 25).

Without a camera file the scale comes from the tube's diameter, measured across the limb edges next to the
corners of a detection at a rough scale (:func:`notchfit.vision.detection.subpixel.edge_stations`). A base
corner whose holder face does not stand against the limb's backdrop (a chuck's end face seen from below,
:func:`notchfit.vision.detection.subpixel.holder_backdrops`) is no point of the tube, but its limb edge up
to the next corner is still the tube's: withholding the corner once cost ``chuck_a`` (gallery, JPEG tone
curve undone) the profiles its scale needed, and with them every corner.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from notchfit.io import load_geometry, load_image
from notchfit.vision.detection import detect_notches, mirror_without_camera
from notchfit.vision.detection.records import Refinement
from notchfit.vision.detection.refine import CornerSpecs
from notchfit.vision.detection.subpixel import edge_stations

ROOT = Path(__file__).resolve().parent.parent


def _base_corner(ok: bool, rim: bool) -> Refinement:
    """One base-right corner at (100, 100) [px]: its incoming edge the holder's face (running up), its
    outgoing edge the limb (running right, 40 px to the next corner)."""
    C = np.array([[100.0, 100.0]])
    sp = CornerSpecs(C, np.array([[0.0, 1.0]]), np.array([[1.0, 0.0]]), np.array([30.0]), np.array([40.0]),
                     np.zeros(2, bool), holder_face=np.array([True, False]))
    return Refinement(np.array([0]), C, C.copy(), np.zeros((1, 2, 2)), np.array([ok]), np.zeros(1), 1.0,
                      np.zeros(1), sp, np.zeros((1, 1)), np.zeros(2), 1.0, rim=np.array([rim]))


@pytest.mark.parametrize("ok, rim", [(True, False), (False, True)])
def test_stations_lie_on_the_limb_only_also_next_to_a_withheld_rim_corner(ok, rim):
    st = edge_stations(_base_corner(ok, rim), 5, 1.0)
    # five stations along the limb (0.3-0.7 of its 40 px), none along the holder's face
    assert st.shape == (5, 4)
    assert np.allclose(st[:, 1], 100.0) and np.allclose(st[:, 0], 100.0 + np.linspace(12.0, 28.0, 5))


def test_no_stations_next_to_a_corner_that_is_neither_ok_nor_a_rim():
    assert edge_stations(_base_corner(False, False), 5, 1.0).shape == (0, 4)


def test_chuck_a_without_camera_file_at_gamma_2_2_keeps_its_corners():
    path = ROOT / "tests" / "data" / "pbr" / "chuck_a.json"
    from notchfit.vision.render.pbr import PbrScene, PbrTruth, score_detection

    rec = json.loads(path.read_text())
    scene, truth = PbrScene.from_dict(rec["scene"]), PbrTruth.from_dict(rec)
    img = load_image(path.parent / rec["image"])
    det = detect_notches(img, None, load_geometry(ROOT / rec["geometry"]), tone_gamma=2.2,
                         mirror=mirror_without_camera(truth.camera, img.shape[:2], truth.pose.plane[3]))
    s = score_detection(det, truth, scene.px_per_mm)
    assert s.wrong == 0 and s.invented == 0 and s.ok >= 7
    # the scale's stated σ covers its error against the render's nominal px/mm
    assert abs(det.scale_mm_per_px * scene.px_per_mm - 1) <= det.scale_sigma * scene.px_per_mm
