"""Quasi-static model, constant curvature and stiffness (Sec. III, docs/models.md).

Equation of motion (Eq. 10)::

    θ̇ = -(1/B) G(θ, t),   G = K_θ(θ) θ + P(θ) T - τ_load(θ)

* ``K_θ(θ) θ = τ(θ)`` is the flexure spring torque (a
  :class:`~notchfit.physics.springs.PiecewiseLinearSpring`; the paper's dual-rate
  spring of Fig. 7 by default).
* ``P(θ) T`` is Eq. (9) with ``P = ∂L/∂θ`` (:mod:`notchfit.physics.cables`) and
  ``T = (T_R, T_L) ≥ 0``: a right-cable pull gives ``P T = -r_x T_R`` per
  joint and bends toward ``+x`` (positive θ), as docs/geometry.md requires.
* **Sign of the wrench term.** The paper writes ``+ J_st^s(θ)^T F_s`` inside
  ``-(1/B)(…)``. Every other term in the bracket is a torque the joints must
  *resist* (the cable term is ``+∂(T·L)/∂θ``, the gradient of the cable's
  potential), so the paper's ``F_s`` must be the wrench the manipulator
  exerts *on its environment*. notchfit reads it that way: the user gives the
  load applied **on** the manipulator at the tool point, in world coordinates
  (force ``f`` [N], moment ``τ`` [N m], Appendix/Eq. 28), and
  ``F_s = -F_s,load`` with ``F_s,load = (f, p̂_st f + τ)`` (Eq. 28). Hence
  ``τ_load = J_st^s(θ)^T F_s,load = J_X^T (f_x, f_z, τ_y)``
  (:func:`notchfit.physics.kinematics.joint_torques_from_tip_wrench`): a force
  toward ``+x`` bends the chain toward ``+x``. Out-of-plane components
  (``f_y, τ_x, τ_z``) are carried by the structure (the nullspace
  ``F_1..F_3`` of Sec. III) and produce no joint torque.

Cable-position input (Eqs. 13-14): ``d = L(θ) - L_0 + u`` and
``T = T(d)`` with a :class:`CableLaw` (linear ``k_c = EA/L_0`` or the
quadratic ``T = K d²`` of Sec. III-C3). A cable cannot push: ``d ≤ 0`` means
a slack cable with ``T = 0``.

Real tubes (docs/models.md, "Real tubes: mechanics"): the spring acts on the
deflection from each joint's rest angle, ``τ_j(θ_j - θ0_j)`` (``geom.rest_angles``);
with ``coupling = "simple"`` the columns of ``P`` are the tendons' moment arms
about each joint's bending axis, ``P[:, R] = -a_R``, ``P[:, L] = +a_L``
(:meth:`~notchfit.physics.geometry.Geometry.moment_arms`; ``±r_x`` for the seed tube,
Eq. 5), and a tendon the geometry lacks must carry no tension. With the
spring of :meth:`notchfit.physics.friction.FrictionParams.joint_spring` and no friction
the rest state is ``τ_j(θ_j - θ0_j) = a_R,j T_R - a_L,j T_L`` per joint.

Stiffness (Sec. III-C): ``K_m = K_θ + P K_c P^T`` (Eq. 17 ff.),
``K_w = (J_X K_m^{-1} J_X^T)^{-1}`` (Eq. 23), the Lagrange system (Eq. 22),
``δθ`` (Eq. 24), whose energy ``½ δθᵀ K_m δθ = ½ δXᵀ K_w δX`` is Eq. (25).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

from . import cables, kinematics
from .. import paper
from .geometry import Geometry
from .shapes import line_fit
from .springs import PiecewiseLinearSpring, dual_rate_spring
from ..validation import as_finite, as_joint_angles

__all__ = [
    "CableLaw",
    "arm_coupling",
    "ConstantCurvature",
    "Equilibrium",
    "FEAReference",
    "PathDependence",
    "QuasiStaticModel",
    "Schedule",
    "Trajectory",
    "constant_curvature",
    "equilibrium",
    "equivalent_stiffness_moment",
    "equivalent_stiffness_transverse",
    "joint_displacement",
    "joint_stiffness",
    "path_dependence",
    "simulate",
    "workspace_stiffness",
    "workspace_stiffness_lagrange",
]


# --------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------
def _tensions(T) -> np.ndarray:
    T = as_finite(T, "cable tensions")
    if T.shape[-1:] != (2,):
        raise ValueError(f"cable tensions must have shape (..., 2) as (T_R, T_L) [N], got {T.shape}")
    if (T < 0).any():
        raise ValueError(f"cable tensions must be >= 0 (a cable cannot push), got {T.tolist()}")
    return T


def _tip_load(F) -> np.ndarray:
    """(f_x, f_z, m_y) from a 3-vector or a 6-vector world load (f, τ)."""
    F = as_finite(F, "tip load")
    if F.shape == (6,):
        return F[[0, 2, 4]]
    if F.shape != (3,):
        raise ValueError("tip load must be (f_x, f_z, m_y) [N, N, N m] or a world wrench "
                         f"(f_x, f_y, f_z, τ_x, τ_y, τ_z), got shape {F.shape}")
    return F


@dataclass(frozen=True, eq=False)
class Schedule:
    """Piecewise-linear time history, held constant outside ``[times[0], times[-1]]``.

    Parameters
    ----------
    times : array_like, shape (k,)
        Strictly increasing times [s].
    values : array_like, shape (k, m)
        Values at those times (tensions [N], positions [m], loads [N, N m]).
    """

    times: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        t = as_finite(self.times, "schedule times")
        v = as_finite(self.values, "schedule values")
        if t.ndim != 1 or t.size < 1:
            raise ValueError("schedule times must be a non-empty 1-D array [s]")
        if v.ndim == 1:
            v = v[:, None]
        if v.shape[0] != t.size:
            raise ValueError(f"schedule values need one row per time, got {v.shape} for {t.size} times")
        if (np.diff(t) <= 0).any():
            raise ValueError("schedule times must be strictly increasing")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "values", v)

    @classmethod
    def constant(cls, value) -> "Schedule":
        v = np.atleast_1d(np.asarray(value, dtype=float))
        return cls(np.array([0.0]), v[None, :])

    def __call__(self, t: float) -> np.ndarray:
        if self.times.size == 1:
            return self.values[0].copy()
        return np.array([np.interp(t, self.times, col) for col in self.values.T])


def _schedule(x, width: int, what: str) -> Schedule | None:
    if x is None:
        return None
    s = x if isinstance(x, Schedule) else Schedule.constant(x)
    if s.values.shape[1] != width and not (what == "tip load" and s.values.shape[1] == 6):
        raise ValueError(f"{what} schedule must have {width} columns, got {s.values.shape[1]}")
    if what == "cable tensions":
        _tensions(s.values)
    return s


@dataclass(frozen=True)
class CableLaw:
    """Tension-elongation law ``T(d)`` of one cable (Eq. 14, Sec. III-C3).

    ``kind="linear"``: ``T = k d`` (``coefficient = k`` [N/m], e.g.
    ``k_c = EA/L_0``); ``kind="quadratic"``: ``T = K d²`` (``coefficient = K``
    [N/m²]). ``T = 0`` for ``d ≤ 0`` (slack: a cable cannot push).
    """

    kind: str
    coefficient: float

    def __post_init__(self) -> None:
        if self.kind not in ("linear", "quadratic"):
            raise ValueError(f"cable law kind must be 'linear' or 'quadratic', got {self.kind!r}")
        if not (math.isfinite(self.coefficient) and self.coefficient > 0):
            raise ValueError(f"cable law coefficient must be positive, got {self.coefficient!r}")

    @classmethod
    def linear(cls, geom: Geometry) -> "CableLaw":
        """``k_c = E A / L_0`` from the geometry (4.17e4 N/m for the paper's cable)."""
        return cls("linear", geom.cable_stiffness)

    @classmethod
    def quadratic(cls, K: float) -> "CableLaw":
        return cls("quadratic", float(K))

    def tension(self, d) -> np.ndarray:
        """``T(d)`` [N] for elongation ``d`` [m]."""
        d = np.maximum(as_finite(d, "cable elongation"), 0.0)
        return self.coefficient * (d if self.kind == "linear" else d * d)

    def stiffness(self, d) -> np.ndarray:
        """``dT/dd`` [N/m]: ``k`` (linear) or ``2 K d`` (quadratic); 0 when slack."""
        d = as_finite(d, "cable elongation")
        if self.kind == "linear":
            return np.where(d > 0, self.coefficient, 0.0)
        return 2.0 * self.coefficient * np.maximum(d, 0.0)


def arm_coupling(geom: Geometry) -> np.ndarray:
    """``P`` (n, 2) [m/rad] of tendons with per-joint moment arms (Eq. 5 generalised).

    Columns (R, L): ``-a_R,j`` and ``+a_L,j`` (:meth:`Geometry.moment_arms`), so
    ``-P T`` is the drive torque ``a_R,j T_R - a_L,j T_L``; for the seed tube
    ``a = r_x`` at every joint and this is Eq. (5) exactly.
    """
    P = np.empty((geom.n_joints, 2))
    P[:, 0] = -geom.moment_arms(+1)
    P[:, 1] = geom.moment_arms(-1)
    return P


# --------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class QuasiStaticModel:
    """Parameters of the quasi-static model (Eq. 10).

    Attributes
    ----------
    geom : Geometry
    spring : PiecewiseLinearSpring
        Flexure law ``τ(θ) = K_θ(θ) θ`` (default: Fig. 7 dual-rate spring).
    damping : float
        ``B`` [N m s/rad] (0.03, the value of Sec. IV-B; it sets only the time scale).
    coupling : {"simple", "exact"}
        ``P`` from Eq. (5) with each joint's moment arms (the paper's Sec. III;
        module docstring) or the exact derivative of the channel cable lengths.
    cable_law : CableLaw, optional
        For cable-position input; default linear ``k_c = EA/L_0`` (None when the
        geometry gives no cable modulus: tensions only).
    cable_offset : float, optional
        Cable length outside the manipulator [m] (:func:`cables.rest_lengths`).
    load_offset : float
        The tip load acts this far beyond the tool point along the
        end-effector axis [m] (0: at the tool point ``(0, 0, n p)``).
    """

    geom: Geometry
    spring: PiecewiseLinearSpring = field(default_factory=dual_rate_spring)
    damping: float = paper.DAMPING
    coupling: str = "simple"
    cable_law: CableLaw | None = None
    cable_offset: float | None = None
    load_offset: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.damping) and self.damping > 0):
            raise ValueError(f"damping B must be positive [N m s/rad], got {self.damping!r}")
        if self.coupling not in ("simple", "exact"):
            raise ValueError(f"coupling must be 'simple' or 'exact', got {self.coupling!r}")
        if not math.isfinite(self.load_offset):
            raise ValueError("load_offset must be finite")
        if self.cable_law is None and None not in (self.geom.cable_E, self.geom.cable_A, self.geom.cable_L0):
            object.__setattr__(self, "cable_law", CableLaw.linear(self.geom))

    # ------------------------------------------------------------ pieces
    @property
    def rest_lengths(self) -> np.ndarray:
        """``L_0 = (L_R0, L_L0)`` [m] (Eq. 13)."""
        return cables.rest_lengths(self.geom, self.cable_offset)

    def lengths(self, theta) -> np.ndarray:
        """Cable lengths ``L(θ)`` (..., 2) [m] in the model's coupling."""
        return cables.cable_lengths(theta, self.geom, "simple" if self.coupling == "simple" else "exact",
                                    self.cable_offset)

    def coupling_matrix(self, theta) -> np.ndarray:
        """``P(θ)`` (n, 2) [m/rad]."""
        if self.coupling == "simple":
            th = as_joint_angles(theta, self.geom.n_joints)
            return np.broadcast_to(arm_coupling(self.geom), th.shape + (2,)).copy()
        return cables.coupling_matrix(theta, self.geom, self.coupling)

    def elongation(self, theta, positions) -> np.ndarray:
        """``d = L(θ) - L_0 + u`` (Eq. 13) [m]."""
        u = as_finite(positions, "cable positions")
        if self.cable_law is None:
            raise ValueError(f"geometry {self.geom.name!r} gives no cable modulus: give cable tensions, not positions")
        if u.shape[-1:] != (2,):
            raise ValueError(f"cable positions must be (u_R, u_L) [m], got shape {u.shape}")
        return self.lengths(theta) - self.rest_lengths + u

    def tensions_from_positions(self, theta, positions) -> np.ndarray:
        """``T(d(θ, u))`` (Eq. 14) [N]; a slack cable carries no tension."""
        return self.cable_law.tension(self.elongation(theta, positions))

    def load_torques(self, theta, tip_load) -> np.ndarray:
        """Joint torques of a tip load applied on the manipulator (world frame).

        ``J_st^s(θ)^T F_s,load`` with ``F_s,load`` from Eq. (28), computed
        as ``J_X^T (f_x, f_z, m_y + e (f_x cos φ - f_z sin φ))`` (``e`` =
        ``load_offset``, ``φ = Σθ``).
        """
        fx, fz, my = _tip_load(tip_load)
        th = np.asarray(theta, dtype=float)
        if self.load_offset:
            phi = th.sum(-1)
            my = my + self.load_offset * (fx * np.cos(phi) - fz * np.sin(phi))
        return kinematics.joint_torques_from_tip_wrench(th, self.geom, fx, fz, my)

    def _load_hessian(self, theta, tip_load) -> np.ndarray:
        fx, fz, _ = _tip_load(tip_load)
        J = kinematics.planar_jacobian(theta, self.geom)
        n = self.geom.n_joints
        idx = np.maximum.outer(np.arange(n), np.arange(n))
        H = fx * J[1][idx] - fz * J[0][idx]
        if self.load_offset:
            phi = float(np.sum(theta))
            H = H + self.load_offset * (-fx * np.sin(phi) - fz * np.cos(phi))
        return H

    # ------------------------------------------------------------ residual
    def residual(self, theta, tensions=None, tip_load=None, positions=None) -> np.ndarray:
        """``G(θ) = τ(θ) + P(θ) T - τ_load(θ)`` [N m] (``θ̇ = -G/B``, Eq. 10).

        Give either ``tensions`` (T_R, T_L) [N] or cable ``positions``
        (u_R, u_L) [m] (Eqs. 13-14), and optionally ``tip_load``.
        """
        th = as_joint_angles(theta, self.geom.n_joints)
        G = self.spring.torque(th - self.geom.rest_angles)
        T = self._T(th, tensions, positions)
        if T is not None:
            G = G + self.coupling_matrix(th) @ T
        if tip_load is not None:
            G = G - self.load_torques(th, tip_load)
        return G

    def _T(self, th, tensions, positions):
        if tensions is not None and positions is not None:
            raise ValueError("give cable tensions or cable positions, not both")
        if tensions is not None:
            T = _tensions(tensions)
            for k, side in enumerate(("right", "left")):
                if side not in self.geom.tendons and np.any(T[..., k] != 0):
                    raise ValueError(f"the geometry has no {side} tendon: its tension must be 0")
            return T
        if positions is not None:
            return self.tensions_from_positions(th, positions)
        return None

    def residual_jacobian(self, theta, tensions=None, tip_load=None, positions=None) -> np.ndarray:
        """``∂G/∂θ`` (n, n) [N m/rad]: tangent spring stiffness, cable and load terms."""
        th = as_joint_angles(theta, self.geom.n_joints)
        Jg = np.diag(self.spring.stiffness(th - self.geom.rest_angles) * np.ones(self.geom.n_joints))
        T = self._T(th, tensions, positions)
        if T is not None:
            if self.coupling == "exact":
                Jg = Jg + np.einsum("c,ckm->km", T, cables.cable_length_hessian(th, self.geom))
            if positions is not None:
                P = self.coupling_matrix(th)
                kc = self.cable_law.stiffness(self.elongation(th, positions))
                Jg = Jg + (P * kc) @ P.T
        if tip_load is not None:
            Jg = Jg - self._load_hessian(th, tip_load)
        return Jg


