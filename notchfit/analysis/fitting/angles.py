"""Shape models fitted to measured joint angles (``angles.csv``; Sec. IV-A in angle space).

Labs that measure the angle of every notch (real tubes, docs/data-formats.md
``angles.csv``) need no plane transform: every shape model of
:mod:`notchfit.physics.shapes` is linear in its parameters, ``θ = B · params``, so each
sample's fit is a weighted linear least-squares problem over the joints that
were measured,

    min Σ_j ((B params − θ_meas)_j / σ)²  (+ the ``free_smooth`` prior λ Δ²θ),

solved in closed form. σ is the experiment's ``[uncertainty] angle_deg``, or,
when not given, estimated once per experiment from the pooled residuals of a
low-order shape (:func:`estimate_angle_sigma`).
Standard errors are ``σ² (AᵀA)⁻¹`` of the whitened problem; χ² = Σ (r/σ)²,
AIC = χ² + 2k, BIC = χ² + k ln N (N measured angles of the sample), with ``k``
the trace of the hat matrix (less than the parameter count with the prior).
Residuals are ``θ_model − θ_meas`` [rad], NaN where an angle was not measured.

:func:`angle_fits_table` and :func:`jointwise_table` are the files
``angle_fits.csv`` and ``jointwise.csv`` of ``notchfit fit`` (docs/data-formats.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...physics.shapes import get_model, line_fit
from ...units import DEG

__all__ = ["DEFAULT_ANGLE_SIGMA", "AngleFit", "ModelAngleFit", "angle_fits_table", "estimate_angle_sigma",
           "fit_angles", "jointwise_table"]

#: Angle uncertainty used when none is given and none can be estimated [rad] (0.5°).
DEFAULT_ANGLE_SIGMA = 0.5 * DEG


@dataclass(frozen=True)
class ModelAngleFit:
    """One shape model fitted to every sample of an experiment (S samples, n joints, k parameters).

    Attributes
    ----------
    model : str
    param_names : tuple of str
    params, se : ndarray (S, k)
        Parameters [rad] and their standard errors (NaN for a failed sample).
    theta : ndarray (S, n) [rad]
        Fitted joint angles.
    residuals : ndarray (S, n) [rad]
        ``θ_model − θ_meas``; NaN where not measured.
    a, b, se_a, se_b : ndarray (S,) [rad]
        ``θ_j = a + b j``: the model's own ``a``, ``b`` for cc (b = 0), linear and
        quadratic, else the least-squares line through the fitted angles with its
        propagated standard errors.
    chi2, k_eff, aic, bic : ndarray (S,)
    n_angles : ndarray (S,) int
        Angles measured in the sample.
    sigma : float [rad]
        σ used (given, or :func:`estimate_angle_sigma`).
    success : ndarray (S,) bool
    message : tuple of str
    """

    model: str
    param_names: tuple
    params: np.ndarray = field(repr=False)
    se: np.ndarray = field(repr=False)
    theta: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    a: np.ndarray = field(repr=False)
    b: np.ndarray = field(repr=False)
    se_a: np.ndarray = field(repr=False)
    se_b: np.ndarray = field(repr=False)
    chi2: np.ndarray = field(repr=False)
    k_eff: np.ndarray = field(repr=False)
    aic: np.ndarray = field(repr=False)
    bic: np.ndarray = field(repr=False)
    n_angles: np.ndarray = field(repr=False)
    sigma: float = math.nan
    success: np.ndarray = field(default=None, repr=False)
    message: tuple = ()

    @property
    def rms(self) -> np.ndarray:
        """Rms of each sample's residuals [rad] (S,); NaN without measured angles."""
        r = self.residuals
        ok = np.isfinite(r)
        n = ok.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, np.sqrt(np.where(ok, r * r, 0.0).sum(axis=1) / np.maximum(n, 1)), np.nan)

    @property
    def max_error(self) -> np.ndarray:
        """Largest ``|θ_model − θ_meas|`` of each sample [rad] (S,)."""
        r = np.abs(self.residuals)
        return np.where(np.isfinite(r).any(axis=1), np.nanmax(np.where(np.isfinite(r), r, -1.0), axis=1), np.nan)


