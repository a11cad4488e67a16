"""Batched Levenberg–Marquardt for many small least-squares problems that share three unknowns.

The shape fits of :mod:`notchfit.analysis.fitting` whiten every residual by its point
uncertainty and solve, for S samples at once, either

* S independent problems (each sample's shape parameters, the plane
  transform fixed), each with its own damping and convergence test, or
* one joint problem over the shared plane transform ``t = (t_x, t_y, φ)``
  and every sample's parameters. Each residual depends on ``t`` and on its
  own sample only, so the normal matrix is block-arrow shaped and every step
  is reduced to the three transform unknowns by a Schur complement.

Robust losses are those of ``scipy.optimize.least_squares`` (``linear``,
``soft_l1``, ``huber``, ``cauchy``, ``arctan``, applied at
``z = (r / f_scale)²``), handled by iteratively reweighted Gauss–Newton
steps with weights ``ρ'(z)`` whose acceptance is tested on the true robust
cost. Shapes: S samples, m points (2m residual rows), k parameters per
sample; lengths in m, angles in rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ...physics.notches import notch_points, notch_points_and_jacobian, plane_params_jacobian, to_plane
from ...physics.shapes import ShapeModel
from ...units import MM

__all__ = ["LOSSES", "Problem", "Settings", "check_loss", "levenberg_marquardt", "loss_weights", "psd_inverse",
           "rho", "schur_cov", "scipy_fits"]

LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")

#: Scale of the transform ``(t_x, t_y, φ)`` in the step tests: its lengths measured in mm.
_TSCALE = np.array([MM, MM, 1.0])


@dataclass(frozen=True)
class Settings:
    """The loss of a shape fit and its solver's tolerances and iteration limit.

    Attributes
    ----------
    loss : str
        One of :data:`LOSSES` (as ``scipy.optimize.least_squares``).
    f_scale : float
        The loss's scale [σ units].
    ftol, xtol : float
        Relative tolerances on the cost decrease and on the step.
    max_iter : int
        Iteration limit.
    """

    loss: str
    f_scale: float
    ftol: float
    xtol: float
    max_iter: int


def check_loss(loss, f_scale) -> None:
    """Raise ``ValueError`` unless ``loss`` is one of :data:`LOSSES` and ``f_scale`` > 0 [σ units]."""
    if loss not in LOSSES:
        raise ValueError(f"loss must be one of {LOSSES}, got {loss!r}")
    if not (isinstance(f_scale, (int, float)) and math.isfinite(f_scale) and f_scale > 0):
        raise ValueError(f"f_scale must be a positive number (in units of sigma), got {f_scale!r}")


def loss_weights(z_sq, loss):
    """``ρ'(z)`` of scipy's losses at ``z = (r / f_scale)²`` (same shape as ``z_sq``)."""
    if loss == "linear":
        return np.ones_like(z_sq)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z_sq)
    if loss == "huber":
        return np.where(z_sq <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z_sq, 1.0)))
    if loss == "cauchy":
        return 1.0 / (1.0 + z_sq)
    if loss == "arctan":
        return 1.0 / (1.0 + z_sq * z_sq)
    raise ValueError(loss)


def rho(z, loss):
    """scipy's loss ``ρ(z)`` at ``z = (r / f_scale)²`` (same shape as ``z``)."""
    if loss == "linear":
        return z
    if loss == "soft_l1":
        return 2.0 * (np.sqrt(1.0 + z) - 1.0)
    if loss == "huber":
        return np.where(z <= 1.0, z, 2.0 * np.sqrt(np.maximum(z, 1.0)) - 1.0)
    if loss == "cauchy":
        return np.log1p(z)
    if loss == "arctan":
        return np.arctan(z)
    raise ValueError(loss)


def _rm(phi, mirror):
    """``Rot(φ) M`` (2, 2) of the plane transform (``M = diag(-1, 1)`` when mirrored)."""
    c, s = math.cos(phi), math.sin(phi)
    R = np.array([[c, -s], [s, c]])
    return R @ np.diag([-1.0, 1.0]) if mirror else R


