"""Predicted measurements and the calibration of a model on measured experiments.

The friction simulator (Sec. IV-B, fast solver) is driven with the measured
tensions and the experiment's protocol; its joint angles give notch points
(Eqs. 1-3) registered in the plane like the measurements (and, for a
calibration warp, warped), or are compared with measured joint angles
directly. :func:`calibrate` fits the baseline, a candidate or a pair of
candidates (:mod:`notchfit.analysis.diagnosis.specs`) to some experiments: one
:class:`notchfit.analysis.estimation.problem.Problem` of the shared parameters (and,
for a calibration warp, a registration block per experiment), solved by the
estimation core (:mod:`notchfit.analysis.estimation.solve`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..causes import REGISTRY
from ..estimation.bands import gauss_newton_covariance, linear_band
from ..estimation.observations import Observations as Prepared, sample_mse
from ..estimation.problem import Block, Problem, Simulations, measure_registered
from ..estimation.solve import best_probe_starts, forward_jacobian, grid_starts, se_values, solve
from ..fitting import fit_experiment
from ...physics.friction import FrictionParams
from ...vision.warp import apply_camera_plane_warp, unwarp_camera_plane
from .specs import (BASELINE_MU_EXCESS, REGISTRATION_BOUNDS, WARP_CENTER_RANGE, WARP_DISTANCE, WARP_PARAMS,
                    WARP_RADIUS, StudyScales, as_model, baseline_specs, model_params, specs_for)
from .tubes import TUBES, has_tube_unknowns, mean_tubes, tube_blocks, tube_params

__all__ = ["Calibration", "SimulationCache", "attainable_mse", "calibrate", "fold_band", "predict_points",
           "reregister"]

#: The simulations of a calibration, cached (the estimation core's :class:`~notchfit.analysis.estimation.problem.Simulations`).
SimulationCache = Simulations
#: Finite-difference step of the registration corrections [m, m, rad] (standard errors).
REGISTRATION_STEP = 1e-6


def _observed(prep: Prepared, theta, values: dict, registration=None, transform=None) -> np.ndarray:
    """What ``prep`` would measure for ``theta``: its registration (with a correction) and the camera-plane
    warp of ``values`` (:data:`~notchfit.analysis.diagnosis.specs.WARP_PARAMS`: a tilted bending plane in
    perspective, then scale and radial terms), or the angles."""
    if prep.metric == "angles":
        return theta
    P = measure_registered(prep, theta, registration, transform)
    warp = {k: values[k] for k in WARP_PARAMS if k in values}
    if warp:
        s, k, c, tilt = _warp_args(warp)
        P = apply_camera_plane_warp(P, s, k, c, tilt=tilt, radius=WARP_RADIUS, distance=WARP_DISTANCE)
    return P


def _warp_args(warp: dict) -> tuple:
    """``(scale_error, k_radial, centre, tilt)`` of the camera-plane warp values ``warp``
    (:func:`notchfit.vision.warp.apply_camera_plane_warp`; an absent tilt is none)."""
    return (warp.get("scale_error", 0.0), warp.get("k_radial", 0.0), (warp["warp_center_x"], warp["warp_center_y"]),
            (warp.get("plane_tilt_x", 0.0), warp.get("plane_tilt_y", 0.0)))


def _model(base, o, values: dict, tube: dict) -> FrictionParams:
    """The simulator's model of ``values`` (:func:`~notchfit.analysis.diagnosis.specs.model_params`) with the
    tube's rest angles and cut depths (real tubes)."""
    return tube_params(model_params(values, base)[0], tube)


def _measure(o, theta, values: dict, blocks: dict) -> np.ndarray:
    """What ``o`` would measure (its registration block's correction and the point warp included)."""
    return _observed(o, theta, values, blocks.get("registration"))


def predict_points(prep: Prepared, values: dict, *, transform=None, registration=None,
                   cache: Simulations | None = None, base: FrictionParams | None = None, tubes: dict | None = None):
    """Predicted measurements for parameter ``values``: notch points in the plane frame, or joint
    angles for angle data.

    Parameters
    ----------
    prep : Observations
    values : dict
        Model parameters by name (baseline, extension and warp).
    transform : PlaneTransform, optional
        Registration to use instead of ``prep.transform``.
    registration : (dtx [m], dty [m], dphi [rad]), optional
        Correction added to the registration.
    cache : Simulations, optional
    base : FrictionParams, optional
        The model the values change (default: the paper's, Sec. IV-B).
    tubes : dict, optional
        A calibration's per-tube values (:attr:`Calibration.tubes`); a tube not among them keeps its
        geometry's rest angles and depths (a tube never seen by the fit).

    Returns
    -------
    predicted : ndarray, shape (S, m, 2) [m] or (S, n) [rad]
    theta : ndarray, shape (S, n) [rad]
    """
    params = tube_params(model_params(values, base)[0], (tubes or {}).get(prep.tube))
    theta = (cache or Simulations()).theta(prep, params)
    return _observed(prep, theta, values, registration, transform), theta


