"""Slot dimensions per joint: the one place the detector reads them from the geometry.

The geometry holds one slot width and depth today; per-joint arrays
(real-tubes.md) only need these functions to change.
"""

from __future__ import annotations

import numpy as np

from ..geometry import Geometry

__all__ = ["joint_z", "slot_depths", "slot_widths"]


def slot_widths(geom: Geometry) -> np.ndarray:
    """Slot width ``w_j`` along the tube of every joint, shape (n,) [m]."""
    return np.broadcast_to(np.asarray(geom.slot_width, float), (geom.n_joints,)).copy()


def slot_depths(geom: Geometry) -> np.ndarray:
    """Slot depth ``d_j`` from the outer edge of every joint, shape (n,) [m]."""
    return np.broadcast_to(np.asarray(geom.slot_depth, float), (geom.n_joints,)).copy()


def joint_z(geom: Geometry) -> np.ndarray:
    """z of every joint in the straight configuration, shape (n,) [m]."""
    return (np.arange(1, geom.n_joints + 1) - 1) * geom.p
