"""Ranking the candidates, the decision rule, and the explanation in words.

Decision rule (the thresholds are keyword arguments of
:func:`notchfit.analysis.diagnosis.diagnose`):

* ``none`` when the baseline's held-out mean squared point error is within
  ``(1 + none_tol)`` of the noise floor;
* otherwise the best candidate by held-out error if it improves on the
  baseline with ``z >= z_crit`` and removes at least ``min_excess_removed``
  of the baseline's excess over the noise floor;
* otherwise ``unexplained`` — where trials repeat, only when the held-out
  baseline's lack of fit beyond the trials' scatter is significant and larger
  than ``none_tol`` times the noise floor
  (:mod:`notchfit.analysis.diagnosis.replicates`); else ``none``.
"""

from __future__ import annotations

import math

import numpy as np

from ..causes import REGISTRY
from .crossval import HeldOut
from .noise import paired_z, pooled_mse
from .replicates import lack_of_fit_mse
from ..estimation.observations import metric_unit, point_factor
from .results import CandidateResult, Signature
from .specs import CANDIDATES, as_model, model_key, specs_for

__all__ = ["decide", "explain", "fmt_err", "hysteresis_shape", "rank_candidates", "score_candidate"]


def fmt_err(v: float, metric: str = "points") -> str:
    """An rms error [m or rad] in the metric's file unit: ``"0.123 mm"`` or ``"0.456°"``."""
    u, f = metric_unit(metric)
    return f"{v / f:.3f} mm" if u == "mm" else f"{v / f:.3f}°"


def _signature_values(sigs) -> dict:
    """``{name: value}`` of Signature objects or of their dictionaries."""
    return {(s.name if isinstance(s, Signature) else s["signature"]):
            (s.value if isinstance(s, Signature) else s["value"]) for s in sigs}


def rank_candidates(sigs, noise_rms: float) -> list[tuple[str, float, str]]:
    """Order the candidate causes by how well the signatures point to each.

    A heuristic score per cause from the signatures (each cause's
    :attr:`notchfit.analysis.causes.Cause.signature`); it orders the search and the
    explanation, the held-out test decides. Equal scores keep the causes'
    ``rank_tie`` order.

    Parameters
    ----------
    sigs : sequence of Signature (or of their dictionaries)
    noise_rms : float
        Root of the noise floor [m].

    Returns
    -------
    list of (cause, score, reason)
        Highest score first.
    """
    s = _signature_values(sigs)
    out = [(c.id, c.score(s), c.reason) for c in sorted(REGISTRY.values(), key=lambda c: c.rank_tie)]
    return sorted(out, key=lambda t: -t[1])


def score_candidate(cause, held: HeldOut, preps, base_mse, base_ms: float, excess: float, *,
                    z_crit: float = 3.0, min_excess_removed: float = 0.3, new=None) -> CandidateResult:
    """Held-out score of a candidate against the model it extends (the baseline, or for a pair its
    first cause).

    Parameters
    ----------
    cause : str or tuple of str
        The candidate's model.
    held : HeldOut
        The candidate's held-out predictions.
    preps : sequence of Prepared
    base_mse : list of ndarray, shape (S_i,) [m² or rad²]
        The extended model's per-sample held-out mean squared errors.
    base_ms : float
        Their mean [m² or rad²].
    excess : float
        That model's excess over the noise floor [m² or rad²].
    z_crit, min_excess_removed : float
        The significance thresholds (module docstring).
    new : sequence of str, optional
        The causes whose parameters the result lists (default: all of the model's).

    Returns
    -------
    CandidateResult
    """
    model = as_model(cause)
    mse = held.sample_mse(preps)
    ms = pooled_mse(mse)
    z = paired_z(base_mse, mse)
    removed = (base_ms - ms) / excess if excess > 0 else 0.0
    cals = held.calibrations
    vals = held.mean_values()
    n_par = len(specs_for(model))
    n_res = sum(c.n_residuals for c in cals)
    cost = sum(c.cost for c in cals)
    aic = n_res * math.log(max(2 * cost / max(n_res, 1), 1e-300)) + 2 * n_par
    names = [s.name for c in (new or model) for s in CANDIDATES[c]]
    return CandidateResult(cause=model_key(model), params={k: vals[k] for k in names}, n_params=len(names),
                           train_rms=float(np.mean([c.train_rms for c in cals])),
                           heldout_rms=math.sqrt(ms), aic=aic, z=z, excess_removed=removed,
                           significant=bool(z >= z_crit and removed >= min_excess_removed))


