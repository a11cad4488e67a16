"""Measured experiments as the estimation sees them: one type, one metric vocabulary, one noise rule.

An experiment is compared with simulations in one of two *metrics*
(:data:`METRICS`): its notch points (``"points"``, the paper's error metric,
Sec. IV-A; registered in the plane by the free-θ fit of the measurements
alone; errors in files in mm) or its measured joint angles (``"angles"``,
``angles.csv`` of a real tube; no registration; errors in files in degrees).
Either way it is reduced once to an :class:`Observations`: the measured
tension history and protocol, the observations with their σ, the measured
shapes (joint angles, the linear ``θ_j = a + b j`` fit), its pulled tendon, its
samples labelled with the regimes I/II/III of Sec. IV (Fig. 11) and its tube
(experiments that share a geometry are one tube, :func:`tube_labels`).

The load cells' uncertainty (:func:`tension_sigma`) follows one rule for every
engine: ``[uncertainty] tension_N`` of experiment.toml, else the data-format
default :data:`notchfit.physics.friction.LOAD_CELL_SIGMA` (0.05 N). A real load cell is
never noise-free, and the diagnosis's noise floor pushes this σ through the
model; assuming 0 N when a file is silent understated the floor and let the
diagnosis call a study "unexplained" that identify predicted within its noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...physics.cables import RIGHT, pulled_side
from ..fitting import fit_experiment
from ..fitting.angles import DEFAULT_ANGLE_SIGMA
from ...physics.friction import LOAD_CELL_SIGMA
from ...physics.notches import notch_points
from ...units import UNIT_SIZE

__all__ = ["METRICS", "Observations", "angle_residuals", "choose_metric", "metric_unit", "observe",
           "observe_study", "peak_regimes", "point_factor", "sample_mse", "tension_sigma", "tube_labels", "zero_tension_samples"]

#: The comparison metrics: what is compared, and the unit of its errors in files.
METRICS = {"points": "mm", "angles": "deg"}
#: Point σ [m] when experiment.toml gives none and the free-θ fit cannot estimate it.
DEFAULT_POINT_SIGMA = 2e-5


def metric_unit(metric: str = "points") -> tuple[str, float]:
    """File unit and its size in SI of a metric: ``("mm", MM)`` for points, ``("deg", DEG)`` for angles."""
    u = METRICS["angles" if metric == "angles" else "points"]
    return u, UNIT_SIZE[u]


def tension_sigma(exp) -> float:
    """The load-cell uncertainty σ_T of an experiment [N]: experiment.toml's, else 0.05 N (module docstring)."""
    return float(exp.tension_sigma) if exp.tension_sigma is not None else LOAD_CELL_SIGMA


def point_factor(metric: str) -> float:
    """Perfect-model mean squared error per measured value over ``σ²``: 2 for a point (two coordinates),
    1 for an angle."""
    return 2.0 if metric == "points" else 1.0


