"""The diagnosis of a study: baseline, signatures, candidates, verdict, a second cause, extension and gain."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import numpy as np

from ..causes import REGISTRY
from .calibration import calibrate
from .crossval import HeldOut, folds_by_experiment, run_folds
from .decision import decide, explain, fmt_err, hysteresis_shape, rank_candidates, score_candidate
from .noise import pooled_mse, pooled_rms
from .pairs import (SecondStep, contributions, pair_sentence, screen_pairs, screen_singles, second_candidates,
                    second_step)
from .replicates import heldout_lack_of_fit, lack_of_fit_first
from ..estimation.observations import choose_metric, observe_study
from .results import Diagnosis, Gain
from .scope import applicable_causes, base_model, resolve_protocol
from .signatures import signatures, skipped_signatures
from .specs import CANDIDATES, CAUSES, StudyScales, Thresholds, model_key
from .tubes import has_tube_unknowns

__all__ = ["diagnose", "restart_unconverged"]


def _noise(base, held, preps) -> float:
    """The noise floor [m² or rad²]: the smaller of the baseline's and the best candidate's.

    The floor depends on the model's tension sensitivity; a baseline that
    compensates a missing effect (e.g. too soft) overstates it.
    """
    floors = [base.mean_floor()]
    if held:
        best = min(held, key=lambda c: pooled_mse(held[c].sample_mse(preps)))
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


def _baseline_words(base, preps) -> str:
    """What the calibrated baseline is, in words."""
    if base.spring_law == "material":
        law = "capstan friction of a tendon in the lumen" if base.friction_law == "capstan" else "channel friction"
        tube = (" and each tube's rest angles and cut depths (identify's calibrated model)"
                if has_tube_unknowns(preps) else "")
        return (f"the friction model of the tube's material and section springs and {law}, with E_lin, E_se, "
                f"strain_lower and μ_d fitted{tube}")
    return "the paper's friction model with k_lin, k_mid and μ_d fitted"


@dataclass(frozen=True)
class _Options:
    """What :func:`diagnose` was asked: the candidates, the measurements compared, how the fits run, the
    decision rule and the second-cause step."""

    causes: tuple
    metric: str
    estimate_protocol: bool
    calibrate_kw: dict
    jobs: int
    seed: int
    say: Callable
    rule: Thresholds
    second_cause: bool
    max_second: int
    screen: bool = True
    screen_ratio: float = 1.0
    cause_kw: dict = field(default_factory=dict)

    @property
    def candidate_kw(self) -> dict:
        """The calibration options of the candidates' and pairs' fits (the baseline's: ``calibrate_kw``)."""
        return {**self.calibrate_kw, **self.cause_kw}


@dataclass
class _Study:
    """The prepared study and what every fit shares."""

    preps: tuple
    base: object
    scales: StudyScales
    protocol: dict
    protocol_fit: object
    skipped: dict
    order: tuple = ()


@dataclass(frozen=True)
class _First:
    """The first step: the decision on the single candidates.

    ``cause`` the decision (a candidate, ``none`` or ``unexplained``), the discrepancy signatures, the scored
    candidates, the baseline's held-out per-sample errors (list of (S,) [m² or rad²]), the noise floor
    [m² or rad²], the baseline's held-out lack of fit and the mean prediction variance of its folds'
    parameter uncertainty [m² or rad²] (its floor is ``noise + band``).
    """

    cause: str
    sigs: list
    cands: list
    base_mse: list
    noise: float
    lack_of_fit: object
    band: float = 0.0
    screen: dict = field(default_factory=dict)
    unscreened: tuple = ()


@dataclass(frozen=True)
class _Fits:
    """The models fitted on every experiment (the baseline, the extended one or None) and the extended
    model's held-out per-sample errors and lack of fit (the baseline's without a named cause; None)."""

    baseline: object
    extended: object
    ext_mse: list
    ext_lack_of_fit: object


def _setup(experiments, opts: _Options) -> _Study:
    """Measurements, base model, scales, protocol and the candidates that apply."""
    say, kw = opts.say, opts.calibrate_kw
    metric = choose_metric(experiments, opts.metric)
    say(f"registering measurements and fitting measured shapes ({metric})")
    preps = observe_study(experiments, metric)
    base = base_model(preps)
    scales = StudyScales.of(preps, base)
    recorded = {e.name: e.ramp_time for e in experiments}
    if any(v is None for v in recorded.values()) and opts.estimate_protocol:
        say("estimating the protocol of the experiments without [protocol]")
    preps, protocol, cal = resolve_protocol(preps, recorded, base, scales, kw, estimate=opts.estimate_protocol,
                                            none_tol=opts.rule.none_tol, seed=opts.seed, jobs=opts.jobs)
    usable, skipped, reveal = applicable_causes(preps, opts.causes)
    return _Study(preps, base, scales, protocol, cal,
                  {"signatures": skipped_signatures(preps), "candidates": skipped, "experiments": reveal}, usable)


def restart_unconverged(held: HeldOut, folds, run) -> HeldOut:
    """The baseline's fold fits that stopped at their evaluation limit, refitted from the other folds'
    converged optima; each fold keeps its lowest training cost.

    The candidates extend the baseline, start from its fold optima and are scored against its held-out
    errors: a baseline fold left far from its optimum is a discrepancy every candidate "explains" (the
    null wrist ``wrist_asymmetric`` as notch points, seed 2: the fold trained on the two lighter trials
    stopped at the bounds of E_se and strain_lower with 250 times the training cost the same model
    reaches from another fold's optimum, and a stiffness gradient was named; docs/history.md).

    Parameters
    ----------
    held : HeldOut
        The baseline's held-out predictions, one calibration per fold.
    folds : list of ndarray
        Held-out indices of each fold.
    run : callable
        ``run(folds, causes, starts)`` -> ``{model key: HeldOut}``: :func:`~.crossval.run_folds` with the
        study's experiments and options bound.

    Returns
    -------
    HeldOut
        ``held`` itself when every fold converged (or none did).
    """
    cals = list(held.calibrations)
    bad = [k for k, c in enumerate(cals) if not c.success]
    good = [c.start() for c in cals if c.success]
    if not bad or not good:
        return held
    predicted, theta, floor, band = dict(held.predicted), dict(held.theta), dict(held.floor), dict(held.band)
    for start in good:              # one run per start: the folds restarted in it hold out distinct trials
        again = run([folds[k] for k in bad], [None], [start] * len(bad))["baseline"]
        for k, cal in zip(bad, again.calibrations):
            if cal.cost < cals[k].cost:
                cals[k] = cal
                for i in (int(i) for i in folds[k]):
                    predicted[i], theta[i], floor[i] = again.predicted[i], again.theta[i], again.floor[i]
                    if i in again.band:
                        band[i] = again.band[i]
    return HeldOut(held.cause, predicted, theta, floor, tuple(cals), band)


def _masked_first(st: _Study, opts: _Options, cands, held):
    """For ``unexplained``: every pair of the candidates screened on all experiments; the pair that
    lowers the in-sample error most gives the first cause (the one better alone) and the second.

    Returns ``(first, second, screened)`` (``(None, None, {})`` with fewer than two candidates).
    """
    pool = [c.cause for c in sorted(cands, key=lambda c: c.heldout_rms)
            if c.cause in st.order and (not REGISTRY[c.cause].second_if_significant or c.significant)]
    if len(pool) < 2:
        return None, None, {}
    opts.say(f"no single cause is significant: screening the {len(pool) * (len(pool) - 1) // 2} pairs of "
             "candidates")
    screened = {}
    for i, a in enumerate(pool[:-1]):
        screened.update(screen_pairs(a, pool[i + 1:], st.preps, held[a].mean_values(), scales=st.scales,
                                     others={c: held[c].mean_values() for c in pool[i + 1:]}, base=st.base,
                                     calibrate_kw=opts.candidate_kw, jobs=opts.jobs))
    best = min((k for k in screened if "+" in k), key=lambda k: screened[k][1])
    first, second = best.split("+")
    return first, second, screened


def _second(st: _Study, opts: _Options, held, step: _First, run, single, rival=None) -> SecondStep:
    """The second-cause step (:mod:`notchfit.analysis.diagnosis.pairs`). For ``unexplained`` (two strong
    effects can each keep the other's candidate from significance) every pair is screened and the best is
    cross-validated from the candidate better alone; it must be significant against the baseline too.
    ``rival()`` retakes the first decision once a candidate the screen left out is cross-validated alone
    for its pair (:func:`~.pairs.second_step`); a different first cause ends the step (``displaced``)."""
    cause, cands, noise, base_mse = step.cause, step.cands, step.noise, step.base_mse
    base_ms = pooled_mse(base_mse)
    if not opts.second_cause or (cause not in CANDIDATES and cause != "unexplained"):
        return SecondStep((cause,) if cause in CANDIDATES else (), cause)
    if cause == "unexplained":
        first, c2, pre = _masked_first(st, opts, cands, held)
        if first is None:
            return SecondStep((), cause)
        second, against, screen = [c2], (base_mse, base_ms), (lambda sec: pre)
    else:
        first, against = cause, None
        second = [c for c in second_candidates(first, cands, max_second=opts.max_second) if c in st.order]
        # the candidates not cross-validated alone follow, by their in-sample error (a dominant first
        # effect can hide a second one from the single candidates' screen)
        second += [c for c in step.unscreened if c != first and not REGISTRY[c].second_if_significant]
        second = second[:opts.max_second]
        screen = partial(screen_pairs, first, preps=st.preps, start=held[first].mean_values(), scales=st.scales,
                         others={c: held[c].mean_values() if c in held else step.screen[c][0].start()
                                 for c in second}, base=st.base,
                         calibrate_kw=opts.candidate_kw, jobs=opts.jobs)
        if second:
            opts.say(f"screening {len(second)} second causes with {first} on all experiments")
    within = pooled_mse(held[first].sample_mse(st.preps)) <= noise * (1.0 + opts.rule.none_tol)
    c2, hp, res, screened, displaced = second_step(first, held, st.preps, run, noise, second, opts.rule,
                                                   against_baseline=against, screen=screen, single=single,
                                                   rival=rival if against is None else None)
    held.update(hp)
    if against is not None:
        return SecondStep((first, c2) if c2 else (), first, res, within, screened)
    return SecondStep((first, c2) if c2 else (first,), first, res, within, screened, displaced)


def _extended(st: _Study, causes, held, screened, kw):
    """The extended model fitted on every experiment (None without a named cause), started from the
    mean of its fold optima (or the second-cause screen's fit of it)."""
    if not causes:
        return None
    key = model_key(causes)
    if key in screened:
        return screened[key][0]
    return calibrate(st.preps, causes, held[key].mean_values(), scales=st.scales, base=st.base, paper_start=False,
                     **kw)


def diagnose(experiments, *, jobs: int = 1, scheduler=None, seed: int = 0, max_folds: int = 6,
             causes=CAUSES, none_tol: float = 0.5, z_crit: float = 3.0, min_excess_removed: float = 0.3,
             calibrate_kw: dict | None = None, progress=None, metric: str = "auto", second_cause: bool = True,
             max_second: int = 4, estimate_protocol: bool = True, lof_alpha: float = 0.01, fold_band: bool = True,
             replicate_tol_sigma: float = 3.0, screen_candidates: bool = True, screen_ratio: float = 1.0,
             candidate_secant: int = 0) -> Diagnosis:
    """Diagnose a study against the friction model (Sec. IV-B; docs/diagnosis.md).

    The baseline is calibrated on the training experiments of each fold and
    compared with the held-out ones; the discrepancy signatures order the
    candidate causes, each candidate is fitted and scored the same way, and
    the decision rule (:mod:`notchfit.analysis.diagnosis.decision`) names the first
    cause. Then each promising second candidate is fitted with it and kept if
    it removes a further significant part of the held-out discrepancy by the
    same rule (:mod:`notchfit.analysis.diagnosis.pairs`). The extended model (every
    named cause) is refitted on all experiments. Nothing is written.

    Parameters
    ----------
    experiments : sequence of notchfit.io.Experiment
        At least two, with notch points or with joint angles (``angles.csv``).
    jobs : int
        Worker processes for the (model × fold) calibrations (1: here; 0: one per CPU).
    scheduler : str or dask.distributed.Client, optional
        Run the (model × fold) calibrations on this Dask cluster instead.
    seed : int
        Seed of the noise floor's Monte Carlo draws
        (:func:`notchfit.analysis.estimation.noise_floor`).
    max_folds : int
        Leave-one-experiment-out up to this many experiments, else k-fold.
    causes : sequence of str
        Candidates to try (default: all six; those that do not apply to the
        study are skipped with their reason).
    none_tol : float
        ``none`` when the baseline's held-out mean squared error is below
        ``(1 + none_tol)`` times the noise floor (and no second cause when the
        first cause's is).
    z_crit : float
        Significance of a candidate's held-out improvement
        (:func:`notchfit.analysis.diagnosis.noise.paired_z`).
    min_excess_removed : float
        Fraction of the excess over the noise floor a candidate must remove.
    calibrate_kw : dict, optional
        Passed to :func:`notchfit.analysis.diagnosis.calibration.calibrate`.
    progress : callable, optional
        Called with a short message at each stage.
    metric : {"auto", "points", "angles"}
        What is compared (:func:`notchfit.analysis.estimation.observations.choose_metric`).
    second_cause : bool
        Look for a second cause after the first.
    max_second : int
        Second candidates fitted with the first (the best single ones).
    estimate_protocol : bool
        Estimate ``ramp_time`` where experiment.toml gives no ``[protocol]``
        (:func:`notchfit.analysis.diagnosis.scope.resolve_protocol`); else a step is assumed.
    lof_alpha, replicate_tol_sigma : float
        Where trials repeat, ``unexplained`` needs a material held-out lack of fit, significant at ``lof_alpha``
        (replicate tensions within ``replicate_tol_sigma`` load-cell σ; :func:`_lack_of_fit_first`).
    fold_band : bool
        Judge the baseline against the noise floor plus its folds' prediction variance (:func:`~.calibration.fold_band`).
    screen_candidates, screen_ratio : bool, float
        Screen the candidates on all experiments first (:func:`_singles`; False: cross-validate every one).
    candidate_secant : int
        Broyden updates in a row in the candidates' fits (:func:`notchfit.analysis.estimation.solve.solve`).

    Returns
    -------
    Diagnosis
    """
    unknown = set(causes) - set(CAUSES)
    if unknown:
        raise ValueError(f"unknown cause(s) {sorted(unknown)}; known: {', '.join(CAUSES)}")
    opts = _Options(tuple(causes), metric, estimate_protocol, dict(calibrate_kw or {}), jobs, seed,
                    progress or (lambda msg: None), Thresholds(none_tol, z_crit, min_excess_removed), second_cause,
                    max_second, screen_candidates, screen_ratio, {"secant": candidate_secant})
    say, kw, st = opts.say, opts.calibrate_kw, _setup(experiments, opts)
    preps, folds = st.preps, folds_by_experiment(len(st.preps), max_folds)
    run_on = partial(run_folds, preps, calibrate_kw=kw, seed=seed, jobs=jobs, scheduler=scheduler,
                     scales=st.scales, base=st.base, fold_band=fold_band, cause_kw=opts.cause_kw)
    run = partial(run_on, folds)

    say(f"calibrating the baseline on {len(folds)} folds")
    base = restart_unconverged(run([None])["baseline"], folds, run_on)
    held, base_start = {"baseline": base}, [cal.start() for cal in base.calibrations]
    sigs = signatures(preps, base, base.mean_floor())
    order = [c for c, _, _ in rank_candidates(sigs, math.sqrt(base.mean_floor())) if c in st.order]
    say("fitting the baseline on all experiments")
    full_base = st.protocol_fit or calibrate(preps, None, base_start[0], scales=st.scales, base=st.base, **kw)
    score, single = partial(_score, base, preps, base.sample_mse(preps), opts.rule), partial(_single, run, base_start)
    singles, screen, unscreened = _singles(st, opts, order, full_base, single, score)
    held.update(singles)
    lof_kw = dict(tol_sigma=replicate_tol_sigma, alpha=lof_alpha)
    decide_first = partial(_decide, st, opts, held, _Ranked(sigs, tuple(order), screen, unscreened, score, lof_kw))
    first, second = _both_steps(st, opts, held, decide_first, run, single)
    named = second.causes
    say(f"fitting the extended model ({model_key(named)}) on all experiments")
    fits = _Fits(full_base, _extended(st, named, held, second.screened, kw),
                 held[model_key(named)].sample_mse(preps) if named else first.base_mse,
                 heldout_lack_of_fit(preps, held[model_key(named)].predicted, **lof_kw) if named else None)
    return _result(st, opts, held, first, second, fits)


@dataclass(frozen=True)
class _Ranked:
    """What the first decision reads besides the held-out fits: the baseline's signatures, the candidates in
    the order of their signatures' ranking, the screen's fits on all experiments (:func:`_singles`) and those
    it left out, the scoring against the baseline (:func:`_score`) and the lack-of-fit test's options."""
    sigs: object
    order: tuple
    screen: dict
    unscreened: tuple
    score: Callable
    lof_kw: dict


def _decide(st: _Study, opts: _Options, held: dict, r: _Ranked) -> _First:
    """The first step's decision (:func:`_lack_of_fit_first`) on the single candidates of ``held`` so far:
    those the screen left out (``r.unscreened``) and the second step later cross-validated alone take part."""
    sigs, order, screen, unscreened, score, lof_kw = r.sigs, r.order, r.screen, r.unscreened, r.score, r.lof_kw
    preps, base = st.preps, held["baseline"]
    singles = {c: held[c] for c in order if c in held}
    left = tuple(c for c in unscreened if c not in singles)
    noise, base_mse, band = _noise(base, singles, preps), base.sample_mse(preps), base.mean_band()
    cands = [score(c, singles) for c in order if c in singles]
    cause, lof = _lack_of_fit_first(cands, pooled_mse(base_mse), preps, base, lof_kw, noise + band,
                                    opts.rule.none_tol)
    return _First(cause, sigs, cands, base_mse, noise, lof, band, screen, left)


def _both_steps(st: _Study, opts: _Options, held: dict, decide_first, run, single) -> tuple[_First, SecondStep]:
    """The first decision and the second-cause step, taken again from the better first cause while the
    second step displaces it (a candidate the screen left out, cross-validated alone for its pair:
    :func:`~.pairs.second_step`); each round cross-validates at least one more candidate. A displacing
    candidate leaves the list of those not cross-validated (``st.skipped["screened"]``)."""
    first = decide_first()
    second = _second(st, opts, held, first, run, single, partial(_rival, decide_first, first.cause))
    while second.displaced:
        opts.say(f"{second.displaced} cross-validated alone is the better first cause: the second step again")
        first = decide_first()
        second = _second(st, opts, held, first, run, single, partial(_rival, decide_first, first.cause))
    if "screened" in st.skipped:
        st.skipped["screened"] = {c: why for c, why in st.skipped["screened"].items() if c in first.unscreened}
        if not st.skipped["screened"]:
            del st.skipped["screened"]
    return first, second


def _rival(decide_first, cause: str) -> str:
    """The first cause :func:`_decide` names now, when it is a candidate other than ``cause``; else ``""``."""
    now = decide_first().cause
    return now if now != cause and now in CANDIDATES else ""


def _score(base, preps, base_mse, rule: Thresholds, c: str, singles: dict):
    """Candidate ``c``'s :class:`~.results.CandidateResult` against the baseline's held-out errors, the noise
    floor that of the candidates cross-validated so far (:func:`_noise`)."""
    base_ms = pooled_mse(base_mse)
    noise = _noise(base, singles, preps)
    return score_candidate(c, singles[c], preps, base_mse, base_ms, base_ms - noise, z_crit=rule.z_crit,
                           min_excess_removed=rule.min_excess_removed)


def _single(run, starts, causes) -> dict:
    """``{cause: HeldOut}``: the candidates ``causes`` cross-validated alone by ``run`` from the baseline's
    fold optima ``starts``."""
    return run(causes, {c: starts for c in causes})


def _singles(st: _Study, opts: _Options, order, full_base, single, score) -> tuple[dict, dict, tuple]:
    """The single candidates cross-validated: ``({cause: HeldOut}, screen, not cross-validated)``.

    Without the screen (``opts.screen`` False) every candidate of ``order``. With it, each candidate is
    first fitted on every experiment from ``full_base`` (:func:`~.pairs.screen_singles`) and the
    candidates are cross-validated in the order of that in-sample error, until the next one's in-sample
    mean squared error is at least ``opts.screen_ratio`` times the held-out one of the best significant
    candidate so far: a model's held-out error is not below its in-sample one, so that candidate could
    not be the best (the decision names the best by held-out error). Those left are recorded in
    ``st.skipped["screened"]`` with their in-sample rms; they stay second candidates
    (:func:`_second`). Without a significant candidate every one is cross-validated. That bound holds
    only at the model's optimum: a candidate whose fit on all experiments stalled at its start
    (:attr:`~.calibration.Calibration.stalled`: every step tried raised the cost though the fit's linear
    model promised a decrease; a kink of the non-smooth cost, not an optimum) is never left out on it; it is
    cross-validated with the last ones.
    """
    if not order:
        return {}, {}, ()
    if not opts.screen:
        return single(order), {}, ()
    opts.say(f"screening {len(order)} candidate extensions on all experiments")
    screen = screen_singles(order, st.preps, full_base.start(), scales=st.scales, base=st.base,
                            calibrate_kw=opts.candidate_kw, jobs=opts.jobs)
    ranked = sorted(order, key=lambda c: screen[c][1])
    singles, best = {}, None
    for k, c in enumerate(ranked):
        if best is not None and screen[c][1] >= opts.screen_ratio * best.heldout_rms ** 2:
            stalled = [x for x in ranked[k:] if screen[x][0].stalled]
            if stalled:
                opts.say(f"cross-validating {', '.join(stalled)} (its fit on all experiments stalled at its start)")
                singles.update(single(stalled))
            left = tuple(x for x in ranked[k:] if x not in stalled)
            if not left:
                return singles, screen, ()
            best = _best_significant(score, singles)
            unit = st.preps[0].metric
            st.skipped["screened"] = {
                x: (f"in-sample rms {fmt_err(math.sqrt(screen[x][1]), unit)} on all experiments, not below "
                    f"{best.cause}'s held-out {fmt_err(best.heldout_rms, unit)}") for x in left}
            return singles, screen, left
        opts.say(f"cross-validating {c}")
        singles.update(single([c]))
        best = _best_significant(score, singles)
    return singles, screen, ()


def _best_significant(score, singles: dict):
    """The significant candidate of ``singles`` with the lowest held-out rms (``score``: :func:`_score`), or None."""
    sig = [r for r in (score(x, singles) for x in singles) if r.significant]
    return min(sig, key=lambda r: r.heldout_rms) if sig else None


def _lack_of_fit_first(cands, base_ms: float, preps, base, lof_kw: dict, noise: float, none_tol: float):
    """The verdict (:func:`~.decision.decide`) and the held-out baseline's lack of fit against the trials' scatter
    (``noise``: the baseline's floor [m² or rad²], its folds' prediction variance included);
    ``unexplained`` becomes ``none`` where trials repeat and the lack of fit is not material
    (:func:`~.replicates.lack_of_fit_first`)."""
    cause = decide(base_ms <= noise * (1.0 + none_tol), cands)
    lof = heldout_lack_of_fit(preps, base.predicted, **lof_kw)
    return lack_of_fit_first(cause, lof, noise, preps[0].point_factor, none_tol=none_tol), lof


def _result(st: _Study, opts: _Options, held, first: _First, second: SecondStep, fits: _Fits) -> Diagnosis:
    """The :class:`Diagnosis`: contributions, explanation, gains."""
    preps, rule, named, cause, sigs = st.preps, opts.rule, second.causes, first.cause, first.sigs
    metric = preps[0].metric
    base_rms, noise_rms = math.sqrt(pooled_mse(first.base_mse)), math.sqrt(first.noise)
    extended = fits.extended
    contribs = contributions(named, held, preps, first.noise, extended.values, metric=metric) if named else ()
    causes = tuple(c.cause for c in contribs)
    text = explain(cause, sigs, first.cands, base_rms, noise_rms, none_tol=rule.none_tol, z_crit=rule.z_crit,
                   min_removed=rule.min_excess_removed, metric=metric, baseline=_baseline_words(st.base, preps),
                   lack_of_fit=first.lack_of_fit, band_rms=math.sqrt(first.band))
    if named:
        text += pair_sentence(second, contribs, rule, metric=metric, alone=cause == second.first)
        if "joint_hysteresis" in named:
            text += hysteresis_shape(extended.values, st.scales.angle)
    if st.skipped["candidates"]:
        text += " Not tried: " + "; ".join(f"{c} ({why})" for c, why in st.skipped["candidates"].items()) + "."
    if st.skipped.get("screened"):
        text += (" Not cross-validated (fitted on all experiments, they could not beat the named cause): "
                 + "; ".join(f"{c} ({why})" for c, why in st.skipped["screened"].items()) + ".")
    if st.skipped["experiments"]:
        text += " To reveal what this study cannot: " + "; ".join(st.skipped["experiments"].values()) + "."
    text += " " + st.protocol["text"]
    return Diagnosis(experiments=tuple(p.name for p in preps), baseline=fits.baseline,
                     baseline_heldout_rms=base_rms, discrepancies=tuple(sigs), candidates=tuple(first.cands),
                     cause=causes[0] if causes else cause, explanation=text,
                     gain=Gain(base_rms, math.sqrt(pooled_mse(fits.ext_mse))), extended=extended,
                     per_regime=_per_regime(preps, first.base_mse, fits.ext_mse), noise_rms=noise_rms,
                     seed=opts.seed, heldout=held, prepared=preps, causes=causes, contributions=contribs,
                     pair_candidates=tuple(second.results), metric=metric, protocol=st.protocol,
                     skipped=st.skipped, base=st.base, lack_of_fit=first.lack_of_fit,
                     extended_lack_of_fit=fits.ext_lack_of_fit, band_rms=math.sqrt(first.band))
