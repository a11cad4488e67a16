"""Slot dimensions per joint: the one place the detector reads them from the geometry.

They come from the geometry's per-joint arrays (docs/geometry.md: one value
for every joint, or one per joint for tubes whose notches differ).
"""

from __future__ import annotations

import numpy as np

from ...physics.geometry import Geometry

__all__ = ["joint_z", "slot_depths", "slot_widths"]


def slot_widths(geom: Geometry) -> np.ndarray:
    """Slot width (notch height) ``w_j`` along the tube of every joint, shape (n,) [m]."""
    return geom.slot_widths


def slot_depths(geom: Geometry) -> np.ndarray:
    """Slot depth ``d_j`` from the outer edge of every joint, shape (n,) [m]."""
    return geom.slot_depths


def joint_z(geom: Geometry) -> np.ndarray:
    """z of every joint in the straight configuration, shape (n,) [m]."""
    return geom.joint_z
