"""Synthetic studies with a known, hidden physical effect (``notchfit synth``).

A *recipe* (TOML, ``datasets/recipes/*.toml``, read by :mod:`notchfit.studies.recipes`) describes a study the way a
lab would run it: several paper-like bend/unbend tests (Sec. IV, Fig. 11:
one cable ramped up to a peak of 20–32 N and back down, a constant
counter-tension on the other, samples taken at rest about 5 s apart, both
pull directions), and it describes the "truth" that produced the data:

* base friction-model parameters ``k_lin``, ``k_mid``, ``μ_d`` drawn
  uniformly in recipe ranges and *away from* the paper's values (by at least
  ``min_rel_offset``), so an analysis must calibrate them;
* hidden physical effects — none, one, or several at once (``cause = [...]``) —
  each a cause id of docs/data-formats.md, with its size drawn from a recipe
  range (optionally with a random sign):

  ======================  =============================================
  cause                   truth-model field(s)
  ======================  =============================================
  ``proximal_friction``   ``proximal_beta`` (capstan band before the base)
  ``static_friction``     ``mu_s_excess`` = ``μ_s - μ_d`` (paper: 0.01;
                          ``static_excess`` is read as an alias)
  ``joint_hysteresis``    ``hysteresis_torque`` [N m] (the play; with
                          ``hysteresis_onset``, ``hysteresis_yield`` the
                          candidate family), or laws no candidate has:
                          ``bouc_wen_torque`` [N m] + ``bouc_wen_stiffness``
                          [N m/rad] (smooth elastic-plastic loops),
                          ``superelastic_gap`` [N m] (flag-shaped loops of a
                          two-branch superelastic plateau);
                          :mod:`notchfit.physics._hysteresis_kernels`
  ``external_load``       ``tip_force_x``, ``tip_force_z`` [N]
  ``stiffness_gradient``  ``stiffness_gradient`` g
  ``calibration_error``   ``scale_error``, ``k_radial`` (a plane-frame
                          point warp, :func:`notchfit.vision.warp.apply_point_warp`,
                          one camera for the whole study), and/or
                          ``plane_tilt_x``, ``plane_tilt_y`` [rad] (the bending
                          plane tilted against the calibrated one, seen in
                          perspective from ``distance_mm``,
                          :func:`notchfit.vision.warp.apply_camera_plane_warp`)
  ======================  =============================================

* what is measured (``observe``): notch points, joint angles (``angles.csv``,
  real-tubes data) or both;
* measurement noise (Gaussian, seeded): notch-point coordinates ``σ_p``,
  joint angles ``σ_θ`` (``[noise] angle_deg``), load-cell tensions ``σ_T``;
  the actuator displacement is quantised to its step; optionally a fraction
  of occluded points;
* a random proper rigid plane transform per experiment (shared by its
  samples, docs/geometry.md "Measured points live in a plane frame"),
  optionally mirrored.

The joint angles are produced by :func:`notchfit.physics.friction.simulate` with
``method="reference"`` driven by the *true* tensions, while the files hold
the noisy measured ones. The true tensions lie on the file's 0.1 mN grid
(:data:`notchfit.studies.recipes.TENSION_RESOLUTION`), so that with noise-free load
cells ``samples.csv`` holds them exactly. The reference integrator is a different solver from
the ``fast`` one that analyses fit with, so a diagnosis cannot win by
reproducing the generator's discretisation. A frictionless truth (``μ_d =
μ_s = 0``, no band, hysteresis or tip load) has an independent formulation:
each sample's rest state is the quasi-static equilibrium
:func:`notchfit.physics.statics.equilibrium` of the same springs, rest angles and
moment arms, solved directly (``truth.json`` says ``"truth_solver"``).

Real tubes (``datasets/recipes/wrist_*.toml``): the recipe's ``geometry``
names a geometry file, ``[fixed]`` holds the model's laws and parameters
(strings for ``spring_law``/``friction_law``, lists for per-joint values), and
``[base]`` may draw the material parameters ``E_lin``, ``E_se``,
``strain_lower`` (away from notchfit's defaults). A tendon the geometry
lacks must have ``counter_N = 0``; its ``samples.csv`` columns are written
empty (docs/data-formats.md, real tubes).

:func:`synthesize` returns the study in memory with its ground truth;
:func:`write_study` writes it per docs/data-formats.md, plus ``truth.json`` at
the study root, a file no analysis command reads. :func:`synthetic_points`
makes measured-like points from given joint angles (tests, benchmarks,
figure demonstrations).
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import io
from ..physics import statics
from ..batch import run_batch
from ..physics.cables import pulled_side
from ..analysis.fitting.results import as_transform
from ..physics.friction import FrictionParams, cable_displacement, simulate, stepwise_regimes
from ..physics.geometry import Geometry
from ..io import datasets_dir, load_geometry
from ..physics.notches import notch_points, to_plane
from .recipes import (_BASE_FIELDS, _MODEL_EFFECTS, _PAPER_MU_S_EXCESS, _REFERENCE_VALUES, CAUSES, EFFECT_FIELDS,
                      ProtocolSpec, Recipe, _protocol, bend_unbend_protocol, list_recipes, load_recipe,
                      recipe_from_dict)
from ..units import DEG, MM
from ..vision.warp import apply_camera_plane_warp

__all__ = [
    "CAUSES",
    "EFFECT_FIELDS",
    "ProtocolSpec",
    "Recipe",
    "SynthExperiment",
    "SynthStudy",
    "bend_unbend_protocol",
    "generate_study",
    "render_study_images",
    "list_recipes",
    "load_recipe",
    "recipe_from_dict",
    "synthesize",
    "synthetic_points",
    "write_study",
]

# ----------------------------------------------------------------------------- study
@dataclass(frozen=True)
class SynthExperiment:
    """One synthetic experiment with its ground truth.

    Attributes
    ----------
    name, description : str
    pull : str
    counter_N, peak_N : float
    samples : DataFrame
        ``samples.csv`` as written (measured, noisy tensions; displacements).
    points : ndarray (S, m, 2) [m] or None
        Measured plane-frame points (warp, noise, occlusions applied); None
        when the recipe observes joint angles only.
    true_points : ndarray (S, m, 2) [m]
        The true plane-frame points (no warp, no noise).
    theta : ndarray (S, n) [rad]
        True joint angles.
    tension_left, tension_right : ndarray (S,) [N]
        True load-cell tensions (the simulator's input).
    plane : dict
        ``tx, ty`` [m], ``phi`` [rad], ``mirror``.
    regime : ndarray (S,) of str
    angles : ndarray (S, n) [rad] or None
        Measured joint angles (true angles plus Gaussian noise ``angle_sigma_deg``),
        when the recipe observes them.
    geometry : str
        The experiment's geometry as the recipe names it (its own, or the recipe's).
    """

    name: str
    description: str
    pull: str
    counter_N: float
    peak_N: float
    samples: pd.DataFrame
    points: np.ndarray
    true_points: np.ndarray
    theta: np.ndarray
    tension_left: np.ndarray
    tension_right: np.ndarray
    plane: dict
    regime: np.ndarray
    angles: np.ndarray | None = None
    geometry: str = "default"


@dataclass(frozen=True)
class SynthStudy:
    """A synthetic study and its ground truth (:func:`synthesize`)."""

    recipe: Recipe
    seed: int
    geometry: Geometry
    params: object                 # notchfit.physics.friction.FrictionParams of the truth
    effect: dict                   # the drawn effect fields (empty for "none")
    warp: dict | None              # calibration_error: scale_error, k_radial, center [m], radius [m],
                                   # tilt (2,) [rad], distance [m]
    experiments: tuple
    truth_solver: str = "reference"  # "reference", "fast" or "statics" (frictionless truth)

    @property
    def cause(self):
        """The hidden cause (a tuple of causes for several at once)."""
        return self.recipe.cause

    def truth(self) -> dict:
        """The ground truth as written to ``truth.json`` (file units)."""
        params = self.params.to_dict() if isinstance(self.params, FrictionParams) else dict(self.params)
        warp = None
        if self.warp is not None:
            warp = {"scale_error": self.warp["scale_error"], "k_radial": self.warp["k_radial"],
                    "center_mm": [c / MM for c in self.warp["center"]],
                    "radius_mm": self.warp["radius"] / MM}
            if any(self.warp["tilt"]):
                warp.update(tilt_rad=list(self.warp["tilt"]), distance_mm=self.warp["distance"] / MM)
        exps = {}
        for e in self.experiments:
            exps[e.name] = {
                "pull": e.pull, "counter_N": e.counter_N, "peak_N": e.peak_N,
                "plane": {"tx_mm": e.plane["tx"] / MM, "ty_mm": e.plane["ty"] / MM,
                          "phi_rad": e.plane["phi"], "mirror": e.plane["mirror"]},
                "sample": e.samples["sample"].tolist(),
                "true_tension_left_N": e.tension_left.tolist(),
                "true_tension_right_N": e.tension_right.tolist(),
                "regime": [str(r) for r in e.regime],
                "theta_rad": e.theta.tolist(),
                **({"geometry": e.geometry} if e.geometry != self.recipe.geometry else {}),
            }
        return {
            "note": "ground truth of a synthetic study; no analysis command reads this file",
            "recipe": self.recipe.name, "seed": self.seed,
            "cause": self.cause if isinstance(self.cause, str) else list(self.cause),
            "effect": dict(self.effect), "params": params, "geometry": self.geometry.name,
            "noise": {"point_mm": self.recipe.point_sigma_mm, "tension_N": self.recipe.tension_sigma_N,
                      "displacement_step_mm": self.recipe.displacement_step_mm,
                      "missing_points": self.recipe.missing_points,
                      **({"angle_deg": self.recipe.angle_sigma_deg} if self.recipe.observe != "points" else {})},
            "observe": self.recipe.observe,
            "warp": warp, "experiments": exps,
            # how the true angles were computed, written when not the default reference solver
            **({"truth_solver": self.truth_solver} if self.truth_solver != "reference" else {}),
        }


def _draw_away(rng, lo, hi, ref, min_rel, max_tries=1000):
    """Uniform in [lo, hi], redrawn until at least ``min_rel`` (relative) from ``ref``."""
    if hi - lo <= 0:
        return float(lo)
    for _ in range(max_tries):
        v = float(rng.uniform(lo, hi))
        if abs(v - ref) >= min_rel * abs(ref):
            return v
    raise ValueError(f"range [{lo}, {hi}] leaves no room {min_rel:.0%} away from the paper's {ref}")


def _draw_truth(recipe: Recipe, rng):
    """The truth's FrictionParams and the drawn effect fields (recipe ranges, ``rng``)."""
    values = {}
    for k in _BASE_FIELDS:
        if k in recipe.base:
            lo, hi = recipe.base[k]
            values[k] = _draw_away(rng, lo, hi, _REFERENCE_VALUES[k], recipe.min_rel_offset)
    values.update({k: _fixed_value(v) for k, v in recipe.fixed.items()})
    effect = {}
    for k in recipe.effect_order:
        lo, hi = recipe.effect[k]
        v = float(rng.uniform(lo, hi)) if hi > lo else lo
        if k in recipe.random_sign and rng.random() < 0.5:
            v = -v
        effect[k] = v
    params_kw = dict(values)
    if "mu_s_excess" in effect:
        mu_d = params_kw.get("mu_d", FrictionParams().mu_d)
        params_kw["mu_s"] = mu_d + effect["mu_s_excess"]
    elif "mu_s" not in params_kw:
        mu_d = params_kw.get("mu_d", FrictionParams().mu_d)
        params_kw["mu_s"] = mu_d + _PAPER_MU_S_EXCESS
    for k in _MODEL_EFFECTS:
        if k in effect:
            params_kw[k] = effect[k]
    try:
        params = FrictionParams(**params_kw)
    except TypeError as exc:
        raise ValueError(f"recipe {recipe.name!r}: {exc}") from None
    return params, effect


