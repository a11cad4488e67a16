"""Diagnosis: what the friction simulation gets wrong, the cause, the extension, the gain.

Given measured experiments (tensions and notch points), :func:`diagnose`
answers four questions about the paper's friction model (Sec. IV-B):

1. **What does the simulation get wrong?** The baseline (the friction
   simulator with ``k_lin``, ``k_mid`` and ``μ_d`` calibrated, models.md) is
   fitted on training experiments and compared with held-out ones
   (cross-validation by experiment). Discrepancy *signatures* are measured:
   error by regime, the extra tension the measured shape holds while
   unloading, hysteresis-loop areas, ``b`` on each branch, the bend left at
   the end of unloading, residuals along the backbone, the spatial pattern
   that no joint configuration explains (free-θ fit residuals against the
   noise), the asymmetry between pull directions, and stalls on the upper
   loading ramp (:func:`loading_stalls`).
2. **What is the cause?** Every candidate of data-format.md is a physical
   extension of the simulator (:data:`CANDIDATES`); each is fitted together
   with the baseline parameters on the training folds and scored on the
   held-out ones. The significance rule treats the residuals of one
   experiment as serially correlated (effective sample size from the lag-1
   autocorrelation of the per-sample log-ratio of squared errors) and measures improvement
   against the noise floor: the squared point error a perfect model would
   leave, ``2 σ_p²`` from the point uncertainty plus the load-cell
   uncertainty ``σ_T`` propagated through the model (:func:`noise_floor`;
   with the paper's ±0.11 N load cells it dominates: about 0.1 mm).
3. **Extend the model**: the chosen candidate refitted on all experiments,
   with standard errors, saved as a parameter TOML that
   ``notchfit simulate --model FILE`` reads.
4. **Measure the gain**: held-out notch-point rms of baseline and extension,
   overall and per regime.

Decision rule (all thresholds are keyword arguments of :func:`diagnose`):

* ``none`` when the baseline's held-out mean squared point error is within
  ``(1 + none_tol)`` of the noise floor;
* otherwise the best candidate by held-out error if it improves on the
  baseline with ``z >= z_crit`` and removes at least ``min_excess_removed``
  of the baseline's excess over the noise floor;
* otherwise ``unexplained``.

The analysis never reads a study's ``truth.json``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from .batch import single_threaded_worker
from .fitting import fit_experiment
from .friction import FrictionParams, simulate
from .io import save_params
from .notches import notch_points, to_plane
from .warp import apply_point_warp, unwarp_points

__all__ = [
    "CANDIDATES",
    "CAUSES",
    "ParamSpec",
    "Prepared",
    "diagnose",
    "diagnose_study",
    "loading_stalls",
    "measured_regimes",
    "prepare_experiment",
]

CAUSES = ("proximal_friction", "static_friction", "joint_hysteresis", "external_load",
          "stiffness_gradient", "calibration_error")
_MM = 1e3


# =============================================================================
# Parameters of the baseline and of each candidate
# =============================================================================
@dataclass(frozen=True)
class ParamSpec:
    """A fitted parameter: bounds, start, whether it is fitted in log space, unit."""

    name: str
    lower: float
    upper: float
    start: float
    log: bool = False
    unit: str = ""
    probes: tuple = ()

    def to_x(self, v: float) -> float:
        return math.log(v) if self.log else v

    def from_x(self, x: float) -> float:
        return math.exp(x) if self.log else x

    @property
    def x_bounds(self) -> tuple[float, float]:
        return (self.to_x(self.lower), self.to_x(self.upper))


BASELINE = (
    ParamSpec("k_lin", 0.05, 5.0, 0.4829, log=True, unit="N m/rad"),
    ParamSpec("k_mid", 0.01, 5.0, 0.25, log=True, unit="N m/rad"),
    ParamSpec("mu_d", 0.0, 0.8, 0.29, unit="-"),
)
#: models.md: μ_s − μ_d held at the paper's 0.01 in the baseline.
BASELINE_MU_EXCESS = 0.01

#: Extension parameters of each cause (data-format.md "Causes").
#: ``probes`` are start values tried (one residual evaluation each) before the
#: least-squares fit starts from the best: the friction models are only
#: piecewise smooth and have local minima along some extension axes.
CANDIDATES: dict[str, tuple[ParamSpec, ...]] = {
    "proximal_friction": (ParamSpec("proximal_beta", 0.0, 1.5, 0.05, unit="-",
                                    probes=(0.02, 0.05, 0.1, 0.2, 0.4)),),
    "static_friction": (ParamSpec("mu_s_excess", 0.0, 0.8, 0.05, unit="-",
                                  probes=tuple(round(0.05 * i, 2) for i in range(17))),),
    "joint_hysteresis": (ParamSpec("hysteresis_torque", 0.0, 0.05, 0.002, unit="N m",
                                   probes=(0.0005, 0.001, 0.002, 0.004, 0.008, 0.016)),),
    "external_load": (ParamSpec("tip_force_x", -3.0, 3.0, 0.0, unit="N", probes=(-0.3, 0.0, 0.3)),
                      ParamSpec("tip_force_z", -3.0, 3.0, 0.0, unit="N", probes=(-0.3, 0.0, 0.3))),
    "stiffness_gradient": (ParamSpec("stiffness_gradient", -0.9, 0.9, 0.0, unit="-",
                                     probes=(-0.5, -0.25, 0.0, 0.25, 0.5)),),
    "calibration_error": (ParamSpec("scale_error", -0.2, 0.2, 0.0, unit="-",
                                    probes=(-0.02, 0.0, 0.02)),
                          ParamSpec("k_radial", -0.02, 0.02, 0.0, unit="-",
                                    probes=(-0.005, 0.0, 0.005)),
                          ParamSpec("warp_center_x", -0.2, 0.2, 0.0, unit="m"),
                          ParamSpec("warp_center_y", -0.2, 0.2, 0.0, unit="m")),
}
#: Bounds of the per-experiment registration corrections fitted with the
#: calibration_error candidate (translation [m], rotation [rad]).
REGISTRATION_BOUNDS = (0.005, 0.005, 0.1)
_WARP = ("scale_error", "k_radial", "warp_center_x", "warp_center_y")
#: Radius that normalises the radial warp coefficient [m] (notchfit.warp).
WARP_RADIUS = 0.01
#: The warp centre is fitted within this distance of the data centroid [m]; with
#: |k_radial| <= 0.02 the warp stays one-to-one within about 70 mm of its centre.
WARP_CENTER_RANGE = 0.03


def _specs(cause: str | None) -> tuple[ParamSpec, ...]:
    return BASELINE + (CANDIDATES[cause] if cause else ())


# =============================================================================
# Measured data, prepared once
# =============================================================================
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
        +1 when the right cable is the ramped one (bends toward +θ), -1 left.
    regime : ndarray of str, shape (S,)
        I / II / III from the measured data (:func:`measured_regimes`).
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
        return self.tension_right if self.pulled > 0 else self.tension_left

    @property
    def tip_angle(self) -> np.ndarray:
        """Measured tip angle ``Σθ`` toward the pulled side [rad] (S,)."""
        return self.pulled * self.theta_free.sum(axis=1)


def measured_regimes(pulled_tension, tip_angle, *, hold_fraction: float = 0.2) -> np.ndarray:
    """Regime of each sample from the data (Sec. IV intro, Fig. 11).

    I (loading) up to the peak of the pulled tension; after it II (holding)
    while the tip angle has lost less than ``hold_fraction`` of its drop from
    the peak to its lowest later value, then III (releasing).

    Parameters
    ----------
    pulled_tension, tip_angle : array_like, shape (S,) [N, rad]
        Tip angle signed toward the pulled side.

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
    pulled = 1 if np.ptp(tr) >= np.ptp(tl) else -1
    counter = float(np.median(tl if pulled > 0 else tr))
    a, b, _, _ = fit.ab("linear")
    tip = pulled * np.nansum(theta, axis=1)
    regime = measured_regimes(tr if pulled > 0 else tl, tip)
    return Prepared(name=exp.name, geom=geom, time=exp.time, tension_left=tl, tension_right=tr,
                    measured=Q, valid=valid, transform=fit.transform, sigma=float(sig),
                    theta_free=theta, free_residuals=resid, a=a, b=b, pulled=pulled,
                    regime=regime, counter_tension=counter,
                    tension_sigma=float(exp.tension_sigma or 0.0))


