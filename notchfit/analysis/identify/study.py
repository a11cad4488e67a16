"""``identify``: calibrate the model on a study, with held-out errors (:func:`identify`)."""

from __future__ import annotations

import math
import multiprocessing
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np
from threadpoolctl import threadpool_limits

from ...batch import run_batch
from ...physics.friction import FrictionParams
from ...physics.friction_params import PARAM_KEYS
from ...units import DEG, MM
from ..estimation.observations import METRICS, metric_unit, observe_study
from ..estimation.bands import NewTubePrior
from ..estimation.identifiability import Identifiability, assess
from ..estimation.problem import measure_registered
from ..estimation.solve import folds, forward_jacobian, se_values, tube_folds
from ..lack_of_fit import Trial, lack_of_fit_summary, study_lack_of_fit
from .problem import Solution, errors, make_problem, predict, solve, steps, with_values
from .specs import (DEPTH, DEPTH_COMMON, DEPTH_RANGE, DEPTH_TOLERANCE, REST, REST_RANGE, REST_SIGMA_GEOMETRY, REST_SIGMA_MIN,
                    base_model, default_free, parse_free, specs_for)

__all__ = ["FIT_SOLVER", "Identification", "TubeFit", "identify"]

#: The fast solver's options inside the fits: joints move at most 2 mrad per step while a link
#: slides (default 0.5 mrad): half the time, within 0.014° of the default on the shipped wrists
#: (benchmarks/bench_identify.py); the reported errors use the defaults.
FIT_SOLVER = {"dtheta_max": 2e-3}


@dataclass(frozen=True)
class TubeFit:
    """One tube's identified per-notch values (n joints).

    Attributes
    ----------
    name : str
        Tube label (:func:`notchfit.analysis.estimation.observations.tube_labels`).
    experiments : tuple of str
    rest_angles, rest_se : ndarray (n,) [rad]
        Rest angles used (identified, or the geometry's) and their standard errors (NaN: not identified).
    slot_depths : ndarray (n,) [m]
        Effective cut depths used (the geometry's plus the identified offsets).
    depth_offsets, depth_se : ndarray (n,) [m]
        Identified offsets from the geometry's depths (0 when not identified) and their standard errors.
    model : FrictionParams
        The tube's model: the shared values with its rest angles and cut depths.
    rest_prior, rest_prior_sd : ndarray (n,) [rad]
        The prior of the rest angles: measured at zero force in the tube's trials (or the geometry's)
        and its standard deviation (NaN: no prior).
    depth_prior_sd : float [m]
        The prior standard deviation of each cut-depth offset (the tolerance; NaN: not identified).
    """

    name: str
    experiments: tuple
    rest_angles: np.ndarray = field(repr=False)
    rest_se: np.ndarray = field(repr=False)
    slot_depths: np.ndarray = field(repr=False)
    depth_offsets: np.ndarray = field(repr=False)
    depth_se: np.ndarray = field(repr=False)
    model: FrictionParams = field(repr=False)
    rest_prior: np.ndarray | None = field(default=None, repr=False)
    rest_prior_sd: np.ndarray | None = field(default=None, repr=False)
    depth_prior_sd: float = math.nan

    def as_dict(self) -> dict:
        """Degrees and millimetres (µm for the depth offsets), as in ``identify.json``."""
        deg = lambda a: [math.degrees(float(v)) for v in a]  # noqa: E731
        um = lambda a: [float(v) * 1e6 for v in a]  # noqa: E731
        nan = np.full(len(self.rest_angles), math.nan)
        return {"experiments": list(self.experiments), "rest_angle_deg": deg(self.rest_angles),
                "rest_angle_se_deg": deg(self.rest_se),
                "rest_angle_prior_deg": deg(nan if self.rest_prior is None else self.rest_prior),
                "rest_angle_prior_sd_deg": deg(nan if self.rest_prior_sd is None else self.rest_prior_sd),
                "slot_depth_mm": [float(v) / MM for v in self.slot_depths],
                "slot_depth_offset_um": um(self.depth_offsets), "slot_depth_offset_se_um": um(self.depth_se),
                "slot_depth_prior_sd_um": float(self.depth_prior_sd) * 1e6}