@dataclass(frozen=True, eq=False)
class Observations:
    """One experiment ready for comparison with simulations (S samples, n joints, m points).

    Attributes
    ----------
    name : str
    geom : Geometry
    time, tension_left, tension_right : ndarray, shape (S,) [s, N, N]
        The measured history (load-cell readings clipped at zero by :mod:`notchfit.io`).
    measured : ndarray, shape (S, m, 2) or (S, n)
        Measured notch points in the plane frame [m] (metric ``"points"``) or
        measured joint angles [rad] (``"angles"``); NaN where missing.
    valid : ndarray of bool, shape (S, m) or (S, n)
    transform : PlaneTransform or None
        Registration of the manipulator frame in the plane (from the free-θ fit of
        the measurements alone); None for angle data.
    sigma : float
        Uncertainty of one measured value: a point coordinate [m] or a joint
        angle [rad] (experiment.toml, else estimated or assumed).
    theta_free : ndarray, shape (S, n)
        Measured joint angles: the free-θ fit of each sample's points, or the
        angles themselves [rad] (what rest angles start from).
    free_residuals : ndarray, shape (S, m, 2), or None
        Residuals of the free-θ fit [m] (what no joint configuration explains); None for angle data.
    a, b : ndarray, shape (S,)
        Linear-model fit ``θ_j = a + b j`` of the measurements [rad].
    pulled : int
        +1 when the right tendon is the ramped one (bends toward +θ), -1 left.
    regime : ndarray of str, shape (S,)
        I / II / III from the measured data (:func:`peak_regimes`).
    counter_tension : float
        Median tension of the tendon that is not ramped [N] (0 on a one-tendon tube).
    tension_sigma : float
        Load-cell uncertainty [N] (:func:`tension_sigma`).
    metric : {"points", "angles"}
    ramp_time : float
        The protocol the simulations are driven with: seconds over which the
        tensions move to the next sample's (0: a step).
    tube : str
        Label of its geometry in the study (:func:`tube_labels`; its geometry's name alone).
    """

    name: str
    geom: object
    time: np.ndarray = field(repr=False)
    tension_left: np.ndarray = field(repr=False)
    tension_right: np.ndarray = field(repr=False)
    measured: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    transform: object
    sigma: float
    theta_free: np.ndarray = field(repr=False)
    free_residuals: np.ndarray | None = field(repr=False)
    a: np.ndarray = field(repr=False)
    b: np.ndarray = field(repr=False)
    pulled: int
    regime: np.ndarray = field(repr=False)
    counter_tension: float
    tension_sigma: float = LOAD_CELL_SIGMA
    metric: str = "points"
    ramp_time: float = 0.0
    tube: str = ""

    @property
    def pulled_tension(self) -> np.ndarray:
        """Tension of the pulled tendon [N] (S,)."""
        return self.tension_right if self.pulled > 0 else self.tension_left

    @property
    def tip_angle(self) -> np.ndarray:
        """Measured tip angle ``Σθ`` toward the pulled side [rad] (S,) (angle data: over the measured joints)."""
        if self.metric == "angles":
            return self.pulled * np.nansum(self.theta_free, axis=1)
        return self.pulled * self.theta_free.sum(axis=1)

    @property
    def point_factor(self) -> float:
        """Perfect-model mean squared error per measured value over ``σ²`` (:func:`point_factor`)."""
        return point_factor(self.metric)

    @property
    def values_per_item(self) -> int:
        """Residuals per measured item: 2 coordinates of a point, 1 angle."""
        return 2 if self.metric == "points" else 1

    @property
    def n_values(self) -> int:
        """Measured angles, or measured points."""
        return int(self.valid.sum())

    @property
    def tendon_tensions(self) -> tuple:
        """``(left, right)`` for :func:`notchfit.physics.friction.simulate`: None for a tendon the tube lacks."""
        return (self.tension_left if "left" in self.geom.tendons else None,
                self.tension_right if "right" in self.geom.tendons else None)

    def observe(self, theta: np.ndarray, transform=None) -> np.ndarray:
        """What the measurement would be for joint angles ``theta`` (S, n): notch points in the
        plane (with ``transform``, default the registration) or the angles themselves."""
        if self.metric == "angles":
            return np.asarray(theta, dtype=float)
        T = transform or self.transform
        return T.to_plane(notch_points(theta, self.geom))


def angle_residuals(theta_pred, theta_meas) -> np.ndarray:
    """``θ_pred − θ_meas`` [rad] (..., n), NaN where the angle was not measured.

    Parameters
    ----------
    theta_pred : array_like, shape (..., n) [rad]
    theta_meas : array_like, shape (..., n) [rad]
        NaN = not measured.
    """
    pred = np.asarray(theta_pred, dtype=float)
    meas = np.asarray(theta_meas, dtype=float)
    if pred.shape != meas.shape:
        raise ValueError(f"predicted and measured angles differ in shape: {pred.shape} vs {meas.shape}")
    return np.where(np.isfinite(meas), pred - meas, np.nan)


def sample_mse(obs: Observations, predicted: np.ndarray) -> np.ndarray:
    """Mean squared error of each sample [m² per point or rad² per angle] (S,), NaN without data.

    Points: the squared distance ``|Q_i − Q̃_i|²`` averaged over the measured
    points (the paper's error, Sec. IV-A); angles: the squared angle error
    averaged over the measured joints.
    """
    d = np.asarray(predicted, dtype=float) - obs.measured
    d2 = np.sum(d**2, axis=-1) if obs.metric == "points" else d**2
    d2[~obs.valid] = np.nan
    out = np.full(d2.shape[0], np.nan)
    has = obs.valid.any(axis=1)
    out[has] = np.nanmean(d2[has], axis=1)
    return out


