"""What a photograph brings to the detector (issue 25, item 4): an EXIF orientation tag, the `mirror` flag
with and without a camera file, the working resolution, overlays that frame what was found.
"""

import io as _io

import numpy as np
import pytest
from PIL import Image, ImageOps

from notchfit.vision.camera import CameraModel
from notchfit.vision.detection import detect_notches, mirror_without_camera
from notchfit.physics.geometry import Geometry, default_geometry
from notchfit.io import image_orientation, load_image
from notchfit.vision.render import place_in_view, render_manipulator
from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

WRIST = Geometry(n_joints=5, p=1.6e-3, outer_radius=0.81e-3, slot_width=0.8e-3, slot_depth=1.3e-3,
                 slot_sides=(1,) * 5, mount_half_width=2.5e-3, name="wrist", inner_radius=0.7e-3,
                 tendons=("right",), tendon_path="lumen", r_x=None, r_z=None, cable_radius=None, channel_radius=None)
BEND = np.array([0.2, 0.25, 0.3, 0.3, 0.25])


def _with_orientation(pixels, tag, fmt):
    """Encoded image bytes holding ``pixels`` and the EXIF orientation ``tag``."""
    im = Image.fromarray(pixels)
    exif = im.getexif()
    exif[0x0112] = tag
    buf = _io.BytesIO()
    im.save(buf, format=fmt, exif=exif.tobytes(), **({"quality": 95} if fmt == "JPEG" else {}))
    return buf.getvalue()


@pytest.mark.parametrize("tag", range(1, 9))
def test_exif_orientation_applied_as_a_photo_viewer_does(tmp_path, tag):
    """Every EXIF orientation (1..8): the loaded pixels are Pillow's ImageOps.exif_transpose of the file."""
    rng = np.random.default_rng(tag)
    pixels = rng.integers(0, 256, (7, 12), dtype=np.uint8)
    data = _with_orientation(pixels, tag, "PNG")
    path = tmp_path / "photo.png"
    path.write_bytes(data)
    expect = np.asarray(ImageOps.exif_transpose(Image.open(_io.BytesIO(data))))
    np.testing.assert_array_equal(load_image(path), expect)
    assert (image_orientation(path) == "") == (tag == 1)


def test_an_exif_rotated_photo_is_detected_as_it_is_seen(tmp_path):
    """A camera held sideways stores the picture turned by 90° with tag 6 ("turn clockwise to view"): the
    tube hangs from the top as the photo viewer shows it, ``base = "top"`` refers to that view, and the
    corners come out in the upright picture's pixels."""
    cam, plane = scene_camera(BEND, WRIST, image_size=(600, 500), mm_per_px=1 / 40, angle_deg=90)
    r = render_scene(BEND, WRIST, cam, plane=plane, scene=Scene(holder="chuck"), rng=np.random.default_rng(7))
    sensor = np.ascontiguousarray(np.rot90(r.image, 1))          # what the sensor stored
    path = tmp_path / "sideways.jpg"
    path.write_bytes(_with_orientation(sensor, 6, "JPEG"))
    img = load_image(path)
    assert img.shape == r.image.shape
    assert image_orientation(path) == "turned 90 degrees clockwise"
    det = detect_notches(img, cam, WRIST, base="top", tone_gamma=1.0)
    ok = np.array(det.status) == "ok"
    assert det.base_side == "top" and ok.sum() >= 12, det.message
    assert np.abs(det.points_px[ok] - r.points_px[ok]).max() < 1.0      # JPEG q95: well under a pixel


@pytest.mark.parametrize("mirror", [False, True])
def test_mirror_means_the_same_with_and_without_a_camera_file(mirror):
    """A camera calibrated on a board seen from its printed side maps pixels to the plane with the image's
    handedness (x right, y down); without a camera file the plane frame is that of the image: the same
    `mirror` flag numbers the same corners, the opposite one numbers none (never a wrong number)."""
    geom = default_geometry()
    cam = CameraModel.synthetic(1920, 1200, mm_per_px=0.03)
    th = np.full(geom.n_joints, 0.05)
    plane, _ = place_in_view(th, geom, cam, phi=np.pi / 2 + 0.2, mirror=mirror)
    r = render_manipulator(th, geom, cam, plane=plane, rng=np.random.default_rng(3))
    assert mirror_without_camera(cam, r.image.shape, mirror) == mirror
    with_cam = detect_notches(r.image, cam, geom, mirror=mirror)
    without = detect_notches(r.image, None, geom, mirror=mirror)
    ok = np.array(with_cam.status) == "ok"
    assert with_cam.n_ok >= 50 and np.array_equal(ok, np.array(without.status) == "ok"), without.message
    np.testing.assert_allclose(without.points_px[ok], with_cam.points_px[ok], atol=0.15)
    # the image's own frame: x right, y down, in mm
    np.testing.assert_allclose(without.points[ok] / (without.scale_mm_per_px * 1e-3), without.points_px[ok],
                               atol=1e-6)
    wrong = detect_notches(r.image, None, geom, mirror=not mirror)
    good = np.array(wrong.status) == "ok"
    assert np.abs(wrong.points_px[good] - r.points_px[good]).max(initial=0.0) < 0.5


