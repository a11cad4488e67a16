"""Camera calibration and the metric bending plane (docs/data-formats.md).

A :class:`CameraModel` holds the pinhole intrinsics and lens distortion of a
camera (OpenCV model and order ``k1 k2 p1 p2 k3 ...``) and, optionally, the
pose of the **bending plane**: ``X_cam = R(plane_rvec) X_plane + plane_tvec``
with ``X_plane = (x, y, 0)``. The plane frame is the frame of a calibration
board lying in the manipulator's bending plane (board x along its columns,
y along its rows, origin at the board's top-left outer corner, z into the
board). Everything inside is SI (``plane_tvec`` in m); the camera file
(read and written by :mod:`notchfit.io.camera`) stores ``plane_tvec`` in mm.

Calibration boards (:class:`Board`; their TOML definitions in ``calibration/``
are read by :func:`notchfit.io.load_board`):
ChArUco boards (``cv2.aruco.CharucoBoard`` + ``CharucoDetector.detectBoard``
+ ``board.matchImagePoints``, the OpenCV >= 4.7 / 5.0 API) and plain
chessboards (``findChessboardCornersSB`` + ``cornerSubPix``). Intrinsics come
from ``cv2.calibrateCameraExtended`` (with standard deviations and per-view
errors); bad views are rejected with a reason and the calibration repeated.

Pixels follow CONVENTIONS.md: ``(u, v)`` = (column, row), integer values at
pixel centres.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..imaging import to_gray8
from ..units import MM
from ..validation import readonly

__all__ = [
    "Board",
    "BoardDetection",
    "Calibration",
    "CameraModel",
    "DIST_LENGTHS",
    "PlanePose",
    "ViewReport",
    "calibrate_camera",
    "detect_board",
    "estimate_plane_pose",
]

#: Numbers of OpenCV distortion coefficients a camera model may hold.
DIST_LENGTHS = (4, 5, 8, 12, 14)
_INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6",
                    "s1", "s2", "s3", "s4", "tau_x", "tau_y")


# ----------------------------------------------------------------------------- boards
@dataclass(frozen=True)
class Board:
    """A planar calibration target.

    Attributes
    ----------
    name : str
    kind : str
        ``"charuco"`` or ``"chessboard"``.
    squares_x, squares_y : int
        Number of squares along the board's x (columns) and y (rows).
    square_size : float
        Side of a chessboard square [m].
    marker_size : float or None
        Side of an ArUco marker [m] (ChArUco only).
    dictionary : str or None
        Predefined ArUco dictionary name, e.g. ``"DICT_5X5_100"``.
    legacy : bool
        ``CharucoBoard.setLegacyPattern(True)``: boards made before OpenCV 4.6
        (and some stock boards with an even number of rows).
    """

    name: str
    kind: str
    squares_x: int
    squares_y: int
    square_size: float
    marker_size: float | None = None
    dictionary: str | None = None
    legacy: bool = False

    def __post_init__(self):
        if self.kind not in ("charuco", "chessboard"):
            raise ValueError(f"board {self.name!r}: type must be 'charuco' or 'chessboard', got {self.kind!r}")
        for f in ("squares_x", "squares_y"):
            v = getattr(self, f)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 2:
                raise ValueError(f"board {self.name!r}: {f} must be an integer >= 2, got {v!r}")
        if not (math.isfinite(self.square_size) and self.square_size > 0):
            raise ValueError(f"board {self.name!r}: square size must be positive, got {self.square_size!r}")
        if self.kind == "charuco":
            if self.marker_size is None or not (0 < self.marker_size < self.square_size):
                raise ValueError(f"board {self.name!r}: a ChArUco board needs 0 < marker size < square size")
            if not self.dictionary or not hasattr(cv2.aruco, str(self.dictionary)):
                raise ValueError(f"board {self.name!r}: unknown ArUco dictionary {self.dictionary!r} "
                                 "(expected a cv2.aruco name such as DICT_5X5_100)")

    @property
    def inner_corners(self) -> tuple[int, int]:
        """Inner chessboard corners (per row, per column)."""
        return (self.squares_x - 1, self.squares_y - 1)

    @property
    def n_corners(self) -> int:
        return (self.squares_x - 1) * (self.squares_y - 1)

    @property
    def size(self) -> tuple[float, float]:
        """Board extent (width, height) [m]."""
        return (self.squares_x * self.square_size, self.squares_y * self.square_size)

    def corner_points(self) -> np.ndarray:
        """All inner corners in the board frame, in id order, shape (N, 3) [m].

        Id ``k`` is row ``k // (squares_x - 1)``, column ``k % (squares_x - 1)``
        at ``((col + 1) s, (row + 1) s, 0)`` (OpenCV's ChArUco numbering).
        """
        nx, ny = self.inner_corners
        j, i = np.mgrid[0:ny, 0:nx]
        pts = np.stack([(i.ravel() + 1) * self.square_size, (j.ravel() + 1) * self.square_size,
                        np.zeros(nx * ny)], axis=1)
        return pts

    def cv_board(self):
        """The ``cv2.aruco.CharucoBoard`` (board units: mm)."""
        if self.kind != "charuco":
            raise ValueError(f"board {self.name!r} is a plain chessboard, not a ChArUco board")
        return _cv_charuco(self.squares_x, self.squares_y, self.square_size / MM,
                           self.marker_size / MM, self.dictionary, self.legacy)


@functools.lru_cache(maxsize=16)
def _cv_charuco(sx, sy, square_mm, marker_mm, dictionary, legacy):
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    b = cv2.aruco.CharucoBoard((int(sx), int(sy)), float(square_mm), float(marker_mm), d)
    if legacy:
        b.setLegacyPattern(True)
    return b


# ----------------------------------------------------------------------------- camera model
@dataclass(frozen=True, eq=False)
class CameraModel:
    """A calibrated camera and (optionally) the pose of the bending plane.

    Attributes
    ----------
    camera_matrix : ndarray (3, 3)
        ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` [px].
    dist_coeffs : ndarray (k,)
        OpenCV distortion coefficients ``k1 k2 p1 p2 [k3 ...]``, k in 4, 5, 8, 12, 14.
    image_size : tuple (width, height) [px]
    plane_rvec : ndarray (3,) or None
        Rotation vector of the plane frame in the camera frame.
    plane_tvec : ndarray (3,) or None
        Origin of the plane frame in the camera frame [m].
    rms : float
        Overall reprojection rms of the calibration [px] (NaN if unknown).
    std_intrinsics : ndarray or None
        Standard deviations of ``fx, fy, cx, cy, k1, k2, p1, p2, k3, ...`` [px, -].
    per_view_errors : ndarray or None
        Reprojection rms of each view used [px].
    plane_rms : float
        Reprojection rms of the plane-pose fit [px] (NaN if unknown).
    """

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple
    plane_rvec: np.ndarray | None = None
    plane_tvec: np.ndarray | None = None
    rms: float = math.nan
    std_intrinsics: np.ndarray | None = None
    per_view_errors: np.ndarray | None = None
    plane_rms: float = math.nan

    def __post_init__(self):
        K = np.asarray(self.camera_matrix, dtype=float)
        if K.shape != (3, 3) or not np.isfinite(K).all():
            raise ValueError(f"camera_matrix must be a finite 3x3 matrix, got shape {K.shape}")
        if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
            raise ValueError("camera_matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        d = np.asarray(self.dist_coeffs, dtype=float).ravel()
        if d.size == 0:
            d = np.zeros(5)
        if d.size not in DIST_LENGTHS or not np.isfinite(d).all():
            raise ValueError(f"distortion_coefficients must hold 4, 5, 8, 12 or 14 finite numbers, got {d.size}")
        w, h = (int(x) for x in self.image_size)
        if w <= 0 or h <= 0:
            raise ValueError(f"image size must be positive, got {self.image_size}")
        if (self.plane_rvec is None) != (self.plane_tvec is None):
            raise ValueError("plane_rvec and plane_tvec must be given together")
        object.__setattr__(self, "camera_matrix", readonly(K))
        object.__setattr__(self, "dist_coeffs", readonly(d))
        object.__setattr__(self, "image_size", (w, h))
        if self.plane_rvec is not None:
            rv, tv = np.asarray(self.plane_rvec, float).ravel(), np.asarray(self.plane_tvec, float).ravel()
            if rv.size != 3 or tv.size != 3 or not (np.isfinite(rv).all() and np.isfinite(tv).all()):
                raise ValueError("plane_rvec and plane_tvec must hold 3 finite numbers each")
            object.__setattr__(self, "plane_rvec", readonly(rv))
            object.__setattr__(self, "plane_tvec", readonly(tv))
        for f in ("std_intrinsics", "per_view_errors"):
            object.__setattr__(self, f, readonly(getattr(self, f)))

    # -- construction -----------------------------------------------------------------
    @classmethod
    def synthetic(cls, width: int = 1920, height: int = 1200, *, mm_per_px: float = 0.03,
                  focal_px: float = 4000.0, dist=(-0.08, 0.05, 0.0003, -0.0002, 0.0),
                  tilt_deg=(3.0, -2.0), plane_center_mm=(12.0, 0.0), plane_angle_deg: float = -90.0):
        """A plausible bench camera looking at the bending plane (for synthetic data).

        The plane is at the distance that gives ``mm_per_px`` at the image
        centre, tilted by ``tilt_deg`` (about the camera x and y axes), and
        rotated by ``plane_angle_deg`` about the optical axis; the plane point
        ``plane_center_mm`` is on the optical axis. With the defaults the
        plane's +y axis runs along +u (the manipulator lies horizontally).

        Returns
        -------
        CameraModel
        """
        K = np.array([[focal_px, 0.0, (width - 1) / 2.0], [0.0, focal_px, (height - 1) / 2.0], [0, 0, 1]])
        dist_m = focal_px * mm_per_px * MM
        ax, ay = (math.radians(t) for t in tilt_deg)
        c = math.radians(plane_angle_deg)
        Rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
        Rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
        Ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
        R = Rx @ Ry @ Rz
        pc = np.array([plane_center_mm[0] * MM, plane_center_mm[1] * MM, 0.0])
        t = np.array([0.0, 0.0, dist_m]) - R @ pc
        rvec = cv2.Rodrigues(R)[0].ravel()
        return cls(K, np.asarray(dist, float), (width, height), rvec, t)

    def with_plane(self, rvec, tvec, plane_rms: float = math.nan) -> "CameraModel":
        """A copy with the plane pose set (``tvec`` in m)."""
        return dataclasses.replace(self, plane_rvec=rvec, plane_tvec=tvec, plane_rms=plane_rms)

    def replace(self, **changes) -> "CameraModel":
        return dataclasses.replace(self, **changes)

    # -- properties --------------------------------------------------------------------
    @property
    def has_plane(self) -> bool:
        return self.plane_rvec is not None

    def _need_plane(self):
        if not self.has_plane:
            raise ValueError("the camera model has no plane pose (plane_rvec/plane_tvec); "
                             "calibrate with --plane-image")

    @property
    def plane_rotation(self) -> np.ndarray:
        self._need_plane()
        return cv2.Rodrigues(np.asarray(self.plane_rvec, float))[0]

    @property
    def plane_homography(self) -> np.ndarray:
        """``H`` mapping plane (x, y, 1) [m] to undistorted pixels (u, v, 1) (3, 3)."""
        R = self.plane_rotation
        H = self.camera_matrix @ np.column_stack([R[:, 0], R[:, 1], self.plane_tvec])
        return H / H[2, 2]

    # -- mappings ----------------------------------------------------------------------
    def undistort_pixels(self, uv, *, iterations: int = 20, eps: float = 1e-9, normalized: bool = False):
        """Raw (distorted) pixels -> ideal pinhole pixels (or normalized coordinates).

        Parameters
        ----------
        uv : array_like (..., 2) [px]
        iterations, eps : OpenCV's iterative undistortion criteria.
        normalized : bool
            Return normalized image coordinates ``(x/z, y/z)`` instead of pixels.

        Returns
        -------
        ndarray (..., 2)
        """
        uv = np.asarray(uv, dtype=float)
        shape = uv.shape
        if shape[-1] != 2:
            raise ValueError(f"pixel coordinates must have shape (..., 2), got {shape}")
        pts = uv.reshape(-1, 1, 2)
        if pts.shape[0] == 0:
            return uv.copy()
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, int(iterations), float(eps))
        P = None if normalized else self.camera_matrix
        out = cv2.undistortPoints(pts, self.camera_matrix, self.dist_coeffs, None, None, P, crit)
        out = out.reshape(shape)
        bad = ~np.isfinite(uv).all(axis=-1)
        if bad.any():
            out[bad] = np.nan
        return out

    def distort_pixels(self, uv_ideal) -> np.ndarray:
        """Ideal pinhole pixels -> raw (distorted) pixels, shape (..., 2)."""
        uv = np.asarray(uv_ideal, dtype=float)
        shape = uv.shape
        K = self.camera_matrix
        flat = uv.reshape(-1, 2)
        y = (flat[:, 1] - K[1, 2]) / K[1, 1]
        x = (flat[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        return self._project_normalized(np.stack([x, y], -1)).reshape(shape)

    def _project_normalized(self, xy):
        n = xy.shape[0]
        out = np.full((n, 2), np.nan)
        ok = np.isfinite(xy).all(axis=1)
        if ok.any():
            obj = np.concatenate([xy[ok], np.ones((ok.sum(), 1))], axis=1)
            proj, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), self.camera_matrix, self.dist_coeffs)
            out[ok] = proj.reshape(-1, 2)
        return out

    def plane_to_pixel(self, xy) -> np.ndarray:
        """Plane-frame points [m] -> raw image pixels (with distortion).

        Parameters
        ----------
        xy : array_like (..., 2) [m]

        Returns
        -------
        ndarray (..., 2) [px]; NaN where the input is NaN.
        """
        self._need_plane()
        xy = np.asarray(xy, dtype=float)
        if xy.shape[-1] != 2:
            raise ValueError(f"plane points must have shape (..., 2), got {xy.shape}")
        flat = xy.reshape(-1, 2)
        R = self.plane_rotation
        Xc = flat @ R[:, :2].T + np.asarray(self.plane_tvec)
        with np.errstate(divide="ignore", invalid="ignore"):
            nrm = Xc[:, :2] / Xc[:, 2:3]
        nrm[~(Xc[:, 2] > 0)] = np.nan
        return self._project_normalized(nrm).reshape(xy.shape)

    def pixel_to_plane(self, uv, **undistort_kw) -> np.ndarray:
        """Raw image pixels -> plane-frame points [m] (undistort, then ray-plane intersection).

        Parameters
        ----------
        uv : array_like (..., 2) [px]

        Returns
        -------
        ndarray (..., 2) [m]; NaN where the ray misses the plane.
        """
        self._need_plane()
        nrm = self.undistort_pixels(uv, normalized=True, **undistort_kw)
        return self._rays_to_plane(nrm)

    def _rays_to_plane(self, nrm):
        shape = nrm.shape
        d = np.concatenate([nrm.reshape(-1, 2), np.ones((int(np.prod(shape[:-1])), 1))], axis=1)
        R = self.plane_rotation
        t = np.asarray(self.plane_tvec)
        n = R[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = (n @ t) / (d @ n)
        X = d * lam[:, None]
        P = (X - t) @ R
        P[~(lam > 0)] = np.nan
        return P[:, :2].reshape(shape)

    def ideal_to_plane(self, uv_ideal) -> np.ndarray:
        """Undistorted (ideal pinhole) pixels -> plane [m], via the plane homography."""
        uv = np.asarray(uv_ideal, float)
        Hi = np.linalg.inv(self.plane_homography)
        flat = uv.reshape(-1, 2)
        q = flat @ Hi[:, :2].T + Hi[:, 2]
        return (q[:, :2] / q[:, 2:3]).reshape(uv.shape)

    def ideal_to_plane_jacobian(self, uv_ideal) -> np.ndarray:
        """``∂(plane [m]) / ∂(ideal pixel)`` at ideal pixels, shape (..., 2, 2)."""
        uv = np.asarray(uv_ideal, float)
        Hi = np.linalg.inv(self.plane_homography)
        flat = uv.reshape(-1, 2)
        q = flat @ Hi[:, :2].T + Hi[:, 2]
        w = q[:, 2]
        J = (Hi[None, :2, :2] - (q[:, :2, None] / w[:, None, None]) * Hi[None, 2:3, :2]) / w[:, None, None]
        return J.reshape(uv.shape[:-1] + (2, 2))

    def plane_scale(self, xy=None) -> float:
        """Mean image scale [px per m] on the plane at plane point ``xy`` (default: the image centre)."""
        self._need_plane()
        if xy is None:
            c = np.array([(self.image_size[0] - 1) / 2, (self.image_size[1] - 1) / 2])
            xy = self.pixel_to_plane(c)
        uv = self.undistort_pixels(self.plane_to_pixel(np.asarray(xy, float)))
        J = self.ideal_to_plane_jacobian(uv)
        return float(1.0 / np.sqrt(abs(np.linalg.det(J))))

    def check_image(self, image_or_shape) -> None:
        """Raise ValueError if an image does not have this camera's size."""
        shp = getattr(image_or_shape, "shape", image_or_shape)
        h, w = int(shp[0]), int(shp[1])
        if (w, h) != tuple(self.image_size):
            raise ValueError(f"image is {w}x{h} px but the calibration is for "
                             f"{self.image_size[0]}x{self.image_size[1]} px: wrong calibration file?")


# ----------------------------------------------------------------------------- board detection
@dataclass(frozen=True)
class BoardDetection:
    """Corners of a board found in one image.

    Attributes
    ----------
    object_points : ndarray (N, 3) [m]
    image_points : ndarray (N, 2) [px]
    ids : ndarray (N,) of int
        Corner ids (see :meth:`Board.corner_points`).
    """

    object_points: np.ndarray
    image_points: np.ndarray
    ids: np.ndarray

    @property
    def n(self) -> int:
        return len(self.ids)


def detect_board(image, board: Board, *, subpix_window: int = 5, subpix_iterations: int = 50,
                 subpix_eps: float = 1e-4) -> BoardDetection:
    """Find a board's inner corners in an image.

    ChArUco: ``CharucoDetector.detectBoard`` then ``board.matchImagePoints``.
    Chessboard: ``findChessboardCornersSB`` then ``cornerSubPix``.

    Returns
    -------
    BoardDetection
        Possibly empty (``n == 0``) when the board is not found.
    """
    gray = to_gray8(image)
    empty = BoardDetection(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, dtype=int))
    if board.kind == "charuco":
        cvb = board.cv_board()
        det = cv2.aruco.CharucoDetector(cvb)
        cc, ci, _, _ = det.detectBoard(gray)
        if cc is None or ci is None or len(ci) == 0:
            return empty
        obj, img = cvb.matchImagePoints(cc, ci)
        ids = np.asarray(ci, dtype=int).ravel()
        return BoardDetection(np.asarray(obj, float).reshape(-1, 3) * MM,
                              np.asarray(img, float).reshape(-1, 2), ids)
    found, corners = cv2.findChessboardCornersSB(gray, board.inner_corners,
                                                 flags=cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found or corners is None:
        return empty
    corners = np.asarray(corners, np.float32).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, int(subpix_iterations), float(subpix_eps))
    corners = cv2.cornerSubPix(gray, corners, (subpix_window, subpix_window), (-1, -1), crit)
    ids = np.arange(board.n_corners)
    return BoardDetection(board.corner_points(), corners.reshape(-1, 2).astype(float), ids)


# ----------------------------------------------------------------------------- calibration
@dataclass(frozen=True)
class ViewReport:
    """What happened to one calibration view."""

    name: str
    n_corners: int
    rms: float          # [px], NaN if the view was not used in the final calibration
    used: bool
    reason: str         # "" when used


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate_camera`."""

    camera: CameraModel
    views: tuple
    rounds: int

    @property
    def rms(self) -> float:
        return self.camera.rms

    @property
    def n_used(self) -> int:
        return sum(v.used for v in self.views)

    def intrinsics_table(self) -> list[tuple[str, float, float]]:
        """``(name, value, std)`` for fx, fy, cx, cy and the distortion coefficients."""
        K, d, s = self.camera.camera_matrix, self.camera.dist_coeffs, self.camera.std_intrinsics
        vals = [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *d]
        std = list(s) if s is not None else [math.nan] * len(vals)
        return [(_INTRINSIC_NAMES[i], float(v), float(std[i]) if i < len(std) else math.nan)
                for i, v in enumerate(vals)]


_DIST_FLAGS = {
    "k1k2p1p2": cv2.CALIB_FIX_K3,
    "k1k2p1p2k3": 0,
    "rational": cv2.CALIB_RATIONAL_MODEL,
}


def calibrate_camera(images, board: Board, *, names=None, image_size=None, detections=None,
                     dist_model: str = "k1k2p1p2", min_corners: int | None = None,
                     min_views: int = 3, max_view_rms: float = 1.0, rel_view_rms: float = 3.0,
                     max_rounds: int = 10, max_iter: int = 100, eps: float = 1e-12) -> Calibration:
    """Intrinsics and distortion from several views of a board.

    Views with too few corners (or collinear ones) are rejected first; then
    ``cv2.calibrateCameraExtended`` is repeated, each round rejecting the
    worst view while its reprojection rms exceeds both ``max_view_rms`` and
    ``rel_view_rms`` times the median view rms.

    Parameters
    ----------
    images : sequence of ndarray
        Gray or colour images (may be empty when ``detections`` is given).
    board : Board
    names : sequence of str, optional
        Labels for the report (default ``view1``, ...).
    image_size : (width, height), optional
        Needed only when ``images`` is empty.
    detections : sequence of BoardDetection, optional
        Precomputed corners (skips detection; for tests with exact corners).
    dist_model : {"k1k2p1p2", "k1k2p1p2k3", "rational"}
    min_corners : int, optional
        Minimum corners per view (default ``max(6, n_corners // 4)``).
    min_views : int
    max_view_rms, rel_view_rms : float
        Rejection thresholds [px] and [-].
    max_rounds, max_iter, eps : iteration limits.

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        Fewer than ``min_views`` usable views (with every view's reason).
    """
    if dist_model not in _DIST_FLAGS:
        raise ValueError(f"dist_model must be one of {', '.join(_DIST_FLAGS)}, got {dist_model!r}")
    images = list(images) if images is not None else []
    if detections is None:
        detections = [detect_board(im, board) for im in images]
    detections = list(detections)
    n = len(detections)
    names = [f"view{i + 1}" for i in range(n)] if names is None else [str(x) for x in names]
    if len(names) != n:
        raise ValueError(f"{len(names)} names for {n} views")
    if image_size is None:
        image_size = _common_image_size(images, names)
    if min_corners is None:
        min_corners = max(6, board.n_corners // 4)
    reason = _unusable_views(board, names, detections, min_corners)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, int(max_iter), float(eps))
    result = None
    rounds = 0
    while True:
        use = [i for i, nm in enumerate(names) if nm not in reason]
        if len(use) < min_views:
            lines = "; ".join(f"{nm}: {r}" for nm, r in reason.items())
            raise ValueError(f"only {len(use)} usable calibration views (need {min_views}); rejected: {lines}")
        obj = [detections[i].object_points.astype(np.float32).reshape(-1, 1, 3) for i in use]
        img = [detections[i].image_points.astype(np.float32).reshape(-1, 1, 2) for i in use]
        rounds += 1
        out = cv2.calibrateCameraExtended(obj, img, tuple(int(x) for x in image_size), None, None,
                                          flags=_DIST_FLAGS[dist_model], criteria=crit)
        rms, K, dist, rvecs, tvecs, std_in, _std_ex, per_view = out
        per_view = np.asarray(per_view, float).ravel()
        result = (rms, K, dist, std_in, per_view, use)
        if rounds >= max_rounds:
            break
        med = float(np.median(per_view))
        worst = int(np.argmax(per_view))
        if per_view[worst] > max(max_view_rms, rel_view_rms * med) and len(use) > min_views:
            reason[names[use[worst]]] = (f"high reprojection error ({per_view[worst]:.3f} px > "
                                         f"max({max_view_rms:g} px, {rel_view_rms:g} x median {med:.3f} px))")
            continue
        break
    return _calibration_result(result, names, detections, reason, image_size, rounds)


def _common_image_size(images, names) -> tuple[int, int]:
    """(width, height) of the first image; every other image must have it."""
    if not images:
        raise ValueError("image_size is needed when no images are given")
    h, w = np.asarray(images[0]).shape[:2]
    for nm, im in zip(names, images):
        if tuple(np.asarray(im).shape[:2]) != (h, w):
            raise ValueError(f"{nm}: image size {np.asarray(im).shape[1]}x{np.asarray(im).shape[0]} "
                             f"differs from the first image's {w}x{h}")
    return (w, h)


def _unusable_views(board: Board, names, detections, min_corners: int) -> dict:
    """``{view name: reason}`` for views rejected before calibrating (too few or collinear corners)."""
    reason = {}
    for nm, det in zip(names, detections):
        if det.n == 0:
            reason[nm] = "board not found"
        elif det.n < min_corners:
            reason[nm] = f"too few corners ({det.n} < {min_corners})"
        elif board.kind == "charuco" and board.cv_board().checkCharucoCornersCollinear(
                det.ids.reshape(-1, 1).astype(np.int32)):
            reason[nm] = "corners are collinear"
    return reason


def _calibration_result(result, names, detections, reason, image_size, rounds) -> Calibration:
    rms, K, dist, std_in, per_view, use = result
    nd = len(np.ravel(dist))
    std = np.asarray(std_in, float).ravel()[: 4 + nd]
    cam = CameraModel(K, np.ravel(dist), tuple(image_size), rms=float(rms), std_intrinsics=std,
                      per_view_errors=per_view)
    err = dict(zip([names[i] for i in use], per_view))
    views = tuple(ViewReport(nm, detections[i].n, float(err.get(nm, math.nan)), nm in err,
                             reason.get(nm, "")) for i, nm in enumerate(names))
    return Calibration(camera=cam, views=views, rounds=rounds)


@dataclass(frozen=True)
class PlanePose:
    """Pose of a board in the camera frame (``X_cam = R(rvec) X_board + tvec``)."""

    rvec: np.ndarray   # (3,)
    tvec: np.ndarray   # (3,) [m]
    rms: float         # reprojection rms [px]
    n_corners: int


def estimate_plane_pose(image, board: Board, camera: CameraModel, *, min_corners: int = 6,
                        detection: BoardDetection | None = None) -> PlanePose:
    """Pose of a board lying in the bending plane (``solvePnP``: IPPE, then LM refinement).

    The board frame becomes the metric plane frame of docs/data-formats.md.

    Raises
    ------
    ValueError
        Board not found or too few corners.
    """
    det = detection if detection is not None else detect_board(image, board)
    if det.n < min_corners:
        raise ValueError(f"plane image: board not found or too few corners ({det.n} < {min_corners})")
    obj = det.object_points.astype(np.float64).reshape(-1, 1, 3)
    img = det.image_points.astype(np.float64).reshape(-1, 1, 2)
    K, d = camera.camera_matrix, camera.dist_coeffs
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, d, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise ValueError("plane image: solvePnP failed")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, d, rvec, tvec)
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, d)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, axis=1))))
    return PlanePose(np.ravel(rvec).astype(float), np.ravel(tvec).astype(float), rms, det.n)