@dataclass(frozen=True)
class Identification:
    """The identified model of a study and how well it predicts experiments it never saw.

    Errors are in the metric's file unit (:attr:`unit`): degrees (joint angles) or millimetres
    (notch-point distances); an rms is over every measured value it covers
    (the "rms per notch" of the real-tube literature for angles).

    Attributes
    ----------
    metric : {"angles", "points"}
    free : tuple of str
        The scalar free parameters (FrictionParams field names), in fit order.
    values, se : dict
        Their identified values and standard errors (SI; :func:`notchfit.analysis.identify.problem.standard_errors`).
    tube_free : tuple of str
        The per-tube unknowns identified: ``"rest_angle"``, ``"slot_depth"``.
    tubes : dict
        Tube label -> :class:`TubeFit`.
    model : FrictionParams
        The shared model: the base model with ``values``; with one tube, also
        its rest angles and cut depths (its :attr:`TubeFit.model`).
    experiment_tubes : dict
        Experiment -> tube label.
    train_rms : float
        Rms error of the fit on every experiment.
    train : dict
        Experiment -> its rms error in that fit.
    heldout_rms : float
        Rms error of each experiment predicted by the model fitted without it
        (leave one experiment out), over every experiment's values; NaN with one experiment.
    heldout : dict
        Experiment -> its held-out rms error.
    heldout_by_tube : dict
        With several tubes: tube -> rms error of its experiments predicted by the
        model fitted on the other tubes only (from its geometry file: its rest
        angles and depths as drawn).
    solution : Solution
        The fit on every experiment (cost, evaluations, convergence).
    identifiability : Identifiability or None
        What the data determine: a verdict per free parameter of the fit on every experiment
        (:func:`notchfit.analysis.estimation.identifiability.assess`).
    fixed : dict
        Parameters the data did not determine, fixed at their start values (the base model's) and
        fitted no further: name -> value (SI). They are not among :attr:`free`.
    lack_of_fit : dict
        Tube -> :class:`notchfit.analysis.lack_of_fit.LackOfFit` of the fit on every experiment: the
        trials' scatter (pure error) and the error beyond it, per notch and per force range, with
        its F test (in :attr:`unit`).
    new_tube : NewTubePrior or None
        What the model knows of a tube it has never seen (the shared parameters' covariance, the
        tube-to-tube scatter of rest angles and cut depths): the prediction bands of ``simulate
        --model`` and :class:`notchfit.analysis.estimation.bands.BandPredictor`.
    """

    metric: str
    free: tuple
    values: dict
    se: dict
    tube_free: tuple
    tubes: dict
    model: FrictionParams
    experiment_tubes: dict
    train_rms: float
    train: dict
    heldout_rms: float
    heldout: dict
    heldout_by_tube: dict = field(default_factory=dict)
    solution: Solution | None = field(default=None, repr=False)
    identifiability: Identifiability | None = field(default=None, repr=False)
    fixed: dict = field(default_factory=dict)
    lack_of_fit: dict = field(default_factory=dict, repr=False)
    new_tube: NewTubePrior | None = field(default=None, repr=False)

    @property
    def unit(self) -> str:
        """The file unit of the errors: ``"deg"`` (joint angles) or ``"mm"`` (notch points)."""
        return METRICS[self.metric]

    def summary(self) -> str:
        """What ``notchfit identify`` prints: the identified values with their standard errors, each tube's
        per-notch values, and the training and held-out errors (in :attr:`unit`)."""
        unit, data = self.unit, self.as_dict()
        lines = [f"identify: {len(self.experiment_tubes)} experiments, {len(self.tubes)} tube(s), errors in {unit}"]
        lines += [f"  {key:18s} = {v:.5g} ± {data['se'][key]:.2g}" for key, v in data["params"].items()]
        lines += [f"  {PARAM_KEYS[f]:18s}   not determined by these data: fixed at its start value {v:.5g}"
                  for f, v in self.fixed.items()]
        for tube, fit in self.tubes.items():
            if REST in self.tube_free:
                lines.append(f"  {tube}: rest angles [deg] " + ", ".join(f"{v / DEG:.2f}" for v in fit.rest_angles))
                if fit.rest_prior is not None and np.isfinite(fit.rest_prior).any():
                    lines.append(f"  {tube}: their prior (zero-force trials, else geometry) [deg] " + ", ".join(
                        f"{m / DEG:.2f} ± {sd / DEG:.2f}" for m, sd in zip(fit.rest_prior, fit.rest_prior_sd)))
            if DEPTH in self.tube_free:
                lines.append(f"  {tube}: cut depths [mm] " + ", ".join(f"{v / MM:.4f}" for v in fit.slot_depths))
        held = "" if math.isnan(self.heldout_rms) else (f"; held-out rms {self.heldout_rms:.3f} {unit} "
                                                        "(each experiment predicted by a model fitted without it)")
        lines.append(f"train rms {self.train_rms:.3f} {unit}{held}")
        lines += [f"  {name:12s} held out {v:.3f} {unit}" for name, v in self.heldout.items()]
        lines += [f"  tube {tube}: predicted from the other tubes' fit {v:.3f} {unit}"
                  for tube, v in self.heldout_by_tube.items()]
        if self.lack_of_fit:
            lines.append(lack_of_fit_summary(self.lack_of_fit))
        return "\n".join(lines)

    def as_dict(self) -> dict:
        """The ``identify.json`` mapping (docs/data-formats.md): file keys with units, per-tube values."""
        key = PARAM_KEYS
        tube_keys = {REST: "rest_angle_rad", DEPTH: "slot_depth_offset_m"}
        sol = self.solution
        return {
            # `free` names exactly the keys of `params` and `se` (readers of the contract's form can
            # look every free name up); the per-tube parameters are listed apart, values under `tubes`
            "free": [key[f] for f in self.free],
            "free_per_tube": [tube_keys[f] for f in self.tube_free],
            "params": {key[f]: self.values[f] for f in self.free},
            "se": {key[f]: self.se[f] for f in self.free},
            "metric": self.unit, "train_rms": self.train_rms, "heldout_rms": self.heldout_rms,
            "heldout": dict(self.heldout), "train": dict(self.train),
            "heldout_by_geometry": dict(self.heldout_by_tube),
            "tubes": {t: f.as_dict() for t, f in self.tubes.items()},
            # parameters the data do not determine: fixed at their start value, never printed as a number
            # plus or minus many times itself; the verdicts of the first fit, per free parameter
            "fixed_at_prior": {key[f]: v for f, v in self.fixed.items()},
            "lack_of_fit": {t: lof.as_dict() for t, lof in self.lack_of_fit.items()},
            "prediction": None if self.new_tube is None else self.new_tube.as_metadata(),
            "identifiability": None if self.identifiability is None else {
                key.get(p.name, p.name): {"verdict": p.verdict, "relative_se": p.relative_se,
                                          "null_weight": p.null_weight}
                for p in self.identifiability.parameters if p.name in key},
            "fit": None if sol is None else {"cost": sol.cost, "n_residuals": sol.n_residuals,
                                             "success": sol.success, "message": sol.message, "nfev": sol.nfev,
                                             "starts": sol.starts},
        }