# =============================================================================
# Prediction and calibration
# =============================================================================
def _split(values: dict) -> tuple[FrictionParams, dict]:
    """Parameter values by name -> (FrictionParams, warp values)."""
    v = dict(values)
    warp = {k: v.pop(k) for k in _WARP if k in v}
    excess = v.pop("mu_s_excess", BASELINE_MU_EXCESS)
    v["mu_s"] = v["mu_d"] + excess
    return FrictionParams(**v), warp


class SimulationCache:
    """Fast-solver joint angles cached by (experiment, inputs, parameters).

    The finite-difference Jacobian of a calibration perturbs warp and
    registration parameters that need no new simulation; the cache makes
    those evaluations cost only the projection.
    """

    def __init__(self, max_items: int = 4096):
        self.max_items = max_items
        self._d: dict = {}

    def theta(self, prep: Prepared, params: FrictionParams, dl: float = 0.0, dr: float = 0.0):
        key = (prep.name, dl, dr, dataclasses.astuple(params))
        th = self._d.get(key)
        if th is None:
            if len(self._d) >= self.max_items:
                self._d.clear()
            th = simulate(prep.time, prep.tension_left + dl, prep.tension_right + dr, params,
                          prep.geom, method="fast").theta
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
    params, warp = _split(values)
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
    """
    _, warp = _split(values)
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

    @property
    def n_params(self) -> int:
        return len(self.values)


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

    Returns
    -------
    Calibration
    """
    cache = cache or SimulationCache()
    specs = _specs(cause)
    k = len(specs)
    start = dict(start or {})
    x0 = np.array([s.to_x(float(np.clip(start.get(s.name, s.start), s.lower, s.upper)))
                   for s in specs])
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

    def values_of(x):
        return {s.name: s.from_x(float(v)) for s, v in zip(specs, x[:k])}

    def fun(x):
        vals = values_of(x)
        out = []
        for i, prep in enumerate(preps):
            reg = x[k + 3 * i:k + 3 * i + 3] if n_reg else None
            P, _ = predict_points(prep, vals, registration=reg, cache=cache)
            r = (P - prep.measured) / prep.sigma
            r[~prep.valid] = 0.0
            out.append(r.ravel())
        return np.concatenate(out)

    starts = [x0]
    probe_idx = [i for i, s in enumerate(specs) if s.probes and s.name not in start]
    if probe_idx:
        # the baseline optimum may have compensated the missing effect (e.g. a soft
        # mid-range rate standing in for a stiffness gradient): probe from it and
        # from the paper's values, and optimise from the best probe of each
        paper = x0.copy()
        for i, s in enumerate(BASELINE):
            paper[i] = s.to_x(s.start)
        starts = []
        for base_x in (x0, paper):
            best = (np.inf, base_x)
            for combo in itertools.product(*(specs[i].probes for i in probe_idx)):
                x = base_x.copy()
                for i, v in zip(probe_idx, combo):
                    x[i] = specs[i].to_x(v)
                cost = float(np.sum(fun(x) ** 2))
                if cost < best[0]:
                    best = (cost, x)
            starts.append(np.clip(best[1], lo, hi))

    res = None
    for xs in starts:
        r = least_squares(fun, xs, bounds=(lo, hi), method="trf", diff_step=diff_step,
                          max_nfev=max_nfev, ftol=ftol, xtol=xtol, x_scale="jac")
        if res is None or r.cost < res.cost:
            res = r
    vals = values_of(res.x)
    reg = tuple(tuple(res.x[k + 3 * i:k + 3 * i + 3]) for i in range(len(preps))) if n_reg else ()
    n_res = int(sum(p.valid.sum() * 2 for p in preps))
    n_samples = int(sum(len(p.time) for p in preps))
    J = res.jac[:, :k]
    dof = max(n_res - len(res.x), 1)
    s2 = 2.0 * res.cost / dof
    cov_x = np.linalg.pinv(J.T @ J) * s2 * max(n_res / max(n_samples, 1), 1.0)
    se = {}
    for i, s in enumerate(specs):
        sx = math.sqrt(max(cov_x[i, i], 0.0))
        se[s.name] = vals[s.name] * sx if s.log else sx
    r = fun(res.x) * np.concatenate([np.full(p.valid.size * 2, p.sigma) for p in preps])
    train_rms = math.sqrt(float(np.sum(r**2)) / max(n_res / 2, 1))
    return Calibration(cause=cause, values=vals, se=se, train_rms=train_rms, cost=float(res.cost),
                       n_residuals=n_res, success=bool(res.success), message=str(res.message),
                       nfev=int(res.nfev), registration=reg)


