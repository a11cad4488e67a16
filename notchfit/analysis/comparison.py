"""A simulation against the measurement (Sec. IV-A, IV-B; Figs. 18–19).

The friction model (:func:`notchfit.physics.friction.simulate`) predicts the joint
angles at every sample from the measured tensions; the measurement is the
experiment's notch points. They are compared as the paper does:

* the shape summary ``a``, ``b`` of ``θ_j = a + b j`` (Sec. IV-A): of the
  measurement by the linear shape model fitted to the points
  (:func:`notchfit.analysis.fitting.fit_experiment`), of the prediction by the
  least-squares line through the predicted angles
  (:func:`notchfit.physics.shapes.line_fit`);
* the notch-point error of the prediction: the predicted virtual points
  mapped into the plane with the fit's plane transform, against the measured
  points, ``e_i = ||Q_i − Q̃_i||`` per sample (rms and maximum).

For an experiment with measured joint angles (``angles.csv``, real tubes) the
comparison is in angle space (:func:`compare_angles`): the residual
``θ_sim − θ_meas`` of every measured joint and sample, its rms per sample, per
joint and overall, and the shape summary ``a``, ``b`` of the measured angles
(the linear model fitted to them, :func:`notchfit.analysis.fitting.fit_angles`).
:func:`angle_residuals` (the estimation core's, :mod:`notchfit.analysis.estimation`, which
``identify`` and ``diagnose`` fit with) and :func:`angle_rms` are the one home of the
angle residual and its rms.

Returns objects and writes nothing; :func:`comparison_table` and
:func:`angle_comparison_table` are the ``simulation_vs_measured.csv`` and
``simulation_vs_angles.csv`` layouts (docs/data-formats.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .estimation.observations import angle_residuals
from .fitting import PlaneTransform, fit_angles, fit_experiment
from ..physics.notches import notch_points
from ..physics.shapes import line_fit
from ..units import DEG, MM

__all__ = ["AngleComparison", "SimulationComparison", "angle_comparison_table", "angle_residuals", "angle_rms",
           "compare_angles", "compare_simulation", "comparison_table", "nan_rms_max"]


@dataclass(frozen=True)
class SimulationComparison:
    """Measured against predicted shapes of one experiment (S samples, n joints).

    Attributes
    ----------
    samples : tuple
        Sample ids.
    a_meas, b_meas : ndarray, shape (S,)
        ``a``, ``b`` of the linear model fitted to the measured points [rad].
    a_sim, b_sim : ndarray, shape (S,)
        ``a``, ``b`` of the least-squares line through the predicted angles [rad].
    theta_meas : ndarray, shape (S, n)
        The linear model's fitted joint angles [rad] (NaN for a failed fit).
    point_rms, point_max : ndarray, shape (S,)
        Rms and maximum over the measured points of the prediction's
        pointwise error [m]; NaN for a sample without points.
    transform : PlaneTransform
        The plane transform estimated with the linear fit.
    """

    samples: tuple
    a_meas: np.ndarray = field(repr=False)
    b_meas: np.ndarray = field(repr=False)
    a_sim: np.ndarray = field(repr=False)
    b_sim: np.ndarray = field(repr=False)
    theta_meas: np.ndarray = field(repr=False)
    point_rms: np.ndarray = field(repr=False)
    point_max: np.ndarray = field(repr=False)
    transform: PlaneTransform = field(repr=False)


def nan_rms_max(err) -> tuple[np.ndarray, np.ndarray]:
    """Per-row rms and maximum over the finite entries of ``err`` (S, m); NaN for a row with none.

    Returns
    -------
    rms, max : ndarray, shape (S,)
    """
    err = np.asarray(err, dtype=float)
    ok = np.isfinite(err)
    n = ok.sum(axis=1)
    sq = np.where(ok, err, 0.0) ** 2
    rms = np.full(err.shape[0], np.nan)
    mx = np.full(err.shape[0], np.nan)
    has = n > 0
    rms[has] = np.sqrt(sq[has].sum(axis=1) / n[has])
    mx[has] = np.where(ok, err, -np.inf)[has].max(axis=1)
    return rms, mx


def compare_simulation(result, points, *, mirror: bool = False, sigma=None, samples=None,
                       geom=None) -> SimulationComparison:
    """Compare a simulation with the measured notch points of the same experiment.

    Parameters
    ----------
    result : notchfit.physics.friction.SimulationResult
        The prediction, S samples.
    points : array_like, shape (S, m, 2)
        Measured plane-frame points [m], NaN where missing.
    mirror : bool
        The experiment's mirror flag.
    sigma : float or array_like, optional
        Point uncertainty [m] (estimated by the fit when omitted).
    samples : sequence, optional
        Sample ids (default 0..S-1).
    geom : Geometry, optional
        Default: the simulation's geometry.

    Returns
    -------
    SimulationComparison

    Raises
    ------
    ValueError, numpy.linalg.LinAlgError
        The linear fit of the points fails (e.g. too few points to place the
        manipulator in the plane).
    """
    geom = result.geom if geom is None else geom
    pts = np.asarray(points, dtype=float)
    fit = fit_experiment(pts, geom, ("linear",), mirror=mirror, sigma=sigma, samples=samples)
    a_m, b_m, _, _ = fit.ab("linear")
    theta = np.asarray(result.theta)
    pred = fit.transform.to_plane(notch_points(theta, geom))
    rms, mx = nan_rms_max(np.linalg.norm(pred - pts, axis=-1))        # NaN where a point is missing
    a_s, b_s = line_fit(theta)
    return SimulationComparison(fit.samples, a_m, b_m, a_s, b_s, fit.theta("linear"), rms, mx, fit.transform)


def comparison_table(comp: SimulationComparison, result) -> pd.DataFrame:
    """``simulation_vs_measured.csv``: one row per sample (docs/data-formats.md).

    Columns: ``sample, tension_left_N, tension_right_N, regime, a_meas, b_meas,
    a_sim, b_sim`` [rad], ``point_rms_mm, point_max_mm`` [mm].
    """
    return pd.DataFrame({
        "sample": list(comp.samples), "tension_left_N": np.asarray(result.input_left),
        "tension_right_N": np.asarray(result.input_right), "regime": np.asarray(result.regime).astype(str),
        "a_meas": comp.a_meas, "b_meas": comp.b_meas, "a_sim": comp.a_sim, "b_sim": comp.b_sim,
        "point_rms_mm": comp.point_rms / MM, "point_max_mm": comp.point_max / MM})


def angle_rms(residuals, axis=None):
    """Rms over the measured entries of ``residuals`` [rad] (NaN = not measured; NaN when none is).

    ``axis=None``: one number over every sample and joint (the "rms per notch"
    of the real-tube literature); ``axis=1``: per sample; ``axis=0``: per joint.
    """
    r = np.asarray(residuals, dtype=float)
    ok = np.isfinite(r)
    n = ok.sum(axis=axis)
    sq = np.where(ok, r * r, 0.0).sum(axis=axis)
    if axis is None:
        return float(np.sqrt(sq / n)) if n else float("nan")
    return np.where(n > 0, np.sqrt(sq / np.maximum(n, 1)), np.nan)


@dataclass(frozen=True)
class AngleComparison:
    """Predicted against measured joint angles of one experiment (S samples, n joints).

    Attributes
    ----------
    samples : tuple
    theta_meas, theta_sim : ndarray (S, n) [rad]
        Measured (NaN = not measured) and predicted angles.
    a_meas, b_meas : ndarray (S,) [rad]
        The linear model ``θ_j = a + b j`` fitted to the measured angles
        (:func:`notchfit.analysis.fitting.fit_angles`; NaN with fewer than two).
    a_sim, b_sim : ndarray (S,) [rad]
        The least-squares line through the predicted angles.
    residuals : ndarray (S, n) [rad]
        ``θ_sim − θ_meas`` (:func:`angle_residuals`).
    """

    samples: tuple
    theta_meas: np.ndarray = field(repr=False)
    theta_sim: np.ndarray = field(repr=False)
    a_meas: np.ndarray = field(repr=False)
    b_meas: np.ndarray = field(repr=False)
    a_sim: np.ndarray = field(repr=False)
    b_sim: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)

    @property
    def rms(self) -> float:
        """Rms over every measured angle [rad]."""
        return angle_rms(self.residuals)

    @property
    def sample_rms(self) -> np.ndarray:
        """Rms of each sample's measured angles [rad] (S,)."""
        return angle_rms(self.residuals, axis=1)

    @property
    def sample_max(self) -> np.ndarray:
        """Largest ``|θ_sim − θ_meas|`` of each sample [rad] (S,)."""
        return nan_rms_max(np.abs(self.residuals))[1]

    @property
    def joint_rms(self) -> np.ndarray:
        """Rms of each joint over the samples [rad] (n,)."""
        return angle_rms(self.residuals, axis=0)


