"""``notchfit simulate``: the friction simulator driven by measured tensions (Sec. IV-B)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .. import io
from ..analysis.estimation.bands import NewTubePrior, band_table, tube_band
from ..analysis.fitting.angles import DEFAULT_ANGLE_SIGMA
from ..analysis.comparison import angle_comparison_table, compare_angles, compare_simulation, comparison_table
from ..figures.friction import plot_fig18, plot_fig19
from ..physics.friction import FrictionParams, default_params, simulate, simulation_table
from ..progress import bar as progress_bar
from ..units import DEG
from ._common import EXIT_ITEMS_FAILED, add_batch_options, add_points_option, check_points_dir, list_failures
from ._points import MISSING_HINT, lookup_points
from ._resumable import add_resume_option, check_out, open_run, run_resumable

NAME = "simulate"
ORDER = 50
HELP = "simulate an experiment or a study from its measured tensions (friction model)"
DESCRIPTION = """Run the cable-friction simulator (Sec. IV-B) on the measured tension history of
each experiment: after each sample the tensions move to the next sample's values over
[protocol] ramp_time_s of experiment.toml (a step when it is absent or 0; the log says which)
and the manipulator comes to rest before that sample is taken. Parameters are the paper's values, or
those of a model file (--model: a TOML file written by notchfit.io.save_params, e.g. the
extended model that `notchfit diagnose`
saves), then any --param overrides (SI units: k_lin N m/rad, mu_d, b N m s/rad, ...).

Measured points, to compare with, come from the experiment's own notch_points.csv, else
from detections.csv of the detect run given with --points DIR, else from detections.csv in
the --out folder (the log says which, and names the experiments simulated without them).

Writes simulation.csv (sample, regime, a, b, theta_1..theta_n, base tensions, predicted
cable displacements) and, when the experiment has measured points, simulation_vs_measured.csv
(measured vs predicted shape parameters a, b of theta_j = a + b j and the notch-point error of
the prediction, Sec. IV-A); when it has measured joint angles (angles.csv),
simulation_vs_angles.csv (the angle error per sample and per joint, in degrees); with Figs. 18
(joint angles) and 19 (a and b vs tension, and the point error) as PNG and CSV; for a study,
into OUT/<experiment>/. With a model file from `notchfit identify`, also prediction_band.csv:
every notch angle's 95 % prediction interval for a tube the model has never seen (the shared
parameters' covariance plus the tube-to-tube scatter of rest angles and cut depths), and the
share of the measured angles inside it.

Each finished experiment is kept in OUT/.notchfit-resume-simulate/ as it completes, so an
interrupted or killed run is continued with --resume: only the experiments not yet
simulated, or whose data or options changed since, are simulated again.

Examples:
  notchfit simulate study/ --out out/
  notchfit simulate study/L045 --out out/ --param mu_d=0.25 --param k_mid=0.3
  notchfit simulate study/ --out ext/ --model out/extended_model.toml --jobs 2
  notchfit simulate study/ --out out/ --resume     (after an interrupted run)
