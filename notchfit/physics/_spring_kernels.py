"""Numba kernels of the flexure springs (Fig. 17 form, per-joint rates and scale).

Shared by the friction simulator's kernels (:mod:`notchfit.physics._friction_kernels`)
and the joint-hysteresis laws (:mod:`notchfit.physics._hysteresis_kernels`).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def spring_mag(x, k1, k2, k3, tm, ts):
    """Unscaled spring torque magnitude for ``x = |θ| >= 0`` (Fig. 17)."""
    if x < tm:
        return k1 * x
    if x < ts:
        return k1 * tm + k2 * (x - tm)
    return k1 * tm + k2 * (ts - tm) + k3 * (x - ts)


@njit(cache=True, inline="always")
def spring_torque(th, k1, k2, k3, tm, ts, s):
    """Odd spring torque ``τ(θ)`` with joint scale ``s`` [N m]."""
    if th >= 0.0:
        return s * spring_mag(th, k1, k2, k3, tm, ts)
    return -(s * spring_mag(-th, k1, k2, k3, tm, ts))


@njit(cache=True, inline="always")
def spring_angle(tq, k1, k2, k3, tm, ts, s):
    """Inverse spring ``θ(τ)`` [rad]; odd."""
    y = abs(tq) / s
    y1 = k1 * tm
    y2 = y1 + k2 * (ts - tm)
    if y < y1:
        x = y / k1
    elif y < y2:
        x = tm + (y - y1) / k2
    else:
        x = ts + (y - y2) / k3
    return x if tq >= 0.0 else -x


@njit(cache=True, inline="always")
def spring_piece(x, tm, ts):
    """Piece of the spring law holding ``x``: 0 linear, ±1 mid range, ±2 beyond the stop."""
    a = abs(x)
    if a < tm:
        return 0
    sg = 1 if x > 0.0 else -1
    return sg if a < ts else 2 * sg
