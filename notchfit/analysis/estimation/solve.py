"""Solving a :class:`~notchfit.analysis.estimation.problem.Problem`: probe starts, bounded least squares, standard
errors, and the leave-one-out splits both engines score with.

* **Starts.** The friction model is piecewise smooth (the superelastic plateau's
  onset, the slot-closure stop and the stick/slip switching put kinks and local
  minima in the cost): the cost is evaluated on the grid of the specs' probe
  values around a start (one residual evaluation each) and the fit runs from the
  best (:func:`grid_starts`: the best ``n`` of the start and its grid;
  :func:`best_probe_starts`: the best probe around each of several starts).
* **Fit.** ``scipy.optimize.least_squares`` (``trf``, bounded) from each start,
  the lowest cost kept (:func:`solve`); the Jacobian by forward differences with
  a step per parameter (:meth:`Problem.steps`, large enough to step over the
  stick/slip switching) or scipy's relative ``2-point`` step.
* **Standard errors** (:func:`standard_errors`), one rule for every fit: per
  parameter the larger of the Gauss–Newton and the cluster-robust (jackknife)
  estimate, one cluster per sample — the residuals of one sample share its
  load-cell error and are correlated.
* **Leave-one-out** (:func:`folds`, :func:`tube_folds`): held-out experiments,
  or whole tubes.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

from .problem import Problem

__all__ = ["Solution", "best_probe_starts", "folds", "forward_jacobian", "grid_starts", "se_values", "solve", "stalled_at_start",
           "standard_errors", "tube_folds"]


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
        Residual evaluations, probes and Jacobians included.
    starts : int
        Least-squares runs.
    jacobian : ndarray or None
        The forward-difference Jacobian of the whitened residuals at ``x`` that the standard
        errors came from (None when they were not computed).
    loss_cost : float
        The cost the least squares minimised at ``x`` (``scipy.optimize.least_squares``'s ``cost``: with
        its robust ``loss``; equal to ``cost`` for the linear one): what decides between two runs.
    stalled : bool
        The winning run ended at its start (within scipy's ``xtol`` step test) although its linear model
        there promised a decrease of at least ``ftol`` times the cost: every step it tried raised the cost
        until the trust region fell below ``xtol`` (a kink of the friction model's non-smooth cost between
        the finite-difference step and the trial steps). Its cost is that of its start, no evidence of an
        optimum (:func:`stalled_at_start`).
    """

    x: np.ndarray
    se: np.ndarray
    cost: float
    n_residuals: int
    success: bool
    message: str
    nfev: int
    starts: int
    jacobian: np.ndarray | None = field(default=None, repr=False)
    loss_cost: float = math.nan
    stalled: bool = False


def _cost(pb: Problem, x) -> float:
    return float(np.sum(pb.residuals(x) ** 2))


def _grid(pb: Problem, base_x, idx):
    """``base_x`` with every combination of the probe values of the specs ``idx``."""
    for combo in itertools.product(*(pb.specs[i].probes for i in idx)):
        x = base_x.copy()
        for i, v in zip(idx, combo):
            x[i] = pb.specs[i].x_of_spec_value(v)
        yield x


def grid_starts(pb: Problem, n_starts: int) -> tuple[list, int]:
    """The ``n_starts`` best of ``x0`` and its grid of probe values (clipped into the bounds); and the
    number of residual evaluations spent."""
    idx = [i for i, s in enumerate(pb.specs) if s.probes]
    cands = [pb.x0] + [np.clip(x, pb.lo, pb.hi) for x in _grid(pb, pb.x0, idx)]
    if len(cands) == 1:
        return cands, 0
    costs = [_cost(pb, x) for x in cands]
    order = np.argsort(costs, kind="stable")
    return [cands[i] for i in order[:max(1, n_starts)]], len(cands)


