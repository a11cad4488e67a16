"""Prediction intervals: the model's uncertainty carried to every notch angle.

A tube never measured is predicted from parameters known only up to a
covariance: the shared (material, friction) parameters from the
identification's covariance, the per-tube ones (rest angles, cut depths) from
the scatter between tubes or the drawing's tolerance. The joint angles are a
nonlinear function of them (stick/slip, the superelastic plateau, slot
closure), so the uncertainty is carried by sigma points: the model runs at
``μ`` and at ``μ ± h s_j`` along the columns ``s_j`` of a square root of the
covariance, ``2p + 1`` runs where Monte Carlo needs hundreds, and the mean and
variance come from Stirling's second-order divided differences (Nørgaard,
Poulsen & Ravn, "New developments in state estimation for nonlinear
systems", Automatica 36(11), 2000, Sec. 3; the same points as the unscented
transform of Julier & Uhlmann, Proc. IEEE 92(3), 2004, with ``κ = 3 − p``).
The step ``h = √3`` matches the Gaussian's fourth moment; the result is exact
for a linear model, gets the mean of a quadratic one right, and its variance
is never negative. The spread stays within ``√3 σ`` of the mean, so a kink
of the model (a joint reaching its stop) far out in the tails does not
inflate the band, as the unscented transform's ``√p σ`` points do for
many parameters.

:func:`prediction_band` bands any prediction function of a parameter vector
(a whole simulated history); :class:`BandPredictor` runs one
:class:`~notchfit.physics.predictor.Predictor` per sigma point and bands each sample
as it arrives (the real-time estimate with its interval).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pandas as pd
from scipy import stats

from ...physics.friction import simulate_angles
from ...physics.predictor import Predictor

__all__ = ["BandPredictor", "NewTubePrior", "PredictionBand", "band_table", "gauss_newton_covariance", "linear_band",
           "prediction_band", "sigma_points", "tube_band"]


#: the divided-difference step: √3, the Gaussian's kurtosis (Nørgaard et al. 2000)
STEP = float(np.sqrt(3.0))


def sigma_points(mean, cov, *, step: float = STEP):
    """The symmetric sigma points ``mean``, ``mean + h s_j``, ``mean − h s_j`` of ``N(mean, cov)``.

    Parameters
    ----------
    mean : array_like (p,)
    cov : array_like (p, p)
        Symmetric positive semi-definite.
    step : float
        ``h``, in standard deviations.

    Returns
    -------
    points : ndarray (2p + 1, p)
        The mean, then the ``+`` points, then the ``−`` points (``s_j`` the columns of a square root of ``cov``).
    weights : ndarray (2p + 1,)
        Mean weights ``(h² − p)/h²`` and ``1/(2h²)`` (they sum to 1).
    """
    mu = np.asarray(mean, dtype=float)
    C = np.asarray(cov, dtype=float)
    p = mu.size
    if C.shape != (p, p):
        raise ValueError(f"cov must be ({p}, {p}), got {C.shape}")
    if not np.allclose(C, C.T, rtol=1e-10, atol=1e-300):
        raise ValueError("cov must be symmetric")
    w, V = np.linalg.eigh(C)                     # a square root that tolerates a singular covariance
    if w.min() < -1e-12 * max(w.max(), 0.0):
        raise ValueError("cov must be positive semi-definite")
    L = V * np.sqrt(np.clip(w, 0.0, None))
    spread = step * L.T                          # (p, p): row j is h times the j-th column of L
    points = np.vstack([mu, mu + spread, mu - spread])
    weights = np.r_[(step ** 2 - p) / step ** 2, np.full(2 * p, 1.0 / (2 * step ** 2))]
    return points, weights


@dataclass(frozen=True)
class PredictionBand:
    """A prediction with its interval, elementwise.

    Attributes
    ----------
    mean : ndarray (...)
        The unscented mean of the prediction [its unit].
    sd : ndarray (...)
        Its standard deviation, with the measurement noise if given [its unit].
    level : float
        Two-sided coverage of ``lower``/``upper`` (0.95: a 95 % interval).
    """

    mean: np.ndarray
    sd: np.ndarray
    level: float

    @property
    def half_width(self) -> np.ndarray:
        return stats.norm.ppf(0.5 + self.level / 2.0) * self.sd

    @property
    def lower(self) -> np.ndarray:
        return self.mean - self.half_width

    @property
    def upper(self) -> np.ndarray:
        return self.mean + self.half_width

    def coverage(self, observed) -> float:
        """Fraction of the finite ``observed`` values inside the interval."""
        y = np.asarray(observed, dtype=float)
        ok = np.isfinite(y) & np.isfinite(self.mean)
        inside = (y >= self.lower) & (y <= self.upper)
        return float(np.mean(inside[ok])) if ok.any() else float("nan")


def _band(outputs, weights, noise_sd, level, step: float = STEP) -> PredictionBand:
    """Mean and variance of the outputs at :func:`sigma_points` (Stirling's second-order formulas)."""
    Y = np.asarray(outputs, dtype=float)
    p = (Y.shape[0] - 1) // 2
    y0, yp, ym = Y[0], Y[1:p + 1], Y[p + 1:]
    w = weights.reshape((-1,) + (1,) * (Y.ndim - 1))
    mean = np.sum(w * Y, axis=0)
    h2 = step ** 2
    first = np.sum(((yp - ym) / (2.0 * step)) ** 2, axis=0)
    second = (h2 - 1.0) / (4.0 * h2 ** 2) * np.sum((yp + ym - 2.0 * y0) ** 2, axis=0)
    var = first + second + np.asarray(noise_sd, dtype=float) ** 2
    return PredictionBand(mean, np.sqrt(var), float(level))


def prediction_band(predict: Callable[[np.ndarray], np.ndarray], mean, cov, *, noise_sd=0.0,
                    level: float = 0.95) -> PredictionBand:
    """Band the predictions of a model whose parameters are ``N(mean, cov)``.

    Parameters
    ----------
    predict : callable
        ``predict(x) -> ndarray`` for a parameter vector ``x`` (p,), e.g. the simulated joint angles
        (S, n) [rad] of a tension history.
    mean, cov : array_like (p,), (p, p)
        The parameters' distribution (identified values and covariance, with the tube-to-tube
        scatter of the per-tube parameters added).
    noise_sd : float or array_like
        Standard deviation of one measurement, added in quadrature for an interval that should
        cover *measured* values (0: the model's own uncertainty) [unit of the prediction].
    level : float
        Two-sided coverage.

    Returns
    -------
    PredictionBand
    """
    points, weights = sigma_points(mean, cov)
    return _band([predict(x) for x in points], weights, noise_sd, level)


def gauss_newton_covariance(jacobian, prior_sd=None) -> np.ndarray:
    """The parameters' covariance ``(JᵀJ + diag(1/prior_sd²))⁻¹`` of a fit from its whitened Jacobian (p, p).

    The known noise only: the residuals are whitened by their measurement σ (and a prior's rows by
    its σ), so this is what the noise leaves of the parameters whatever the fit's residual variance
    (the Gauss–Newton covariance without its ``s²`` factor). A direction the data do not determine
    (a Jacobian column of zeros: a modulus of a range the trials never reach) has no finite variance
    from the data: ``prior_sd`` bounds it (e.g. a uniform prior over the parameter's bounds,
    ``(hi − lo)/√12``); without one the pseudo-inverse gives it none.

    Parameters
    ----------
    jacobian : array_like (r, p)
        Of the whitened residuals at the optimum (priors' rows included).
    prior_sd : array_like (p,), optional
        Each parameter's prior standard deviation (``inf``: none) [parameter unit].
    """
    J = np.asarray(jacobian, dtype=float)
    info = J.T @ J
    if prior_sd is not None:
        info = info + np.diag(1.0 / np.asarray(prior_sd, dtype=float) ** 2)
    return np.linalg.pinv(info, hermitian=True)


def linear_band(prediction, jacobian, cov, *, noise_sd=0.0, level: float = 0.95) -> PredictionBand:
    """The first-order band of a prediction: ``var = diag(J C Jᵀ)`` (linear error propagation).

    :func:`prediction_band`'s variance keeps its first-order term (for a linear model the same
    number) and drops the second-order one; it needs the ``p`` derivatives a fit's Jacobian
    already has (forward differences: ``p + 1`` runs where the sigma points take ``2p + 1``).

    Parameters
    ----------
    prediction : array_like (...)
        The prediction at the parameters' mean [its unit].
    jacobian : array_like (prediction.size, p)
        Its derivatives by the parameters, rows in the order of ``prediction.ravel()`` [unit per parameter].
    cov : array_like (p, p)
        The parameters' covariance.
    noise_sd, level :
        As :func:`prediction_band`'s.

    Returns
    -------
    PredictionBand
    """
    y = np.asarray(prediction, dtype=float)
    J = np.asarray(jacobian, dtype=float).reshape(y.size, -1)
    var = np.einsum("ij,jk,ik->i", J, np.asarray(cov, dtype=float), J).reshape(y.shape)
    var = np.clip(var, 0.0, None) + np.asarray(noise_sd, dtype=float) ** 2
    return PredictionBand(y, np.sqrt(var), float(level))


@dataclass(frozen=True)
class BandPrediction:
    """One sample's estimate with its interval (:class:`BandPredictor`).

    Attributes
    ----------
    time : float [s]
    theta : PredictionBand
        Joint angles (n,) [rad] with their band.
    """

    time: float
    theta: PredictionBand


class BandPredictor:
    """The real-time shape estimate with a prediction interval, one sample at a time.

    One :class:`~notchfit.physics.predictor.Predictor` runs at each sigma point of the
    parameters; every sample advances all of them and the band is their
    unscented spread. The cost per sample is ``2p + 1`` predictor steps.

    Parameters
    ----------
    make_params : callable
        ``make_params(x) -> FrictionParams`` for a parameter vector ``x`` (p,).
    mean, cov : array_like (p,), (p, p)
        The parameters' distribution.
    geom : Geometry
    noise_sd : float [rad]
        Added in quadrature (an interval for measured angles); 0 for the model's own.
    level : float
        Two-sided coverage.
    **predictor_options
        Passed to every :class:`~notchfit.physics.predictor.Predictor` (``ramp_time``, ``settle_time``,
        ``tension_sigma``); ``points`` is off.
    """

    def __init__(self, make_params, mean, cov, geom, *, noise_sd: float = 0.0, level: float = 0.95,
                 **predictor_options):
        points, self._weights = sigma_points(mean, cov)
        predictor_options["points"] = False
        self._predictors = [Predictor(make_params(x), geom, **predictor_options) for x in points]
        self.noise_sd = float(noise_sd)
        self.level = float(level)

    @property
    def n_models(self) -> int:
        """Predictors run per sample (``2p + 1``)."""
        return len(self._predictors)

    @classmethod
    def for_tube(cls, params, geom, prior: "NewTubePrior", **kw) -> "BandPredictor":
        """The band predictor of a tube of ``geom`` under an identified model ``params`` and its
        :class:`NewTubePrior` (the shared covariance and the tube-to-tube scatter); ``kw`` as the
        constructor's."""
        mean, cov, make = prior.distribution(params, geom)
        return cls(make, mean, cov, geom, **kw)

    def reset(self) -> None:
        for p in self._predictors:
            p.reset()

    def step(self, time: float, tension_left: float | None = None,
             tension_right: float | None = None) -> BandPrediction:
        """Advance every sigma-point model to the new sample; the angles and their band."""
        thetas = [p.step(time, tension_left, tension_right).theta for p in self._predictors]
        return BandPrediction(float(time), _band(thetas, self._weights, self.noise_sd, self.level))


# ----------------------------------------------------------------------------- a tube never measured
@dataclass(frozen=True)
class NewTubePrior:
    """What an identified model knows of a tube cut from its stock that it has never seen.

    The shared parameters (material, friction) are known up to the identification's covariance;
    the tube's own — its rest angles and cut depths — vary from tube to tube: the rest angles
    about its geometry file's with the scatter the identified tubes showed about theirs, the cut
    depths about the drawing with the drawing's tolerance. :meth:`distribution` turns this into the
    parameters' mean and covariance for :func:`prediction_band` or :class:`BandPredictor`.

    Attributes
    ----------
    names : tuple of str
        The shared parameters (:class:`~notchfit.physics.friction.FrictionParams` fields).
    log : tuple of bool
        Whether each is in log coordinates (moduli, thresholds).
    mean : ndarray (k,)
        Their identified values, in those coordinates.
    cov : ndarray (k, k)
        Their covariance, in those coordinates.
    rest_sd : float [rad]
        Tube-to-tube standard deviation of a rest angle about the geometry file's (0: as drawn).
    depth_sd : float or None [m]
        Standard deviation of a cut depth about the drawing's; None: the geometry's
        ``slot_depth_tolerance`` (else ``default_depth_sd``); 0: as drawn.
    default_depth_sd : float [m]
        The tolerance of a geometry that states none.
    """

    names: tuple
    log: tuple
    mean: np.ndarray
    cov: np.ndarray
    rest_sd: float = 0.0
    depth_sd: float | None = None
    default_depth_sd: float = 15e-6

    def as_metadata(self) -> dict:
        """A model file's ``[metadata.prediction]`` table (the covariance row by row, flattened)."""
        d = {"names": list(self.names), "log": [bool(v) for v in self.log],
             "mean": [float(v) for v in self.mean], "cov": [float(v) for v in np.ravel(self.cov)],
             "rest_angle_sd_rad": float(self.rest_sd), "default_depth_sd_m": float(self.default_depth_sd)}
        if self.depth_sd is not None:
            d["slot_depth_sd_m"] = float(self.depth_sd)
        return d

    @classmethod
    def from_metadata(cls, d: dict) -> "NewTubePrior":
        """Read :meth:`as_metadata`'s table.

        Raises
        ------
        ValueError
            A missing key or a covariance of the wrong size.
        """
        try:
            k = len(d["names"])
            cov = np.asarray(d["cov"], dtype=float)
            if cov.size != k * k or len(d["mean"]) != k or len(d["log"]) != k:
                raise ValueError(f"prediction: names, log, mean and a {k}x{k} cov must agree in size")
            return cls(tuple(d["names"]), tuple(bool(v) for v in d["log"]), np.asarray(d["mean"], float),
                       cov.reshape(k, k), float(d.get("rest_angle_sd_rad", 0.0)), d.get("slot_depth_sd_m"),
                       float(d.get("default_depth_sd_m", 15e-6)))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"prediction table: missing or bad key {exc}") from None

    def distribution(self, params, geom):
        """The parameters of a new tube of ``geom`` as ``N(mean, cov)`` and the model of a draw.

        The tube's own unknowns are added when ``params`` holds none of its own (a model of the
        stock, not of one tube): its rest angles (``rest_sd``) and cut-depth offsets (the depth σ).

        Returns
        -------
        mean : ndarray (p,)
        cov : ndarray (p, p)
        make_params : callable
            ``make_params(x) -> FrictionParams``.
        """
        k, n = len(self.names), geom.n_joints
        own = params.rest_angle is None and params.slot_depth_offset is None
        depth_sd = self.depth_sd if self.depth_sd is not None else (geom.slot_depth_tolerance or self.default_depth_sd)
        extra = [("rest_angle", params.rest_angles(geom), self.rest_sd)] if own and self.rest_sd > 0 else []
        if own and params.spring_law == "material" and depth_sd > 0:
            extra.append(("slot_depth_offset", np.zeros(n), depth_sd))
        mean = np.concatenate([self.mean] + [m for _, m, _ in extra])
        cov = np.zeros((mean.size, mean.size))
        cov[:k, :k] = self.cov
        for i, (_, _, sd) in enumerate(extra):
            cov[k + i * n:k + (i + 1) * n, k + i * n:k + (i + 1) * n] = np.eye(n) * sd ** 2
        excess = params.mu_s - params.mu_d

        def make_params(x):
            vals = {name: (math.exp(v) if lg else float(v)) for name, lg, v in zip(self.names, self.log, x[:k])}
            if "mu_d" in vals:
                vals["mu_s"] = vals["mu_d"] + excess
            per = {name: tuple(float(v) for v in x[k + i * n:k + (i + 1) * n]) for i, (name, _, _) in enumerate(extra)}
            return params.replace(**vals, **per)

        return mean, cov, make_params


