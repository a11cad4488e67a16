"""``notchfit fit``: least-squares shape fits of measured notch points (Sec. IV-A)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from .. import io
from ..figures.fitting import experiment_figures, fig12_sample_index
from ..analysis.fitting import StudyFit, angle_fits_table, failed_fits, fit_angles, fit_experiment, fits_table, jointwise_table, pointwise_table
from ..analysis.estimation.observations import tube_labels
from ..analysis.lack_of_fit import shape_fit_lack_of_fit
from ..progress import bar as progress_bar
from ..physics.shapes import get_model
from ..units import MM
from ._common import (EXIT_ITEMS_FAILED, InputError, add_batch_options, add_points_option, check_points_dir,
                      list_failures)
from ._points import MISSING_HINT, lookup_points, points_problem
from ._resumable import add_resume_option, check_out, open_run, run_resumable

NAME = "fit"
ORDER = 40
HELP = "fit shape models (cc, linear, ...) to the notch points or measured angles of an experiment or a study"
DESCRIPTION = """Fit shape models to every sample of an experiment (or of every experiment of a
study): the plane transform of each experiment is estimated once for all its samples, then
each sample is fitted with each model (Sec. IV-A, Figs. 12-15). Points come from the
experiment's own notch_points.csv, else from detections.csv of the detect run given with
--points DIR, else from detections.csv in the --out folder (the log says which).

Writes fits.csv (one row per sample and model: sample,model,a,b,...,base_x_mm,base_y_mm,
base_phi_rad,rms_mm,max_mm,n_points,...), pointwise.csv (sample,model,point,err_mm) and the
figures of Figs. 12-15; for a study, into OUT/<experiment>/. An experiment with measured joint
angles (angles.csv) and no points is fitted in angle space (theta = B params, no plane
transform): angle_fits.csv (sample,model,a,b,...,rms_deg,max_deg,n_angles,...) and
jointwise.csv (sample,model,joint,err_deg). Experiments run in parallel
(--jobs, or a Dask cluster with --scheduler); one that fails is listed and the others finish
(exit code 1).

Each finished experiment is kept in OUT/.notchfit-resume-fit/ as it completes, so an
interrupted or killed run is continued with --resume: only the experiments not yet fitted,
or whose data or options changed since, are fitted again.

Models: cc (constant curvature), linear (a + b j), quadratic, pw<k> (piecewise constant on
k segments), free (every joint), free_smooth[=lambda].

Examples:
  notchfit fit study/ --out out/
  notchfit fit study/L045 --models cc,linear,quadratic --out out_L045/
  notchfit fit study/ --out out/ --jobs 2
  notchfit fit study/ --out out/ --scheduler tcp://10.0.0.5:8786
  notchfit fit study/ --out out/ --resume     (after an interrupted run)
