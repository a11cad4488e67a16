"""Cable kinematics (Sec. II-B to II-D): segment lengths, totals, coupling matrix.

How the cable route is read
---------------------------
Each cable (right at ``x = +r_x``, left at ``x = -r_x``) runs alternately
through a *channel* fixed to a link and across a *free segment*. Following
Fig. 2 and the paper's own vector for ``L_Ri``, a free segment spans one link
``i`` (joints ``i`` and ``i + 1``): it leaves the channel of link ``i - 1`` at
the point ``(x_c, +r_z)`` relative to joint ``i`` (link ``i - 1``
coordinates) and enters the channel of link ``i + 1`` at ``(x_c, -r_z)``
relative to joint ``i + 1`` (link ``i + 1`` coordinates), ``x_c = ±r_x``.
Written in link ``i``'s frame (origin at joint ``i``) with
``R_y(φ) (x, z) = (x cos φ + z sin φ, -x sin φ + z cos φ)``::

    A = R_y(-θ_i)(x_c, r_z)            = (c_i x_c - s_i r_z,     s_i x_c + c_i r_z)
    B = (0, p) + R_y(θ_{i+1})(x_c, -r_z) = (c_{i+1} x_c - s_{i+1} r_z,
                                          p - s_{i+1} x_c - c_{i+1} r_z)
    L_i = ||B - A||

With ``x_c = +r_x`` this is *exactly* the vector printed in Sec. II-B (it
is not garbled under this reading: only the ``y = 0`` rows carry nothing).
The channel of a link therefore reaches ``r_z`` beyond each of its joints and
is ``p + 2 r_z`` long, which is the ``+ p + 2 r_z`` term of the paper's
total; the nominal free segment is ``p - 2 r_z`` (810 µm, Fig. 3 caption).

Which links carry channels: the right cable's free segments span links
``0, 2, 4, …`` (joint pairs ``(0, 1), (2, 3), …, (26, 27)``), the left
cable's span links ``1, 3, …`` (pairs ``(1, 2), …, (25, 26), (27, 28)``).
A joint index ``0`` or ``n + 1`` is a virtual joint fixed at ``θ = 0`` (the
base channel, the end effector): this reproduces the paper's sum
``p - θ_1 r_x - 2 r_z + (p + 2 r_z) + p - (θ_2 + θ_3) r_x - 2 r_z + …``.
For the default layout (right slots at even joints) each free segment
contains the slot on its cable's side. Every joint lies in exactly one free
segment of each cable, so the simplified totals are Eqs. (2)-(3) for any n.

Totals: ``L_c(θ) = L_c0 + Σ_seg (L_seg(θ) - (p - 2 r_z))`` with
``L_c0 = offset + n p - 2 r_z`` (Sec. II-B); ``offset`` is the cable length
outside the flexible portion, by default chosen so that ``L_c0`` equals the
geometry's free cable length ``cable_L0`` (the ``L_0`` of Eq. 13 and of
``k_c = EA/L_0``).

Shapes: joint angles ``(..., n)``; lengths per cable ``(..., 2)`` ordered
``(R, L)`` as the paper's ``T = (T_R, T_L)``; ``P(θ)`` ``(..., n, 2)`` with
``P[..., k, c] = ∂L_c/∂θ_k`` (Eq. 4; the paper prints ``P^T``).
"""

from __future__ import annotations

import numpy as np

from .geometry import Geometry
from .validation import as_joint_angles

__all__ = [
    "LEFT",
    "RIGHT",
    "cable_length_hessian",
    "cable_lengths",
    "coupling_matrix",
    "coupling_matrix_simple",
    "pulled_side",
    "rest_lengths",
    "segment_joints",
    "segment_length",
    "segment_length_grad",
    "segment_length_min",
    "segment_length_simple",
]

RIGHT, LEFT = +1, -1
_SIDES = (RIGHT, LEFT)  # column order of lengths / P / T


def pulled_side(tension_left, tension_right) -> int:
    """Which cable a test pulls: the one whose tension varies more.

    The one rule used everywhere (friction regimes, figures, diagnosis). A tie
    (both ranges equal, e.g. constant tensions) counts as the left cable, the
    cable the paper's test pulls (Sec. IV, Fig. 11).

    Parameters
    ----------
    tension_left, tension_right : array_like, shape (S,) [N]

    Returns
    -------
    int
        :data:`RIGHT` (+1) or :data:`LEFT` (-1), the sign of the bend it makes.
    """
    tl = np.asarray(tension_left, dtype=float)
    tr = np.asarray(tension_right, dtype=float)
    return LEFT if np.ptp(tl) >= np.ptp(tr) else RIGHT