def test_working_resolution_follows_the_tube_not_the_file():
    """The working copy's factor comes from the tube's radius and narrowest slot in pixels: the seed tube
    at 0.03 mm/px and the lab's wrist at 130 px/mm keep their factors (2 and 8); a large printed tube in a
    2 MP phone photo at 20 px/mm is worked on at 1/5 (it used to be full resolution); the file's size
    does not enter."""
    from notchfit.vision.detection import DetectorOptions, work_factor

    opts = DetectorOptions()
    printed = Geometry(n_joints=6, p=4e-3, outer_radius=3e-3, slot_width=1.5e-3, slot_depth=4.2e-3,
                       slot_sides=(1, -1, 1, -1, 1, -1), name="printed", inner_radius=2e-3, tendon_path="lumen",
                       r_x=None, r_z=None, cable_radius=None, channel_radius=None)
    assert work_factor(default_geometry(), 1 / 0.03e-3, opts) == 2
    assert work_factor(WRIST, 130e3, opts) == 8
    assert work_factor(printed, 20e3, opts) == 5
    assert work_factor(WRIST, 10e3, opts) == 1                 # a thin tube seen small: full resolution


def test_overlay_frames_a_partial_detection_without_a_sliver():
    """Two corners found far apart on one image row (a partial detection): the crop around them keeps a
    readable shape (sides at most 2:1), in both overlays."""
    from notchfit.vision.detection import overlay_with_crop
    from notchfit.vision.detection.overlay import overlay_crop
    from notchfit.vision.detection.result import Detection

    img = np.full((3000, 4000), 150, np.uint8)
    px = np.full((14, 2), np.nan)
    px[3], px[9] = (200.0, 1500.0), (3800.0, 1510.0)
    det = Detection(px.copy(), px, np.full(14, np.nan), ("occluded",) * 3 + ("ok",) + ("occluded",) * 5 + ("ok",)
                    + ("occluded",) * 4, "partial", "", np.zeros((0, 2)))
    both = overlay_with_crop(img, det, height=500)
    assert both.shape[0] == 500 and both.shape[1] <= 500 * 4000 / 3000 + 8 + 2 * 500 + 2
    crop = overlay_crop(img, det, size=1000)
    assert max(crop.shape[:2]) == 1000 and min(crop.shape[:2]) >= 400


def test_a_geometry_written_for_detection_alone_needs_no_tendon():
    """The dimensions and the slots only: loaded, detected with; what needs a tendon says which keys."""
    from notchfit.physics.geometry import geometry_from_dict

    g = geometry_from_dict({"n_joints": 5, "p_mm": 1.6, "outer_radius_mm": 0.81, "slot_width_mm": 0.8,
                            "slot_depth_mm": 1.3, "base_edge_z_mm": WRIST.base_edge_z * 1e3,
                            "slot_sides": [1] * 5}, "wrist_for_detection.toml")
    assert g.tendons == ()
    cam, plane = scene_camera(BEND, g, image_size=(600, 500), mm_per_px=1 / 40, angle_deg=90)
    r = render_scene(BEND, g, cam, plane=plane, scene=Scene(holder="chuck"), rng=np.random.default_rng(2))
    det = detect_notches(r.image, cam, g)
    assert det.n_ok == r.visible.sum(), det.message
    with pytest.raises(ValueError, match="describes no tendon.*r_x_mm"):
        g.moment_arms(+1)


def test_fit_says_what_happened_to_a_detections_file_without_an_ok_point(tmp_path):
    """A detections.csv whose rows are all occluded or ambiguous: the hint counts them and points at the
    detect run's messages (not "header only?"); a file with the header alone says that."""
    from types import SimpleNamespace

    import pandas as pd

    from notchfit.commands._points import points_problem

    exp = SimpleNamespace(points=np.full((2, 14, 2), np.nan), geometry=WRIST)
    path = tmp_path / "detections.csv"
    rows = [{"sample": s, "point": p, "x_mm": np.nan, "y_mm": np.nan, "u_px": np.nan, "v_px": np.nan,
             "sigma_mm": np.nan, "status": "ambiguous" if p < 4 else "occluded"} for s in (1, 2) for p in range(1, 15)]
    pd.DataFrame(rows).to_csv(path, index=False)
    why = points_problem(exp, path, "fitting")
    assert "header only" not in why and "28 rows" in why and "occluded 22" in why and "ambiguous 6" in why
    assert "detect_run.json" in why
    pd.DataFrame(rows[:0], columns=list(rows[0])).to_csv(path, index=False)
    assert "header only" in points_problem(exp, path, "fitting")
