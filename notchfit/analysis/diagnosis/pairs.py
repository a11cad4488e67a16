"""Two causes at once: the second-cause step, and what each named cause contributes.

After the best single cause ``a`` is named, every second candidate ``b`` is
first fitted together with ``a`` on all experiments (a screen, started from
``a``'s fold optima): the one that lowers the in-sample error most (and any
within ``screen_tol`` of it) is then fitted on the same folds as ``a`` and
scored against ``a`` alone with the same significance rule as the first step
(:func:`notchfit.analysis.diagnosis.decision.score_candidate`): paired ``z >= z_crit``
on the held-out per-sample errors and at least ``min_excess_removed`` of
``a``'s remaining excess over the noise floor. When even in-sample the best
pair removes less than half that fraction, no pair is cross-validated (an
in-sample gain overstates the held-out one). No second cause is tried when
``a`` already explains the data within the noise. A second candidate the
first step did not cross-validate (the candidates' screen left it out on one
local fit) is cross-validated alone before its pair, and may displace ``a`` as
the first cause (:func:`second_step`'s ``rival``).

Each named cause's contribution is its Shapley share of the held-out mean
squared discrepancy removed (the average, over both orders of adding the two
causes, of what it removes; the shares add to one), its gain when added last,
and the discrepancy signatures it moves.
"""

from __future__ import annotations

import math
import multiprocessing
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ...batch import run_batch
from ..causes import REGISTRY
from .calibration import SimulationCache, calibrate, predict_points
from .crossval import HeldOut
from .decision import fmt_err, score_candidate
from .noise import paired_z, pooled_mse, pooled_rms
from ..estimation.observations import sample_mse
from .results import Contribution
from .signatures import signatures
from .specs import CANDIDATES, PAPER_START, Thresholds, model_key

__all__ = ["SecondStep", "contributions", "pair_sentence", "screen_pairs", "screen_singles", "second_candidates",
           "second_step"]


@dataclass(frozen=True)
class SecondStep:
    """The second-cause step's outcome.

    Attributes
    ----------
    causes : tuple of str
        The causes named (none, the first, or the first and a second).
    first : str
        The first cause the step started from (the decision's, or for ``unexplained`` the better alone of the
        best screened pair).
    results : tuple of CandidateResult
        Each cross-validated pair scored against ``first`` alone.
    within_noise : bool
        ``first`` alone explains the held-out data within the noise (no second cause tried).
    screened : dict
        The screen's ``{model key: (Calibration, in-sample mse, start)}`` (empty without one).
    displaced : str
        A candidate the first step had not cross-validated that, cross-validated alone for its pair, is the
        better first cause (the step stopped before the pairs' cross-validation); else ``""``.
    """

    causes: tuple
    first: str
    results: tuple = ()
    within_noise: bool = False
    screened: dict = field(default_factory=dict)
    displaced: str = ""


def second_candidates(c1: str, cands, *, max_second: int = 4) -> list[str]:
    """Second causes worth fitting with ``c1``: the other single candidates, best held-out first, at
    most ``max_second``; a cause marked ``second_if_significant`` (static friction: its break-away
    decisions are otherwise decided by the load-cell noise, docs/diagnosis.md) only when it was
    significant alone. A candidate that
    did worse than the baseline alone stays in: a dominant first effect can mask it."""
    pool = [c for c in cands if c.cause != c1 and (not REGISTRY[c.cause].second_if_significant or c.significant)]
    pool.sort(key=lambda c: c.heldout_rms)
    return [c.cause for c in pool[:max_second]]


def _fit_all(args):
    """A model fitted on every experiment and its in-sample mean squared error (a batch item)."""
    preps, model, start, scales, base, kw, variant = args
    with threadpool_limits(limits=1):
        cache = SimulationCache.shared()
        cal = calibrate(preps, model, start, cache=cache, scales=scales, base=base,
                        paper_start=model[-1] in PAPER_START, **kw)
        reg = cal.registration or (None,) * len(preps)
        pred = [predict_points(p, cal.values, registration=r, cache=cache, base=base, tubes=cal.tubes)[0]
                for p, r in zip(preps, reg)]
        ms = pooled_mse([sample_mse(p, q) for p, q in zip(preps, pred)])
    return model_key(model), cal, ms, variant


def union_start(first: dict, c1: str, second: dict) -> dict:
    """A pair's start with each cause at its own single optimum: the first cause's parameters from
    ``first``, the baseline's and the second cause's from ``second`` (the first cause's fit may have
    bent the baseline's parameters to stand in for the second effect, e.g. μ_d for a joint
    hysteresis; the second's holds the baseline values that go with that effect)."""
    return {**second, **{s.name: first[s.name] for s in CANDIDATES[c1]}}