def peak_regimes(pulled_tension, tip_angle, *, hold_fraction: float = 0.2) -> np.ndarray:
    """Regime of each sample of one bend/unbend test from its peak (Sec. IV intro, Fig. 11).

    I (loading) up to the peak of the pulled tension; after it II (holding)
    while the tip angle has lost less than ``hold_fraction`` of its drop from
    the peak to its lowest later value, then III (releasing).

    This labels a whole measured test at once from two landmarks (the
    tension peak and the lowest later tip angle), which is robust to the
    noise of measured tensions and shapes. It differs from
    :func:`notchfit.physics.friction.stepwise_regimes`, which labels any history step by
    step from the change of the load and of the shape against the loading
    compliance; the two can disagree on single samples near the boundaries.

    Parameters
    ----------
    pulled_tension, tip_angle : array_like, shape (S,) [N, rad]
        Tip angle signed toward the pulled side.
    hold_fraction : float
        Fraction of the unloading drop of the tip angle that ends regime II.

    Returns
    -------
    ndarray of str, shape (S,)
    """
    T = np.asarray(pulled_tension, dtype=float)
    phi = np.asarray(tip_angle, dtype=float)
    S = len(T)
    out = np.full(S, "I", dtype="<U3")
    k = int(np.argmax(T))
    if k >= S - 1:
        return out
    drop = phi[k] - np.nanmin(phi[k:])
    for s in range(k + 1, S):
        if drop <= 0 or phi[k] - phi[s] < hold_fraction * drop:
            out[s] = "II"
        else:
            out[s:] = "III"
            break
    return out


def choose_metric(experiments, metric: str = "auto", *, prefer: str = "points", who: str = "the diagnosis") -> str:
    """The metric of a study: with ``"auto"`` the preferred one when every experiment has it, else the
    other when every experiment has that; or the one asked for.

    ``diagnose`` prefers notch points (the paper's metric), ``identify`` joint
    angles (what real-tube labs measure).

    Raises
    ------
    ValueError
        An experiment lacks what the metric compares, or the study mixes them (the message names them).
    """
    if metric not in ("auto", *METRICS):
        raise ValueError(f"metric must be 'auto', 'points' or 'angles', got {metric!r}")
    no_pts = [e.name for e in experiments if e.points is None]
    no_ang = [e.name for e in experiments if getattr(e, "angles", None) is None]
    if metric == "auto":
        lacking = {"points": no_pts, "angles": no_ang}
        for m in (prefer, "angles" if prefer == "points" else "points"):
            if not lacking[m]:
                return m
        raise ValueError(f"{who} compares one kind of measurement per study: experiment(s) "
                         f"{', '.join(no_pts)} have no notch points and {', '.join(no_ang)} no joint angles "
                         "(angles.csv); analyse them apart")
    missing = no_pts if metric == "points" else no_ang
    if missing:
        what = "notch points (notch_points.csv or detections)" if metric == "points" else "angles.csv"
        raise ValueError(f"experiment(s) {', '.join(missing)} have no {what} to compare")
    return metric


