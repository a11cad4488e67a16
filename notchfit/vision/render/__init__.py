"""Synthetic images with exact ground truth (round trips for calibration and detection).

Two scenes, both seen through a :class:`~notchfit.vision.camera.CameraModel` with
its lens distortion:

* :func:`render_board`: a ChArUco board or chessboard at a chosen pose. Every
  supersample (pixel-centre sampling of an ``S x S`` grid inside each pixel)
  is traced back to the board plane (undistortion + ray-plane intersection)
  and the board pattern is evaluated analytically there; the samples are
  block-averaged.
* :func:`render_manipulator`: the notched tube for joint angles ``θ`` as the
  silhouette of docs/geometry.md ("What a camera sees"): a band ``|x| <= R`` from
  the base edge to the tip face, each link rigid, rectangular slots ``w``
  wide and ``d`` deep from the open side, the flexure side continuous (the
  two links' edges meet where their lines intersect, no gap, no overlap), the
  mount band below the base edge, a straight tip face. The outline is placed
  in the plane by :func:`notchfit.physics.notches.to_plane` (plane pose and mirror
  flag), subdivided densely, projected with distortion
  (``cv2.projectPoints``) and rasterised by an unbiased scanline fill:
  pixel-centre sampling on ``S`` sub-rows per pixel and the exact covered
  length along each sub-row (the limit of pixel-centre sampling in x).
  ``cv2.fillPoly`` is not used: it pushes edges outward by 0.1-0.7 px.

Image formation (both scenes): supersampled coverage -> a non-flat
background (smooth additive texture) and the object level -> a smooth
multiplicative illumination field -> Gaussian optical blur (``blur_sigma``
px) -> Gaussian sensor noise (``noise`` x contrast, from a seeded
``numpy.random.Generator``) -> rounding to the output dtype.

Every function returns the exact ground truth beside the image.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Board, CameraModel
from ...physics.geometry import Geometry
from ...physics.kinematics import chain, link_origins
from ...physics.notches import notch_points, to_plane
from ...units import MM
from .raster import polygon_coverage, union_coverage

__all__ = [
    "RenderedBoard",
    "RenderedManipulator",
    "camera_for_shapes",
    "manipulator_outline",
    "place_in_view",
    "polygon_coverage",
    "render_board",
    "render_manipulator",
    "union_coverage",
]


# ----------------------------------------------------------------------------- outlines
def _subdivide(poly, max_len):
    """Insert points so that no edge of the closed polygon is longer than ``max_len``."""
    p = np.asarray(poly, float)
    q = np.roll(p, -1, axis=0)
    seg = np.linalg.norm(q - p, axis=1)
    k = np.maximum(np.ceil(seg / max_len).astype(int), 1)
    idx = np.repeat(np.arange(len(p)), k)
    frac = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
    return p[idx] + frac[:, None] * (q[idx] - p[idx])


# ----------------------------------------------------------------------------- image formation
def _smooth_field(shape, rng, n_waves=4, min_wavelength=150.0, max_wavelength=600.0):
    """A smooth random field of unit peak-to-peak amplitude (sum of plane waves).

    Each wave ``cos(a u + b v + φ)`` is evaluated as the separable
    ``cos(a u) cos(b v + φ) - sin(a u) sin(b v + φ)``, and all waves at once as
    one (H, 2k) @ (2k, W) product of 1-D cosines and sines instead of a cosine
    per pixel.
    """
    H, W = shape
    u, v = np.arange(W, dtype=float), np.arange(H, dtype=float)
    A = np.empty((H, 2 * n_waves))
    B = np.empty((2 * n_waves, W))
    for k in range(n_waves):
        lam = rng.uniform(min_wavelength, max_wavelength)
        ang = rng.uniform(0, 2 * np.pi)
        ph = rng.uniform(0, 2 * np.pi)
        au, bv = (2 * np.pi / lam) * np.cos(ang) * u, (2 * np.pi / lam) * np.sin(ang) * v + ph
        A[:, 2 * k], A[:, 2 * k + 1] = np.cos(bv), -np.sin(bv)
        B[2 * k], B[2 * k + 1] = np.cos(au), np.sin(au)
    f = A.astype(np.float32) @ B.astype(np.float32)
    ptp = float(f.max() - f.min())
    return (f - f.mean()) / ptp if ptp > 0 else f


def _illumination(shape, rng, amplitude):
    """A smooth multiplicative field: linear gradient + broad hot spot, peak-to-peak ``amplitude``.

    Both terms are separable in (u, v) and are built by broadcasting 1-D arrays.
    """
    H, W = shape
    if amplitude <= 0:
        return None
    un = (np.arange(W, dtype=float) / max(W - 1, 1) - 0.5)[None, :]
    vn = (np.arange(H, dtype=float) / max(H - 1, 1) - 0.5)[:, None]
    g = rng.normal(size=2)
    cu, cv = rng.uniform(-0.3, 0.3, size=2)
    f = (g[0] * un + g[1] * vn).astype(np.float32)
    f += (np.exp(-((vn - cv) ** 2) / 0.18) * np.exp(-((un - cu) ** 2) / 0.18)).astype(np.float32)
    f = (f - f.min()) / max(float(f.max() - f.min()), 1e-12)
    return (1.0 - amplitude / 2.0 + amplitude * f).astype(np.float32)


def _form_image(coverage, *, rng, background, foreground, blur_sigma, noise, illumination, texture,
                dtype):
    """coverage (object fraction) -> camera image."""
    H, W = coverage.shape
    contrast = abs(background - foreground)
    cov = coverage.astype(np.float32, copy=False)
    bg = np.full((H, W), background, np.float32)
    if texture > 0:
        bg += np.float32(texture * contrast) * _smooth_field((H, W), rng)
    img = np.float32(foreground) - bg          # bg (1 - c) + fg c = bg + (fg - bg) c
    img *= cov
    img += bg
    illum = _illumination((H, W), rng, illumination)
    if illum is not None:
        img *= illum
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigmaX=float(blur_sigma), sigmaY=float(blur_sigma),
                               borderType=cv2.BORDER_REFLECT)
    if noise > 0:
        img += rng.normal(0.0, noise * contrast, size=(H, W)).astype(np.float32)
    dtype = np.dtype(dtype)
    if dtype.kind in "ui":
        info = np.iinfo(dtype)
        return np.clip(np.rint(img), info.min, info.max).astype(dtype)
    return img.astype(dtype)


def _check_rng(rng):
    if rng is None:
        raise ValueError("pass a seeded numpy.random.Generator as rng (e.g. np.random.default_rng(1))")
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(rng)
    return rng


# ----------------------------------------------------------------------------- boards
@dataclass(frozen=True)
class RenderedBoard:
    """A rendered board and its ground truth.

    Attributes
    ----------
    image : ndarray (H, W)
    corners_px : ndarray (N, 2)
        Exact image position of every inner corner (id order), with distortion [px].
    ids : ndarray (N,)
    object_points : ndarray (N, 3) [m]
    visible : ndarray (N,) bool
        Corner at least ``margin`` px inside the image.
    rvec, tvec : ndarray (3,)
        Board pose in the camera frame (tvec [m]).
    """

    image: np.ndarray
    corners_px: np.ndarray
    ids: np.ndarray
    object_points: np.ndarray
    visible: np.ndarray
    rvec: np.ndarray
    tvec: np.ndarray


def _board_pattern(board: Board, X, Y, margin_squares=1.0):
    """Reflectance (1 white, 0 black, 0.5 outside the printed sheet) at board points [m]."""
    s = board.square_size
    bw, bh = board.size
    out = np.full(X.shape, 0.5, np.float32)
    sheet = (X >= -margin_squares * s) & (X < bw + margin_squares * s) & \
            (Y >= -margin_squares * s) & (Y < bh + margin_squares * s)
    out[sheet] = 1.0
    inb = (X >= 0) & (X < bw) & (Y >= 0) & (Y < bh)
    i = np.floor(X[inb] / s).astype(np.int64)
    j = np.floor(Y[inb] / s).astype(np.int64)
    val = np.ones(i.shape, np.float32)
    if board.kind == "chessboard":
        val[(i + j) % 2 == 0] = 0.0
    else:
        cvb = board.cv_board()
        obj = np.asarray(cvb.getObjPoints(), float) * MM          # (M, 4, 3) [m]
        ids = np.asarray(cvb.getIds()).ravel()
        d = cvb.getDictionary()
        nb = int(d.markerSize)
        table = np.full((board.squares_y, board.squares_x), -1, np.int64)
        bits = np.zeros((len(ids), nb + 2, nb + 2), np.float32)
        for k, (mid, corners) in enumerate(zip(ids, obj)):
            ci = int(np.floor(corners[:, 0].mean() / s))
            cj = int(np.floor(corners[:, 1].mean() / s))
            table[cj, ci] = k
            bits[k] = cv2.aruco.generateImageMarker(d, int(mid), nb + 2, borderBits=1) / 255.0
        mk = table[j, i]
        val[mk < 0] = 0.0
        has = mk >= 0
        x0 = obj[mk[has], 0, 0]
        y0 = obj[mk[has], 0, 1]
        cell = board.marker_size / (nb + 2)
        lx = (X[inb][has] - x0) / cell
        ly = (Y[inb][has] - y0) / cell
        inside = (lx >= 0) & (lx < nb + 2) & (ly >= 0) & (ly < nb + 2)
        v2 = np.ones(lx.shape, np.float32)
        kk = mk[has][inside]
        v2[inside] = bits[kk, np.floor(ly[inside]).astype(np.int64), np.floor(lx[inside]).astype(np.int64)]
        val[has] = v2
    out[inb] = val
    return out


def render_board(board: Board, camera: CameraModel, rvec, tvec, *, rng, supersample: int = 4,
                 white: float = 220.0, black: float = 30.0, blur_sigma: float = 0.7,
                 noise: float = 0.01, illumination: float = 0.1, margin: float = 3.0,
                 dtype=np.uint8) -> RenderedBoard:
    """Render a calibration board at pose ``(rvec, tvec)`` (``X_cam = R X_board + t``, t [m]).

    Parameters
    ----------
    board : Board
    camera : CameraModel
        Intrinsics, distortion and image size (its plane pose is not used).
    rvec, tvec : array_like (3,)
    rng : numpy.random.Generator or int seed
    supersample : int
        ``S x S`` samples per pixel (pixel-centre sampling).
    white, black : float
        Reflectance levels [DN]; outside the printed sheet the scene is mid-gray.
    blur_sigma : float [px]; noise : float (fraction of white - black);
    illumination : float (peak-to-peak relative variation)
    margin : float
        Corners closer than this to the image border are not ``visible`` [px].

    Returns
    -------
    RenderedBoard
    """
    rng = _check_rng(rng)
    W, H = camera.image_size
    S = int(supersample)
    # exact undistortion at pixel corners, bilinear in between (the map is smooth)
    gu, gv = np.meshgrid(np.arange(W + 1) - 0.5, np.arange(H + 1) - 0.5)
    nrm = camera.undistort_pixels(np.stack([gu, gv], -1), normalized=True)       # (H+1, W+1, 2)
    R = cv2.Rodrigues(np.asarray(rvec, float).reshape(3))[0]
    t = np.asarray(tvec, float).reshape(3)
    nvec = R[:, 2]
    acc = np.zeros((H, W), np.float32)
    a00, a01, a10, a11 = nrm[:-1, :-1], nrm[:-1, 1:], nrm[1:, :-1], nrm[1:, 1:]
    for sy in range(S):
        fy = (sy + 0.5) / S
        for sx in range(S):
            fx = (sx + 0.5) / S
            d = (a00 * ((1 - fx) * (1 - fy)) + a01 * (fx * (1 - fy)) + a10 * ((1 - fx) * fy) + a11 * (fx * fy))
            lam = (nvec @ t) / (d[..., 0] * nvec[0] + d[..., 1] * nvec[1] + nvec[2])
            Xc = np.stack([d[..., 0] * lam, d[..., 1] * lam, lam], -1) - t
            P = Xc @ R
            val = _board_pattern(board, P[..., 0], P[..., 1])
            val[lam <= 0] = 0.5
            acc += val
    refl = acc / (S * S)
    # reflectance -> object coverage of the black level
    cov = (1.0 - refl).astype(np.float32)
    img = _form_image(cov, rng=rng, background=white, foreground=black, blur_sigma=blur_sigma,
                      noise=noise, illumination=illumination, texture=0.0, dtype=dtype)
    obj = board.corner_points()
    proj, _ = cv2.projectPoints(obj, np.asarray(rvec, float).reshape(3), t, camera.camera_matrix,
                                camera.dist_coeffs)
    proj = proj.reshape(-1, 2)
    vis = (proj[:, 0] >= margin) & (proj[:, 0] <= W - 1 - margin) & (proj[:, 1] >= margin) & \
          (proj[:, 1] <= H - 1 - margin)
    return RenderedBoard(img, proj, np.arange(len(obj)), obj, vis, np.asarray(rvec, float).reshape(3), t)


# ----------------------------------------------------------------------------- manipulator
def _link_frames(theta, geom: Geometry):
    """Orientation φ_l, origin O_l and straight-configuration pivot a_l of links 0..n.

    The pivot chain of :func:`notchfit.physics.kinematics.link_origins` (joints at the
    geometry's pivots: the tube axis, or each slot's neutral axis): a point ``P``
    of link ``l`` in the straight configuration goes to ``O_l + R(φ_l)(P - a_l)``.
    """
    th = np.asarray(theta, float)
    if th.shape != (geom.n_joints,):
        raise ValueError(f"theta must have shape ({geom.n_joints},), got {th.shape}")
    if not np.isfinite(th).all():
        raise ValueError("theta contains NaN or inf")
    phi, org = link_origins(th, geom)
    piv = np.concatenate([np.zeros((1, 2)), chain(geom).pivots])
    return phi, org, piv


def pivot_closure_angles(geom: Geometry) -> np.ndarray:
    """Joint angles at which the pivot model closes each slot's mouth (n,) [rad].

    The outer corners of slot ``j`` (height ``w_j``, on side ``σ_j``) are
    ``c = R - σ_j x_na,j`` across and ``w_j / 2`` along from the pivot; they meet
    at ``2 atan(w_j / 2c)`` (the seed tube's ``2 atan(w / 2R)``; a little below the
    arc model's ``h / (R + ȳ)`` for a section backbone).
    """
    c = geom.outer_radius - geom.sides * chain(geom).axis_offset
    return np.array([2.0 * math.atan(w / (2.0 * cj)) for w, cj in zip(geom.slot_widths, c)])


def _world(phi, org, piv, link, x, z):
    """Straight-configuration point (x, z) rigidly attached to ``link`` -> world (x, z)."""
    c, s = math.cos(phi[link]), math.sin(phi[link])
    lx, lz = x - piv[link, 0], z - piv[link, 1]
    return (org[link, 0] + c * lx + s * lz, org[link, 1] - s * lx + c * lz)


def _join(phi, org, piv, j, a):
    """Where the lines x = a of links j-1 and j meet (the flexure side of joint j)."""
    p0 = np.array(_world(phi, org, piv, j - 1, a, piv[j, 1]))
    p1 = np.array(_world(phi, org, piv, j, a, piv[j, 1]))
    d0 = np.array([math.sin(phi[j - 1]), math.cos(phi[j - 1])])
    d1 = np.array([math.sin(phi[j]), math.cos(phi[j])])
    det = d0[0] * (-d1[1]) - d0[1] * (-d1[0])
    if abs(det) < 1e-15:
        return tuple(p1)
    t = ((p1 - p0)[0] * (-d1[1]) - (p1 - p0)[1] * (-d1[0])) / det
    return tuple(p0 + t * d0)


def manipulator_outline(theta, geom: Geometry, *, include_mount: bool = True) -> np.ndarray:
    """Silhouette outline of the tube (docs/geometry.md, "What a camera sees").

    Links are rigid and turn about the geometry's pivots (the pivot model of
    :mod:`notchfit.physics.kinematics`, the projector's default), each slot with its own
    height and depth.

    Parameters
    ----------
    theta : array_like (n,)
        Joint angles [rad]; ``|θ_j|`` must not exceed the slot-closure angle
        (:func:`pivot_closure_angles`).
    geom : Geometry
    include_mount : bool
        Include the mount band below the base edge (when the geometry has one).

    Returns
    -------
    ndarray (K, 2)
        Vertices (x, z) [m] in the manipulator frame, anticlockwise, a simple
        polygon. Every notch point is a vertex.
    """
    th = np.asarray(theta, float)
    phi, org, piv = _link_frames(th, geom)
    closure = pivot_closure_angles(geom)
    if np.any(np.abs(th) > closure * (1 + 1e-9)):
        j = int(np.argmax(np.abs(th) / closure))
        raise ValueError(f"|theta_{j + 1}| = {abs(th[j]):.4f} rad exceeds the slot-closure angle "
                         f"{closure[j]:.4f} rad: the slot faces would overlap")
    n, R = geom.n_joints, geom.outer_radius
    zs, ws, ds = geom.joint_z, geom.slot_widths, geom.slot_depths
    P = functools.partial(_world, phi, org, piv)
    join = functools.partial(_join, phi, org, piv)
    zb = geom.base_edge_z
    mount = include_mount and geom.mount_half_width is not None
    pts = []
    if mount:
        M = geom.mount_half_width
        pts += [(-M, geom.mount_bottom_z), (M, geom.mount_bottom_z), (M, zb)]
    pts.append((R, zb))
    for j in range(1, n + 1):
        zj, w, d = zs[j - 1], ws[j - 1], ds[j - 1]
        if geom.slot_sides[j - 1] == +1:
            pts += [P(j - 1, R, zj - w / 2), P(j - 1, R - d, zj - w / 2), join(j, R - d),
                    P(j, R - d, zj + w / 2), P(j, R, zj + w / 2)]
        else:
            pts.append(join(j, R))
    pts += [P(n, R, geom.tip_z), P(n, -R, geom.tip_z)]
    for j in range(n, 0, -1):
        zj, w, d = zs[j - 1], ws[j - 1], ds[j - 1]
        if geom.slot_sides[j - 1] == -1:
            pts += [P(j, -R, zj + w / 2), P(j, -(R - d), zj + w / 2), join(j, -(R - d)),
                    P(j - 1, -(R - d), zj - w / 2), P(j - 1, -R, zj - w / 2)]
        else:
            pts.append(join(j, -R))
    pts.append((-R, zb))
    if mount:
        pts.append((-geom.mount_half_width, zb))
    return np.asarray(pts, float)


@dataclass(frozen=True)
class RenderedManipulator:
    """A rendered manipulator image and its ground truth.

    Attributes
    ----------
    image : ndarray (H, W)
    points_px : ndarray (m, 2)
        Exact notch points in the raw (distorted) image [px].
    points_plane : ndarray (m, 2)
        Exact notch points in the plane frame [m].
    theta : ndarray (n,) [rad]
    plane : tuple (tx [m], ty [m], phi [rad], mirror)
    visible : ndarray (m,) bool
        Inside the image by at least ``margin`` px.
    """

    image: np.ndarray
    points_px: np.ndarray
    points_plane: np.ndarray
    theta: np.ndarray
    plane: tuple
    visible: np.ndarray


def outline_in_plane(theta, geom, tx, ty, phi, mirror=False, include_mount=True):
    """The outline (:func:`manipulator_outline`) mapped into the plane frame [m], (K, 2)."""
    poly = manipulator_outline(theta, geom, include_mount=include_mount)
    return to_plane(poly, tx, ty, phi, mirror)


def render_manipulator(theta, geom: Geometry, camera: CameraModel, *, plane=(0.0, 0.0, 0.0, False),
                       rng, supersample: int = 32, background: float = 200.0, foreground: float = 40.0,
                       blur_sigma: float = 1.0, noise: float = 0.02, illumination: float = 0.15,
                       texture: float = 0.05, max_segment_px: float = 0.5, margin: float = 2.0,
                       dtype=np.uint8) -> RenderedManipulator:
    """Render the notched tube at joint angles ``θ`` through a calibrated camera.

    Parameters
    ----------
    theta : array_like (n,) [rad]
    geom : Geometry
    camera : CameraModel
        Must have a plane pose.
    plane : (tx, ty, phi, mirror)
        Manipulator -> plane transform (:func:`notchfit.physics.notches.to_plane`), tx, ty [m].
    rng : numpy.random.Generator or int seed
    supersample : int
        Sub-rows per pixel of the scanline rasteriser. Along a sub-row the
        coverage is exact; across rows it is sampled, so an edge parallel to
        the pixel rows can be off by up to ``1 / (2 S)`` px, the same at
        every point of the edge (a bias the detector would report as its own
        error); 32 keeps it below 0.016 px.
    background, foreground : float
        Background and tube levels [DN] (a dark silhouette on a bright
        background by default; the reverse works too).
    blur_sigma : float
        Gaussian optical blur [px].
    noise : float
        Sensor noise standard deviation as a fraction of ``|background - foreground|``.
    illumination : float
        Peak-to-peak relative variation of a smooth multiplicative light field.
    texture : float
        Peak-to-peak amplitude of a smooth additive background texture, as a
        fraction of the contrast.
    max_segment_px : float
        Outline edges are subdivided to at most this length before projection [px].
    margin : float
        Points closer than this to the border are not ``visible`` [px].
    dtype : numpy dtype
        ``uint8`` (default), ``uint16`` or a float type.

    Returns
    -------
    RenderedManipulator
    """
    rng = _check_rng(rng)
    tx, ty, phi, mirror = plane
    th = np.asarray(theta, float)
    W, H = camera.image_size
    poly = outline_in_plane(th, geom, tx, ty, phi, mirror)
    scale = camera.plane_scale(poly.mean(axis=0))               # px per m
    poly = _subdivide(poly, max_segment_px / scale)
    uv = camera.plane_to_pixel(poly)
    if not np.isfinite(uv).all():
        raise ValueError("part of the manipulator outline is behind the camera")
    # rasterise only the region the outline touches (plus the blur margin)
    pad = int(math.ceil(4 * blur_sigma)) + 3
    u0 = int(max(math.floor(uv[:, 0].min()) - pad, 0))
    v0 = int(max(math.floor(uv[:, 1].min()) - pad, 0))
    u1 = int(min(math.ceil(uv[:, 0].max()) + pad, W - 1))
    v1 = int(min(math.ceil(uv[:, 1].max()) + pad, H - 1))
    cov = np.zeros((H, W), np.float32)
    if u1 >= u0 and v1 >= v0:
        cov[v0:v1 + 1, u0:u1 + 1] = polygon_coverage([uv], (v1 - v0 + 1, u1 - u0 + 1),
                                                     supersample=supersample, offset=(u0, v0))
    img = _form_image(cov, rng=rng, background=background, foreground=foreground, blur_sigma=blur_sigma,
                      noise=noise, illumination=illumination, texture=texture, dtype=dtype)
    pts_plane = to_plane(notch_points(th, geom), tx, ty, phi, mirror)
    pts_px = camera.plane_to_pixel(pts_plane)
    vis = (pts_px[:, 0] >= margin) & (pts_px[:, 0] <= W - 1 - margin) & \
          (pts_px[:, 1] >= margin) & (pts_px[:, 1] <= H - 1 - margin)
    return RenderedManipulator(img, pts_px, pts_plane, th.copy(), (float(tx), float(ty), float(phi), bool(mirror)),
                               vis)


# ----------------------------------------------------------------------------- placement
def place_in_view(theta_list, geom: Geometry, camera: CameraModel, *, phi: float = 0.0, mirror: bool = False,
                  margin_px: float = 10.0):
    """A plane translation that centres the shapes (outline with mount) in the image.

    Parameters
    ----------
    theta_list : array_like (n,) or (S, n)
    phi : float, mirror : bool
        The rotation and mirror of the manipulator -> plane transform.

    Returns
    -------
    plane : tuple (tx, ty, phi, mirror)
    fits : bool
        Every outline point of every shape is at least ``margin_px`` inside the image.
    """
    ths = np.atleast_2d(np.asarray(theta_list, float))
    outl = np.concatenate([outline_in_plane(t, geom, 0.0, 0.0, phi, mirror) for t in ths])
    c_img = np.array([(camera.image_size[0] - 1) / 2, (camera.image_size[1] - 1) / 2])
    # iterate: centre the projected bounding box on the image centre
    t = camera.pixel_to_plane(c_img) - 0.5 * (outl.min(0) + outl.max(0))
    for _ in range(3):
        uv = camera.plane_to_pixel(outl + t)
        mid = 0.5 * (uv.min(0) + uv.max(0))
        t = t + (camera.pixel_to_plane(c_img) - camera.pixel_to_plane(mid))
    uv = camera.plane_to_pixel(outl + t)
    W, H = camera.image_size
    e = float(margin_px)
    fits = bool(np.isfinite(uv).all() and uv[:, 0].min() >= e and uv[:, 1].min() >= e
                and uv[:, 0].max() <= W - 1 - e and uv[:, 1].max() <= H - 1 - e)
    return (float(t[0]), float(t[1]), float(phi), bool(mirror)), fits


def camera_for_shapes(theta_list, geom: Geometry, *, mm_per_px: float = 0.03, margin_px: int = 60,
                      phi: float = 0.0, mirror: bool = False, planes=None, max_size: int = 4096,
                      **synthetic_kw):
    """A synthetic camera just large enough for the given shapes (small test images).

    Parameters
    ----------
    theta_list : array_like (n,) or (S, n)
    mm_per_px : float
        Image scale at the image centre.
    margin_px : int
        Free border around the shapes.
    phi, mirror : the manipulator -> plane rotation and mirror used when ``planes`` is None.
    planes : sequence of (tx, ty, phi, mirror), optional
        Given plane transforms (one per shape): the camera is then centred on them.
    **synthetic_kw : passed to :meth:`CameraModel.synthetic` (focal_px, dist, tilt_deg, ...).

    Returns
    -------
    camera : CameraModel
    planes : list of (tx, ty, phi, mirror)
        One per shape, all inside the image.
    """
    ths = np.atleast_2d(np.asarray(theta_list, float))
    if planes is None:
        planes0 = [(0.0, 0.0, phi, mirror)] * len(ths)
    else:
        planes0 = [tuple(pl) for pl in planes]
        if len(planes0) != len(ths):
            raise ValueError(f"{len(planes0)} planes for {len(ths)} shapes")
    outl = np.concatenate([outline_in_plane(t, geom, *pl) for t, pl in zip(ths, planes0)]) / MM
    lo, hi = outl.min(0), outl.max(0)
    angle = synthetic_kw.get("plane_angle_deg", -90.0)
    ca, sa = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    # extent along the image axes (plane rotated by `angle` about the optical axis)
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    img_xy = corners @ np.array([[ca, sa], [-sa, ca]])
    ext = img_xy.max(0) - img_xy.min(0)
    W = int(math.ceil(ext[0] / mm_per_px * 1.03 + 2 * margin_px))
    H = int(math.ceil(ext[1] / mm_per_px * 1.03 + 2 * margin_px))
    if max(W, H) > max_size:
        raise ValueError(f"the shapes need a {W}x{H} px image at {mm_per_px} mm/px (max {max_size})")
    center = 0.5 * (lo + hi)
    for _ in range(12):
        cam = CameraModel.synthetic(W, H, mm_per_px=mm_per_px, plane_center_mm=tuple(center), **synthetic_kw)
        uv = cam.plane_to_pixel(outl * MM)
        lo_px, hi_px = uv.min(0), uv.max(0)
        if (lo_px.min() >= 0.9 * margin_px and hi_px[0] <= W - 1 - 0.9 * margin_px
                and hi_px[1] <= H - 1 - 0.9 * margin_px):
            break
        need = np.maximum(hi_px - lo_px + 2 * margin_px, 1)
        mid = 0.5 * (lo_px + hi_px)
        c_img = np.array([(W - 1) / 2, (H - 1) / 2])
        center = center + (cam.pixel_to_plane(c_img) - cam.pixel_to_plane(mid)) / MM
        if need[0] > W or need[1] > H:
            W, H = int(math.ceil(max(W, need[0]))), int(math.ceil(max(H, need[1])))
    else:
        raise ValueError("camera_for_shapes: could not fit the shapes in the image (extreme tilt or distortion?)")
    return cam, planes0
