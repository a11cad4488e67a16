"""The notched tube as a solid: its exact silhouette and corners in a view that is not fronto-parallel.

A camera sees a tube whose axis is a few degrees out of the image plane
(a tilted mount, or simply the perspective of a lens: a slot 20 mm off the
optical axis at 270 mm is seen 4° from the side) differently from the
planar silhouette of geometry.md: the slot faces and the tip face are
circles seen obliquely, so each face's edge in the image is an arc of an
ellipse that meets the tube's outer edge tangentially.

The tube is a union of convex pieces, each a cylinder of radius ``R`` cut by
planes in the straight frame of its link: the solid part of every link
between its slots, and the backbone left by each slot (``σ_j x ≤ R - d_j``)
split between the two links it joins by the mitre plane through the pivot
(the plane that bisects the two links' axes: the two rotated half-backbones
meet on it exactly, as the planar outline's flexure side joins the two
links' edges where their lines intersect). A convex piece's image is the
convex hull of the images of its edges (the circles and lines where its
planes meet the cylinder and each other), which are sampled densely; the
tube's coverage is the union of the hulls
(:func:`~notchfit.vision.render.raster.union_coverage`).

A face's corner in the image is where the cylinder's limb (the generator
whose tangent plane holds the camera centre) meets the face's circle: the
projection of that 3-D point is the ground truth (within 0.001 mm of the
notch point ``(±R, 0, z)`` for tilts of a few degrees).

Shapes: 3-D points ``(..., 3)`` as ``(x, y, z)`` in the manipulator frame
(``y`` out of the bending plane) or ``(X, Y, Z)`` in the plane frame (``Z``
out of the plane); pixels ``(..., 2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import ConvexHull

from ...physics.geometry import Geometry, notch_layout
from ...physics.notches import to_plane
from . import _link_frames

__all__ = ["Piece", "SolidPose", "limb_corners", "piece_outlines", "tube_pieces"]


@dataclass(frozen=True)
class Piece:
    """A convex piece of the tube: the cylinder ``x² + y² ≤ R²`` of ``link``'s straight frame
    cut by the half-spaces ``planes[:, :3] · p ≤ planes[:, 3]`` (k, 4)."""

    link: int
    planes: np.ndarray


@dataclass(frozen=True)
class SolidPose:
    """Where the solid tube is: the plane pose and a tilt out of the plane.

    Attributes
    ----------
    plane : (tx, ty, phi, mirror)
        The planar pose (:func:`notchfit.physics.notches.to_plane`).
    tilt : float
        Rotation out of the plane [rad] about an axis through the base-edge
        centre ``(0, 0, z_base)``.
    tilt_axis : float
        Direction of that axis in the bending plane [rad]: 0 is ``x`` (the
        tube's far end leaves the plane), π/2 is the tube's base axis ``z``
        (the bending plane turns about it).
    """

    plane: tuple
    tilt: float = 0.0
    tilt_axis: float = 0.0


def _half(n, c):
    return np.array([n[0], n[1], n[2], c], float)


def tube_pieces(theta, geom: Geometry, base_z: float) -> list:
    """The tube's convex pieces from ``base_z`` (≤ the base edge) to the tip face.

    Returns
    -------
    list of Piece
    """
    th = np.asarray(theta, float)
    n, R = geom.n_joints, geom.outer_radius
    zj, w, d, sides = geom.joint_z, geom.slot_widths, geom.slot_depths, geom.sides
    xna = np.asarray(geom.neutral_axis_x, float)
    out = []
    for link in range(n + 1):
        lo = base_z if link == 0 else zj[link - 1] + w[link - 1] / 2
        hi = geom.tip_z if link == n else zj[link] - w[link] / 2
        out.append(Piece(link, np.array([_half((0, 0, -1), -lo), _half((0, 0, 1), hi)])))
        for j, above in ((link, True), (link + 1, False)):      # joint j's backbone half on this link
            if not 1 <= j <= n:
                continue
            s, h = sides[j - 1], 0.5 * th[j - 1]
            cut = _half((s, 0, 0), R - d[j - 1])
            P = np.array([xna[j - 1], 0.0, zj[j - 1]])
            if above:        # link j, from the mitre up to its solid part; link j-1's axis is (-sin θ, cos θ)
                m = np.array([-math.sin(h), 0.0, math.cos(h)])
                planes = [cut, _half(-m, -m @ P), _half((0, 0, 1), lo)]
            else:            # link j-1, from its solid part up to the mitre; link j's axis is (sin θ, cos θ)
                m = np.array([math.sin(h), 0.0, math.cos(h)])
                planes = [cut, _half(m, m @ P), _half((0, 0, -1), -hi)]
            out.append(Piece(link, np.array(planes)))
    return out


def _edge_points(planes, R: float, n_curve: int, tol: float = 1e-12):
    """Points on the edges of a convex piece (straight frame) (P, 3): its plane-cylinder curves and the
    points where two planes meet the cylinder, inside every other half-space."""
    ps = np.linspace(0, 2 * math.pi, n_curve, endpoint=False)
    pts = []
    for k, pl in enumerate(planes):
        if abs(pl[2]) > 1e-12:
            x, y = R * np.cos(ps), R * np.sin(ps)
            pts.append(np.stack([x, y, (pl[3] - pl[0] * x - pl[1] * y) / pl[2]], 1))
        for q in planes[k + 1:]:
            u = np.cross(pl[:3], q[:3])
            a = u[0] ** 2 + u[1] ** 2
            if a < 1e-24:
                continue
            p0 = np.linalg.pinv(np.stack([pl[:3], q[:3]])) @ np.array([pl[3], q[3]])
            b = 2 * (p0[0] * u[0] + p0[1] * u[1])
            c = p0[0] ** 2 + p0[1] ** 2 - R * R
            disc = b * b - 4 * a * c
            if disc >= 0:
                t = (-b + np.array([-1.0, 1.0]) * math.sqrt(disc)) / (2 * a)
                pts.append(p0 + t[:, None] * u)
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    scale = max(R, float(np.abs(planes[:, 3]).max()))
    inside = np.all(P @ planes[:, :3].T <= planes[:, 3] + tol * scale * 1e3, axis=1)
    return P[inside]


def _rotation(axis, angle: float) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(axis, float) * angle)[0]


def to_plane_3d(link, pts, theta, geom: Geometry, pose: SolidPose) -> np.ndarray:
    """Straight-frame points of ``link`` (P, 3) -> plane frame (P, 3) [m] (bend, tilt, plane pose)."""
    phi, org, piv = _link_frames(np.asarray(theta, float), geom)
    c, s = math.cos(phi[link]), math.sin(phi[link])
    lx, lz = pts[:, 0] - piv[link, 0], pts[:, 2] - piv[link, 1]
    xyz = np.stack([org[link, 0] + c * lx + s * lz, pts[:, 1], org[link, 1] - s * lx + c * lz], 1)
    if pose.tilt:
        pivot = np.array([0.0, 0.0, geom.base_edge_z])
        Q = _rotation((math.cos(pose.tilt_axis), 0.0, math.sin(pose.tilt_axis)), pose.tilt)
        xyz = pivot + (xyz - pivot) @ Q.T
    tx, ty, ph, mirror = pose.plane
    XY = to_plane(xyz[:, [0, 2]], tx, ty, ph, mirror)
    return np.concatenate([XY, (-xyz[:, 1:2] if mirror else xyz[:, 1:2])], 1)


def project(camera, P) -> np.ndarray:
    """Plane-frame 3-D points (P, 3) [m] -> raw pixels (P, 2) (pinhole and the camera's distortion)."""
    Xc = P @ camera.plane_rotation.T + np.asarray(camera.plane_tvec)
    K = camera.camera_matrix
    nrm = Xc[:, :2] / Xc[:, 2:3]
    ideal = np.stack([K[0, 0] * nrm[:, 0] + K[0, 1] * nrm[:, 1] + K[0, 2], K[1, 1] * nrm[:, 1] + K[1, 2]], 1)
    return camera.distort_pixels(ideal)


def piece_outlines(theta, geom: Geometry, camera, pose: SolidPose, base_z: float, *,
                   n_curve: int = 720) -> list:
    """The image of every convex piece: polygons (K_i, 2) [px], anticlockwise in the image."""
    out = []
    for pc in tube_pieces(theta, geom, base_z):
        P = _edge_points(pc.planes, geom.outer_radius, n_curve)
        if len(P) < 3:
            continue
        uv = project(camera, to_plane_3d(pc.link, P, theta, geom, pose))
        out.append(uv[ConvexHull(uv).vertices])
    return out


def _camera_centre(camera) -> np.ndarray:
    return -camera.plane_rotation.T @ np.asarray(camera.plane_tvec, float)


def limb_corners(theta, geom: Geometry, camera, pose: SolidPose, *, z_shift: float = 0.0) -> np.ndarray:
    """Image of every notch point's face corner: where the limb meets the face's circle (m, 2) [px].

    For point ``i`` on link ``l`` at ``(σ R, z)`` (geometry.md), the circle of
    radius ``R`` about the axis at ``z`` and the limb angle ``ψ`` with
    ``e(ψ) · (C - c) = R`` (the tangent plane holds the camera centre ``C``),
    nearest ``ψ = 0`` (σ = +1) or ``π``. ``z_shift`` [m] moves every circle
    along its link (a second point on each limb line).
    """
    lay = notch_layout(geom)
    R = geom.outer_radius
    C = _camera_centre(camera)
    out = np.zeros((lay.n_points, 2))
    for i in range(lay.n_points):
        link, z = int(lay.link[i]), float(lay.straight[i, 1]) + z_shift
        pts = np.array([[0, 0, z], [1, 0, z], [0, 1, z]], float)
        c, e1, e2 = to_plane_3d(link, pts, theta, geom, pose)
        e1, e2 = e1 - c, e2 - c
        wv = C - c
        w1, w2 = float(wv @ e1), float(wv @ e2)
        om, r = math.atan2(w2, w1), math.hypot(w1, w2)
        want = 0.0 if lay.side[i] > 0 else math.pi
        cands = [om + sgn * math.acos(min(R / r, 1.0)) for sgn in (-1, 1)]
        psi = min(cands, key=lambda a: abs(math.remainder(a - want, 2 * math.pi)))
        P = c + R * (math.cos(psi) * e1 + math.sin(psi) * e2)
        out[i] = project(camera, P[None])[0]
    return out