def attainable_mse(prep: Prepared, params: FrictionParams, *, transform=None, warp: dict | None = None,
                   cache: Simulations | None = None) -> np.ndarray:
    """Per-sample squared error of the generating model itself on ``prep``: the floor no fitted model can
    beat on average where the truth is known (a synthetic study).

    The simulator with the true parameters is driven by the measured (noisy) tensions, like every fitted
    model, its notch points placed by the true registration and seen through the true camera-plane warp;
    what is left is the point noise and the load-cell noise carried through the model (the expectation of
    :func:`~notchfit.analysis.estimation.noise.noise_floor`, here drawn once, as the data drew it).

    Parameters
    ----------
    prep : Observations
    params : FrictionParams
        The true model.
    transform : PlaneTransform, optional
        The true registration (default: ``prep``'s estimated one).
    warp : dict, optional
        The true camera-plane warp: ``scale_error``, ``k_radial`` [-], ``center`` (2,) [m], ``radius`` [m],
        ``tilt`` (2,) [rad], ``distance`` [m] (:func:`notchfit.vision.warp.apply_camera_plane_warp`).
    cache : Simulations, optional

    Returns
    -------
    ndarray (S,) [m² or rad²]
        As :func:`~notchfit.analysis.estimation.observations.sample_mse`.
    """
    theta = (cache or Simulations()).theta(prep, params)
    P = measure_registered(prep, theta, None, transform)
    if warp is not None and prep.metric == "points":
        P = apply_camera_plane_warp(P, warp["scale_error"], warp["k_radial"], warp["center"],
                                    tilt=warp.get("tilt", (0.0, 0.0)), radius=warp["radius"],
                                    distance=warp.get("distance", WARP_DISTANCE))
    return sample_mse(prep, P)

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
        s, k, c, tilt = _warp_args(warp)
        Q = unwarp_camera_plane(prep.measured, s, k, c, tilt=tilt, radius=WARP_RADIUS, distance=WARP_DISTANCE)
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
        Standard errors (:func:`notchfit.analysis.estimation.solve.standard_errors`).
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
    tubes : dict
        Real tubes: ``{tube: {"rest_angle": (n,) [rad], "slot_depth_offset": (n,) [m]}}`` of the tubes
        fitted (identify's per-tube unknowns, :mod:`notchfit.analysis.diagnosis.tubes`); else empty.
    stalled : bool
        The fit ended at its start though its linear model there promised a real decrease
        (:attr:`notchfit.analysis.estimation.solve.Solution.stalled`): its cost is that of a probe, no
        evidence of the model's optimum.
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
    tubes: dict = field(default_factory=dict, repr=False)
    stalled: bool = False

    def start(self) -> dict:
        """The fitted values as a start of another fit: ``values`` and, under ``"tubes"``, :attr:`tubes`."""
        return {**self.values, TUBES: self.tubes} if self.tubes else dict(self.values)

    def params(self, base: FrictionParams | None, tube: str | None = None) -> FrictionParams:
        """The simulator's model of one tube (its rest angles and depths; the geometry's when not fitted)."""
        return tube_params(model_params(self.values, base)[0], self.tubes.get(tube))


def mean_start(cals) -> dict:
    """The mean of several calibrations' optima by parameter name [SI], with their mean per-tube values
    (a start for a fit on every experiment)."""
    out = {k: float(np.mean([c.values[k] for c in cals])) for k in cals[0].values}
    tubes = mean_tubes([c.tubes for c in cals])
    return {**out, TUBES: tubes} if tubes else out


def _aim_point(preps) -> np.ndarray:
    """Where a camera over experiments ``preps`` is aimed [m] (2,): the mean of the straight tube's notch points
    (Eqs. 1-3 at θ = 0) under each experiment's registration.

    The centre of a camera-plane warp is fitted near it. The bent tube's points lean to the side it is
    pulled to: the centroid of the measured points of a training set pulled one way only lies some 10 mm off
    the other's, and a warp centre started and bounded there trades the tilt for a centre at its bound; the
    straight tube lies where it lies whichever way it is pulled.
    """
    return np.mean([measure_registered(p, np.zeros((1, p.geom.n_joints)))[0].mean(axis=0) for p in preps], axis=0)

def _problem(preps, model: tuple, start: dict, cache, scales: StudyScales, base) -> Problem:
    """Start vector and bounds; a real tube's per-tube unknowns and prior (identify's); for a point
    correction the warp centre at the aim point (:func:`_aim_point`) and registrations."""
    geoms = [p.geom for p in preps]
    specs = specs_for(model, base, geoms)
    sc = tuple(scales.factor(s.scale) for s in specs)
    x0 = np.array([s.x_of_spec_value(s.start) if s.name not in start
                   else s.to_x(float(start[s.name]), c) for s, c in zip(specs, sc)])
    lo = np.array([s.x_bounds[0] for s in specs])
    hi = np.array([s.x_bounds[1] for s in specs])
    blocks, prior, offset = (), np.zeros((0, len(specs))), np.zeros(0)
    if has_tube_unknowns(preps):
        k = len(baseline_specs(base, geoms))
        excess = float(start.get("mu_s_excess", BASELINE_MU_EXCESS))
        tb, t0, tlo, thi, tprior, offset = tube_blocks(preps, base, specs[:k], excess, start=start.get(TUBES),
                                               sim_kw=cache.sim_kw)
        blocks = tuple(tb)
        x0, lo, hi = np.r_[x0, t0], np.r_[lo, tlo], np.r_[hi, thi]
        prior = np.hstack([tprior[:, :k], np.zeros((tprior.shape[0], len(specs) - k)), tprior[:, k:]])
    if any(REGISTRY[c].corrects_points for c in model):
        c = _aim_point(preps)
        idx = [i for i, s in enumerate(specs) if s.name in ("warp_center_x", "warp_center_y")]
        if "warp_center_x" not in start:
            x0[idx] = c
        lo[idx], hi[idx] = c - WARP_CENTER_RANGE, c + WARP_CENTER_RANGE
        blocks += tuple(Block("registration", p.name, 3, kind="experiment", step=REGISTRATION_STEP) for p in preps)
        b = np.tile(REGISTRATION_BOUNDS, len(preps))
        x0, lo, hi = np.r_[x0, np.zeros(b.size)], np.r_[lo, -b], np.r_[hi, b]
        prior = np.hstack([prior, np.zeros((prior.shape[0], b.size))])
    x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
    return Problem(tuple(preps), specs, sc, blocks, x0, lo, hi, prior,
                   model=partial(_model, base), measure=_measure,
                   sims=cache, prior_offset=offset)


def calibrate(preps, cause=None, start: dict | None = None, *,
              diff_step: float = 2e-3, max_nfev: int = 60, ftol: float = 1e-3,
              xtol: float = 1e-3, cache: Simulations | None = None,
              scales: StudyScales | None = None, base: FrictionParams | None = None,
              paper_start: bool = True, keep_start: float = math.inf, errors: bool = True,
              tube_starts: int = 2, tube_tol: float = 1e-6, secant: int = 0) -> Calibration:
    """Fit the baseline (``cause=None``), a candidate or a pair of candidates on experiments ``preps``.

    Bounded least squares (:func:`notchfit.analysis.estimation.solve.solve`) on the
    measurement residuals (notch points or joint angles) normalised by σ,
    scipy's finite-difference Jacobian with a relative step ``diff_step``
    large enough to step over the stick/slip switching of the simulator.
    Positive stiffnesses are fitted in log space, the tube-sized parameters
    in units of the study's scales. The extension parameters without a start
    value start from the best of their ``probes`` (each one residual
    evaluation), with the baseline parameters at ``start`` and at the base
    model's values; the fit runs from the best probe of each and keeps the
    lower cost (:func:`notchfit.analysis.estimation.solve.best_probe_starts`). A
    candidate that corrects the points (a calibration warp) also fits a
    registration correction per experiment (the registration was estimated
    from the uncorrected points). Standard errors: the estimation core's one
    rule (:func:`notchfit.analysis.estimation.solve.standard_errors`).

    Parameters
    ----------
    preps : sequence of Observations
    cause : None, str or sequence of str
        The model (:func:`notchfit.analysis.diagnosis.specs.as_model`).
    start : dict, optional
        Start values by name (e.g. the baseline optimum, or a single cause's
        fit for a pair); the spec's start for the rest.
    diff_step, max_nfev, ftol, xtol : float, int
        Passed to ``scipy.optimize.least_squares``.
    cache : Simulations, optional
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
    errors : bool
        Compute the standard errors (False for the cross-validation's fold fits, whose errors are not
        reported: NaN).
    tube_starts, tube_tol :
        Real tubes (per-tube unknowns, :mod:`notchfit.analysis.diagnosis.tubes`): the baseline without a
        start runs from the best ``tube_starts`` of the material's probe grid, as identify does; every fit
        uses forward differences with the unknowns' own steps, and ``ftol``, ``xtol`` at most ``tube_tol``
        (identify's; the per-tube unknowns move the cost little each, and a fit stopped early would leave
        the baseline an error a candidate then removes).
    secant : int
        Broyden rank-one Jacobian updates allowed in a row between finite differences
        (:func:`notchfit.analysis.estimation.solve.solve`; 0: differences at every accepted point).

    Returns
    -------
    Calibration
    """
    start = dict(start or {})
    model = as_model(cause)
    base = base or FrictionParams()
    pb = _problem(preps, model, start, cache or Simulations(), scales or StudyScales.of(preps, base), base)
    paper = pb.x0.copy()
    for i, s in enumerate(baseline_specs(base, [p.geom for p in preps])):
        paper[i] = s.x_of_spec_value(s.start)
    tubes = any(b.kind == "tube" for b in pb.blocks)
    nprobe = 0
    if tubes and not model and TUBES not in start:
        # identify's calibration: the best starts of the material's probe grid
        starts, nprobe = grid_starts(pb, tube_starts)
    else:
        starts = best_probe_starts(pb, _bases(pb.x0, paper, paper_start), skip=start, keep=keep_start)
    # per-tube unknowns need their own finite-difference steps (Problem.steps): a relative step of a
    # cut-depth offset of a few micrometres would be no step at all
    sol = solve(pb, starts, jac="forward" if tubes else "2-point", diff_rel=diff_step, max_nfev=max_nfev,
                ftol=min(ftol, tube_tol) if tubes else ftol, xtol=min(xtol, tube_tol) if tubes else xtol,
                errors=errors, nfev=nprobe, secant=secant)
    vals = pb.values(sol.x)
    regs = pb.block_values(sol.x, "experiment")
    reg = tuple(tuple(regs[p.name]["registration"]) for p in preps) if regs else ()
    sigma = np.concatenate([np.full(p.valid.size * p.values_per_item, p.sigma) for p in preps])
    r = pb.residuals(sol.x)[:sigma.size] * sigma               # the prior's rows left out
    n_val = sum(p.valid.sum() for p in preps)
    train_rms = math.sqrt(float(np.sum(r**2)) / max(n_val, 1))
    return Calibration(cause=model, values=vals, se=se_values(pb, sol.x, sol.se), train_rms=train_rms,
                       cost=sol.cost, n_residuals=sol.n_residuals, success=sol.success, message=sol.message,
                       nfev=sol.nfev, registration=reg, tubes=pb.tube_values(sol.x), stalled=sol.stalled)


def _bases(x0, paper, paper_start: bool) -> tuple:
    """The starts probed around: ``x0`` and, when asked and different, the base model's values."""
    return (x0, paper) if paper_start and not np.array_equal(x0, paper) else (x0,)


def _tension_sandwich(pb: Problem, x, J: np.ndarray, C: np.ndarray, *, step: float = 1.0) -> np.ndarray:
    """The parameters' covariance with the training trials' load-cell noise: ``C (C⁻¹ + Σ_s g_s g_sᵀ) C``.

    The fit is least squares weighted by the measurement σ alone (``C = (JᵀJ + P)⁻¹``, ``P`` the prior's
    information), but the residuals also carry the noise of the measured tensions the simulator is driven
    with: sample ``s`` of a trial moves by ``v_s = σ_T ∂y_s/∂T`` (whitened). For a misweighted least-squares
    fit the parameters' covariance is the sandwich ``C (Jᵀ Σ J + P) C`` with ``Σ = I + Σ_s v_s v_sᵀ``, so
    ``g_s = J_sᵀ v_s`` over that sample's rows. ``v_s`` is the response to a common offset of ``step σ_T`` on
    every sample of the trial's tendon, one run per trial and tendon: each sample's own slope where the
    response has no memory (a wrist loading along its superelastic curve), the slope to an offset where
    friction remembers the history (an approximation there).

    Parameters
    ----------
    pb : Problem
        The fold's training problem; ``x`` its optimum.
    J : ndarray (r, p)
        Its whitened Jacobian at ``x`` (the prior's rows included).
    C : ndarray (p, p)
        ``(JᵀJ + P)⁻¹`` (:func:`~notchfit.analysis.estimation.bands.gauss_newton_covariance`).
    step : float
        The offset, in load-cell σ.
    """
    r0, rows = pb.residuals(x), pb.clusters()
    seen = rows >= 0
    extra = np.zeros_like(C)
    for side in ("left", "right"):
        moved = tuple(dataclasses.replace(o, **{f"tension_{side}": getattr(o, f"tension_{side}") + step * o.tension_sigma})
                      if side in o.geom.tendons and o.tension_sigma > 0 else o for o in pb.obs)
        if all(m is o for m, o in zip(moved, pb.obs)):
            continue
        v = (dataclasses.replace(pb, obs=moved).residuals(x) - r0) / step       # whitened, per σ_T
        g = np.zeros((int(rows.max()) + 1, J.shape[1]))
        np.add.at(g, rows[seen], J[seen] * v[seen, None])
        extra += g.T @ g
    return C + C @ extra @ C


def fold_band(train, cal: Calibration, test, *, cache: Simulations | None = None,
              scales: StudyScales | None = None, base: FrictionParams | None = None,
              diff_step: float = 2e-3, bound_prior: bool = True, tension_noise: bool = True) -> list[np.ndarray]:
    """The prediction variance of a baseline fold's held-out experiments, per sample [m² or rad²].

    The fold's fit knows its parameters ``x`` up to ``C = (JᵀJ)⁻¹``, ``J`` the whitened training
    residuals' Jacobian at the optimum (the known noise and the per-tube priors only: a model that
    misfits does not widen its own band, :func:`~notchfit.analysis.estimation.bands.gauss_newton_covariance`),
    widened by the training trials' load-cell noise (``tension_noise``, :func:`_tension_sandwich`);
    a held-out prediction moves with ``x`` by ``J_h``, so its variance is ``diag(J_h C J_hᵀ)``
    (:func:`~notchfit.analysis.estimation.bands.linear_band`). Both Jacobians are the estimation core's
    forward differences (:func:`~notchfit.analysis.estimation.solve.forward_jacobian`) with its steps
    (:meth:`~notchfit.analysis.estimation.problem.Problem.steps`): ``p + 1`` runs of the training
    experiments and of the held-out ones. A held-out trial the training trials must extrapolate to (the
    heaviest) gets a wide band where the training trials pin its parameters poorly.

    Parameters
    ----------
    train, test : sequence of Observations
        The fold's training and held-out experiments.
    cal : Calibration
        The baseline fitted on ``train`` (``cal.cause == ()``).
    cache, scales, base :
        As :func:`calibrate`'s.
    diff_step : float
        Relative step of the shared parameters (:func:`calibrate`'s ``diff_step``).
    bound_prior : bool
        Each parameter also known to lie within its fit bounds (a uniform prior's σ, ``(hi − lo)/√12``): a
        parameter the training trials do not move at all (``wrist_tip_first``'s E_se and strain_lower, whose
        plateau its lighter trials never reach) gets that spread instead of none (False: the data's own
        information only, the pseudo-inverse's zero for such a direction).
    tension_noise : bool
        The training trials' load-cell noise in ``C`` too (:func:`_tension_sandwich`): the fit weighs its
        residuals by the point or angle σ alone, while on a wrist's superelastic snap the noise of the
        measured tension moves a sample ten times more (False: the measurement noise only).

    Returns
    -------
    list of ndarray (S_i,)
        Per held-out experiment, the mean over its measured points (the squared distance's
        variance, both coordinates) or angles of the prediction variance, as
        :func:`~notchfit.analysis.estimation.observations.sample_mse` averages a squared error.
    """
    if cal.cause:
        raise ValueError("fold_band bands the baseline only")
    base = base or FrictionParams()
    pb = _problem(tuple(train), (), cal.start(), cache or Simulations(), scales or StudyScales.of(train, base), base)
    x = pb.x0                                        # the fold's optimum, as the fit's start
    h = pb.steps(x, diff_step)
    prior_sd = (pb.hi - pb.lo) / math.sqrt(12.0) if bound_prior else None
    J = forward_jacobian(pb, x, h)
    C = gauss_newton_covariance(J, prior_sd)
    if tension_noise:
        C = _tension_sandwich(pb, x, J, C)
    # the held-out experiments under the same unknowns (a tube not trained on keeps its drawing's values)
    held = dataclasses.replace(pb, obs=tuple(test), prior=np.zeros((0, x.size)), prior_offset=None)
    Jh = forward_jacobian(held, x, h)
    out, row = [], 0
    for i, o in enumerate(test):
        k = o.measured.size
        pred = held.predicted(i, x)[0]
        band = linear_band(pred, Jh[row:row + k] * o.sigma, C)          # un-whitened: [m or rad] per x
        row += k
        out.append(sample_mse(o, o.measured + band.sd))                  # the mean variance per sample
    return out