def _nan_line_fit(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``θ_j = a + b j`` per row through the finite angles (NaN with fewer than two) [rad]."""
    S, n = theta.shape
    a, b = np.full(S, np.nan), np.full(S, np.nan)
    j = np.arange(1, n + 1, dtype=float)
    for s in range(S):
        ok = np.isfinite(theta[s])
        if ok.sum() >= 2:
            b[s], a[s] = np.polyfit(j[ok], theta[s, ok], 1)
    return a, b


def _register_points(exp, sigma_default: float):
    """Free-θ and linear fits of the points: measured, valid, transform, σ, θ, residuals, a, b."""
    geom = exp.geometry
    fit = fit_experiment(exp.points, geom, models=("linear", "free"), mirror=exp.mirror,
                         sigma=exp.point_sigma, sigma_default=sigma_default)
    sig = exp.point_sigma if exp.point_sigma else float(np.nanmedian(fit.sigma))
    theta = fit.theta("free")
    Q = np.asarray(exp.points, dtype=float)
    valid = np.isfinite(Q).all(axis=-1)
    th_ok = np.where(np.isfinite(theta), theta, 0.0)
    resid = Q - fit.transform.to_plane(notch_points(th_ok, geom))
    resid[~valid] = np.nan
    a, b, _, _ = fit.ab("linear")
    return Q, valid, fit.transform, float(sig), theta, resid, a, b


def observe(exp, *, metric: str = "points", tube: str | None = None, sigma_default: float = DEFAULT_POINT_SIGMA,
            angle_sigma_default: float = DEFAULT_ANGLE_SIGMA, ramp_time: float | None = None) -> Observations:
    """Reduce one experiment to its :class:`Observations` (registration and measured shapes included).

    Parameters
    ----------
    exp : notchfit.io.Experiment
        Must carry what ``metric`` compares: notch points (``notch_points.csv``
        or detections) or joint angles (``angles.csv``, at least one measured).
    metric : {"points", "angles"}
    tube : str, optional
        Its tube label (default: its geometry's name).
    sigma_default : float
        Point σ [m] used when experiment.toml gives none and it cannot be estimated.
    angle_sigma_default : float
        Angle σ [rad] used when experiment.toml gives none (``[uncertainty] angle_deg``).
    ramp_time : float, optional
        The protocol to simulate [s] (default: experiment.toml's, else a step).
    """
    geom = exp.geometry
    if metric == "points":
        if exp.points is None:
            raise ValueError(f"{exp.path}: experiment {exp.name} has no notch points "
                             "(notch_points.csv or detections) to compare")
        Q, valid, transform, sig, theta, resid, a, b = _register_points(exp, sigma_default)
    else:
        if getattr(exp, "angles", None) is None:
            raise ValueError(f"{exp.path}: experiment {exp.name} has no angles.csv to compare")
        Q = np.asarray(exp.angles, dtype=float)
        valid = np.isfinite(Q)
        if not valid.any():
            raise ValueError(f"{exp.path}: experiment {exp.name} has no measured angle in angles.csv")
        transform, resid, theta = None, None, Q
        sig = float(exp.angle_sigma or angle_sigma_default)
        a, b = _nan_line_fit(Q)
    tl, tr = np.asarray(exp.tension_left, float), np.asarray(exp.tension_right, float)
    pulled = pulled_side(tl, tr)
    counter = float(np.median(tl if pulled == RIGHT else tr))
    tip = pulled * np.nansum(theta - geom.rest_angles, axis=1)
    regime = peak_regimes(tr if pulled == RIGHT else tl, tip)
    ramp = ramp_time if ramp_time is not None else (exp.ramp_time or 0.0)
    return Observations(name=exp.name, geom=geom, time=np.asarray(exp.time, float), tension_left=tl,
                        tension_right=tr, measured=Q, valid=valid, transform=transform, sigma=sig,
                        theta_free=theta, free_residuals=resid, a=a, b=b, pulled=pulled, regime=regime,
                        counter_tension=counter, tension_sigma=tension_sigma(exp), metric=metric,
                        ramp_time=float(ramp), tube=geom.name if tube is None else tube)


def tube_labels(geoms) -> list[str]:
    """A label per geometry: its name, made unique (``name-2``, ...) among the distinct geometries."""
    label_of: dict = {}
    count: dict = {}
    for g in geoms:
        if g not in label_of:
            k = count[g.name] = count.get(g.name, 0) + 1
            label_of[g] = g.name if k == 1 else f"{g.name}-{k}"
    return [label_of[g] for g in geoms]


def observe_study(exps, metric: str = "auto", *, prefer: str = "points", who: str = "the diagnosis",
                  **kw) -> tuple[Observations, ...]:
    """Every experiment of a study observed in one metric (:func:`choose_metric`), labelled with its tube.

    Keyword arguments go to :func:`observe`.
    """
    exps = list(exps)
    if not exps:
        raise ValueError(f"{who} needs at least one experiment")
    metric = choose_metric(exps, metric, prefer=prefer, who=who)
    tubes = tube_labels([e.geometry for e in exps])
    return tuple(observe(e, metric=metric, tube=t, **kw) for e, t in zip(exps, tubes))


def zero_tension_samples(obs: Observations, *, n_sigma: float = 3.0) -> np.ndarray:
    """Indices of the samples taken at rest before the first load: every tendon within ``n_sigma σ_T`` of zero.

    Only samples before the first one above the threshold count: after a
    load, friction may hold a bend at zero tension.
    """
    thr = n_sigma * obs.tension_sigma
    low = (obs.tension_left <= thr) & (obs.tension_right <= thr)
    if low.all():
        return np.arange(low.size)
    return np.arange(int(np.argmin(low)))