def _geometry_source(name: str) -> str:
    """A recipe's ``geometry``: ``"default"``, a path, or the name of a shipped geometry
    file (``"wrist_asymmetric"`` for ``datasets/geometry/wrist_asymmetric.toml``)."""
    if name == "default" or Path(name).is_file():
        return name
    shipped = datasets_dir() / "geometry" / f"{name}.toml"
    return str(shipped) if shipped.is_file() else name


def _fixed_value(v):
    """A ``[fixed]`` value: a law's name, a per-joint list, or a number."""
    if isinstance(v, str):
        return v
    if isinstance(v, list):
        return tuple(float(x) for x in v)
    return float(v)


def _frictionless(params: FrictionParams) -> bool:
    """No friction, band, hysteresis or tip load: the rest states are quasi-static equilibria."""
    return (params.mu_d == 0.0 and params.mu_s == 0.0 and params.proximal_beta == 0.0
            and params.hysteresis_torque == 0.0 and params.tip_force_x == 0.0 and params.tip_force_z == 0.0
            and params.bouc_wen_torque == 0.0 and params.superelastic_gap == 0.0)


@dataclass(frozen=True)
class _StaticsTruth:
    """Rest states from the quasi-static equilibrium (the fields ``_observe`` reads)."""

    theta: np.ndarray
    displacement_left: np.ndarray
    displacement_right: np.ndarray
    regime: np.ndarray