@dataclass(frozen=True)
class _Task:
    """One fit: the experiments it trains on (indices into ``obs``) and the ones it predicts.

    ``kind``: ``"all"`` (the fit on every experiment), ``"experiment"`` (one left
    out), ``"tube"`` (one tube's experiments left out); ``key`` names the fit. ``part``: ``""``
    (the whole procedure: probe grid and ``n_starts`` runs), ``"warm"`` (one run from ``warm``,
    the fit on every experiment: :func:`_warm_start`), ``"grid"`` (one run from the grid's best).
    A tube's held-out fit with a warm start is its ``"grid"`` and ``"warm"`` parts, the lower cost
    kept (:func:`_merge`): the grid part needs nothing of the fit on every experiment and runs beside it.
    """

    kind: str
    obs: tuple
    train: tuple
    test: tuple
    base: dict
    free: tuple
    start: FrictionParams | None
    excess: float
    options: dict
    key: str = "all"
    part: str = ""
    warm: _FitJacobian | None = None
    seed_jacobian: bool = True

    @classmethod
    def full(cls, obs, base: dict, free: tuple, start: FrictionParams | None, excess: float, options: dict) -> _Task:
        """The fit on every experiment (the held-out fits are it with another split: :func:`_tasks`)."""
        return cls("all", obs, tuple(range(len(obs))), (), base, free, start, excess, options)


#: The options of :func:`_Task.options` that build the problem (the others solve it).
_PROBLEM_OPTIONS = ("sim_kw", "rest_range", "depth_range", "depth_sigma", "depth_common", "rest_prior",
                    "rest_sigma_geometry", "rest_sigma_min")


class _FitOut(NamedTuple):
    """What one fit returns: its problem and solution, each tube's model and the held-out experiments'
    errors (experiment -> errors)."""

    pb: object
    sol: Solution
    fitted: dict
    preds: dict


