"""Friction simulator of Sec. IV-B: cable stick/slip in the channels, first-order joints.

The model (``docs/models.md``, the paper's four-step algorithm):

1. **Tension propagation**, base to tip, per cable ``c`` and link ``j``
   (between joints ``j`` and ``j+1``): ``N_j = T_c[j+1] |sin θ_{j+1}| +
   T_c[j] |sin θ_j|``; sliding toward the base ``T_c[j+1] = T_c[j] - μ_d N_j``,
   toward the tip ``T_c[j+1] = T_c[j] + μ_d N_j`` (both solved exactly for
   ``T_c[j+1]``), sticking: ``T_c[j+1]`` keeps its value.
2. **First-order dynamics** ``b θ̇_j = r_x (T_R[j] - T_L[j]) - τ_j(θ_j)``
   (+ the extensions below).
3. **Cable speed** through link ``j``: ``v_c[j] = s_c r_x Σ_{k>j} θ̇_k``
   (``s_R = +1``, ``s_L = -1``; positive = toward the base).
4. **State machine**: a sliding link sticks when ``|v| < v_thr`` and
   ``|ΔT| <= μ_s N``; a sticking link slides toward the base when
   ``T[j] - T[j+1] > μ_s N``, toward the tip when ``T[j+1] - T[j] > μ_s N``.
   (The paper writes ``|ΔT| < μ_s N`` for sticking; with ``N = 0`` — straight
   joints — that can never hold and a link would slide forever, so the
   test is ``<=`` with a relative slack of 1e-9.)

Start: ``θ = 0``, zero tension, every link sticking.

**Input protocol** (the paper: "moved slowly between sample points, and at
rest when the sample data were taken", ~5 s apart). The measured tensions of
sample ``k-1`` move linearly to those of sample ``k`` during the first
``ramp_time`` seconds of the interval and are then held until sample ``k``
is taken; before the first sample the model starts at rest with no tension
``settle_time`` seconds earlier. The default ``ramp_time = 0`` (the tension
steps to its new value and the manipulator then comes to rest) is the
protocol whose rest states are well defined: with slow ramps the cable
speed in the distal links stays below ``v_thr`` during the ramp and they
stick-slip in a sawtooth between ``μ_d N`` and ``μ_s N``; the rest state
then depends on the sawtooth's phase, i.e. on the reference's time step and
on the ramp time (docs/models.md, "Input protocol"; measured by
``benchmarks/bench_friction.py --protocols``, numbers in docs/history.md).

Two solvers of the same model (``method=``):

* ``"reference"``: the four steps verbatim, explicit Euler, fixed step
  ``dt`` (default :data:`DEFAULT_DT`), numba.
* ``"fast"``: the same steps and state machine in the same order, but every
  joint moves by the exact solution of its piecewise-linear relaxation over
  large steps, state changes are located inside steps, slip fronts are
  resolved with the joints frozen (the reference's ``dt -> 0`` limit) and the
  rest state is solved in closed form once every link sticks
  (:func:`notchfit._friction_kernels.fast_kernel`).

**Extensions** (all off by default; each is a cause id of docs/data-formats.md):

* ``proximal_beta`` (``proximal_friction``): a capstan band between the
  load cell and the base. The base tension is a play operator on
  ``log T``: it stays put while inside ``[T_meas e^-β, T_meas e^β]`` and is
  dragged along by the nearer bound. The cable between load cell and base
  does not move while the band sticks, consistent with the base tension
  (and hence the manipulator) not changing. Rate independent; its output
  has kinks where the band starts to slip (non-smooth in β there).
* ``mu_s > mu_d + 0.01`` (``static_friction``): a larger static coefficient
  (no presliding/Dahl state: a clean one needs a cable-compliance state
  per link that the paper's lumped model does not have). ``μ_s`` acts only
  at break-away: a sliding link rests at ``|ΔT| = μ_d N``, so rest states
  reached by steps larger than ``(μ_s - μ_d) N`` do not depend on it; a
  smaller step stalls the cable. The rest state jumps when such a decision
  flips (non-smooth in μ_s and in the input tensions; docs/diagnosis.md).
* ``hysteresis_torque`` ``h`` (``joint_hysteresis``): a play operator in each
  joint, ``b θ̇ = F - τ(θ) ∓ h`` outside the band ``|F - τ(θ)| <= h`` and
  ``θ̇ = 0`` inside (``F`` = applied torque): rate independent, leaves a
  residual bend up to ``τ⁻¹(h)`` at zero tension difference.
* ``tip_force_x``, ``tip_force_z`` (``external_load``): a constant
  manipulator-frame force at the tool point ``(0, 0, n p)``, joint torques
  ``J_X(θ)^T (f_x, f_z, 0)`` (Eqs. 18–20, as
  :func:`notchfit.kinematics.joint_torques_from_tip_wrench`).
  Smooth.
* ``stiffness_gradient`` ``g`` (``stiffness_gradient``): every rate of joint
  ``j`` is scaled by ``1 + g (2 (j-1)/(n-1) - 1)``. Smooth.

**Cable displacement** (what the actuator draws in, from the cable model):
``Δ_L = -r_x Σ_j θ_j + T_L,meas / k_c`` and ``Δ_R = +r_x Σ_j θ_j + T_R,meas / k_c``
[m], relative to the straight, unloaded cable, with ``k_c = E A / L_0``
(Sec. III-B, the cable as an inextensible cable in series with a spring;
the lumped stretch uses the measured tension).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from . import _friction_kernels as _k
from . import paper
from .cables import pulled_side
from .geometry import Geometry, default_geometry
from .notches import notch_points
from .shapes import line_fit
from .springs import PiecewiseLinearSpring, friction_spring, material_spring
from .units import MM
from .validation import readonly

__all__ = [
    "DEFAULT_DAMPING_TIME",
    "DEFAULT_DT",
    "FRICTION_LAWS",
    "SPRING_LAWS",
    "FrictionParams",
    "SimulationResult",
    "cable_displacement",
    "clip_load_cell",
    "params_from_mapping",
    "params_to_mapping",
    "simulate",
    "simulation_table",
    "stepwise_regimes",
]

#: Default time step of the reference solver [s] (its convergence in dt: docs/history.md).
DEFAULT_DT = 1e-4

# TOML key (SI, with unit) for each parameter
PARAM_KEYS = {
    "k_lin": "k_lin_Nm_per_rad",
    "k_mid": "k_mid_Nm_per_rad",
    "k_stop": "k_stop_Nm_per_rad",
    "theta_mid": "theta_mid_rad",
    "theta_stop": "theta_stop_rad",
    "mu_d": "mu_d",
    "mu_s": "mu_s",
    "b": "b_Nms_per_rad",
    "v_thr": "v_thr_m_per_s",
    "proximal_beta": "proximal_beta",
    "hysteresis_torque": "hysteresis_torque_Nm",
    "tip_force_x": "tip_force_x_N",
    "tip_force_z": "tip_force_z_N",
    "stiffness_gradient": "stiffness_gradient",
    # real tubes (docs/models.md, "Real tubes: mechanics"); written only when not at their defaults
    "spring_law": "spring_law",
    "friction_law": "friction_law",
    "damping_time": "damping_time_s",
    "E_lin": "E_lin_Pa",
    "E_se": "E_se_Pa",
    "strain_lower": "strain_lower",
    "stop_ratio": "stop_ratio",
}
#: the keys every model file holds (the seed paper's model and its extensions)
_SEED_KEYS = ("k_lin", "k_mid", "k_stop", "theta_mid", "theta_stop", "mu_d", "mu_s", "b", "v_thr",
              "proximal_beta", "hysteresis_torque", "tip_force_x", "tip_force_z", "stiffness_gradient")
#: fields that may be one value per joint (a tuple, base to tip)
PER_JOINT_FIELDS = ("k_lin", "k_mid", "k_stop", "theta_mid", "theta_stop")
SPRING_LAWS = ("rates", "material")
FRICTION_LAWS = ("channel", "capstan")
#: The seed tube's damping as a time constant, ``b / k_lin`` = 0.03 / 0.4829 s (Sec. IV-B):
#: ``DEFAULT_DAMPING_TIME * 0.4829 == 0.03`` exactly in floating point (tested).
DEFAULT_DAMPING_TIME = paper.DAMPING / paper.FRICTION_K_LIN


@dataclass(frozen=True)
class FrictionParams:
    """Parameters of the friction simulator (SI units; defaults = Sec. IV-B, docs/models.md).

    Attributes
    ----------
    k_lin, k_mid, k_stop : float or tuple of n floats
        Spring rates [N m/rad]: below ``theta_mid`` (0.4829), mid range
        (0.25, fitted), beyond ``theta_stop`` (slot closure, 10) (Fig. 17);
        one value for every joint or one per joint, base to tip
        (``spring_law = "rates"``).
    theta_mid, theta_stop : float or tuple of n floats
        Breaks of the spring [rad] (0.07, 0.14), measured from the rest angle.
    mu_d, mu_s : float
        Sliding and static friction coefficients (0.29, 0.30); ``0 <= mu_d < 1``,
        ``mu_s >= mu_d``.
    b : float
        First-order damping [N m s/rad] (0.03).
    v_thr : float
        Cable speed below which a sliding link sticks [m/s] (5e-5).
    proximal_beta : float
        Capstan band between load cell and base, ``β = μ × wrap angle`` (>= 0).
    hysteresis_torque : float
        Play-operator joint hysteresis ``h`` [N m] (>= 0).
    tip_force_x, tip_force_z : float
        Constant manipulator-frame force at the tool point [N].
    stiffness_gradient : float
        ``g`` in (-1, 1): joint ``j``'s rates scaled by ``1 + g (2 (j-1)/(n-1) - 1)``.
    spring_law : {"rates", "material"}
        ``"rates"``: the paper's law with the rates and breaks above.
        ``"material"``: :func:`notchfit.springs.material_spring` from the
        geometry's section and ``E_lin``, ``E_se``, ``strain_lower``,
        ``stop_ratio`` (one set for every tube cut from the same stock).
    friction_law : {"channel", "capstan"}
        The seed's per-link channel law, or the capstan law of a tendon free
        in the lumen (tension ``e^{-μ Σ|θ|}`` along the tendon in full sliding).
    damping_time : float
        ``τ_b`` [s]: joint ``j``'s damping is ``b_j = τ_b k_j`` (``k_j`` its
        linear rate, scale included), so every joint settles on the same time
        scale on any tube. 0 (default): the absolute ``b`` for the rates law
        (the paper), :data:`DEFAULT_DAMPING_TIME` (the seed tube's ``b/k_lin``)
        for the material law.
    E_lin, E_se : float
        Linear and superelastic-plateau moduli [Pa] (material law; 40 and 4 GPa,
        superelastic nitinol, fitted).
    strain_lower : float
        Outer-fibre strain where the plateau starts (material law; 0.015).
    stop_ratio : float
        Slot-closure stop rate over the linear rate (material law; the seed's
        ``k_stop / k_lin``).
    """

    k_lin: float = paper.FRICTION_K_LIN
    k_mid: float = paper.FRICTION_K_MID
    k_stop: float = paper.FRICTION_K_STOP
    theta_mid: float = paper.FRICTION_THETA_MID
    theta_stop: float = paper.FRICTION_THETA_STOP
    mu_d: float = paper.MU_D
    mu_s: float = paper.MU_S
    b: float = paper.DAMPING
    v_thr: float = paper.V_THR
    proximal_beta: float = 0.0
    hysteresis_torque: float = 0.0
    tip_force_x: float = 0.0
    tip_force_z: float = 0.0
    stiffness_gradient: float = 0.0
    spring_law: str = "rates"
    friction_law: str = "channel"
    damping_time: float = 0.0
    E_lin: float = 40e9
    E_se: float = 4e9
    strain_lower: float = 0.015
    stop_ratio: float = paper.FRICTION_K_STOP / paper.FRICTION_K_LIN

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in ("spring_law", "friction_law"):
                continue
            if f.name in PER_JOINT_FIELDS and isinstance(v, (tuple, list, np.ndarray)):
                v = tuple(_number(f.name, x) for x in v)
                if not v:
                    raise ValueError(f"friction parameter {f.name} needs at least one value")
            else:
                v = _number(f.name, v)
            object.__setattr__(self, f.name, v)
        if self.spring_law not in SPRING_LAWS:
            raise ValueError(f"spring_law must be one of {SPRING_LAWS}, got {self.spring_law!r}")
        if self.friction_law not in FRICTION_LAWS:
            raise ValueError(f"friction_law must be one of {FRICTION_LAWS}, got {self.friction_law!r}")
        for name in ("k_lin", "k_mid", "k_stop", "b", "v_thr", "theta_mid", "E_lin", "E_se", "strain_lower",
                     "stop_ratio"):
            v = getattr(self, name)
            if (min(v) if isinstance(v, tuple) else v) <= 0:
                raise ValueError(f"friction parameter {name} must be positive, got {getattr(self, name)}")
        if self.damping_time < 0:
            raise ValueError(f"damping_time must be >= 0 s (0: the default damping), got {self.damping_time}")
        lengths = {len(getattr(self, f)) for f in PER_JOINT_FIELDS if isinstance(getattr(self, f), tuple)}
        if len(lengths) > 1:
            raise ValueError(f"per-joint parameters must all have one length, got {sorted(lengths)}")
        if self.n_per_joint is None:
            bad = self.theta_stop <= self.theta_mid
        else:
            bad = np.any(np.asarray(self.theta_stop) <= np.asarray(self.theta_mid))
        if bad:
            raise ValueError(f"need theta_mid < theta_stop, got {self.theta_mid} and {self.theta_stop}")
        if not 0.0 <= self.mu_d < 1.0:
            raise ValueError(f"mu_d must be in [0, 1), got {self.mu_d}")
        if self.mu_s < self.mu_d:
            raise ValueError(f"mu_s must be >= mu_d (static >= sliding), got mu_s={self.mu_s}, mu_d={self.mu_d}")
        if self.proximal_beta < 0:
            raise ValueError(f"proximal_beta must be >= 0, got {self.proximal_beta}")
        if self.hysteresis_torque < 0:
            raise ValueError(f"hysteresis_torque must be >= 0, got {self.hysteresis_torque}")
        if not -1.0 < self.stiffness_gradient < 1.0:
            raise ValueError(f"stiffness_gradient must be in (-1, 1), got {self.stiffness_gradient}")

    @property
    def n_per_joint(self) -> int | None:
        """Number of joints the per-joint parameters are given for (None: all scalar)."""
        for f in PER_JOINT_FIELDS:
            v = getattr(self, f)
            if isinstance(v, tuple):
                return len(v)
        return None

    def joint_scale(self, n: int) -> np.ndarray:
        """Per-joint stiffness factor ``1 + g (2 (j-1)/(n-1) - 1)`` (n,)."""
        if n == 1:
            return np.ones(1)
        return 1.0 + self.stiffness_gradient * (2.0 * np.arange(n) / (n - 1) - 1.0)

    def spring(self, n: int | None = None) -> PiecewiseLinearSpring:
        """The Fig. 17 spring, with the per-joint gradient scale when ``n`` is given.

        Per-joint rates or breaks give a spring with breaks (n, 2), rates (n, 3).
        """
        scale = 1.0 if n is None else self.joint_scale(n)
        if self.n_per_joint is None:
            return friction_spring(self.k_lin, self.k_mid, self.k_stop, self.theta_mid, self.theta_stop, scale)
        m = self.n_per_joint
        if n is not None and n != m:
            raise ValueError(f"per-joint friction parameters are given for {m} joints, the geometry has {n}")
        col = lambda v: np.broadcast_to(np.asarray(v, dtype=float), (m,))  # noqa: E731
        breaks = np.stack([col(self.theta_mid), col(self.theta_stop)], axis=-1)
        rates = np.stack([col(self.k_lin), col(self.k_mid), col(self.k_stop)], axis=-1)
        return PiecewiseLinearSpring(breaks, rates, scale)

    def joint_spring(self, geom: Geometry) -> PiecewiseLinearSpring:
        """The spring of every joint of ``geom`` (breaks (n, 2), rates (n, 3), scale (n,)).

        The rates law (:meth:`spring`) or the material law
        (:func:`notchfit.springs.material_spring`), with the gradient scale. The
        spring acts on the deflection from the rest angle, ``θ_j - θ0_j``.
        """
        n = geom.n_joints
        if self.spring_law == "material":
            sp = material_spring(geom, self.E_lin, self.E_se, self.strain_lower, self.stop_ratio)
            return sp.with_scale(self.joint_scale(n))
        sp = self.spring(n)
        b = np.broadcast_to(sp.breaks, (n, 2))
        r = np.broadcast_to(sp.rates, (n, 3))
        return PiecewiseLinearSpring(b, r, sp.scale)

    def joint_damping(self, spring: PiecewiseLinearSpring) -> np.ndarray:
        """``b_j`` [N m s/rad] (n,): ``τ_b k_j`` or the absolute ``b`` (see ``damping_time``)."""
        tau = self.damping_time
        if tau == 0.0 and self.spring_law == "material":
            tau = DEFAULT_DAMPING_TIME
        n = spring.rates.shape[0]
        if tau == 0.0:
            return np.full(n, self.b)
        return tau * (spring.rates[:, 0] * np.broadcast_to(spring.scale, (n,)))

    def replace(self, **changes) -> "FrictionParams":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """``{field: value}`` (SI): the seed model's fields, and the real-tube fields
        (laws, damping time, material) where they differ from their defaults.
        Per-joint values are lists."""
        default = FrictionParams()
        out = {}
        for f in PARAM_KEYS:
            v = getattr(self, f)
            if f in _SEED_KEYS or v != getattr(default, f):
                out[f] = list(v) if isinstance(v, tuple) else v
        return out

    def joint_table(self, geom: Geometry) -> np.ndarray:
        """The kernels' per-joint table (``_friction_kernels.J_*`` rows, n columns), read-only.

        Spring rates, breaks and scale (:meth:`joint_spring`), damping
        (:meth:`joint_damping`), rest angles ``θ0_j`` and the moment arms of the
        right and left tendons about each joint's bending axis
        (:meth:`Geometry.moment_arms`). Cached per (parameters, geometry).
        """
        return _joint_table(self, geom)

    def _build_joint_table(self, geom: Geometry) -> np.ndarray:
        sp = self.joint_spring(geom)
        n = geom.n_joints
        J = np.empty((_k.N_J, n))
        J[_k.J_K1], J[_k.J_K2], J[_k.J_K3] = sp.rates[:, 0], sp.rates[:, 1], sp.rates[:, 2]
        J[_k.J_TM], J[_k.J_TS] = sp.breaks[:, 0], sp.breaks[:, 1]
        J[_k.J_S] = np.broadcast_to(sp.scale, (n,))
        J[_k.J_B] = self.joint_damping(sp)
        J[_k.J_TH0] = geom.rest_angles
        J[_k.J_AR], J[_k.J_AL] = geom.moment_arms(+1), geom.moment_arms(-1)
        return readonly(J)

    def packed(self, geom: Geometry, table: np.ndarray | None = None) -> np.ndarray:
        """The kernels' parameter vector (``_friction_kernels.P_*``).

        The spring and damping entries hold joint 1's values; ``P_UNI`` says
        whether every joint has the same law and damping, ``P_ARMU`` whether
        both tendons have one moment arm ``P_RX`` at every joint (the seed tube).
        """
        J = self.joint_table(geom) if table is None else table
        par = np.zeros(_k.N_PAR)
        par[_k.P_K1], par[_k.P_K2], par[_k.P_K3] = J[_k.J_K1, 0], J[_k.J_K2, 0], J[_k.J_K3, 0]
        par[_k.P_TM], par[_k.P_TS], par[_k.P_B] = J[_k.J_TM, 0], J[_k.J_TS, 0], J[_k.J_B, 0]
        par[_k.P_MUD], par[_k.P_MUS], par[_k.P_VTHR] = self.mu_d, self.mu_s, self.v_thr
        par[_k.P_BETA], par[_k.P_H] = self.proximal_beta, self.hysteresis_torque
        par[_k.P_FX], par[_k.P_FZ] = self.tip_force_x, self.tip_force_z
        rows = [_k.J_K1, _k.J_K2, _k.J_K3, _k.J_TM, _k.J_TS, _k.J_B]
        par[_k.P_UNI] = float(np.all(J[rows] == J[rows, :1]))
        arms = J[[_k.J_AR, _k.J_AL]]
        par[_k.P_ARMU] = float(np.all(arms == arms[0, 0]))
        par[_k.P_RX] = arms[0, 0]
        par[_k.P_LAW] = _k.LAW_CAPSTAN if self.friction_law == "capstan" else _k.LAW_CHANNEL
        pitches = geom.pitches
        if (self.tip_force_x != 0.0 or self.tip_force_z != 0.0) and (
                not np.all(pitches == pitches[0]) or geom.backbone != "axis"):
            raise ValueError("a tip force needs equal joint spacings and backbone = 'axis' "
                             "(the tip-load torques of the section backbone come with its kinematics)")
        par[_k.P_P] = pitches[0]
        return par


@functools.lru_cache(maxsize=64)
def _joint_table(params: FrictionParams, geom: Geometry) -> np.ndarray:
    return params._build_joint_table(geom)


@functools.lru_cache(maxsize=64)
def _kernel_inputs(params: FrictionParams, geom: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' per-joint table and parameter vector (read-only, cached)."""
    J = params.joint_table(geom)
    return J, readonly(params.packed(geom, J))


@functools.lru_cache(maxsize=1)
def _paper_params() -> FrictionParams:
    return FrictionParams()


def _number(name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise ValueError(f"friction parameter {name} must be a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"friction parameter {name} must be finite, got {v}")
    return v


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Output of :func:`simulate`: the rest state at every sample (S samples, n joints).

    Attributes
    ----------
    time : ndarray (S,) [s]
    input_left, input_right : ndarray (S,) [N]
        Measured (load-cell) tensions, the input.
    theta : ndarray (S, n) [rad]
    tension_left, tension_right : ndarray (S, n) [N]
        Cable tension where it crosses joints 1..n (index 0 = base).
    base_tension_left, base_tension_right : ndarray (S,) [N]
        Tension at the base, after the proximal band (= input without it).
    state_left, state_right : ndarray (S, n-1) int8
        Per link 1..n-1, how its cable moved on the way into the sample:
        +1 slid toward the base, -1 toward the tip, 0 stuck throughout (the
        last sliding direction of the interval; at rest every link sticks,
        so the tension of a link marked ±1 sits at its sliding bound).
    displacement_left, displacement_right : ndarray (S,) [m]
        Cable drawn in by the actuator (module docstring).
    a, b : ndarray (S,) [rad]
        Least-squares ``θ_j = a + b j`` (j = 1..n) of the prediction (Sec. IV-A).
    regime : ndarray (S,) str
        ``"I"`` loading, ``"II"`` holding, ``"III"`` releasing (:func:`stepwise_regimes`).
    params : FrictionParams
    geom : Geometry
    method : str
        ``"fast"`` or ``"reference"``.
    n_steps : int
        Time steps the solver took (fast: steps + frozen passes).
    n_clipped : int
        Load-cell readings slightly below zero (down to ``-3 σ_T``) that were
        clipped at zero (:func:`clip_load_cell`); the command logs the count.
    """

    time: np.ndarray
    input_left: np.ndarray
    input_right: np.ndarray
    theta: np.ndarray
    tension_left: np.ndarray
    tension_right: np.ndarray
    base_tension_left: np.ndarray
    base_tension_right: np.ndarray
    state_left: np.ndarray
    state_right: np.ndarray
    displacement_left: np.ndarray
    displacement_right: np.ndarray
    a: np.ndarray
    b: np.ndarray
    regime: np.ndarray
    params: FrictionParams
    geom: Geometry
    method: str = "fast"
    n_steps: int = 0
    n_clipped: int = 0

    @property
    def n_samples(self) -> int:
        return self.theta.shape[0]

    @property
    def tip_angle(self) -> np.ndarray:
        """Tip orientation ``Σ_j θ_j`` (S,) [rad]."""
        return self.theta.sum(axis=1)

    def points(self) -> np.ndarray:
        """Manipulator-frame notch points of the prediction (S, m, 2) [m]."""
        return notch_points(self.theta, self.geom)


# =============================================================================
# small pure functions
# =============================================================================
def cable_displacement(theta, tension_left, tension_right, geom: Geometry):
    """Cable drawn in by each actuator ``(Δ_L, Δ_R)`` [m] (module docstring).

    ``Δ_L = -r_x Σθ + T_L/k_c``, ``Δ_R = r_x Σθ + T_R/k_c``, ``k_c = E A / L_0``;
    with per-joint moment arms ``Δ_c = s_c Σ_j a_c,j θ_j`` (+ the stretch), and
    no stretch term when the geometry gives no cable modulus.

    Parameters
    ----------
    theta : array_like, shape (..., n) [rad]
    tension_left, tension_right : array_like, shape (...) [N]
    """
    th = np.asarray(theta, dtype=float)
    aR, aL = geom.moment_arms(+1), geom.moment_arms(-1)
    if np.all(aR == aR[0]) and np.all(aL == aR[0]):
        sR = sL = aR[0] * th.sum(axis=-1)
    else:
        sR, sL = th @ aR, th @ aL
    tl, tr = np.asarray(tension_left, float), np.asarray(tension_right, float)
    if None in (geom.cable_E, geom.cable_A, geom.cable_L0):
        return -sL, sR
    kc = geom.cable_stiffness
    return -sL + tl / kc, sR + tr / kc


def stepwise_regimes(tension_left, tension_right, shape, *, tension_tol: float = 0.05,
                     hold_fraction: float = 0.25) -> np.ndarray:
    """Regime of each sample, step by step: I loading, II holding, III releasing (Sec. IV, Fig. 11).

    Each step into a sample is labelled by how the load changed and whether the
    shape followed it, so a history with several loading/unloading cycles gets
    several runs of I–III. It labels simulated histories
    (:attr:`SimulationResult.regime`). The diagnosis labels measured tests with
    :func:`notchfit.diagnosis.peak_regimes` instead: one loading up to the
    pulled tension's peak, then II until the tip angle has lost a fraction of its
    drop, then III — robust to measurement noise on the shape, but one cycle only.

    The pulled cable is :func:`notchfit.cables.pulled_side`; ``load`` is its
    tension minus the other's and ``shape`` (e.g. the tip angle, or the
    pulled cable's displacement) is taken with the sign that grows with the
    load. For the step into sample ``k``:

    * load rises by more than ``tension_tol``: **I**;
    * load falls by more than ``tension_tol``: **III** if the shape returns by
      at least ``hold_fraction`` of what the loading compliance (median of
      Δshape/Δload over the I steps) predicts for that fall — or if an
      earlier step of this release already did — else **II** (the shape
      holds while the tension drops);
    * otherwise the previous label (holding still).

    The first sample is I unless the load falls right after it (then II).

    Parameters
    ----------
    tension_left, tension_right : array_like, shape (S,) [N]
    shape : array_like, shape (S,)
        Any scalar shape measure per sample.
    tension_tol : float
        Tension change below which the load is "unchanged" [N].
    hold_fraction : float
        Fraction of the loading compliance separating II from III.

    Returns
    -------
    ndarray of str, shape (S,)
    """
    tl = np.asarray(tension_left, dtype=float)
    tr = np.asarray(tension_right, dtype=float)
    sh = np.asarray(shape, dtype=float)
    if not (tl.shape == tr.shape == sh.shape) or tl.ndim != 1:
        raise ValueError(f"tensions and shape must be 1-D arrays of one length, got {tl.shape}, {tr.shape}, {sh.shape}")
    S = tl.size
    out = np.empty(S, dtype="<U3")
    if S == 0:
        return out
    load = pulled_side(tl, tr) * (tr - tl)
    dload = np.diff(load)
    dshape = np.diff(sh)
    up = dload > tension_tol
    if up.any():
        sgn = 1.0 if np.sum(dshape[up]) >= 0 else -1.0
    else:
        sgn = 1.0 if np.sum(dshape * dload) >= 0 else -1.0
    dshape = sgn * dshape
    if up.any():
        comp = float(np.median(dshape[up] / dload[up]))
    else:
        big = np.abs(dload) > tension_tol
        comp = float(np.median(np.abs(dshape[big] / dload[big]))) if big.any() else 0.0
    comp = max(comp, 0.0)
    out[0] = "II" if (S > 1 and dload[0] < -tension_tol) else "I"
    released = False
    for k in range(1, S):
        dl, ds = dload[k - 1], dshape[k - 1]
        if dl > tension_tol:
            out[k] = "I"
            released = False
        elif dl < -tension_tol:
            moved = -ds >= hold_fraction * comp * (-dl)
            if released or moved:
                out[k] = "III"
                released = True
            else:
                out[k] = "II"
        else:
            out[k] = out[k - 1]
    return out


# =============================================================================
# the simulator
# =============================================================================
def clip_load_cell(tension, sigma: float = 0.05, name: str = "tension") -> tuple[np.ndarray, int]:
    """Load-cell readings clipped at zero (docs/models.md, real tubes: load cells).

    A load cell reads slightly below zero at rest (offset and noise). A reading
    down to ``-3 σ_T`` is a valid measurement of zero tension: it is clipped at
    zero and counted, so that the run log can say so. Below that it is an
    input error.

    Parameters
    ----------
    tension : array_like [N]
    sigma : float
        ``σ_T``, the tension uncertainty [N] (the experiment's, default 0.05 N).
    name : str
        Named in the message.

    Returns
    -------
    clipped : ndarray [N]
    count : int
        Readings that were below zero.

    Raises
    ------
    ValueError
        A reading below ``-3 σ_T`` (its index and value in the message).
    """
    a = np.asarray(tension, dtype=float)
    if not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be >= 0 N, got {sigma}")
    low = a < -3.0 * sigma
    if low.any():
        bad = int(np.flatnonzero(low)[0])
        raise ValueError(f"{name} must be >= 0 N (cables only pull; readings down to -3 sigma_T = "
                         f"{-3.0 * sigma:g} N count as zero), got {a[bad]} at sample index {bad}")
    neg = a < 0
    return np.where(neg, 0.0, a), int(neg.sum())


def _tendon_tension(tension, geom: Geometry, side: str, like):
    """The tension of one tendon: None or zeros for a tendon the geometry lacks."""
    if side in geom.tendons:
        if tension is None:
            raise ValueError(f"the geometry has a {side} tendon: tension_{side} is required")
        return tension
    if tension is None:
        return np.zeros(np.shape(like))
    a = np.asarray(tension, dtype=float)
    if np.any(a != 0):
        raise ValueError(f"the geometry has no {side} tendon (tendons = {list(geom.tendons)}): "
                         f"tension_{side} must be absent or zero")
    return a


def _check_inputs(time, tension_left, tension_right, sigma=None):
    t = np.asarray(time, dtype=float)
    tl = np.asarray(tension_left, dtype=float)
    tr = np.asarray(tension_right, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"time must be a non-empty 1-D array [s], got shape {t.shape}")
    if tl.shape != t.shape or tr.shape != t.shape:
        raise ValueError(f"tension_left, tension_right must have the shape of time {t.shape}, "
                         f"got {tl.shape} and {tr.shape}")
    for name, a in (("time", t), ("tension_left", tl), ("tension_right", tr)):
        if not np.isfinite(a).all():
            bad = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ValueError(f"{name} contains NaN or inf (first at sample index {bad})")
    clipped = 0
    if sigma is None:
        for name, a in (("tension_left", tl), ("tension_right", tr)):
            if (a < 0).any():
                bad = int(np.flatnonzero(a < 0)[0])
                raise ValueError(f"{name} must be >= 0 N (cables only pull), got {a[bad]} at sample index {bad}")
    else:
        tl, cl = clip_load_cell(tl, sigma, "tension_left")
        tr, cr = clip_load_cell(tr, sigma, "tension_right")
        clipped = cl + cr
    if t.size > 1 and not (np.diff(t) > 0).all():
        bad = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"time must increase strictly, got {t[bad]} then {t[bad + 1]} s at sample index {bad + 1}")
    return (np.ascontiguousarray(t), np.ascontiguousarray(tl), np.ascontiguousarray(tr), clipped)


def _check_protocol(t, ramp_time, settle_time) -> float:
    """Check the input protocol's times; the settle time, defaulting to the median interval [s]."""
    if not (math.isfinite(ramp_time) and ramp_time >= 0):
        raise ValueError(f"ramp_time must be >= 0 s, got {ramp_time}")
    if settle_time is None:
        settle_time = float(np.median(np.diff(t))) if t.size > 1 else 5.0
    if not (math.isfinite(settle_time) and settle_time > 0):
        raise ValueError(f"settle_time must be > 0 s, got {settle_time}")
    return settle_time


def _fast(t, tl, tr, par, J, ramp_time, settle_time, *, n, h_min, h_max, growth, dtheta_max, order,
          land_sticks, max_events, max_micro, settle_tol, settle_maxiter):
    """Check the fast solver's options and run it (:func:`simulate` documents them)."""
    for name, v in (("h_min", h_min), ("h_max", h_max)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be > 0 s, got {v}")
    if not (math.isfinite(growth) and growth >= 1):
        raise ValueError(f"growth must be >= 1, got {growth}")
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order}")
    me = max(64, 4 * n) if max_events is None else int(max_events)
    mm = max(1000, 40 * n) if max_micro is None else int(max_micro)
    if me < 0 or mm < 0:
        raise ValueError("max_events and max_micro must be >= 0")
    return _k.fast_kernel(t, tl, tr, par, J, ramp_time, settle_time,
                          float(h_min), float(h_max), float(growth), me, mm,
                          float(settle_tol), int(settle_maxiter), bool(land_sticks), float(dtheta_max),
                          int(order))


def simulate(time, tension_left, tension_right, params: FrictionParams | None = None,
             geom: Geometry | None = None, *, method: str = "fast", dt: float | None = None,
             ramp_time: float = 0.0, settle_time: float | None = None,
             h_min: float = 3e-3, h_max: float = 0.05, growth: float = 1.5, dtheta_max: float = 5e-4, order: int | None = None,
             land_sticks: bool = True,
             max_events: int | None = None, max_micro: int | None = None,
             settle_tol: float = 1e-13, settle_maxiter: int = 200,
             tension_tol: float = 0.05, hold_fraction: float = 0.25,
             tension_sigma: float | None = None) -> SimulationResult:
    """Simulate a tension history with the friction model (Sec. IV-B).

    Parameters
    ----------
    time : array_like, shape (S,) [s]
        Sample times, strictly increasing.
    tension_left, tension_right : array_like, shape (S,) [N], or None
        Measured (load-cell) tensions, >= 0. Between samples: the protocol
        of the module docstring. A tendon the geometry lacks
        (``geom.tendons``) carries no tension: None or zeros.
    params : FrictionParams, optional
        The paper's values by default.
    geom : Geometry, optional
        The default manipulator by default (``n_joints``, ``r_x``, ``p``, cable).
    method : {"fast", "reference"}
    dt : float, optional
        Reference solver's largest step [s] (default :data:`DEFAULT_DT`).
    ramp_time : float
        Seconds of each interval over which the tension moves linearly to
        the next sample's (0: a step; then held until the sample).
    settle_time : float, optional
        Time at rest before the first sample [s] (default: the median
        sample interval, 5 s for one sample).
    h_min, h_max, growth : float
        Fast solver: first step after an input change, largest step while a
        link slides [s], and the step's growth factor.
    dtheta_max : float
        Fast solver: while a link slides, the step is also limited so that no
        joint moves more than this [rad] (rates at the step's start).
    order : {1, 2}, optional
        Fast solver: 1 holds each joint's drive over a step; 2 adds a
        corrector with the drive's mean over the step (trapezoid). Default:
        2 with a tip load (its torques turn with the whole configuration),
        else 1.
    land_sticks : bool
        Fast solver: shorten steps to land on every sliding -> sticking event
        (True) or freeze the tension interpolated at the crossing (False: faster,
        less accurate).
    max_events, max_micro : int, optional
        Fast solver: located events and frozen slip passes per interval
        (default ``max(64, 4 n)`` and ``max(1000, 40 n)``).
    settle_tol, settle_maxiter :
        Fast solver: fixed point of the closed-form rest state (tip load) [rad].
    tension_tol, hold_fraction :
        Passed to :func:`stepwise_regimes`.
    tension_sigma : float, optional
        ``σ_T`` of the load cells [N]: readings down to ``-3 σ_T`` are clipped at
        zero and counted (:func:`clip_load_cell`, ``n_clipped``). None (default):
        every reading must be >= 0.

    Returns
    -------
    SimulationResult

    Raises
    ------
    ValueError
        Bad input (shapes, NaN, negative tension, a tension on a missing
        tendon, time not increasing) or options.
    """
    params = _paper_params() if params is None else params
    geom = default_geometry() if geom is None else geom
    if not isinstance(params, FrictionParams):
        raise ValueError(f"params must be a FrictionParams, got {type(params).__name__}")
    t, tl, tr, n_clipped = _check_inputs(time, _tendon_tension(tension_left, geom, "left", time),
                                         _tendon_tension(tension_right, geom, "right", time), tension_sigma)
    settle_time = _check_protocol(t, ramp_time, settle_time)
    J, par = _kernel_inputs(params, geom)
    if method == "reference":
        dt = DEFAULT_DT if dt is None else float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be > 0 s, got {dt}")
        out = _k.reference_kernel(t, tl, tr, par, J, dt, float(ramp_time), float(settle_time))
    elif method == "fast":
        if order is None:
            order = 2 if (params.tip_force_x != 0.0 or params.tip_force_z != 0.0) else 1
        out = _fast(t, tl, tr, par, J, float(ramp_time), float(settle_time), n=geom.n_joints, h_min=h_min,
                    h_max=h_max, growth=growth, dtheta_max=dtheta_max, order=order, land_sticks=land_sticks,
                    max_events=max_events, max_micro=max_micro, settle_tol=settle_tol,
                    settle_maxiter=settle_maxiter)
    else:
        raise ValueError(f"method must be 'fast' or 'reference', got {method!r}")
    return _result(out, t, tl, tr, params, geom, method, n_clipped, tension_tol, hold_fraction)


def _result(out, t, tl, tr, params, geom, method, n_clipped, tension_tol, hold_fraction) -> SimulationResult:
    """The :class:`SimulationResult` of a kernel's output."""
    theta, TL, TR, bL, bR, sL, sR, nsteps = out
    dl, dr = cable_displacement(theta, tl, tr, geom)
    a, b = line_fit(theta)
    regime = stepwise_regimes(tl, tr, theta.sum(axis=1) * pulled_side(tl, tr),
                              tension_tol=tension_tol, hold_fraction=hold_fraction)
    return SimulationResult(
        time=readonly(t), input_left=readonly(tl), input_right=readonly(tr), theta=readonly(theta),
        tension_left=readonly(TL), tension_right=readonly(TR), base_tension_left=readonly(bL),
        base_tension_right=readonly(bR), state_left=readonly(sL, np.int8), state_right=readonly(sR, np.int8),
        displacement_left=readonly(dl), displacement_right=readonly(dr), a=readonly(a), b=readonly(b),
        regime=readonly(regime, regime.dtype), params=params, geom=geom, method=method,
        n_steps=int(nsteps), n_clipped=n_clipped)


def simulation_table(result: SimulationResult, sample_ids=None):
    """The ``simulation.csv`` table (docs/data-formats.md) of a result.

    Columns: ``sample, time_s, regime, a, b, theta_1..theta_n`` [rad],
    ``tension_left_N, tension_right_N`` (measured input),
    ``tension_base_left_N, tension_base_right_N`` (after the proximal band),
    ``tension_tip_left_N, tension_tip_right_N`` (at joint n),
    ``displacement_left_mm, displacement_right_mm``.

    Parameters
    ----------
    result : SimulationResult
    sample_ids : array_like of int, shape (S,), optional
        The experiment's sample numbers (default 1..S).
    """
    S, n = result.theta.shape
    ids = np.arange(1, S + 1) if sample_ids is None else np.asarray(sample_ids)
    if ids.shape != (S,):
        raise ValueError(f"sample_ids must have {S} entries, got shape {ids.shape}")
    cols = {"sample": ids, "time_s": result.time, "regime": np.asarray(result.regime).astype(str),
            "a": result.a, "b": result.b}
    for j in range(n):
        cols[f"theta_{j + 1}"] = result.theta[:, j]
    cols.update({
        "tension_left_N": result.input_left, "tension_right_N": result.input_right,
        "tension_base_left_N": result.base_tension_left, "tension_base_right_N": result.base_tension_right,
        "tension_tip_left_N": result.tension_left[:, -1], "tension_tip_right_N": result.tension_right[:, -1],
        "displacement_left_mm": result.displacement_left / MM,
        "displacement_right_mm": result.displacement_right / MM,
    })
    return pd.DataFrame(cols)


# =============================================================================
# parameter files (the mapping of model.toml; notchfit.io reads and writes the file)
# =============================================================================
def params_from_mapping(data: dict, origin: str = "<dict>") -> FrictionParams:
    """Friction parameters from a parameter-file mapping (keys with units, :data:`PARAM_KEYS`).

    Parameters
    ----------
    data : dict
        Missing keys take the paper's values; a ``metadata`` table is ignored.
        Plain field names (``k_lin``) are accepted too.
    origin : str
        Where the mapping came from, at the start of every message.

    Returns
    -------
    FrictionParams

    Raises
    ------
    ValueError
        ``"<origin>: <problem>"`` for an unknown key, a key given twice, a
        non-number or an invalid value.
    """
    by_key = {v: k for k, v in PARAM_KEYS.items()}
    kw = {}
    for key, val in data.items():
        if key == "metadata" and isinstance(val, dict):
            continue
        field = by_key.get(key, key if key in PARAM_KEYS else None)
        if field is None:
            raise ValueError(f"{origin}: unknown friction parameter {key!r} "
                             f"(known: {', '.join(PARAM_KEYS.values())})")
        if field in kw:
            raise ValueError(f"{origin}: parameter {field} given twice")
        kw[field] = _mapping_value(field, key, val, origin)
    try:
        return FrictionParams(**kw)
    except ValueError as exc:
        raise ValueError(f"{origin}: {exc}") from None


def _mapping_value(field: str, key: str, val, origin: str):
    """One parameter-file value: a string law, a number, or a list for a per-joint field."""
    if field in ("spring_law", "friction_law"):
        if not isinstance(val, str):
            raise ValueError(f"{origin}: {key} must be a string, got {val!r}")
        return val
    if field in PER_JOINT_FIELDS and isinstance(val, list):
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in val):
            raise ValueError(f"{origin}: {key} must be a number or a list of numbers, got {val!r}")
        return tuple(float(v) for v in val)
    if isinstance(val, bool) or not isinstance(val, (int, float)):
        raise ValueError(f"{origin}: {key} must be a number, got {val!r}")
    return float(val)


def params_to_mapping(params: FrictionParams) -> dict:
    """``{file key: value}`` of ``params`` (SI keys with units, :data:`PARAM_KEYS`), in file order.

    The seed model's keys always; the real-tube keys (laws, damping time,
    material) only where they differ from their defaults, so a seed model file
    is as before. Per-joint values are lists.
    """
    return {PARAM_KEYS[f]: v for f, v in params.to_dict().items()}


def __getattr__(name):
    """``load_params`` / ``save_params``: the model.toml reader and writer of docs/data-formats.md.

    They live in :mod:`notchfit.io.models` (physics imports no file I/O);
    these names are the documented aliases, resolved on first use.
    """
    if name in ("load_params", "save_params"):
        from .io import models  # file I/O on demand: friction itself imports no notchfit.io

        return getattr(models, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