class Problem:
    """Whitened residuals ``(Q̃ − Q)/σ`` of S samples for one shape model.

    Rows are (S, 2m) in the order x₁, y₁, x₂, …; a missing point's rows have
    weight 0 (residual and Jacobian rows are zero).

    Parameters
    ----------
    Q : ndarray, shape (S, m, 2)
        Measured plane-frame points [m], NaN where missing.
    sig : ndarray, shape (S, m)
        Point uncertainty [m], NaN drops a point.
    geom : Geometry
    model : ShapeModel
    mirror : bool
    """

    def __init__(self, Q, sig, geom, model: ShapeModel, mirror):
        self.valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
        self.W = np.where(self.valid, 1.0 / np.where(self.valid, sig, 1.0), 0.0)
        self.Q0 = np.where(self.valid[..., None], Q, 0.0)
        self.geom, self.model, self.mirror = geom, model, bool(mirror)
        self.S, self.m = self.W.shape

    def residuals(self, t, P):
        """Whitened residuals (S, 2m) at transform ``t`` (3,) and parameters ``P`` (S, k)."""
        theta = P @ self.model.basis.T
        plane = to_plane(notch_points(theta, self.geom), t[0], t[1], t[2], self.mirror)
        return ((plane - self.Q0) * self.W[..., None]).reshape(self.S, -1)

    def evaluate(self, t, P):
        """r (S, 2m), J_p (S, 2m, k), J_t (S, 2m, 3), plane points (S, m, 2), θ (S, n)."""
        B = self.model.basis
        theta = P @ B.T
        pts, jth = notch_points_and_jacobian(theta, self.geom)
        plane = to_plane(pts, t[0], t[1], t[2], self.mirror)
        W = self.W[..., None]
        r = ((plane - self.Q0) * W).reshape(self.S, -1)
        RM = _rm(t[2], self.mirror)
        jp = np.einsum("ab,smbn->sman", RM, jth, optimize=True) @ B
        Jp = (jp * W[..., None]).reshape(self.S, 2 * self.m, -1)
        Jt = (plane_params_jacobian(pts, t[2], self.mirror) * W[..., None]).reshape(self.S, 2 * self.m, 3)
        return r, Jp, Jt, plane, theta


@dataclass(frozen=True)
class _Normal:
    """The robust Gauss–Newton model of one iteration: whitened residuals ``r`` (S, 2m), Jacobians ``Jp``
    (S, 2m, k) and ``Jt`` (S, 2m, 3), loss weights ``w`` (S, 2m), the per-sample normal matrices ``A``
    (S, k, k) (prior included), gradients ``g`` (S, k) and damping scales ``dA`` (S, k)."""

    r: np.ndarray
    Jp: np.ndarray
    Jt: np.ndarray
    w: np.ndarray
    A: np.ndarray
    g: np.ndarray
    dA: np.ndarray

    @classmethod
    def at(cls, r, Jp, Jt, P, w, DtD) -> _Normal:
        """The model at parameters ``P`` (S, k) with weights ``w`` and the prior's normal matrix ``DtD``."""
        JpW = Jp * w[..., None]
        A = np.einsum("sri,srj->sij", JpW, Jp) + DtD
        g = np.einsum("sri,sr->si", JpW, r) + P @ DtD
        dA = np.diagonal(A, axis1=1, axis2=2)
        dA = np.maximum(dA, np.maximum(1e-12 * dA.max(-1, keepdims=True), 1e-30))
        return cls(r, Jp, Jt, w, A, g, dA)

    def damped(self, mu) -> np.ndarray:
        """``A + μ diag(dA)`` (S, k, k) with ``mu`` a scalar or (S,)."""
        return self.A + np.reshape(mu, (-1, 1, 1)) * self.dA[:, :, None] * np.eye(self.A.shape[-1])