def _fit_batch(items, what: str, jobs: int) -> dict:
    """Run :func:`_fit_all` items (here or in ``jobs`` workers): ``{model key: (Calibration, in-sample mse,
    variant)}``, the lower cost of each model's variants kept."""
    res = run_batch(_fit_all, items, keys=[f"{model_key(it[1])}/{it[-1]}" for it in items], jobs=jobs,
                    progress=False, start_method=multiprocessing.get_start_method())
    if res.failures:
        raise RuntimeError(res.summary(what))
    out = {}
    for k, cal, ms, variant in res.values():
        if k not in out or cal.cost < out[k][0].cost:
            out[k] = (cal, ms, variant)
    return out


def screen_singles(causes, preps, start: dict, *, scales, base, calibrate_kw=None, jobs: int = 1) -> dict:
    """Each candidate of ``causes`` alone, fitted on every experiment from ``start`` (the baseline's fit on
    every experiment; the paper's values too where the candidate asks, :data:`~.specs.PAPER_START`), without
    standard errors: the in-sample errors that order the candidates' cross-validation
    (:func:`notchfit.analysis.diagnosis.diagnose`).

    Returns
    -------
    dict
        ``{cause: (Calibration, in-sample mean squared error [m² or rad²], "single")}``.
    """
    kw = {**(calibrate_kw or {}), "errors": False}
    return _fit_batch([(tuple(preps), (c,), dict(start), scales, base, kw, "single") for c in causes],
                      "candidate screen", jobs)


def screen_pairs(c1: str, second, preps, start: dict, *, others: dict | None = None, scales, base,
                 calibrate_kw=None, jobs: int = 1) -> dict:
    """``c1`` alone and with each second candidate, fitted on every experiment.

    A pair is fitted from ``start`` (``c1``'s optimum, the second cause's
    parameters from their probes) and, when ``others`` gives the second
    cause's own single optimum, also from :func:`union_start` (each cause
    where it fitted alone, the baseline where the second did: a first cause
    that compensated the second one holds the probes' fit in its basin); the
    lower cost is kept.

    Returns
    -------
    dict
        ``{model key: (Calibration, in-sample mean squared error [m² or rad²], start)}``,
        ``start`` ``"first"`` or ``"union"``.
    """
    others = others or {}
    kw = dict(calibrate_kw or {})
    items = [(tuple(preps), (c1,), dict(start), scales, base, kw, "first")]
    for c2 in second:
        items.append((tuple(preps), (c1, c2), dict(start), scales, base, kw, "first"))
        if c2 in others:
            items.append((tuple(preps), (c1, c2), union_start(start, c1, others[c2]), scales, base, kw, "union"))
    return _fit_batch(items, "second-cause screen", jobs)


def _to_cross_validate(c1, second, screen, noise, min_excess_removed, screen_tol, max_cv) -> list[str]:
    """The second candidates whose screen earns a cross-validation (module docstring), and after them those
    whose pair fit stalled at its start (:attr:`.calibration.Calibration.stalled`): an in-sample error bounds
    the held-out one only at an optimum, so a stalled screen fit says nothing about its pair, as in the
    candidates' screen of the first step."""
    ms1 = screen[c1][1]
    ms = {c2: screen[model_key((c1, c2))][1] for c2 in second}
    order = sorted(second, key=ms.get)
    stalled = [c for c in order if screen[model_key((c1, c))][0].stalled]
    if ms1 - ms[order[0]] < 0.5 * min_excess_removed * (ms1 - noise):
        return stalled
    chosen = [c for c in order if ms[c] <= screen_tol * ms[order[0]]][:max_cv]
    return chosen + [c for c in stalled if c not in chosen]


