"""The least-squares problem of an identification: its unknowns, priors and solution.

The problem is the estimation core's (:class:`notchfit.analysis.estimation.problem.Problem`):
the scalar free parameters shared by every tube (log scale for moduli, rates
and thresholds), then per tube its rest angles [rad] and cut-depth offsets [m]
(:class:`~notchfit.analysis.estimation.problem.Block`), with a zero-mean Gaussian prior
of the cutting tolerance on the offsets. Residuals: each experiment simulated
under its tube's model (Sec. IV-B, fast solver) against its observations —
joint angles ``(θ_sim − θ_meas)/σ_θ`` where measured, or notch points
``(Q̃ − Q)/σ_p`` registered in the plane (Sec. IV-A) — stacked.

What identify adds here are its tube rules: where the rest angles start
(:func:`_rest_start`: from the samples taken at rest), how far they and the
cut depths may move, and the depth prior. :func:`solve` runs the core's
multi-start least squares from the best of the probe grid
(:func:`notchfit.analysis.estimation.solve.grid_starts`) with the core's standard errors.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from ...physics.friction import FrictionParams
from ...physics.geometry import Geometry
from ..estimation.observations import angle_residuals, zero_tension_samples
from ..estimation.problem import Block, Problem, Simulations, measure_registered, predict, whitened, with_values
from ..estimation.solve import Solution, grid_starts, standard_errors
from ..estimation.solve import solve as solve_problem
from .specs import DEPTH_TOLERANCE, REST_SIGMA_GEOMETRY, REST_SIGMA_MIN

__all__ = ["Problem", "Solution", "errors", "make_problem", "predict", "solve", "standard_errors", "steps",
           "whitened", "with_values"]

#: Finite-difference step of the cut-depth offsets [m].
DEPTH_STEP = 2e-7


def errors(o, theta: np.ndarray) -> np.ndarray:
    """Unweighted errors of the measured values [rad or m]: angle residuals, or point distances."""
    if o.metric == "angles":
        r = angle_residuals(theta, o.measured)
        return r[np.isfinite(r)]
    d = np.linalg.norm(measure_registered(o, theta) - o.measured, axis=-1)
    return d[o.valid]


def _tube_model(base: dict, excess: float, o, values: dict, tube: dict):
    """The model of experiment ``o``: its tube's base model with the shared ``values`` and the tube's
    rest angles and cut-depth offsets (``tube``)."""
    return with_values(base[o.tube], values, excess, **tube)


def _rest_measurements(obs, tube, base, sim_kw) -> list:
    """Per experiment of ``tube`` with samples at rest before the first load (:func:`zero_tension_samples`):
    ``(mean, count, sigma)`` — the mean misfit of those samples per joint [rad] (the measured angles less the
    prediction of ``base``, whose small deflection at rest is so taken out), how many measured each joint,
    and the experiment's angle σ [rad] (NaN for notch points: their angles have no stated σ)."""
    out = []
    for o in obs:
        if o.tube != tube:
            continue
        idx = zero_tension_samples(o)
        if not idx.size:
            continue
        d = o.theta_free[idx] - predict(o, base, sim_kw)[idx]
        ok = np.isfinite(d)
        count = ok.sum(axis=0)
        mean = np.where(count > 0, np.where(ok, d, 0.0).sum(axis=0) / np.maximum(count, 1), np.nan)
        out.append((mean, count, o.sigma if o.metric == "angles" else np.nan))
    return out


def _rest_start(obs, tube, base, sim_kw) -> np.ndarray:
    """Rest angles to start from: the geometry's (or the base model's), moved by the mean misfit of the
    samples taken at rest before the first load (:func:`zero_tension_samples`), where the prediction's
    small deflection is taken out."""
    geom = next(o.geom for o in obs if o.tube == tube)
    rest0 = base.rest_angles(geom)
    trials = _rest_measurements(obs, tube, base, sim_kw)
    if not trials:
        return rest0
    sums = sum(np.nan_to_num(m) * c for m, c, _ in trials)
    counts = sum(c for _, c, _ in trials)
    return rest0 + np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)


