"""The committed physically based gallery (tests/data/pbr, made by benchmarks/make_pbr_gallery.py).

No Mitsuba needed: the renders and their ground truth are files. The truth must be self-consistent
(every corner projects from the recorded joint angles, pose and camera through notchfit's solid model;
the scene rebuilds the same camera and truth; the table matches the records), and today's detector
is scored on it per scene kind: the guarantee that no corner ever gets a wrong number is asserted, the
rest (corners found, error, z-scores) is printed (``pytest -s``) and tabled by
``benchmarks/bench_detection.py --pbr``.
"""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from notchfit.vision.detection import detect_notches
from notchfit.physics.geometry import notch_layout
from notchfit.io import load_geometry, load_image
from notchfit.physics.notches import notch_points, to_plane
from notchfit.vision.render.pbr import PbrScene, PbrTruth, pbr_camera, pbr_truth, score_detection
from notchfit.vision.render.solid import limb_corners

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "tests" / "data" / "pbr"
RECORDS = sorted(GALLERY.glob("*.json"))
KINDS = {"polished-chuck", "closed-grid", "tendon-loop", "printed-paper", "defocus"}


def _load(path):
    rec = json.loads(path.read_text())
    return rec, PbrScene.from_dict(rec["scene"]), PbrTruth.from_dict(rec), load_geometry(ROOT / rec["geometry"])


def test_gallery_is_small_and_covers_the_scene_kinds():
    assert len(RECORDS) >= 10
    kinds = {json.loads(p.read_text())["kind"] for p in RECORDS}
    assert kinds == KINDS
    size = sum(p.stat().st_size for p in GALLERY.iterdir())
    assert size < 5e6, f"the gallery holds {size / 1e6:.1f} MB"


@pytest.mark.parametrize("path", RECORDS, ids=lambda p: p.stem)
def test_truth_is_self_consistent(path):
    rec, scene, truth, geom = _load(path)
    img = load_image(GALLERY / rec["image"])
    assert img.shape[:2] == (truth.camera.image_size[1], truth.camera.image_size[0])
    th = np.asarray(rec["theta_rad"])
    assert np.array_equal(th, scene.theta) and len(truth.points_px) == geom.n_points
    # the corners are the solid tube's face corners at the recorded angles, through the recorded camera
    assert np.allclose(limb_corners(th, geom, truth.camera, truth.pose), truth.points_px, atol=1e-6)
    # the scene description rebuilds the same camera, pose and truth
    cam, pose = pbr_camera(scene, geom)
    assert np.allclose(cam.camera_matrix, truth.camera.camera_matrix)
    assert np.allclose(cam.plane_tvec, truth.camera.plane_tvec, atol=1e-12)
    again = pbr_truth(scene, geom, cam, pose)
    assert np.allclose(again.points_px, truth.points_px, atol=1e-6) and (again.visible == truth.visible).all()
    # the planar notch points (geometry.md) are the solid's corners moved along the face circle to the
    # limb: by at most R times the widest angle of a view ray off the optical axis (plus the tilt)
    planar = truth.camera.plane_to_pixel(to_plane(notch_points(th, geom), *truth.pose.plane))
    near = np.linalg.norm(planar - truth.points_px, axis=1)[truth.visible]
    W, H = truth.camera.image_size
    ray = np.arctan(0.5 * np.hypot(W, H) / truth.camera.camera_matrix[0, 0]) + np.radians(scene.tilt_deg)
    assert near.max() < 1.2 * geom.outer_radius * 1e3 * scene.px_per_mm * ray + 1.0
    # base points are never scored (holder rim or no holder), every visible corner is inside the frame
    base = np.array(notch_layout(geom).kind) == "base"
    assert not truth.visible[base].any()
    vis = truth.points_px[truth.visible]
    assert ((vis >= 0) & (vis <= [W - 1, H - 1])).all()


def test_truth_table_matches_the_records():
    rows = defaultdict(list)
    with open(GALLERY / "truth.csv", newline="") as f:
        for r in csv.DictReader(f):
            rows[r["scene"]].append(r)
    assert set(rows) == {p.stem for p in RECORDS}
    for p in RECORDS:
        rec = json.loads(p.read_text())
        got = np.array([[float(r["u_px"]), float(r["v_px"])] for r in rows[p.stem]])
        want = np.array([[q["u_px"], q["v_px"]] for q in rec["points"]])
        assert np.allclose(got, want, atol=1e-4)
        assert [int(r["visible"]) for r in rows[p.stem]] == [int(q["visible"]) for q in rec["points"]]


def _gallery_scores():
    per_kind = defaultdict(lambda: [0, 0, 0, 0, [], []])
    for p in RECORDS:
        rec, scene, truth, geom = _load(p)
        det = detect_notches(load_image(GALLERY / rec["image"]), truth.camera, geom, mirror=truth.pose.plane[3])
        s = score_detection(det, truth, scene.px_per_mm)
        k = per_kind[scene.kind]
        k[0] += s.ok
        k[1] += s.present
        k[2] += s.wrong
        k[3] += s.invented
        k[4].append(s.errors_mm)
        k[5].append(s.z)
    lines = []
    for kind, (ok, present, wrong, invented, errs, _) in sorted(per_kind.items()):
        e = np.concatenate(errs)
        rms = f"{np.sqrt(np.mean(e ** 2)):.4f} mm" if e.size else "-"
        lines.append(f"{kind:15s} {ok:3d}/{present:<3d} ok, {wrong} wrong, {invented} invented, rms {rms}")
    print("\n" + "\n".join(lines))
    return per_kind, "\n".join(lines)


@pytest.fixture(scope="module")
def gallery_scores():
    return _gallery_scores()