@dataclass(frozen=True)
class AngleFit:
    """Every requested model fitted to one experiment's measured angles.

    Attributes
    ----------
    samples : tuple
        Sample ids.
    measured : ndarray (S, n) [rad]
        The measured angles (NaN = not measured).
    fits : tuple of ModelAngleFit
        One per model, in the order requested.
    """

    samples: tuple
    measured: np.ndarray = field(repr=False)
    fits: tuple = ()

    @property
    def models(self) -> tuple:
        return tuple(f.model for f in self.fits)

    def get(self, model: str) -> ModelAngleFit:
        """The fit of ``model`` (by its registry name)."""
        for f in self.fits:
            if f.model == model:
                return f
        raise KeyError(f"model {model!r} was not fitted (fitted: {', '.join(self.models)})")


def _line_projection(n: int) -> np.ndarray:
    """(2, n): ``(a, b)`` of the least-squares line ``a + b j`` through θ (as :func:`notchfit.physics.shapes.line_fit`)."""
    return np.stack(line_fit(np.eye(n)), axis=0)


def _solve_sample(B, prior, theta, ok, sigma):
    """Whitened least squares of one sample: params, their covariance ``(AᵀA)⁻¹``, the whitened
    residuals of the measured rows, and the trace of the hat matrix."""
    Bw = B[ok] / sigma
    A = np.vstack([Bw, prior])
    y = np.concatenate([theta[ok] / sigma, np.zeros(prior.shape[0])])
    p, *_ = np.linalg.lstsq(A, y, rcond=None)
    cov = np.linalg.pinv(A.T @ A)
    return p, cov, Bw @ p - y[:Bw.shape[0]], float(np.trace(Bw @ cov @ Bw.T))


def _fit_model(name: str, meas: np.ndarray, sigma: float) -> ModelAngleFit:
    """One model on every sample with the angle uncertainty ``sigma`` [rad] (:func:`fit_angles`)."""
    S, n = meas.shape
    model = get_model(name, n)
    B, prior, k = model.basis, model._prior, model.n_params
    params, se = np.full((S, k), np.nan), np.full((S, k), np.nan)
    theta, ab_se = np.full((S, n), np.nan), np.full((S, 2), np.nan)
    chi2, k_eff = np.full(S, np.nan), np.full(S, np.nan)
    success = np.zeros(S, bool)
    msgs = []
    n_ang = np.isfinite(meas).sum(axis=1)
    P = _line_projection(n)
    for s in range(S):
        ok = np.isfinite(meas[s])
        if n_ang[s] == 0 or n_ang[s] + prior.shape[0] < k:
            msgs.append(f"{n_ang[s]} measured angles for {k} parameters")
            continue
        p, cov, r, ke = _solve_sample(B, prior, meas[s], ok, sigma)
        params[s], se[s] = p, np.sqrt(np.clip(np.diag(cov), 0.0, None))
        ab_se[s] = np.sqrt(np.clip(np.diag(P @ B @ cov @ B.T @ P.T), 0.0, None))
        theta[s], chi2[s], k_eff[s], success[s] = B @ p, float(r @ r), ke, True
        msgs.append("")
    a, b = line_fit(theta)
    if model.param_names[:2] == ("a", "b"):
        a, b, ab_se = params[:, 0], params[:, 1], se[:, :2]
    elif model.param_names == ("a",):
        a, b = params[:, 0], np.where(success, 0.0, np.nan)
        ab_se = np.stack([se[:, 0], np.where(success, 0.0, np.nan)], axis=1)
    return ModelAngleFit(model=model.name, param_names=model.param_names, params=params, se=se, theta=theta,
                         residuals=np.where(np.isfinite(meas), theta - meas, np.nan), a=a, b=b,
                         se_a=ab_se[:, 0], se_b=ab_se[:, 1], chi2=chi2, k_eff=k_eff, aic=chi2 + 2 * k_eff,
                         bic=chi2 + k_eff * np.log(np.maximum(n_ang, 1)), n_angles=n_ang, sigma=sigma,
                         success=success, message=tuple(msgs))


def estimate_angle_sigma(angles, *, default: float = DEFAULT_ANGLE_SIGMA) -> float:
    """Angle uncertainty [rad] from the pooled, dof-corrected residuals of a low-order shape.

    The quadratic model (linear for 3 joints, cc for 2) leaves only the
    measurement noise on a smooth bend; ``default`` when no sample has
    residual degrees of freedom.
    """
    meas = np.asarray(angles, dtype=float)
    n = meas.shape[1]
    if n < 2:
        return default
    name = "quadratic" if n >= 4 else ("linear" if n == 3 else "cc")
    f = _fit_model(name, meas, 1.0)
    dof = float(np.sum((f.n_angles - f.k_eff)[f.success]))
    if dof <= 0.5:
        return default
    sig = math.sqrt(float(np.nansum(f.chi2)) / dof)
    return sig if sig > 0 else default


