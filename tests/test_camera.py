"""Camera calibration, plane pose and camera file (issue 6; data-format.md "Camera calibration file")."""

import math

import cv2
import numpy as np
import pytest

from notchfit.vision.camera import CameraModel, BoardDetection, calibrate_camera, detect_board, estimate_plane_pose
from notchfit.io import load_board, read_camera, write_camera
from notchfit.vision.render import render_board

K_TRUE = np.array([[800.0, 0, 322.0], [0, 805.0, 236.0], [0, 0, 1]])
D_TRUE = np.array([-0.1, 0.05, 0.001, -0.0005, 0.0])


def _cam():
    return CameraModel(K_TRUE, D_TRUE, (640, 480))


def _poses(board, n, rng, dist=0.38):
    c = np.array([board.size[0] / 2, board.size[1] / 2, 0.0])
    out = []
    for _ in range(n):
        rv = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)])
        R = cv2.Rodrigues(rv)[0]
        tv = np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.02, 0.02), dist]) - R @ c
        out.append((rv, tv))
    return out


@pytest.fixture(scope="module")
def charuco_views():
    board = load_board("charuco_a4")
    rng = np.random.default_rng(6)
    return board, [render_board(board, _cam(), rv, tv, rng=rng) for rv, tv in _poses(board, 8, rng)]


def test_shipped_boards_load():
    for name in ("charuco_a4", "charuco_small", "chessboard_9x6"):
        b = load_board(name)
        assert b.n_corners == (b.squares_x - 1) * (b.squares_y - 1)
    with pytest.raises(FileNotFoundError, match="shipped boards"):
        load_board("no_such_board")


def test_charuco_calibration_round_trip(charuco_views):
    """Rendered ChArUco views (blur 0.7 px, noise 1 %): f and principal point within 0.5 %."""
    board, views = charuco_views
    for v in views:
        det = detect_board(v.image, board)
        assert det.n >= board.n_corners // 2
        err = np.linalg.norm(det.image_points - v.corners_px[det.ids], axis=1)
        assert np.sqrt(np.mean(err ** 2)) < 0.15          # corner localisation [px]
    cal = calibrate_camera([v.image for v in views], board)
    K = cal.camera.camera_matrix
    assert cal.n_used == len(views)
    assert abs(K[0, 0] / 800.0 - 1) < 0.005 and abs(K[1, 1] / 805.0 - 1) < 0.005
    assert abs(K[0, 2] / 322.0 - 1) < 0.005 and abs(K[1, 2] / 236.0 - 1) < 0.005
    assert 0 < cal.rms < 0.2
    assert cal.camera.std_intrinsics is not None and np.all(cal.camera.std_intrinsics[:4] > 0)


def test_calibration_rms_matches_injected_corner_noise():
    """Exact corners + Gaussian noise sigma per coordinate -> rms ~ sigma*sqrt(2)*sqrt(1 - p/(2N))."""
    board = load_board("charuco_a4")
    rng = np.random.default_rng(11)
    sigma = 0.3
    dets = []
    for rv, tv in _poses(board, 10, rng):
        obj = board.corner_points()
        uv, _ = cv2.projectPoints(obj, rv, tv, K_TRUE, D_TRUE)
        uv = uv.reshape(-1, 2) + rng.normal(0, sigma, (len(obj), 2))
        dets.append(BoardDetection(obj, uv, np.arange(len(obj))))
    cal = calibrate_camera([], board, detections=dets, image_size=(640, 480))
    n_obs = 2 * sum(d.n for d in dets)
    n_par = 8 + 6 * len(dets)
    expected = sigma * math.sqrt(2) * math.sqrt(1 - n_par / n_obs)    # cv2 rms is per point (2-D)
    assert abs(cal.rms / expected - 1) < 0.15
    # the principal point moves within its reported standard deviation at this noise level
    K, std = cal.camera.camera_matrix, cal.camera.std_intrinsics
    assert abs(K[0, 0] - 800.0) < 4 * std[0] and abs(K[0, 2] - 322.0) < 4 * std[2]