def best_probe_starts(pb: Problem, bases, *, skip=(), keep: float = math.inf) -> list[np.ndarray]:
    """Around each start of ``bases``, the best point of the grid of the probe values of the specs not
    named in ``skip`` (``[x0]`` when none has probes); the starts are ordered by cost and kept when within
    ``keep`` times the lowest."""
    idx = [i for i, s in enumerate(pb.specs) if s.probes and s.name not in skip]
    if not idx:
        return [pb.x0]
    found = []
    for base_x in bases:
        best = (np.inf, base_x)
        for x in _grid(pb, base_x, idx):
            cost = _cost(pb, x)
            if cost < best[0]:
                best = (cost, x)
        found.append(best)
    low = min(c for c, _ in found)
    return [np.clip(x, pb.lo, pb.hi) for c, x in sorted(found, key=lambda t: t[0]) if c <= keep * low]


def forward_jacobian(pb: Problem, x, h) -> np.ndarray:
    """Forward differences of the residuals with steps ``h``, stepping inward at an upper bound."""
    r0 = pb.residuals(x)
    J = np.empty((r0.size, x.size))
    for i in range(x.size):
        step = h[i] if x[i] + h[i] <= pb.hi[i] else -h[i]
        xi = x.copy()
        xi[i] += step
        J[:, i] = (pb.residuals(xi) - r0) / step
    return J


class _Jacobian:
    """The Jacobian callable of one least-squares run that skips the one scipy would discard.

    ``scipy.optimize.least_squares`` (``trf``) evaluates the Jacobian at every accepted point, also at
    the last one, after its ``xtol`` test has already ended the run; that Jacobian is used for nothing
    but the reported gradient. When the step just accepted passes the ``xtol`` test
    (``‖Δx‖ < xtol (xtol + ‖x‖)``, within ``margin`` so that rounding cannot decide it) the run ends
    whatever the Jacobian, and the previous one is returned: the optimum, its cost and the counts of
    evaluations are those of the full run, bit for bit, one Jacobian (``p`` residual evaluations)
    cheaper. Only scipy's status word may differ (its gradient test, ``gtol``, reads this Jacobian:
    "xtol" where "gtol" would have been said, both a success). ``J0``: the Jacobian at ``x0`` when the
    caller has it, returned for the first call there.
    """

    def __init__(self, jac, xtol: float, margin: float = 1e-9, x0=None, J0=None):
        self.jac, self.xtol, self.margin = jac, xtol, margin
        self.x, self.J = (None, None) if J0 is None else (np.asarray(x0, dtype=float).copy(), J0)   # known at x0
        self.skipped = 0

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        if self.x is not None:
            limit = (1.0 - self.margin) * self.xtol * (self.xtol + float(np.linalg.norm(self.x)))
            if float(np.linalg.norm(x - self.x)) < limit:
                self.skipped += 1
                return self.J
        self.x, self.J = x.copy(), self.jac(x)
        return self.J


class _Secant:
    """Finite-difference Jacobians with Broyden's rank-one updates between them (Madsen, Nielsen & Tingleff
    2004, "Methods for non-linear least squares problems", §3.4).

    At an accepted point reached by the first step tried since the last Jacobian, the previous Jacobian is
    updated with the step ``Δx`` and the change of the residuals ``Δr`` (both already evaluated by the least
    squares), ``J ← J + (Δr − J Δx) Δxᵀ / (Δxᵀ Δx)``, which costs no residual evaluation; differences
    (``fd``) are taken at the start, after a step that was rejected (the linear model failed: the update
    refreshed by differences), after a step that lowered the cost by less than ``ratio`` times what the
    Jacobian predicted (the linear model described it poorly: a kink of the friction model's cost between the
    points) and after ``max_updates`` updates in a row. ``residuals`` is the function
    handed to the least squares (it records the last point evaluated); ``J0`` the Jacobian at ``x0`` when
    the caller has it.
    """

    def __init__(self, fun, fd, max_updates: int, x0=None, J0=None, ratio: float = 0.0):
        self.fun, self.fd, self.max_updates, self.ratio = fun, fd, max_updates, ratio
        self.x0, self.J0 = (None, None) if J0 is None else (np.asarray(x0, dtype=float).copy(), J0)
        self.x = self.r = self.J = None
        self.last = None                      # (x, r) of the last residual evaluation
        self.calls = 0                        # residual evaluations since the last Jacobian
        self.updates = 0                      # rank-one updates in a row
        self.differences = 0                  # finite-difference Jacobians taken

    def residuals(self, x):
        r = self.fun(x)
        self.calls += 1
        self.last = (np.array(x, dtype=float), r)
        return r

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        at_last = self.last is not None and np.array_equal(self.last[0], x)
        r = self.last[1] if at_last else self.fun(x)
        if self.J0 is not None and np.array_equal(x, self.x0):
            J, self.updates = self.J0, 0
        elif (self.J is None or not at_last or self.calls != 1 or self.updates >= self.max_updates
              or not self._predicted(x, r)):
            J, self.updates = self.fd(x), 0
            self.differences += 1
        else:
            dx, dr = x - self.x, r - self.r
            J = self.J + np.outer(dr - self.J @ dx, dx) / float(dx @ dx)
            self.updates += 1
        self.x, self.r, self.J, self.calls = x.copy(), r, J, 0
        return J

    def _predicted(self, x, r) -> bool:
        """The step to ``x`` lowered the cost by at least ``ratio`` times what the Jacobian predicted."""
        if self.ratio <= 0.0:
            return True
        r0 = self.r
        pred = float(r0 @ r0) - float(np.sum((r0 + self.J @ (x - self.x)) ** 2))
        return pred > 0.0 and float(r0 @ r0) - float(r @ r) >= self.ratio * pred