def fit_angles(angles, models=("cc", "linear"), *, sigma: float | None = None, samples=None) -> AngleFit:
    """Fit shape models to every sample's measured joint angles (module docstring).

    Parameters
    ----------
    angles : array_like, shape (S, n) [rad]
        Measured angles, NaN where not measured.
    models : sequence of str
        Registry names of :func:`notchfit.physics.shapes.get_model`.
    sigma : float, optional
        Angle uncertainty [rad] (> 0); when None, :func:`estimate_angle_sigma`
        (one σ for every model, so that χ², AIC and BIC compare across models).
    samples : sequence, optional
        Sample ids (default 0..S-1).

    Returns
    -------
    AngleFit
        A sample with fewer measured angles than a model has parameters fails
        for that model (``success`` False, with the reason).
    """
    meas = np.asarray(angles, dtype=float)
    if meas.ndim != 2 or meas.shape[1] < 1:
        raise ValueError(f"angles must have shape (S, n), got {meas.shape}")
    if np.isinf(meas).any():
        raise ValueError("angles contain inf (NaN marks an angle not measured)")
    if sigma is not None and not (math.isfinite(sigma) and sigma > 0):
        raise ValueError(f"sigma must be > 0 rad, got {sigma!r}")
    if not models:
        raise ValueError("fit_angles needs at least one model")
    ids = tuple(range(meas.shape[0])) if samples is None else tuple(samples)
    if len(ids) != meas.shape[0]:
        raise ValueError(f"samples has {len(ids)} ids for {meas.shape[0]} samples")
    sig = estimate_angle_sigma(meas) if sigma is None else float(sigma)
    return AngleFit(samples=ids, measured=meas, fits=tuple(_fit_model(m, meas, sig) for m in models))


def angle_fits_table(result: AngleFit) -> pd.DataFrame:
    """``angle_fits.csv``: one row per sample and model (docs/data-formats.md).

    Columns: ``sample, model, a, b,`` model-specific parameters (``c``,
    ``s1…sk``), ``theta_1…theta_n`` [rad], ``rms_deg, max_deg, n_angles, se_a,
    se_b`` [rad], ``chi2, k_eff, aic, bic, sigma_deg, success, message``.
    """
    n = result.measured.shape[1]
    extra = []
    for f in result.fits:
        for pn in f.param_names:
            if pn not in ("a", "b") and not pn.startswith("theta_") and pn not in extra:
                extra.append(pn)
    frames = []
    for f in result.fits:
        cols = {"sample": list(result.samples), "model": f.model, "a": f.a, "b": f.b}
        pmap = {pn: f.params[:, i] for i, pn in enumerate(f.param_names)}
        for pn in extra:
            cols[pn] = pmap.get(pn, np.full(len(result.samples), np.nan))
        for j in range(n):
            cols[f"theta_{j + 1}"] = f.theta[:, j]
        cols.update({"rms_deg": f.rms / DEG, "max_deg": f.max_error / DEG, "n_angles": f.n_angles,
                     "se_a": f.se_a, "se_b": f.se_b, "chi2": f.chi2, "k_eff": f.k_eff, "aic": f.aic,
                     "bic": f.bic, "sigma_deg": f.sigma / DEG, "success": f.success, "message": list(f.message)})
        frames.append(pd.DataFrame(cols))
    return pd.concat(frames, ignore_index=True)


def jointwise_table(result: AngleFit) -> pd.DataFrame:
    """``jointwise.csv``: ``sample, model, joint, err_deg`` (``θ_model − θ_meas``; empty where not measured)."""
    S, n = result.measured.shape
    frames = [pd.DataFrame({"sample": np.repeat(np.array(result.samples, dtype=object), n), "model": f.model,
                            "joint": np.tile(np.arange(1, n + 1), S), "err_deg": (f.residuals / DEG).ravel()})
              for f in result.fits]
    df = pd.concat(frames, ignore_index=True)
    df["sample"] = df["sample"].infer_objects()
    return df