def test_bad_view_rejected_with_reason():
    board = load_board("charuco_a4")
    rng = np.random.default_rng(12)
    dets = []
    for k, (rv, tv) in enumerate(_poses(board, 7, rng)):
        obj = board.corner_points()
        uv, _ = cv2.projectPoints(obj, rv, tv, K_TRUE, D_TRUE)
        uv = uv.reshape(-1, 2) + rng.normal(0, 0.05, (len(obj), 2))
        if k == 3:
            uv += rng.normal(0, 4.0, uv.shape)                 # a smeared view
        dets.append(BoardDetection(obj, uv, np.arange(len(obj))))
    dets.append(BoardDetection(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, int)))
    cal = calibrate_camera([], board, detections=dets, image_size=(640, 480))
    reasons = {v.name: v.reason for v in cal.views}
    assert "high reprojection error" in reasons["view4"]
    assert reasons["view8"] == "board not found"
    assert cal.n_used == 6 and cal.rms < 0.1
    with pytest.raises(ValueError, match="usable calibration views"):
        calibrate_camera([], board, detections=dets[:2], image_size=(640, 480))


def test_chessboard_calibration():
    board = load_board("chessboard_9x6")
    rng = np.random.default_rng(3)
    views = [render_board(board, _cam(), rv, tv, rng=rng) for rv, tv in _poses(board, 6, rng, dist=0.5)]
    cal = calibrate_camera([v.image for v in views], board)
    K = cal.camera.camera_matrix
    assert abs(K[0, 0] / 800.0 - 1) < 0.005 and abs(K[1, 2] / 236.0 - 1) < 0.005


@pytest.fixture(scope="module")
def plane_setup():
    cam = CameraModel.synthetic(640, 480, mm_per_px=0.06)
    board = load_board("charuco_small")
    R = cv2.Rodrigues(np.asarray(cam.plane_rvec))[0]
    # the board lies in the plane: its frame equals the plane frame shifted by (-15, -12) mm
    off = np.array([-15e-3, -12e-3, 0.0])
    rv, tv = cam.plane_rvec, cam.plane_tvec + R @ off
    img = render_board(board, cam, rv, tv, rng=np.random.default_rng(2), blur_sigma=0.8).image
    return cam, board, img, rv, tv


def test_plane_pose_from_board_image(plane_setup):
    cam, board, img, rv, tv = plane_setup
    pose = estimate_plane_pose(img, board, cam.replace(plane_rvec=None, plane_tvec=None))
    assert pose.rms < 0.2
    # a long lens (f = 4000 px) barely constrains the small board's tilt (near-orthographic view); the
    # pixel -> plane map, which is what the detector uses, is checked below
    R_est, R_true = cv2.Rodrigues(pose.rvec)[0], cv2.Rodrigues(np.asarray(rv))[0]
    assert np.degrees(np.arccos(np.clip((np.trace(R_est.T @ R_true) - 1) / 2, -1, 1))) < 2.0
    cam2 = cam.with_plane(pose.rvec, pose.tvec, pose.rms)
    # plane points of the board agree within 0.01 mm over the board
    P = board.corner_points()[:, :2]
    uv_true = cv2.projectPoints(board.corner_points(), np.asarray(rv), np.asarray(tv), cam.camera_matrix,
                                cam.dist_coeffs)[0].reshape(-1, 2)
    # measured: 0.031 mm max (0.5 px) for this 32 x 24 mm board seen at 0.06 mm/px from one image
    err = np.linalg.norm(cam2.pixel_to_plane(uv_true) - P, axis=1)
    assert err.max() < 4e-5 and np.sqrt(np.mean(err ** 2)) < 1.5e-5
    with pytest.raises(ValueError, match="board not found"):
        estimate_plane_pose(np.full_like(img, 128), board, cam)


def test_pixel_plane_round_trip():
    cam = CameraModel.synthetic(1920, 1200)
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], [1919, 1199], (500, 2))
    xy = cam.pixel_to_plane(uv)
    assert np.abs(cam.plane_to_pixel(xy) - uv).max() < 1e-6
    und = cam.undistort_pixels(uv)
    assert np.abs(cam.distort_pixels(und) - uv).max() < 1e-6
    # consistent with cv2.projectPoints
    XY = np.column_stack([xy, np.zeros(len(xy))])
    ref = cv2.projectPoints(XY, np.asarray(cam.plane_rvec), np.asarray(cam.plane_tvec), cam.camera_matrix,
                            cam.dist_coeffs)[0].reshape(-1, 2)
    assert np.abs(ref - uv).max() < 1e-6
    assert abs(cam.plane_scale() * 1e-3 - 1 / 0.03) / (1 / 0.03) < 0.01