def _side(side) -> int:
    if side not in (RIGHT, LEFT) or isinstance(side, bool):
        raise ValueError(f"side must be +1 (right cable) or -1 (left cable), got {side!r}")
    return int(side)


def _angles(*arrays):
    out = []
    for a in arrays:
        a = np.asarray(a, dtype=float)
        if not np.isfinite(a).all():
            raise ValueError("joint angles contain NaN or inf")
        out.append(a)
    return out


# --------------------------------------------------------------------------
# One free segment (Sec. II-B, Figs. 2-5)
# --------------------------------------------------------------------------
def _endpoints(ta, tb, geom: Geometry, side: int):
    """Channel exit A and entrance B in link i's frame, (x, z) each."""
    xc, rz, p = side * geom.r_x, geom.r_z, geom.p
    ca, sa, cb, sb = np.cos(ta), np.sin(ta), np.cos(tb), np.sin(tb)
    A = (ca * xc - sa * rz, sa * xc + ca * rz)
    B = (cb * xc - sb * rz, p - sb * xc - cb * rz)
    return A, B, (ca, sa, cb, sb)


def segment_length(theta_a, theta_b, geom: Geometry, side: int = RIGHT) -> np.ndarray:
    """Exact free-segment length ``L_Ri`` (``side=+1``) or ``L_Li`` (``side=-1``) (Sec. II-B).

    Parameters
    ----------
    theta_a, theta_b : array_like, broadcasting
        The angles ``θ_i`` and ``θ_{i+1}`` of the two joints the segment
        crosses [rad] (0 for a virtual joint).
    geom : Geometry
    side : {+1, -1}
        Right (``x = +r_x``) or left cable.

    Returns
    -------
    ndarray [m]
        ``||B - A||`` with the channel points of the module docstring.
        ``L_Li(θ_a, θ_b) = L_Ri(-θ_a, -θ_b)`` (mirror).
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    (ax, az), (bx, bz), _ = _endpoints(ta, tb, geom, side)
    return np.hypot(bx - ax, bz - az)


def segment_length_simple(theta_a, theta_b, geom: Geometry, side: int = RIGHT) -> np.ndarray:
    """Simplified ``L_RSi = p - (θ_i + θ_{i+1}) r_x - 2 r_z`` (left: ``+ r_x``) [m] (Sec. II-B).

    Small angles (``c = 1``, ``s = θ``) and the ``(θ_i - θ_{i+1})² r_z²``
    term dropped.
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    return geom.p - side * (ta + tb) * geom.r_x - 2.0 * geom.r_z