"""

def add_arguments(parser) -> None:
    parser.add_argument("input", type=Path, help="experiment folder or study folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--model", type=Path, default=None, help="friction parameters TOML (save_params)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="override one parameter (repeatable), e.g. --param mu_d=0.25")
    parser.add_argument("--method", default="fast", help="solver: fast (default) or reference")
    add_points_option(parser, help="a detect run's output folder, for experiments without notch_points.csv "
                                   "(looked for after them, before --out)")
    parser.add_argument("--no-figures", action="store_true", help="skip Figs. 18-19")
    add_batch_options(parser)
    parser.add_argument("--force", action="store_true", help="replace existing outputs in --out "
                        "(and start again over an interrupted run)")
    add_resume_option(parser, "experiments")


def parse_params(model_file, overrides, base: FrictionParams | None = None):
    """FrictionParams from a model file (else ``base``, else the paper's) and ``NAME=VALUE`` overrides.

    Raises ValueError on a bad override.
    """
    params = io.load_params(model_file) if model_file is not None else (base or FrictionParams())
    fields = {f.name for f in dataclasses.fields(FrictionParams)}
    changes = {}
    for text in overrides:
        if "=" not in text:
            raise ValueError(f"--param {text!r}: expected NAME=VALUE")
        k, v = (s.strip() for s in text.split("=", 1))
        if k not in fields:
            raise ValueError(f"--param {k!r}: unknown parameter (known: {', '.join(sorted(fields))})")
        try:
            changes[k] = float(v)
        except ValueError:
            raise ValueError(f"--param {k}={v!r}: not a number") from None
    try:
        return dataclasses.replace(params, **changes) if changes else params
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--param: {exc}") from None


def simulate_one(item: dict) -> dict:
    """Simulate one experiment and compare with its points (a batch item; module level so that it pickles)."""
    res = simulate(item["time"], item["tension_left"], item["tension_right"], item["params"],
                   item["geometry"], method=item["method"], ramp_time=item["ramp_time"])
    out = {"result": res, "table": simulation_table(res, item["samples"])}
    if item.get("band") is not None:
        out.update(_band(item))
    if item.get("angles") is not None:
        comp = compare_angles(res, item["angles"], sigma=item.get("angle_sigma"), samples=item["samples"])
        out.update(angle_comparison=comp, angle_compare=angle_comparison_table(comp, res))
    if item["points"] is not None:
        try:
            comp = compare_simulation(res, item["points"], mirror=item["mirror"], sigma=item["sigma"],
                                      samples=item["samples"])
            out.update(comparison=comp, compare=comparison_table(comp, res))
        except (ValueError, np.linalg.LinAlgError) as exc:
            # the simulation stands; only the comparison with the measured points failed
            out["compare_error"] = f"{type(exc).__name__}: {exc}"
    return out


def _band(item: dict) -> dict:
    """The 95 % prediction band of every notch angle (the model file's ``[metadata.prediction]``), with the
    measured angles' coverage when the experiment has some."""
    g = item["geometry"]
    band = tube_band(item["params"], g, item["time"], item["tension_left"] if "left" in g.tendons else None,
                     item["tension_right"] if "right" in g.tendons else None,
                     NewTubePrior.from_metadata(item["band"]), noise_sd=item["band_noise"],
                     ramp_time=item["ramp_time"])
    table = band_table(band, item["samples"], item.get("angles"))
    out = {"band": table}
    if item.get("angles") is not None:
        out["band_coverage"] = band.coverage(item["angles"])
    return out


def simulation_figures(value: dict, out_dir: Path) -> list[Path]:
    """Figs. 18 (joint angles: prediction vs the measured ones or the linear fit of the points) and 19
    (a, b vs tension) of one experiment."""
    res = value["result"]
    if "comparison" in value:
        comp, rms = value["comparison"], value["compare"]["point_rms_mm"]
    elif "angle_comparison" in value:
        comp, rms = value["angle_comparison"], None
    else:
        return []
    return (plot_fig18(res, out_dir, measured_theta=comp.theta_meas, name="fig18_joint_angles")
            + plot_fig19(res, out_dir, measured_a=comp.a_meas, measured_b=comp.b_meas,
                         name="fig19_shape_parameters", point_rms_mm=rms))


def _experiment_params(exps, args) -> dict:
    """The model of each experiment: the model file, or the default for its geometry
    (:func:`notchfit.physics.friction.default_params`: the paper's for the seed tube), then the overrides."""
    return {e.name: parse_params(args.model, args.param, base=default_params(e.geometry)) for e in exps}


def _prediction_table(model_file):
    """``[metadata.prediction]`` of the model file (written by identify: the bands' covariance), or None."""
    if model_file is None:
        return None
    table = io.load_toml(model_file, what="friction parameter file").data.get("metadata", {}).get("prediction")
    if table is not None:
        try:
            NewTubePrior.from_metadata(table)
        except ValueError as exc:
            raise ValueError(f"{model_file}: [metadata.prediction]: {exc}") from None
    return table


def _params_record(params: dict) -> dict:
    """The run record's ``params``: one table when every experiment shares it, else one per experiment."""
    first = next(iter(params.values()), None)
    if all(p == first for p in params.values()):
        return {"params": first.to_dict() if first is not None else None}
    return {"params": None, "params_by_experiment": {n: p.to_dict() for n, p in params.items()}}


def _measured_points(exps, args) -> dict:
    """``{name: points}`` of the experiments with measured points or angles (:func:`lookup_points`;
    an experiment measured as angles has None points and is compared through its ``angles``); those
    with neither are named with the fix."""
    lookup = lookup_points(exps, args, "simulate")
    if lookup.problems:
        names = ", ".join(lookup.problems)
        print(f"simulate: no measured points or angles for {names}: simulated without a comparison with the "
              f"measured shapes (no simulation_vs_measured.csv, no Figs. 18-19); {MISSING_HINT}")
    return {e.name: e.points for e in lookup.experiments}


def _items(exps, params: dict, args) -> list[dict]:
    """One batch item per experiment: the measured tensions (clipped at 0 N), the points and angles, if any,
    and the model file's prediction table (bands), if it has one."""
    pts = _measured_points(exps, args)
    band = _prediction_table(args.model)
    return [{"time": e.time, "tension_left": e.tension_left,
             "tension_right": e.tension_right, "params": params[e.name], "geometry": e.geometry,
             "method": args.method, "samples": [int(s) for s in e.sample_ids], "points": pts.get(e.name),
             "mirror": e.mirror, "sigma": e.point_sigma, "ramp_time": e.ramp_time or 0.0,
             "angles": e.angles, "angle_sigma": e.angle_sigma, "band": band,
             "band_noise": (e.angle_sigma or DEFAULT_ANGLE_SIGMA) if e.angles is not None else 0.0} for e in exps]


def run(args) -> int:
    if args.method not in ("fast", "reference"):
        raise ValueError(f"--method must be fast or reference, got {args.method!r}")
    check_out(args, "simulate_run.json")
    check_points_dir(args.points)
    scan = io.scan_study(args.input)
    exps, study = scan.experiments, scan.study
    params = _experiment_params(exps, args)
    no_protocol = [e.name for e in exps if e.ramp_time is None]
    if no_protocol:
        print(f"  no [protocol] in experiment.toml of {', '.join(no_protocol)}: assumed a step to each "
              "sample's tensions, then rest (ramp_time_s = 0)")
    for e in exps:
        if e.n_clipped:
            print(f"  {e.name}: {e.n_clipped} tension reading(s) slightly below 0 N (load-cell offset, within "
                  f"3 sigma_T) taken as 0 N")
    items = _items(exps, params, args)
    names = [e.name for e in exps]
    outputs = ["simulate_run.json"] + [str(io.experiment_output_dir("", n, study) / "simulation.csv")
                                       for n in names]
    with open_run(args, outputs, "experiments") as run_:
        res = run_resumable(run_, simulate_one, items, names, option_keys=("params", "method"), args=args)
        failed = {**scan.problems, **{r.key: r.error for r in res.failures}}
        _write_outputs(exps, res, run_, study, failed, figures=not args.no_figures)
        io.write_json_atomic(io.provenance("simulate", args.input,
                                           **_params_record(params), **_angle_record(exps, res),
                                           clipped_tensions={e.name: e.n_clipped for e in exps if e.n_clipped},
                                           model_file=str(args.model) if args.model else None,
                                           param_overrides=list(args.param),
                                           method=args.method, experiments=names, failures=failed),
                             run_.path("simulate_run.json"))
    _print_summary(exps, res, failed, args.out, len(scan.problems))
    return EXIT_ITEMS_FAILED if failed else 0


def _write_outputs(exps, res, run_, study, failed: dict, *, figures: bool) -> None:
    """simulation.csv, simulation_vs_measured.csv / simulation_vs_angles.csv and (``figures``)
    Figs. 18-19 of each simulated experiment, with a progress bar; what fails is recorded in ``failed``."""
    with progress_bar(len(exps), "simulate: tables and figures" if figures else None, unit="experiments") as bar:
        for e, r in zip(exps, res.items):
            bar.update(1)
            if not r.ok:
                continue
            sub = io.experiment_output_dir("", e.name, study)
            io.write_table_atomic(r.value["table"], run_.path(sub / "simulation.csv"))
            if "compare_error" in r.value:
                failed[f"{e.name} comparison with the points"] = r.value["compare_error"]
            if "angle_compare" in r.value:
                io.write_table_atomic(r.value["angle_compare"], run_.path(sub / "simulation_vs_angles.csv"))
            if "band" in r.value:
                io.write_table_atomic(r.value["band"], run_.path(sub / "prediction_band.csv"))
            if "compare" in r.value:
                io.write_table_atomic(r.value["compare"], run_.path(sub / "simulation_vs_measured.csv"))
            if ("compare" in r.value or "angle_compare" in r.value) and figures:
                try:
                    simulation_figures(r.value, run_.path(sub / "x").parent)
                except Exception as exc:  # noqa: BLE001 - a figure must not lose the simulation
                    failed[f"{e.name} figures"] = f"{type(exc).__name__}: {exc}"


def _angle_record(exps, res) -> dict:
    """The run record's angle errors [deg]: rms over every measured angle, and per joint, per experiment."""
    comps = {e.name: r.value["angle_comparison"] for e, r in zip(exps, res.items)
             if r.ok and "angle_comparison" in r.value}
    if not comps:
        return {}
    cover = {e.name: r.value["band_coverage"] for e, r in zip(exps, res.items) if r.ok and "band_coverage" in r.value}
    return {"angle_rms_deg": {k: c.rms / DEG for k, c in comps.items()},
            "angle_rms_deg_by_joint": {k: [float(v) for v in c.joint_rms / DEG] for k, c in comps.items()},
            **({"band_coverage": cover} if cover else {})}


def _print_summary(exps, res, failed, out, n_unread: int = 0) -> None:
    for e, r in zip(exps, res.items):
        if r.ok and "angle_comparison" in r.value:
            c = r.value["angle_comparison"]
            per = ", ".join(f"{v:.2f}" for v in c.joint_rms / DEG)
            print(f"  {e.name:10s} prediction rms {c.rms / DEG:.3f} deg over {int(np.isfinite(c.theta_meas).sum())} "
                  f"measured angles (per joint: {per})")
        if r.ok and "band_coverage" in r.value:
            print(f"  {e.name:10s} 95 % prediction band covers {100 * r.value['band_coverage']:.1f} % of the measured "
                  "angles (prediction_band.csv)")
        if r.ok and "compare" in r.value:
            c = r.value["compare"]
            v = c["point_rms_mm"].to_numpy(float)
            v = v[np.isfinite(v)]
            txt = f"{np.sqrt(np.mean(v ** 2)):.3f} mm" if v.size else "n/a (no measured points)"
            print(f"  {e.name:10s} prediction rms {txt} over {v.size} of {len(c)} samples")
        elif r.ok and "angle_comparison" not in r.value:
            print(f"  {e.name:10s} simulated ({len(r.value['table'])} samples; no measured points or angles)")
    print(f"simulate: {res.n_ok} of {len(exps) + n_unread} experiments in {res.seconds:.1f} s; outputs in {out}")
    list_failures(failed, limit=len(failed))