def decide(within_noise: bool, cands) -> str:
    """``none`` within the noise, else the best candidate if significant, else ``unexplained``."""
    best = min(cands, key=lambda c: c.heldout_rms) if cands else None
    if within_noise:
        return "none"
    if best is not None and best.significant:
        return best.cause
    return "unexplained"


def hysteresis_shape(values: dict, angle_scale: float = 1.0, *, onset_min: float = 0.15,
                     yield_min: float = 0.05) -> str:
    """The loop shape of a fitted joint_hysteresis, in words (:mod:`notchfit.physics._hysteresis_kernels`).

    An onset below ``onset_min`` and a yield angle below ``yield_min`` times
    the study's angle scale (where the flexures' plateau starts, [rad]) are
    described as absent (constant width, rigid play).
    """
    h = values.get("hysteresis_torque", 0.0)
    on = values.get("hysteresis_onset", 0.0)
    y = values.get("hysteresis_yield", 0.0)
    if on > 0.0:
        y = min(y, 0.5 * on)
    if on < onset_min * angle_scale:
        on = 0.0
    if y < yield_min * angle_scale:
        y = 0.0
    if on > 0.0:
        shape = (f"flag-shaped loops confined to deflections beyond {0.5 * on:.3f} rad (full width "
                 f"{2e3 * h:.2f} mN m from {on:.3f} rad; no residual bend at zero load), as in a "
                 "superelastic plateau")
    else:
        shape = f"loops {2e3 * h:.2f} mN m wide at every deflection"
    if y > 0.0:
        shape += (f", elastic-plastic: after a reversal the joint unloads elastically over {2 * y:.4f} rad "
                  "(Masing's doubled elastic range) before its loop branch")
    else:
        shape += ", rigid-plastic (a play operator: the joint holds until the torque has changed by the width)"
    return f" The fitted hysteresis has {shape}."


def _stall_hint(sigs, stall_hint: float) -> str:
    """For ``unexplained``: static friction named as the likely cause when the shape stalls."""
    stalls = next((s.value for s in sigs if s.name == "loading_stalls"), 0.0)
    if stalls < stall_hint:
        return ""
    return (f" The measured shape stalls on {100 * stalls:.0f}% of the upper loading steps, the "
            "mark of static friction well above the sliding friction: when the load-cell noise is "
            "comparable to the break-away excess, that noise decides which steps break a cable "
            "away, and no deterministic model predicts these shapes much better from the measured "
            "tensions (docs/diagnosis.md, 'What it cannot find').")