def second_step(c1: str, held: dict, preps, run, noise: float, second, rule: Thresholds, *, against_baseline=None,
                screen=None, screen_tol: float = 1.05, max_cv: int = 2, single=None, rival=None):
    """Fit ``c1`` with each second candidate and name the best if it is significant.

    Parameters
    ----------
    c1 : str
        The first cause.
    held : dict
        ``{model key: HeldOut}`` of the single candidates.
    preps : sequence of Prepared
    run : callable
        ``run(models, starts) -> {model key: HeldOut}`` (:func:`notchfit.analysis.diagnosis.crossval.run_folds`).
    noise : float
        The noise floor [m² or rad²].
    second : sequence of str
        The second candidates (:func:`second_candidates`).
    rule : Thresholds
        The thresholds of the first step, applied to this one.
    against_baseline : (list of ndarray, float), optional
        The baseline's per-sample held-out errors and their mean: when ``c1``
        was not significant alone, the pair must also be significant against
        the baseline (two effects that mask each other).
    screen : callable, optional
        ``screen(second) -> {model key: (Calibration, in-sample mse, start)}``
        (:func:`screen_pairs`); without it every second candidate is
        cross-validated. A pair whose screen fit was best from the union
        start is cross-validated from each fold's union start.
    screen_tol, max_cv : float, int
        Cross-validate the best screened pair and those within ``screen_tol``
        of its in-sample error, at most ``max_cv``.
    single : callable, optional
        ``single(causes) -> {cause: HeldOut}``: cross-validates alone a second candidate that ``held``
        lacks (one the first step did not cross-validate, :func:`notchfit.analysis.diagnosis.diagnose`),
        added to ``held`` before its pair is cross-validated: the first step left it out on its fit on
        all experiments, a local fit from where the baseline compensated its effect (a pair the screen
        found worth a cross-validation says the candidate moves the data), so it is given the held-out
        test the first step's decision rests on.
    rival : callable, optional
        ``rival() -> str`` (empty: none): the first step's decision retaken with the candidates now in ``held``;
        when it names another cause than ``c1`` the step stops there (``displaced``) and the pairs are not
        cross-validated.

    Returns
    -------
    c2 : str or None
    held_pairs : dict
        ``{"c1+c2": HeldOut}``.
    results : tuple of CandidateResult
        Each cross-validated pair scored against ``c1`` alone.
    screened : dict
        The screen's ``{model key: (Calibration, in-sample mse, start)}`` (empty without one).
    displaced : str
        The rival's first cause, or ``""``.
    """
    m1 = held[c1]
    mse1 = m1.sample_mse(preps)
    ms1 = pooled_mse(mse1)
    if ms1 <= noise * (1.0 + rule.none_tol) or not second:
        return None, {}, (), {}, ""
    screened = screen(second) if screen is not None else {}
    if screened:
        second = _to_cross_validate(c1, second, screened, noise, rule.min_excess_removed, screen_tol, max_cv)
        if not second:
            return None, {}, (), screened, ""
    models = [(c1, c2) for c2 in second]
    union = {m: screened.get(model_key(m), (None, None, "first"))[2] == "union" for m in models}
    if _cross_validate_alone(second, held, single) and rival is not None:
        displaced = rival()
        if displaced:
            return None, {}, (), screened, displaced
    starts = {}
    for m in models:
        starts[model_key(m)] = [union_start(c.values, c1, held[m[1]].calibrations[k].values) if union[m]
                                else c.values for k, c in enumerate(m1.calibrations)]
    hp = run(models, starts)
    res = tuple(score_candidate(m, hp[model_key(m)], preps, mse1, ms1, ms1 - noise, z_crit=rule.z_crit,
                                min_excess_removed=rule.min_excess_removed, new=(m[1],)) for m in models)
    best = min(res, key=lambda r: r.heldout_rms)
    ok = best.significant
    if ok and against_baseline is not None:
        base_mse, base_ms = against_baseline
        ok = score_candidate(best.cause.split("+"), hp[best.cause], preps, base_mse, base_ms, base_ms - noise,
                             z_crit=rule.z_crit, min_excess_removed=rule.min_excess_removed).significant
    c2 = best.cause.split("+")[1] if ok else None
    return c2, hp, res, screened, ""


def _cross_validate_alone(causes, held: dict, single) -> list[str]:
    """The causes ``held`` lacks cross-validated alone by ``single`` (:func:`second_step`), into ``held``;
    returns them."""
    missing = [c for c in causes if c not in held]
    if missing and single is not None:
        held.update(single(missing))
        return missing
    return []


def _removes(cause: str, without: HeldOut, final: HeldOut, preps, noise: float, metric: str) -> str:
    """Which discrepancy ``cause`` removes: the target signatures it moves toward a perfect model's
    value, and the regime whose held-out error falls most."""
    s0 = {s.name: s.value for s in signatures(preps, without, noise)}
    s1 = {s.name: s.value for s in signatures(preps, final, noise)}
    parts = []
    for name, ideal, words in REGISTRY[cause].targets:
        if name in s0 and name in s1 and abs(s1[name] - ideal) < 0.7 * abs(s0[name] - ideal):
            parts.append(f"{words} from {s0[name]:+.4g} to {s1[name]:+.4g}")
    m0, m1 = without.sample_mse(preps), final.sample_mse(preps)
    best = None
    for reg in ("I", "II", "III"):
        masks = [p.regime == reg for p in preps]
        r0, r1 = pooled_rms(m0, masks), pooled_rms(m1, masks)
        if np.isfinite(r0) and np.isfinite(r1) and (best is None or r0 - r1 > best[1] - best[2]):
            best = (reg, r0, r1)
    if best is not None:
        parts.append(f"the held-out error of regime {best[0]} from {fmt_err(best[1], metric)} to "
                     f"{fmt_err(best[2], metric)}")
    return "; ".join(parts) if parts else "no single signature"


