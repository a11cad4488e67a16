"""Predicted measurements and the calibration of a model on measured experiments.

The friction simulator (Sec. IV-B, fast solver) is driven with the measured
tensions and the experiment's protocol; its joint angles give notch points
(Eqs. 1-3) registered in the plane like the measurements, or are compared
with measured joint angles directly. :func:`calibrate` fits the baseline, a
candidate or a pair of candidates (:mod:`notchfit.diagnosis.specs`) to some
experiments by bounded least squares.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..causes import REGISTRY
from ..fitting import fit_experiment
from ..friction import FrictionParams, simulate
from ..notches import notch_points, to_plane
from ..warp import apply_point_warp, unwarp_points
from .prepare import Prepared
from .specs import (REGISTRATION_BOUNDS, WARP_CENTER_RANGE, WARP_RADIUS, StudyScales, as_model, baseline_specs,
                    model_params, specs_for)

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
        """Simulated joint angles [rad] (S, n) of ``prep`` driven by its measured tensions and protocol."""
        key = (prep.name, prep.ramp_time, dataclasses.astuple(params))
        th = self._d.get(key)
        if th is None:
            if len(self._d) >= self.max_items:
                self._d.clear()
            th = simulate(prep.time, prep.tension_left, prep.tension_right, params, prep.geom,
                          method="fast", ramp_time=prep.ramp_time).theta
            self._d[key] = th
        return th


def predict_points(prep: Prepared, values: dict, *, transform=None, registration=None,
                   cache: SimulationCache | None = None, base: FrictionParams | None = None):
    """Predicted measurements for parameter ``values``: notch points in the plane frame, or joint
    angles for angle data.

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
    base : FrictionParams, optional
        The model the values change (default: the paper's, Sec. IV-B).

    Returns
    -------
    predicted : ndarray, shape (S, m, 2) [m] or (S, n) [rad]
    theta : ndarray, shape (S, n) [rad]
    """
    params, warp = model_params(values, base)
    theta = (cache or SimulationCache()).theta(prep, params)
    if prep.metric == "angles":
        return theta, theta
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
    if not warp or prep.metric != "points":
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
    cause : tuple of str
        The model: ``()`` for the baseline, one cause, or a pair.
    values : dict
        Parameter values by name (SI).
    se : dict
        Standard errors, inflated for correlated residuals (see :func:`calibrate`).
    train_rms : float
        Rms error on the training experiments [m per point, or rad per angle].
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

    cause: tuple
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
    sc: tuple
    x0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    n_reg: int
    cache: SimulationCache
    base: FrictionParams

    @property
    def k(self) -> int:
        return len(self.specs)

    def values_of(self, x) -> dict:
        return {s.name: s.from_x(float(v), c) for s, c, v in zip(self.specs, self.sc, x[:self.k])}

    def registration(self, x, i: int):
        return x[self.k + 3 * i:self.k + 3 * i + 3] if self.n_reg else None

    def residuals(self, x) -> np.ndarray:
        """Residuals of the measurements normalised by σ, zero where a value is missing."""
        vals = self.values_of(x)
        out = []
        for i, prep in enumerate(self.preps):
            P, _ = predict_points(prep, vals, registration=self.registration(x, i), cache=self.cache,
                                  base=self.base)
            r = (P - prep.measured) / prep.sigma
            r[~prep.valid] = 0.0
            out.append(r.ravel())
        return np.concatenate(out)


def _problem(preps, model: tuple, start: dict, cache, scales: StudyScales, base) -> _Problem:
    """Start vector and bounds; for calibration_error the warp centre on the data and registrations."""
    specs = specs_for(model, base)
    sc = tuple(scales.factor(s.scale) for s in specs)
    x0 = np.array([s.x_of_spec_value(s.start) if s.name not in start
                   else s.to_x(float(start[s.name]), c) for s, c in zip(specs, sc)])
    lo = np.array([s.x_bounds[0] for s in specs])
    hi = np.array([s.x_bounds[1] for s in specs])
    n_reg = 0
    if any(REGISTRY[c].corrects_points for c in model):
        # centre the warp on the data: where a camera would be aimed
        allp = np.concatenate([p.measured[p.valid] for p in preps])
        c = np.nanmean(allp, axis=0)
        idx = [i for i, s in enumerate(specs) if s.name in ("warp_center_x", "warp_center_y")]
        if "warp_center_x" not in start:
            x0[idx] = c
        lo[idx], hi[idx] = c - WARP_CENTER_RANGE, c + WARP_CENTER_RANGE
        n_reg = 3 * len(preps)
        b = np.tile(REGISTRATION_BOUNDS, len(preps))
        x0, lo, hi = np.r_[x0, np.zeros(n_reg)], np.r_[lo, -b], np.r_[hi, b]
    x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
    return _Problem(tuple(preps), specs, sc, x0, lo, hi, n_reg, cache, base)


def _probe_starts(pb: _Problem, start: dict, paper_start: bool = True, keep: float = math.inf) -> list[np.ndarray]:
    """Start points of the least-squares runs: ``x0``, or the best probe from ``x0`` and from the
    base model's values.

    The baseline optimum may have compensated the missing effect (e.g. a soft
    mid-range rate standing in for a stiffness gradient): the extension's
    probes are tried from it and from the base model's (the paper's) values.
    The fit runs from the better of the two; from the other as well only when
    its best probe's cost is within ``keep`` times the better one's (the two
    basins are then not told apart by the probes).
    """
    probe_idx = [i for i, s in enumerate(pb.specs) if s.probes and s.name not in start]
    if not probe_idx:
        return [pb.x0]
    paper = pb.x0.copy()
    for i, s in enumerate(baseline_specs(pb.base)):
        paper[i] = s.x_of_spec_value(s.start)
    found = []
    for base_x in ((pb.x0, paper) if paper_start else (pb.x0,)):
        best = (np.inf, base_x)
        for combo in itertools.product(*(pb.specs[i].probes for i in probe_idx)):
            x = base_x.copy()
            for i, v in zip(probe_idx, combo):
                x[i] = pb.specs[i].x_of_spec_value(v)
            cost = float(np.sum(pb.residuals(x) ** 2))
            if cost < best[0]:
                best = (cost, x)
        found.append(best)
    low = min(c for c, _ in found)
    return [np.clip(x, pb.lo, pb.hi) for c, x in sorted(found, key=lambda t: t[0]) if c <= keep * low]


def _standard_errors(pb: _Problem, res, vals: dict, n_res: int) -> dict:
    """Standard errors from ``(JᵀJ)⁻¹`` scaled by the residual variance and by residuals per sample."""
    n_samples = int(sum(len(p.time) for p in pb.preps))
    J = res.jac[:, :pb.k]
    dof = max(n_res - len(res.x), 1)
    s2 = 2.0 * res.cost / dof
    cov_x = np.linalg.pinv(J.T @ J) * s2 * max(n_res / max(n_samples, 1), 1.0)
    se = {}
    for i, (s, c) in enumerate(zip(pb.specs, pb.sc)):
        sx = math.sqrt(max(cov_x[i, i], 0.0))
        se[s.name] = vals[s.name] * sx if s.log else sx * c
    return se


def calibrate(preps, cause=None, start: dict | None = None, *,
              diff_step: float = 2e-3, max_nfev: int = 60, ftol: float = 1e-3,
              xtol: float = 1e-3, cache: SimulationCache | None = None,
              scales: StudyScales | None = None, base: FrictionParams | None = None,
              paper_start: bool = True, keep_start: float = math.inf) -> Calibration:
    """Fit the baseline (``cause=None``), a candidate or a pair of candidates on experiments ``preps``.

    Bounded least squares (``scipy.optimize.least_squares``, ``trf``) on the
    measurement residuals (notch points or joint angles) normalised by σ,
    finite-difference Jacobian with a
    relative step ``diff_step`` large enough to step over the stick/slip
    switching of the simulator. Positive stiffnesses are fitted in log
    space, the tube-sized parameters in units of the study's scales. The
    extension parameters without a start value start from the best of their
    ``probes`` (each one residual evaluation), with the baseline parameters
    at ``start`` and at the base model's values; the fit runs from the best probe
    of each and keeps the lower cost. The calibration_error
    candidate also fits a registration correction per experiment (the
    registration was estimated from the uncorrected points). Standard
    errors come from ``(JᵀJ)⁻¹`` scaled by the residual variance and by the
    ratio of residual count to samples (the residuals of one sample are
    correlated: the sample, not the point, is the unit).

    Parameters
    ----------
    preps : sequence of Prepared
    cause : None, str or sequence of str
        The model (:func:`notchfit.diagnosis.specs.as_model`).
    start : dict, optional
        Start values by name (e.g. the baseline optimum, or a single cause's
        fit for a pair); the spec's start for the rest.
    diff_step, max_nfev, ftol, xtol : float, int
        Passed to ``scipy.optimize.least_squares``.
    cache : SimulationCache, optional
    scales : StudyScales, optional
        Default: the scales of ``preps``.
    base : FrictionParams, optional
        The model whose fixed parameters (laws, breaks, damping) the fit keeps
        (default: the paper's, Sec. IV-B).
    paper_start : bool
        Also probe and fit from the base model's values (False: from ``start``
        only, e.g. a pair started from its first cause's optimum).
    keep_start : float
        Fit from the second start too when its best probe's cost is within this
        factor of the first's (default: always; a probe's cost does not tell
        which start's basin the fit ends in: a tip load fitted from the
        baseline optimum's best probe stopped at half the true force, from the
        paper's values it found it).

    Returns
    -------
    Calibration
    """
    start = dict(start or {})
    model = as_model(cause)
    base = base or FrictionParams()
    pb = _problem(preps, model, start, cache or SimulationCache(), scales or StudyScales.of(preps, base), base)
    res = None
    for xs in _probe_starts(pb, start, paper_start, keep_start):
        r = least_squares(pb.residuals, xs, bounds=(pb.lo, pb.hi), method="trf", diff_step=diff_step,
                          max_nfev=max_nfev, ftol=ftol, xtol=xtol, x_scale="jac")
        if res is None or r.cost < res.cost:
            res = r
    vals = pb.values_of(res.x)
    reg = tuple(tuple(pb.registration(res.x, i)) for i in range(len(preps))) if pb.n_reg else ()
    per = [p.valid.size * (2 if p.metric == "points" else 1) for p in preps]
    n_res = int(sum(p.valid.sum() * (2 if p.metric == "points" else 1) for p in preps))
    se = _standard_errors(pb, res, vals, n_res)
    r = pb.residuals(res.x) * np.concatenate([np.full(k, p.sigma) for k, p in zip(per, preps)])
    n_val = sum(p.valid.sum() for p in preps)
    train_rms = math.sqrt(float(np.sum(r**2)) / max(n_val, 1))
    return Calibration(cause=model, values=vals, se=se, train_rms=train_rms, cost=float(res.cost),
                       n_residuals=n_res, success=bool(res.success), message=str(res.message),
                       nfev=int(res.nfev), registration=reg)