def _joint_steps(nm: _Normal, mu: float):
    """Damped and undamped joint steps ``(dt, dP)`` and the Newton decrement (Schur complement on t)."""
    JtW = nm.Jt * nm.w[..., None]
    Bm = np.einsum("sri,srj->sij", nm.Jp * nm.w[..., None], nm.Jt)
    C = np.einsum("sri,srj->ij", JtW, nm.Jt)
    gt = np.einsum("sri,sr->i", JtW, nm.r)
    dC = np.maximum(np.diag(C), 1e-12 * np.diag(C).max())

    def step(mu_):
        Am = nm.damped(mu_)
        AiB = np.linalg.solve(Am, Bm)
        Aig = np.linalg.solve(Am, nm.g[..., None])[..., 0]
        Sc = C + mu_ * np.diag(dC) - np.einsum("sia,sib->ab", Bm, AiB)
        rhs = gt - np.einsum("sia,si->a", Bm, Aig)
        dt_ = -np.linalg.solve(Sc, rhs)
        return dt_, -(Aig + AiB @ dt_)

    dt, dP = step(mu)
    dt0, dP0 = step(1e-12)
    # Newton decrement of the undamped Gauss–Newton step
    return dt, dP, -0.5 * (gt @ dt0 + np.sum(nm.g * dP0))


def _independent_steps(nm: _Normal, mu, done):
    """Per-sample damped steps ``dP`` (S, k) and Newton decrements (S,)."""
    dP = -np.linalg.solve(nm.damped(mu), nm.g[..., None])[..., 0]
    dP[done] = 0.0
    dP0 = -np.linalg.solve(nm.damped(1e-12), nm.g[..., None])[..., 0]
    return dP, -0.5 * np.sum(nm.g * dP0, axis=-1)


@dataclass(frozen=True)
class _Trial:
    """A trial step ``(dt, dP)`` from the iterate ``(t, P)`` (3,), (S, k), and the robust costs (S,) before
    (``cost``) and after it (``cost_new``)."""

    t: np.ndarray
    P: np.ndarray
    dt: np.ndarray
    dP: np.ndarray
    cost: np.ndarray
    cost_new: np.ndarray


def _small(dec, ref, step, xnorm, opts: Settings):
    """Whether a step is too small to matter: a cost decrease ``dec`` within ``ftol`` of ``ref``, or a step
    length ``step`` within ``xtol`` of ``xnorm``."""
    return (dec <= opts.ftol * ref + 1e-14) | (step <= opts.xtol * (xnorm + opts.xtol))


def _joint_tests(tr: _Trial, opts: Settings):
    """Acceptance (S,) and "step too small to matter" (S,) of a joint trial step: one test on the summed
    cost and on the whole step (the transform's lengths in mm), alike for every sample."""
    S = tr.P.shape[0]
    accept = np.full(S, tr.cost_new.sum() <= tr.cost.sum())
    dec = np.full(S, tr.cost.sum() - tr.cost_new.sum())
    ref = np.full(S, tr.cost.sum())
    step = np.full(S, np.linalg.norm(np.concatenate([tr.dt / _TSCALE, tr.dP.ravel()])))
    xnorm = np.full(S, np.linalg.norm(np.concatenate([tr.t / _TSCALE, tr.P.ravel()])))
    return accept, _small(dec, ref, step, xnorm, opts)


def _independent_tests(tr: _Trial, done, opts: Settings):
    """Acceptance (S,) and "step too small to matter" (S,) of independent trial steps, sample by sample
    (none accepted for a sample ``done``)."""
    accept = (tr.cost_new <= tr.cost) & ~done
    step = np.linalg.norm(tr.dP, axis=-1)
    xnorm = np.linalg.norm(tr.P, axis=-1)
    return accept, _small(tr.cost - tr.cost_new, tr.cost, step, xnorm, opts)