"""

def add_arguments(parser) -> None:
    parser.add_argument("input", type=Path, help="experiment folder or study folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--models", default="cc,linear", help="comma-separated shape models (default cc,linear)")
    add_points_option(parser, help="a detect run's output folder, for experiments without notch_points.csv "
                                   "(looked for after them, before --out)")
    parser.add_argument("--sigma-mm", type=float, default=None,
                        help="point uncertainty [mm] (default: [uncertainty] point_mm, else estimated)")
    parser.add_argument("--loss", default="linear", help="linear, soft_l1, huber, cauchy or arctan")
    parser.add_argument("--no-figures", action="store_true", help="skip the Figs. 12-15 PNGs")
    add_batch_options(parser)
    parser.add_argument("--force", action="store_true", help="replace existing fits in --out "
                        "(and start again over an interrupted run)")
    add_resume_option(parser, "experiments")


def fit_one(item: dict) -> dict:
    """Fit one experiment (a batch item; module level so that it pickles): its points, else its angles."""
    if item.get("angles") is not None:
        res = fit_angles(item["angles"], item["models"], sigma=item["sigma"], samples=item["samples"])
        return {"result": res, "angle_fits": angle_fits_table(res), "jointwise": jointwise_table(res)}
    res = fit_experiment(item["points"], item["geometry"], item["models"], mirror=item["mirror"],
                         sigma=item["sigma"], loss=item["loss"], samples=item["samples"])
    return {"result": res, "fits": fits_table(res), "pointwise": pointwise_table(res)}


def fit_figures(result, out_dir: Path, name: str, exp=None) -> list[Path]:
    """Figs. 12-15 of one experiment (:func:`notchfit.figures.fitting.experiment_figures`).

    With the experiment given, Fig. 15 is drawn against the tension difference
    ``T_left - T_right`` [N], and Fig. 12 on the sample's own image when the
    experiment has images and a camera file.
    """
    kw = {}
    if exp is not None:
        kw = {"x": exp.tension_left - exp.tension_right, "xlabel": "T_left − T_right [N]"}
        kw.update(_read_overlay_image(result, exp))
    return list(experiment_figures(result, out_dir, title=name, **kw))


def _read_overlay_image(result, exp) -> dict:
    """The image and plane-to-pixel mapping of Fig. 12's sample, as in the paper (empty when not available)."""
    if not exp.has_images or exp.calibration_path is None:
        return {}
    try:
        s = fig12_sample_index(result)
        path = exp.image_paths[s]
        if path is None:
            return {}
        camera = io.read_camera(exp.calibration_path)
        return {"sample": result.samples[s], "image": io.load_image(path), "to_pixel": camera.plane_to_pixel}
    except (FileNotFoundError, ValueError, KeyError, IndexError):
        return {}        # the plane-frame overlay is drawn instead


def _model_names(text: str) -> tuple:
    """The ``--models`` list (at least one name)."""
    models = tuple(m.strip() for m in text.split(",") if m.strip())
    if not models:
        raise InputError("--models needs at least one model")
    return models


def _check_models(models, n_joints: int) -> None:
    """Each ``--models`` name must be in the shape-model registry."""
    for m in models:
        try:
            get_model(m, n_joints)
        except ValueError as exc:
            raise InputError(f"--models: {exc}") from None


def _fittable(args, models) -> tuple[list, dict, bool]:
    """The experiments to fit, ``{name: reason}`` for those that cannot be, and whether it is a study."""
    scan = io.scan_study(args.input)
    _check_models(models, scan.experiments[0].geometry.n_joints)
    lookup = lookup_points(scan.experiments, args, "fit")
    problems = {**scan.problems, **{k: f"{v}; {MISSING_HINT}" for k, v in lookup.problems.items()}}
    what = f"fitting --models {','.join(models)}"
    keep = []
    for e in lookup.experiments:
        if e.points is None:            # measured joint angles: fitted in angle space
            keep.append(e)
            continue
        why = points_problem(e, lookup.sources[e.name][1], what)
        if why is None:
            keep.append(e)
        else:
            problems[e.name] = why
    if not keep:
        raise InputError("nothing to fit: " + "; ".join(f"{k}: {v}" for k, v in problems.items()))
    return keep, problems, scan.study


def run(args) -> int:
    models = _model_names(args.models)
    check_out(args, "fit_run.json")
    check_points_dir(args.points)
    exps, problems, study = _fittable(args, models)
    items = [_item(e, models, args) for e in exps]
    names = [e.name for e in exps]
    outputs = ["fit_run.json"] + [str(io.experiment_output_dir("", e.name, study) / f) for e in exps
                                  for f in _FILES[e.points is None]]
    with open_run(args, outputs, "experiments") as run_:
        res = run_resumable(run_, fit_one, items, names, option_keys=("models", "loss"), args=args)
        failed = {r.key: r.error for r in res.failures}
        failed.update(problems)
        bad_samples = _write_outputs(exps, res, run_, study, failed, figures=not args.no_figures)
        lof = _lack_of_fit(exps, res, models)
        io.write_json_atomic(io.provenance("fit", args.input, models=list(models), experiments=names,
                                           failures=failed, failed_samples=bad_samples,
                                           lack_of_fit={m: {t: v.as_dict() for t, v in d.items()}
                                                        for m, d in lof.items()}),
                             run_.path("fit_run.json"))
    _print_summary(res, len(exps) + len(problems), failed, bad_samples, args.out, lof)
    return EXIT_ITEMS_FAILED if (failed or bad_samples) else 0