def _rest_prior(obs, tube, base, sim_kw, *, geometry_sigma: float = REST_SIGMA_GEOMETRY,
                min_sigma: float = REST_SIGMA_MIN) -> tuple[np.ndarray, np.ndarray]:
    """The prior of one tube's rest angles: mean and standard deviation per joint [rad] (n,), (n,).

    The rest angle is a measurement: the angles of the tube's own trials at zero force
    (:func:`_rest_measurements`), averaged over the trials, with the larger of two
    standard errors — the angle noise over all those samples (``σ_θ / √N``) and the
    trial-to-trial scatter of the trials' means (``s / √T``, two trials or more) — and
    at least ``min_sigma``. A joint no trial measured at rest is tied to the geometry
    file's (or the base model's) rest angle with ``geometry_sigma``.
    """
    geom = next(o.geom for o in obs if o.tube == tube)
    rest0 = base.rest_angles(geom)
    mean, sigma = rest0.copy(), np.full(rest0.shape, float(geometry_sigma))
    trials = _rest_measurements(obs, tube, base, sim_kw)
    if not trials:
        return mean, sigma
    M = np.array([m for m, _, _ in trials])                    # (T, n) per-trial mean misfits
    C = np.array([c for _, c, _ in trials], dtype=float)
    noise = np.array([sg for _, _, sg in trials])
    n_tot = C.sum(axis=0)
    has = n_tot > 0
    mean[has] = rest0[has] + (np.nansum(np.nan_to_num(M) * C, axis=0)[has] / n_tot[has])
    # noise: the trials' stated σ (angles), or, for angles from notch points, the spread of the rest samples
    sig_theta = float(np.nanmax(noise)) if np.isfinite(noise).any() else np.nan
    sem_noise = sig_theta / np.sqrt(np.maximum(n_tot, 1)) if np.isfinite(sig_theta) else np.zeros_like(n_tot)
    T = np.isfinite(M).sum(axis=0)
    sem_trials = np.zeros(rest0.shape)
    for j in np.flatnonzero(T >= 2):
        v = M[np.isfinite(M[:, j]), j]
        sem_trials[j] = v.std(ddof=1) / np.sqrt(v.size)
    sem = np.maximum(np.maximum(sem_noise, sem_trials), min_sigma)
    if not np.isfinite(sig_theta):                             # points with a single trial: no σ measured
        sem = np.where(T >= 2, sem, geometry_sigma)
    sigma[has] = sem[has]
    return mean, sigma


def _depth_block(geom, depth_range: float, min_wall: float):
    """Bounds of one tube's cut-depth offsets [m]: ``±depth_range``, the cut kept inside the tube."""
    g = geom.slot_depths
    lo = np.maximum(-depth_range, -0.5 * g)
    hi = np.minimum(depth_range, 2.0 * geom.outer_radius - min_wall - g)
    return lo, hi


@dataclass(frozen=True)
class _Tube:
    """One tube of a problem: its label, geometry, base model and the model at the specs' starts."""

    name: str
    geom: Geometry
    base: FrictionParams
    start: FrictionParams


@dataclass(frozen=True)
class _TubeRules:
    """How far each tube's rest angles and cut-depth offsets may move, and their priors
    (:func:`make_problem`'s keywords of the same names)."""

    rest_range: float
    closure_margin: float
    rest_prior: bool
    rest_sigma_geometry: float
    rest_sigma_min: float
    rest_step: float
    depth_range: float
    depth_sigma: float | None
    depth_common: float | None
    min_wall: float


def _rest_unknowns(obs, tube: _Tube, rules: _TubeRules, sim_kw, offset: int):
    """One tube's rest angles: start, bounds, prior rows ``(indices, weights, mean, σ)`` and block, the first
    at ``offset`` of ``x``."""
    g, n = tube.geom, tube.geom.n_joints
    ref, cap = tube.base.rest_angles(g), rules.closure_margin * g.closure_angles
    lo, hi = np.maximum(ref - rules.rest_range, -cap), np.minimum(ref + rules.rest_range, cap)
    rows = []
    if rules.rest_prior:
        centre, sig = _rest_prior(obs, tube.name, tube.start, sim_kw, geometry_sigma=rules.rest_sigma_geometry,
                                  min_sigma=rules.rest_sigma_min)
        x0 = list(np.clip(centre, lo, hi))
        rows = [([offset + j], 1.0, float(centre[j]), float(sig[j])) for j in range(n)]
    else:
        x0 = list(np.clip(_rest_start(obs, tube.name, tube.start, sim_kw), lo, hi))
    return x0, list(lo), list(hi), rows, Block("rest_angle", tube.name, n, step=rules.rest_step)