def levenberg_marquardt(prob: Problem, t, P, opts: Settings, *, joint: bool, mu0: float = 1e-4,
                        mu_max: float = 1e10):
    """Levenberg–Marquardt on the block-arrow problem (batched over samples).

    ``joint``: the transform ``t`` (in m, m, rad) is a shared unknown; the
    normal equations are reduced to it by the Schur complement of the
    per-sample blocks, with one damping factor. Otherwise every sample is an
    independent problem with its own damping and convergence test. A robust
    loss is handled by iteratively reweighted Gauss–Newton steps (weights
    ``ρ'``) whose acceptance is tested on the true robust cost, so the fixed
    point is that of ``scipy.optimize.least_squares`` with the same loss.
    The prior rows are not robustified.

    Parameters
    ----------
    prob : Problem
    t : array_like, shape (3,)
        Plane transform (t_x [m], t_y [m], φ [rad]).
    P : array_like, shape (S, k)
        Start parameters.
    opts : Settings
        The loss, its scale, the tolerances (the transform's lengths measured
        in mm in the step test) and the iteration limit.
    joint : bool
    mu0, mu_max : float
        Initial damping, and the damping at which a sample is declared at
        its minimum to precision.

    Returns
    -------
    t, P, converged (S,), iterations, r, Jp, Jt, plane, theta at the end.
    """
    loss, ftol = opts.loss, opts.ftol
    D = prob.model.prior_jacobian()
    DtD = D.T @ D
    S = P.shape[0]
    f2 = opts.f_scale * opts.f_scale

    def cost_of(r, P):
        return 0.5 * (f2 * rho(r * r / f2, loss).sum(-1) + ((P @ D.T) ** 2).sum(-1))

    t = np.asarray(t, dtype=float).copy()
    P = np.asarray(P, dtype=float).copy()
    r, Jp, Jt, plane, theta = prob.evaluate(t, P)
    cost = cost_of(r, P)
    done = np.zeros(S, dtype=bool)
    mu = np.full(S, mu0)
    it = 0
    for it in range(1, opts.max_iter + 1):
        nm = _Normal.at(r, Jp, Jt, P, loss_weights(r * r / f2, loss), DtD)
        if joint:
            dt, dP, decr = _joint_steps(nm, mu[0])
            decr = np.full(S, decr)
        else:
            dt = np.zeros(3)
            dP, decr = _independent_steps(nm, mu, done)
        # at a minimum to precision: the Gauss–Newton model predicts no decrease
        done |= decr <= ftol * (cost + f2) + 1e-14
        if done.all():
            break
        t_new, P_new = t + dt, P + dP
        cost_new = cost_of(prob.residuals(t_new, P_new), P_new)
        trial = _Trial(t, P, dt, dP, cost, cost_new)
        accept, small = _joint_tests(trial, opts) if joint else _independent_tests(trial, done, opts)
        small &= mu < 1.0                      # a tiny step is meaningful only when barely damped
        if accept.any():
            if joint:
                t = t_new
            P = np.where(accept[:, None], P_new, P)
            r, Jp, Jt, plane, theta = prob.evaluate(t, P)
            cost = cost_of(r, P)
            done |= accept & small
        mu = np.where(accept, np.maximum(mu / 3.0, 1e-12), mu * 4.0)
        done |= (mu > mu_max) & ~done          # no decrease possible: at a minimum to precision
        if done.all():
            break
    return t, P, done, it, r, Jp, Jt, plane, theta


def psd_inverse(A, rcond: float = 1e-13):
    """Inverse of a stack of symmetric positive semi-definite matrices (..., k, k).

    Diagonally scaled batched inverse; a matrix that is singular to ``rcond``
    gets its pseudo-inverse instead (one by one, rare). Batched
    eigendecompositions are avoided: they are slow under BLAS threading.
    """
    A = np.asarray(A, dtype=float)
    d = np.sqrt(np.maximum(np.diagonal(A, axis1=-2, axis2=-1), 1e-300))
    As = A / (d[..., :, None] * d[..., None, :])
    flat = As.reshape(-1, *As.shape[-2:])
    out = np.empty_like(flat)
    try:
        out[:] = np.linalg.inv(flat)
        bad = ~np.isfinite(out).all((-1, -2)) | (np.abs(out).max((-1, -2)) * rcond > 1.0)
    except np.linalg.LinAlgError:
        bad = np.ones(len(flat), dtype=bool)
    for i in np.nonzero(bad)[0]:
        out[i] = np.linalg.pinv(flat[i], rcond=rcond, hermitian=True)
    out = out.reshape(As.shape)
    return out / (d[..., :, None] * d[..., None, :])


