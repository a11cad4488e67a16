"""``notchfit identify``: the model's parameters calibrated on a study, with held-out errors."""

from __future__ import annotations

import re
from pathlib import Path

from .. import io
from ..analysis.identify import identify, tube_labels
from ._common import (EXIT_ITEMS_FAILED, InputError, add_batch_options, add_points_option, check_out_dir,
                      check_points_dir, list_failures)
from ._points import MISSING_HINT, lookup_points

NAME = "identify"
ORDER = 55
HELP = "identify the model's parameters on a study (tubes of one stock share the material)"
DESCRIPTION = """Calibrate the friction model (Sec. IV-B; real tubes: springs from material and section,
capstan friction) on every experiment of a study, and measure how well it predicts experiments
it never saw. The experiments may use different geometry files (tubes): every tube shares the
fitted scalar parameters (tubes cut from one stock share the material); each real tube gets its
own rest angles.

Free parameters (--free, comma-separated; field names or model-file keys): by default the
material law's E_lin, E_se, strain_lower (or the seed tube's k_lin, k_mid), its tension-compression
asymmetry strain_ratio where a notch's section lets it act, mu_d, and for every real tube (section
backbone) each notch's rest angle (rest_angle, tied to the angles its trials measured at zero force,
with their standard error) and effective cut depth (slot_depth, tied to the drawing with the
geometry's slot_depth_tolerance_mm, default 15 um). Bounds and starts come from physics
(docs/models.md, "Identification"); the fit starts from the best of a grid of probes. --model
FILE gives the values of everything not fitted (and the starts); without it a real tube's
model gets the quasi-static damping time (1 ms).

Compares measured joint angles (angles.csv: errors in degrees) when every experiment has them,
else notch points (notch_points.csv or detect's detections.csv: errors in mm). Held out: each
experiment predicted by a model fitted without it (leave one experiment out) and, with several
tubes, each tube's experiments predicted by a model fitted on the other tubes, from its geometry.

Where trials repeat, it prints the trial-to-trial scatter and the lack of fit beyond it, per
notch and per force range, with its F test.

Writes into --out: model.toml (the identified model, read by `notchfit simulate --model` and
notchfit.io.load_params; with several tubes it holds the shared parameters, and
model_<tube>.toml each tube's model with its rest angles; [metadata.prediction]: what simulate
needs for the prediction bands of a new tube), identify.json (free parameters, values, standard
errors, metric, training and held-out errors, lack of fit) and identify_run.json.

Examples:
  notchfit identify wrists/ --out ident/ --jobs 2
  notchfit identify wrists/ --out ident/ --free E_lin,E_se,strain_lower,mu_d
  notchfit simulate new_wrist/ --out pred/ --model ident/model.toml
"""

#: The files every run writes (and model_<tube>.toml per tube of a study of several tubes).
OUTPUTS = ("model.toml", "identify.json", "identify_run.json")


def add_arguments(parser) -> None:
    parser.add_argument("study", type=Path, help="a study folder (or one experiment folder)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--free", default=None, metavar="NAME,...",
                        help="parameters to fit (default: by the tubes' physics, see above)")
    parser.add_argument("--model", type=Path, default=None,
                        help="model file with the values of everything not fitted, and the starts")
    add_points_option(parser, help="folder with detect's detections.csv for experiments without notch_points.csv "
                                   "(default: --out)")
    parser.add_argument("--starts", type=int, default=2, help="least-squares runs from the best probes (default 2)")
    parser.add_argument("--loss", default="linear", help="linear (default), soft_l1, huber, cauchy or arctan")
    parser.add_argument("--no-heldout", action="store_true",
                        help="skip the held-out refits (per experiment and per tube)")
    add_batch_options(parser)
    parser.add_argument("--force", action="store_true", help="replace existing outputs in --out")


def _tube_file(tube: str) -> str:
    return "model_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", tube) + ".toml"


def _model_metadata(result, data: dict) -> dict:
    """The ``[metadata]`` of model.toml: source, metric, free parameters, standard errors, errors."""
    meta = {"source": "notchfit identify", "metric": result.unit, "free": data["free"] + data["free_per_tube"],
            "se": data["se"],
            "train_rms": result.train_rms, "heldout_rms": result.heldout_rms, "tubes": list(result.tubes)}
    if data.get("prediction"):
        meta["prediction"] = data["prediction"]     # the prediction bands of `simulate --model`
    if len(meta["tubes"]) > 1:
        meta["note"] = ("shared parameters of every tube; each tube's rest angles and cut depths are in "
                        "its model_<tube>.toml")
    return meta


def write_identification(result, out_dir) -> dict:
    """Write model.toml, model_<tube>.toml (several tubes) and identify.json into ``out_dir``; returns the JSON."""
    out = Path(out_dir)
    data = result.as_dict()
    meta = _model_metadata(result, data)
    io.save_params(result.model, out / "model.toml", **meta)
    files = {}
    if len(result.tubes) > 1:
        for tube, fit in result.tubes.items():
            files[tube] = _tube_file(tube)
            io.save_params(fit.model, out / files[tube], **{**meta, "tube": tube, "note": "the model of one tube"})
    data["model_file"] = "model.toml"
    data["tube_model_files"] = files
    io.write_json_atomic(data, out / "identify.json")
    return data


def _experiments(args) -> tuple[list, dict]:
    """The study's experiments with measured data; the sub-folders and experiments left out ``{name: reason}``."""
    scan = io.scan_study(args.study, missing_images="keep")
    lookup = lookup_points(scan.experiments, args, "identify")
    exps = list(lookup.experiments)
    problems = {k: f"{v}; {MISSING_HINT}" for k, v in lookup.problems.items()}
    if not exps:
        raise InputError("nothing to identify: " + "; ".join(f"{k}: {v}" for k, v in
                                                             {**scan.problems, **problems}.items()))
    return exps, {**scan.problems, **problems}


def run(args) -> int:
    if args.starts < 1:
        raise InputError("--starts must be at least 1")
    check_out_dir(args.out, args.study, outputs=OUTPUTS, force=args.force)
    check_points_dir(args.points)
    free = None if args.free is None else [f for f in args.free.split(",") if f.strip()]
    model = io.load_params(args.model) if args.model is not None else None
    exps, left_out = _experiments(args)
    tubes = sorted(set(tube_labels([e.geometry for e in exps])))
    outputs = list(OUTPUTS) + ([_tube_file(t) for t in tubes] if len(tubes) > 1 else [])
    with io.OutputRun(args.out, outputs=outputs, force=args.force, name="identify") as run_:
        result = identify(exps, free=free, model=model, heldout=not args.no_heldout,
                          by_tube=not args.no_heldout, jobs=args.jobs,
                          scheduler=args.scheduler, n_starts=args.starts, loss=args.loss)
        data = write_identification(result, run_.stage)
        io.write_json_atomic(io.provenance("identify", args.study, experiments=[e.name for e in exps],
                                           failures=left_out, model_file=str(args.model) if args.model else None,
                                           free=data["free"] + data["free_per_tube"], starts=args.starts, loss=args.loss),
                             run_.path("identify_run.json"))
    _print_summary(result, data, args.out)
    if left_out:
        print(f"identified on {len(exps)} experiments; {len(left_out)} left out:")
        list_failures(left_out, limit=len(left_out))
        return EXIT_ITEMS_FAILED
    return 0


def _print_summary(result, data: dict, out) -> None:
    print(result.summary())
    print(f"wrote {Path(out) / 'model.toml'} and {Path(out) / 'identify.json'}")
