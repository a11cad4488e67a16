"""Cross-validation by experiment: folds, held-out predictions, the fan-out of the fits.

Every (model × fold) calibration is one independent item of
:func:`notchfit.batch.run_batch`: it runs here, in worker processes or on a
Dask cluster, with native libraries single-threaded (the matrices are small:
BLAS threads only contend).
"""

from __future__ import annotations

import multiprocessing
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ..batch import run_batch
from .calibration import Calibration, SimulationCache, calibrate, predict_points, reregister
from .noise import noise_floor

__all__ = ["FoldTask", "HeldOut", "folds_by_experiment", "run_fold", "run_folds"]


def folds_by_experiment(n: int, max_folds: int = 6) -> list[np.ndarray]:
    """Held-out experiment indices of each fold: leave-one-out up to ``max_folds``, else k-fold."""
    if n < 2:
        raise ValueError("diagnosis needs at least two experiments (train and held out)")
    k = min(n, max_folds)
    return [np.arange(n)[i::k] for i in range(k)]


@dataclass(frozen=True)
class FoldTask:
    """One model calibrated on the training experiments of one fold and scored on the held-out ones.

    Attributes
    ----------
    preps : tuple of Prepared
        Every experiment of the study.
    train, test : tuple of int
        Indices into ``preps``.
    cause : str or None
        The candidate (None: the baseline).
    start : dict or None
        Start values (the baseline's optimum on this fold for a candidate).
    calibrate_kw : dict
        Passed to :func:`notchfit.diagnosis.calibration.calibrate`.
    seed : int
        Seed of the noise floor's draws (:func:`notchfit.diagnosis.noise.noise_floor`).
    """

    preps: tuple
    train: tuple
    test: tuple
    cause: str | None
    start: dict | None
    calibrate_kw: dict = field(default_factory=dict)
    seed: int = 0


@dataclass(frozen=True)
class FoldResult:
    """Calibration of one fold and its held-out predictions ``{index: (points, theta, floor)}``."""

    cause: str | None
    test: tuple
    calibration: Calibration
    predictions: dict


def run_fold(task: FoldTask) -> FoldResult:
    """Calibrate on the training experiments, predict the held-out ones (a batch item)."""
    with threadpool_limits(limits=1):
        cache = SimulationCache()
        train = [task.preps[i] for i in task.train]
        cal = calibrate(train, task.cause, task.start, cache=cache, **task.calibrate_kw)
        preds = {}
        for i in task.test:
            prep = task.preps[i]
            T = reregister(prep, cal.values) if task.cause == "calibration_error" else None
            P, theta = predict_points(prep, cal.values, transform=T, cache=cache)
            preds[int(i)] = (P, theta, noise_floor(prep, cal.values, cache, seed=task.seed))
    return FoldResult(task.cause, tuple(task.test), cal, preds)


@dataclass(frozen=True)
class HeldOut:
    """Held-out predictions of one model for every experiment.

    Attributes
    ----------
    cause : str or None
    points : dict
        Experiment index -> predicted points (S, m, 2) [m].
    theta : dict
        Experiment index -> predicted joint angles (S, n) [rad].
    floor : dict
        Experiment index -> noise floor (S,) [m²].
    calibrations : tuple of Calibration
        One per fold, in fold order.
    """

    cause: str | None
    points: dict = field(default_factory=dict)
    theta: dict = field(default_factory=dict)
    floor: dict = field(default_factory=dict)
    calibrations: tuple = ()

    @classmethod
    def from_folds(cls, cause, results) -> HeldOut:
        """Collect the :class:`FoldResult` of one model (in fold order)."""
        points, theta, floor = {}, {}, {}
        for r in results:
            for i, (P, th, fl) in r.predictions.items():
                points[i], theta[i], floor[i] = P, th, fl
        return cls(cause, points, theta, floor, tuple(r.calibration for r in results))

    def mean_floor(self) -> float:
        """Mean noise floor over every held-out sample [m²] (:func:`notchfit.diagnosis.noise.noise_floor`)."""
        return float(np.nanmean(np.concatenate([self.floor[i] for i in sorted(self.floor)])))

    def sample_mse(self, preps) -> list[np.ndarray]:
        """Per experiment, the mean squared point error of each sample [m²] (S,)."""
        out = []
        for i, p in enumerate(preps):
            d2 = np.sum((self.points[i] - p.measured) ** 2, axis=-1)
            d2[~p.valid] = np.nan
            out.append(np.nanmean(d2, axis=1))
        return out


def run_folds(preps, folds, causes, starts=None, *, calibrate_kw: dict | None = None, seed: int = 0,
              jobs: int = 1, scheduler=None) -> dict:
    """Calibrate every model of ``causes`` on every fold and collect the held-out predictions.

    Parameters
    ----------
    preps : sequence of Prepared
    folds : list of ndarray
        Held-out indices of each fold (:func:`folds_by_experiment`).
    causes : sequence of (str or None)
        Models to calibrate (None: the baseline).
    starts : list of dict, optional
        Start values per fold (default: the specs' start values).
    calibrate_kw : dict, optional
    seed : int
        Seed of the noise floor's draws.
    jobs : int
        Worker processes (1: here; 0: one per CPU).
    scheduler : str or dask.distributed.Client, optional
        Run the (model × fold) items on this Dask cluster instead.

    Returns
    -------
    dict
        ``{cause: HeldOut}``.

    Raises
    ------
    RuntimeError
        When a calibration failed (the message lists each failed item).
    """
    preps = tuple(preps)
    all_idx = np.arange(len(preps))
    starts = starts if starts is not None else [None] * len(folds)
    kw = dict(calibrate_kw or {})
    tasks, keys = [], []
    for cause in causes:
        for k, f in enumerate(folds):
            train = tuple(int(i) for i in np.setdiff1d(all_idx, f))
            tasks.append(FoldTask(preps, train, tuple(int(i) for i in f), cause, starts[k], kw, seed))
            keys.append(f"{cause or 'baseline'}/fold{k + 1}")
    # the platform's default start method (fork on Linux), whatever threads this process
    # runs: spawn would re-import notchfit in every worker (seconds per pool) and re-run
    # a caller's unguarded script
    res = run_batch(run_fold, tasks, keys=keys, jobs=jobs, scheduler=scheduler, progress=False,
                    start_method=multiprocessing.get_start_method())
    if res.failures:
        raise RuntimeError(res.summary("diagnosis calibrations"))
    results = res.values()
    return {c: HeldOut.from_folds(c, [r for r in results if r.cause == c]) for c in causes}
