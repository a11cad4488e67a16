"""The diagnosis of a study: baseline, signatures, candidates, verdict, extension and gain."""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from .calibration import calibrate
from .crossval import folds_by_experiment, run_folds
from .decision import decide, explain, rank_candidates, score_candidate
from .noise import pooled_rms
from .prepare import prepare_experiment
from .results import Diagnosis, Gain
from .signatures import signatures
from .specs import CANDIDATES, CAUSES

__all__ = ["diagnose"]


def _mean_mse(mse) -> float:
    """Mean of per-sample squared errors pooled over experiments [m²]."""
    return float(np.nanmean(np.concatenate(mse)))


def _noise(base, held, preps) -> float:
    """The noise floor [m²]: the smaller of the baseline's and the best candidate's.

    The floor depends on the model's tension sensitivity; a baseline that
    compensates a missing effect (e.g. too soft) overstates it.
    """
    floors = [base.mean_floor()]
    if held:
        best = min(held, key=lambda c: _mean_mse(held[c].sample_mse(preps)))
        floors.append(held[best].mean_floor())
    return min(floors)


def _per_regime(preps, base_mse, ext_mse) -> dict:
    """``{regime: Gain}`` for the regimes I/II/III that occur in the measured data."""
    out = {}
    for reg in ("I", "II", "III"):
        masks = [p.regime == reg for p in preps]
        rb, re_ = pooled_rms(base_mse, masks), pooled_rms(ext_mse, masks)
        if np.isfinite(rb):
            out[reg] = Gain(rb, re_)
    return out


def diagnose(experiments, *, jobs: int = 1, scheduler=None, seed: int = 0, max_folds: int = 6,
             causes=CAUSES, none_tol: float = 0.5, z_crit: float = 3.0, min_excess_removed: float = 0.3,
             calibrate_kw: dict | None = None, progress=None) -> Diagnosis:
    """Diagnose a study against the paper's friction model (Sec. IV-B; docs/diagnosis.md).

    The baseline is calibrated on the training experiments of each fold and
    compared with the held-out ones; the discrepancy signatures order the
    candidate causes, each candidate is fitted and scored the same way, and
    the decision rule (:mod:`notchfit.diagnosis.decision`) names the cause.
    The chosen extension is refitted on all experiments. Nothing is written.

    Parameters
    ----------
    experiments : sequence of notchfit.io.Experiment
        At least two, with notch points.
    jobs : int
        Worker processes for the (model × fold) calibrations (1: here; 0: one per CPU).
    scheduler : str or dask.distributed.Client, optional
        Run the (model × fold) calibrations on this Dask cluster instead.
    seed : int
        Seed of the noise floor's Monte Carlo draws
        (:func:`notchfit.diagnosis.noise.noise_floor`).
    max_folds : int
        Leave-one-experiment-out up to this many experiments, else k-fold.
    causes : sequence of str
        Candidates to try (default: all six).
    none_tol : float
        ``none`` when the baseline's held-out mean squared error is below
        ``(1 + none_tol)`` times the noise floor.
    z_crit : float
        Significance of a candidate's held-out improvement
        (:func:`notchfit.diagnosis.noise.paired_z`).
    min_excess_removed : float
        Fraction of the baseline's excess over the noise floor a candidate
        must remove.
    calibrate_kw : dict, optional
        Passed to :func:`notchfit.diagnosis.calibration.calibrate`.
    progress : callable, optional
        Called with a short message at each stage.

    Returns
    -------
    Diagnosis
    """
    say = progress or (lambda msg: None)
    kw = dict(calibrate_kw or {})
    unknown = set(causes) - set(CAUSES)
    if unknown:
        raise ValueError(f"unknown cause(s) {sorted(unknown)}; known: {', '.join(CAUSES)}")
    say("registering measurements and fitting measured shapes")
    preps = tuple(prepare_experiment(e) for e in experiments)
    folds = folds_by_experiment(len(preps), max_folds)
    run = partial(run_folds, preps, folds, calibrate_kw=kw, seed=seed, jobs=jobs, scheduler=scheduler)

    say(f"calibrating the baseline on {len(folds)} folds")
    base = run([None])[None]
    base_start = [cal.values for cal in base.calibrations]
    sigs = signatures(preps, base, base.mean_floor())
    order = [c for c, _, _ in rank_candidates(sigs, math.sqrt(base.mean_floor())) if c in causes]
    say(f"fitting {len(order)} candidate extensions")
    held = run(order, base_start) if order else {}

    base_mse = base.sample_mse(preps)
    base_ms = _mean_mse(base_mse)
    noise = _noise(base, held, preps)
    say("fitting the baseline on all experiments")
    full_base = calibrate(preps, None, base_start[0], **kw)
    cands = [score_candidate(c, held[c], preps, base_mse, base_ms, base_ms - noise, z_crit=z_crit,
                             min_excess_removed=min_excess_removed) for c in order]
    cause = decide(base_ms <= noise * (1.0 + none_tol), cands)

    extended, ext_mse = None, base_mse
    if cause in CANDIDATES:
        say(f"fitting the {cause} extension on all experiments")
        extended = calibrate(preps, cause, full_base.values, **kw)
        ext_mse = held[cause].sample_mse(preps)
    base_rms, noise_rms = math.sqrt(base_ms), math.sqrt(noise)
    text = explain(cause, sigs, cands, base_rms, noise_rms, none_tol=none_tol, z_crit=z_crit,
                   min_removed=min_excess_removed)
    return Diagnosis(experiments=tuple(p.name for p in preps), baseline=full_base,
                     baseline_heldout_rms=base_rms, discrepancies=tuple(sigs), candidates=tuple(cands),
                     cause=cause, explanation=text, gain=Gain(base_rms, math.sqrt(_mean_mse(ext_mse))),
                     extended=extended, per_regime=_per_regime(preps, base_mse, ext_mse),
                     noise_rms=noise_rms, seed=seed, heldout={"baseline": base, **held}, prepared=preps)