def statics_truth(time, tension_left, tension_right, params: FrictionParams, geom: Geometry, *,
                  tol: float = 1e-13) -> _StaticsTruth:
    """Frictionless rest state of every sample by :func:`notchfit.physics.statics.equilibrium`.

    ``τ_j(θ_j - θ0_j) = a_R,j T_R - a_L,j T_L`` with the springs of
    :meth:`FrictionParams.joint_spring` (the same law the friction simulator
    uses at μ = 0, solved by Newton's method instead of by time stepping), each
    sample started from the previous rest state.

    Parameters
    ----------
    time : array_like (S,) [s]
    tension_left, tension_right : array_like (S,) [N]
    params : FrictionParams
    geom : Geometry
    tol : float
        Residual torque tolerance [N m].
    """
    tl, tr = np.asarray(tension_left, float), np.asarray(tension_right, float)
    geom = params.tube_geometry(geom)
    model = statics.QuasiStaticModel(geom, spring=params.joint_spring(geom))
    th = geom.rest_angles
    out = []
    for a, b in zip(tr, tl):
        eq = statics.equilibrium(model, tensions=(a, b), theta0=th, tol=tol)
        if not eq.success:
            raise ValueError(f"statics truth: {eq.message}")
        th = eq.theta
        out.append(th)
    theta = np.array(out)
    dl, dr = cable_displacement(theta, tl, tr, geom)
    return _StaticsTruth(theta, dl, dr, stepwise_regimes(tl, tr, theta.sum(axis=1) * pulled_side(tl, tr)))