# --------------------------------------------------------------------------
# Integration of Eq. (10) and the direct solver
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Trajectory:
    """Result of :func:`simulate`: ``theta[k]`` (n,) at ``t[k]`` [s, rad]."""

    t: np.ndarray
    theta: np.ndarray
    success: bool
    message: str
    rate: float  # max |θ̇| at the end [rad/s]

    @property
    def final(self) -> np.ndarray:
        return self.theta[-1]


def simulate(model: QuasiStaticModel, t_span, theta0=None, *, tensions=None, tip_load=None,
             positions=None, t_eval=None, method: str = "Radau", rtol: float = 1e-9,
             atol: float = 1e-12, max_step: float = np.inf) -> Trajectory:
    """Integrate ``θ̇ = -(1/B)(K_θ(θ)θ + J^T F_s + P T)`` (Eq. 10).

    Parameters
    ----------
    model : QuasiStaticModel
    t_span : (float, float)
        Start and end time [s].
    theta0 : array_like, shape (n,), optional
        Initial angles (default 0).
    tensions, positions, tip_load : Schedule or array_like, optional
        Time histories (a :class:`Schedule`, or a constant): cable tensions
        ``(T_R, T_L)`` [N] *or* cable positions ``(u_R, u_L)`` [m]
        (Eqs. 13-14), and the tip load on the manipulator in world
        coordinates ``(f_x, f_z, m_y)`` or ``(f, τ)`` [N, N m].
    t_eval : array_like, optional
        Output times (default: the schedule knots and the end).
    method : str
        A stiff :func:`scipy.integrate.solve_ivp` method (the 10 N m/rad stop
        makes the problem stiff); the analytic Jacobian is supplied.
    rtol, atol, max_step : float
        Integrator tolerances.

    Returns
    -------
    Trajectory
    """
    n = model.geom.n_joints
    t0, t1 = (float(v) for v in t_span)
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span must be (t0, t1) with t1 > t0, got {t_span!r}")
    th0 = np.zeros(n) if theta0 is None else as_joint_angles(theta0, n).copy()
    if tensions is not None and positions is not None:
        raise ValueError("give cable tensions or cable positions, not both")
    sT = _schedule(tensions, 2, "cable tensions")
    sU = _schedule(positions, 2, "cable positions")
    sF = _schedule(tip_load, 3, "tip load")
    B = model.damping

    def args(t):
        return (None if sT is None else sT(t), None if sF is None else sF(t),
                None if sU is None else sU(t))

    def f(t, th):
        return -model.residual(th, *args(t)) / B

    def jac(t, th):
        return -model.residual_jacobian(th, *args(t)) / B

    knots = sorted({t0, t1, *[float(k) for s in (sT, sU, sF) if s is not None for k in s.times
                              if t0 < k < t1]})
    if t_eval is None:
        t_eval = np.array(knots)
    t_eval = as_finite(t_eval, "t_eval")
    if ((t_eval < t0) | (t_eval > t1)).any():
        raise ValueError("t_eval must lie within t_span")
    ts, ths, ok, msg = [], [], True, "ok"
    th = th0
    for a, b in zip(knots[:-1], knots[1:]):   # restart at every kink of the inputs
        last = b == knots[-1]
        want = t_eval[(t_eval >= a) & ((t_eval < b) | (last & (t_eval <= b)))]
        grid = np.union1d(want, [b])
        sol = solve_ivp(f, (a, b), th, method=method, jac=jac, rtol=rtol, atol=atol,
                        max_step=max_step, t_eval=grid)
        if not sol.success:
            ok, msg = False, str(sol.message)
            break
        keep = np.isin(sol.t, want)
        ts.append(sol.t[keep])
        ths.append(sol.y.T[keep])
        th = sol.y[:, -1]
    t_out = np.concatenate(ts) if ts else np.empty(0)
    th_out = np.concatenate(ths) if ths else np.empty((0, n))
    rate = float(np.abs(f(t1, th)).max()) if ok else float("nan")
    return Trajectory(t_out, th_out, ok, msg, rate)


