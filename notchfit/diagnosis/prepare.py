"""Measured experiments prepared once for the comparison with simulations.

Each experiment's notch points are registered in the plane (the free-θ fit
of the measurements alone), its measured shapes summarised (free-θ joint
angles, the linear ``θ_j = a + b j`` fit), its pulled cable found and its
samples labelled with the regimes I/II/III of Sec. IV (Fig. 11).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cables import RIGHT, pulled_side
from ..fitting import fit_experiment
from ..notches import notch_points

__all__ = ["Prepared", "peak_regimes", "prepare_experiment"]


@dataclass(frozen=True)
class Prepared:
    """One experiment ready for simulation-vs-measurement comparison.

    Attributes
    ----------
    name : str
    geom : Geometry
    time, tension_left, tension_right : ndarray, shape (S,) [s, N, N]
    measured : ndarray, shape (S, m, 2)
        Measured notch points in the plane frame [m] (NaN where missing).
    valid : ndarray of bool, shape (S, m)
    transform : PlaneTransform
        Registration of the manipulator frame in the plane (from the
        free-θ fit of the measurements alone).
    sigma : float
        Point uncertainty per coordinate [m] (experiment.toml, else estimated).
    theta_free : ndarray, shape (S, n)
        Free-θ fit of each sample [rad].
    free_residuals : ndarray, shape (S, m, 2)
        Residuals of the free-θ fit [m] (what no joint configuration explains).
    a, b : ndarray, shape (S,)
        Linear-model fit ``θ_j = a + b j`` of the measurements [rad].
    pulled : int
        +1 when the right cable is the ramped one (bends toward +θ), -1 left
        (:func:`notchfit.cables.pulled_side`).
    regime : ndarray of str, shape (S,)
        I / II / III from the measured data (:func:`peak_regimes`).
    counter_tension : float
        Median tension of the cable that is not ramped [N].
    tension_sigma : float
        Load-cell uncertainty [N] (experiment.toml; 0 when not given).
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
    free_residuals: np.ndarray
    a: np.ndarray
    b: np.ndarray
    pulled: int
    regime: np.ndarray
    counter_tension: float
    tension_sigma: float = 0.0

    @property
    def pulled_tension(self) -> np.ndarray:
        """Tension of the pulled cable [N] (S,)."""
        return self.tension_right if self.pulled > 0 else self.tension_left

    @property
    def tip_angle(self) -> np.ndarray:
        """Measured tip angle ``Σθ`` toward the pulled side [rad] (S,)."""
        return self.pulled * self.theta_free.sum(axis=1)


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


def prepare_experiment(exp, *, sigma_default: float = 2e-5) -> Prepared:
    """Register one experiment's measurements and fit the measured shapes.

    Parameters
    ----------
    exp : notchfit.io.Experiment
        Must carry notch points (from ``notch_points.csv`` or detections).
    sigma_default : float
        Point σ [m] used when experiment.toml gives none and it cannot be
        estimated.

    Returns
    -------
    Prepared
    """
    if exp.points is None:
        raise ValueError(f"{exp.path}: experiment {exp.name} has no notch points "
                         "(notch_points.csv or detections) to diagnose")
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
    tl, tr = exp.tension_left, exp.tension_right
    pulled = pulled_side(tl, tr)
    counter = float(np.median(tl if pulled == RIGHT else tr))
    a, b, _, _ = fit.ab("linear")
    tip = pulled * np.nansum(theta, axis=1)
    regime = peak_regimes(tr if pulled == RIGHT else tl, tip)
    return Prepared(name=exp.name, geom=geom, time=exp.time, tension_left=tl, tension_right=tr,
                    measured=Q, valid=valid, transform=fit.transform, sigma=float(sig),
                    theta_free=theta, free_residuals=resid, a=a, b=b, pulled=pulled,
                    regime=regime, counter_tension=counter,
                    tension_sigma=float(exp.tension_sigma or 0.0))
