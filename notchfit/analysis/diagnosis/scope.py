"""What a study lets the diagnosis ask: its base model, the candidates that apply, its protocol.

* The base model is the friction model the tube gets by default
  (:func:`notchfit.physics.friction.default_params`: the paper's for the seed tube, the
  material and capstan laws for a one-sided lumen-tendon wrist); its laws are
  kept, its calibrated parameters fitted.
* A candidate that cannot act on the study's measurements, or that its
  protocol cannot reveal, is skipped with its reason and the experiment that
  would reveal it (a calibration warp of the image-to-plane mapping on
  joint-angle data; a hysteresis loop or a proximal capstan band when no
  trial unloads: fitted on loading alone, their extra freedom stands in for
  what the baseline lacks and would be named for it).
* The protocol: ``[protocol] ramp_time_s`` of experiment.toml drives the
  simulations; where it is absent the diagnosis estimates it (data-format
  contract), conservatively, because rest shapes driven by noisy measured
  tensions hardly tell a step from a ramp. The baseline is calibrated on
  every experiment with a step, and its mean squared error compared with its
  own noise floor (the load-cell noise pushed through that protocol,
  :func:`notchfit.analysis.estimation.noise.noise_floor`). Within ``1 + none_tol`` of
  the floor the step is kept: nothing in the data asks for more. Beyond it
  (and up to ``ramp_cutoff`` times the floor) the baseline is calibrated with
  ramps too, and a ramp is taken only when it brings the error within the
  noise — a discrepancy that a ramp removes entirely. Otherwise a discrepancy
  dominates, the protocol cannot be told from the rest shapes, and a step is
  assumed. Measured on the null recipe (reduced studies, seeds 1-3): the
  ratio of a correctly simulated step to its floor was 0.46-0.94, of a step
  simulating 4 s-ramp data 0.56-1.10, of a 4 s ramp on step data 0.70-2.0:
  the lowest error, or the ratio closest to 1, would pick the wrong protocol
  (a ramp for step data in seed 2, after which a proximal band was named on
  a null study). The result says which, with the ratios.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ...batch import run_batch
from ..causes import REGISTRY, REQUIREMENTS, suggested_experiment
from ...physics.friction import default_params
from .calibration import SimulationCache, calibrate, predict_points
from ..estimation.noise import noise_floor
from .noise import pooled_mse
from ..estimation.observations import sample_mse

__all__ = ["applicable_causes", "base_model", "lacks", "resolve_protocol", "unloads"]


def base_model(preps):
    """The study's base model (:func:`notchfit.physics.friction.default_params` of its geometries).

    Raises
    ------
    ValueError
        The experiments' tubes have default models with different laws (one
        diagnosis calibrates one model).
    """
    models = [default_params(p.geom) for p in preps]
    laws = {(m.spring_law, m.friction_law) for m in models}
    if len(laws) > 1:
        raise ValueError("the study mixes tubes whose models have different laws "
                         f"({sorted(laws)}): diagnose them as separate studies")
    return models[0]


def unloads(prep, *, drop: float = 0.25, min_drop_sigma: float = 5.0) -> bool:
    """Whether an experiment unloads: after its peak the pulled tension falls by at least ``drop`` of the
    peak and by ``min_drop_sigma`` times the load cell's σ (a loading-only trial's noise is no unloading)."""
    t = np.asarray(prep.pulled_tension, dtype=float)
    if t.size < 2:
        return False
    k = int(np.nanargmax(t))
    fall = float(t[k] - np.nanmin(t[k:]))
    return fall >= drop * float(t[k]) and fall >= min_drop_sigma * float(np.max(prep.tension_sigma))


def lacks(preps) -> set:
    """The requirements (:data:`notchfit.analysis.causes.REQUIREMENTS`) the study does not meet."""
    out = set()
    if preps[0].metric == "angles":
        out.add("points")
    if not any(unloads(p) for p in preps):
        out.add("unloading")
    return out


def applicable_causes(preps, causes) -> tuple[tuple, dict, dict]:
    """The candidate causes that apply to the study, ``{cause: reason}`` for those skipped, and
    ``{cause: the experiment that would reveal it}`` for those an experiment could reveal.

    A cause applies when the study has what its record requires
    (:attr:`notchfit.analysis.causes.Cause.requires`: notch points, a trial that unloads); the first
    requirement missing gives the reason, and every missing one an experiment can supply gives a
    suggestion (:func:`notchfit.analysis.causes.suggested_experiment`) unless one that cannot be
    supplied is missing.
    """
    missing = lacks(preps)
    skipped, reveal = {}, {}
    for c in causes:
        needs = [n for n in REQUIREMENTS if n in missing and n in REGISTRY[c].requires]
        if not needs:
            continue
        skipped[c] = REGISTRY[c].requires[needs[0]]
        tests = [suggested_experiment(c, n) for n in needs]
        if all(tests):
            reveal[c] = "; ".join(tests)
    return tuple(c for c in causes if c not in skipped), skipped, reveal


@dataclass(frozen=True)
class _RampFits:
    """What the protocol's calibrations share: the experiments, those whose protocol is recorded, the base
    model, the study scales, :func:`calibrate`'s options and the noise floors' seed."""

    preps: tuple
    known: set
    base: object
    scales: object
    calibrate_kw: dict
    seed: int


def _fit_ramp(item):
    """Baseline on every experiment with the unknown protocols set to one ramp time, its mean squared
    error and its noise floor [m² or rad²] (a batch item: ``(_RampFits, ramp time [s])``)."""
    fits, ramp = item
    preps = tuple(p if p.name in fits.known else dataclasses.replace(p, ramp_time=ramp) for p in fits.preps)
    base = fits.base
    with threadpool_limits(limits=1):
        cache = SimulationCache.shared()
        cal = calibrate(preps, None, None, scales=fits.scales, base=base, cache=cache, **fits.calibrate_kw)
        pred = [predict_points(p, cal.values, cache=cache, base=base, tubes=cal.tubes)[0] for p in preps]
        ms = pooled_mse([sample_mse(p, q) for p, q in zip(preps, pred)])
        floor = pooled_mse([noise_floor(p, cal.params(base, p.tube), cache, seed=fits.seed) for p in preps])
    return ramp, cal, ms, floor


def resolve_protocol(preps, recorded: dict, base, scales, calibrate_kw: dict | None = None, *,
                     estimate: bool = True, fractions=(0.8,), none_tol: float = 0.5, seed: int = 0,
                     ramp_cutoff: float = 3.0, jobs: int = 1):
    """The protocol of every experiment: recorded, estimated, or a step assumed (module docstring).

    Parameters
    ----------
    preps : sequence of Prepared
    recorded : dict
        ``{experiment: ramp_time_s or None}`` from experiment.toml.
    base, scales :
        The base model and the study scales (:func:`calibrate`).
    calibrate_kw : dict, optional
    estimate : bool
        Estimate an unknown protocol (else a step is assumed).
    fractions : sequence of float
        Ramp times tried besides a step, as fractions of the median sample interval.
    none_tol : float
        A protocol is told from the rest shapes only when the baseline's mean
        squared error with it is within ``1 + none_tol`` of its noise floor.
    seed : int
        Seed of the noise floors' draws.
    ramp_cutoff : float
        The ramps are fitted only when the step leaves at most this many times
        its noise floor.
    jobs : int
        Worker processes for the calibrations.

    Returns
    -------
    preps : tuple of Prepared
        With their ``ramp_time`` set.
    protocol : dict
        ``{"ramp_time_s": {name: s}, "source": {name: "experiment.toml" | "estimated" |
        "assumed"}, "text": str}``.
    calibration : Calibration or None
        The baseline on every experiment at the chosen protocol (when estimated).
    """
    known = {k for k, v in recorded.items() if v is not None}
    unknown = [p.name for p in preps if p.name not in known]
    cal, how = None, "assumed"
    if not unknown:
        text = "The protocol of every experiment is given by its experiment.toml ([protocol] ramp_time_s)."
    elif not estimate:
        preps = tuple(p if p.name in known else dataclasses.replace(p, ramp_time=0.0) for p in preps)
        text = (f"experiment.toml gives no [protocol] for {', '.join(unknown)}: a step was assumed (the "
                "tensions jump to each sample's values and the tube comes to rest).")
    else:
        fits = _RampFits(tuple(preps), known, base, scales, dict(calibrate_kw or {}), seed)
        preps, cal, text, how = _estimate(fits, unknown, fractions, none_tol=none_tol, ramp_cutoff=ramp_cutoff,
                                          jobs=jobs)
    source = {p.name: "experiment.toml" if p.name in known else how for p in preps}
    return preps, {"ramp_time_s": {p.name: p.ramp_time for p in preps}, "source": source, "text": text}, cal


def _estimate(ramp_fits: _RampFits, unknown, fractions, *, none_tol: float, ramp_cutoff: float, jobs: int):
    """A step unless only a ramp brings the calibrated baseline within the noise (module docstring)."""
    preps, known = ramp_fits.preps, ramp_fits.known
    dt = float(np.median(np.concatenate([np.diff(p.time) for p in preps if p.name in unknown])))
    _, cal0, ms0, fl0 = _fit_ramp((ramp_fits, 0.0))
    fits = {0.0: (cal0, ms0 / fl0)}
    if 1.0 + none_tol < ms0 / fl0 <= ramp_cutoff:
        ramps = [round(f * dt, 6) for f in fractions]
        items = [(ramp_fits, r) for r in ramps]
        res = run_batch(_fit_ramp, items, keys=[f"ramp {r:g} s" for r in ramps], jobs=jobs, progress=False,
                        start_method=multiprocessing.get_start_method())
        if res.failures:
            raise RuntimeError(res.summary("protocol estimation"))
        fits.update({r: (cal, ms / fl) for r, cal, ms, fl in res.values()})
    ratios = ", ".join(("a step" if r == 0 else f"a {r:g} s ramp") + f" {q:.2f}×" for r, (_, q) in fits.items())
    within = [r for r, (_, q) in fits.items() if q <= 1.0 + none_tol]
    missing = ", ".join(unknown)
    if 0.0 in within:
        best, how = 0.0, "estimated"
        text = (f"experiment.toml gives no [protocol] for {missing}: estimated as a step — with a step the "
                f"calibrated baseline leaves {fits[0.0][1]:.2f}× its noise floor, nothing asks for a ramp (rest "
                "shapes driven by noisy tensions hardly tell a step from a ramp).")
    elif within:
        best, how = min(within, key=lambda r: fits[r][1]), "estimated"
        text = (f"experiment.toml gives no [protocol] for {missing}: estimated as a ramp over {best:g} s of each "
                f"{dt:g} s interval, then rest — the only protocol with which the calibrated baseline explains "
                f"the data within the noise ({ratios} of each protocol's noise floor).")
    else:
        best, how = 0.0, "assumed"
        text = (f"experiment.toml gives no [protocol] for {missing}: a step was assumed; the protocol cannot be "
                "told from these rest shapes, since the calibrated baseline leaves an excess over the noise "
                f"floor with every protocol tried ({ratios}).")
    preps = tuple(p if p.name in known else dataclasses.replace(p, ramp_time=best) for p in preps)
    return preps, fits[best][0], text, how