@dataclass(frozen=True)
class Equilibrium:
    """Result of :func:`equilibrium`."""

    theta: np.ndarray
    residual_norm: float  # max |G| [N m]
    success: bool
    message: str
    nfev: int


def equilibrium(model: QuasiStaticModel, *, tensions=None, tip_load=None, positions=None,
                theta0=None, tol: float = 1e-13, xtol: float = 1e-14, maxfev: int = 2000) -> Equilibrium:
    """Rest state ``G(θ) = 0`` of Eq. (10) by Powell's hybrid Newton method.

    ``scipy.optimize.root(method="hybr")`` with the analytic Jacobian
    ``∂G/∂θ = K_θ'(θ) + Σ_c T_c ∂²L_c/∂θ² + P K_c P^T - ∂τ_load/∂θ``.
    Where several equilibria exist (Fig. 8) the one found depends on
    ``theta0``.

    Parameters
    ----------
    model : QuasiStaticModel
    tensions, positions, tip_load : array_like
        As in :meth:`QuasiStaticModel.residual` (constant values).
    theta0 : array_like, shape (n,), optional
        Start (default 0).
    tol : float
        Success when ``max |G| ≤ tol`` [N m].
    xtol, maxfev : solver controls.

    Returns
    -------
    Equilibrium
    """
    n = model.geom.n_joints
    x0 = np.zeros(n) if theta0 is None else as_joint_angles(theta0, n)
    model.residual(x0, tensions, tip_load, positions)  # validates the inputs

    def fun(th):
        return model.residual(th, tensions, tip_load, positions)

    def jac(th):
        return model.residual_jacobian(th, tensions, tip_load, positions)

    sol = root(fun, x0, jac=jac, method="hybr", options={"xtol": xtol, "maxfev": maxfev})
    th = sol.x
    # polish with plain Newton steps (the piecewise-linear spring is exact there)
    for _ in range(5):
        r = fun(th)
        if np.abs(r).max() <= tol:
            break
        th = th - np.linalg.solve(jac(th), r)
    res = float(np.abs(fun(th)).max())
    ok = res <= tol
    return Equilibrium(th, res, ok, "converged" if ok else f"residual {res:.3g} N m > tol; {sol.message}",
                       int(sol.nfev))


