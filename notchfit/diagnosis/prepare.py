"""Measured experiments prepared once for the comparison with simulations.

An experiment is compared in one of two *metrics*: its notch points
(``"points"``, the paper's error metric, Sec. IV-A: the points are registered
in the plane by the free-θ fit of the measurements alone) or its measured
joint angles (``"angles"``, ``angles.csv`` of a real tube: no registration).
Either way its measured shapes are summarised (joint angles, the linear
``θ_j = a + b j`` fit), its pulled tendon found and its samples labelled with
the regimes I/II/III of Sec. IV (Fig. 11).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cables import RIGHT, pulled_side
from ..fitting import fit_experiment
from ..fitting.angles import DEFAULT_ANGLE_SIGMA
from ..notches import notch_points

__all__ = ["METRICS", "Prepared", "choose_metric", "peak_regimes", "prepare_experiment",
           "sample_mse"]

#: The comparison metrics: what is compared, and the unit of its errors in files.
METRICS = {"points": "mm", "angles": "deg"}


@dataclass(frozen=True)
class Prepared:
    """One experiment ready for simulation-vs-measurement comparison.

    Attributes
    ----------
    name : str
    geom : Geometry
    time, tension_left, tension_right : ndarray, shape (S,) [s, N, N]
    measured : ndarray, shape (S, m, 2) or (S, n)
        Measured notch points in the plane frame [m] (metric ``"points"``) or
        measured joint angles [rad] (``"angles"``); NaN where missing.
    valid : ndarray of bool, shape (S, m) or (S, n)
    transform : PlaneTransform or None
        Registration of the manipulator frame in the plane (from the
        free-θ fit of the measurements alone); None for angle data.
    sigma : float
        Uncertainty of one measured value: a point coordinate [m] or a joint
        angle [rad] (experiment.toml, else estimated or assumed).
    theta_free : ndarray, shape (S, n)
        Measured joint angles: the free-θ fit of each sample's points, or the
        angles themselves [rad].
    free_residuals : ndarray, shape (S, m, 2), or None
        Residuals of the free-θ fit [m] (what no joint configuration
        explains); None for angle data.
    a, b : ndarray, shape (S,)
        Linear-model fit ``θ_j = a + b j`` of the measurements [rad].
    pulled : int
        +1 when the right tendon is the ramped one (bends toward +θ), -1 left
        (:func:`notchfit.cables.pulled_side`).
    regime : ndarray of str, shape (S,)
        I / II / III from the measured data (:func:`peak_regimes`).
    counter_tension : float
        Median tension of the tendon that is not ramped [N] (0 on a one-tendon tube).
    tension_sigma : float
        Load-cell uncertainty [N] (experiment.toml; 0 when not given).
    metric : {"points", "angles"}
    ramp_time : float
        The protocol the simulations are driven with: seconds over which the
        tensions move to the next sample's (0: a step; ``[protocol]`` of
        experiment.toml, else estimated or assumed by the diagnosis).
    """

    name: str
    geom: object
    time: np.ndarray
    tension_left: np.ndarray
    tension_right: np.ndarray
    measured: np.ndarray
    valid: np.ndarray
    transform: object
    sigma: float
    theta_free: np.ndarray
    free_residuals: np.ndarray | None
    a: np.ndarray
    b: np.ndarray
    pulled: int
    regime: np.ndarray
    counter_tension: float
    tension_sigma: float = 0.0
    metric: str = "points"
    ramp_time: float = 0.0

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
        """Perfect-model mean squared error per measured value over ``σ²``: 2 for a
        point (two coordinates), 1 for an angle."""
        return 2.0 if self.metric == "points" else 1.0

    def observe(self, theta: np.ndarray, transform=None) -> np.ndarray:
        """What the measurement would be for joint angles ``theta`` (S, n): notch points in the
        plane (with ``transform``, default the registration) or the angles themselves."""
        if self.metric == "angles":
            return np.asarray(theta, dtype=float)
        T = transform or self.transform
        return T.to_plane(notch_points(theta, self.geom))


def sample_mse(prep: Prepared, predicted: np.ndarray) -> np.ndarray:
    """Mean squared error of each sample [m² per point or rad² per angle] (S,), NaN without data.

    Points: the squared distance ``|Q_i − Q̃_i|²`` averaged over the measured
    points (the paper's error, Sec. IV-A); angles: the squared angle error
    averaged over the measured joints.
    """
    d = np.asarray(predicted, dtype=float) - prep.measured
    d2 = np.sum(d**2, axis=-1) if prep.metric == "points" else d**2
    d2[~prep.valid] = np.nan
    out = np.full(d2.shape[0], np.nan)
    has = prep.valid.any(axis=1)
    out[has] = np.nanmean(d2[has], axis=1)
    return out


def peak_regimes(pulled_tension, tip_angle, *, hold_fraction: float = 0.2) -> np.ndarray:
    """Regime of each sample of one bend/unbend test from its peak (Sec. IV intro, Fig. 11).

    I (loading) up to the peak of the pulled tension; after it II (holding)
    while the tip angle has lost less than ``hold_fraction`` of its drop from
    the peak to its lowest later value, then III (releasing).

    This labels a whole measured test at once from two landmarks (the
    tension peak and the lowest later tip angle), which is robust to the
    noise of measured tensions and shapes; the diagnosis uses it on measured
    data. It differs from :func:`notchfit.friction.stepwise_regimes`, which labels any history
    (simulated or measured) step by step from the change of the load and of
    the shape against the loading compliance, with its own tolerances; the
    two can disagree on single samples near the I/II and II/III boundaries.

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


def choose_metric(experiments, metric: str = "auto") -> str:
    """The metric of a study: notch points when every experiment has them, else joint angles
    when every experiment has them (``"auto"``); or the one asked for.

    Raises
    ------
    ValueError
        An experiment lacks what the metric compares (the message names it).
    """
    if metric not in ("auto", *METRICS):
        raise ValueError(f"metric must be 'auto', 'points' or 'angles', got {metric!r}")
    no_pts = [e.name for e in experiments if e.points is None]
    no_ang = [e.name for e in experiments if getattr(e, "angles", None) is None]
    if metric == "auto":
        if not no_pts:
            return "points"
        if not no_ang:
            return "angles"
        raise ValueError(f"experiment(s) {', '.join(no_pts)} have no notch points and "
                         f"{', '.join(no_ang)} no joint angles: the diagnosis compares one kind of measurement "
                         "across a study")
    missing = no_pts if metric == "points" else no_ang
    if missing:
        what = "notch points (notch_points.csv or detections)" if metric == "points" else "angles.csv"
        raise ValueError(f"experiment(s) {', '.join(missing)} have no {what} to diagnose")
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


def prepare_experiment(exp, *, metric: str = "points", sigma_default: float = 2e-5,
                       angle_sigma_default: float = DEFAULT_ANGLE_SIGMA,
                       ramp_time: float | None = None) -> Prepared:
    """Register one experiment's measurements and fit the measured shapes.

    Parameters
    ----------
    exp : notchfit.io.Experiment
        Must carry what ``metric`` compares: notch points (``notch_points.csv``
        or detections) or joint angles (``angles.csv``).
    metric : {"points", "angles"}
    sigma_default : float
        Point σ [m] used when experiment.toml gives none and it cannot be
        estimated.
    angle_sigma_default : float
        Angle σ [rad] used when experiment.toml gives none (``[uncertainty] angle_deg``).
    ramp_time : float, optional
        The protocol to simulate [s] (default: experiment.toml's, else a step).

    Returns
    -------
    Prepared
    """
    geom = exp.geometry
    if metric == "points":
        if exp.points is None:
            raise ValueError(f"{exp.path}: experiment {exp.name} has no notch points "
                             "(notch_points.csv or detections) to diagnose")
        Q, valid, transform, sig, theta, resid, a, b = _register_points(exp, sigma_default)
    else:
        if getattr(exp, "angles", None) is None:
            raise ValueError(f"{exp.path}: experiment {exp.name} has no angles.csv to diagnose")
        Q = np.asarray(exp.angles, dtype=float)
        valid = np.isfinite(Q)
        transform, resid, theta = None, None, Q
        sig = float(exp.angle_sigma or angle_sigma_default)
        a, b = _nan_line_fit(Q)
    tl, tr = exp.tension_left, exp.tension_right
    pulled = pulled_side(tl, tr)
    counter = float(np.median(tl if pulled == RIGHT else tr))
    tip = pulled * np.nansum(theta - geom.rest_angles, axis=1)
    regime = peak_regimes(tr if pulled == RIGHT else tl, tip)
    ramp = ramp_time if ramp_time is not None else (exp.ramp_time or 0.0)
    return Prepared(name=exp.name, geom=geom, time=exp.time, tension_left=tl, tension_right=tr,
                    measured=Q, valid=valid, transform=transform, sigma=sig,
                    theta_free=theta, free_residuals=resid, a=a, b=b, pulled=pulled,
                    regime=regime, counter_tension=counter,
                    tension_sigma=float(exp.tension_sigma or 0.0), metric=metric, ramp_time=float(ramp))