@dataclass(frozen=True)
class _Plan:
    """One experiment as drawn before its truth is simulated: its recipe entry, its own random stream (the
    noise is drawn from it after the simulation), the peak tension [N], the protocol's times [s] and cable
    tensions (S,) [N], the plane transform (``tx``, ``ty`` [m], ``phi`` [rad], ``mirror``), and its geometry
    with the recipe's name for it."""

    spec: ProtocolSpec
    rng: np.random.Generator
    peak: float
    time: np.ndarray
    tension_left: np.ndarray
    tension_right: np.ndarray
    plane: dict
    geom: Geometry
    source: str


def _simulate_one(args):
    """Truth simulation of one experiment (module level: runs in worker processes)."""
    time, tl, tr, params, geom, method, ramp = args
    if method == "statics":
        return statics_truth(time, tl, tr, params, geom)
    return simulate(time, tl if "left" in geom.tendons else None, tr if "right" in geom.tendons else None,
                    params, geom, method=method, ramp_time=ramp)


def synthesize(recipe: Recipe | str | Path, seed: int | None = None, *, jobs: int = 1,
               method: str = "reference") -> SynthStudy:
    """Generate a synthetic study in memory.

    Parameters
    ----------
    recipe : Recipe, name or path
    seed : int, optional
        Overrides the recipe's seed. Every draw comes from
        ``numpy.random.default_rng`` seeded from it: the truth parameters and
        the warp from two child streams, each experiment from its own child
        (so an experiment's data do not change when others are added).
    jobs : int
        Processes for the truth simulations.
    method : str
        Solver of :func:`notchfit.physics.friction.simulate` for the truth
        (``"reference"``; ``"fast"`` only for quick tests of this module).

    Returns
    -------
    SynthStudy
    """
    if not isinstance(recipe, Recipe):
        recipe = load_recipe(recipe)
    seed = recipe.seed if seed is None else int(seed)
    geom = load_geometry(_geometry_source(recipe.geometry))
    sources = {spec.name: spec.geometry or recipe.geometry for spec in recipe.experiments}
    geoms = {src: geom if src == recipe.geometry else load_geometry(_geometry_source(src))
             for src in dict.fromkeys(sources.values())}
    ss = np.random.SeedSequence(seed)
    kids = ss.spawn(2 + len(recipe.experiments))
    rng_params, rng_warp = np.random.default_rng(kids[0]), np.random.default_rng(kids[1])
    params, effect = _draw_truth(recipe, rng_params)

    warp = None
    if "calibration_error" in recipe.causes:
        (cx0, cx1), (cy0, cy1) = recipe.warp_center_mm
        warp = {"scale_error": effect.get("scale_error", 0.0), "k_radial": effect.get("k_radial", 0.0),
                "center": (float(rng_warp.uniform(cx0, cx1)) * MM, float(rng_warp.uniform(cy0, cy1)) * MM),
                "radius": recipe.warp_radius_mm * MM,
                "tilt": (effect.get("plane_tilt_x", 0.0), effect.get("plane_tilt_y", 0.0)),
                "distance": recipe.warp_distance_mm * MM}

    # draw each experiment's protocol, plane and noise streams, then simulate (maybe in parallel)
    plans = []
    for spec, kid in zip(recipe.experiments, kids[2:]):
        rng = np.random.default_rng(kid)
        lo, hi = spec.peak_N if isinstance(spec.peak_N, tuple) else (spec.peak_N, spec.peak_N)
        peak = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        time, tl, tr = _protocol(spec, peak)
        plane = {"tx": float(rng.uniform(*recipe.plane_tx_mm)) * MM,
                 "ty": float(rng.uniform(*recipe.plane_ty_mm)) * MM,
                 "phi": math.radians(float(rng.uniform(*recipe.plane_phi_deg))),
                 "mirror": bool(recipe.mirror)}
        plans.append(_Plan(spec, rng, peak, np.asarray(time, float), np.asarray(tl, float), np.asarray(tr, float),
                           plane, geoms[sources[spec.name]], sources[spec.name]))
    truth_method = "statics" if _frictionless(params) else method
    for spec in recipe.experiments:
        other = "left" if spec.pull == "right" else "right"
        if spec.counter_N != 0 and other not in geoms[sources[spec.name]].tendons:
            raise ValueError(f"recipe {recipe.name!r}: experiment {spec.name}: the geometry has only the "
                             f"{spec.pull} tendon, so counter_N must be 0")
    items = [(p.time, p.tension_left, p.tension_right, params, p.geom, truth_method, recipe.ramp_time_s)
             for p in plans]
    if jobs > 1 and len(items) > 1:
        res = run_batch(_simulate_one, items, jobs=jobs, keys=[p.spec.name for p in plans],
                        desc="truth simulation")
        res.raise_on_failure()
        results = res.values()
    else:
        results = [_simulate_one(it) for it in items]

    exps = [_observe(recipe, plan, sim, warp) for plan, sim in zip(plans, results)]
    return SynthStudy(recipe=recipe, seed=seed, geometry=geom, params=params, effect=effect, warp=warp,
                      experiments=tuple(exps), truth_solver=truth_method)