def contributions(causes, held: dict, preps, noise: float, values: dict, *, metric: str = "points"):
    """What each named cause contributes, ordered by its share (largest first).

    Parameters
    ----------
    causes : tuple of str
        One or two named causes.
    held : dict
        ``{model key: HeldOut}`` with the baseline, each single cause and the pair.
    preps : sequence of Prepared
    noise : float
        The noise floor [m² or rad²].
    values : dict
        The extended model fitted on all experiments (parameters by name).
    metric : {"points", "angles"}

    Returns
    -------
    tuple of Contribution
    """
    final = model_key(causes)
    ms = {k: pooled_mse(held[k].sample_mse(preps)) for k in ("baseline", *causes, final)}
    if len(causes) == 1:
        share = {causes[0]: 1.0}
        without = {causes[0]: "baseline"}
    else:
        a, b = causes
        total = ms["baseline"] - ms[final]
        sa = 0.5 * ((ms["baseline"] - ms[a]) + (ms[b] - ms[final]))
        share = {a: sa / total, b: 1.0 - sa / total} if total > 0 else {a: 0.5, b: 0.5}
        without = {a: b, b: a}
    fin_mse = held[final].sample_mse(preps)
    out = []
    for c in causes:
        w = without[c]
        out.append(Contribution(
            cause=c, params={s.name: float(values[s.name]) for s in CANDIDATES[c]},
            alone_rms=math.sqrt(ms[c]), without_rms=math.sqrt(ms[w]), with_rms=math.sqrt(ms[final]),
            share=float(share[c]), z=paired_z(held[w].sample_mse(preps), fin_mse),
            removes=_removes(c, held[w], held[final], preps, noise, metric), without_key=w))
    return tuple(sorted(out, key=lambda c: -c.share))


def pair_sentence(step: SecondStep, contribs, rule: Thresholds, *, metric: str, alone: bool = True) -> str:
    """The second step and each cause's contribution, in words (``contribs``: the named causes'
    :class:`Contribution`; ``alone``: the first cause was significant by itself)."""
    causes, pair_results, c1, screened = tuple(c.cause for c in contribs), step.results, step.first, step.screened
    z_crit, min_removed = rule.z_crit, rule.min_excess_removed
    if not alone and len(causes) == 2:
        r = next(x for x in pair_results if set(x.cause.split("+")) == set(causes))
        step = (f" No cause is significant alone, but two together are: starting from the best single "
                f"candidate, {c1}, {r.cause} lowers the held-out rms to {fmt_err(r.heldout_rms, metric)} "
                f"(z = {r.z:.1f} against {c1} alone, {100 * r.excess_removed:.0f}% of its remaining excess "
                "over noise; significant against the baseline as well).")
    elif step.within_noise:
        step = f" {c1} alone explains the held-out data within the noise: no second cause was tried."
    elif not pair_results and screened and len(screened) > 1:
        best = min((k for k in screened if "+" in k), key=lambda k: screened[k][1])
        step = (f" Fitted on all experiments with each other candidate, {c1} improved too little to try a "
                f"second cause on held-out data (best in-sample: {best}, {fmt_err(math.sqrt(screened[c1][1]), metric)} "
                f"-> {fmt_err(math.sqrt(screened[best][1]), metric)}).")
    elif not pair_results:
        step = f" No second cause was tried with {c1}."
    elif len(causes) == 1:
        best = min(pair_results, key=lambda r: r.heldout_rms)
        step = (f" Adding a second cause to {c1} removes no further significant part of the discrepancy "
                f"(best: {best.cause}, {fmt_err(best.heldout_rms, metric)}, z = {best.z:.1f}, "
                f"{100 * best.excess_removed:.0f}% of the remaining excess; needed z ≥ {z_crit:g} and "
                f"{100 * min_removed:.0f}%).")
    else:
        r = next(x for x in pair_results if set(x.cause.split("+")) == set(causes))
        step = (f" A second cause removes a further significant part of the discrepancy: {r.cause} lowers "
                f"the held-out rms to {fmt_err(r.heldout_rms, metric)} (z = {r.z:.1f} against {c1} alone, "
                f"{100 * r.excess_removed:.0f}% of its remaining excess over noise).")
    each = " ".join(f"{c.cause} ({100 * c.share:.0f}% of the removed discrepancy; "
                    f"{c.gain_pct:.0f}% lower held-out rms when added last) removes {c.removes}."
                    for c in contribs)
    return step + (" " + each if each else "")
