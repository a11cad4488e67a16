"""Slots closed at the mouth, numbered from a clean silhouette: never a wrong identity (issue 25).

A silhouette that keeps only the tube (no cast shadow, no paper) can lose the solid edge of a link as bright
as the backdrop between two slots closed at the mouth; the outline then shows one gap from the earlier
slot's mouth to the later one's, and the chain read it as the later slot, its first corner one joint off
(``closed_b``: corner 10 reported ``ok`` on slot 4's mouth, one link from its own). First the chain's
candidates of that reading (plane, working px, as the detector gave them), then the render itself with
the threshold's silhouette cut to notchfit's own renderer's silhouette of the same view.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from notchfit.io import load_geometry, load_image
from notchfit.vision.detection import detect_notches, pipeline
from notchfit.vision.detection.chain import ChainTolerance, SideCandidates
from notchfit.vision.detection.numbering import ChainInput, _lost_link_gaps, _side_numbers
from notchfit.vision.detection.segment import downsample, segment
from notchfit.vision.render.pbr import PbrScene, PbrTruth, score_detection
from notchfit.vision.render.scenes import Scene, render_scene

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"
NINE = load_geometry(GALLERY / "wrist_nine.toml")

# closed_b's right side as the chain saw it: slots closed at the mouth (one point, slack half a slot),
# the open gap from slot 4's closed mouth to slot 5's (link 4's edge lost), the base and the tip corner
_CLOSED = 3.375
_CANDS = [((6.5, 68.5), (10.5, 68.5), 0.0), ((27.5, 45.5),) * 2 + (_CLOSED,), ((15.5, 32.5), (2.5, 25.5), 0.0),
          ((-4.5, 24.5),) * 2 + (_CLOSED,), ((-9.5, 25.5),) * 2 + (_CLOSED,), ((-17.5, 28.5),) * 2 + (_CLOSED,),
          ((-25.5, 36.5),) * 2 + (_CLOSED,)]


def _chain_input():
    corners = {k: (np.array(a), np.array(b)) for k, (a, b, _) in enumerate(_CANDS)}
    slack = {k: s for k, (_, _, s) in enumerate(_CANDS) if s}
    outline = np.array([[-29.5, 42.5], [0.0, 0.0]])                  # the tip corners (right, left)
    return ChainInput(corners, slack, (np.array([23.5, 68.5]), None), outline, 6.666666666666664e-05,
                      ChainTolerance(0.08, 2.5, 1.0))


def test_a_gap_spanning_a_lost_link_is_not_numbered_as_the_later_slot():
    """Read as one slot, the gap from slot 4's mouth to slot 5's fits joint 5 with the base and the tip
    next to their slots (the joints skipped on either side take up the difference): its first corner, slot
    4's mouth, would be numbered 5. Read as two closed mouths it fits otherwise: no number where the two
    readings disagree, and none for the gap itself."""
    msg = []
    got = dict(_side_numbers(list(range(len(_CANDS))), +1, _chain_input(), NINE, (0, 1), msg))
    assert 2 not in got
    assert all(got[k] == j for k, j in ((3, 6), (4, 7)) if k in got)     # where these are numbered: truly
    assert any("as long as a link's edge" in m for m in msg)


@pytest.mark.parametrize("width, closed_beside, doubtful", [
    (6.75, True, False),       # a slot at its cut width between closed mouths
    (9.0, True, False),        # within the chain's tolerance of it
    (15.0, True, True),        # a link's edge long, between closed mouths: which reading is not known
    (15.0, False, False),      # between open slots: a slot bent open
])
def test_which_gaps_may_be_a_lost_link(width, closed_beside, doubtful):
    """The middle of three candidates [plane units: 15 per mm, slots 0.45 mm, links 0.55 mm]."""
    near = np.array([[0.0, 0.0], [0.0, 20.0], [0.0, 50.0]])
    far = near + [[0.0, 0.0], [0.0, width], [0.0, 0.0]]
    slack = np.array([_CLOSED, 0.0, _CLOSED]) if closed_beside else np.zeros(3)
    got = _lost_link_gaps(SideCandidates(+1, near, far, slack=slack), NINE, _chain_input())
    assert got.tolist() == [False, doubtful, False]


def _scene(name):
    rec = json.loads((GALLERY / f"{name}.json").read_text())
    return PbrScene.from_dict(rec["scene"]), PbrTruth.from_dict(rec), load_image(GALLERY / rec["image"])


def _own_silhouette_cut(monkeypatch, scene, truth, *, k: int, base: str):
    """The ``local`` silhouette variant replaced by ``base`` (the threshold's or the local background's
    silhouette) cut to the own renderer's silhouette of the same view dilated by ``k`` working px."""
    r = render_scene(np.asarray(scene.theta), NINE, truth.camera, plane=truth.pose.plane,
                     scene=Scene(holder="none" if scene.holder == "none" else "chuck", solid=True,
                                 holder_half_width=scene.holder_half_width, tilt_deg=scene.tilt_deg,
                                 tilt_axis_deg=scene.tilt_axis_deg, blur_sigma=1.0),
                     rng=np.random.default_rng(scene.seed))
    orig = pipeline.variant_mask

    def patched(name, seg, setup, cache):
        if name != "local":
            return orig(name, seg, setup, cache)
        src = seg.mask if base == "threshold" else orig("local", seg, setup, cache)
        own = segment(downsample(r.image.astype(float), setup.f)).mask.astype(np.uint8)
        return src & (cv2.dilate(own, np.ones((2 * k + 1, 2 * k + 1), np.uint8)) > 0)

    monkeypatch.setattr(pipeline, "variant_mask", patched)


def test_closed_b_with_a_clean_silhouette_gives_no_wrong_identity(monkeypatch):
    """Before the guard: corner 10 ``ok`` 0.3 px from corner 9, 32.7 px from its own (1 wrong identity)."""
    scene, truth, img = _scene("closed_b")
    _own_silhouette_cut(monkeypatch, scene, truth, k=1, base="threshold")
    s = score_detection(detect_notches(img, truth.camera, NINE, mirror=truth.pose.plane[3]), truth,
                        scene.px_per_mm)
    assert s.wrong == 0 and s.invented == 0
    assert s.ok >= 1


def test_closed_a_base_corner_hidden_by_the_rim_is_not_invented(monkeypatch):
    """The local background's silhouette cut to the own renderer's (dilated 1 px): corner 0 (hidden by the
    chuck's rim) is located 16 px off and must not be reported ``ok`` (the refinement's acceptance withholds
    it today; this pins that)."""
    scene, truth, img = _scene("closed_a")
    _own_silhouette_cut(monkeypatch, scene, truth, k=1, base="local")
    det = detect_notches(img, truth.camera, NINE, mirror=truth.pose.plane[3])
    s = score_detection(det, truth, scene.px_per_mm)
    assert s.wrong == 0 and s.invented == 0
    assert not truth.visible[0] and det.status[0] != "ok"