def test_camera_yaml_round_trip_opencv_keys(tmp_path):
    cam = CameraModel.synthetic(1920, 1200).replace(rms=0.123, std_intrinsics=np.arange(1, 10) * 0.1,
                                                    per_view_errors=np.array([0.1, 0.2]))
    path = write_camera(cam, tmp_path / "camera.yml")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.allclose(fs.getNode("camera_matrix").mat(), cam.camera_matrix)
    assert fs.getNode("distortion_coefficients").mat().shape == (1, 5)
    assert int(fs.getNode("image_width").real()) == 1920 and int(fs.getNode("image_height").real()) == 1200
    assert fs.getNode("avg_reprojection_error").real() == pytest.approx(0.123)
    assert fs.getNode("plane_rvec").mat().shape == (3, 1)
    assert np.allclose(fs.getNode("plane_tvec").mat().ravel(), np.asarray(cam.plane_tvec) * 1e3)   # mm
    fs.release()
    back = read_camera(path)
    assert np.allclose(back.camera_matrix, cam.camera_matrix) and np.allclose(back.dist_coeffs, cam.dist_coeffs)
    assert np.allclose(back.plane_tvec, cam.plane_tvec) and np.allclose(back.plane_rvec, cam.plane_rvec)
    assert back.image_size == (1920, 1200) and back.rms == pytest.approx(0.123)


def test_read_camera_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_camera(tmp_path / "none.yml")
    bad = tmp_path / "bad.yml"
    bad.write_text("%YAML:1.0\n---\nimage_width: 10\n")
    with pytest.raises(ValueError, match="camera_matrix"):
        read_camera(bad)
    junk = tmp_path / "junk.yml"
    junk.write_text("this is not { yaml")
    with pytest.raises(ValueError, match="junk.yml"):
        read_camera(junk)
    cam = CameraModel.synthetic(100, 80)
    with pytest.raises(ValueError, match="wrong calibration file"):
        cam.check_image(np.zeros((81, 100)))


def test_board_file_errors_name_file_and_line(tmp_path):
    from notchfit.io import TomlError

    f = tmp_path / "b.toml"
    f.write_text('type = "chessboard"\nsquares_x = 7\nsquares_y = 5\nsquare_mm = -3\n')
    with pytest.raises(TomlError, match=r"b\.toml: line 4: square_mm must be a positive number"):
        load_board(f)
    f.write_text('type = "chessboard"\nsquares_x = 7\nsquares_y = 5\nsquare_mm = 3\ncolour = "red"\n')
    with pytest.raises(TomlError, match=r"b\.toml: line 5: unknown board key\(s\) colour"):
        load_board(f)
    f.write_text('type = "chessboard"\nsquares_x = 7\n')
    with pytest.raises(TomlError, match=r"b\.toml: missing board key\(s\) squares_y, square_mm"):
        load_board(f)
    assert load_board("chessboard_9x6").kind == "chessboard"


def test_camera_file_has_normal_permissions(tmp_path):
    import os

    mask = os.umask(0o022)
    try:
        path = write_camera(CameraModel.synthetic(), tmp_path / "camera.yml")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["camera.yml"]


def test_shipped_sample_views_are_the_rendered_board():
    """calibration/samples/charuco_a4 (README: `calibrate` in one command) are the views
    notchfit.vision.render.boards renders (JPEG quality 90: a few DN apart), small, and they calibrate
    to the camera they were rendered with."""
    from notchfit.io import calibration_dir, load_image
    from notchfit.vision.render.boards import SAMPLE_CAMERA, SAMPLE_PLANE_POSE, sample_board_views

    folder = calibration_dir() / "samples" / "charuco_a4"
    board = load_board("charuco_a4")
    views = sample_board_views(board)
    assert sorted(p.stem for p in folder.glob("*.jpg")) == sorted(views)
    for name, v in views.items():
        path = folder / f"{name}.jpg"
        assert path.stat().st_size < 80_000
        diff = np.abs(load_image(path).astype(float) - v.image)
        assert diff.mean() < 2.0 and np.percentile(diff, 99) < 12, name
    images = [load_image(folder / f"view{k}.jpg") for k in range(1, 6)]
    cal = calibrate_camera(images, board)
    K = cal.camera.camera_matrix
    assert cal.n_used == 5 and cal.rms < 0.2
    assert np.allclose(K[[0, 1, 0, 1], [0, 1, 2, 2]], SAMPLE_CAMERA.camera_matrix[[0, 1, 0, 1], [0, 1, 2, 2]],
                       rtol=0.01)
    pose = estimate_plane_pose(load_image(folder / "plane.jpg"), board, cal.camera)
    assert np.allclose(np.ravel(pose.tvec), SAMPLE_PLANE_POSE[1], atol=3e-3)
