"""Predicted notch points and the calibration of a model on measured experiments.

The friction simulator (Sec. IV-B, fast solver) is driven with the measured
tensions; its joint angles give notch points (Eqs. 1-3) that are registered
in the plane like the measurements. :func:`calibrate` fits the baseline or a
candidate (:mod:`notchfit.diagnosis.specs`) to the points of some
experiments by bounded least squares.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..fitting import fit_experiment
from ..friction import FrictionParams, simulate
from ..notches import notch_points, to_plane
from ..warp import apply_point_warp, unwarp_points
from .prepare import Prepared
from .specs import BASELINE, REGISTRATION_BOUNDS, WARP_CENTER_RANGE, WARP_RADIUS, model_params, specs_for

__all__ = ["Calibration", "SimulationCache", "calibrate", "predict_points", "reregister"]


class SimulationCache:
    """Fast-solver joint angles cached by (experiment, inputs, parameters).

    The finite-difference Jacobian of a calibration perturbs warp and
    registration parameters that need no new simulation; the cache makes
    those evaluations cost only the projection.

    Parameters
    ----------
    max_items : int
        The cache is emptied when it holds this many histories.
    """

    def __init__(self, max_items: int = 4096):
        self.max_items = max_items
        self._d: dict = {}

    def theta(self, prep: Prepared, params: FrictionParams) -> np.ndarray:
        """Simulated joint angles [rad] (S, n) of ``prep`` driven by its measured tensions."""
        key = (prep.name, dataclasses.astuple(params))
        th = self._d.get(key)
        if th is None:
            if len(self._d) >= self.max_items:
                self._d.clear()
            th = simulate(prep.time, prep.tension_left, prep.tension_right, params, prep.geom,
                          method="fast").theta
            self._d[key] = th
        return th


def predict_points(prep: Prepared, values: dict, *, transform=None, registration=None,
                   cache: SimulationCache | None = None):
    """Predicted notch points in the plane frame for parameter ``values``.

    Parameters
    ----------
    prep : Prepared
    values : dict
        Model parameters by name (baseline, extension and warp).
    transform : PlaneTransform, optional
        Registration to use instead of ``prep.transform``.
    registration : (dtx [m], dty [m], dphi [rad]), optional
        Correction added to the registration.
    cache : SimulationCache, optional

    Returns
    -------
    points : ndarray, shape (S, m, 2) [m]
    theta : ndarray, shape (S, n) [rad]
    """
    params, warp = model_params(values)
    theta = (cache or SimulationCache()).theta(prep, params)
    T = transform or prep.transform
    tx, ty, phi = T.tx, T.ty, T.phi
    if registration is not None:
        tx, ty, phi = tx + registration[0], ty + registration[1], phi + registration[2]
    P = to_plane(notch_points(theta, prep.geom), tx, ty, phi, T.mirror)
    if warp:
        P = apply_point_warp(P, warp["scale_error"], warp["k_radial"],
                             (warp["warp_center_x"], warp["warp_center_y"]), WARP_RADIUS)
    return P, theta


def reregister(prep: Prepared, values: dict):
    """Registration of an experiment whose points are corrected by the warp in ``values``.

    The calibration_error candidate corrects the measurement; the corrected
    points are registered exactly as the baseline's (free-θ fit). A warp
    that is not one-to-one over the points leaves the registration as is.

    Returns
    -------
    PlaneTransform
    """
    _, warp = model_params(values)
    if not warp:
        return prep.transform
    try:
        Q = unwarp_points(prep.measured, warp["scale_error"], warp["k_radial"],
                          (warp["warp_center_x"], warp["warp_center_y"]), WARP_RADIUS)
    except ValueError:
        # the fitted warp folds over within these points: it is no correction of
        # them; score it with the uncorrected registration
        return prep.transform
    fit = fit_experiment(Q, prep.geom, models=("free",), mirror=prep.transform.mirror,
                         sigma=prep.sigma)
    return fit.transform


@dataclass(frozen=True)
class Calibration:
    """A model fitted on some experiments.

    Attributes
    ----------
    cause : str or None
        None for the baseline.
    values : dict
        Parameter values by name (SI).
    se : dict
        Standard errors, inflated for correlated residuals (see :func:`calibrate`).
    train_rms : float
        Notch-point rms on the training experiments [m].
    cost : float
        Half the sum of squared normalised residuals.
    n_residuals : int
    success : bool
    message : str
    nfev : int
    registration : tuple
        Per training experiment, the fitted registration correction
        (dtx [m], dty [m], dphi [rad]) (calibration_error only; else empty).
    """

    cause: str | None
    values: dict
    se: dict
    train_rms: float
    cost: float
    n_residuals: int
    success: bool
    message: str
    nfev: int
    registration: tuple = ()


@dataclass(frozen=True)
class _Problem:
    """The least-squares problem of one calibration (optimiser coordinates)."""

    preps: tuple
    specs: tuple
    x0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    n_reg: int
    cache: SimulationCache

    @property
    def k(self) -> int:
        return len(self.specs)

    def values_of(self, x) -> dict:
        return {s.name: s.from_x(float(v)) for s, v in zip(self.specs, x[:self.k])}

    def registration(self, x, i: int):
        return x[self.k + 3 * i:self.k + 3 * i + 3] if self.n_reg else None

    def residuals(self, x) -> np.ndarray:
        """Notch-point residuals normalised by σ, zero where a point is missing."""
        vals = self.values_of(x)
        out = []
        for i, prep in enumerate(self.preps):
            P, _ = predict_points(prep, vals, registration=self.registration(x, i), cache=self.cache)
            r = (P - prep.measured) / prep.sigma
            r[~prep.valid] = 0.0
            out.append(r.ravel())
        return np.concatenate(out)


def _problem(preps, cause, start: dict, cache) -> _Problem:
    """Start vector and bounds; for calibration_error the warp centre on the data and registrations."""
    specs = specs_for(cause)
    x0 = np.array([s.to_x(float(np.clip(start.get(s.name, s.start), s.lower, s.upper))) for s in specs])
    lo = np.array([s.x_bounds[0] for s in specs])
    hi = np.array([s.x_bounds[1] for s in specs])
    n_reg = 0
    if cause == "calibration_error":
        # centre the warp on the data: where a camera would be aimed
        allp = np.concatenate([p.measured[p.valid] for p in preps])
        c = np.nanmean(allp, axis=0)
        if "warp_center_x" not in start:
            x0[-2:] = c
        lo[-2:], hi[-2:] = c - WARP_CENTER_RANGE, c + WARP_CENTER_RANGE
        n_reg = 3 * len(preps)
        b = np.tile(REGISTRATION_BOUNDS, len(preps))
        x0, lo, hi = np.r_[x0, np.zeros(n_reg)], np.r_[lo, -b], np.r_[hi, b]
    x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
    return _Problem(tuple(preps), specs, x0, lo, hi, n_reg, cache)


def _probe_starts(pb: _Problem, start: dict) -> list[np.ndarray]:
    """Start points of the least-squares runs: ``x0``, or the best probe from ``x0`` and from the paper's values.

    The baseline optimum may have compensated the missing effect (e.g. a soft
    mid-range rate standing in for a stiffness gradient): the extension's
    probes are tried from it and from the paper's values.
    """
    probe_idx = [i for i, s in enumerate(pb.specs) if s.probes and s.name not in start]
    if not probe_idx:
        return [pb.x0]
    paper = pb.x0.copy()
    for i, s in enumerate(BASELINE):
        paper[i] = s.to_x(s.start)
    starts = []
    for base_x in (pb.x0, paper):
        best = (np.inf, base_x)
        for combo in itertools.product(*(pb.specs[i].probes for i in probe_idx)):
            x = base_x.copy()
            for i, v in zip(probe_idx, combo):
                x[i] = pb.specs[i].to_x(v)
            cost = float(np.sum(pb.residuals(x) ** 2))
            if cost < best[0]:
                best = (cost, x)
        starts.append(np.clip(best[1], pb.lo, pb.hi))
    return starts


def _standard_errors(pb: _Problem, res, vals: dict, n_res: int) -> dict:
    """Standard errors from ``(JᵀJ)⁻¹`` scaled by the residual variance and by residuals per sample."""
    n_samples = int(sum(len(p.time) for p in pb.preps))
    J = res.jac[:, :pb.k]
    dof = max(n_res - len(res.x), 1)
    s2 = 2.0 * res.cost / dof
    cov_x = np.linalg.pinv(J.T @ J) * s2 * max(n_res / max(n_samples, 1), 1.0)
    se = {}
    for i, s in enumerate(pb.specs):
        sx = math.sqrt(max(cov_x[i, i], 0.0))
        se[s.name] = vals[s.name] * sx if s.log else sx
    return se


def calibrate(preps, cause: str | None = None, start: dict | None = None, *,
              diff_step: float = 2e-3, max_nfev: int = 60, ftol: float = 1e-4,
              xtol: float = 1e-4, cache: SimulationCache | None = None) -> Calibration:
    """Fit the baseline (``cause=None``) or a candidate on experiments ``preps``.

    Bounded least squares (``scipy.optimize.least_squares``, ``trf``) on the
    notch-point residuals normalised by σ, finite-difference Jacobian with a
    relative step ``diff_step`` large enough to step over the stick/slip
    switching of the simulator. Positive stiffnesses are fitted in log
    space. The extension parameters start from the best of their
    ``probes`` (each one residual evaluation), with the baseline parameters
    at ``start`` and at the paper's values; the fit runs from the best probe
    of each and keeps the lower cost. The calibration_error
    candidate also fits a registration correction per experiment (the
    registration was estimated from the uncorrected points). Standard
    errors come from ``(JᵀJ)⁻¹`` scaled by the residual variance and by the
    ratio of residual count to samples (the residuals of one sample are
    correlated: the sample, not the point, is the unit).

    Parameters
    ----------
    preps : sequence of Prepared
    cause : str or None
    start : dict, optional
        Start values by name (e.g. the baseline optimum); the spec's start
        for the rest.
    diff_step, max_nfev, ftol, xtol : float, int
        Passed to ``scipy.optimize.least_squares``.
    cache : SimulationCache, optional

    Returns
    -------
    Calibration
    """
    start = dict(start or {})
    pb = _problem(preps, cause, start, cache or SimulationCache())
    res = None
    for xs in _probe_starts(pb, start):
        r = least_squares(pb.residuals, xs, bounds=(pb.lo, pb.hi), method="trf", diff_step=diff_step,
                          max_nfev=max_nfev, ftol=ftol, xtol=xtol, x_scale="jac")
        if res is None or r.cost < res.cost:
            res = r
    vals = pb.values_of(res.x)
    reg = tuple(tuple(pb.registration(res.x, i)) for i in range(len(preps))) if pb.n_reg else ()
    n_res = int(sum(p.valid.sum() * 2 for p in preps))
    se = _standard_errors(pb, res, vals, n_res)
    r = pb.residuals(res.x) * np.concatenate([np.full(p.valid.size * 2, p.sigma) for p in preps])
    train_rms = math.sqrt(float(np.sum(r**2)) / max(n_res / 2, 1))
    return Calibration(cause=cause, values=vals, se=se, train_rms=train_rms, cost=float(res.cost),
                       n_residuals=n_res, success=bool(res.success), message=str(res.message),
                       nfev=int(res.nfev), registration=reg)