def explain(cause: str, sigs, cands, base_rms: float, noise_rms: float, *, none_tol: float,
            z_crit: float, min_removed: float, stall_hint: float = 0.05, metric: str = "points",
            baseline: str = "the paper's friction model with k_lin, k_mid and μ_d fitted", lack_of_fit=None,
            band_rms: float = 0.0) -> str:
    """The diagnosis in words: the baseline against the noise, the signatures, the verdict and its physics.

    Parameters
    ----------
    cause : str
        The verdict for the first cause (:func:`decide`).
    sigs : sequence of Signature
    cands : sequence of CandidateResult
    base_rms, noise_rms : float
        The baseline's held-out rms and the root of the noise floor [m or rad].
    none_tol, z_crit, min_removed : float
        The thresholds of the decision rule (module docstring).
    stall_hint : float
        For ``unexplained``: the fraction of stalled loading steps above which
        static friction is named as the likely cause.
    metric : {"points", "angles"}
    baseline : str
        What the baseline is, in words.
    lack_of_fit : LackOfFit, optional
        The held-out baseline's pure error and lack of fit (:mod:`notchfit.analysis.diagnosis.replicates`):
        its verdict follows the lead when trials repeat.
    band_rms : float
        Root of the mean prediction variance of the baseline's folds [m or rad]: the baseline's floor is
        ``√(noise_rms² + band_rms²)`` (:func:`~notchfit.analysis.diagnosis.calibration.fold_band`).
    """
    what = "notch points" if metric == "points" else "joint angles"
    floor = math.hypot(noise_rms, band_rms)
    against = (f"a floor of {fmt_err(floor, metric)} (noise {fmt_err(noise_rms, metric)}, the folds' prediction "
               f"uncertainty {fmt_err(band_rms, metric)})" if band_rms > 0 else
               f"a noise floor of {fmt_err(noise_rms, metric)}")
    lead = (f"The calibrated baseline ({baseline}) predicts held-out {what} with {fmt_err(base_rms, metric)} "
            f"rms against {against}.")
    top = [f"{c} ({why})" for c, sc, why in rank_candidates(sigs, noise_rms) if sc > 0][:3]
    hint = (" The discrepancy signatures point first to " + "; then ".join(top) + ".") if top else ""
    ranked = sorted(cands, key=lambda c: c.heldout_rms)
    table = "; ".join(f"{c.cause} {fmt_err(c.heldout_rms, metric)} (z = {c.z:.1f})" for c in ranked[:4])
    lof = lack_of_fit if lack_of_fit is not None and lack_of_fit.has_replicates else None
    if lof is not None:
        lead += f" Against the repeated trials: {lof.verdict()}."
    if cause == "none" and lof is not None and base_rms > floor * math.sqrt(1 + none_tol):
        if lof.overall.significant(lof.alpha):
            why = (f" The lack of fit beyond the trials' scatter is significant but small: "
                   f"{fmt_err(math.sqrt(lack_of_fit_mse(lof, point_factor(metric))), metric)} "
                   f"rms, within the {fmt_err(math.sqrt(none_tol) * floor, metric)} over the floor that the "
                   "noise rule tolerates; the rest of the excess is the trials' scatter or lies in samples no "
                   "other trial repeats (on a steep part of the curve the load-cell noise and the parameters' "
                   "error move the shape alike): no extension is justified.")
        else:
            why = " The error exceeds the floor but not the trials' own scatter: no extension is justified."
        return lead + why + hint + (f" Held-out rms of the candidates: {table}." if table else "")
    if cause == "none":
        return (lead + f" That is within {math.sqrt(1 + none_tol):.2f}× the floor: the baseline explains "
                "the data within the measurement uncertainty, so no extension is justified." + hint
                + (f" Held-out rms of the candidates: {table}." if table else ""))
    if cause == "unexplained":
        return (lead + " The excess over noise is significant, but no candidate extension removes "
                f"at least {100 * min_removed:.0f}% of it with z ≥ {z_crit:g} on held-out experiments."
                + hint + _stall_hint(sigs, stall_hint) + f" Held-out rms of the candidates: {table}.")
    c = next(r for r in cands if r.cause == cause)
    second = next((r for r in ranked if r.cause != cause), None)
    sec = (f" The next best, {second.cause}, reached {fmt_err(second.heldout_rms, metric)}." if second else "")
    return (lead + hint + f" Fitting each candidate with the baseline parameters on the training "
            f"experiments, {cause} lowers the held-out rms to {fmt_err(c.heldout_rms, metric)} "
            f"(z = {c.z:.1f} for the per-sample improvement with serial correlation accounted for, "
            f"{100 * c.excess_removed:.0f}% of the excess over noise removed)." + sec
            + " " + REGISTRY[cause].explanation)