def noise_floor(prep: Prepared, values: dict, cache: SimulationCache | None = None, *,
                draws: int = 4, seed: int = 0) -> np.ndarray:
    """Expected squared point error of a perfect model, per sample [m²] (S,).

    Point noise gives ``2 σ_p²``. Load-cell noise ``σ_T`` enters through the
    model's input: the tensions the simulator is driven with are the noisy
    measured ones. Its effect is estimated by Monte Carlo: the experiment is
    re-simulated ``draws`` times with independent Gaussian noise of standard
    deviation ``σ_T`` added to every measured tension (seeded
    ``numpy.random.default_rng``), and the mean squared change of the
    predicted points is added. Independent per-sample noise matters more
    than a common offset: a small spurious reversal of the tension makes
    cables stick and changes the friction history.
    """
    floor = np.full(len(prep.time), 2.0 * prep.sigma**2)
    if not prep.tension_sigma or draws < 1:
        return floor
    params, _ = _split(values)
    base = notch_points((cache or SimulationCache()).theta(prep, params), prep.geom)
    rng = np.random.default_rng([seed, len(prep.time), int(1e6 * prep.tension_sigma)])
    acc = np.zeros(len(prep.time))
    for _ in range(draws):
        tl = np.maximum(prep.tension_left + rng.normal(0.0, prep.tension_sigma, len(prep.time)), 0.0)
        tr = np.maximum(prep.tension_right + rng.normal(0.0, prep.tension_sigma, len(prep.time)), 0.0)
        th = simulate(prep.time, tl, tr, params, prep.geom, method="fast").theta
        d2 = np.sum((notch_points(th, prep.geom) - base) ** 2, axis=-1)
        d2[~prep.valid] = np.nan
        acc += np.nanmean(d2, axis=1)
    return floor + acc / draws


# =============================================================================
# Cross-validation
# =============================================================================
def folds_by_experiment(n: int, max_folds: int = 6) -> list[np.ndarray]:
    """Held-out experiment indices of each fold: leave-one-out up to ``max_folds``, else k-fold."""
    if n < 2:
        raise ValueError("diagnosis needs at least two experiments (train and held out)")
    k = min(n, max_folds)
    return [np.arange(n)[i::k] for i in range(k)]


def _fold_task(args):
    preps, train_idx, test_idx, cause, start, kw = args
    cache = SimulationCache()
    train = [preps[i] for i in train_idx]
    cal = calibrate(train, cause, start, cache=cache, **kw)
    preds = {}
    for i in test_idx:
        T = reregister(preps[i], cal.values) if cause == "calibration_error" else None
        P, theta = predict_points(preps[i], cal.values, transform=T, cache=cache)
        preds[int(i)] = (P, theta, noise_floor(preps[i], cal.values, cache))
    return cause, tuple(int(i) for i in test_idx), cal, preds


def _run_tasks(tasks, jobs: int):
    """Run fold tasks here or in ``jobs`` worker processes, native libraries single-threaded
    (the matrices are small: BLAS threads only contend; see :func:`notchfit.batch.single_threaded_worker`)."""
    if jobs <= 1 or len(tasks) <= 1:
        with threadpool_limits(limits=1):
            return [_fold_task(t) for t in tasks]
    # the default start method (fork on Linux): spawn would re-import notchfit in every
    # worker (seconds per pool) and re-run a caller's unguarded script
    with ProcessPoolExecutor(max_workers=jobs, initializer=single_threaded_worker) as ex:
        return list(ex.map(_fold_task, tasks))