def test_detector_on_the_gallery_never_numbers_a_corner_wrongly(gallery_scores):
    """The detector (with the camera file) per scene kind; 0 wrong identities is the guarantee (on the
    printed tube through a phone lens, slot faces seen 20° from the side once put a distal corner on the
    face's far rim, nearer its partner's true position: the faces are now measured as ellipse arcs)."""
    per_kind, table = gallery_scores
    assert sum(k[2] for k in per_kind.values()) == 0, table


def test_local_edge_model_finds_more_corners_on_the_gallery(gallery_scores):
    """Issue 25: edges whose levels the image-wide contrast does not describe (a polished limb mirroring the
    backdrop, shading along the tube) take each profile's own fitted step: 39 of the 218 visible corners ok
    with the camera file (35 with the image-wide levels alone), none numbered wrongly, none invented."""
    per_kind, table = gallery_scores
    assert sum(k[0] for k in per_kind.values()) >= 39, table
    assert sum(k[2] for k in per_kind.values()) == 0 and sum(k[3] for k in per_kind.values()) == 0, table


def test_both_sides_from_the_silhouettes_that_number_them(gallery_scores):
    """Issue 25: on the printed tube through a phone lens (``printed_a``) the gray threshold numbers the right
    side's slots and the colour distance the left side's; each side is confirmed on its own silhouette, the
    corners are merged point by point (before: the silhouette with more corners won whole and the other side
    was lost), none numbered wrongly. The gallery: 46 of 218 corners ok with the camera file (39 before)."""
    per_kind, table = gallery_scores
    rec, scene, truth, geom = _load(GALLERY / "printed_a.json")
    det = detect_notches(load_image(GALLERY / rec["image"]), truth.camera, geom, mirror=truth.pose.plane[3])
    lay = notch_layout(geom)
    ok = np.array([s == "ok" for s in det.status])
    slot = np.array([k in ("proximal", "distal") for k in lay.kind])
    assert (ok & slot & (lay.side > 0)).any() and (ok & slot & (lay.side < 0)).any(), det.message
    assert score_detection(det, truth, scene.px_per_mm).wrong == 0
    assert sum(k[0] for k in per_kind.values()) >= 46, table
    assert sum(k[2] for k in per_kind.values()) == 0 and sum(k[3] for k in per_kind.values()) == 0, table


def test_stated_sigma_matches_the_errors_on_the_gallery(gallery_scores):
    """Honest uncertainty: over every corner found ok (with the camera file), the rms of (found - true) / σ
    is near 1, not 4-9 (slot faces seen from the side put a straight line's corner half their bulge off;
    the stated σ now says so)."""
    per_kind, table = gallery_scores
    z = np.concatenate([np.concatenate(k[5]) for k in per_kind.values()])
    assert z.size >= 20
    assert 0.5 < np.sqrt(np.mean(z ** 2)) < 2.0, table


def test_score_counts_wrong_numbers_invented_points_and_z():
    """The scorer on a made-up detection: found = truth + noise of the stated σ, two corners swapped,
    a base point reported, a closed mouth's corners a pixel apart not counted as swapped."""
    from notchfit.vision.detection.result import Detection
    from notchfit.units import MM

    rec, scene, truth, geom = _load(GALLERY / "closed_b.json")
    rng = np.random.default_rng(5)
    m = geom.n_points
    sigma_px = 0.3
    scale = 1.0 / scene.px_per_mm                       # mm per px
    pts = truth.points_px + rng.normal(0, sigma_px, (m, 2))
    vis = np.nonzero(truth.visible)[0]
    a, b = vis[0], vis[-1]                               # far apart: the base and the tip end
    d = np.linalg.norm(truth.points_px[vis][:, None] - truth.points_px[vis][None], axis=2)
    assert (d[np.triu_indices(len(vis), 1)] < 2.0).any()    # closed mouths: corners under 2 px apart
    pts[[a, b]] = pts[[b, a]]
    status = ["ok" if (v or i == 0) else "occluded" for i, v in enumerate(truth.visible)]
    det = Detection(points=np.full((m, 2), np.nan), points_px=pts, sigma=np.full(m, sigma_px * scale * MM),
                    status=tuple(status), image_status="partial", message="", contour_px=np.zeros((0, 2)),
                    scale_mm_per_px=scale)
    s = score_detection(det, truth, scene.px_per_mm)
    assert s.wrong == 2 and s.invented == 1 and s.present == truth.visible.sum() and s.ok == s.present - 2
    assert 0.8 < np.sqrt(np.mean(s.z ** 2)) < 1.2                 # errors of the stated size: z spread 1
    assert s.errors_mm.max() < 5 * sigma_px / scene.px_per_mm


def test_a_jpegs_tone_curve_undone_for_the_edges_only_numbers_no_corner_wrongly():
    """``notchfit detect`` undoes a JPEG's tone curve (gamma 2.2) unless experiment.toml says otherwise, and
    the gallery's files carry an sRGB curve. The silhouette, the slots and their numbers are found on the
    file's values (the noise of a tone-mapped image is about even across its levels, so one threshold
    holds from shadow to highlight) and only the sub-pixel edges in linear light: with every stage in
    linear light one printed-tube corner got its partner's number (with the camera file; three more
    without it)."""
    wrong = []
    for p in RECORDS:
        rec, scene, truth, geom = _load(p)
        det = detect_notches(load_image(GALLERY / rec["image"]), truth.camera, geom, mirror=truth.pose.plane[3],
                             tone_gamma=2.2)
        wrong.append(score_detection(det, truth, scene.px_per_mm).wrong)
    assert sum(wrong) == 0, dict(zip([p.stem for p in RECORDS], wrong))