# --------------------------------------------------------------------------
# Constant curvature (Sec. III-A, Eqs. 11-12)
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class ConstantCurvature:
    """Uniform joint angle ``θ_i`` [rad], curvature ``κ = |θ_i|/p`` [1/m], radius ``p/|θ_i|`` [m]."""

    theta: float
    curvature: float
    radius: float


def constant_curvature(geom: Geometry, tensions, spring: PiecewiseLinearSpring | None = None,
                       k1: float | None = None) -> ConstantCurvature:
    """Closed-form equilibrium without tip load (Eqs. 11-12), simplified ``P`` (Eq. 5).

    Every joint carries ``τ = r_x (T_R - T_L)`` (Eq. 9 with Eq. 5), so
    ``θ_i = (r_x / k_1)(T_R - T_L)`` in the linear range — the paper's
    ``θ_i = -(r_x/k_1)(T_L - T_R)`` (docs/geometry.md sign: a right pull gives
    positive θ) — and ``κ = r_x |T_L - T_R| / (p k_1)`` (Eq. 12). With a
    ``spring``, the inverse spring law ``θ_i = τ^{-1}(r_x (T_R - T_L))``
    (Eq. 11 beyond the linear range).

    Parameters
    ----------
    geom : Geometry
    tensions : array_like, shape (2,)
        ``(T_R, T_L)`` [N], ≥ 0.
    spring : PiecewiseLinearSpring, optional
        Use its inverse law (per-joint scales are not allowed: the result is uniform).
    k1 : float, optional
        Linear joint stiffness [N m/rad] (default 0.36, Fig. 7) when no spring is given.
    """
    T = _tensions(tensions)
    if T.shape != (2,):
        raise ValueError(f"tensions must be (T_R, T_L), got shape {T.shape}")
    tau = geom.r_x * (T[0] - T[1])
    if spring is not None:
        th = spring.angle(tau)
        if np.ndim(th) != 0:
            raise ValueError("constant_curvature needs a spring without per-joint scale")
        th = float(th)
    else:
        k1 = paper.DUAL_RATE_K1 if k1 is None else k1
        if not (math.isfinite(k1) and k1 > 0):
            raise ValueError(f"k1 must be positive [N m/rad], got {k1!r}")
        th = tau / k1
    kappa = abs(th) / geom.p
    return ConstantCurvature(float(th), float(kappa), math.inf if th == 0 else float(geom.p / abs(th)))


