"""The detector on renders of real lab scenes (issue 15): holders, plain tube, border entry, polarity,
specular streak, JPEG, orientations, one-sided slots, photos without calibration.

Small images (600 x 500 px at 40 px/mm) of a one-sided wrist like the lab's (OD 1.62 mm, five notches
0.8 mm high, all cut on one side). Every rendered corner that is a real corner must be found and
numbered, no other point may be reported, and the error stays within 0.005 mm rms (0.2 px).
"""

import numpy as np
import pytest

from notchfit.vision.detection import detect_notches, draw_overlay, mirror_without_camera, overlay_with_crop
from notchfit.physics.geometry import Geometry, default_geometry
from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

WRIST = Geometry(n_joints=5, p=1.6e-3, outer_radius=0.81e-3, slot_width=0.8e-3, slot_depth=1.3e-3,
                 slot_sides=(1,) * 5, mount_half_width=2.5e-3, name="wrist", inner_radius=0.7e-3,
                 tendons=("right",), tendon_path="lumen", r_x=None, r_z=None, cable_radius=None, channel_radius=None)
BEND = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
MM_PER_PX = 1 / 40


def _scene(seed, angle=90.0, theta=BEND, geom=WRIST, size=(600, 500), mm_per_px=MM_PER_PX, **scene_kw):
    cam, plane = scene_camera(theta, geom, image_size=size, mm_per_px=mm_per_px, angle_deg=angle)
    r = render_scene(theta, geom, cam, plane=plane, scene=Scene(**scene_kw), rng=np.random.default_rng(seed))
    return cam, r


def _uncal_mirror(cam, r):
    """The scene cameras see the plane from behind (plane y up the image): without the camera file the
    same view is a mirrored one (the image's own frame has a calibration's handedness, x right, y down)."""
    return mirror_without_camera(cam, r.image.shape[:2], False)


def _check(det, r, *, rms_mm=0.005, max_mm=0.01, mm_per_px=MM_PER_PX):
    ok = np.array(det.status) == "ok"
    assert not np.any(ok & ~r.visible), "a point that is not a corner in the image was reported"
    assert np.array_equal(ok, r.visible), det.message
    err = np.linalg.norm(det.points_px[ok] - r.points_px[ok], axis=1) * mm_per_px
    assert np.sqrt(np.mean(err ** 2)) <= rms_mm and err.max() <= max_mm
    return err


SCENES = {
    "chuck_touching_the_tube": dict(holder="chuck"),
    "collet_and_plain_tube": dict(holder="collet", plain_length=0.5e-3),
    "clamp": dict(holder="clamp"),
    "tube_from_the_border": dict(holder="none"),
    "light_on_dark": dict(holder="chuck", background=30.0, tube_level=190.0, holder_level=170.0),
    "specular_streak": dict(holder="chuck", streak=0.7),
    "jpeg_q80": dict(holder="chuck", jpeg_quality=80),
}


@pytest.mark.parametrize("kind", list(SCENES))
def test_scene_kind(kind):
    cam, r = _scene(list(SCENES).index(kind) + 1, **SCENES[kind])
    det = detect_notches(r.image, cam, WRIST)
    _check(det, r)
    if SCENES[kind].get("holder") in ("collet", "none"):
        assert det.status[0] == det.status[1] == "occluded"       # no corner at the base edge


@pytest.mark.parametrize("angle,side", [(90, "top"), (0, "left"), (180, "right"), (270, "bottom"), (35, "left")])
def test_any_orientation_base_found(angle, side):
    theta = BEND if angle != 35 else -0.4 * BEND
    cam, r = _scene(10 + angle, angle=angle, theta=theta, holder="chuck")
    det = detect_notches(r.image, cam, WRIST)
    assert det.base_side == side
    _check(det, r)


def test_stated_base_side():
    cam, r = _scene(3, angle=180, holder="none")
    det = detect_notches(r.image, cam, WRIST, base="right")
    _check(det, r)
    wrong = detect_notches(r.image, cam, WRIST, base="left")
    assert wrong.n_ok == 0 and "base" in wrong.message
    with pytest.raises(ValueError, match="base"):
        detect_notches(r.image, cam, WRIST, base="up")