def segment_length_min(theta_a, theta_b, geom: Geometry, side: int = RIGHT,
                       play: float | None = None) -> np.ndarray:
    """Lower bound ``L_DMi`` with channel side play (Sec. II-D, Fig. 4).

    A cable of radius ``r_cable`` in a channel of radius ``r_channel`` may sit
    anywhere within ``±(r_channel - r_cable)`` of the channel axis. The cable
    end at the exit of link ``i-1``'s channel may thus move along that link's
    x axis, ``A + a e_x^{(i-1)}``, and the end at the entrance of link
    ``i+1``'s channel along its x axis, ``B + b e_x^{(i+1)}``, with
    ``|a|, |b| ≤ play``. ``L_DMi`` is the shortest such segment, i.e. the
    distance between the two channel mouths (two line segments that do not
    cross, so the minimum is an endpoint-to-segment distance). The cable
    inside a channel is taken as ``p + 2 r_z`` long whatever its position
    (Fig. 4). ``L_DMi ≤ L_Ri`` (``a = b = 0`` is feasible), with equality at
    ``play = 0``.

    Parameters
    ----------
    theta_a, theta_b : array_like, broadcasting [rad]
    geom : Geometry
    side : {+1, -1}
    play : float, optional
        Side play [m]; default ``geom.channel_radius - geom.cable_radius``.

    Returns
    -------
    ndarray [m]
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    if play is None:
        play = geom.channel_radius - geom.cable_radius
    if not (np.isfinite(play) and play >= 0):
        raise ValueError(f"play must be a finite non-negative length [m], got {play!r}")
    (ax, az), (bx, bz), (ca, sa, cb, sb) = _endpoints(ta, tb, geom, side)
    A = np.stack(np.broadcast_arrays(ax, az), -1)
    B = np.stack(np.broadcast_arrays(bx, bz), -1)
    ea = np.stack(np.broadcast_arrays(ca, sa), -1)    # link i-1's x axis in link i's frame
    eb = np.stack(np.broadcast_arrays(cb, -sb), -1)   # link i+1's x axis in link i's frame
    A0, A1 = A - play * ea, A + play * ea
    B0, B1 = B - play * eb, B + play * eb

    def point_seg(P, S0, S1):
        d = S1 - S0
        dd = np.sum(d * d, -1)
        t = np.where(dd > 0, np.sum((P - S0) * d, -1) / np.where(dd > 0, dd, 1.0), 0.0)
        t = np.clip(t, 0.0, 1.0)
        return np.linalg.norm(P - (S0 + t[..., None] * d), axis=-1)

    return np.minimum.reduce([point_seg(A0, B0, B1), point_seg(A1, B0, B1),
                              point_seg(B0, A0, A1), point_seg(B1, A0, A1)])


def segment_length_grad(theta_a, theta_b, geom: Geometry, side: int = RIGHT, hessian: bool = False):
    """Exact segment length and its derivatives (for ``P(θ)``, Eq. 4).

    Parameters
    ----------
    theta_a, theta_b : array_like, broadcasting [rad]
    geom : Geometry
    side : {+1, -1}
    hessian : bool
        Also return the second derivatives.

    Returns
    -------
    L, dL_da, dL_db : ndarray [m, m/rad]
    (H_aa, H_ab, H_bb) : tuple of ndarray [m/rad²], only with ``hessian=True``
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    xc, rz = side * geom.r_x, geom.r_z
    (ax, az), (bx, bz), (ca, sa, cb, sb) = _endpoints(ta, tb, geom, side)
    vx, vz = bx - ax, bz - az
    L = np.hypot(vx, vz)
    # dv/dθa = -dA/dθa, dv/dθb = dB/dθb
    dax, daz = -(-xc * sa - rz * ca), -(xc * ca - rz * sa)
    dbx, dbz = -xc * sb - rz * cb, -xc * cb + rz * sb
    ga = (vx * dax + vz * daz) / L
    gb = (vx * dbx + vz * dbz) / L
    if not hessian:
        return L, ga, gb
    # d²A/dθa² = -A  =>  d²v/dθa² = +A ;  d²B/dθb² = -(B - (0, p))  =>  d²v/dθb² = -(B - (0,p))
    vaa = vx * ax + vz * az
    vbb = -(vx * bx + vz * (bz - geom.p))
    Haa = (dax * dax + daz * daz + vaa) / L - ga * ga / L
    Hbb = (dbx * dbx + dbz * dbz + vbb) / L - gb * gb / L
    Hab = (dax * dbx + daz * dbz) / L - ga * gb / L
    return L, ga, gb, (Haa, Hab, Hbb)


