"""CLI: ``notchfit detect`` and ``notchfit calibrate`` on small rendered images (issue 6)."""

import cv2
import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.vision.camera import CameraModel
from notchfit.cli import main
from notchfit.io import load_board, read_camera, write_camera
from notchfit.vision.render import camera_for_shapes, render_board, render_manipulator


def _experiment(tmp_path, geom, thetas, *, corrupt=None, missing=None):
    cam, planes = camera_for_shapes(thetas, geom, mm_per_px=0.03, phi=0.4)
    folder = tmp_path / "exp"
    (folder / "images").mkdir(parents=True)
    write_camera(cam, folder / "camera.yml")
    rng = np.random.default_rng(3)
    rows, truth = [], []
    for s, th in enumerate(thetas, start=1):
        r = render_manipulator(th, geom, cam, plane=planes[0], rng=rng)
        p = folder / "images" / f"{s:04d}.png"
        if s == corrupt:
            p.write_bytes(b"not a png")
        elif s != missing:
            cv2.imwrite(str(p), r.image)
        truth.append(r.points_plane)
        rows.append({"sample": s, "time_s": float(s), "tension_left_N": 1.0, "tension_right_N": 0.5,
                     "displacement_left_mm": np.nan, "displacement_right_mm": np.nan,
                     "image": f"images/{s:04d}.png"})
    (folder / "experiment.toml").write_text('name = "exp"\ngeometry = "default"\nmirror = false\n'
                                            'calibration = "camera.yml"\n')
    pd.DataFrame(rows).to_csv(folder / "samples.csv", index=False)
    return folder, np.stack(truth)


def test_detect_cli_writes_detections_and_overlays(tmp_path, geom, capsys):
    thetas = [np.zeros(geom.n_joints), np.full(geom.n_joints, 0.04)]
    folder, truth = _experiment(tmp_path, geom, thetas)
    out = tmp_path / "out"
    assert main(["detect", str(folder), "--out", str(out)]) == 0
    df = io.read_detections(out / "detections.csv", n_points=58, sample_ids=[1, 2])
    assert list(df.columns)[:8] == ["sample", "point", "x_mm", "y_mm", "u_px", "v_px", "sigma_mm", "status"]
    assert (df["status"] == "ok").all() and len(df) == 116
    exp = io.load_detected_points(io.read_experiment(folder), out / "detections.csv")
    assert np.abs(exp.points - truth).max() < 0.03e-3
    assert (out / "detect_run.json").is_file()
    # the overlay: a JPEG crop around the tube, its longer side 1000 px, fewer pixels than the image
    crop = cv2.imread(str(out / "overlays" / "0001.jpg"))
    img = cv2.imread(str(folder / "images" / "0001.png"), cv2.IMREAD_UNCHANGED)
    assert max(crop.shape[:2]) == 1000 and crop.shape[0] * crop.shape[1] < img.size
    # nothing overwritten without --force; --full-overlays adds the whole view beside the crop
    assert main(["detect", str(folder), "--out", str(out)]) == 2
    assert main(["detect", str(folder), "--out", str(out), "--force", "--full-overlays"]) == 0
    both = cv2.imread(str(out / "overlays" / "0001.jpg"))
    assert both.shape[0] == 1000 and both.shape[1] > 1000 * img.shape[1] / img.shape[0]


def test_detect_cli_reports_corrupt_and_missing_images(tmp_path, geom, capsys):
    thetas = [np.zeros(geom.n_joints)] * 3
    folder, truth = _experiment(tmp_path, geom, thetas, corrupt=2, missing=3)
    out = tmp_path / "out"
    assert main(["detect", str(folder), "--out", str(out), "--no-overlays"]) == 1
    text = capsys.readouterr().out
    assert "sample 2" in text and "corrupt" in text and "sample 3" in text and "missing" in text
    df = pd.read_csv(out / "detections.csv")
    assert set(df["sample"]) == {1} and (df["status"] == "ok").all()


def test_calibrate_cli(tmp_path, capsys):
    board = load_board("charuco_a4")
    K = np.array([[800.0, 0, 322.0], [0, 805.0, 236.0], [0, 0, 1]])
    cam = CameraModel(K, np.array([-0.1, 0.05, 0.001, -0.0005, 0.0]), (640, 480))
    rng = np.random.default_rng(4)
    paths = []
    c = np.array([board.size[0] / 2, board.size[1] / 2, 0.0])
    for k in range(6):
        rv = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)])
        tv = np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.02, 0.02), 0.38]) - cv2.Rodrigues(rv)[0] @ c
        p = tmp_path / f"view{k}.png"
        cv2.imwrite(str(p), render_board(board, cam, rv, tv, rng=rng).image)
        paths.append(str(p))
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    # the board lying in the plane, seen from the front
    rvp, tvp = np.array([0.05, -0.04, 0.0]), np.array([-0.1, -0.07, 0.40])
    plane = tmp_path / "plane.png"
    cv2.imwrite(str(plane), render_board(board, cam, rvp, tvp, rng=rng).image)
    out = tmp_path / "camera.yml"
    code = main(["calibrate", *paths, str(blank), "--board", "charuco_a4", "--out", str(out),
                 "--plane-image", str(plane)])
    assert code == 1                                   # the blank view is rejected and listed
    assert "REJECTED blank.png: board not found" in capsys.readouterr().out
    got = read_camera(out)
    assert abs(got.camera_matrix[0, 0] / 800 - 1) < 0.005 and got.has_plane
    assert np.allclose(got.plane_tvec, tvp, atol=2e-3)
    assert main(["calibrate", *paths, "--board", "charuco_a4", "--out", str(out)]) == 2     # exists
    assert main(["calibrate", *paths, "--board", "no_such_board", "--out", str(tmp_path / "x.yml")]) == 2