@dataclass
class HeldOut:
    """Held-out predictions of one model for every experiment."""

    cause: str | None
    points: dict = field(default_factory=dict)    # exp index -> (S, m, 2)
    theta: dict = field(default_factory=dict)     # exp index -> (S, n)
    floor: dict = field(default_factory=dict)     # exp index -> (S,) noise floor [m²]
    calibrations: list = field(default_factory=list)

    def mean_floor(self) -> float:
        """Mean noise floor over every held-out sample [m²] (:func:`noise_floor`)."""
        return float(np.nanmean(np.concatenate([self.floor[i] for i in sorted(self.floor)])))

    def sample_mse(self, preps) -> list[np.ndarray]:
        """Per experiment, the mean squared point error of each sample [m²] (S,)."""
        out = []
        for i, p in enumerate(preps):
            d2 = np.sum((self.points[i] - p.measured) ** 2, axis=-1)
            d2[~p.valid] = np.nan
            out.append(np.nanmean(d2, axis=1))
        return out


def _effective_n(x: np.ndarray) -> float:
    """Effective number of independent values of a serially correlated series."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 3 or np.var(x) == 0:
        return float(max(n, 1))
    xc = x - x.mean()
    rho = float(np.sum(xc[1:] * xc[:-1]) / np.sum(xc * xc))
    rho = min(max(rho, 0.0), 0.99)
    return float(np.clip(n * (1 - rho) / (1 + rho), 1.0, n))


def paired_z(base_mse: list[np.ndarray], cand_mse: list[np.ndarray]) -> float:
    """z of the mean log-ratio ``ln(mse_base / mse_cand)`` per sample, serial correlation accounted for.

    The log-ratio measures the relative improvement of each held-out sample
    and is not dominated by the few samples with the largest errors (raw
    differences of squared errors are heavy-tailed). Each experiment's
    per-sample values form one series whose effective size is
    ``n (1 − ρ₁)/(1 + ρ₁)`` (lag-1 autocorrelation ρ₁); the variance of the
    pooled mean uses the sum of the effective sizes.
    """
    d = []
    for b, c in zip(base_mse, cand_mse):
        with np.errstate(divide="ignore", invalid="ignore"):
            d.append(np.log(np.asarray(b, float) / np.asarray(c, float)))
    allv = np.concatenate([x[np.isfinite(x)] for x in d])
    if len(allv) < 2:
        return 0.0
    n_eff = sum(_effective_n(x) for x in d)
    sd = float(np.std(allv, ddof=1))
    if sd == 0:
        return math.inf if allv.mean() > 0 else 0.0
    return float(allv.mean() / (sd / math.sqrt(max(n_eff, 1.0))))


def _rms(mse_list, mask_list=None) -> float:
    vals = []
    for i, m in enumerate(mse_list):
        sel = np.isfinite(m) if mask_list is None else (np.isfinite(m) & mask_list[i])
        vals.append(m[sel])
    v = np.concatenate(vals) if vals else np.array([])
    return float(math.sqrt(np.mean(v))) if len(v) else float("nan")


# =============================================================================
# Signatures
# =============================================================================
def _loop_area(T, phi) -> float:
    """Area enclosed by the path (T, φ) closed back to its start [N rad]."""
    T = np.asarray(T, dtype=float)
    phi = np.asarray(phi, dtype=float)
    ok = np.isfinite(T) & np.isfinite(phi)
    T, phi = T[ok], phi[ok]
    if len(T) < 3:
        return 0.0
    return float(0.5 * abs(np.dot(T, np.roll(phi, -1)) - np.dot(phi, np.roll(T, -1))))


def _release_tension(T, phi, regime, level: float = 0.5) -> float:
    """Pulled tension at which the tip angle has lost ``level`` of its unloading drop [N]."""
    k = int(np.argmax(T))
    seg_T, seg_phi = T[k:], phi[k:]
    if len(seg_T) < 2:
        return float("nan")
    drop = seg_phi[0] - np.min(seg_phi)
    if drop <= 0:
        return float("nan")
    target = seg_phi[0] - level * drop
    for s in range(1, len(seg_phi)):
        if seg_phi[s] <= target:
            f = (seg_phi[s - 1] - target) / max(seg_phi[s - 1] - seg_phi[s], 1e-15)
            return float(seg_T[s - 1] + f * (seg_T[s] - seg_T[s - 1]))
    return float("nan")


def loading_stalls(T, tip_measured, tip_predicted, *, min_step: float = 0.01, ratio: float = 0.3,
                   upper: float = 0.5) -> tuple[int, int]:
    """Loading steps on which the measured shape stalled where the model moved.

    A static friction coefficient well above the sliding one (Sec. IV-B
    Step 4) makes a cable break away only when a tension step exceeds
    ``(μ_s − μ_d) N``: with the large normal forces of the upper loading
    ramp some steps move nothing, the next ones catch up. Counted are the
    steps ``k-1 -> k`` with rising pulled tension above ``upper`` times its
    peak on which the predicted tip angle grows by more than ``min_step``
    [rad] (far above the measurement noise) and the measured one by less
    than ``ratio`` of that.

    Parameters
    ----------
    T : ndarray, shape (S,)
        Pulled tension [N].
    tip_measured, tip_predicted : ndarray, shape (S,)
        Tip angle toward the pulled side [rad].

    Returns
    -------
    n_stalled, n_steps : int
    """
    T, tm, tp = (np.asarray(a, dtype=float) for a in (T, tip_measured, tip_predicted))
    up = (np.diff(T) > 0) & (T[1:] > upper * np.nanmax(T))
    dm, dp = np.diff(tm)[up], np.diff(tp)[up]
    big = np.isfinite(dm) & (dp > min_step)
    return int(np.sum(dm[big] < ratio * dp[big])), int(np.sum(big))


def signatures(preps, base: HeldOut, noise: float, *, stall_ratio: float = 0.3) -> list[dict]:
    """Discrepancy signatures of the held-out baseline, with numbers and words.

    ``noise`` is the mean squared point error a perfect model would leave [m²]
    (:func:`noise_floor`); ``stall_ratio`` is passed to :func:`loading_stalls`.
    """
    out = []
    mse = base.sample_mse(preps)
    for reg in ("I", "II", "III"):
        masks = [p.regime == reg for p in preps]
        r = _rms(mse, masks)
        if np.isfinite(r):
            out.append({"signature": f"heldout_rms_regime_{reg}", "value": r * _MM, "unit": "mm",
                        "text": f"held-out baseline notch-point rms in regime {reg} is {r * _MM:.3f} mm "
                                f"(noise floor {math.sqrt(noise) * _MM:.3f} mm)"})
    holds, area_m, area_p, bl, bu, zero, back, front, asym = [], [], [], [], [], [], [], [], []
    n_stall = n_steps = 0
    for i, p in enumerate(preps):
        th_p = base.theta[i]
        tip_m = p.tip_angle
        tip_p = p.pulled * th_p.sum(axis=1)
        T = p.pulled_tension
        rm, rp = _release_tension(T, tip_m, p.regime), _release_tension(T, tip_p, p.regime)
        if np.isfinite(rm) and np.isfinite(rp):
            holds.append(rp - rm)
        area_m.append(_loop_area(T, tip_m))
        area_p.append(_loop_area(T, tip_p))
        ns, nt = loading_stalls(T, tip_m, tip_p, ratio=stall_ratio)
        n_stall, n_steps = n_stall + ns, n_steps + nt
        j = np.arange(1, p.geom.n_joints + 1)
        bp = p.pulled * np.polyfit(j, th_p.T, 1)[0]
        bm = p.pulled * p.b
        load = p.regime == "I"
        unload = ~load
        if load.any():
            bl.append(np.nanmean(bm[load] - bp[load]))
        if unload.any():
            bu.append(np.nanmean(bm[unload] - bp[unload]))
        zero.append(tip_m[-1] - tip_p[-1])
        dth = p.pulled * (p.theta_free - th_p)
        third = max(p.geom.n_joints // 3, 1)
        back.append(np.nanmean(dth[:, :third]))
        front.append(np.nanmean(dth[:, -third:]))
        asym.append(np.nanmean(p.theta_free.sum(axis=1) - th_p.sum(axis=1)))
    if holds:
        v = float(np.mean(holds))
        word = "longer" if v > 0 else "shorter"
        out.append({"signature": "unloading_hold", "value": v, "unit": "N",
                    "text": f"the measured shape holds {abs(v):.2f} N {word} while unloading than the "
                            "baseline predicts (tension at half release, measured vs predicted)"})
    if n_steps:
        out.append({"signature": "loading_stalls", "value": n_stall / n_steps, "unit": "-",
                    "text": f"on {n_stall} of {n_steps} steps of the upper loading ramp the measured shape "
                            f"moved less than {100 * stall_ratio:.0f}% of the baseline's prediction (a cable "
                            "that stuck where the model slides)"})
    am, ap = float(np.mean(area_m)), float(np.mean(area_p))
    ratio = am / ap if ap > 0 else float("inf")
    out.append({"signature": "loop_area_ratio", "value": ratio, "unit": "-",
                "text": f"hysteresis loop (pulled tension vs tip angle) is {am:.3f} N rad measured vs "
                        f"{ap:.3f} N rad predicted (ratio {ratio:.2f})"})
    for name, vals, what in (("b_loading_error", bl, "loading"), ("b_unloading_error", bu, "unloading")):
        if vals:
            v = float(np.mean(vals))
            out.append({"signature": name, "value": v, "unit": "rad",
                        "text": f"on the {what} branch the measured b (θ_j = a + b j, toward the pulled "
                                f"side) differs from the baseline's by {v:+.5f} rad per joint"})
    v = float(np.mean(zero))
    out.append({"signature": "residual_bend", "value": v, "unit": "rad",
                "text": f"after unloading the measured tip angle exceeds the predicted by {v:+.4f} rad "
                        "(toward the pulled side)"})
    vb, vf = float(np.mean(back)), float(np.mean(front))
    out.append({"signature": "backbone_residual", "value": vb - vf, "unit": "rad",
                "text": f"joint-angle error (measured − baseline) is {vb:+.4f} rad on the base third and "
                        f"{vf:+.4f} rad on the tip third"})
    v = float(np.mean(asym))
    out.append({"signature": "direction_asymmetry", "value": v, "unit": "rad",
                "text": f"the tip-angle error has mean {v:+.4f} rad in the manipulator frame over both pull "
                        "directions (a mirror-symmetric model error averages out; a steady load does not)"})
    free_ms = np.nanmean(np.concatenate([np.sum(p.free_residuals**2, -1)[p.valid] for p in preps]))
    point_noise = np.mean([2 * p.sigma**2 for p in preps])
    v = float(math.sqrt(free_ms / point_noise))
    out.append({"signature": "spatial_pattern", "value": v, "unit": "-",
                "text": f"free-θ fits leave a residual {v:.2f}× the noise level: "
                        + ("a pattern across the image that no joint configuration explains" if v > 1.3
                           else "no pattern beyond noise")})
    cts = [p.counter_tension for p in preps]
    ers = [math.sqrt(np.nanmean(m)) for m in mse]
    if len(set(np.round(cts, 6))) > 1:
        c = float(np.corrcoef(cts, ers)[0, 1])
        out.append({"signature": "counter_tension_dependence", "value": c, "unit": "-",
                    "text": f"held-out error correlates with counter-tension at r = {c:+.2f}"})
    return out


def rank_candidates(sigs: list[dict], noise_rms: float) -> list[tuple[str, float, str]]:
    """Order the candidate causes by how well the signatures point to each.

    A heuristic score per cause from the signatures (documented beside
    each rule); it orders the search and the explanation, the held-out test
    decides.

    Returns
    -------
    list of (cause, score, reason)
    """
    s = {d["signature"]: d["value"] for d in sigs}
    hold = s.get("unloading_hold", 0.0)
    loop = s.get("loop_area_ratio", 1.0)
    spat = s.get("spatial_pattern", 1.0)
    asym = abs(s.get("direction_asymmetry", 0.0))
    bend = s.get("residual_bend", 0.0)
    bl = s.get("b_loading_error", 0.0)
    stalls = s.get("loading_stalls", 0.0)
    out = [
        ("calibration_error", 3.0 * max(spat - 1.2, 0.0),
         "free-θ fits leave a spatial residual pattern"),
        ("external_load", 400.0 * asym, "the error does not mirror between pull directions"),
        ("joint_hysteresis", 50.0 * max(bend, 0.0) + 0.2 * max(hold, 0.0),
         "a bend remains after unloading"),
        ("proximal_friction", 0.5 * max(hold, 0.0) + 0.5 * max(loop - 1.0, 0.0),
         "the shape holds longer while unloading and the loop is wider"),
        ("static_friction", 0.4 * max(hold, 0.0) + 0.5 * max(loop - 1.0, 0.0) + 20.0 * stalls,
         "the shape stalls on some loading steps: the cables stick longer than μ_s ≈ μ_d allows"),
        ("stiffness_gradient", 200.0 * abs(bl), "the shape differs along the backbone while loading"),
    ]
    return sorted(out, key=lambda t: -t[1])


# =============================================================================
# The diagnosis
# =============================================================================
@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`; :meth:`to_json` gives data-format.md's ``diagnosis.json``."""

    experiments: tuple
    baseline: Calibration
    baseline_heldout_rms: float
    discrepancies: tuple
    candidates: tuple            # dicts per data-format.md plus extra keys
    cause: str
    explanation: str
    gain: dict
    extended: Calibration | None
    per_regime: dict
    noise_rms: float
    heldout: dict = field(repr=False, default_factory=dict)

    def to_json(self) -> dict:
        ext = None
        if self.extended is not None:
            ext = {"cause": self.extended.cause, "params": self.extended.values,
                   "se": self.extended.se, "train_rms_mm": self.extended.train_rms * _MM}
        return {
            "experiments": list(self.experiments),
            "baseline": {"model": "moses2015", "params": self.baseline.values,
                         "se": self.baseline.se,
                         "fixed": {"mu_s_minus_mu_d": BASELINE_MU_EXCESS, "b": FrictionParams().b,
                                   "v_thr": FrictionParams().v_thr},
                         "heldout_rms_mm": self.baseline_heldout_rms * _MM,
                         "train_rms_mm": self.baseline.train_rms * _MM},
            "noise_rms_mm": self.noise_rms * _MM,
            "discrepancies": list(self.discrepancies),
            "candidates": list(self.candidates),
            "cause": self.cause,
            "explanation": self.explanation,
            "extended_model": ext,
            "gain": self.gain,
            "per_regime_rms_mm": self.per_regime,
        }


