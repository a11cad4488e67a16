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

from ...batch import run_batch
from ..causes import REGISTRY
from ..estimation.noise import noise_floor
from ..estimation.solve import folds
from .calibration import Calibration, SimulationCache, calibrate, fold_band, mean_start, predict_points, reregister
from ..estimation.observations import sample_mse
from .specs import PAPER_START, StudyScales, as_model, model_key

__all__ = ["FoldTask", "HeldOut", "folds_by_experiment", "run_fold", "run_folds"]


def folds_by_experiment(n: int, max_folds: int = 6) -> list[np.ndarray]:
    """Held-out experiment indices of each fold: leave-one-out up to ``max_folds``, else k-fold."""
    if n < 2:
        raise ValueError("diagnosis needs at least two experiments (train and held out)")
    return folds(n, max_folds)


@dataclass(frozen=True)
class FoldTask:
    """One model calibrated on the training experiments of one fold and scored on the held-out ones.

    Attributes
    ----------
    preps : tuple of Prepared
        Every experiment of the study.
    train, test : tuple of int
        Indices into ``preps``.
    cause : tuple of str
        The model: ``()`` the baseline, one candidate or a pair.
    start : dict or None
        Start values (the baseline's optimum on this fold for a candidate).
    calibrate_kw : dict
        Passed to :func:`notchfit.analysis.diagnosis.calibration.calibrate`.
    seed : int
        Seed of the noise floor's draws (:func:`notchfit.analysis.estimation.noise.noise_floor`).
    scales : StudyScales
        The whole study's scales (every fold fits in the same units).
    base : FrictionParams or None
        The base model (default: the paper's).
    band : bool
        Also the held-out predictions' variance from the fold's parameter uncertainty (the baseline
        only, :func:`~notchfit.analysis.diagnosis.calibration.fold_band`).
    """

    preps: tuple
    train: tuple
    test: tuple
    cause: tuple
    start: dict | None
    calibrate_kw: dict = field(default_factory=dict)
    seed: int = 0
    scales: StudyScales = field(default_factory=StudyScales)
    base: object = None
    band: bool = False


@dataclass(frozen=True)
class FoldResult:
    """Calibration of one fold and its held-out predictions ``{index: (predicted, theta, floor)}``, with
    their prediction variance ``{index: (S,) [m² or rad²]}`` when asked (:attr:`FoldTask.band`)."""

    cause: tuple
    test: tuple
    calibration: Calibration
    predictions: dict
    band: dict = field(default_factory=dict)


def run_fold(task: FoldTask) -> FoldResult:
    """Calibrate on the training experiments, predict the held-out ones (a batch item)."""
    with threadpool_limits(limits=1):
        cache = SimulationCache.shared()
        train = [task.preps[i] for i in task.train]
        # the candidates whose fit may end in another basin from the baseline's (or, for a pair, the
        # first cause's) optimum are also fitted from the paper's values (specs.PAPER_START)
        paper = task.cause[-1] in PAPER_START if task.cause else False
        cal = calibrate(train, task.cause, task.start, cache=cache, scales=task.scales, base=task.base,
                        paper_start=paper, errors=False, **task.calibrate_kw)
        preds = {}
        for i in task.test:
            prep = task.preps[i]
            T = reregister(prep, cal.values) if any(REGISTRY[c].corrects_points for c in task.cause) else None
            P, theta = predict_points(prep, cal.values, transform=T, cache=cache, base=task.base, tubes=cal.tubes)
            floor = noise_floor(prep, cal.params(task.base, prep.tube), cache, seed=task.seed)
            preds[int(i)] = (P, theta, floor)
        band = {}
        if task.band:                                  # the baseline's (run_folds asks for no other)
            var = fold_band(train, cal, [task.preps[i] for i in task.test], cache=cache, scales=task.scales,
                            base=task.base, diff_step=task.calibrate_kw.get("diff_step", 2e-3))
            band = {int(i): v for i, v in zip(task.test, var)}
    return FoldResult(task.cause, tuple(task.test), cal, preds, band)