def test_detect_cli_photo_without_calibration_and_stated_base(tmp_path, capsys):
    """A lab photo of a one-sided wrist in a chuck, no camera file, `base = "top"` in experiment.toml:
    the scale comes from the tube's diameter (within 1 %), stated in the log and in detect_run.json."""
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    geom = io.load_geometry(io.datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    th = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
    cam, plane = scene_camera(th, geom, image_size=(700, 500), mm_per_px=1 / 40, angle_deg=90)
    r = render_scene(th, geom, cam, plane=plane, scene=Scene(holder="chuck"), rng=np.random.default_rng(8))
    folder = tmp_path / "exp"
    (folder / "images").mkdir(parents=True)
    cv2.imwrite(str(folder / "images" / "0001.png"), r.image)
    pd.DataFrame([{"sample": 1, "time_s": 1.0, "tension_right_N": 0.5, "image": "images/0001.png"}]) \
        .to_csv(folder / "samples.csv", index=False)
    # the scene camera sees the plane from behind: without its file, the same view is a mirrored one
    (folder / "experiment.toml").write_text(
        f'name = "exp"\ngeometry = "{io.datasets_dir() / "geometry" / "wrist_asymmetric.toml"}"\nbase = "top"\n'
        'mirror = true\n')
    out = tmp_path / "out"
    assert main(["detect", str(folder), "--out", str(out)]) == 0
    assert "outer diameter" in capsys.readouterr().out
    run = io.read_json(out / "detect_run.json")["samples"]["exp"]["sample 1"]
    assert run["base_side"] == "top" and run["assumption"]
    assert abs(run["scale_mm_per_px"] - 1 / 40) < 0.01 / 40
    det = pd.read_csv(out / "detections.csv")
    assert (det["status"] == "ok").sum() == r.visible.sum()
    ov = cv2.imread(str(out / "overlays" / "0001.jpg"))
    assert max(ov.shape[:2]) == 1000                # readable at any photo size: the crop at 1000 px


def _tone_curve_experiment(tmp_path, image_gamma=None):
    """A wrist photographed as a camera writes it: a tone curve (gamma 2.2), blur, JPEG."""
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    geom = io.load_geometry(io.datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    th = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
    cam, plane = scene_camera(th, geom, image_size=(900, 760), mm_per_px=1 / 60, angle_deg=90)
    r = render_scene(th, geom, cam, plane=plane, scene=Scene(holder="chuck", gamma=2.2, blur_sigma=2.0),
                     rng=np.random.default_rng(44))
    folder = tmp_path / f"exp{image_gamma}"
    (folder / "images").mkdir(parents=True)
    write_camera(cam, folder / "camera.yml")
    cv2.imwrite(str(folder / "images" / "0001.jpg"), r.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    pd.DataFrame([{"sample": 1, "time_s": 1.0, "tension_right_N": 0.5, "image": "images/0001.jpg"}]) \
        .to_csv(folder / "samples.csv", index=False)
    gamma = "" if image_gamma is None else f"image_gamma = {image_gamma}\n"
    (folder / "experiment.toml").write_text(f'name = "exp"\ngeometry = "{io.datasets_dir() / "geometry"}'
                                            f'/wrist_asymmetric.toml"\ncalibration = "camera.yml"\n{gamma}')
    return folder, r


def test_detect_undoes_a_cameras_tone_curve_in_jpeg_files(tmp_path, capsys):
    """JPEG files without image_gamma are taken as a camera's tone curve (gamma 2.2, said in the log and
    detect_run.json): the corners come out as in linear light; image_gamma = 1 keeps the values, and
    the 50 % crossings of the blurred edges move toward the dark side (about 0.3 sigma of blur)."""
    rms = {}
    for g in (None, 1):
        folder, r = _tone_curve_experiment(tmp_path, g)
        out = tmp_path / f"out{g}"
        assert main(["detect", str(folder), "--out", str(out), "--no-overlays"]) == 0
        said = capsys.readouterr().out
        run = io.read_json(out / "detect_run.json")
        assert ("assumed a camera's tone curve" in said) == (g is None)
        assert run["image_gamma_assumed"] == (["exp"] if g is None else [])
        assert run["samples"]["exp"]["sample 1"]["image_gamma"] == (2.2 if g is None else 1.0)
        det = pd.read_csv(out / "detections.csv")
        ok = (det["status"] == "ok").to_numpy()
        uv = det[["u_px", "v_px"]].to_numpy()[ok]
        err = np.linalg.norm(uv - r.points_px[det["point"].to_numpy()[ok] - 1], axis=1) / 60
        rms[g] = np.sqrt(np.mean(err ** 2))
    assert rms[None] <= 0.003 < rms[1]


def test_image_gamma_out_of_range_names_the_line(tmp_path):
    folder, _ = _tone_curve_experiment(tmp_path, 0.5)
    with pytest.raises(ValueError, match=r"line 4: image_gamma must be a number from 1 \(linear light\) to 4"):
        io.read_experiment(folder)
