"""Tables of the shape fits: ``fits.csv`` and ``pointwise.csv`` (docs/data-formats.md), model comparison.

The tables are the file layout of the fits, in file units (mm, rad); the
result objects they are built from hold SI values (m, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...physics.shapes import get_model
from ...units import MM
from ..lack_of_fit import lack_of_fit_summary
from .results import ExperimentFit

__all__ = ["StudyFit", "compare_models", "failed_fits", "fit_summary", "fits_table", "pointwise_table"]


def fits_table(result: ExperimentFit, *, include_theta: bool = True) -> pd.DataFrame:
    """One row per sample and model, the ``fits.csv`` layout of docs/data-formats.md.

    Columns: ``sample, model, a, b,`` then model-specific parameters (``c``,
    ``s1…sk``; NaN for models without them), ``theta_1…theta_n`` (the fitted
    joint angles of every model, when ``include_theta``), then
    ``base_x_mm, base_y_mm, base_phi_rad, rms_mm, max_mm, n_points``, then
    ``se_a, se_b, chi2, k_eff, aic, bic, sigma_mm, success, message``.

    ``a``, ``b`` [rad] are the literal parameters for cc (b = 0 exactly, se_b
    = 0: the model fixes it), linear and quadratic; for the piecewise and free
    models they are the least-squares line ``a + b j`` through the fitted
    θ_j, with its propagated standard errors. ``rms_mm``/``max_mm`` are the
    rms and maximum of the pointwise error ``||Q_i − Q̃_i||`` (Sec. IV-A).
    """
    n = result.geom.n_joints
    extra = []
    for name in result.models:
        for pn in get_model(name, n).param_names:
            if pn not in ("a", "b") and not pn.startswith("theta_") and pn not in extra:
                extra.append(pn)
    theta_cols = [f"theta_{j}" for j in range(1, n + 1)] if include_theta else []
    T = result.transform
    rows = []
    for name, fs in zip(result.models, result.fits):
        for f in fs:
            row = {"sample": f.sample, "model": name, "a": f.a, "b": f.b}
            pmap = dict(zip(f.param_names, f.params))
            for pn in extra:
                row[pn] = pmap.get(pn, np.nan)
            for j, c in enumerate(theta_cols):
                row[c] = f.theta[j]
            sig = f.sigma[np.isfinite(f.sigma)]
            row.update({
                "base_x_mm": T.tx / MM, "base_y_mm": T.ty / MM, "base_phi_rad": T.phi,
                "rms_mm": f.rms / MM, "max_mm": f.max_error / MM, "n_points": f.n_points,
                "se_a": f.se_a, "se_b": f.se_b, "chi2": f.chi2, "k_eff": f.k_eff,
                "aic": f.aic, "bic": f.bic,
                "sigma_mm": float(np.median(sig)) / MM if sig.size else np.nan,
                "success": f.success, "message": f.message,
            })
            rows.append(row)
    cols = (["sample", "model", "a", "b"] + extra + theta_cols
            + ["base_x_mm", "base_y_mm", "base_phi_rad", "rms_mm", "max_mm", "n_points",
               "se_a", "se_b", "chi2", "k_eff", "aic", "bic", "sigma_mm", "success", "message"])
    df = pd.DataFrame(rows, columns=cols)
    df["n_points"] = df["n_points"].astype(int)
    df["success"] = df["success"].astype(bool)
    return df


def pointwise_table(result: ExperimentFit) -> pd.DataFrame:
    """``pointwise.csv`` of docs/data-formats.md: ``sample, model, point, err_mm``.

    One row per sample, model and point (point 1-based, docs/geometry.md
    numbering); ``err_mm = ||Q_i − Q̃_i||`` (Sec. IV-A, Figs. 13–14), NaN for
    a missing point or a failed fit.
    """
    m = result.geom.n_points
    frames = []
    for name in result.models:
        E = result.errors(name) / MM                       # (S, m)
        frames.append(pd.DataFrame({
            "sample": np.repeat(np.array(result.samples, dtype=object), m),
            "model": name,
            "point": np.tile(np.arange(1, m + 1), len(result.samples)),
            "err_mm": E.ravel(),
        }))
    df = pd.concat(frames, ignore_index=True)
    df["sample"] = df["sample"].infer_objects()
    return df


def compare_models(result: ExperimentFit) -> pd.DataFrame:
    """Model comparison over the whole experiment (Sec. IV-A).

    Sums over the successfully fitted samples: ``n_samples``, ``n_failed``,
    ``n_points``, ``k_eff`` (effective parameters), ``chi2``, ``aic``
    (χ² + 2k), ``bic`` (χ² + k ln N, N the number of coordinates), the rms
    and maximum pointwise error [mm] over all points, and ``delta_aic``,
    ``delta_bic`` relative to the best model. The shared transform adds the
    same 3 parameters to every model and is left out.

    Returns
    -------
    DataFrame, one row per model.
    """
    rows = []
    for name, fs in zip(result.models, result.fits):
        ok = [f for f in fs if f.success]
        e = np.concatenate([f.errors for f in ok]) if ok else np.array([])
        e = e[np.isfinite(e)]
        npts = sum(f.n_points for f in ok)
        k = sum(f.k_eff for f in ok)
        chi2 = sum(f.chi2 for f in ok)
        rows.append({
            "model": name, "n_samples": len(ok), "n_failed": len(fs) - len(ok),
            "n_points": npts, "k_eff": k, "chi2": chi2,
            "aic": chi2 + 2 * k, "bic": chi2 + k * math.log(max(2 * npts, 1)),
            "rms_mm": float(np.sqrt(np.mean(e * e))) / MM if e.size else np.nan,
            "max_mm": float(e.max()) / MM if e.size else np.nan,
        })
    df = pd.DataFrame(rows)
    df["delta_aic"] = df["aic"] - df["aic"].min()
    df["delta_bic"] = df["bic"] - df["bic"].min()
    return df


def fit_summary(fits: pd.DataFrame) -> pd.DataFrame:
    """Per-model summary of ``fits.csv`` rows (one or several experiments) over the successful fits.

    Parameters
    ----------
    fits : DataFrame
        Rows of :func:`fits_table` (``model``, ``rms_mm``, ``max_mm``, ``success``).

    Returns
    -------
    DataFrame
        One row per model in order of appearance: ``model``, ``rms_mm`` (the
        rms of the samples' rms errors [mm]), ``max_mm`` (the largest
        pointwise error [mm]), ``n_samples``.
    """
    ok = fits["success"].astype(bool) if "success" in fits else np.ones(len(fits), bool)
    rows = []
    for model, g in fits[ok].groupby("model", sort=False):
        r = g["rms_mm"].to_numpy(float)
        rows.append({"model": model, "rms_mm": float(np.sqrt(np.mean(r ** 2))),
                     "max_mm": float(g["max_mm"].max()), "n_samples": len(g)})
    return pd.DataFrame(rows, columns=["model", "rms_mm", "max_mm", "n_samples"])


@dataclass(frozen=True)
class StudyFit:
    """The shape fits of a study (``notchfit fit``): the rows of every fitted experiment.

    Attributes
    ----------
    point_fits : DataFrame or None
        ``fits.csv`` rows of the experiments fitted to notch points (:func:`fits_table`).
    angle_fits : DataFrame or None
        ``angle_fits.csv`` rows of those fitted to measured joint angles (``rms_deg``, ``max_deg``).
    n_fitted, n_total : int
        Experiments fitted, and asked for.
    seconds : float
        Wall time of the fits [s].
    lack_of_fit : dict or None
        Model -> tube -> :class:`notchfit.analysis.lack_of_fit.LackOfFit`: each shape model's error
        against the trials' scatter (:func:`notchfit.analysis.lack_of_fit.shape_fit_lack_of_fit`).
    """

    point_fits: pd.DataFrame | None
    angle_fits: pd.DataFrame | None
    n_fitted: int
    n_total: int
    seconds: float
    lack_of_fit: dict | None = None

    def summary(self) -> str:
        """Per model the rms and largest error over the successful fits, then the count."""
        lines = []
        if self.point_fits is not None:
            lines += [f"  {r.model:12s} rms {r.rms_mm:.4f} mm, max {r.max_mm:.4f} mm over {r.n_samples} samples"
                      for r in fit_summary(self.point_fits).itertuples(index=False)]
        if self.angle_fits is not None:
            df = self.angle_fits
            for model, g in df[df["success"]].groupby("model", sort=False):
                rms = float(np.sqrt(np.mean(g["rms_deg"].to_numpy(float) ** 2)))
                lines.append(f"  {model:12s} rms {rms:.3f} deg, max {g['max_deg'].max():.3f} deg over {len(g)} "
                             "samples (measured angles)")
        for model, tables in (self.lack_of_fit or {}).items():
            if tables:
                lines.append(f"{model}: " + lack_of_fit_summary(tables))
        lines.append(f"fit: {self.n_fitted} of {self.n_total} experiments fitted in {self.seconds:.1f} s")
        return "\n".join(lines)


def failed_fits(fits: pd.DataFrame) -> pd.DataFrame:
    """The rows of ``fits.csv`` whose fit failed (``success`` false): sample, model, message."""
    if "success" not in fits:
        return fits.iloc[:0][["sample", "model"]]
    bad = fits[~fits["success"].astype(bool)]
    return bad[[c for c in ("sample", "model", "message") if c in bad]]