def _write_outputs(exps, res, run_, study, failed: dict, *, figures: bool) -> list[str]:
    """fits.csv, pointwise.csv and (``figures``) Figs. 12-15 of each fitted experiment, with a
    progress bar; a figure that fails is recorded in ``failed``. Returns the failed samples."""
    bad_samples = []
    with progress_bar(len(exps), "fit: tables and figures" if figures else None, unit="experiments") as bar:
        for e, r in zip(exps, res.items):
            bar.update(1)
            if not r.ok:
                continue
            sub = io.experiment_output_dir("", e.name, study)
            if "angle_fits" in r.value:
                _write_angle_fits(r.value, run_, sub, e.name, bad_samples)
                continue
            io.write_table_atomic(r.value["fits"], run_.path(sub / "fits.csv"))
            io.write_table_atomic(r.value["pointwise"], run_.path(sub / "pointwise.csv"))
            for row in failed_fits(r.value["fits"]).itertuples(index=False):
                bad_samples.append(f"{e.name} sample {row.sample} ({row.model}): {getattr(row, 'message', '')}")
            if figures:
                try:
                    fit_figures(r.value["result"], run_.path(sub / "x").parent, e.name, e)
                except Exception as exc:  # noqa: BLE001 - a figure must not lose the fits
                    failed[f"{e.name} figures"] = f"{type(exc).__name__}: {exc}"
    return bad_samples


#: Files written per experiment: from notch points, from measured angles.
_FILES = {False: ("fits.csv", "pointwise.csv"), True: ("angle_fits.csv", "jointwise.csv")}


def _item(e, models, args) -> dict:
    """The batch item of one experiment: its points (σ from --sigma-mm or the experiment), else its angles."""
    base = {"geometry": e.geometry, "models": models, "samples": tuple(int(s) for s in e.sample_ids)}
    if e.points is None:
        return {**base, "angles": e.angles, "sigma": e.angle_sigma}
    sigma = args.sigma_mm * MM if args.sigma_mm is not None else e.point_sigma
    if sigma is None and e.point_sigmas is not None:     # reviewed points (notchfit review): σ per point
        sigma = e.point_sigmas
    return {**base, "points": e.points, "mirror": e.mirror, "sigma": sigma, "loss": args.loss}


def _write_angle_fits(value, run_, sub, name, bad_samples) -> None:
    """angle_fits.csv and jointwise.csv of an experiment fitted in angle space; failed samples listed."""
    io.write_table_atomic(value["angle_fits"], run_.path(sub / "angle_fits.csv"))
    io.write_table_atomic(value["jointwise"], run_.path(sub / "jointwise.csv"))
    for row in failed_fits(value["angle_fits"]).itertuples(index=False):
        bad_samples.append(f"{name} sample {row.sample} ({row.model}): {getattr(row, 'message', '')}")


def _lack_of_fit(exps, res, models) -> dict:
    """Model -> tube -> LackOfFit of the fitted experiments (:func:`shape_fit_lack_of_fit`)."""
    ok = [(e, r.value["result"]) for e, r in zip(exps, res.items) if r.ok]
    tubes = tube_labels([e.geometry for e, _ in ok])
    return shape_fit_lack_of_fit([(e.name, t, e.tension_left, e.tension_right, v) for (e, v), t in zip(ok, tubes)],
                                 models)


def _print_summary(res, n_total, failed, bad_samples, out, lof=None):
    def rows(key):
        frames = [r.value[key] for r in res.items if r.ok and key in r.value]
        return pd.concat(frames, ignore_index=True) if frames else None

    study = StudyFit(rows("fits"), rows("angle_fits"), sum(r.ok for r in res.items), n_total, res.seconds, lof)
    print(f"{study.summary()}; outputs in {out}")
    list_failures(failed, limit=len(failed))
    for s in bad_samples[:20]:
        print(f"  FAILED {s}")
    if len(bad_samples) > 20:
        print(f"  ... and {len(bad_samples) - 20} more failed samples")