# --------------------------------------------------------------------------
# Stiffness (Sec. III-C)
# --------------------------------------------------------------------------
def joint_stiffness(model: QuasiStaticModel, theta0, cable_stiffness) -> np.ndarray:
    """Joint-space stiffness ``K_m = K_θ + P K_c P^T`` (Sec. III-C1).

    ``K_θ`` is the tangent spring stiffness at ``θ_0`` (``diag(k_1)`` in the
    linear range, as the paper assumes); ``P`` is the model's coupling at
    ``θ_0`` (held constant, as in the paper).

    Parameters
    ----------
    model : QuasiStaticModel
    theta0 : array_like, shape (n,)
    cable_stiffness : array_like, shape (2,)
        ``K_c = diag(k_R, k_L)`` [N/m] (``k_c`` for linear cables, ``2 K d``
        for quadratic ones, see :meth:`CableLaw.stiffness`).

    Returns
    -------
    ndarray, shape (n, n) [N m/rad]
    """
    th = as_joint_angles(theta0, model.geom.n_joints)
    kc = as_finite(cable_stiffness, "cable stiffness")
    if kc.shape != (2,) or (kc < 0).any():
        raise ValueError(f"cable_stiffness must be (k_R, k_L) >= 0 [N/m], got {kc}")
    P = model.coupling_matrix(th)
    return np.diag(model.spring.stiffness(th) * np.ones(th.size)) + (P * kc) @ P.T


