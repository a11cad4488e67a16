"""Orchestration of the shape fits: the joint transform fit, per-sample fits, the experiment.

See :mod:`notchfit.analysis.fitting` for the procedure, the uncertainty model and the
gauge. The numerical work is the batched Levenberg–Marquardt of
:mod:`notchfit.analysis.fitting.lm`; the start values come from
:mod:`notchfit.analysis.fitting.first_pass`. Lengths in m, angles in rad.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ...physics.geometry import Geometry
from ...physics.notches import notch_points
from ...physics.shapes import ShapeModel, get_model
from .first_pass import as_points, as_sigma, estimate_angles, initial_transform
from .lm import Problem, Settings, check_loss, levenberg_marquardt, loss_weights, psd_inverse, schur_cov, scipy_fits
from .results import ExperimentFit, PlaneTransform, SampleFit, as_transform

__all__ = ["fit_experiment", "fit_sample", "fit_samples", "fit_transform"]


def fit_transform(points, geom: Geometry, model="free", *, mirror: bool = False, sigma=2e-5,
                  loss: str = "linear", f_scale: float = 2.0, x0=None, theta0=None,
                  ftol: float = 1e-10, xtol: float = 1e-10, max_iter: int = 100,
                  identifiability_tol: float = 1e-8):
    """Jointly fit the shared plane transform and every sample's shape.

    One least-squares problem over (t_x, t_y, φ) and each sample's parameters
    of ``model``. Its normal matrix is block-arrow shaped (each residual
    depends on the transform and on its own sample only), so each
    Levenberg–Marquardt step is reduced to the three transform unknowns by a
    Schur complement and solved exactly, batched over samples (analytic
    Jacobians throughout). Samples with too few points for ``model`` are
    left out.

    Parameters
    ----------
    points : array_like, shape (S, m, 2)
        Plane-frame points [m], NaN where missing.
    geom : Geometry
    model : str or ShapeModel
    mirror : bool
    sigma : float or array_like, shape (S, m)
        Point uncertainty [m].
    loss, f_scale : str, float
        Loss (as ``scipy.optimize.least_squares``) and its scale in σ units.
    x0 : (tx, ty, phi), optional
        Start [m, m, rad]; :func:`initial_transform` when omitted.
    theta0 : array_like, shape (S, n), optional
        Start angles; :func:`estimate_angles` when omitted.
    ftol, xtol : float
        Relative tolerances on the cost decrease and on the step.
    max_iter : int
        Iteration limit.
    identifiability_tol : float
        Smallest allowed fraction of each transform parameter's information
        that survives eliminating the shapes (Schur-complement diagonal over
        the full diagonal; about 1e-3 for φ with the three base-link points,
        1e-14 without them under the ``free`` model) and smallest
        eigenvalue of the correlation-normalized Schur complement; below
        either the transform is reported as not identifiable (infinite
        covariance).

    Returns
    -------
    transform : PlaneTransform
    params : ndarray, shape (S, k)
        The samples' parameters at the joint optimum (NaN for left-out samples).
    """
    check_loss(loss, f_scale)
    Q = as_points(points, geom)
    S, m = Q.shape[:2]
    sig = as_sigma(sigma, (S, m))
    model = get_model(model, geom.n_joints)
    k = model.n_params
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    use = 2 * valid.sum(1) > k
    if not use.any():
        raise ValueError(f"no sample has enough points to fit model {model.name!r} "
                         f"({k} parameters)")
    t0 = initial_transform(Q, geom, mirror) if x0 is None else tuple(float(v) for v in x0)[:3]
    if theta0 is None:
        theta0 = estimate_angles(Q, geom, (*t0, mirror))
    theta0 = np.nan_to_num(np.asarray(theta0, dtype=float)[use])
    prob = Problem(Q[use], sig[use], geom, model, mirror)
    t, P, conv, nit, r, Jp, Jt, _, _ = levenberg_marquardt(
        prob, np.array(t0), model.initial(theta0), Settings(loss, f_scale, ftol, xtol, max_iter), joint=True)
    w = loss_weights(r * r / f_scale ** 2, loss)
    DtD = model.prior_jacobian().T @ model.prior_jacobian()
    cov, identifiable = schur_cov(Jp, Jt, w, DtD, identifiability_tol)
    ok = bool(conv.all())
    msg = (f"converged in {nit} iterations" if ok else
           f"not converged in {max_iter} iterations")
    if not identifiable:
        msg += (f"; the transform is not identifiable from these points with model "
                f"{model.name!r} (the rotation trades off against θ₁: base-link points missing?)")
    T = PlaneTransform(float(t[0]), float(t[1]), float(t[2]), bool(mirror), cov=cov, fixed=False,
                       model=model.name, identifiable=identifiable, success=ok, message=msg,
                       nfev=int(nit))
    params = np.full((S, k), np.nan)
    params[use] = P
    return T, params


def fit_samples(points, geom: Geometry, model, transform, *, sigma=2e-5, loss: str = "linear",
                f_scale: float = 2.0, theta0=None, samples=None, transform_cov=None,
                min_points=None, solver: str = "lm", ftol: float = 1e-10, xtol: float = 1e-10,
                max_iter: int = 100) -> tuple:
    """Fit each sample's shape parameters with the plane transform fixed.

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Plane-frame points [m], NaN where missing.
    geom : Geometry
    model : str or ShapeModel
    transform : PlaneTransform or (tx, ty, phi, mirror)
    sigma : float or array_like, shape (S, m) or (m,)
        Point uncertainty [m]; NaN drops a point.
    loss, f_scale : str, float
        Loss and its scale in σ units.
    theta0 : array_like, shape (S, n), optional
        Start angles; :func:`estimate_angles` when omitted.
    samples : sequence, optional
        Ids stored in the results (default 0..S-1).
    transform_cov : ndarray, shape (3, 3), optional
        Covariance of (t_x, t_y, φ) to propagate into the parameter
        covariance (module doc); ignored when not finite.
    min_points : int, optional
        Fewest points to attempt a fit; default ``ceil((k + 1) / 2)``, i.e.
        more residuals than parameters.
    solver : {"lm", "scipy"}
        ``lm``: batched Levenberg–Marquardt over all samples at once
        (:func:`notchfit.analysis.fitting.lm.levenberg_marquardt`, the fast default); ``scipy``: one
        ``scipy.optimize.least_squares`` (``trf``) call per sample, with
        the same analytic Jacobian (a cross-check). They reach the same
        optimum except with a robust loss and a smoothness prior: ``lm``
        applies the loss to the point residuals only, scipy to the prior
        rows as well.
    ftol, xtol, max_iter
        Tolerances and iteration limit.

    Returns
    -------
    tuple of SampleFit
        A sample with too few points, or whose fit fails, has
        ``success=False`` and a message; it never raises for the others.
    """
    check_loss(loss, f_scale)
    model = get_model(model, geom.n_joints)
    T = as_transform(transform)
    Q = as_points(points, geom)
    S, m = Q.shape[:2]
    sig = as_sigma(sigma, (S, m))
    samples = tuple(range(S)) if samples is None else tuple(samples)
    if len(samples) != S:
        raise ValueError(f"got {len(samples)} sample ids for {S} samples")
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    sig = np.where(valid, sig, np.nan)
    npts = valid.sum(1)
    if theta0 is None:
        theta0 = estimate_angles(Q, geom, T)
    theta0 = np.asarray(theta0, dtype=float).reshape(S, geom.n_joints)
    theta0 = np.where(np.isfinite(theta0).all(1, keepdims=True), theta0, 0.0)
    out = _screen(samples, model, geom, sig, npts, min_points)
    use = np.array([o is None for o in out])
    if not use.any():
        return tuple(out)
    prob = Problem(Q[use], sig[use], geom, model, T.mirror)
    opts = Settings(loss, f_scale, ftol, xtol, max_iter)
    solved = _solve(prob, T.params, model.initial(theta0[use]), solver, opts)
    data = _Samples(Q[use], sig[use], npts[use], [samples[s] for s in np.nonzero(use)[0]])
    fits = _assemble(prob, T.params, solved, data, opts, transform_cov)
    for s, f in zip(np.nonzero(use)[0], fits):
        out[s] = f
    return tuple(out)


def _failed(sample, model, m, n, sig, n_points, message):
    """A :class:`SampleFit` with NaN results, ``success=False`` and ``message``."""
    k = model.n_params
    nan = float("nan")
    return SampleFit(sample, model.name, model.param_names, np.full(k, nan), np.full((k, k), nan),
                     np.full(n, nan), model.basis, np.full((m, 2), nan), np.full((m, 2), nan), sig,
                     n_points, nan, nan, False, message, 0)


def _screen(samples, model, geom, sig, npts, min_points) -> list:
    """Failed fits for samples with too few points, ``None`` for those to fit."""
    k, m, n = model.n_params, geom.n_points, geom.n_joints
    need = math.ceil((k + 1) / 2) if min_points is None else int(min_points)
    out = [None] * len(samples)
    for s in range(len(samples)):
        if npts[s] == 0:
            out[s] = _failed(samples[s], model, m, n, sig[s], 0, "no valid points (all missing)")
        elif npts[s] < need:
            out[s] = _failed(samples[s], model, m, n, sig[s], int(npts[s]),
                             f"only {npts[s]} valid points for {k} parameters of model "
                             f"{model.name!r} (need at least {need})")
    return out


@dataclass(frozen=True)
class _Samples:
    """The samples solved: points (S, m, 2) [m], σ (S, m) [m], valid points (S,) and ids."""

    Q: np.ndarray
    sig: np.ndarray
    npts: np.ndarray
    ids: list


@dataclass(frozen=True)
class _Solved:
    """Per-sample optimum ``P`` (S, k), converged (S,), messages and evaluation counts (S,)."""

    P: np.ndarray
    conv: np.ndarray
    msgs: list
    nfev: np.ndarray


def _solve(prob, t, P0, solver, opts: Settings) -> _Solved:
    """The per-sample optima of ``prob`` with the transform ``t`` fixed, from ``P0`` (S, k)."""
    if solver == "lm":
        _, P, conv, nit, *_ = levenberg_marquardt(prob, t, P0, opts, joint=False)
        msgs = [f"converged in at most {nit} iterations" if c else
                f"not converged in {opts.max_iter} iterations" for c in conv]
        return _Solved(P, conv, msgs, np.full(P.shape[0], nit))
    if solver == "scipy":
        return _Solved(*scipy_fits(prob, t, P0, opts))
    raise ValueError(f"solver must be 'lm' or 'scipy', got {solver!r}")


def _assemble(prob, t, solved: _Solved, data: _Samples, opts: Settings, transform_cov) -> list:
    """:class:`SampleFit` of every solved sample: covariance, effective parameters, χ², status."""
    model = prob.model
    k = model.n_params
    P, npts = solved.P, data.npts
    r, Jp, Jt, plane, theta = prob.evaluate(t, P)
    w = loss_weights(r * r / opts.f_scale ** 2, opts.loss)
    D = model.prior_jacobian()
    JpW = Jp * w[..., None]
    JtJ = np.einsum("sri,srj->sij", JpW, Jp)
    Ainv = psd_inverse(JtJ + D.T @ D)
    cov = Ainv.copy()
    k_eff = np.einsum("sij,sji->s", Ainv, JtJ)
    if transform_cov is not None and np.isfinite(transform_cov).all() and np.any(transform_cov):
        G = Ainv @ np.einsum("sri,srj->sij", JpW, Jt)
        cov = cov + G @ np.asarray(transform_cov, dtype=float) @ np.swapaxes(G, 1, 2)
    resid = plane - data.Q
    chi2 = (r * r).sum(-1)
    out = []
    for j in range(len(data.ids)):
        ok = bool(solved.conv[j] and np.isfinite(P[j]).all())
        msg = solved.msgs[j]
        if model.n_prior == 0 and k_eff[j] < k - 0.5:
            # a parameter the points do not determine (e.g. only base-link points, or a
            # free-model joint whose links lost all their points)
            ok = False
            msg = (f"the {npts[j]} valid points determine only {k_eff[j]:.0f} of the {k} "
                   f"parameters of model {model.name!r}")
        out.append(SampleFit(data.ids[j], model.name, model.param_names, P[j], cov[j], theta[j],
                             model.basis, plane[j], resid[j], data.sig[j], int(npts[j]), float(k_eff[j]),
                             float(chi2[j]), ok, msg, int(solved.nfev[j])))
    return out


def fit_sample(points, geom: Geometry, model, transform, *, sigma=2e-5, sample=0, theta0=None,
               **kw) -> SampleFit:
    """Fit one sample (points (m, 2)) with the transform fixed; see :func:`fit_samples`."""
    Q = as_points(points, geom)
    if Q.shape[0] != 1:
        raise ValueError(f"fit_sample takes one sample, points of shape ({geom.n_points}, 2)")
    sig = np.asarray(sigma, dtype=float)
    return fit_samples(Q, geom, model, transform, sigma=sig if sig.ndim == 0 else sig[None],
                       samples=(sample,), theta0=None if theta0 is None else np.asarray(theta0)[None],
                       **kw)[0]


def fit_experiment(points, geom: Geometry, models=("cc", "linear"), *, mirror: bool = False,
                   sigma=None, loss: str = "linear", f_scale: float = 2.0, transform=None,
                   transform_model="free", samples=None, include_transform_uncertainty: bool = True,
                   sigma_default: float = 2e-5, min_points=None, solver: str = "lm",
                   ftol: float = 1e-10, xtol: float = 1e-10, max_iter: int = 100) -> ExperimentFit:
    """Fit every sample of one experiment with each shape model (Sec. IV-A).

    Parameters
    ----------
    points : array_like, shape (S, m, 2) or (m, 2)
        Measured notch points in the plane frame [m]; NaN (or a missing
        point) is dropped from the residuals.
    geom : Geometry
    models : sequence of str or ShapeModel
        Registry names (:func:`notchfit.physics.shapes.get_model`).
    mirror : bool
        The experiment's ``mirror`` flag (a view from -y, Fig. 12).
    sigma : float or array_like (S, m) or (m,), optional
        Point uncertainty [m]. ``None``: estimated from the pooled residuals
        of the ``transform_model`` fit (module doc).
    loss : str
        ``linear`` (least squares), ``soft_l1``, ``huber``, ``cauchy`` or ``arctan``.
    f_scale : float
        Robust-loss scale in units of σ.
    transform : PlaneTransform or (tx, ty, phi), optional
        Fixed plane transform [m, m, rad]; estimated jointly when omitted.
    transform_model : str
        Shape model used for the joint transform estimate (default ``free``),
        and for the σ estimate.
    samples : sequence, optional
        Sample ids (default 0..S-1).
    include_transform_uncertainty : bool
        Add the estimated transform's propagated covariance to every
        sample's parameter covariance.
    sigma_default : float
        σ [m] used to whiten the first pass when ``sigma`` is None.
    min_points : int, optional
        See :func:`fit_samples`.
    solver : {"lm", "scipy"}
        Per-sample solver, see :func:`fit_samples`.
    ftol, xtol, max_iter
        Tolerances and iteration limit (joint and per-sample fits).

    Returns
    -------
    ExperimentFit
        A sample that cannot be fitted (all NaN, too few points) has
        ``success=False`` and a message; the others are unaffected.
    """
    check_loss(loss, f_scale)
    Q = as_points(points, geom)
    S, m = Q.shape[:2]
    samples = _sample_ids(samples, S)
    shape_models = _shape_models(models, geom.n_joints)
    names = tuple(sm.name for sm in shape_models)
    tmodel = get_model(transform_model, geom.n_joints)
    settings = dict(loss=loss, f_scale=f_scale, ftol=ftol, xtol=xtol, max_iter=max_iter)
    sigma_estimated = sigma is None
    sig = as_sigma(sigma_default if sigma is None else sigma, (S, m))
    valid = np.isfinite(Q).all(-1) & np.isfinite(sig)
    pts = _Points(Q, valid, sig, geom, mirror, sigma_estimated)
    if transform is None:
        T, sig, theta_start = _joint_transform(pts, tmodel, sigma_default, settings)
    else:
        T, sig, theta_start = _given_transform(pts, tmodel, transform,
                                               dict(settings, min_points=min_points, solver=solver))
    if theta_start is None or not np.isfinite(theta_start).all():
        est = estimate_angles(Q, geom, T)
        theta_start = est if theta_start is None else np.where(np.isfinite(theta_start), theta_start, est)

    tcov = T.cov if (include_transform_uncertainty and not T.fixed) else None
    fits = tuple(fit_samples(Q, geom, sm, T, sigma=sig, theta0=theta_start, samples=samples,
                             transform_cov=tcov, min_points=min_points, solver=solver, **settings)
                 for sm in shape_models)
    return ExperimentFit(T, names, samples, fits, Q, np.where(valid, sig, np.nan),
                         sigma_estimated, geom, loss, float(f_scale))


def _sample_ids(samples, S) -> tuple:
    """Sample ids (default 0..S-1), checked: one per sample, unique."""
    samples = tuple(range(S)) if samples is None else tuple(samples)
    if len(samples) != S:
        raise ValueError(f"got {len(samples)} sample ids for {S} samples")
    if len(set(samples)) != S:
        raise ValueError("sample ids must be unique")
    return samples


def _shape_models(models, n_joints) -> list:
    """The requested shape models (names or ShapeModel), at least one, distinct."""
    if isinstance(models, (str, ShapeModel)):
        models = (models,)
    shape_models = [get_model(mm, n_joints) for mm in models]
    names = tuple(sm.name for sm in shape_models)
    if not names:
        raise ValueError("models must name at least one shape model")
    if len(set(names)) != len(names):
        raise ValueError(f"models must be distinct, got {names}")
    return shape_models


@dataclass(frozen=True)
class _Points:
    """One experiment's points (S, m, 2) [m], which are valid (S, m), their σ (S, m) [m] (the nominal one
    when ``sigma_estimated``), its geometry and ``mirror`` flag."""

    Q: np.ndarray
    valid: np.ndarray
    sig: np.ndarray
    geom: Geometry
    mirror: bool
    sigma_estimated: bool


def _joint_transform(pts: _Points, tmodel, sigma_default, settings):
    """Step 2 of :func:`fit_experiment`: the transform estimated jointly (and σ when not given).

    Returns the transform, the σ (S, m) [m] to use and the start angles (S, n).
    """
    Q, geom, mirror, sig = pts.Q, pts.geom, pts.mirror, pts.sig
    loss = settings["loss"]
    T, Pt = fit_transform(Q, geom, tmodel, mirror=mirror, sigma=sig, **settings)
    theta_start = Pt @ tmodel.basis.T
    if pts.sigma_estimated:
        s_hat = _estimate_sigma(pts, Pt, tmodel, T, loss)
        sig = np.where(np.isfinite(sig), s_hat, np.nan)
        if loss != "linear":     # refit: f_scale is in units of the (now known) σ
            T, Pt = fit_transform(Q, geom, tmodel, mirror=mirror, sigma=sig, x0=T.params,
                                  theta0=np.nan_to_num(theta_start), **settings)
            theta_start = Pt @ tmodel.basis.T
        # the transform covariance was computed with the nominal σ: rescale
        factor = (s_hat / sigma_default) ** 2 if loss == "linear" else 1.0
        if factor != 1.0:
            T = dataclasses.replace(T, cov=T.cov * factor)
    return T, sig, theta_start


def _given_transform(pts: _Points, tmodel, transform, settings):
    """Step 2 with the transform given: σ estimated from ``tmodel`` fits when not given.

    Returns the transform, the σ (S, m) [m] to use and the start angles (S, n) or None.
    """
    T = as_transform(transform, pts.mirror)
    if T.mirror != bool(pts.mirror):
        raise ValueError(f"transform.mirror={T.mirror} disagrees with mirror={bool(pts.mirror)}")
    if not pts.sigma_estimated:
        return T, pts.sig, None
    fits_t = fit_samples(pts.Q, pts.geom, tmodel, T, sigma=pts.sig, **settings)
    Pt = np.stack([f.params for f in fits_t])
    s_hat = _estimate_sigma(pts, Pt, tmodel, T, settings["loss"])
    sig = np.where(np.isfinite(pts.sig), s_hat, np.nan)
    return T, sig, np.stack([f.theta for f in fits_t])


def _estimate_sigma(pts: _Points, P, model, T, loss) -> float:
    """Pooled per-coordinate noise estimate [m] from a fit's residuals."""
    Q, valid, geom = pts.Q, pts.valid, pts.geom
    ok = np.isfinite(P).all(1)
    if not ok.any():
        raise ValueError("cannot estimate sigma: no sample could be fitted; pass sigma explicitly")
    th = P[ok] @ model.basis.T
    pred = T.to_plane(notch_points(th, geom))
    r = (pred - Q[ok])[valid[ok]]
    r = r[np.isfinite(r)]
    dof = r.size - ok.sum() * model.n_params - (0 if T.fixed else 3)
    if dof <= 0:
        raise ValueError("cannot estimate sigma: no residual degrees of freedom; pass sigma explicitly")
    if loss == "linear":
        s = math.sqrt(float(np.sum(r * r)) / dof)
    else:
        s = 1.4826 * float(np.median(np.abs(r))) * math.sqrt(r.size / dof)
    if not s > 0:
        raise ValueError("cannot estimate sigma: the residuals are zero; pass sigma explicitly")
    return s