def diagnose(experiments, *, jobs: int = 1, max_folds: int = 6, causes=CAUSES,
             none_tol: float = 0.5, z_crit: float = 3.0, min_excess_removed: float = 0.3,
             calibrate_kw: dict | None = None, progress=None) -> tuple[Diagnosis, list[Prepared]]:
    """Diagnose a study (see the module docstring for the rule).

    Parameters
    ----------
    experiments : sequence of notchfit.io.Experiment
        At least two, with notch points.
    jobs : int
        Worker processes for the (model × fold) calibrations.
    max_folds : int
        Leave-one-experiment-out up to this many experiments, else k-fold.
    causes : sequence of str
        Candidates to try (default: all six).
    none_tol : float
        ``none`` when the baseline's held-out mean squared error is below
        ``(1 + none_tol)`` times the noise floor (:func:`noise_floor`).
    z_crit : float
        Significance of a candidate's held-out improvement (see :func:`paired_z`).
    min_excess_removed : float
        Fraction of the baseline's excess over the noise floor a candidate
        must remove.
    calibrate_kw : dict, optional
        Passed to :func:`calibrate`.
    progress : callable, optional
        Called with a short message at each stage.

    Returns
    -------
    Diagnosis, list of Prepared
    """
    say = progress or (lambda msg: None)
    kw = dict(calibrate_kw or {})
    unknown = set(causes) - set(CAUSES)
    if unknown:
        raise ValueError(f"unknown cause(s) {sorted(unknown)}; known: {', '.join(CAUSES)}")
    say("registering measurements and fitting measured shapes")
    preps = [prepare_experiment(e) for e in experiments]
    names = tuple(p.name for p in preps)
    folds = folds_by_experiment(len(preps), max_folds)
    all_idx = np.arange(len(preps))

    say(f"calibrating the baseline on {len(folds)} folds")
    results = _run_tasks([(preps, np.setdiff1d(all_idx, f), f, None, None, kw) for f in folds], jobs)
    base = HeldOut(None)
    for _, test, cal, preds in results:
        base.calibrations.append(cal)
        for i, (P, th, floor) in preds.items():
            base.points[i], base.theta[i], base.floor[i] = P, th, floor
    base_start = [cal.values for _, _, cal, _ in results]

    sigs = signatures(preps, base, base.mean_floor())
    order = [c for c, _, _ in rank_candidates(sigs, math.sqrt(base.mean_floor())) if c in causes]

    say(f"fitting {len(order)} candidate extensions")
    tasks = []
    for cause in order:
        for k, f in enumerate(folds):
            tasks.append((preps, np.setdiff1d(all_idx, f), f, cause, base_start[k], kw))
    held = {c: HeldOut(c) for c in order}
    for cause, test, cal, preds in _run_tasks(tasks, jobs):
        held[cause].calibrations.append(cal)
        for i, (P, th, floor) in preds.items():
            held[cause].points[i], held[cause].theta[i], held[cause].floor[i] = P, th, floor

    base_mse = base.sample_mse(preps)
    base_ms = float(np.nanmean(np.concatenate(base_mse)))
    base_rms = math.sqrt(base_ms)
    # The floor depends on the model's tension sensitivity; a baseline that
    # compensates a missing effect (e.g. too soft) overstates it, so the
    # smaller of the baseline's and the best candidate's floor is used.
    floors = [base.mean_floor()]
    if held:
        best_c = min(held, key=lambda c: np.nanmean(np.concatenate(held[c].sample_mse(preps))))
        floors.append(held[best_c].mean_floor())
    noise = min(floors)
    noise_rms = math.sqrt(noise)
    excess = base_ms - noise
    within_noise = base_ms <= noise * (1.0 + none_tol)

    say("fitting the baseline on all experiments")
    full_base = calibrate(preps, None, base_start[0], **kw)

    cands = []
    for cause in order:
        mse = held[cause].sample_mse(preps)
        ms = float(np.nanmean(np.concatenate(mse)))
        z = paired_z(base_mse, mse)
        removed = (base_ms - ms) / excess if excess > 0 else 0.0
        cals = held[cause].calibrations
        vals = {k: float(np.mean([c.values[k] for c in cals])) for k in cals[0].values}
        n_par = len(_specs(cause))
        n_res = sum(c.n_residuals for c in cals)
        cost = sum(c.cost for c in cals)
        aic = n_res * math.log(max(2 * cost / max(n_res, 1), 1e-300)) + 2 * n_par
        cands.append({"cause": cause, "params": {k: vals[k] for k in (s.name for s in CANDIDATES[cause])},
                      "n_params": len(CANDIDATES[cause]),
                      "train_rms_mm": float(np.mean([c.train_rms for c in cals])) * _MM,
                      "heldout_rms_mm": math.sqrt(ms) * _MM, "aic": aic, "z": z,
                      "excess_removed": removed,
                      "significant": bool(z >= z_crit and removed >= min_excess_removed)})
    best = min(cands, key=lambda c: c["heldout_rms_mm"]) if cands else None
    if within_noise:
        cause = "none"
    elif best is not None and best["significant"]:
        cause = best["cause"]
    else:
        cause = "unexplained"

    extended = None
    if cause in CANDIDATES:
        say(f"fitting the {cause} extension on all experiments")
        extended = calibrate(preps, cause, full_base.values, **kw)
        ext_mse = held[cause].sample_mse(preps)
    else:
        ext_mse = base_mse
    ext_rms = math.sqrt(float(np.nanmean(np.concatenate(ext_mse))))
    per_regime = {}
    for reg in ("I", "II", "III"):
        masks = [p.regime == reg for p in preps]
        rb, re_ = _rms(base_mse, masks), _rms(ext_mse, masks)
        if np.isfinite(rb):
            per_regime[reg] = {"baseline": rb * _MM, "extended": re_ * _MM,
                               "reduction_pct": 100.0 * (rb - re_) / rb if rb > 0 else 0.0}
    gain = {"metric": "heldout_rms_mm", "baseline": base_rms * _MM, "extended": ext_rms * _MM,
            "reduction_pct": 100.0 * (base_rms - ext_rms) / base_rms if base_rms > 0 else 0.0}
    text = _explain(cause, sigs, cands, order, base_rms, noise_rms, none_tol, z_crit,
                    min_excess_removed, rank_candidates(sigs, noise_rms))
    diag = Diagnosis(experiments=names, baseline=full_base, baseline_heldout_rms=base_rms,
                     discrepancies=tuple(sigs), candidates=tuple(cands), cause=cause,
                     explanation=text, gain=gain, extended=extended, per_regime=per_regime,
                     noise_rms=noise_rms, heldout={"baseline": base, **held})
    return diag, preps