def _check_spd(K_m: np.ndarray) -> np.ndarray:
    K_m = as_finite(K_m, "K_m")
    if K_m.ndim != 2 or K_m.shape[0] != K_m.shape[1]:
        raise ValueError(f"K_m must be square (n, n), got {K_m.shape}")
    try:
        np.linalg.cholesky(0.5 * (K_m + K_m.T))
    except np.linalg.LinAlgError:
        raise ValueError("K_m must be symmetric positive definite") from None
    return K_m


def _check_JX(J_X: np.ndarray, n: int, rcond: float) -> np.ndarray:
    J_X = as_finite(J_X, "J_X")
    if J_X.shape != (3, n):
        raise ValueError(f"J_X must have shape (3, {n}), got {J_X.shape}")
    s = np.linalg.svd(J_X, compute_uv=False)
    if s[-1] <= rcond * s[0]:
        raise ValueError(
            f"J_X is singular (rank < 3, singular values {s}): the workspace stiffness of Eq. (23) "
            "needs three independent rows; a straight manipulator (θ = 0) has J_z = 0")
    return J_X


def workspace_stiffness(K_m, J_X, rcond: float = 1e-10) -> np.ndarray:
    """``K_w = (J_X K_m^{-1} J_X^T)^{-1}`` (Eq. 23).

    Parameters
    ----------
    K_m : array_like, shape (n, n) [N m/rad], symmetric positive definite
    J_X : array_like, shape (3, n)
        Planar Jacobian (Eqs. 18-20) at the equilibrium.
    rcond : float
        ``J_X`` counts as singular when ``σ_min ≤ rcond σ_max``.

    Returns
    -------
    ndarray, shape (3, 3)
        Rows/columns ``(x, z, φ)``; units N/m, N, N m/rad.
    """
    K_m = _check_spd(K_m)
    J_X = _check_JX(J_X, K_m.shape[0], rcond)
    C = J_X @ np.linalg.solve(K_m, J_X.T)
    Kw = np.linalg.inv(C)
    return 0.5 * (Kw + Kw.T)