def _observe(recipe, plan: _Plan, sim, warp) -> SynthExperiment:
    """Measurement model of the experiment ``plan`` whose truth is ``sim``: points in the plane frame
    (+``warp``, noise, occlusion) and/or joint angles (+noise), noisy tensions."""
    spec, rng, peak, time, plane, geom = plan.spec, plan.rng, plan.peak, plan.time, plan.plane, plan.geom
    tl, tr = plan.tension_left, plan.tension_right
    theta = np.asarray(sim.theta, dtype=float)
    true_pts = to_plane(notch_points(theta, geom), plane["tx"], plane["ty"], plane["phi"],
                        plane["mirror"])
    S = len(time)
    pts = None
    if recipe.observe != "angles":
        pts = true_pts
        if warp is not None:
            pts = apply_camera_plane_warp(pts, warp["scale_error"], warp["k_radial"], warp["center"],
                                          tilt=warp["tilt"], radius=warp["radius"], distance=warp["distance"])
        pts = pts + rng.normal(0.0, recipe.point_sigma_mm * MM, pts.shape)
        if recipe.missing_points > 0:
            gone = rng.random(pts.shape[:2]) < recipe.missing_points
            pts = pts.copy()
            pts[gone] = np.nan
    meas_l = np.maximum(tl + rng.normal(0.0, recipe.tension_sigma_N, S), 0.0)
    meas_r = np.maximum(tr + rng.normal(0.0, recipe.tension_sigma_N, S), 0.0)

    def disp(d):
        d = np.asarray(d, dtype=float) / MM
        step = recipe.displacement_step_mm
        return np.round(d / step) * step if step > 0 else d

    for side, meas, d in (("left", meas_l, "displacement_left"), ("right", meas_r, "displacement_right")):
        if side not in geom.tendons:       # a tendon the geometry lacks: empty columns
            meas[:] = np.nan
            sim = dataclasses.replace(sim, **{d: np.full(S, np.nan)}) if dataclasses.is_dataclass(sim) else sim
    samples = pd.DataFrame({
        "sample": np.arange(1, S + 1, dtype=np.int64),
        "time_s": time,
        "tension_left_N": np.round(meas_l, 4),
        "tension_right_N": np.round(meas_r, 4),
        "displacement_left_mm": np.round(disp(sim.displacement_left), 6),
        "displacement_right_mm": np.round(disp(sim.displacement_right), 6),
    })
    other = "right" if spec.pull == "left" else "left"
    desc = (f"{spec.pull} cable ramped {spec.counter_N:g} -> {peak:.1f} -> {spec.counter_N:g} N "
            f"in {spec.n_up}+{spec.n_down} steps, {spec.counter_N:g} N on the {other} cable "
            f"(synthetic, recipe {recipe.name})")
    angles = None
    if recipe.observe != "points":
        angles = theta + rng.normal(0.0, recipe.angle_sigma_deg * DEG, theta.shape)
    return SynthExperiment(name=spec.name, description=desc, pull=spec.pull, counter_N=spec.counter_N,
                           peak_N=peak, samples=samples, points=pts, true_points=true_pts, theta=theta,
                           tension_left=tl, tension_right=tr, plane=plane,
                           regime=np.asarray(getattr(sim, "regime", np.full(S, ""))), angles=angles,
                           geometry=plan.source)