def _fit(task: _Task) -> _FitOut:
    """Fit on the training experiments; predict the test ones (a batch item)."""
    with threadpool_limits(limits=1):
        train = [task.obs[i] for i in task.train]
        models = [task.base[o.tube] for o in train]
        specs = specs_for(task.free, models, start=task.start)
        opt = dict(task.options)
        prob_kw = {k: opt.pop(k) for k in _PROBLEM_OPTIONS if k in opt}
        pb = make_problem(train, task.base, specs, rest=REST in task.free, depth=DEPTH in task.free,
                          excess=task.excess, **prob_kw)
        if task.kind != "all":
            opt["errors"] = False            # a held-out fit predicts; its standard errors are not read
        if task.part == "warm":              # one run from the fit on every experiment, with its Jacobian
            pb = replace(pb, x0=_warm_x(pb, task.warm))
            if task.seed_jacobian:
                opt["jacobian0"] = task.warm.for_problem(pb, steps(pb, pb.x0, opt["diff_rel"], opt["rest_step"]))
            opt.update(grid=False, n_starts=1)
        elif task.part == "grid":            # one run from the grid's best (the warm part competes)
            opt.update(n_starts=1)
        sol = solve(pb, **opt)
        fitted = pb.params(sol.x)
        vals = pb.values(sol.x)
        preds = {}
        for i in task.test:
            o = task.obs[i]
            params = fitted.get(o.tube, with_values(task.base[o.tube], vals, task.excess))
            preds[o.name] = errors(o, predict(o, params))
        return _FitOut(pb, sol, fitted, preds)


@dataclass(frozen=True)
class _FitJacobian:
    """A fit's optimum and its forward-difference Jacobian there (:attr:`Solution.jacobian`), with their
    layout: experiment -> its rows, unknown (``("", spec name)`` or ``(owner, block name)``) -> its columns.
    ``h``, ``lo``, ``hi``: the steps and bounds the Jacobian was computed with."""

    x: np.ndarray
    J: np.ndarray
    h: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    rows: dict
    cols: dict

    @classmethod
    def of(cls, pb, sol, h) -> "_FitJacobian":
        rows, r = {}, 0
        for o in pb.obs:
            rows[o.name] = (r, r + o.valid.size * o.values_per_item)
            r = rows[o.name][1]
        cols = {("", s.name): (i, i + 1) for i, s in enumerate(pb.specs)}
        c = pb.k
        for b in pb.blocks:
            cols[b.owner, b.name] = (c, c + b.size)
            c += b.size
        return cls(np.asarray(sol.x, float), sol.jacobian, np.asarray(h, float), pb.lo, pb.hi, rows, cols)

    def index(self, pb) -> np.ndarray | None:
        """The columns of ``pb``'s unknowns (None when it has one the fit had not)."""
        keys = [k for k, _ in _unknowns(pb)]
        if any(k not in self.cols for k in keys):
            return None
        return np.concatenate([np.arange(*self.cols[k]) for k in keys])

    def for_problem(self, pb, h) -> np.ndarray | None:
        """The forward-difference Jacobian of ``pb`` (a subset of the fit's experiments and unknowns, its
        own priors) at its start ``pb.x0`` with steps ``h``, bit for bit as
        :func:`notchfit.analysis.estimation.solve.forward_jacobian` would compute it, without a simulation:
        the fit's rows and columns of its experiments and unknowns (whose residuals are the fit's), then
        the differences of its linear prior rows. None unless its start, steps and bounds are the fit's."""
        cols = self.index(pb)
        if self.J is None or cols is None or any(o.name not in self.rows for o in pb.obs):
            return None
        same = [np.array_equal(a, b[cols]) for a, b in ((pb.x0, self.x), (h, self.h), (pb.lo, self.lo),
                                                         (pb.hi, self.hi))]
        if not all(same):
            return None
        rows = np.concatenate([np.arange(*self.rows[o.name]) for o in pb.obs])
        # the prior rows by the same differences: the problem's own, its residuals only the prior's
        prior = forward_jacobian(SimpleNamespace(residuals=pb.prior_residuals, hi=pb.hi), pb.x0, h)
        return np.vstack([self.J[np.ix_(rows, cols)], prior])


def _unknowns(pb) -> list:
    """``pb``'s unknowns in the order of ``x``: (key, size), key ``("", spec name)`` or ``(owner, block name)``."""
    return [(("", s.name), 1) for s in pb.specs] + [((b.owner, b.name), b.size) for b in pb.blocks]