@dataclass(frozen=True)
class HeldOut:
    """Held-out predictions of one model for every experiment.

    Attributes
    ----------
    cause : tuple of str
        The model.
    predicted : dict
        Experiment index -> predicted measurements: points (S, m, 2) [m] or
        joint angles (S, n) [rad].
    theta : dict
        Experiment index -> predicted joint angles (S, n) [rad].
    floor : dict
        Experiment index -> noise floor (S,) [m² or rad²].
    calibrations : tuple of Calibration
        One per fold, in fold order.
    band : dict
        Experiment index -> the prediction variance of its fold's parameter uncertainty (S,)
        [m² or rad²] (the baseline's, when asked: :func:`~notchfit.analysis.diagnosis.calibration.fold_band`).
    """

    cause: tuple
    predicted: dict = field(default_factory=dict)
    theta: dict = field(default_factory=dict)
    floor: dict = field(default_factory=dict)
    calibrations: tuple = ()
    band: dict = field(default_factory=dict)

    @classmethod
    def from_folds(cls, cause, results) -> HeldOut:
        """Collect the :class:`FoldResult` of one model (in fold order)."""
        predicted, theta, floor, band = {}, {}, {}, {}
        for r in results:
            for i, (P, th, fl) in r.predictions.items():
                predicted[i], theta[i], floor[i] = P, th, fl
            band.update(r.band)
        return cls(as_model(cause), predicted, theta, floor, tuple(r.calibration for r in results), band)

    def mean_floor(self) -> float:
        """Mean noise floor over every held-out sample [m²] (:func:`notchfit.analysis.estimation.noise.noise_floor`)."""
        return float(np.nanmean(np.concatenate([self.floor[i] for i in sorted(self.floor)])))

    def mean_band(self) -> float:
        """Mean prediction variance of the folds' parameter uncertainty over every held-out sample [m² or rad²]
        (0 when not computed)."""
        if not self.band:
            return 0.0
        return float(np.nanmean(np.concatenate([self.band[i] for i in sorted(self.band)])))

    def mean_values(self) -> dict:
        """The mean of the fold optima by parameter name [SI] (a start for a fit on every experiment; a real
        tube's per-tube values under ``"tubes"``, :func:`~notchfit.analysis.diagnosis.calibration.mean_start`)."""
        return mean_start(self.calibrations)

    def sample_mse(self, preps) -> list[np.ndarray]:
        """Per experiment, the mean squared error of each sample [m² or rad²] (S,)
        (:func:`notchfit.analysis.estimation.observations.sample_mse`)."""
        return [sample_mse(p, self.predicted[i]) for i, p in enumerate(preps)]


def run_folds(preps, folds, causes, starts=None, *, calibrate_kw: dict | None = None, seed: int = 0,
              jobs: int = 1, scheduler=None, scales: StudyScales | None = None, base=None,
              fold_band: bool = False, cause_kw: dict | None = None) -> dict:
    """Calibrate every model of ``causes`` on every fold and collect the held-out predictions.

    Parameters
    ----------
    preps : sequence of Prepared
    folds : list of ndarray
        Held-out indices of each fold (:func:`folds_by_experiment`).
    causes : sequence of models
        Models to calibrate: None or ``()`` the baseline, a cause id, or a
        tuple of causes (:func:`notchfit.analysis.diagnosis.specs.as_model`).
    starts : list of dict, or dict of such lists, optional
        Start values per fold (default: the specs' start values); a dict gives
        them per model key (:func:`notchfit.analysis.diagnosis.specs.model_key`).
    calibrate_kw : dict, optional
    seed : int
        Seed of the noise floor's draws.
    jobs : int
        Worker processes (1: here; 0: one per CPU).
    scheduler : str or dask.distributed.Client, optional
        Run the (model × fold) items on this Dask cluster instead.
    scales : StudyScales, optional
        Default: the scales of ``preps``.
    base : FrictionParams, optional
        The base model (default: the paper's).
    fold_band : bool
        Also the baseline's held-out prediction variance (:attr:`HeldOut.band`; ``p + 1`` more runs of
        each fold's experiments).
    cause_kw : dict, optional
        Added to ``calibrate_kw`` for the models with a cause (not the baseline), e.g. ``{"secant": 3}``.

    Returns
    -------
    dict
        ``{model key: HeldOut}`` (``"baseline"``, ``"joint_hysteresis"``, ``"a+b"``).

    Raises
    ------
    RuntimeError
        When a calibration failed (the message lists each failed item).
    """
    preps = tuple(preps)
    all_idx = np.arange(len(preps))
    scales = scales or StudyScales.of(preps, base)
    models = [as_model(c) for c in causes]
    kw = dict(calibrate_kw or {})
    tasks, keys = [], []
    for model in models:
        st = starts.get(model_key(model)) if isinstance(starts, dict) else starts
        st = st if st is not None else [None] * len(folds)
        for k, f in enumerate(folds):
            train = tuple(int(i) for i in np.setdiff1d(all_idx, f))
            tasks.append(FoldTask(preps, train, tuple(int(i) for i in f), model, st[k],
                                  {**kw, **(cause_kw or {})} if model else kw, seed, scales, base,
                                  fold_band and not model))
            keys.append(f"{model_key(model)}/fold{k + 1}")
    # the platform's default start method (fork on Linux), whatever threads this process
    # runs: spawn would re-import notchfit in every worker (seconds per pool) and re-run
    # a caller's unguarded script
    res = run_batch(run_fold, tasks, keys=keys, jobs=jobs, scheduler=scheduler, progress=False,
                    start_method=multiprocessing.get_start_method())
    if res.failures:
        raise RuntimeError(res.summary("diagnosis calibrations"))
    results = res.values()
    return {model_key(m): HeldOut.from_folds(m, [r for r in results if r.cause == m]) for m in models}
