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

from functools import partial

import numpy as np

from ..estimation.observations import angle_residuals, zero_tension_samples
from ..estimation.problem import Block, Problem, Simulations, measure_registered, predict, whitened, with_values
from ..estimation.solve import Solution, grid_starts, standard_errors
from ..estimation.solve import solve as solve_problem

__all__ = ["Problem", "Solution", "errors", "make_problem", "predict", "solve", "standard_errors", "whitened",
           "with_values"]

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


def _rest_start(obs, tube, base, sim_kw) -> np.ndarray:
    """Rest angles to start from: the geometry's (or the base model's), moved by the mean misfit of the
    samples taken at rest before the first load (:func:`zero_tension_samples`), where the prediction's
    small deflection is taken out."""
    geom = next(o.geom for o in obs if o.tube == tube)
    rest0 = base.rest_angles(geom)
    diffs = []
    for o in obs:
        if o.tube != tube:
            continue
        idx = zero_tension_samples(o)
        if idx.size:
            th = predict(o, base, sim_kw)[idx]
            diffs.append(o.theta_free[idx] - th)
    if not diffs:
        return rest0
    d = np.concatenate(diffs)
    shift = np.where(np.isfinite(d).any(axis=0), np.nanmean(np.where(np.isfinite(d), d, np.nan), axis=0), 0.0)
    return rest0 + np.nan_to_num(shift)


def _depth_block(geom, depth_range: float, min_wall: float):
    """Bounds of one tube's cut-depth offsets [m]: ``±depth_range``, the cut kept inside the tube."""
    g = geom.slot_depths
    lo = np.maximum(-depth_range, -0.5 * g)
    hi = np.minimum(depth_range, 2.0 * geom.outer_radius - min_wall - g)
    return lo, hi


def make_problem(obs, base: dict, specs, *, rest: bool = False, depth: bool = False, excess: float,
                 sim_kw: dict | None = None, rest_range: float = 0.2, closure_margin: float = 0.9,
                 depth_range: float = 60e-6, depth_sigma: float = 15e-6, depth_common: float | None = 2e-6,
                 min_wall: float = 20e-6, rest_step: float = 2e-4) -> Problem:
    """Build the problem of fitting ``specs`` (and each tube's rest angles and cut depths) to ``obs``.

    Parameters
    ----------
    base : dict
        Tube -> base FrictionParams; the tubes not in ``obs`` are ignored.
    rest, depth : bool
        Fit each tube's rest angles (from the start of :func:`_rest_start`) and its
        per-notch cut-depth offsets (from 0, with the Gaussian prior ``depth_sigma``).
    rest_range : float
        Rest angles move at most this far from the geometry's [rad] ...
    closure_margin : float
        ... and stay within this fraction of each slot's closure angle.
    depth_range, depth_sigma, min_wall : float
        Cut-depth offsets: bound, prior standard deviation (the cutting tolerance) and
        the thinnest wall left [m].
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
    for t in tubes:
        g, n = geoms[t], geoms[t].n_joints
        if rest:
            ref, cap = base[t].rest_angles(g), closure_margin * g.closure_angles
            lo_t, hi_t = np.maximum(ref - rest_range, -cap), np.minimum(ref + rest_range, cap)
            x0 += list(np.clip(_rest_start(obs, t, start_params[t], sim_kw), lo_t, hi_t))
            lo, hi = lo + list(lo_t), hi + list(hi_t)
            blocks.append(Block("rest_angle", t, n, step=rest_step))
        if depth:
            lo_t, hi_t = _depth_block(g, depth_range, min_wall)
            i = len(x0)
            x0, lo, hi = x0 + [0.0] * n, lo + list(lo_t), hi + list(hi_t)
            rows += [(list(range(i + j, i + j + 1)), depth_sigma) for j in range(n)]
            if depth_common is not None:
                rows.append((list(range(i, i + n)), depth_common))
            blocks.append(Block("slot_depth_offset", t, n, step=DEPTH_STEP))
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x0 = np.clip(np.asarray(x0, float), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    prior = np.zeros((len(rows), x0.size))
    for r, (idx, sigma) in enumerate(rows):
        prior[r, idx] = 1.0 / (len(idx) * sigma)          # one unknown / sigma, or a block's mean / sigma
    excess = float(excess)
    return Problem(tuple(obs), tuple(specs), (1.0,) * len(specs), tuple(blocks), x0, lo, hi, prior,
                   model=partial(_tube_model, base, excess),
                   sims=Simulations(sim_kw))


def solve(pb: Problem, *, n_starts: int = 2, loss: str = "linear", f_scale: float = 3.0,
          max_nfev: int = 100, ftol: float = 1e-6, xtol: float = 1e-6, diff_rel: float = 2e-3,
          rest_step: float = 2e-4) -> Solution:
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
    """
    starts, nprobe = grid_starts(pb, n_starts)
    return solve_problem(pb, starts, jac="forward", loss=loss, f_scale=f_scale, max_nfev=max_nfev, ftol=ftol,
                         xtol=xtol, diff_rel=diff_rel, block_steps={"rest_angle": rest_step}, nfev=nprobe)