def _warm_x(pb, jac: _FitJacobian) -> np.ndarray:
    """``pb``'s unknowns at the fit's optimum ``jac.x`` (where it has them; its own start elsewhere),
    clipped inside the bounds."""
    x0, i = pb.x0.copy(), 0
    for k, size in _unknowns(pb):
        if k in jac.cols:
            x0[i:i + size] = jac.x[slice(*jac.cols[k])]
        i += size
    margin = 1e-9 * (pb.hi - pb.lo)
    return np.clip(x0, pb.lo + margin, pb.hi - margin)


def _rms(values) -> float:
    v = np.concatenate([np.ravel(a) for a in values]) if values else np.zeros(0)
    return float(np.sqrt(np.mean(v * v))) if v.size else math.nan


def _base_models(obs, model: FrictionParams | None) -> dict:
    """Tube -> base model: ``model`` (a model with rest angles belongs to one tube) or the geometry's default."""
    tubes = dict.fromkeys(o.tube for o in obs)
    if model is not None and model.rest_angle is not None and len(tubes) > 1:
        raise ValueError("the --model file holds rest angles (rest_angle_rad), which belong to one tube; this "
                         f"study has {len(tubes)} tubes ({', '.join(tubes)}): remove rest_angle_rad from it")
    out = {}
    for t in tubes:
        geom = next(o.geom for o in obs if o.tube == t)
        out[t] = model if model is not None else base_model(geom)
        out[t].rest_angles(geom)           # checks the model's rest angles against the tube
    return out


def _tasks(full: _Task, *, heldout: bool, by_tube: bool, warm_start: bool) -> list:
    """The fit on every experiment (``full``), one fit per left-out experiment, one per left-out tube
    (:class:`_Task`: ``full`` with another split). With ``warm_start`` the held-out fits start from the fit
    on every experiment (their ``"warm"`` parts, :func:`_warm_start` fills ``warm`` in); a tube's also
    from the probe grid (its ``"grid"`` part)."""
    obs, idx = full.obs, full.train
    tasks = [full]

    def held_out(kind, key, test, part):
        test = tuple(int(i) for i in test)
        return replace(full, kind=kind, train=tuple(j for j in idx if j not in test), test=test, key=key,
                       part=part)

    if heldout and len(obs) > 1:
        for f in folds(len(obs)):
            tasks.append(held_out("experiment", f"without {obs[f[0]].name}", f, "warm" if warm_start else ""))
    for t, f in (tube_folds(obs) if by_tube else {}).items():
        parts = ("grid", "warm") if warm_start else ("",)
        tasks += [held_out("tube", f"without tube {t}", f, part) for part in parts]
    return tasks


