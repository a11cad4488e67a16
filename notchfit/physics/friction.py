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
  (:func:`notchfit.physics._friction_kernels.fast_kernel`).

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
  residual bend up to ``τ⁻¹(h)`` at zero tension difference. With
  ``hysteresis_onset`` the band's width grows with the deflection from zero
  (flag-shaped loops confined to large bends, no residual bend), with
  ``hysteresis_yield`` the element is elastic before it slips (a stop:
  elastic-plastic Masing loops); :mod:`notchfit.physics._hysteresis_kernels`.
  The generator's laws ``bouc_wen_*`` and ``superelastic_gap`` (hidden-effect
  studies) are simulated by the reference solver only.
* ``tip_force_x``, ``tip_force_z`` (``external_load``): a constant
  manipulator-frame force at the tool point ``(0, 0, n p)``, joint torques
  ``J_X(θ)^T (f_x, f_z, 0)`` (Eqs. 18–20, as
  :func:`notchfit.physics.kinematics.joint_torques_from_tip_wrench`).
  Smooth.
* ``stiffness_gradient`` ``g`` (``stiffness_gradient``): every rate of joint
  ``j`` is scaled by ``1 + g (2 (j-1)/(n-1) - 1)``. Smooth.

**Real tubes** (docs/models.md, "Real tubes: mechanics"; parameters in
:mod:`notchfit.physics.friction_params`): per-joint spring rates and breaks (or the
material law of :func:`notchfit.physics.springs.material_spring`), rest angles (the
spring acts on ``θ_j - θ0_j``), per-joint moment arms of each tendon
(``Geometry.moment_arms``: drive ``a_R,j T_R[j] - a_L,j T_L[j]``, cable speed
``s_c Σ_{k>j} a_c,k θ̇_k``), one-tendon operation, the capstan law
(``friction_law = "capstan"``) and damping as a time constant. With the seed
tube every per-joint value is equal and the kernels take the seed's formulas
verbatim (results bit for bit as before).

**Cable displacement** (what the actuator draws in, from the cable model):
``Δ_L = -r_x Σ_j θ_j + T_L,meas / k_c`` and ``Δ_R = +r_x Σ_j θ_j + T_R,meas / k_c``
[m], relative to the straight, unloaded cable, with ``k_c = E A / L_0``
(Sec. III-B, the cable as an inextensible cable in series with a spring;
the lumped stretch uses the measured tension).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from . import _friction_kernels as _k
from .cables import pulled_side
from .geometry import Geometry, default_geometry
from .notches import notch_points
from .shapes import line_fit
from .friction_params import DEFAULT_DAMPING_TIME, FRICTION_LAWS, GENERATOR_LAWS, PARAM_KEYS, PER_JOINT_FIELDS, QUASI_STATIC_DAMPING_TIME, SPRING_LAWS, FrictionParams, _kernel_inputs, check_fast_laws, default_params  # noqa: F401
from ..units import MM
from ..validation import readonly

__all__ = [
    "DEFAULT_DAMPING_TIME",
    "DEFAULT_DT",
    "FastOptions",
    "FRICTION_LAWS",
    "PARAM_KEYS",
    "PER_JOINT_FIELDS",
    "QUASI_STATIC_DAMPING_TIME",
    "SPRING_LAWS",
    "FrictionParams",
    "SimulationResult",
    "cable_displacement",
    "LOAD_CELL_SIGMA",
    "clip_load_cell",
    "default_params",
    "simulate",
    "simulate_angles",
    "simulation_table",
    "stepwise_regimes",
]

#: Default time step of the reference solver [s] (its convergence in dt: docs/history.md).
DEFAULT_DT = 1e-4


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
    :func:`notchfit.analysis.diagnosis.peak_regimes` instead: one loading up to the
    pulled tension's peak, then II until the tip angle has lost a fraction of its
    drop, then III — robust to measurement noise on the shape, but one cycle only.

    The pulled cable is :func:`notchfit.physics.cables.pulled_side`; ``load`` is its
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
#: Load-cell uncertainty σ_T when an experiment gives none [N] (docs/data-formats.md).
LOAD_CELL_SIGMA = 0.05


def clip_load_cell(tension, sigma: float = LOAD_CELL_SIGMA, name: str = "tension") -> tuple[np.ndarray, int]:
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