def write_study(study: SynthStudy, out_dir, *, force: bool = False, images: bool | None = None,
                jobs: int = 1) -> Path:
    """Write a synthetic study: ``OUT/<experiment>/`` per docs/data-formats.md and ``OUT/truth.json``.

    The whole study is written into a staging folder and moved into place at
    the end (:class:`notchfit.io.OutputRun`); an existing study is replaced
    only with ``force``.

    Parameters
    ----------
    images : bool, optional
        Render one image per sample of the true shape (:func:`render_study_images`,
        one camera for the study, ``OUT/calibration/camera.yml``); default: the recipe's
        ``[images] render``. The experiments then hold images and no ``notch_points.csv``:
        their points are what ``notchfit detect`` finds. Not available with a
        ``calibration_error`` study (its warp acts on points, not on the camera).
    """
    out = Path(out_dir)
    images = study.recipe.images if images is None else images
    if images and study.warp is not None:
        raise ValueError("calibration_error with rendered images is not supported: the warp is applied to "
                         "the notch points, and a rendered study's points come from its images through a "
                         "correct camera file; generate this study without --images")
    names = [e.name for e in study.experiments] + ["truth.json"]
    if images:
        names.append("calibration")
    geometry_files = _study_geometry_files(study)
    if geometry_files:
        names.append(GEOMETRY_DIR)
    with io.OutputRun(out, outputs=names, force=force, name="synth", whole_dirs=True) as run:
        calib_rel = None
        if images:
            calib_rel = _render_images(study, run, jobs=jobs)
        for source, rel in geometry_files.items():
            shutil.copyfile(source, run.path(rel))
        r = study.recipe
        for e in study.experiments:
            samples = e.samples
            if images:
                samples = samples.assign(image=[f"images/{s:04d}.png" for s in samples["sample"]])
            # with images the points are what `detect` finds: no notch_points.csv, and no stated
            # point uncertainty (the fits estimate it; detections.csv carries sigma_mm per point)
            io.write_experiment(run.path(e.name), name=e.name, samples=samples,
                                points=None if images else e.points, angles=e.angles,
                                angle_sigma=r.angle_sigma_deg * DEG if (e.angles is not None
                                                                         and r.angle_sigma_deg > 0) else None,
                                mirror=e.plane["mirror"], description=e.description,
                                geometry=("default" if e.geometry == "default"
                                          else f"../{geometry_files[_geometry_source(e.geometry)]}"),
                                calibration=calib_rel, point_sigma=r.point_sigma_mm * MM if
                                (r.point_sigma_mm > 0 and not images) else None,
                                tension_sigma=r.tension_sigma_N if r.tension_sigma_N > 0 else None,
                                protocol={"ramp_time_s": r.ramp_time_s} if r.record_protocol else None,
                                force=True)
        io.write_json_atomic(study.truth(), run.path("truth.json"))
    return out