def identify(exps, *, free=None, model: FrictionParams | None = None, heldout: bool = True,
             by_tube: bool = True, jobs: int = 1, scheduler=None, n_starts: int = 2, loss: str = "linear",
             f_scale: float = 3.0, max_nfev: int = 100, ftol: float = 1e-6, xtol: float = 1e-6,
             diff_rel: float = 2e-3, rest_step: float = 2e-4, rest_range: float = REST_RANGE,
             depth_range: float = DEPTH_RANGE, depth_sigma: float | None = None,
             depth_common: float | None = DEPTH_COMMON, rest_prior: bool = True,
             rest_sigma_geometry: float = REST_SIGMA_GEOMETRY, rest_sigma_min: float = REST_SIGMA_MIN,
             sim_kw: dict | None = None, fix_undetermined: bool = True, warm_start: bool = True) -> Identification:
    """Identify the model's parameters on a study; held-out errors by leaving experiments (and tubes) out.

    Parameters
    ----------
    exps : sequence of notchfit.io.Experiment
        With measured joint angles (every one) or notch points (every one);
        they may use different geometries (tubes): all share the scalar
        parameters, each tube has its own rest angles.
    free : sequence of str, optional
        Parameters to fit (field names or model-file keys, ``rest_angle`` for
        the rest angles); default :func:`notchfit.analysis.identify.specs.default_free`.
    model : FrictionParams, optional
        Base model (the values of everything not fitted, and the starts);
        default :func:`notchfit.analysis.identify.specs.base_model` of each geometry
        (the geometry's default model; quasi-static damping for the material law).
    heldout, by_tube : bool
        Also refit without each experiment / without each tube (when the study has several).
    jobs, scheduler :
        The fits run on :func:`notchfit.batch.run_batch`.
    n_starts, loss, f_scale, max_nfev, ftol, xtol, diff_rel, rest_step :
        Passed to :func:`notchfit.analysis.identify.problem.solve` (every fit alike).
    rest_range : float
        How far the rest angles may move from the geometry's [rad].
    depth_range, depth_sigma, depth_common : float
        Cut-depth offsets: bound, Gaussian prior per notch (the cutting tolerance; None: each
        geometry's ``slot_depth_tolerance_mm``, else 15 µm) and of a tube's mean (None: free) [m]
        (:func:`notchfit.analysis.identify.problem.make_problem`).
    rest_prior, rest_sigma_geometry, rest_sigma_min :
        Tie each tube's rest angles to the angles its trials measured at zero force, with their
        standard error (else to the geometry's, σ ``rest_sigma_geometry`` [rad]; at least
        ``rest_sigma_min`` [rad]); False: rest angles free within ``rest_range`` (the behaviour
        before the prior).
    sim_kw : dict, optional
        Options of :func:`notchfit.physics.friction.simulate` during the fits (default
        :data:`FIT_SOLVER`); the reported errors always use its defaults.
    fix_undetermined : bool
        When the fit on every experiment leaves a shared parameter undetermined
        (:func:`notchfit.analysis.estimation.identifiability.assess` on its Jacobian), fix it at its
        start value and make every fit without it (:attr:`Identification.fixed`). The fit on every
        experiment therefore runs before the held-out fits.
    warm_start : bool
        The held-out fits start from the fit on every experiment (one least-squares run, no probe
        grid: the data of all but one experiment or tube put the optimum near it; a tube's also runs
        from the best of its probe grid, the lower cost kept); False: each runs the full procedure
        from the probe grid. With ``jobs`` > 1 the fits that need nothing of the fit on every
        experiment (a tube's from its grid; every held-out fit without ``warm_start``) run beside it,
        and every batch of fits is handed out largest first.

    Returns
    -------
    Identification
    """
    obs = observe_study(exps, prefer="angles", who="identify")
    base = _base_models(obs, model)
    free = parse_free(free) if free is not None else default_free(list(base.values()), [o.geom for o in obs])
    first = next(iter(base.values()))
    excess = max(first.mu_s - first.mu_d, 0.0)
    options = dict(n_starts=n_starts, loss=loss, f_scale=f_scale, max_nfev=max_nfev, ftol=ftol, xtol=xtol,
                   diff_rel=diff_rel, rest_step=rest_step, rest_range=rest_range, depth_range=depth_range,
                   depth_sigma=depth_sigma, depth_common=depth_common, rest_prior=rest_prior,
                   rest_sigma_geometry=rest_sigma_geometry, rest_sigma_min=rest_sigma_min,
                   sim_kw=dict(FIT_SOLVER if sim_kw is None else sim_kw))
    run = dict(jobs=jobs, scheduler=scheduler)
    # in parallel, the held-out fits that need nothing of the fit on every experiment run beside it
    beside = (jobs != 1 or scheduler is not None)

    def plan(free):
        tasks = _tasks(_Task.full(obs, base, free, model, excess, options), heldout=heldout, by_tube=by_tube,
                       warm_start=warm_start)
        return tasks, [t for t in tasks if t.kind == "all" or (beside and t.part != "warm")]

    tasks, early = plan(free)
    outs = _run(early, run)
    verdicts = _identifiability(outs["all", ""].pb, outs["all", ""].sol)
    drop = [f for f in verdicts.undetermined() if f in free] if fix_undetermined else []
    if drop:
        # a parameter the data do not determine stays at its start value; every fit is made without it
        free = tuple(f for f in free if f not in drop)
        tasks, early = plan(free)
        outs = _run(early, run)
    warm = _warm_start(outs["all", ""], options) if warm_start else None
    later = [replace(t, warm=warm if t.part == "warm" else None) for t in tasks if (t.key, t.part) not in outs]
    outs.update(_run(later, run))
    result = _result(obs, base, free, excess, tasks, outs)
    return replace(result, identifiability=verdicts, fixed={f: float(getattr(first, f)) for f in drop})


def _warm_start(fit: _FitOut, options: dict) -> _FitJacobian:
    """Where the held-out fits start: the optimum of ``fit`` (the fit on every experiment) with its
    Jacobian there, which their first least-squares step uses."""
    return _FitJacobian.of(fit.pb, fit.sol, steps(fit.pb, fit.sol.x, options["diff_rel"], options["rest_step"]))