def _depth_unknowns(tube: _Tube, rules: _TubeRules, offset: int):
    """One tube's cut-depth offsets: start (0), bounds, prior rows ``(indices, weights, mean, σ)`` (per notch,
    and the tube's mean) and block, the first at ``offset`` of ``x``."""
    g, n = tube.geom, tube.geom.n_joints
    sigma = rules.depth_sigma if rules.depth_sigma is not None else (g.slot_depth_tolerance or DEPTH_TOLERANCE)
    lo, hi = _depth_block(g, max(rules.depth_range, 4.0 * sigma), rules.min_wall)
    rows = [([offset + j], 1.0, 0.0, sigma) for j in range(n)]
    if rules.depth_common is not None:
        rows.append((list(range(offset, offset + n)), 1.0 / n, 0.0, rules.depth_common))    # the tube's mean offset
    return [0.0] * n, list(lo), list(hi), rows, Block("slot_depth_offset", tube.name, n, step=DEPTH_STEP)


def _tube_block_rows(obs, tube: _Tube, *, rest: bool, depth: bool, sim_kw, rules: _TubeRules, offset: int):
    """One tube's unknowns (its rest angles with ``rest``, its cut-depth offsets with ``depth``): start,
    bounds, prior rows ``(indices, weights, mean, σ)`` and blocks, its first unknown at ``offset`` of ``x``."""
    parts = []
    if rest:
        parts.append(_rest_unknowns(obs, tube, rules, sim_kw, offset))
    if depth:
        parts.append(_depth_unknowns(tube, rules, offset + sum(len(p[0]) for p in parts)))
    x0, lo, hi, rows = ([v for p in parts for v in p[i]] for i in range(4))
    return x0, lo, hi, rows, [p[4] for p in parts]