def schur_cov(Jp, Jt, w_rho, DtD, tol):
    """Transform covariance (3, 3) from the joint normal matrix (Schur complement), and identifiability.

    Parameters
    ----------
    Jp, Jt : ndarray, shapes (S, 2m, k) and (S, 2m, 3)
        Whitened Jacobians at the joint optimum.
    w_rho : ndarray, shape (S, 2m)
        Robust-loss weights ``ρ'``.
    DtD : ndarray, shape (k, k)
        Prior normal matrix.
    tol : float
        Identifiability threshold (see :func:`notchfit.analysis.fitting.fit_transform`).

    Returns
    -------
    cov : ndarray, shape (3, 3)
        Inverse Schur complement; inf when not identifiable.
    identifiable : bool
    """
    JpW = Jp * w_rho[..., None]
    A = np.einsum("sri,srj->sij", JpW, Jp) + DtD
    Bm = np.einsum("sri,srj->sij", JpW, Jt)
    C = np.einsum("sri,srj->ij", Jt * w_rho[..., None], Jt)
    Ainv = psd_inverse(A)
    Mt = C - np.einsum("sia,sij,sjb->ab", Bm, Ainv, Bm)
    # identifiable when the shape parameters leave the transform some information of
    # its own: the Schur diagonal relative to the full diagonal (the fraction of each
    # transform parameter's information not explained away by the shapes), and no
    # near-degenerate combination of the three (correlation-normalized eigenvalues)
    kept = np.diag(Mt) / np.maximum(np.diag(C), 1e-300)
    d = np.sqrt(np.maximum(np.diag(Mt), 1e-300))
    eig = np.linalg.eigvalsh(Mt / np.outer(d, d))
    identifiable = bool(kept.min() > tol and eig.min() > tol)
    return (np.linalg.inv(Mt) if identifiable else np.full((3, 3), np.inf)), identifiable


def scipy_fits(prob: Problem, t, P0, opts: Settings):
    """Reference per-sample fits with ``scipy.optimize.least_squares`` (``trf``, analytic Jacobian), with the
    loss, tolerances and evaluation limit of ``opts``.

    Returns
    -------
    P : ndarray, shape (S, k)
    converged : ndarray (S,) of bool
    messages : list of str
    nfev : ndarray (S,) of int
    """
    D = prob.model.prior_jacobian()
    npr = D.shape[0]
    P = np.empty_like(P0)
    conv, msgs, nfev = [], [], []
    for s in range(P0.shape[0]):
        sub = Problem(np.where(prob.valid[s:s + 1, :, None], prob.Q0[s:s + 1], np.nan),
                      np.where(prob.valid[s:s + 1], 1.0 / np.where(prob.W[s:s + 1] > 0,
                                                                   prob.W[s:s + 1], 1.0), np.nan),
                      prob.geom, prob.model, prob.mirror)
        rows = np.repeat(sub.valid[0], 2)
        cache = {}

        def fun(x, sub=sub, rows=rows, cache=cache):
            r, Jp, *_ = sub.evaluate(t, x[None])
            J = Jp[0][rows]
            r = r[0][rows]
            if npr:
                r = np.concatenate([r, D @ x])
                J = np.concatenate([J, D])
            cache["x"], cache["J"] = x.copy(), J
            return r

        def jac(x, fun=fun, cache=cache):
            if not np.array_equal(cache.get("x"), x):
                fun(x)
            return cache["J"]

        res = least_squares(fun, P0[s], jac=jac, method="trf", x_scale="jac", loss=opts.loss,
                            f_scale=opts.f_scale, ftol=max(opts.ftol, 1e-15), xtol=max(opts.xtol, 1e-15),
                            gtol=1e-12, max_nfev=opts.max_iter)
        P[s] = res.x
        conv.append(res.status > 0)
        msgs.append(str(res.message))
        nfev.append(res.nfev)
    return P, np.array(conv), msgs, np.array(nfev)