#: The study's folder of geometry files (``synth`` copies every geometry an experiment names into it).
GEOMETRY_DIR = "geometry"


def _study_geometry_files(study: SynthStudy) -> dict[str, str]:
    """``{geometry source: path in the study}`` of every experiment's geometry other than the default.

    Each file is copied into the study's :data:`GEOMETRY_DIR` and the experiments name it relative to
    their own folder (``../geometry/wrist_asymmetric.toml``), so a study can be moved or shared.
    """
    out: dict[str, str] = {}
    for e in study.experiments:
        if e.geometry == "default":
            continue
        source = _geometry_source(e.geometry)
        if source not in out:
            stem, k = Path(source).stem, 1
            while f"{GEOMETRY_DIR}/{stem}.toml" in out.values():
                k += 1
                stem = f"{Path(source).stem}_{k}"
            out[source] = f"{GEOMETRY_DIR}/{stem}.toml"
    return out


def _render_images(study: SynthStudy, run, *, jobs: int = 1) -> str:
    """Render every sample's image; returns the calibration path relative to an experiment folder."""
    return render_study_images(study, run.path("calibration"), experiment_dir=lambda name: run.path(name),
                               jobs=jobs, **study.recipe.image_options)


def render_study_images(study, calib_dir, *, experiment_dir, jobs: int = 1, mm_per_px: float = 0.03,
                        seed: int | None = None, **render_kw) -> str:
    """Render one image per sample of a synthetic study (for ``notchfit synth``).

    One camera serves the whole study (its plane frame is the study's plane
    frame): :func:`notchfit.vision.render.camera_for_shapes` over every sample's true
    shape and plane transform. (Here, above the file I/O, not in the renderer:
    vision sits below I/O and writes nothing.) Writes ``calib_dir/camera.yml`` and
    ``experiment_dir(name)/images/NNNN.png`` per sample.

    Parameters
    ----------
    study : notchfit.studies.synth.SynthStudy
    calib_dir : path
    experiment_dir : callable name -> path
    jobs : int
        Worker processes.
    mm_per_px : float
    seed : int, optional
        Noise seed (default: the study's seed).
    **render_kw : passed to :func:`notchfit.vision.render.render_manipulator` (blur_sigma, noise, ...).

    Returns
    -------
    str
        The camera file's path relative to an experiment folder
        (``../calibration/camera.yml`` for the synth layout).
    """
    from ..vision.render import camera_for_shapes, pivot_closure_angles  # slow optional dependency: cv2

    geom = study.geometry
    thetas, planes, keys = [], [], []
    for e in study.experiments:
        pl = (e.plane["tx"], e.plane["ty"], e.plane["phi"], e.plane["mirror"])
        for s, th in zip(e.samples["sample"], e.theta):
            thetas.append(th)
            planes.append(pl)
            keys.append((e.name, int(s)))
    closure = pivot_closure_angles(geom)
    clip = np.clip(np.asarray(thetas, float), -closure, closure)
    cam, _ = camera_for_shapes(clip, geom, mm_per_px=mm_per_px, planes=planes)
    calib_dir = Path(calib_dir)
    calib_dir.mkdir(parents=True, exist_ok=True)
    io.write_camera(cam, calib_dir / "camera.yml")
    base = int(study.seed if seed is None else seed)
    items = []
    for k, ((name, s), th, pl) in enumerate(zip(keys, clip, planes)):
        out = Path(experiment_dir(name)) / "images" / f"{s:04d}.png"
        items.append((th, geom, cam, pl, [base, k], out, render_kw))
    res = run_batch(_render_one, items, keys=[f"{n}/{s}" for n, s in keys], jobs=jobs, desc="render",
                    unit="images")
    if res.failures:
        raise ValueError("rendering failed: " + "; ".join(f"{r.key}: {r.error}" for r in res.failures[:5]))
    return Path(os.path.relpath(calib_dir / "camera.yml", Path(experiment_dir(keys[0][0])))).as_posix() \
        if keys else str(calib_dir / "camera.yml")