def make_problem(obs, base: dict, specs, *, rest: bool = False, depth: bool = False, excess: float,
                 sim_kw: dict | None = None, rest_range: float = 0.2, closure_margin: float = 0.9,
                 depth_range: float = 60e-6, depth_sigma: float | None = None, depth_common: float | None = 2e-6,
                 min_wall: float = 20e-6, rest_step: float = 2e-4, rest_prior: bool = True,
                 rest_sigma_geometry: float = REST_SIGMA_GEOMETRY, rest_sigma_min: float = REST_SIGMA_MIN) -> Problem:
    """Build the problem of fitting ``specs`` (and each tube's rest angles and cut depths) to ``obs``.

    Each tube's unknowns carry Gaussian priors, whitened residual rows ``(a·x − mean)/σ``
    after the experiments' (:attr:`Problem.prior`, :attr:`Problem.prior_offset`).

    Parameters
    ----------
    base : dict
        Tube -> base FrictionParams; the tubes not in ``obs`` are ignored.
    rest, depth : bool
        Fit each tube's rest angles and its per-notch cut-depth offsets (from 0).
    rest_range : float
        Rest angles move at most this far from the geometry's [rad] ...
    closure_margin : float
        ... and stay within this fraction of each slot's closure angle.
    rest_prior : bool
        Tie each tube's rest angles to their measurement (:func:`_rest_prior`: the angles of its
        trials at zero force, with their standard error; else the geometry's with
        ``rest_sigma_geometry``) and start from it; False: free within their bounds, started
        from :func:`_rest_start`.
    rest_sigma_geometry, rest_sigma_min : float
        Prior σ of a rest angle no trial measured at rest, and the smallest prior σ [rad].
    depth_range, min_wall : float
        Cut-depth offsets: bound (at least 4 prior σ) and the thinnest wall left [m].
    depth_sigma : float or None
        Prior standard deviation of each offset [m]; None: each tube's geometry
        ``slot_depth_tolerance`` (``slot_depth_tolerance_mm``), else
        :data:`~notchfit.analysis.identify.specs.DEPTH_TOLERANCE` (15 µm).
    rest_step : float
        Finite-difference step of the rest angles [rad].
    depth_common : float or None
        Prior standard deviation of a tube's mean offset [m] (None: only the per-notch
        prior). Small by default: a depth error common to a tube's notches is a
        stiffness scale, which the shared material cannot tell from the tube's;
        the per-notch offsets then carry only the notch-to-notch variation.
    """
    tubes = list(dict.fromkeys(o.tube for o in obs))
    geoms = {t: next(o.geom for o in obs if o.tube == t) for t in tubes}
    base = {t: base[t] for t in tubes}
    x0 = [s.to_x(float(np.clip(s.start, s.lower, s.upper))) for s in specs]
    lo = [s.x_bounds[0] for s in specs]
    hi = [s.x_bounds[1] for s in specs]
    rows = []
    start_params = {t: with_values(base[t], {s.name: s.start for s in specs}, excess) for t in tubes}
    blocks = []
    rules = _TubeRules(rest_range, closure_margin, rest_prior, rest_sigma_geometry, rest_sigma_min, rest_step,
                       depth_range, depth_sigma, depth_common, min_wall)
    for t in tubes:
        x_t, lo_t, hi_t, rows_t, blocks_t = _tube_block_rows(
            obs, _Tube(t, geoms[t], base[t], start_params[t]), rest=rest, depth=depth, sim_kw=sim_kw,
            rules=rules, offset=len(x0))
        x0, lo, hi, rows, blocks = x0 + x_t, lo + lo_t, hi + hi_t, rows + rows_t, blocks + blocks_t
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x0 = np.clip(np.asarray(x0, float), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    prior = np.zeros((len(rows), x0.size))
    offset = np.zeros(len(rows))
    for r, (idx, weight, mean, sigma) in enumerate(rows):
        prior[r, idx] = weight / sigma                # one unknown, or a block's mean, over its σ
        offset[r] = mean / sigma
    excess = float(excess)
    return Problem(tuple(obs), tuple(specs), (1.0,) * len(specs), tuple(blocks), x0, lo, hi, prior,
                   model=partial(_tube_model, base, excess), sims=Simulations(sim_kw), prior_offset=offset)


def steps(pb: Problem, x, diff_rel: float = 2e-3, rest_step: float = 2e-4):
    """The forward-difference steps of :func:`solve` at ``x`` (:meth:`Problem.steps`)."""
    return pb.steps(x, diff_rel, {"rest_angle": rest_step})


def solve(pb: Problem, *, n_starts: int = 2, loss: str = "linear", f_scale: float = 3.0,
          max_nfev: int = 100, ftol: float = 1e-6, xtol: float = 1e-6, diff_rel: float = 2e-3,
          rest_step: float = 2e-4, grid: bool = True, starts=(), errors: bool = True, jacobian0=None) -> Solution:
    """Minimise the problem's cost from the best ``n_starts`` of its probe grid (the core's
    :func:`~notchfit.analysis.estimation.solve.solve`, forward differences).

    Parameters
    ----------
    n_starts : int
        Least-squares runs, from the best probes.
    loss, f_scale :
        ``scipy.optimize.least_squares`` loss (``"soft_l1"`` etc. for outliers)
        and its scale [σ].
    max_nfev, ftol, xtol :
        Per run.
    diff_rel : float
        Finite-difference step: relative for the parameters (their log for log-scale ones).
    rest_step : float
        Finite-difference step of the rest angles [rad].
    grid : bool
        Start from the best of the probe grid; False: one run from the problem's start (a warm
        start, e.g. a held-out refit from the fit on every experiment).
    starts : sequence of ndarray
        Further starts (optimiser coordinates), each one more run.
    errors : bool
        Compute the standard errors (and the Jacobian); False for a fit whose errors nobody reads.
    jacobian0 : ndarray, optional
        The Jacobian at the first start when known (a warm start at an earlier fit's optimum,
        :func:`notchfit.analysis.identify.study.identify`): its run does not compute it.
    """
    first, nprobe = grid_starts(pb, n_starts) if grid else ([pb.x0], 0)
    starts = list(first) + [np.asarray(x, float) for x in starts]
    return solve_problem(pb, starts, jac="forward", loss=loss, f_scale=f_scale, max_nfev=max_nfev, ftol=ftol,
                         xtol=xtol, diff_rel=diff_rel, block_steps={"rest_angle": rest_step}, nfev=nprobe,
                         errors=errors, jacobian0=jacobian0)
