"""The least-squares problem of an identification and its solution.

Unknowns ``x``: the scalar free parameters in optimiser coordinates
(:class:`~notchfit.diagnosis.specs.ParamSpec`: log scale for moduli, rates and
thresholds), then the rest angles [rad] of every tube whose rest angles are
free. Residuals: for each experiment the friction simulator (Sec. IV-B, fast
solver) driven by its measured tensions, against its observations — joint
angles ``(θ_sim − θ_meas)/σ_θ`` where measured, or notch points
``(Q̃ − Q)/σ_p`` registered in the plane (Sec. IV-A) — stacked.

Solution (:func:`solve`): the cost is evaluated on a small grid of probe
values of the scalar parameters (the friction model is piecewise smooth — the
superelastic plateau's onset, the slot-closure stop and the stick/slip
switching put kinks and local minima in the cost), and bounded least squares
(``scipy.optimize.least_squares``, ``trf``, finite differences with steps
large enough to step over the stick/slip switching) runs from the best
``n_starts`` of them; the lowest cost wins. Standard errors
(:func:`standard_errors`): the larger of the Gauss–Newton and the
cluster-robust (jackknife) estimate, one cluster per sample — the residuals
of one sample share its load-cell error and are correlated.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..comparison import angle_residuals
from ..friction import FrictionParams, simulate_angles
from ..notches import notch_points, to_plane
from .data import Observed, zero_tension_samples

__all__ = ["Problem", "Solution", "errors", "make_problem", "predict", "solve", "standard_errors", "whitened",
           "with_values"]


@dataclass(frozen=True, eq=False)
class Problem:
    """One identification's unknowns, bounds and residuals (module docstring).

    Attributes
    ----------
    obs : tuple of Observed
        The experiments fitted.
    base : dict
        Tube -> its base FrictionParams (fixed values of everything not free).
    specs : tuple of ParamSpec
        The scalar free parameters.
    blocks : tuple of (field, tube, n)
        The per-joint unknowns of single tubes after the scalars, in the order
        of ``x``: ``("rest_angle", tube, n)`` [rad], ``("slot_depth_offset", tube, n)`` [m].
    x0, lo, hi : ndarray
        Start and bounds in optimiser coordinates.
    prior : ndarray (m, p)
        A zero-mean Gaussian prior on linear combinations of the unknowns: each
        row adds the residual ``prior[r] @ x`` (the cut depths' tolerance, per
        notch and for a tube's mean).
    excess : float
        ``μ_s − μ_d``, held.
    sim_kw : dict
        Options of :func:`notchfit.friction.simulate`.
    """

    obs: tuple
    base: dict
    specs: tuple
    blocks: tuple
    x0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    prior: np.ndarray
    excess: float
    sim_kw: dict = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def k(self) -> int:
        return len(self.specs)

    def values(self, x) -> dict:
        """Scalar parameter values by field name (SI)."""
        return {s.name: s.from_x(float(v)) for s, v in zip(self.specs, x[:self.k])}

    def tube_values(self, x) -> dict:
        """Tube -> {field: (n,) values} of its free per-joint unknowns."""
        out, i = {}, self.k
        for name, tube, n in self.blocks:
            out.setdefault(tube, {})[name] = np.asarray(x[i:i + n], dtype=float)
            i += n
        return out

    def params(self, x) -> dict:
        """Tube -> the FrictionParams of ``x``."""
        vals, per = self.values(x), self.tube_values(x)
        return {t: with_values(b, vals, self.excess, **per.get(t, {})) for t, b in self.base.items()}

    def theta(self, i: int, params: FrictionParams) -> np.ndarray:
        """Simulated joint angles of experiment ``i`` (S, n) [rad], cached by the parameters."""
        key = (i, params)
        th = self._cache.get(key)
        if th is None:
            if len(self._cache) > 4096:
                self._cache.clear()
            th = predict(self.obs[i], params, self.sim_kw)
            self._cache[key] = th
        return th

    def residuals(self, x) -> np.ndarray:
        """Whitened residuals of every experiment, stacked (fixed length: zeros where not measured),
        then the prior's."""
        by_tube = self.params(x)
        return np.concatenate([whitened(o, self.theta(i, by_tube[o.tube])) for i, o in enumerate(self.obs)]
                              + [self.prior @ np.asarray(x, dtype=float)])

    def clusters(self) -> np.ndarray:
        """The sample each residual belongs to (cluster ids for the standard errors; -1: a prior's)."""
        out, base = [], 0
        for o in self.obs:
            S = o.time.size
            per = o.angles.shape[1] if o.metric == "deg" else 2 * o.points.shape[1]
            out.append(base + np.repeat(np.arange(S), per))
            base += S
        out.append(np.full(self.prior.shape[0], -1))
        return np.concatenate(out)

    def measured(self) -> np.ndarray:
        """Which residuals are measured values (bool, the layout of :meth:`residuals`; False for the prior's)."""
        return np.concatenate([(np.isfinite(o.angles) if o.metric == "deg"
                                else np.repeat(o.valid[..., None], 2, axis=-1)).ravel() for o in self.obs]
                              + [np.zeros(self.prior.shape[0], bool)])


def with_values(params: FrictionParams, values: dict, excess: float, **per_joint) -> FrictionParams:
    """``params`` with scalar ``values`` (``μ_s = μ_d + excess`` when ``μ_d`` is among them) and per-joint
    values of one tube (``rest_angle=``, ``slot_depth_offset=``)."""
    kw = dict(values)
    if "mu_d" in kw:
        kw["mu_s"] = kw["mu_d"] + excess
    for name, v in per_joint.items():
        if v is not None:
            kw[name] = tuple(float(a) for a in v)
    return params.replace(**kw)


def whitened(o: Observed, theta: np.ndarray) -> np.ndarray:
    """Residuals of one experiment, divided by its σ, flattened; zero where not measured."""
    if o.metric == "deg":
        r = angle_residuals(theta, o.angles) / o.sigma
        return np.nan_to_num(r, nan=0.0).ravel()
    T = o.transform
    r = (to_plane(notch_points(theta, o.geom), T.tx, T.ty, T.phi, T.mirror) - o.points) / o.sigma
    r[~o.valid] = 0.0
    return r.ravel()


def errors(o: Observed, theta: np.ndarray) -> np.ndarray:
    """Unweighted errors of the measured values [rad or m]: angle residuals, or point distances."""
    if o.metric == "deg":
        r = angle_residuals(theta, o.angles)
        return r[np.isfinite(r)]
    T = o.transform
    d = np.linalg.norm(to_plane(notch_points(theta, o.geom), T.tx, T.ty, T.phi, T.mirror) - o.points, axis=-1)
    return d[o.valid]


def predict(o: Observed, params: FrictionParams, sim_kw: dict | None = None) -> np.ndarray:
    """Joint angles (S, n) [rad] of one experiment under ``params``."""
    left, right = o.tendon_tensions
    return simulate_angles(o.time, left, right, params, o.geom, ramp_time=o.ramp_time, **(sim_kw or {}))


def _rest_start(obs, tube, base: FrictionParams, sim_kw) -> np.ndarray:
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
            diffs.append(o.shape_angles[idx] - th)
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
                 min_wall: float = 20e-6) -> Problem:
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
    depth_common : float or None
        Prior standard deviation of a tube's mean offset [m] (None: only the per-notch
        prior). Small by default: a depth error common to a tube's notches is a
        stiffness scale, which the shared material cannot tell from the tube's;
        the per-notch offsets then carry only the notch-to-notch variation.
    """
    tubes = list(dict.fromkeys(o.tube for o in obs))
    geoms = {t: next(o.geom for o in obs if o.tube == t) for t in tubes}
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
            blocks.append(("rest_angle", t, n))
        if depth:
            lo_t, hi_t = _depth_block(g, depth_range, min_wall)
            i = len(x0)
            x0, lo, hi = x0 + [0.0] * n, lo + list(lo_t), hi + list(hi_t)
            rows += [(list(range(i + j, i + j + 1)), depth_sigma) for j in range(n)]
            if depth_common is not None:
                rows.append((list(range(i, i + n)), depth_common))
            blocks.append(("slot_depth_offset", t, n))
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x0 = np.clip(np.asarray(x0, float), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    prior = np.zeros((len(rows), x0.size))
    for r, (idx, sigma) in enumerate(rows):
        prior[r, idx] = 1.0 / (len(idx) * sigma)          # one unknown / sigma, or a block's mean / sigma
    return Problem(tuple(obs), {t: base[t] for t in tubes}, tuple(specs), tuple(blocks), x0, lo, hi, prior,
                   float(excess), dict(sim_kw or {}))


@dataclass(frozen=True)
class Solution:
    """A solved problem.

    Attributes
    ----------
    x : ndarray
        Optimum (optimiser coordinates).
    se : ndarray
        Standard errors of ``x`` (:func:`standard_errors`).
    cost : float
        Half the sum of squared whitened residuals at ``x`` (the priors' included).
    n_residuals : int
        Measured values (angles or point coordinates).
    success : bool
    message : str
    nfev : int
        Residual evaluations, probes included.
    starts : int
        Least-squares runs.
    """

    x: np.ndarray
    se: np.ndarray
    cost: float
    n_residuals: int
    success: bool
    message: str
    nfev: int
    starts: int


def _probe_starts(pb: Problem, n_starts: int) -> tuple[list, int]:
    """The ``n_starts`` best of the start and the grid of probe values (one residual evaluation each)."""
    idx = [i for i, s in enumerate(pb.specs) if s.probes]
    cands = [pb.x0]
    for combo in itertools.product(*(pb.specs[i].probes for i in idx)):
        x = pb.x0.copy()
        for i, v in zip(idx, combo):
            x[i] = pb.specs[i].to_x(v)
        cands.append(np.clip(x, pb.lo, pb.hi))
    if len(cands) == 1:
        return cands, 0
    costs = [float(np.sum(pb.residuals(x) ** 2)) for x in cands]
    order = np.argsort(costs, kind="stable")
    return [cands[i] for i in order[:max(1, n_starts)]], len(cands)


def _diff_steps(pb: Problem, x, rel: float, rest_step: float, depth_step: float = 2e-7) -> np.ndarray:
    """Absolute finite-difference steps: ``rel`` of a parameter's value (log coordinates: ``rel`` itself;
    others: ``rel`` of the larger of the value and a tenth of the bound range); ``rest_step`` [rad] for rest
    angles, ``depth_step`` [m] for cut depths."""
    h = np.empty(x.size)
    for i, s in enumerate(pb.specs):
        h[i] = rel if s.log else rel * max(abs(float(x[i])), 0.1 * (pb.hi[i] - pb.lo[i]))
    i = pb.k
    for name, _, n in pb.blocks:
        h[i:i + n] = rest_step if name == "rest_angle" else depth_step
        i += n
    return h


def _jacobian(pb: Problem, x, h) -> np.ndarray:
    """Forward differences, stepping inward at an upper bound."""
    r0 = pb.residuals(x)
    J = np.empty((r0.size, x.size))
    for i in range(x.size):
        step = h[i] if x[i] + h[i] <= pb.hi[i] else -h[i]
        xi = x.copy()
        xi[i] += step
        J[:, i] = (pb.residuals(xi) - r0) / step
    return J


def standard_errors(pb: Problem, x, h) -> np.ndarray:
    """Standard errors of ``x``: per parameter the larger of the Gauss–Newton and the cluster-robust estimate.

    Gauss–Newton: ``s² (JᵀJ)⁻¹`` with ``s²`` the residual variance (exact for
    independent errors of the observations). Cluster-robust, one cluster per
    sample (the residuals of one sample share its load-cell error): the
    jackknife over clusters in its one-step form (CR3),
    ``(G−1)/G Σ_g (d_g − d̄)(d_g − d̄)ᵀ`` with ``d_g = (JᵀJ − J_gᵀJ_g)⁻¹ J_gᵀ r_g``,
    which also holds where a few samples carry most of the information
    (high leverage), where the plain sandwich is biased low.
    """
    J = _jacobian(pb, x, h)
    r = pb.residuals(x)
    keep = pb.measured()
    cl = pb.clusters()
    B = J.T @ J                               # the priors' rows included (a posterior's information)
    J, r, cl = J[keep], r[keep], cl[keep]
    n, p = r.size, x.size
    gn = np.diag(np.linalg.pinv(B)) * float(r @ r) / max(n - p, 1)
    d = []
    for g in np.unique(cl):
        k = cl == g
        Jg = J[k]
        d.append(np.linalg.lstsq(B - Jg.T @ Jg, Jg.T @ r[k], rcond=None)[0])
    d = np.asarray(d)
    G = d.shape[0]
    cr3 = (G - 1) / max(G, 1) * np.sum((d - d.mean(axis=0)) ** 2, axis=0)
    return np.sqrt(np.clip(np.maximum(gn, cr3), 0.0, None))


def solve(pb: Problem, *, n_starts: int = 2, loss: str = "linear", f_scale: float = 3.0,
          max_nfev: int = 100, ftol: float = 1e-6, xtol: float = 1e-6, diff_rel: float = 2e-3,
          rest_step: float = 2e-4) -> Solution:
    """Minimise the problem's cost from the best probes (module docstring).

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
    starts, nprobe = _probe_starts(pb, n_starts)
    best, nfev = None, nprobe
    for x0 in starts:
        h = _diff_steps(pb, x0, diff_rel, rest_step)
        res = least_squares(pb.residuals, x0, jac=lambda x: _jacobian(pb, x, h), bounds=(pb.lo, pb.hi),
                            method="trf", loss=loss, f_scale=f_scale, max_nfev=max_nfev, ftol=ftol, xtol=xtol,
                            x_scale="jac")
        nfev += res.nfev + res.njev * x0.size
        if best is None or res.cost < best.cost:
            best = res
    h = _diff_steps(pb, best.x, diff_rel, rest_step)
    se = standard_errors(pb, best.x, h)
    n_res = int(pb.measured().sum())
    cost = 0.5 * float(np.sum(pb.residuals(best.x) ** 2))          # the priors' terms included
    if not math.isfinite(cost):
        raise ValueError("the identification's cost is not finite at its optimum")
    return Solution(best.x, se, cost, n_res, bool(best.success), str(best.message), nfev + x0.size + 1,
                    len(starts))