def _explain(cause, sigs, cands, order, base_rms, noise_rms, none_tol, z_crit, min_removed,
             ranking, *, stall_hint: float = 0.05) -> str:
    by = {c["cause"]: c for c in cands}
    lead = (f"The calibrated baseline (the paper's friction model with k_lin, k_mid and μ_d fitted) "
            f"predicts held-out notch points with {base_rms * _MM:.3f} mm rms against a noise floor "
            f"of {noise_rms * _MM:.3f} mm.")
    top = [f"{c} ({why})" for c, sc, why in ranking if sc > 0][:3]
    hint = (" The discrepancy signatures point first to " + "; then ".join(top) + ".") if top else ""
    ranked = sorted(cands, key=lambda c: c["heldout_rms_mm"])
    table = "; ".join(f"{c['cause']} {c['heldout_rms_mm']:.3f} mm (z = {c['z']:.1f})" for c in ranked[:4])
    if cause == "none":
        return (lead + f" That is within {math.sqrt(1 + none_tol):.2f}× the noise: the baseline explains "
                "the data within the measurement uncertainty, so no extension is justified." + hint
                + (f" Held-out rms of the candidates: {table}." if table else ""))
    if cause == "unexplained":
        stalls = next((d["value"] for d in sigs if d["signature"] == "loading_stalls"), 0.0)
        sticky = (f" The measured shape stalls on {100 * stalls:.0f}% of the upper loading steps, the "
                  "mark of static friction well above the sliding friction: when the load-cell noise is "
                  "comparable to the break-away excess, that noise decides which steps break a cable "
                  "away, and no deterministic model predicts these shapes much better from the measured "
                  "tensions (docs/diagnosis.md, 'What it cannot find')." if stalls >= stall_hint else "")
        return (lead + " The excess over noise is significant, but no candidate extension removes "
                f"at least {100 * min_removed:.0f}% of it with z ≥ {z_crit:g} on held-out experiments."
                + hint + sticky + f" Held-out rms of the candidates: {table}.")
    c = by[cause]
    second = next((r for r in ranked if r["cause"] != cause), None)
    sec = (f" The next best, {second['cause']}, reached {second['heldout_rms_mm']:.3f} mm."
           if second else "")
    return (lead + hint + f" Fitting each candidate with the baseline parameters on the training "
            f"experiments, {cause} lowers the held-out rms to {c['heldout_rms_mm']:.3f} mm "
            f"(z = {c['z']:.1f} for the per-sample improvement with serial correlation accounted for, "
            f"{100 * c['excess_removed']:.0f}% of the excess over noise removed)." + sec
            + " " + _PHYSICS[cause])


