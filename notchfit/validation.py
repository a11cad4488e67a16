"""Array validation shared by every module: joint angles, finite arrays, read-only copies.

Each check raises ``ValueError`` with a message that names the quantity, so
that a reader of untrusted files can turn it into a one-line error.
"""

from __future__ import annotations

import numpy as np

__all__ = ["as_finite", "as_joint_angles", "readonly"]


def readonly(a, dtype=float, shape=None) -> np.ndarray | None:
    """A read-only copy of ``a`` (``None`` stays ``None``).

    Parameters
    ----------
    a : array_like or None
    dtype : numpy dtype, optional
        Element type of the copy (float by default).
    shape : tuple of int, optional
        Reshape the copy to this shape.

    Returns
    -------
    ndarray or None
        A new array with ``flags.writeable = False``: frozen dataclasses hold
        these so that their contents cannot change behind their back.
    """
    if a is None:
        return None
    out = np.array(a, dtype=dtype)
    if shape is not None:
        out = out.reshape(shape)
    out.flags.writeable = False
    return out


def as_finite(a, name: str = "array") -> np.ndarray:
    """A float array with no NaN or inf.

    Parameters
    ----------
    a : array_like
    name : str
        What the array is, for the error message.

    Returns
    -------
    ndarray (float)

    Raises
    ------
    ValueError
        ``"<name> contains NaN or inf"``.
    """
    arr = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def as_joint_angles(theta, n: int | None = None) -> np.ndarray:
    """Validate joint angles: a float array (..., n) with no NaN or inf.

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    n : int, optional
        Required length of the last axis.

    Returns
    -------
    ndarray, shape (..., n) [rad]

    Raises
    ------
    ValueError
        Mentioning "joint angles" for a scalar, a wrong last axis or
        non-finite values; every module validates angles here.
    """
    th = np.asarray(theta, dtype=float)
    if th.ndim == 0:
        raise ValueError("joint angles must be an array of shape (..., n), got a scalar")
    if n is not None and th.shape[-1] != n:
        raise ValueError(f"joint angles must have last axis n={n}, got shape {th.shape}")
    if not np.all(np.isfinite(th)):
        raise ValueError("joint angles contain NaN or inf")
    return th
