"""``notchfit calibrate``: camera intrinsics, distortion and the metric bending plane."""

from __future__ import annotations

from pathlib import Path

from ..io import load_board, load_image, write_camera
from ..progress import bar as progress_bar
from ._common import EXIT_ITEMS_FAILED, InputError

NAME = "calibrate"
ORDER = 20
HELP = "calibrate the camera from board images (ChArUco or chessboard) and the bending plane"
DESCRIPTION = """Calibrate a camera from several images of a calibration board (ChArUco with the
cv2.aruco API, or a plain chessboard) and, with --plane-image, the pose of the metric bending
plane from one image of the board lying in the manipulator's bending plane (its frame becomes
the plane frame of the measured points, in mm).

Board definitions are TOML files (calibration/*.toml ships charuco_a4, charuco_small and
chessboard_9x6; give a name or a path). Views with too few corners, collinear corners or a
high reprojection error are rejected with their reason. Writes an OpenCV FileStorage YAML
camera file (camera_matrix, distortion_coefficients, image_width, image_height,
avg_reprojection_error, plane_rvec, plane_tvec [mm]) that cv2.FileStorage reads.

Examples:
  notchfit calibrate calib/*.png --board charuco_a4 --out camera.yml
  notchfit calibrate calib/*.png --board my_board.toml --out camera.yml --plane-image plane.png
  notchfit calibrate calib/*.png --board chessboard_9x6 --dist-model k1k2p1p2k3 --out cam.yml --force
"""


def add_arguments(parser) -> None:
    parser.add_argument("images", type=Path, nargs="+", help="board images (3 or more views)")
    parser.add_argument("--board", required=True, help="board TOML file or the name of a shipped board")
    parser.add_argument("--out", type=Path, required=True, help="camera file to write (.yml)")
    parser.add_argument("--plane-image", type=Path, default=None,
                        help="image of the board lying in the bending plane (defines the plane frame)")
    parser.add_argument("--plane-board", default=None, help="board of the plane image (default: --board)")
    parser.add_argument("--dist-model", default="k1k2p1p2", help="k1k2p1p2 (default), k1k2p1p2k3 or rational")
    parser.add_argument("--max-view-rms", type=float, default=1.0,
                        help="reject views above this reprojection rms [px] (and 3x the median)")
    parser.add_argument("--force", action="store_true", help="replace an existing camera file")


def run(args) -> int:
    # slow optional dependency: notchfit.vision.camera imports cv2
    from ..vision.camera import calibrate_camera, detect_board, estimate_plane_pose

    if args.out.exists() and not args.force:
        raise InputError(f"{args.out} exists; use --force to replace it")
    board = load_board(args.board)
    images, names, found, unreadable = [], [], [], {}
    with progress_bar(len(args.images), "calibrate: finding the board", unit="images") as bar:
        for p in args.images:
            bar.update(1)
            try:
                img = load_image(p)
            except (FileNotFoundError, ValueError) as exc:
                unreadable[p.name] = str(exc)
                continue
            images.append(img)
            names.append(p.name)
            found.append(detect_board(img, board))
    if not images:
        raise InputError("no readable calibration image: " + "; ".join(unreadable.values()))
    cal = calibrate_camera(images, board, names=names, detections=found, dist_model=args.dist_model,
                           max_view_rms=args.max_view_rms)
    cam = cal.camera
    if args.plane_image is not None:
        pboard = load_board(args.plane_board) if args.plane_board else board
        img = load_image(args.plane_image)
        cam.check_image(img)
        pose = estimate_plane_pose(img, pboard, cam)
        cam = cam.with_plane(pose.rvec, pose.tvec, pose.rms)
    write_camera(cam, args.out, extra={"board": board.name, "views_used": cal.n_used})
    print(f"calibrate: {cal.n_used} of {len(args.images)} views used, reprojection rms {cal.rms:.3f} px "
          f"({cal.rounds} rounds); camera file {args.out}")
    for name, val, std in cal.intrinsics_table():
        print(f"  {name:6s} {val: .6g} +- {std:.2g}")
    if args.plane_image is not None:
        print(f"  plane: {args.plane_image.name}, reprojection rms {cam.plane_rms:.3f} px")
    rejected = {v.name: v.reason for v in cal.views if not v.used}
    rejected.update(unreadable)
    for k, v in rejected.items():
        print(f"  REJECTED {k}: {v}")
    return EXIT_ITEMS_FAILED if rejected else 0