_PHYSICS = {
    "proximal_friction": "Physically: friction between the load cell and the manipulator base (sheath, "
                         "pulleys) means the tension reaching the base lags the measured one: a capstan "
                         "band that sticks until the measured tension has changed by a factor e^β.",
    "static_friction": "Physically: the cables stick in their channels longer than μ_s ≈ μ_d allows; a "
                       "larger static coefficient holds the shape while the tension falls.",
    "joint_hysteresis": "Physically: the superelastic Nitinol flexures are hysteretic; each joint holds "
                        "its angle until the torque on it changes by the play width.",
    "external_load": "Physically: a steady force acts on the end effector (payload, gravity, contact); it "
                     "bends both pull directions the same way, breaking the model's mirror symmetry.",
    "stiffness_gradient": "Physically: the joint stiffness varies along the backbone (slot dimensions or "
                          "material), changing the shape's base-to-tip distribution even without friction.",
    "calibration_error": "Physically: the image-to-plane mapping is wrong (scale or lens distortion); a "
                         "warp correction fitted across all samples removes a residual pattern that no "
                         "joint configuration can.",
}


# =============================================================================
# Writing the results
# =============================================================================
def save_extension(diag: Diagnosis, path) -> Path | None:
    """Save the extended (or, for none/unexplained, the baseline) model as a parameter TOML.

    ``notchfit simulate --model FILE`` reads it; the warp of a
    ``calibration_error`` extension is stored as metadata.
    """
    cal = diag.extended or diag.baseline
    params, warp = _split(cal.values)
    meta = {"cause": diag.cause, "source": "notchfit diagnose",
            "se": {k: float(v) for k, v in cal.se.items()}}
    if warp:
        meta["point_warp"] = {**{k: float(v) for k, v in warp.items()}, "radius": WARP_RADIUS}
    return save_params(params, path, **meta)


def diagnose_study(experiments, *, out_dir, jobs: int = 1, seed: int = 0, figures: bool = True,
                   **kw) -> dict:
    """Run :func:`diagnose`, write ``diagnosis.json``, the model TOML and figures into ``out_dir``.

    Parameters
    ----------
    experiments : sequence of notchfit.io.Experiment
    out_dir : path
        An existing (prepared) output directory.
    jobs : int
    seed : int
        Unused by the deterministic fit; recorded for provenance.
    figures : bool
        Write ``diagnosis_*.png``.

    Returns
    -------
    dict
        The content of ``diagnosis.json``.
    """
    from .io import write_json_atomic

    out = Path(out_dir)
    diag, preps = diagnose(experiments, jobs=jobs, **kw)
    data = diag.to_json()
    data["seed"] = seed
    model_path = save_extension(diag, out / "extended_model.toml")
    data["extended_model_file"] = Path(model_path).name if model_path else None
    if figures:
        from .figures.diagnosis import write_diagnosis_figures
        data["figures"] = [Path(p).name for p in write_diagnosis_figures(diag, preps, out)]
    write_json_atomic(data, out / "diagnosis.json")
    return data