def workspace_stiffness_lagrange(K_m, J_X, rcond: float = 1e-10):
    """Solve the Lagrange system (Eq. 22) directly for the three unit ``δX``.

    ``[[K_m, J_X^T], [J_X, 0]] [δθ; λ] = [0; δX]``. By the paper's block
    inverse ``λ = -K_w δX``, so ``K_w = -Λ`` with ``Λ`` the multipliers of
    the unit displacements, and ``δθ = D δX`` (Eq. 24).

    Returns
    -------
    K_w : ndarray, shape (3, 3)
    D : ndarray, shape (n, 3)
        Joint displacement per unit ``δX`` [rad per (m, m, rad)].
    """
    K_m = _check_spd(K_m)
    n = K_m.shape[0]
    J_X = _check_JX(J_X, n, rcond)
    A = np.zeros((n + 3, n + 3))
    A[:n, :n] = K_m
    A[:n, n:] = J_X.T
    A[n:, :n] = J_X
    rhs = np.zeros((n + 3, 3))
    rhs[n:] = np.eye(3)
    sol = np.linalg.solve(A, rhs)
    return -sol[n:], sol[:n]


def joint_displacement(K_m, J_X, dX, rcond: float = 1e-10) -> np.ndarray:
    """``δθ = K_m^{-1} J_X^T K_w δX`` (Eq. 24): the minimum-energy joint motion for ``δX``.

    Parameters
    ----------
    dX : array_like, shape (3,) or (k, 3) [m, m, rad]

    Returns
    -------
    ndarray, shape (n,) or (k, n) [rad]
    """
    Kw = workspace_stiffness(K_m, J_X, rcond)
    dX = as_finite(dX, "δX")
    return (np.linalg.solve(K_m, J_X.T) @ Kw @ dX.T).T


# --------------------------------------------------------------------------
# FEA cross-check (Sec. III-D)
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class FEAReference:
    """The paper's FEA of a 4-joint segment (Sec. III-D, Fig. 10), SI units."""

    n_joints: int
    E: float
    nu: float
    moment: float                   # [N m]
    theta_moment: np.ndarray        # (4,) [rad]
    transverse_force: float         # [N]
    theta_transverse: np.ndarray    # (4,) [rad]
    axial_force: float              # [N]
    axial_max_displacement: float   # [m]
    source: str