def test_holder_face_off_the_base_edge_hides_the_base_corners():
    """A holder face 1.5 mm below the base edge: a corner, but not the base points: occluded, the rest numbered."""
    cam, r = _scene(4, holder="chuck", plain_length=1.5e-3)
    det = detect_notches(r.image, cam, WRIST)
    assert det.status[0] == det.status[1] == "occluded"
    _check(det, r)


@pytest.mark.parametrize("kind", ["chuck_touching_the_tube", "tube_from_the_border", "light_on_dark", "jpeg_q80",
                                  "clamp", "specular_streak"])
def test_uncalibrated_scale_from_the_diameter(kind):
    """No camera file: the scale from the tube's outer diameter within 1 % (issue target), stated with
    its uncertainty and assumption; the corners as with the camera."""
    cam, r = _scene(20 + list(SCENES).index(kind), **SCENES[kind])
    det = detect_notches(r.image, None, WRIST, mirror=_uncal_mirror(cam, r))
    assert abs(det.scale_mm_per_px / (MM_PER_PX) - 1) <= 0.01
    assert 0 < det.scale_sigma < 0.01 * det.scale_mm_per_px
    assert "fronto-parallel" in det.assumption and "diameter" in det.assumption
    _check(det, r)
    # plane coordinates: image axes (x right, y down) in mm
    ok = np.array(det.status) == "ok"
    uv = det.points[ok] / (det.scale_mm_per_px * 1e-3)
    np.testing.assert_allclose(uv[:, 0], det.points_px[ok, 0], atol=1e-6)
    np.testing.assert_allclose(uv[:, 1], det.points_px[ok, 1], atol=1e-6)


def test_seed_tube_in_a_chuck_light_on_dark():
    """The alternating 27-joint tube held in a chuck, polished on a dark background, base at the bottom."""
    geom = default_geometry()
    th = np.full(geom.n_joints, 0.03)
    cam, r = _scene(30, angle=270, theta=th, geom=geom, size=(1100, 1400), mm_per_px=0.03, holder="chuck",
                    background=35.0, tube_level=200.0, holder_level=150.0, shading=0.2)
    det = detect_notches(r.image, cam, geom)
    assert det.base_side == "bottom"
    _check(det, r, mm_per_px=0.03, rms_mm=0.005, max_mm=0.015)


def test_overlays_scale_with_the_image():
    cam, r = _scene(5, holder="chuck")
    det = detect_notches(r.image, cam, WRIST)
    ov = draw_overlay(r.image, det)
    assert ov.shape == r.image.shape + (3,)
    both = overlay_with_crop(r.image, det, height=400)
    assert both.shape[0] == 400 and both.shape[1] > 400 * r.image.shape[1] / r.image.shape[0]
    # a big image gets thicker marks: more coloured pixels per corner than the plain scale
    big = np.kron(r.image, np.ones((6, 6), np.uint8))
    det_big = detect_notches(big, None, WRIST, mirror=_uncal_mirror(cam, r))
    green = lambda im: np.count_nonzero((im[..., 1] > 150) & (im[..., 0] < 80) & (im[..., 2] < 80))
    n_small, n_auto = green(draw_overlay(big, det_big, marker_scale=1.0)), green(draw_overlay(big, det_big))
    assert n_auto > 2 * n_small


@pytest.mark.parametrize("name", ["wrist_tip_first", "wrist_asymmetric"])
def test_shipped_wrists_per_notch_dimensions_and_section_backbone(name):
    """Per-notch depths and spacings, joints on each slot's neutral axis (the shipped geometry files):
    rendered with the projector's pivot model, every visible corner found and numbered."""
    from pathlib import Path

    from notchfit.io import load_geometry
    from notchfit.vision.render import pivot_closure_angles

    g = load_geometry(Path(__file__).resolve().parent.parent / "datasets" / "geometry" / f"{name}.toml")
    th = g.rest_angles + 0.6 * (pivot_closure_angles(g) - g.rest_angles)
    cam, r = _scene(11, theta=th, geom=g, holder="chuck")
    det = detect_notches(r.image, cam, g)
    _check(det, r)


