"""The noise floor and the statistics of held-out errors.

The noise floor is the squared point error a perfect model would leave:
``2 σ_p²`` from the point uncertainty plus the load-cell uncertainty ``σ_T``
propagated through the model (with the paper's ±0.11 N load cells it
dominates: about 0.1 mm). Improvements of held-out errors are tested per
sample, with the serial correlation of one experiment's samples accounted
for (docs/diagnosis.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..friction import simulate
from ..notches import notch_points
from .calibration import SimulationCache
from .prepare import Prepared
from .specs import model_params

__all__ = ["noise_floor", "paired_z", "pooled_mse", "pooled_rms"]


def _frame_free(prep: Prepared, theta) -> np.ndarray:
    """What is compared, in a frame that does not depend on the registration: notch points in the
    manipulator frame (a rigid registration keeps distances) or the joint angles."""
    return theta if prep.metric == "angles" else notch_points(theta, prep.geom)


def noise_floor(prep: Prepared, values: dict, cache: SimulationCache | None = None, *,
                draws: int = 4, seed: int = 0, base=None) -> np.ndarray:
    """Expected squared error of a perfect model, per sample [m² per point or rad² per angle] (S,).

    Point noise gives ``2 σ_p²`` (angle noise ``σ_θ²``). Load-cell noise ``σ_T`` enters through the
    model's input: the tensions the simulator is driven with are the noisy
    measured ones. Its effect is estimated by Monte Carlo: the experiment is
    re-simulated ``draws`` times with independent Gaussian noise of standard
    deviation ``σ_T`` added to every measured tension, and the mean squared
    change of the predicted points is added. Independent per-sample noise
    matters more than a common offset: a small spurious reversal of the
    tension makes cables stick and changes the friction history.

    Parameters
    ----------
    prep : Prepared
    values : dict
        Model parameters by name.
    cache : SimulationCache, optional
    draws : int
        Monte Carlo draws (0: point noise only).
    seed : int
        Seed of the draws: ``numpy.random.default_rng([seed, S, round(1e6 σ_T)])``.
    base : FrictionParams, optional
        The model the values change (default: the paper's).

    Returns
    -------
    ndarray, shape (S,) [m² or rad²]
    """
    floor = np.full(len(prep.time), prep.point_factor * prep.sigma**2)
    if not prep.tension_sigma or draws < 1:
        return floor
    params, _ = model_params(values, base)
    ref = _frame_free(prep, (cache or SimulationCache()).theta(prep, params))
    rng = np.random.default_rng([seed, len(prep.time), int(1e6 * prep.tension_sigma)])
    acc = np.zeros(len(prep.time))
    # a tendon the tube lacks carries no tension, with or without noise
    has = {side: side in prep.geom.tendons for side in ("left", "right")}
    for _ in range(draws):
        tl = np.maximum(prep.tension_left + rng.normal(0.0, prep.tension_sigma, len(prep.time)), 0.0)
        tr = np.maximum(prep.tension_right + rng.normal(0.0, prep.tension_sigma, len(prep.time)), 0.0)
        th = simulate(prep.time, tl if has["left"] else None, tr if has["right"] else None, params, prep.geom,
                      method="fast", ramp_time=prep.ramp_time).theta
        d = _frame_free(prep, th) - ref
        d2 = np.sum(d**2, axis=-1) if prep.metric == "points" else d**2
        d2[~prep.valid] = np.nan
        acc += np.nanmean(d2, axis=1)
    return floor + acc / draws


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
