"""Sample views of a calibration board: the images shipped in ``calibration/samples/``.

They let ``notchfit calibrate`` be tried in one command (README, "Working
with your own data"). They were written by::

    from notchfit.io import calibration_dir, load_board, write_image
    from notchfit.vision.render.boards import sample_board_views
    for name, v in sample_board_views(load_board("charuco_a4")).items():
        write_image(calibration_dir() / "samples" / "charuco_a4" / f"{name}.jpg", v.image, jpeg_quality=90)

with the defaults below (JPEG at quality 90 keeps each view near 60 KB and moves
the calibration's reprojection rms by less than 0.001 px, docs/history.md); the
test suite renders them again and compares. The renderer writes no files itself:
vision sits below the file I/O (docs/architecture.md).
"""

from __future__ import annotations


import cv2
import numpy as np

from ..camera import Board, CameraModel
from . import RenderedBoard, render_board

__all__ = ["SAMPLE_CAMERA", "SAMPLE_PLANE_POSE", "board_poses", "sample_board_views"]

#: The camera of the sample views: 640 x 480 px, f ≈ 800 px, mild barrel distortion.
SAMPLE_CAMERA = CameraModel(np.array([[800.0, 0.0, 322.0], [0.0, 805.0, 236.0], [0.0, 0.0, 1.0]]),
                            np.array([-0.1, 0.05, 0.001, -0.0005, 0.0]), (640, 480))
#: Pose of the board lying in the bending plane, seen nearly from the front (rvec, tvec [m]).
SAMPLE_PLANE_POSE = (np.array([0.05, -0.04, 0.0]), np.array([-0.1, -0.07, 0.40]))


def board_poses(board: Board, n: int, rng, *, distance: float = 0.38, tilt: float = 0.5,
                spin: float = 0.3, shift=(0.03, 0.02)) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` random poses of ``board``, its centre about ``distance`` in front of the camera.

    Parameters
    ----------
    board : Board
    n : int
    rng : numpy.random.Generator
    distance : float
        Distance of the board's centre from the camera [m].
    tilt, spin : float
        Largest rotation about the board's x/y axes and about the optical axis [rad].
    shift : (float, float)
        Largest sideways offset of the centre [m].

    Returns
    -------
    list of (rvec (3,), tvec (3,) [m])
        ``X_cam = R(rvec) X_board + tvec``.
    """
    c = np.array([board.size[0] / 2, board.size[1] / 2, 0.0])
    out = []
    for _ in range(n):
        rv = np.array([rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-spin, spin)])
        tv = np.array([rng.uniform(-shift[0], shift[0]), rng.uniform(-shift[1], shift[1]), distance])
        out.append((rv, tv - cv2.Rodrigues(rv)[0] @ c))
    return out


def sample_board_views(board: Board, *, camera: CameraModel = SAMPLE_CAMERA, n_views: int = 5,
                       seed: int = 4, plane_pose=SAMPLE_PLANE_POSE) -> dict[str, RenderedBoard]:
    """Rendered views of ``board`` for a calibration: ``view1..view<n>`` and ``plane``.

    Returns
    -------
    dict
        ``{name: RenderedBoard}``; ``plane`` is the board lying in the bending
        plane at ``plane_pose`` (``calibrate --plane-image``).
    """
    rng = np.random.default_rng(seed)
    views = {f"view{k + 1}": render_board(board, camera, rv, tv, rng=rng)
             for k, (rv, tv) in enumerate(board_poses(board, n_views, rng))}
    views["plane"] = render_board(board, camera, *plane_pose, rng=rng)
    return views