def _run(tasks: list, run: dict) -> dict:
    """The fits ``tasks`` on :func:`notchfit.batch.run_batch`, the largest first (those from the probe grid,
    then by training samples: two workers end together); (key, part) -> :class:`_FitOut`."""
    if not tasks:
        return {}
    tasks = sorted(tasks, key=lambda t: (t.part != "warm", sum(t.obs[i].time.size for i in t.train)), reverse=True)
    # the platform's default start method (fork on Linux), as the diagnosis's folds: spawned workers
    # re-import notchfit and reload the kernels, several seconds for fits of about one second
    res = run_batch(_fit, tasks, keys=[f"{t.key} {t.part}".strip() for t in tasks], jobs=run["jobs"],
                    scheduler=run["scheduler"], desc="identify", start_method=multiprocessing.get_start_method())
    if res.failures:
        raise ValueError("identify: " + "; ".join(f"the fit {r.key}: {r.error}" for r in res.failures))
    return {(t.key, t.part): v for t, v in zip(tasks, res.values())}


def _block_priors(pb) -> dict:
    """Tube -> {block name: (mean, sd) (n,), (n,)} of the per-unknown prior rows of its blocks."""
    single = (pb.prior != 0).sum(axis=1) == 1
    mean_sd = {}
    offset = np.zeros(pb.prior.shape[0]) if pb.prior_offset is None else pb.prior_offset
    for r in np.flatnonzero(single):
        i = int(np.flatnonzero(pb.prior[r])[0])
        w = float(pb.prior[r, i])
        mean_sd[i] = (float(offset[r]) / w, 1.0 / abs(w))
    out, i = {}, pb.k
    for b in pb.blocks:
        rows = [mean_sd.get(k, (math.nan, math.nan)) for k in range(i, i + b.size)]
        out.setdefault(b.owner, {})[b.name] = (np.array([m for m, _ in rows]), np.array([s for _, s in rows]))
        i += b.size
    return out


def _tube_fits(obs, pb, sol, fitted) -> dict:
    """Tube -> :class:`TubeFit` of the full fit."""
    se_of = pb.tube_values(sol.se)
    priors = _block_priors(pb)
    out = {}
    for t in dict.fromkeys(o.tube for o in obs):
        geom = next(o.geom for o in obs if o.tube == t)
        p, n = fitted[t], geom.n_joints
        nan = np.full(n, math.nan)
        rest_prior = priors.get(t, {}).get("rest_angle", (None, None))
        depth_sd = priors.get(t, {}).get("slot_depth_offset", (None, nan))[1]
        out[t] = TubeFit(name=t, experiments=tuple(o.name for o in obs if o.tube == t),
                         rest_angles=p.rest_angles(geom), rest_se=se_of.get(t, {}).get("rest_angle", nan),
                         slot_depths=p.depth_geometry(geom).slot_depths,
                         depth_offsets=np.zeros(n) if p.slot_depth_offset is None
                         else np.broadcast_to(np.asarray(p.slot_depth_offset, float), (n,)).copy(),
                         depth_se=se_of.get(t, {}).get("slot_depth_offset", nan), model=p,
                         rest_prior=rest_prior[0], rest_prior_sd=rest_prior[1],
                         depth_prior_sd=float(depth_sd[0]) if np.size(depth_sd) else math.nan)
    return out


def _identifiability(pb, sol) -> Identifiability:
    """Verdicts on the fit on every experiment, from the Jacobian its standard errors came from, in the
    optimiser's coordinates (each parameter against its bounds' width; the per-tube unknowns take part,
    unnamed)."""
    x = np.asarray(sol.x, dtype=float)
    J = sol.jacobian
    width = np.asarray(pb.hi, float) - np.asarray(pb.lo, float)
    scales = np.where(np.isfinite(width) & (width > 0), width, np.maximum(np.abs(x), 1.0))
    names = [s.name for s in pb.specs] + [f"per-tube {i}" for i in range(x.size - len(pb.specs))]
    return assess(J, names, x, scales)