def _render_one(item):
    """Render and write one sample's image (a batch item)."""
    from ..vision.render import render_manipulator

    th, geom, cam, pl, seed, out, kw = item
    r = render_manipulator(th, geom, cam, plane=pl, rng=np.random.default_rng(seed), **kw)
    io.write_image(out, r.image, png="noisy")       # lossless; noise-dominated: Huffman only
    return str(out)


def generate_study(recipe, out_dir, *, seed: int | None = None, force: bool = False, jobs: int = 1,
                   images: bool | None = None, method: str = "reference") -> SynthStudy:
    """:func:`synthesize` then :func:`write_study`; returns the study with its ground truth."""
    if not isinstance(recipe, Recipe):
        recipe = load_recipe(recipe)
    if (recipe.images if images is None else images) and "calibration_error" in recipe.causes:
        raise ValueError("calibration_error with rendered images is not supported: the warp acts on the "
                         "notch points; generate this study without --images")
    study = synthesize(recipe, seed, jobs=jobs, method=method)
    write_study(study, out_dir, force=force, images=images, jobs=jobs)
    return study


def synthetic_points(theta, geom: Geometry, transform=(0.0, 0.0, 0.0), *, mirror: bool = False,
                     noise: float = 0.0, rng=None):
    """Measured-like notch points from known joint angles (ground truth returned).

    Parameters
    ----------
    theta : array_like, shape (S, n) or (n,)
        True joint angles [rad].
    geom : Geometry
    transform : (tx, ty, phi) or PlaneTransform
        True plane transform [m, m, rad].
    mirror : bool
    noise : float
        Standard deviation of the isotropic Gaussian point noise per
        coordinate [m].
    rng : numpy.random.Generator
        Required when ``noise > 0``.

    Returns
    -------
    points : ndarray, shape (S, m, 2)
        Noisy plane-frame points [m].
    truth : dict
        ``theta`` (S, n), ``points`` (noise-free, (S, m, 2)), ``transform``
        (tx, ty, phi), ``mirror``, ``noise``.
    """
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    T = as_transform(transform, mirror)
    clean = T.to_plane(notch_points(th, geom))
    if noise < 0 or not math.isfinite(noise):
        raise ValueError(f"noise must be a finite standard deviation >= 0 [m], got {noise!r}")
    if noise > 0:
        if rng is None:
            raise ValueError("synthetic_points needs rng (numpy.random.Generator) when noise > 0")
        pts = clean + rng.normal(0.0, noise, clean.shape)
    else:
        pts = clean.copy()
    return pts, {"theta": th, "points": clean, "transform": (T.tx, T.ty, T.phi),
                 "mirror": T.mirror, "noise": float(noise)}