def equivalent_stiffness_moment(moment: float, theta) -> float:
    """Joint stiffness from a pure tip moment: every joint carries ``M``, ``k = M / mean θ`` [N m/rad]."""
    th = as_finite(theta, "theta")
    if th.ndim != 1 or th.size < 1 or np.any(th == 0):
        raise ValueError("theta must be a non-empty 1-D array of non-zero angles [rad]")
    return float(moment / th.mean())


def equivalent_stiffness_transverse(force: float, theta, p: float) -> tuple[float, float]:
    """Joint stiffness and lever arm from a transverse tip load (Sec. III-D).

    Small deflections: joint ``j`` carries ``F (z_F - (j-1) p)`` with
    ``z_F`` the load point's height above joint 1, so
    ``θ_j = (F/k)(z_F - (j-1) p)``: linear in ``j`` with step ``-F p / k``.
    A straight-line fit of ``θ_j`` against ``j`` gives ``k = F p / step``
    and ``z_F``.

    Returns
    -------
    k : float [N m/rad]
    z_F : float [m] load point above joint 1 (``n p`` = the tip face)
    """
    th = as_finite(theta, "theta")
    if th.ndim != 1 or th.size < 2:
        raise ValueError("theta must be a 1-D array of at least two joint angles [rad]")
    a, slope = line_fit(th)          # θ_j = a + b j, j = 1..n
    icpt = a + slope                 # the line at joint 1
    if slope >= 0:
        raise ValueError("a transverse tip load must give angles decreasing toward the tip")
    k = force * p / (-slope)
    return float(k), float(icpt * k / force)


# --------------------------------------------------------------------------
# Fig. 8: path dependence
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class PathDependence:
    """Two load orders with the same final load (Fig. 8).

    ``a``: moment first, then force (solution A); ``b``: force first, then
    moment (solution B). ``max_dtheta`` = ``max_j |θ_A - θ_B|`` [rad];
    ``tip_distance`` = distance between the two tip points [m];
    ``tip_a``/``tip_b`` = ``(x, z, φ)`` of each final tip [m, m, rad].
    """

    a: Trajectory
    b: Trajectory
    load: np.ndarray
    max_dtheta: float
    tip_distance: float
    tip_a: np.ndarray
    tip_b: np.ndarray


def path_dependence(model: QuasiStaticModel, f_x: float = 4.0, f_z: float = 0.0, m_y: float = -0.05,
                    ramp: float = 1.0, hold: float = 4.0, **simulate_kw) -> PathDependence:
    """Fig. 8: apply a tip moment and a tip force in both orders from θ = 0.

    Each load ramps linearly over ``ramp`` seconds, one after the other, then
    both are held for ``hold`` seconds. The defaults (4 N toward +x, 0.05 N m
    toward -x, the Fig. 7 spring) give two stable equilibria: the moment
    first curls the chain against its stops toward -x and the force then
    pulls on a curled chain; the force first bends it toward +x and the
    moment cannot undo that.

    Returns
    -------
    PathDependence
    """
    fx, fz, my = _tip_load([f_x, f_z, m_y])
    if not (ramp > 0 and hold > 0):
        raise ValueError("ramp and hold must be positive [s]")
    t = [0.0, ramp, 2 * ramp, 2 * ramp + hold]
    A = Schedule(t, [[0, 0, 0], [0, 0, my], [fx, fz, my], [fx, fz, my]])
    B = Schedule(t, [[0, 0, 0], [fx, fz, 0], [fx, fz, my], [fx, fz, my]])
    simulate_kw.setdefault("rtol", 1e-7)
    simulate_kw.setdefault("atol", 1e-10)
    a = simulate(model, (0.0, t[-1]), tip_load=A, **simulate_kw)
    b = simulate(model, (0.0, t[-1]), tip_load=B, **simulate_kw)
    if not (a.success and b.success):
        raise RuntimeError(f"integration failed: {a.message}; {b.message}")
    ta, tb = kinematics.tip_pose(a.final, model.geom), kinematics.tip_pose(b.final, model.geom)
    return PathDependence(a, b, np.array([fx, fz, my]), float(np.abs(a.final - b.final).max()),
                          float(np.hypot(*(ta[:2] - tb[:2]))), ta, tb)
