"""The scale without a camera file across a polished limb: the width profiles end at the limb's outer step
(:func:`notchfit.vision.detection.width.measure_diameter`, :func:`notchfit.vision.detection.subpixel.outer_step`).

A polished limb mirrors the backdrop: across its edge the image steps from the backdrop to a strip nearly as
bright, 10-16 px wide at 130 px/mm, then ramps down to the dark body. The width's 50 % crossings lie on that
inner ramp; the tube ends at the outer step.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from notchfit.io import load_geometry, load_image
from notchfit.vision.detection import detect_notches, mirror_without_camera
from notchfit.vision.detection.width import measure_diameter
from notchfit.vision.render.pbr import PbrTruth, score_detection

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"


def _striped_tube(strip_px: float, seed: int = 5):
    """A vertical tube 2R = 120 px wide (columns 40..160) on a backdrop of 200, its body 60, its left limb's
    outer ``strip_px`` at 185 (a mirror strip), blurred σ = 1 px, noise σ = 2: (image, stations on the strip's
    inner ramp with the normal into the tube, true width [px])."""
    rng = np.random.default_rng(seed)
    img = np.full((300, 220), 200.0)
    img[:, 40:160] = 60.0
    img[:, 40:40 + int(strip_px)] = 185.0
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + rng.normal(0.0, 2.0, img.shape)
    x0 = 40 + strip_px - 0.5                                           # the inner ramp's crossing
    v = np.linspace(100.0, 200.0, 5)
    st = np.stack([np.full(5, x0), v, np.ones(5), np.zeros(5)], 1)
    return img.astype(np.float32), st, 120.0


def test_width_profiles_end_at_a_mirror_strips_outer_step():
    """Stations on a 14 px strip's inner ramp: the crossings alone give 2R less the strip; the outer step
    gives 2R within 1 px (the strip's level 15 DN from the backdrop, 10 standard errors of the mean profile)."""
    img, st, width = _striped_tube(14.0)
    ramp = measure_diameter(img, np.zeros(2), st, width, -140.0, 1.0, outer_k=0.0)
    outer = measure_diameter(img, np.zeros(2), st, width, -140.0, 1.0)
    assert np.all(np.abs(ramp - (width - 14.0)) < 1.0)
    assert np.all(np.abs(outer - width) < 1.0)


def test_a_matte_limb_keeps_its_crossings():
    """No strip: the crossings are the tube's edges and nothing is added (to the bit)."""
    img, st, width = _striped_tube(0.0)
    assert np.array_equal(measure_diameter(img, np.zeros(2), st, width, -140.0, 1.0),
                          measure_diameter(img, np.zeros(2), st, width, -140.0, 1.0, outer_k=0.0))


def test_chuck_full_scale_without_camera_is_within_its_stated_sigma():
    # before, the widths ended at the mirror strips' inner ramps: the scale 6.9 % off, its stated σ 1.2 %
    rec = json.loads((GALLERY / "chuck_full.json").read_text())
    truth = PbrTruth.from_dict(rec)
    img = load_image(GALLERY / rec["image"])
    det = detect_notches(img, None, load_geometry(ROOT / rec["geometry"]),
                         mirror=mirror_without_camera(truth.camera, img.shape[:2], truth.pose.plane[3]))
    score = score_detection(det, truth, rec["px_per_mm"])
    assert score.wrong == 0 and score.invented == 0 and score.ok >= 1
    err = det.scale_mm_per_px * rec["px_per_mm"] - 1
    assert abs(err) <= 2 * det.scale_sigma * rec["px_per_mm"]
    assert abs(err) < 0.02
