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

Per-link spacings: the free segment along link ``i`` uses that link's
spacing ``p_i`` (``geom.pitches``; the base channel's segment the first
spacing, the end effector's the last), so ``p`` in ``B`` above is per segment.

Real tubes: a tendon free in the lumen (``geom.tendon_path = "lumen"``)
crosses each notch ``j`` at ``c_j = σ arm_j`` from the joint's neutral axis
(``arm_j = geom.moment_arms(σ)``, ``σ`` its side) and is fixed to the links
between notches. With the notch bent as a circular arc (radius ``h_j/θ_j``,
docs/models.md "Real tubes: kinematics"), its length across the notch is

* ``"simple"``: the arc of the fibre at ``c_j``, ``h_j - c_j θ_j``
  (``Δℓ_j = -c_j θ_j``: the coupling column is minus the moment arm, the
  analogue of Eq. 5; exact for a tendon held at its arm, e.g. by the wall);
* ``"exact"``: the straight chord between the two faces,
  ``2 (h_j/θ_j - c_j) sin(θ_j/2) = h_j sinc(θ_j/2) - 2 c_j sin(θ_j/2)``
  (a tendon across a slot that cuts the lumen open, as deep one-sided
  notches do); its slope at ``θ = 0`` is ``-c_j``.

Shapes: joint angles ``(..., n)``; lengths per cable ``(..., k)`` for the
geometry's ``k`` tendons ordered ``(R, L)`` as the paper's ``T = (T_R, T_L)``
(:func:`tendon_columns`; ``(..., 2)`` for the seed tube); ``P(θ)`` ``(..., n, k)`` with
``P[..., k, c] = ∂L_c/∂θ_k`` (Eq. 4; the paper prints ``P^T``).
"""

from __future__ import annotations

import numpy as np

from .geometry import Geometry
from .kinematics import _sinc_and_derivative
from ..validation import as_joint_angles

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
    "segment_spacings",
    "tendon_columns",
    "tendon_notch_lengths",
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
def _spacing(geom: Geometry, p):
    """The segment's link spacing [m]: ``p`` if given, else the geometry's one spacing."""
    if p is not None:
        return p
    pitches = geom.pitches
    if not np.all(pitches == pitches[0]):
        raise ValueError(f"geometry {geom.name!r} has per-link spacings: pass the segment's p "
                         "(see segment_spacings)")
    return geom.p if not isinstance(geom.p, tuple) else float(pitches[0])


def _endpoints(ta, tb, geom: Geometry, side: int, p=None):
    """Channel exit A and entrance B in link i's frame, (x, z) each."""
    xc, rz, p = side * geom.r_x, geom.r_z, _spacing(geom, p)
    ca, sa, cb, sb = np.cos(ta), np.sin(ta), np.cos(tb), np.sin(tb)
    A = (ca * xc - sa * rz, sa * xc + ca * rz)
    B = (cb * xc - sb * rz, p - sb * xc - cb * rz)
    return A, B, (ca, sa, cb, sb)


def segment_length(theta_a, theta_b, geom: Geometry, side: int = RIGHT, p=None) -> np.ndarray:
    """Exact free-segment length ``L_Ri`` (``side=+1``) or ``L_Li`` (``side=-1``) (Sec. II-B).

    Parameters
    ----------
    theta_a, theta_b : array_like, broadcasting
        The angles ``θ_i`` and ``θ_{i+1}`` of the two joints the segment
        crosses [rad] (0 for a virtual joint).
    geom : Geometry
    side : {+1, -1}
        Right (``x = +r_x``) or left cable.
    p : float or array_like, optional
        The spacing of the link the segment runs along [m] (default: the
        geometry's one spacing; required for per-link spacings).

    Returns
    -------
    ndarray [m]
        ``||B - A||`` with the channel points of the module docstring.
        ``L_Li(θ_a, θ_b) = L_Ri(-θ_a, -θ_b)`` (mirror).
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    (ax, az), (bx, bz), _ = _endpoints(ta, tb, geom, side, p)
    return np.hypot(bx - ax, bz - az)


def segment_length_simple(theta_a, theta_b, geom: Geometry, side: int = RIGHT, p=None) -> np.ndarray:
    """Simplified ``L_RSi = p - (θ_i + θ_{i+1}) r_x - 2 r_z`` (left: ``+ r_x``) [m] (Sec. II-B).

    Small angles (``c = 1``, ``s = θ``) and the ``(θ_i - θ_{i+1})² r_z²``
    term dropped.
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    return _spacing(geom, p) - side * (ta + tb) * geom.r_x - 2.0 * geom.r_z


def segment_length_min(theta_a, theta_b, geom: Geometry, side: int = RIGHT,
                       play: float | None = None, p=None) -> np.ndarray:
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
    (ax, az), (bx, bz), (ca, sa, cb, sb) = _endpoints(ta, tb, geom, side, p)
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


def segment_length_grad(theta_a, theta_b, geom: Geometry, side: int = RIGHT, hessian: bool = False,
                        p=None):
    """Exact segment length and its derivatives (for ``P(θ)``, Eq. 4).

    Parameters
    ----------
    theta_a, theta_b : array_like, broadcasting [rad]
    geom : Geometry
    side : {+1, -1}
    hessian : bool
        Also return the second derivatives.
    p : float or array_like, optional
        The segment's link spacing [m] (see :func:`segment_length`).

    Returns
    -------
    L, dL_da, dL_db : ndarray [m, m/rad]
    (H_aa, H_ab, H_bb) : tuple of ndarray [m/rad²], only with ``hessian=True``
    """
    side = _side(side)
    ta, tb = _angles(theta_a, theta_b)
    xc, rz = side * geom.r_x, geom.r_z
    p = _spacing(geom, p)
    (ax, az), (bx, bz), (ca, sa, cb, sb) = _endpoints(ta, tb, geom, side, p)
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
    vbb = -(vx * bx + vz * (bz - p))
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


def tendon_columns(geom: Geometry) -> tuple[int, ...]:
    """The sides of the geometry's tendons in column order: ``(RIGHT, LEFT)``, or the one it has.

    The column order of every length, coupling matrix and tension vector
    here, the paper's ``T = (T_R, T_L)`` for the seed tube.
    """
    return tuple(s for s in _SIDES if s in geom.tendon_sides)


def segment_spacings(geom: Geometry) -> np.ndarray:
    """Spacing of the link each free channel segment runs along, links 0..n (n + 1,) [m].

    Link ``i`` (1 ≤ i < n) spans joints ``i`` to ``i + 1``: ``geom.pitches[i-1]``;
    the base channel's link 0 and the end effector's link n take the first and
    last spacing (the seed tube: ``p`` everywhere).
    """
    p = geom.pitches
    if geom.n_joints == 1:
        return np.full(2, p[0])
    return np.concatenate([p[:1], p, p[-1:]])


def _lumen(geom: Geometry) -> bool:
    return geom.tendon_path == "lumen"


def _check_channel_law(geom: Geometry, model: str) -> None:
    if geom.backbone != "axis" and model != "simple":
        raise ValueError("the channel law (Sec. II-B) is written for joints on the tube axis "
                         "(backbone = 'axis'); use model='simple' (moment arms about the neutral axes)")


def rest_lengths(geom: Geometry, offset: float | None = None) -> np.ndarray:
    """Tendon lengths at θ = 0, one per tendon (:func:`tendon_columns`) [m] (Sec. II-B, Eqs. 2-3).

    Channel: ``L_c0 = offset + n p - 2 r_z`` (per-link spacings: ``Σ p + p_n``
    for ``n p``). Lumen: ``L_c0 = offset + (z_tip - z_base)``, the tendon
    along the tube from the base edge to the tip face.

    Parameters
    ----------
    geom : Geometry
    offset : float, optional
        Tendon length outside the flexible portion [m]; default
        ``geom.cable_L0 - inside`` so that ``L_c0 = cable_L0`` (0 for a
        geometry without ``cable_L0``).

    Returns
    -------
    ndarray, shape (k,) [m]; ``(2,)`` for the seed tube
    """
    p = geom.pitches
    if _lumen(geom):
        inside = geom.tip_z - geom.base_edge_z
    elif np.all(p == p[0]):
        inside = geom.n_joints * _spacing(geom, None) - 2.0 * geom.r_z
    else:
        inside = float(p.sum() + p[-1]) - 2.0 * geom.r_z
    if offset is None:
        offset = geom.cable_L0 - inside if geom.cable_L0 is not None else 0.0
    if not np.isfinite(offset):
        raise ValueError(f"offset must be a finite length [m], got {offset!r}")
    if offset + inside <= 0:
        raise ValueError(f"offset {offset!r} m gives a non-positive cable length")
    return np.full(len(tendon_columns(geom)), offset + inside)


def tendon_notch_lengths(theta, geom: Geometry, side: int, model: str = "simple", derivative: int = 0,
                         *, series_below: float = 1e-3):
    """Length change of a lumen tendon across each notch, ``Δℓ_j = ℓ_j(θ_j) - h_j`` [m].

    ``"simple"``: ``-c_j θ_j``; ``"exact"``: ``h_j (sinc(θ_j/2) - 1) - 2 c_j sin(θ_j/2)``
    with ``c_j = σ arm_j`` (module docstring; the arc geometry of
    :func:`notchfit.physics.kinematics.arc_translation`).

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    geom : Geometry
    side : {+1, -1}
        The tendon's side.
    model : {"simple", "exact"}
    derivative : {0, 1, 2}
        0: ``Δℓ``; 1: ``dℓ_j/dθ_j`` [m/rad]; 2: ``d²ℓ_j/dθ_j²`` [m/rad²].
    series_below : float
        ``|θ/2|`` below which ``sinc`` and its derivatives use their Taylor series.

    Returns
    -------
    ndarray, shape (..., n)
    """
    side = _side(side)
    th = as_joint_angles(theta, geom.n_joints)
    c = side * geom.moment_arms(side)
    h = geom.slot_widths
    if model == "simple":
        return (-c * th, np.broadcast_to(-c, th.shape).copy(), np.zeros(th.shape))[derivative]
    if model != "exact":
        raise ValueError(f"model must be 'simple' or 'exact' for a lumen tendon, got {model!r}")
    u = 0.5 * th
    sc, dsc = _sinc_and_derivative(u, series_below)
    if derivative == 0:
        return h * (sc - 1.0) - 2.0 * c * np.sin(u)
    if derivative == 1:
        return 0.5 * h * dsc - c * np.cos(u)
    # sinc'' = -sinc - 2 sinc'/u loses digits as 1/u²: its series (to u⁶) below 50 series_below
    small = np.abs(u) < 50.0 * series_below
    us = np.where(small, 1.0, u)
    u2 = u * u
    d2 = np.where(small, -1.0 / 3.0 + u2 / 10.0 - u2 * u2 / 168.0 + u2**3 / 6480.0, -sc - 2.0 * dsc / us)
    return 0.25 * h * d2 + 0.5 * c * np.sin(u)


_MODELS = ("exact", "simple", "min")


def cable_lengths(theta, geom: Geometry, model: str = "exact", offset: float | None = None,
                  play: float | None = None) -> np.ndarray:
    """Total cable lengths ``L(θ) = (L_R, L_L)`` [m] (Eqs. 2-3).

    ``model="simple"`` is Eqs. (2)-(3), ``L_R = L_R0 - r_x Σθ``,
    ``L_L = L_L0 + r_x Σθ``; ``"exact"`` sums the exact segment lengths
    ``L_Ri``/``L_Li``; ``"min"`` sums the lower bounds ``L_DMi`` (Sec. II-D,
    ``L_DM``). A lumen tendon sums :func:`tendon_notch_lengths` (``"simple"``
    or ``"exact"``).

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
    ndarray, shape (..., k) [m], columns :func:`tendon_columns` ((R, L) for the seed tube)
    """
    th = as_joint_angles(theta, geom.n_joints)
    if model not in _MODELS:
        raise ValueError(f"model must be one of {_MODELS}, got {model!r}")
    L0 = rest_lengths(geom, offset)
    cols = tendon_columns(geom)
    if _lumen(geom):
        return np.stack([L0[k] + tendon_notch_lengths(th, geom, s, model).sum(axis=-1)
                         for k, s in enumerate(cols)], axis=-1)
    _check_channel_law(geom, model)
    if model == "simple":
        s = th.sum(axis=-1)
        return np.stack([L0[k] - side * (geom.r_x * s) for k, side in enumerate(cols)], axis=-1)
    pad = np.zeros(th.shape[:-1] + (geom.n_joints + 2,))
    pad[..., 1:-1] = th
    sp = segment_spacings(geom)
    out = []
    for k, side in enumerate(cols):
        a, b = segment_joints(geom.n_joints, side)
        ta, tb = pad[..., a], pad[..., b]
        if model == "exact":
            seg = segment_length(ta, tb, geom, side, p=sp[a])
        else:
            seg = segment_length_min(ta, tb, geom, side, play, p=sp[a])
        out.append(L0[k] + np.sum(seg - (sp[a] - 2.0 * geom.r_z), axis=-1))
    return np.stack(out, axis=-1)


def coupling_matrix_simple(geom: Geometry) -> np.ndarray:
    """Simplified coupling matrix of Eq. (5): ``P^T = r_x [[-1 … -1], [1 … 1]]``.

    For a lumen tendon (or joints off the tube axis) the column of the tendon
    on side ``σ`` is ``-σ arm_j`` (``arm_j = geom.moment_arms(σ)``): the
    same law about each joint's bending axis.

    Returns
    -------
    ndarray, shape (n, k) [m/rad]
        ``P`` (columns :func:`tendon_columns`); its transpose is the paper's ``P^T``.
    """
    cols = tendon_columns(geom)
    P = np.empty((geom.n_joints, len(cols)))
    for k, side in enumerate(cols):
        if _lumen(geom) or geom.backbone != "axis":
            P[:, k] = -side * geom.moment_arms(side)
        else:
            P[:, k] = -side * geom.r_x
    return P


def coupling_matrix(theta, geom: Geometry, model: str = "exact") -> np.ndarray:
    """Coupling matrix ``P(θ)``, ``L̇ = P^T θ̇`` (Eq. 4).

    ``model="exact"``: the analytic derivative of the exact lengths
    (:func:`cable_lengths` with ``"exact"``); ``"simple"``: Eq. (5),
    independent of θ (:func:`coupling_matrix_simple`).

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    geom : Geometry
    model : {"exact", "simple"}

    Returns
    -------
    ndarray, shape (..., n, k) [m/rad], ``P[..., k, c] = ∂L_c/∂θ_k``, c in :func:`tendon_columns`
    """
    th = as_joint_angles(theta, geom.n_joints)
    if model == "simple":
        return np.broadcast_to(coupling_matrix_simple(geom), th.shape + (len(tendon_columns(geom)),)).copy()
    if model != "exact":
        raise ValueError(f"model must be 'exact' or 'simple', got {model!r}")
    cols = tendon_columns(geom)
    if _lumen(geom):
        return np.stack([tendon_notch_lengths(th, geom, s, "exact", 1) for s in cols], axis=-1)
    _check_channel_law(geom, model)
    n = geom.n_joints
    pad = np.zeros(th.shape[:-1] + (n + 2,))
    pad[..., 1:-1] = th
    sp = segment_spacings(geom)
    P = np.zeros(th.shape[:-1] + (n + 2, len(cols)))
    for k, side in enumerate(cols):
        a, b = segment_joints(n, side)
        _, ga, gb = segment_length_grad(pad[..., a], pad[..., b], geom, side, p=sp[a])
        P[..., a, k] = ga       # every joint appears once per cable: no collisions
        P[..., b, k] = gb
    return P[..., 1:-1, :]


def cable_length_hessian(theta, geom: Geometry) -> np.ndarray:
    """Second derivatives ``∂²L_c/∂θ_k∂θ_m`` of the exact lengths (block diagonal).

    Returns
    -------
    ndarray, shape (..., k, n, n) [m/rad²], first axis c in :func:`tendon_columns`
    """
    th = as_joint_angles(theta, geom.n_joints)
    n = geom.n_joints
    cols = tendon_columns(geom)
    if _lumen(geom):
        H = np.zeros(th.shape[:-1] + (len(cols), n, n))
        idx = np.arange(n)
        for k, s in enumerate(cols):
            H[..., k, idx, idx] = tendon_notch_lengths(th, geom, s, "exact", 2)
        return H
    _check_channel_law(geom, "exact")
    pad = np.zeros(th.shape[:-1] + (n + 2,))
    pad[..., 1:-1] = th
    sp = segment_spacings(geom)
    H = np.zeros(th.shape[:-1] + (len(cols), n + 2, n + 2))
    for k, side in enumerate(cols):
        a, b = segment_joints(n, side)
        _, _, _, (haa, hab, hbb) = segment_length_grad(pad[..., a], pad[..., b], geom, side,
                                                       hessian=True, p=sp[a])
        H[..., k, a, a] = haa
        H[..., k, a, b] = hab
        H[..., k, b, a] = hab
        H[..., k, b, b] = hbb
    return H[..., 1:-1, 1:-1]