def compare_angles(result, angles, *, sigma: float | None = None, samples=None) -> AngleComparison:
    """Compare a simulation with the measured joint angles of the same experiment.

    Parameters
    ----------
    result : notchfit.physics.friction.SimulationResult
        The prediction, S samples.
    angles : array_like, shape (S, n) [rad]
        Measured angles (rest angles included), NaN where not measured.
    sigma : float, optional
        Angle uncertainty [rad], for the linear fit of the measured angles.
    samples : sequence, optional
        Sample ids (default 0..S-1).

    Returns
    -------
    AngleComparison
    """
    theta = np.asarray(result.theta, dtype=float)
    meas = np.asarray(angles, dtype=float)
    res = angle_residuals(theta, meas)
    ids = tuple(range(theta.shape[0])) if samples is None else tuple(samples)
    lin = fit_angles(meas, ("linear",), sigma=sigma, samples=ids).get("linear")
    a_s, b_s = line_fit(theta)
    return AngleComparison(ids, meas, theta, lin.a, lin.b, a_s, b_s, res)


def angle_comparison_table(comp: AngleComparison, result) -> pd.DataFrame:
    """``simulation_vs_angles.csv``: one row per sample (docs/data-formats.md).

    Columns: ``sample, tension_left_N, tension_right_N, regime, a_meas, b_meas,
    a_sim, b_sim`` [rad], ``rms_deg, max_deg, n_angles``, then ``err_1_deg …
    err_n_deg`` (``θ_sim − θ_meas`` per joint [deg], empty where not measured).
    """
    cols = {"sample": list(comp.samples), "tension_left_N": np.asarray(result.input_left),
            "tension_right_N": np.asarray(result.input_right), "regime": np.asarray(result.regime).astype(str),
            "a_meas": comp.a_meas, "b_meas": comp.b_meas, "a_sim": comp.a_sim, "b_sim": comp.b_sim,
            "rms_deg": comp.sample_rms / DEG, "max_deg": comp.sample_max / DEG,
            "n_angles": np.isfinite(comp.theta_meas).sum(axis=1)}
    for j in range(comp.residuals.shape[1]):
        cols[f"err_{j + 1}_deg"] = comp.residuals[:, j] / DEG
    return pd.DataFrame(cols)