# ----------------------------------------------------------------------------- seeded random lab scenes
def _lab_geometries():
    """The lab's wrist (joints on each slot's section), and the shipped wrists with per-notch dimensions."""
    from pathlib import Path

    from notchfit.io import load_geometry

    here = Path(__file__).resolve().parent.parent / "datasets" / "geometry"
    return [WRIST.replace(backbone="section", name="lab_wrist")] + [load_geometry(here / f"{n}.toml")
                                                                    for n in ("wrist_asymmetric", "wrist_tip_first")]


def _variety(n, seed, size, px_per_mm, calibrated):
    """Detect n seeded random lab scenes (notchfit.vision.render.variety); totals of the scores."""
    from notchfit.vision.render.variety import draw_scene, render_draw, score

    rng = np.random.default_rng(seed)
    geoms = _lab_geometries()
    found = corners = invented = 0
    errs, scale = [], []
    for _ in range(n):
        d = draw_scene(rng, geoms, size=size, px_per_mm=px_per_mm)
        r = render_draw(d, rng)
        det = detect_notches(r.image, d.camera, d.geom) if calibrated else \
            detect_notches(r.image, None, d.geom, mirror=mirror_without_camera(d.camera, r.image.shape[:2], d.plane[3]))
        s = score(det, r, px_per_mm)
        found, corners, invented = found + s["found"], corners + s["corners"], invented + s["invented"]
        errs.append(s["errors_mm"])
        if not calibrated and det.n_ok:
            scale.append(det.scale_mm_per_px * px_per_mm - 1)
    return found, corners, invented, np.concatenate(errs), np.array(scale)


@pytest.mark.parametrize("calibrated", [True, False])
def test_random_lab_scenes(calibrated):
    """24 seeded draws of everything a lab photograph varies in (holders incl. jaws as dark as the tube or
    brighter, polarity, shading, streak, uneven backdrop and vignetting, perspective and a tilt out of the
    plane up to 4°, blur, defocus, motion, ISO noise, sharpening, JPEG 75-95, any angle, bends up to 0.98
    of each slot's closure, per-notch depths) at 50 px/mm: no point is invented and none is grossly off,
    most corners are found, and the found ones are accurate (docs/robustness.md has the per-kind table
    at 130 px/mm). Without a calibration fewer are found (the tube must be told from the holder and a
    streak's half-bands by its slots on a coarse copy), but the scale is within 1 % wherever points are
    reported."""
    found, corners, invented, err, scale = _variety(24, 15, (960, 640), 50.0, calibrated)
    assert invented == 0
    assert err.max() <= 0.04
    assert found >= (0.85 if calibrated else 0.5) * corners
    assert np.sqrt(np.mean(err ** 2)) <= 0.008
    assert np.all(np.abs(scale) <= 0.01)            # the scale from the diameter, where one was reported


@pytest.mark.slow
@pytest.mark.parametrize("calibrated", [True, False])
def test_random_lab_scenes_full_size(calibrated):
    """The same at the lab's 130 px/mm in 4928 x 3264 images (16 draws)."""
    found, corners, invented, err, scale = _variety(16, 16, (4928, 3264), 130.0, calibrated)
    assert invented == 0
    assert err.max() <= 0.06
    assert found >= (0.7 if calibrated else 0.4) * corners
    assert np.sqrt(np.mean(err ** 2)) <= 0.01
    assert np.all(np.abs(scale) <= 0.01)


def test_a_camera_tone_curve_is_undone_before_the_edges():
    """A JPEG's tone curve (gamma 2.2) moves a blurred edge's 50 % crossing toward the dark side: the
    corners are off by about 0.3 sigma of blur. tone_gamma=2.2 takes the values back to linear light."""
    errs = {}
    for tg in (1.0, 2.2):
        cam, r = _scene(44, holder="chuck", gamma=2.2, blur_sigma=2.0, size=(900, 760), mm_per_px=1 / 60)
        det = detect_notches(r.image, cam, WRIST, tone_gamma=tg)
        errs[tg] = _check(det, r, rms_mm=0.02, max_mm=0.03, mm_per_px=1 / 60)
    assert np.sqrt(np.mean(errs[2.2] ** 2)) <= 0.003 < np.sqrt(np.mean(errs[1.0] ** 2))