def standard_errors(pb: Problem, x, h, jacobian=None) -> np.ndarray:
    """Standard errors of ``x``: per parameter the larger of the Gauss–Newton and the cluster-robust estimate.

    Gauss–Newton: ``s² (JᵀJ)⁻¹`` with ``s²`` the residual variance (exact for
    independent errors of the observations). Cluster-robust, one cluster per
    sample (the residuals of one sample share its load-cell error): the
    jackknife over clusters in its one-step form (CR3),
    ``(G−1)/G Σ_g (d_g − d̄)(d_g − d̄)ᵀ`` with ``d_g = (JᵀJ − J_gᵀJ_g)⁻¹ J_gᵀ r_g``,
    which also holds where a few samples carry most of the information
    (high leverage), where the plain sandwich is biased low. ``jacobian``: the
    Jacobian at ``x`` when the caller has it (else forward differences with ``h``).
    """
    J = forward_jacobian(pb, x, h) if jacobian is None else jacobian
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


def se_values(pb: Problem, x, se) -> dict:
    """Standard errors of the shared parameters by name, in SI (log coordinates: relative to the value)."""
    vals = pb.values(x)
    return {s.name: (vals[s.name] * float(se[i]) if s.log else float(se[i]) * c)
            for i, (s, c) in enumerate(zip(pb.specs, pb.scales))}