def tube_band(params, geom, time, tension_left, tension_right, prior: NewTubePrior, *, noise_sd: float = 0.0,
              level: float = 0.95, ramp_time: float = 0.0, **sim_kw) -> PredictionBand:
    """Every notch angle of a tension history with its interval (S, n) [rad]: the model's parameters
    and the tube's own as :meth:`NewTubePrior.distribution` says, carried by sigma points through the
    fast solver (:func:`notchfit.physics.friction.simulate_angles`); ``noise_sd`` [rad] added in
    quadrature for an interval that should cover measured angles."""
    mean, cov, make = prior.distribution(params, geom)
    return prediction_band(lambda x: simulate_angles(time, tension_left, tension_right, make(x), geom,
                                                     ramp_time=ramp_time, **sim_kw),
                           mean, cov, noise_sd=noise_sd, level=level)


def band_table(band: PredictionBand, samples, measured=None) -> pd.DataFrame:
    """A band of joint angles (S, n) as rows ``sample, joint, theta_rad, sd_rad, lower_rad, upper_rad``
    (and ``measured_rad``, ``inside`` when ``measured`` (S, n) [rad] is given; NaN / empty where not measured)."""
    S, n = band.mean.shape
    rows = {"sample": np.repeat(np.asarray(samples), n), "joint": np.tile(np.arange(1, n + 1), S),
            "theta_rad": band.mean.ravel(), "sd_rad": band.sd.ravel(), "lower_rad": band.lower.ravel(),
            "upper_rad": band.upper.ravel()}
    if measured is not None:
        y = np.asarray(measured, dtype=float).ravel()
        rows["measured_rad"] = y
        inside = (y >= rows["lower_rad"]) & (y <= rows["upper_rad"])
        rows["inside"] = pd.array(np.where(np.isfinite(y), inside, pd.NA), dtype="boolean")
    return pd.DataFrame(rows)
