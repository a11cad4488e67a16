"""How image pixels map to the plane: a calibrated camera, or a scale from the tube's diameter."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["DiameterScale", "mirror_without_camera", "view_orientation"]


class DiameterScale:
    """A fronto-parallel view at a known scale, with the interface of :class:`~notchfit.vision.camera.CameraModel`
    that the detector uses.

    Plane coordinates are ``(u, v) * m_per_px``: x right, y down the image,
    the frame a calibration board lying upright in the bending plane gives
    (a board is always seen from its printed side, so every camera file maps
    pixels to the plane with this handedness). ``mirror`` therefore means
    the same with and without a camera file. There is no lens distortion.

    How far the view looks along the tube at a pixel is not known without a
    camera file; :attr:`camera_matrix`, :attr:`plane_rotation` and
    :attr:`plane_homography` describe the view assumed for that (the
    uncertainty of a slot face seen from the side): the plane facing a
    pinhole camera whose focal length is the image's diagonal (a normal lens,
    about 43 mm on a full-frame sensor; a phone's wide lens is shorter, so
    its faces are seen further from the side than assumed) with its
    principal point at the image's centre.

    Parameters
    ----------
    m_per_px : float
        Scale [m/px].
    image_size : (width, height)
    """

    has_plane = True

    def __init__(self, m_per_px: float, image_size):
        self.m_per_px = float(m_per_px)
        self.image_size = (int(image_size[0]), int(image_size[1]))
        W, H = self.image_size
        f = math.hypot(W, H)
        self.camera_matrix = np.array([[f, 0.0, (W - 1) / 2.0], [0.0, f, (H - 1) / 2.0], [0.0, 0.0, 1.0]])
        self.plane_rotation = np.eye(3)
        self.plane_homography = np.diag([1.0 / self.m_per_px, 1.0 / self.m_per_px, 1.0])

    def check_image(self, image) -> None:
        """Any image size fits (the scale is the image's own)."""
        return None

    def undistort_pixels(self, uv, **kw):
        """No lens model: pixels unchanged (..., 2)."""
        return np.array(uv, float, copy=True)

    def distort_pixels(self, uv):
        """No lens model: pixels unchanged (..., 2)."""
        return np.array(uv, float, copy=True)

    def ideal_to_plane(self, uv):
        """Pixels (..., 2) -> plane (u, v) * scale [m]."""
        return np.asarray(uv, float) * self.m_per_px

    pixel_to_plane = ideal_to_plane

    def plane_to_pixel(self, xy):
        """Plane [m] (..., 2) -> pixels."""
        return np.asarray(xy, float) / self.m_per_px

    def ideal_to_plane_jacobian(self, uv):
        """``diag(s, s)`` at every pixel, shape (..., 2, 2)."""
        uv = np.asarray(uv, float)
        J = np.array([[self.m_per_px, 0.0], [0.0, self.m_per_px]])
        return np.broadcast_to(J, uv.shape[:-1] + (2, 2)).copy()

    def plane_scale(self, xy=None) -> float:
        """Scale [px per m]."""
        return 1.0 / self.m_per_px


def view_orientation(camera, shape, mirror: bool) -> tuple[float, float]:
    """Scale at the image centre [px/m] and the orientation sign of pixel -> manipulator frame.

    The sign is +1 when an anticlockwise traversal in the image (u right,
    v down) is anticlockwise in the manipulator frame: the sign of the
    pixel -> plane Jacobian times -1 for a mirrored view.
    """
    H, W = shape
    c_img = np.array([(W - 1) / 2, (H - 1) / 2])
    px_per_m = camera.plane_scale(camera.pixel_to_plane(c_img))
    det_j = np.linalg.det(camera.ideal_to_plane_jacobian(camera.undistort_pixels(c_img)))
    sgn = float(np.sign(det_j)) * (-1.0 if mirror else 1.0)
    return float(px_per_m), sgn if math.isfinite(sgn) else 1.0


def mirror_without_camera(camera, shape, mirror: bool) -> bool:
    """The ``mirror`` flag that describes the same view when the camera file is left out.

    Without a camera file the plane frame is the image's (x right, y down:
    :class:`DiameterScale`), the handedness every calibration board seen
    from its printed side gives; ``mirror`` is then unchanged. A camera
    whose pixel -> plane map is reflected (the plane seen from behind, as
    the synthetic scene cameras of :mod:`notchfit.vision.render.scenes` do; a
    board calibration never does) turns it over.

    Parameters
    ----------
    camera : CameraModel
    shape : (H, W)
    mirror : bool
        The flag with the camera file.
    """
    _, sgn = view_orientation(camera, shape, mirror)
    return sgn < 0