@dataclass(frozen=True)
class FastOptions:
    """The fast solver's options (:func:`simulate` documents each; its defaults are these)."""

    h_min: float = 3e-3
    h_max: float = 0.05
    growth: float = 1.5
    dtheta_max: float = 5e-4
    order: int | None = None
    land_sticks: bool = True
    max_events: int | None = None
    max_micro: int | None = None
    settle_tol: float = 1e-13
    settle_maxiter: int = 200

    def kernel_args(self, n: int, tip_load: bool) -> tuple:
        """The checked options in :func:`notchfit.physics._friction_kernels.fast_kernel`'s order, from
        ``h_min`` to ``order``, for ``n`` joints (the order defaults to 2 with a tip load, else 1).

        Raises
        ------
        ValueError
            An option out of range.
        """
        for name, v in (("h_min", self.h_min), ("h_max", self.h_max)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0 s, got {v}")
        if not (math.isfinite(self.growth) and self.growth >= 1):
            raise ValueError(f"growth must be >= 1, got {self.growth}")
        order = (2 if tip_load else 1) if self.order is None else self.order
        if order not in (1, 2):
            raise ValueError(f"order must be 1 or 2, got {order}")
        me = max(64, 4 * n) if self.max_events is None else int(self.max_events)
        mm = max(1000, 40 * n) if self.max_micro is None else int(self.max_micro)
        if me < 0 or mm < 0:
            raise ValueError("max_events and max_micro must be >= 0")
        return (float(self.h_min), float(self.h_max), float(self.growth), me, mm, float(self.settle_tol),
                int(self.settle_maxiter), bool(self.land_sticks), float(self.dtheta_max), int(order))


@dataclass(frozen=True)
class _Solver:
    """Which solver runs a history: ``method``, the reference's largest step ``dt`` [s] (None: the
    default), the fast solver's options."""

    method: str = "fast"
    dt: float | None = None
    fast: FastOptions = FastOptions()


@dataclass(frozen=True)
class _Protocol:
    """How the measured tensions drive the model between samples (:func:`simulate`): ramp and settle
    times [s], and the load cells' ``σ_T`` for clipping (None: every reading must be >= 0)."""

    ramp_time: float = 0.0
    settle_time: float | None = None
    tension_sigma: float | None = None


@dataclass(frozen=True, eq=False)
class _Run:
    """A solver's output with what it was driven by: the kernel's tuple, the checked sample times and
    tensions, the model, the solver's name and the clipped load-cell readings."""

    out: tuple
    t: np.ndarray
    tl: np.ndarray
    tr: np.ndarray
    params: FrictionParams
    geom: Geometry
    method: str
    n_clipped: int


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
        Default :func:`default_params` of the geometry (the paper's values for
        the seed tube; the material and capstan laws for a one-sided wrist).
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
    fast = FastOptions(h_min=h_min, h_max=h_max, growth=growth, dtheta_max=dtheta_max, order=order,
                       land_sticks=land_sticks, max_events=max_events, max_micro=max_micro, settle_tol=settle_tol,
                       settle_maxiter=settle_maxiter)
    run = _solve(time, tension_left, tension_right, params, geom, _Solver(method, dt, fast),
                 _Protocol(ramp_time, settle_time, tension_sigma))
    return _result(run, tension_tol, hold_fraction)


def simulate_angles(time, tension_left, tension_right, params: FrictionParams | None = None,
                    geom: Geometry | None = None, *, method: str = "fast", dt: float | None = None,
                    ramp_time: float = 0.0, settle_time: float | None = None, tension_sigma: float | None = None,
                    **fast) -> np.ndarray:
    """The joint angles (S, n) [rad] of :func:`simulate`, without its other outputs.

    The same model, inputs, checks and solver (bit for bit); no tension
    profiles, regimes or displacements are built, which makes it the inner
    loop of an identification (:mod:`notchfit.analysis.identify`). ``fast``: the fast
    solver's options of :func:`simulate` (``h_min``, ``dtheta_max``, ...).
    """
    bad = set(fast) - set(_FAST_FIELDS)
    if bad:
        raise TypeError(f"simulate_angles got unknown option(s) {', '.join(sorted(bad))}")
    run = _solve(time, tension_left, tension_right, params, geom, _Solver(method, dt, FastOptions(**fast)),
                 _Protocol(ramp_time, settle_time, tension_sigma))
    return run.out[0]


#: The fast solver's option names (:class:`FastOptions`), the keywords :func:`simulate_angles` accepts.
_FAST_FIELDS = tuple(f.name for f in fields(FastOptions))


def _solve(time, tension_left, tension_right, params, geom, solver: _Solver, protocol: _Protocol) -> _Run:
    """Check the inputs and run a solver."""
    geom = default_geometry() if geom is None else geom
    params = default_params(geom) if params is None else params
    if not isinstance(params, FrictionParams):
        raise ValueError(f"params must be a FrictionParams, got {type(params).__name__}")
    t, tl, tr, n_clipped = _check_inputs(time, _tendon_tension(tension_left, geom, "left", time),
                                         _tendon_tension(tension_right, geom, "right", time), protocol.tension_sigma)
    settle_time = float(_check_protocol(t, protocol.ramp_time, protocol.settle_time))
    ramp_time = float(protocol.ramp_time)
    J, par = _kernel_inputs(params, geom)
    if solver.method == "reference":
        dt = DEFAULT_DT if solver.dt is None else float(solver.dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be > 0 s, got {dt}")
        out = _k.reference_kernel(t, tl, tr, par, J, dt, ramp_time, settle_time)
    elif solver.method == "fast":
        check_fast_laws(params)
        tip = params.tip_force_x != 0.0 or params.tip_force_z != 0.0
        out = _k.fast_kernel(t, tl, tr, par, J, ramp_time, settle_time, *solver.fast.kernel_args(geom.n_joints, tip))
    else:
        raise ValueError(f"method must be 'fast' or 'reference', got {solver.method!r}")
    return _Run(out, t, tl, tr, params, geom, solver.method, n_clipped)


def _result(run: _Run, tension_tol: float, hold_fraction: float) -> SimulationResult:
    """The :class:`SimulationResult` of a solver's run (regimes with ``tension_tol``, ``hold_fraction``)."""
    theta, TL, TR, bL, bR, sL, sR, nsteps = run.out
    t, tl, tr, params, geom, method, n_clipped = (run.t, run.tl, run.tr, run.params, run.geom, run.method,
                                                  run.n_clipped)
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



#: names that moved to notchfit.io (the model.toml reader and writer and its key mapping):
#: physics imports no file I/O, so the friction module does not forward them.
_MOVED_TO_IO = ("load_params", "save_params", "params_from_mapping", "params_to_mapping")


def __getattr__(name):
    """A clear message for the model-file names that live in :mod:`notchfit.io`."""
    if name in _MOVED_TO_IO:
        raise AttributeError(f"notchfit.physics.friction.{name} moved: use notchfit.io.{name} "
                             "(the model.toml reader and writer live with the other file formats)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