# --------------------------------------------------------------------------
# Whole cables (Eqs. 2-5)
# --------------------------------------------------------------------------
def segment_joints(n: int, side: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint pairs ``(a, b)`` (1-based; 0 and n+1 are virtual, θ = 0) of each free segment.

    Right cable: ``(0, 1), (2, 3), …``; left cable: ``(1, 2), (3, 4), …``
    (see the module docstring). Every joint 1..n appears exactly once.

    Returns
    -------
    a, b : ndarray of int, shape (n_seg,)
    """
    side = _side(side)
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    a = np.arange(0 if side == RIGHT else 1, n + 1, 2)
    return a, a + 1


def rest_lengths(geom: Geometry, offset: float | None = None) -> np.ndarray:
    """``L_0 = (L_R0, L_L0)``, ``L_c0 = offset + n p - 2 r_z`` [m] (Sec. II-B, Eqs. 2-3).

    Parameters
    ----------
    geom : Geometry
    offset : float, optional
        Cable length outside the flexible portion [m]; default
        ``geom.cable_L0 - (n p - 2 r_z)`` so that ``L_c0 = cable_L0``.

    Returns
    -------
    ndarray, shape (2,) [m]
    """
    inside = geom.n_joints * geom.p - 2.0 * geom.r_z
    if offset is None:
        offset = geom.cable_L0 - inside
    if not np.isfinite(offset):
        raise ValueError(f"offset must be a finite length [m], got {offset!r}")
    if offset + inside <= 0:
        raise ValueError(f"offset {offset!r} m gives a non-positive cable length")
    return np.full(2, offset + inside)


_MODELS = ("exact", "simple", "min")


def cable_lengths(theta, geom: Geometry, model: str = "exact", offset: float | None = None,
                  play: float | None = None) -> np.ndarray:
    """Total cable lengths ``L(θ) = (L_R, L_L)`` [m] (Eqs. 2-3).

    ``model="simple"`` is Eqs. (2)-(3), ``L_R = L_R0 - r_x Σθ``,
    ``L_L = L_L0 + r_x Σθ``; ``"exact"`` sums the exact segment lengths
    ``L_Ri``/``L_Li``; ``"min"`` sums the lower bounds ``L_DMi`` (Sec. II-D,
    ``L_DM``).

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    geom : Geometry
    model : {"exact", "simple", "min"}
    offset : float, optional
        See :func:`rest_lengths`.
    play : float, optional
        Channel side play for ``"min"`` (see :func:`segment_length_min`).

    Returns
    -------
    ndarray, shape (..., 2) [m], columns (R, L)
    """
    th = as_joint_angles(theta, geom.n_joints)
    if model not in _MODELS:
        raise ValueError(f"model must be one of {_MODELS}, got {model!r}")
    L0 = rest_lengths(geom, offset)
    if model == "simple":
        s = th.sum(axis=-1)
        return np.stack([L0[0] - geom.r_x * s, L0[1] + geom.r_x * s], axis=-1)
    pad = np.zeros(th.shape[:-1] + (geom.n_joints + 2,))
    pad[..., 1:-1] = th
    nominal = geom.p - 2.0 * geom.r_z
    out = []
    for k, side in enumerate(_SIDES):
        a, b = segment_joints(geom.n_joints, side)
        ta, tb = pad[..., a], pad[..., b]
        if model == "exact":
            seg = segment_length(ta, tb, geom, side)
        else:
            seg = segment_length_min(ta, tb, geom, side, play)
        out.append(L0[k] + np.sum(seg - nominal, axis=-1))
    return np.stack(out, axis=-1)


def coupling_matrix_simple(geom: Geometry) -> np.ndarray:
    """Simplified coupling matrix of Eq. (5): ``P^T = r_x [[-1 … -1], [1 … 1]]``.

    Returns
    -------
    ndarray, shape (n, 2) [m/rad]
        ``P`` (columns R, L); its transpose is the paper's ``P^T``.
    """
    P = np.empty((geom.n_joints, 2))
    P[:, 0] = -geom.r_x
    P[:, 1] = geom.r_x
    return P


def coupling_matrix(theta, geom: Geometry, model: str = "exact") -> np.ndarray:
    """Coupling matrix ``P(θ)``, ``L̇ = P^T θ̇`` (Eq. 4).

    ``model="exact"``: the analytic derivative of the exact lengths
    (:func:`cable_lengths` with ``"exact"``); ``"simple"``: Eq. (5),
    independent of θ.

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    geom : Geometry
    model : {"exact", "simple"}

    Returns
    -------
    ndarray, shape (..., n, 2) [m/rad], ``P[..., k, c] = ∂L_c/∂θ_k``, c = (R, L)
    """
    th = as_joint_angles(theta, geom.n_joints)
    if model == "simple":
        return np.broadcast_to(coupling_matrix_simple(geom), th.shape + (2,)).copy()
    if model != "exact":
        raise ValueError(f"model must be 'exact' or 'simple', got {model!r}")
    n = geom.n_joints
    pad = np.zeros(th.shape[:-1] + (n + 2,))
    pad[..., 1:-1] = th
    P = np.zeros(th.shape[:-1] + (n + 2, 2))
    for k, side in enumerate(_SIDES):
        a, b = segment_joints(n, side)
        _, ga, gb = segment_length_grad(pad[..., a], pad[..., b], geom, side)
        P[..., a, k] = ga       # every joint appears once per cable: no collisions
        P[..., b, k] = gb
    return P[..., 1:-1, :]


def cable_length_hessian(theta, geom: Geometry) -> np.ndarray:
    """Second derivatives ``∂²L_c/∂θ_k∂θ_m`` of the exact lengths (block diagonal).

    Returns
    -------
    ndarray, shape (..., 2, n, n) [m/rad²], first axis c = (R, L)
    """
    th = as_joint_angles(theta, geom.n_joints)
    n = geom.n_joints
    pad = np.zeros(th.shape[:-1] + (n + 2,))
    pad[..., 1:-1] = th
    H = np.zeros(th.shape[:-1] + (2, n + 2, n + 2))
    for k, side in enumerate(_SIDES):
        a, b = segment_joints(n, side)
        _, _, _, (haa, hab, hbb) = segment_length_grad(pad[..., a], pad[..., b], geom, side,
                                                       hessian=True)
        H[..., k, a, a] = haa
        H[..., k, a, b] = hab
        H[..., k, b, a] = hab
        H[..., k, b, b] = hbb
    return H[..., 1:-1, 1:-1]