def _result(obs, base, free, excess, tasks, outs: dict) -> Identification:
    """Collect the full fit and the held-out predictions."""
    pb, sol, fitted = outs["all", ""][:3]
    _, unit = metric_unit(obs[0].metric)
    vals = pb.values(sol.x)
    se = se_values(pb, sol.x, sol.se)
    tubes = _tube_fits(obs, pb, sol, fitted)
    theta = {o.name: predict(o, fitted[o.tube]) for o in obs}
    train_err = {o.name: errors(o, theta[o.name]) for o in obs}
    held, by_tube = {}, {}
    for task in tasks[1:]:
        if task.kind == "experiment":
            held.update(outs[task.key, task.part].preds)
        elif task.part != "warm":            # a tube's fit: its only part, or its grid part against its warm one
            preds = _merge(outs[task.key, task.part], outs.get((task.key, "warm"))).preds
            by_tube[obs[task.test[0]].tube] = _rms([p / unit for p in preds.values()])
    names = list(tubes)
    shared = fitted[names[0]] if len(names) == 1 else with_values(base[names[0]], vals, excess)
    return Identification(
        metric=obs[0].metric, free=tuple(s.name for s in pb.specs), values=vals, se=se,
        tube_free=tuple(f for f in (REST, DEPTH) if f in free), tubes=tubes, model=shared,
        experiment_tubes={o.name: o.tube for o in obs}, train_rms=_rms([e / unit for e in train_err.values()]),
        train={k: _rms([e / unit]) for k, e in train_err.items()},
        heldout_rms=_rms([e / unit for e in held.values()]), heldout={k: _rms([e / unit]) for k, e in held.items()},
        heldout_by_tube=by_tube, solution=sol, lack_of_fit=_lack_of_fit(obs, pb, theta),
        new_tube=_new_tube_prior(pb, sol, tubes, base, free))


def _merge(grid: _FitOut, warm: _FitOut | None) -> _FitOut:
    """A tube's held-out fit from its grid and warm parts: the lower cost, the grid's on a tie (as one
    least-squares call from both starts keeps)."""
    return grid if warm is None or grid.sol.loss_cost <= warm.sol.loss_cost else warm


def _new_tube_prior(pb, sol, tubes: dict, base: dict, free, *, min_rest_sd: float = REST_SIGMA_MIN) -> NewTubePrior:
    """:class:`NewTubePrior` of the fit on every experiment: the shared parameters' covariance in the
    fit's coordinates (the Gauss–Newton correlations scaled to the reported standard errors, marginal
    over the per-tube unknowns); the rest angles' tube-to-tube scatter about the geometry files'
    (their mean square less their squared standard errors, at least ``min_rest_sd``; 0 when they were
    not fitted); the cut depths with each drawing's tolerance (0: as drawn, when not fitted)."""
    k = pb.k
    se = np.asarray(sol.se[:k], float)
    if sol.jacobian is not None and k:
        C = np.linalg.pinv(sol.jacobian.T @ sol.jacobian)[:k, :k]
        d = np.sqrt(np.clip(np.diag(C), 1e-300, None))
        cov = C / np.outer(d, d) * np.outer(se, se)
    else:
        cov = np.diag(se ** 2)
    rest_sd = 0.0
    if REST in free:
        d2, s2 = [], []
        for t, fit in tubes.items():
            geom_rest = base[t].rest_angles(next(o.geom for o in pb.obs if o.tube == t))
            d2.append((fit.rest_angles - geom_rest) ** 2)
            s2.append(np.nan_to_num(fit.rest_se) ** 2)
        rest_sd = math.sqrt(max(float(np.mean(np.concatenate(d2)) - np.mean(np.concatenate(s2))), min_rest_sd ** 2))
    return NewTubePrior(tuple(s.name for s in pb.specs), tuple(bool(s.log) for s in pb.specs),
                        np.asarray(sol.x[:k], float), 0.5 * (cov + cov.T), rest_sd,
                        None if DEPTH in free else 0.0, DEPTH_TOLERANCE)


def _lack_of_fit(obs, pb, theta: dict, *, tol: float = 0.15) -> dict:
    """Tube -> LackOfFit of the fit on every experiment (predicted ``theta`` by experiment), per notch
    (angles) or point coordinate (points); the parameters counted: the shared ones and the tube's."""
    _, unit = metric_unit(obs[0].metric)
    per_tube = {b.owner: 0 for b in pb.blocks}
    for b in pb.blocks:
        per_tube[b.owner] += b.size
    trials, labels = [], None
    for o in obs:
        pred = measure_registered(o, theta[o.name])
        S = o.time.size
        if o.metric == "points":
            labels = [f"point {i + 1}" for i in range(o.measured.shape[1]) for _ in "xy"]
        trials.append(Trial(o.name, o.tube, o.measured.reshape(S, -1), np.asarray(pred, float).reshape(S, -1),
                            o.pulled_tension))
    out = {}
    for t in dict.fromkeys(o.tube for o in obs):
        out.update(study_lack_of_fit([tr for tr in trials if tr.tube == t], n_params=pb.k + per_tube.get(t, 0),
                                     unit=METRICS[obs[0].metric], scale=1.0 / unit, tol=tol,
                                     response_labels=labels))
    return out
