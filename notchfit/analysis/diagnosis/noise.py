"""The statistics of held-out errors (the noise floor is the estimation core's,
:func:`notchfit.analysis.estimation.noise.noise_floor`).

Improvements of held-out errors are tested per sample, with the serial
correlation of one experiment's samples accounted for (docs/diagnosis.md).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["paired_z", "pooled_mse", "pooled_rms"]


def _effective_n(x: np.ndarray) -> float:
    """Effective number of independent values of a serially correlated series.

    ``n (1 − ρ₁)/(1 + ρ₁)`` with the lag-1 autocorrelation ρ₁ clipped to
    [0, 0.99]; non-finite values are dropped.
    """
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

    Parameters
    ----------
    base_mse, cand_mse : list of ndarray, shape (S_i,) [m²]
        Per experiment, the mean squared point error of each held-out sample.

    Returns
    -------
    float
        Positive when the candidate is better.
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


def pooled_mse(mse_list) -> float:
    """Mean of per-sample squared errors pooled over experiments [m² or rad²] (NaN samples left out).

    Parameters
    ----------
    mse_list : list of ndarray, shape (S_i,)
    """
    return float(np.nanmean(np.concatenate(mse_list)))


def pooled_rms(mse_list, mask_list=None) -> float:
    """Root of the mean of per-sample squared errors pooled over experiments [m].

    Parameters
    ----------
    mse_list : list of ndarray, shape (S_i,) [m²]
    mask_list : list of bool ndarray, shape (S_i,), optional
        Samples to include (e.g. one regime); non-finite values are dropped.

    Returns
    -------
    float
        NaN when no sample is selected.
    """
    vals = []
    for i, m in enumerate(mse_list):
        sel = np.isfinite(m) if mask_list is None else (np.isfinite(m) & mask_list[i])
        vals.append(m[sel])
    v = np.concatenate(vals) if vals else np.array([])
    return float(math.sqrt(np.mean(v))) if len(v) else float("nan")