def solve(pb: Problem, starts, *, jac: str = "forward", loss: str = "linear", f_scale: float = 3.0,
          max_nfev: int = 100, ftol: float = 1e-6, xtol: float = 1e-6, diff_rel: float = 2e-3,
          block_steps: dict | None = None, nfev: int = 0, errors: bool = True, jacobian0=None,
          secant: int = 0, secant_ratio: float = 0.75) -> Solution:
    """Bounded least squares from each start; the lowest cost wins, with its standard errors.

    Parameters
    ----------
    starts : sequence of ndarray
        Start points (:func:`grid_starts`, :func:`best_probe_starts`).
    jac : {"forward", "2-point"}
        Forward differences with :meth:`Problem.steps` (``diff_rel``, ``block_steps``), or scipy's
        ``2-point`` with the relative step ``diff_rel``.
    loss, f_scale, max_nfev, ftol, xtol :
        ``scipy.optimize.least_squares`` options, per run.
    nfev : int
        Evaluations already spent (probes), added to the count.
    errors : bool
        Compute the standard errors (else NaN: a fit whose errors nobody reads).
    jacobian0 : ndarray, optional
        The ``"forward"`` Jacobian at the first start, when the caller has it (an earlier fit's at
        that point, same steps): that run does not compute it.
    secant : int
        Broyden rank-one updates allowed in a row between finite-difference Jacobians (:class:`_Secant`;
        0: differences at every accepted point).
    secant_ratio : float
        An update only after a step that lowered the cost by at least this fraction of what the Jacobian
        predicted (a step the linear model described well); else differences.
    """
    best, stalled = None, False
    for j, x0 in enumerate(starts):
        J0 = jacobian0 if j == 0 and jac == "forward" else None
        if jac == "forward":
            h = pb.steps(x0, diff_rel, block_steps)
            fd = lambda x, h=h: forward_jacobian(pb, x, h)       # noqa: E731
        else:
            # scipy's own 2-point differences (least_squares(jac="2-point", diff_step=diff_rel)), called here
            fd = lambda x: approx_derivative(pb.residuals, x, method="2-point", rel_step=diff_rel,  # noqa: E731
                                             f0=pb.residuals(x), bounds=(pb.lo, pb.hi))
        fun, sec = pb.residuals, None
        if secant > 0:
            sec = _Secant(pb.residuals, fd, secant, x0=x0, J0=J0, ratio=secant_ratio)
            fun, fd, J0 = sec.residuals, sec, None
        jac_of = _Jacobian(fd, xtol, x0=x0, J0=J0)
        res = least_squares(fun, x0, jac=jac_of, bounds=(pb.lo, pb.hi), method="trf", loss=loss,
                            f_scale=f_scale, max_nfev=max_nfev, ftol=ftol, xtol=xtol, x_scale="jac")
        njev = res.njev if sec is None else sec.differences
        nfev += res.nfev + (njev * x0.size if jac == "forward" else 0)
        if best is None or res.cost < best.cost:
            best = res
            # at the end (within xtol of the start when stalled): its residuals and last Jacobian
            stalled = stalled_at_start(res.fun, jac_of.J, x0, res.x, xtol=xtol, ftol=ftol)
    h = pb.steps(best.x, diff_rel, block_steps)
    J = forward_jacobian(pb, best.x, h) if errors else None
    se = standard_errors(pb, best.x, h, J) if errors else np.full(best.x.size, np.nan)
    cost = 0.5 * float(np.sum(pb.residuals(best.x) ** 2))          # the priors' terms included
    if not math.isfinite(cost):
        raise ValueError("the least-squares cost is not finite at its optimum")
    return Solution(best.x, se, cost, int(pb.measured().sum()), bool(best.success), str(best.message),
                    nfev + (best.x.size + 1 if errors else 0), len(starts), J, float(best.cost), stalled)


def stalled_at_start(r0, J0, x0, x, *, xtol: float, ftol: float) -> bool:
    """A least-squares run that ended at its start ``x0`` (``‖x − x0‖ < xtol (xtol + ‖x0‖)``, scipy's step
    test) while the Gauss–Newton step of its Jacobian ``J0`` there (``(r, p)``; ``r0`` the residuals) promised a
    decrease of the cost ``½‖r0‖²`` by at least ``ftol`` of it (scipy's cost test): every trial step raised the
    cost, so the start is no optimum of the fit's own linear model (:attr:`Solution.stalled`). An optimum
    where the gradient vanishes promises nothing and is not stalled."""
    x0, r0 = np.asarray(x0, dtype=float), np.asarray(r0, dtype=float)
    if np.linalg.norm(np.asarray(x, dtype=float) - x0) >= xtol * (xtol + np.linalg.norm(x0)) or J0 is None:
        return False
    dx = np.linalg.lstsq(J0, -r0, rcond=None)[0]
    promised = 0.5 * (float(r0 @ r0) - float(np.sum((r0 + J0 @ dx) ** 2)))
    return promised >= ftol * 0.5 * float(r0 @ r0)


# ----------------------------------------------------------------------------- leave-one-out
def folds(n: int, max_folds: int | None = None) -> list[np.ndarray]:
    """Held-out experiment indices of each fold: leave-one-out (up to ``max_folds`` experiments; beyond,
    ``max_folds`` interleaved folds)."""
    k = n if max_folds is None else min(n, max_folds)
    return [np.arange(n)[i::k] for i in range(k)]


def tube_folds(obs) -> dict:
    """Tube -> indices of its experiments (each tube held out in turn; empty with one tube)."""
    tubes = list(dict.fromkeys(o.tube for o in obs))
    if len(tubes) < 2:
        return {}
    return {t: np.array([i for i, o in enumerate(obs) if o.tube == t]) for t in tubes}
