"""Parameters of the friction model (Sec. IV-B and real tubes).

:class:`FrictionParams` holds the seed paper's parameters and extensions and
the real-tube laws (per-joint rates, the material law, the capstan law,
damping as a time constant; docs/models.md); :meth:`FrictionParams.joint_table`
and :meth:`FrictionParams.packed` turn them, with a geometry, into the arrays
the kernels of :mod:`notchfit.physics._friction_kernels` read. :func:`params_from_mapping`
and :func:`params_to_mapping` convert to and from the ``model.toml`` mapping
(:mod:`notchfit.io` reads and writes the file). :mod:`notchfit.physics.friction`
re-exports every public name.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from . import _friction_kernels as _k
from .. import paper
from .geometry import Geometry
from .kinematics import chain
from .springs import PiecewiseLinearSpring, friction_spring, material_spring
from ..validation import readonly

__all__ = [
    "DEFAULT_DAMPING_TIME",
    "QUASI_STATIC_DAMPING_TIME",
    "FRICTION_LAWS",
    "GENERATOR_LAWS",
    "check_fast_laws",
    "FrictionParams",
    "PARAM_KEYS",
    "PER_JOINT_FIELDS",
    "SPRING_LAWS",
    "default_params",
]

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
    # the joint-hysteresis family (written only when not at their defaults)
    "hysteresis_onset": "hysteresis_onset_rad",
    "hysteresis_yield": "hysteresis_yield_rad",
    # laws of the hidden-effect generator (reference solver only; written only when set)
    "bouc_wen_torque": "bouc_wen_torque_Nm",
    "bouc_wen_stiffness": "bouc_wen_stiffness_Nm_per_rad",
    "superelastic_gap": "superelastic_gap_Nm",
    # real tubes (docs/models.md, "Real tubes: mechanics"); written only when not at their defaults
    "spring_law": "spring_law",
    "friction_law": "friction_law",
    "damping_time": "damping_time_s",
    "E_lin": "E_lin_Pa",
    "E_se": "E_se_Pa",
    "strain_lower": "strain_lower",
    "stop_ratio": "stop_ratio",
    "strain_ratio": "strain_ratio",
    "rest_angle": "rest_angle_rad",
    "slot_depth_offset": "slot_depth_offset_m",
}
#: the keys every model file holds (the seed paper's model and its extensions)
_SEED_KEYS = ("k_lin", "k_mid", "k_stop", "theta_mid", "theta_stop", "mu_d", "mu_s", "b", "v_thr",
              "proximal_beta", "hysteresis_torque", "tip_force_x", "tip_force_z", "stiffness_gradient")
#: fields that may be one value per joint (a tuple, base to tip)
PER_JOINT_FIELDS = ("k_lin", "k_mid", "k_stop", "theta_mid", "theta_stop")
#: per-joint properties of one tube that a model may hold in place of its geometry's (None: the geometry's)
TUBE_FIELDS = ("rest_angle", "slot_depth_offset")
SPRING_LAWS = ("rates", "material")
#: the generator's hysteresis laws: the reference solver has them, the fast solver refuses them
GENERATOR_LAWS = ("bouc_wen_torque", "superelastic_gap")
FRICTION_LAWS = ("channel", "capstan")
#: The seed tube's damping as a time constant, ``b / k_lin`` = 0.03 / 0.4829 s (Sec. IV-B):
#: ``DEFAULT_DAMPING_TIME * 0.4829 == 0.03`` exactly in floating point (tested).
DEFAULT_DAMPING_TIME = paper.DAMPING / paper.FRICTION_K_LIN
#: Damping time of the default model of a real tube (material law) [s]: a link of the friction
#: model sticks once its cable speed falls below ``v_thr``, so the rest state after a load step
#: depends on how fast the joints relax; the ``τ_b → 0`` limit is the quasi-static rest state that
#: measurements at rest see, whatever the sample timing. At 1 ms the rest states of the shipped
#: wrists are within 0.1° of that limit and the same for samples 0.5 s or 5 s apart (at the seed
#: tube's 62 ms: up to 1.7° and 8.7° off; docs/history.md).
QUASI_STATIC_DAMPING_TIME = 1e-3


def check_fast_laws(params: "FrictionParams") -> None:
    """Refuse the generator's hysteresis laws (:data:`GENERATOR_LAWS`) for the fast solver and the
    predictor: they are simulated by the reference solver only.

    Raises
    ------
    ValueError
        Naming the laws that are set.
    """
    gen = [f for f in GENERATOR_LAWS if getattr(params, f) != 0.0]
    if gen:
        raise ValueError(f"{', '.join(gen)}: a hysteresis law of the hidden-effect generator, simulated by "
                         "the reference solver only (method='reference'); the fast solver has the "
                         "hysteresis family of hysteresis_torque, hysteresis_onset and hysteresis_yield")


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
        Joint hysteresis threshold ``h`` [N m] (>= 0): with the two fields
        below at 0 a play operator of constant width ``2h``
        (:mod:`notchfit.physics._hysteresis_kernels`).
    hysteresis_onset : float
        ``θ_h`` [rad] (>= 0): the threshold is 0 below a deflection of
        ``θ_h / 2`` and ``h`` beyond ``θ_h``, linear between: loops confined to
        large deflections (flag-shaped, superelastic), no residual bend.
    hysteresis_yield : float
        ``θ_y`` [rad] (>= 0): the elastic deflection of the hysteretic element
        before it slips (a stop of stiffness ``h/θ_y``, at most ``θ_h/2`` when
        ``θ_h > 0``): elastic-plastic (Masing) loops. 0: the rigid play.
    bouc_wen_torque, bouc_wen_stiffness : float
        Generator law (reference solver only): a Bouc-Wen hysteretic torque in
        each joint with ultimate torque ``z_u`` [N m] and initial stiffness
        ``A`` [N m/rad] (``n = 1``, ``β = γ``); 0: off.
    superelastic_gap : float
        Generator law (reference solver only): the flexures' plateau is a
        two-branch superelastic transformation whose reverse plateau lies this
        much below the loading one [N m] (flag-shaped loops); 0: off.
    tip_force_x, tip_force_z : float
        Constant manipulator-frame force at the tool point [N].
    stiffness_gradient : float
        ``g`` in (-1, 1): joint ``j``'s rates scaled by ``1 + g (2 (j-1)/(n-1) - 1)``.
    spring_law : {"rates", "material"}
        ``"rates"``: the paper's law with the rates and breaks above.
        ``"material"``: :func:`notchfit.physics.springs.material_spring` from the
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
    strain_ratio : float
        Onset strain of the plateau in compression over that in tension (material law; 1: one
        threshold for the most strained fibre; superelastic nitinol: 1.2-1.5).
    rest_angle : float, tuple of n floats, or None
        Rest angles ``θ0_j`` [rad] of the tube this model was identified on
        (``notchfit identify``), in place of the geometry's ``rest_angle_rad``;
        None (default): the geometry's. A pre-curve is a property of one tube:
        a model meant for other tubes of the same stock leaves it None.
    slot_depth_offset : float, tuple of n floats, or None
        Effective cut depth of each notch less the geometry's [m] (``notchfit
        identify``: a cut a few µm off the drawing changes the thin wall's
        stiffness by tens of per cent); the springs, the closure angles and the
        tendon's moment arms follow the corrected sections (:meth:`tube_geometry`).
        None (default): the geometry's depths. A property of one tube, like ``rest_angle``.
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
    hysteresis_onset: float = 0.0
    hysteresis_yield: float = 0.0
    bouc_wen_torque: float = 0.0
    bouc_wen_stiffness: float = 0.0
    superelastic_gap: float = 0.0
    spring_law: str = "rates"
    friction_law: str = "channel"
    damping_time: float = 0.0
    E_lin: float = 40e9
    E_se: float = 4e9
    strain_lower: float = 0.015
    stop_ratio: float = paper.FRICTION_K_STOP / paper.FRICTION_K_LIN
    strain_ratio: float = 1.0
    rest_angle: float | tuple | None = None
    slot_depth_offset: float | tuple | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in ("spring_law", "friction_law") or (f.name in TUBE_FIELDS and v is None):
                continue
            if f.name in PER_JOINT_FIELDS + TUBE_FIELDS and isinstance(v, (tuple, list, np.ndarray)):
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
                     "stop_ratio", "strain_ratio"):
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
        for name in ("hysteresis_torque", "hysteresis_onset", "hysteresis_yield", "bouc_wen_torque",
                     "bouc_wen_stiffness", "superelastic_gap"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if (self.bouc_wen_torque > 0) != (self.bouc_wen_stiffness > 0):
            raise ValueError("bouc_wen_torque and bouc_wen_stiffness must be both > 0 (the law on) or both 0, "
                             f"got {self.bouc_wen_torque} and {self.bouc_wen_stiffness}")
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

    def _per_joint(self, name: str, geom: Geometry) -> np.ndarray:
        v = getattr(self, name)
        if isinstance(v, tuple) and len(v) != geom.n_joints:
            raise ValueError(f"the model's {PARAM_KEYS[name]} is given for {len(v)} joints, the geometry "
                             f"{geom.name!r} has {geom.n_joints}")
        return np.broadcast_to(np.asarray(v, dtype=float), (geom.n_joints,)).copy()

    def depth_geometry(self, geom: Geometry) -> Geometry:
        """``geom`` with the model's effective cut depths (``slot_depth_offset``), or ``geom`` when None (cached).

        Raises
        ------
        ValueError
            Offsets given for another number of joints, or a depth outside the tube.
        """
        if self.slot_depth_offset is None:
            return geom
        return _depth_geometry(geom, tuple(self._per_joint("slot_depth_offset", geom)))

    def rest_angles(self, geom: Geometry) -> np.ndarray:
        """Rest angles ``θ0_j`` (n,) [rad]: the model's (``rest_angle``), else the geometry's.

        Raises
        ------
        ValueError
            Rest angles given for another number of joints, or not inside a slot's closure.
        """
        if self.rest_angle is None:
            return geom.rest_angles
        rest = self._per_joint("rest_angle", geom)
        if np.any(np.abs(rest) >= self.depth_geometry(geom).closure_angles):
            raise ValueError(f"the model's rest angles (rest_angle_rad) must be smaller in magnitude than the "
                             f"slots' closure angles of geometry {geom.name!r}")
        return rest

    def tube_geometry(self, geom: Geometry) -> Geometry:
        """``geom`` with this model's rest angles and cut depths (:meth:`rest_angles`, :meth:`depth_geometry`)."""
        g = self.depth_geometry(geom)
        return g if self.rest_angle is None else g.replace(rest_angle=tuple(self.rest_angles(geom)))

    def joint_spring(self, geom: Geometry) -> PiecewiseLinearSpring:
        """The spring of every joint of ``geom`` (breaks (n, 2), rates (n, 3), scale (n,)).

        The rates law (:meth:`spring`) or the material law
        (:func:`notchfit.physics.springs.material_spring`), with the gradient scale. The
        spring acts on the deflection from the rest angle, ``θ_j - θ0_j``
        (:meth:`rest_angles`); the material law takes the model's cut depths
        (:meth:`depth_geometry`).
        """
        n = geom.n_joints
        if self.spring_law == "material":
            sp = material_spring(self.depth_geometry(geom), self.E_lin, self.E_se, self.strain_lower,
                                 self.stop_ratio, rest_angles=self.rest_angles(geom), strain_ratio=self.strain_ratio)
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
            if f in _SEED_KEYS or (v is not None and v != getattr(default, f)):
                out[f] = list(v) if isinstance(v, tuple) else v
        return out

    def joint_table(self, geom: Geometry) -> np.ndarray:
        """The kernels' per-joint table (``_friction_kernels.J_*`` rows, n columns), read-only.

        Spring rates, breaks and scale (:meth:`joint_spring`), damping
        (:meth:`joint_damping`), rest angles ``θ0_j`` and the moment arms of the
        right and left tendons about each joint's bending axis
        (:meth:`Geometry.moment_arms`), and the pivot chain's straight-configuration
        steps (:func:`notchfit.physics.kinematics.chain`: joint to joint, the last to the tool
        point) for the tip-load torques. Cached per (parameters, geometry).
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
        J[_k.J_TH0] = self.rest_angles(geom)
        g = self.depth_geometry(geom)
        J[_k.J_AR], J[_k.J_AL] = g.moment_arms(+1), g.moment_arms(-1)
        ch = chain(g)
        J[_k.J_DX, :-1], J[_k.J_DZ, :-1] = ch.steps[1:, 0], ch.steps[1:, 1]
        J[_k.J_DX, -1], J[_k.J_DZ, -1] = ch.tip
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
        par[_k.P_HON], par[_k.P_HY] = self.hysteresis_onset, self.hysteresis_yield
        par[_k.P_BWZ], par[_k.P_BWA] = self.bouc_wen_torque, self.bouc_wen_stiffness
        par[_k.P_SEG] = self.superelastic_gap
        par[_k.P_FX], par[_k.P_FZ] = self.tip_force_x, self.tip_force_z
        rows = [_k.J_K1, _k.J_K2, _k.J_K3, _k.J_TM, _k.J_TS, _k.J_B]
        par[_k.P_UNI] = float(np.all(J[rows] == J[rows, :1]))
        arms = J[[_k.J_AR, _k.J_AL]]
        par[_k.P_ARMU] = float(np.all(arms == arms[0, 0]))
        par[_k.P_RX] = arms[0, 0]
        par[_k.P_LAW] = _k.LAW_CAPSTAN if self.friction_law == "capstan" else _k.LAW_CHANNEL
        return par


@functools.lru_cache(maxsize=256)
def _depth_geometry(geom: Geometry, offsets: tuple) -> Geometry:
    return geom.replace(slot_depth=tuple(geom.slot_depths + np.asarray(offsets)))


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


def default_params(geom: Geometry) -> FrictionParams:
    """The model a geometry gets when none is given.

    The seed paper's parameters (Sec. IV-B) for a tube bending about its axis;
    for a section backbone (a real asymmetric-notch tube) the material law from
    its section (:func:`notchfit.physics.springs.material_spring`) with the damping time
    :data:`QUASI_STATIC_DAMPING_TIME` (rest states at the quasi-static limit),
    and for a tendon free in the lumen the capstan law.
    """
    changes = {}
    if geom.backbone == "section" and geom.inner_radius is not None:
        changes["spring_law"] = "material"
        changes["damping_time"] = QUASI_STATIC_DAMPING_TIME
    if geom.tendon_path == "lumen":
        changes["friction_law"] = "capstan"
    return _paper_params().replace(**changes) if changes else _paper_params()


def _number(name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise ValueError(f"friction parameter {name} must be a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"friction parameter {name} must be finite, got {v}")
    return v
