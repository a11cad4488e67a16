"""Polygon area by the shoelace formula (hysteresis loops, image contours)."""

from __future__ import annotations

import numpy as np

__all__ = ["polygon_area"]


def polygon_area(x, y, *, signed: bool = False, skip_nonfinite: bool = True) -> float:
    """Area of the closed polygon through ``(x_k, y_k)`` (closed back to its start).

    Parameters
    ----------
    x, y : array_like, shape (m,)
        Vertices in order [any units].
    signed : bool
        Return the signed area (positive anticlockwise in an x-right, y-up
        frame) instead of its absolute value.
    skip_nonfinite : bool
        Drop vertices with a NaN or inf coordinate first.

    Returns
    -------
    float
        Area [units of x × units of y]; 0 for fewer than three vertices.
    """
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.shape != y.shape:
        raise ValueError(f"x and y must have the same length, got {x.shape} and {y.shape}")
    if skip_nonfinite:
        ok = np.isfinite(x) & np.isfinite(y)
        x, y = x[ok], y[ok]
    if x.size < 3:
        return 0.0
    area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return area if signed else abs(area)
