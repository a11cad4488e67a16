"""``notchfit diagnose``: what the simulation gets wrong, the cause, the extension, the gain."""

from __future__ import annotations

import sys
from pathlib import Path

from .. import io
from ..analysis.diagnosis import CAUSES, Diagnosis, choose_metric, diagnose
from ..figures.diagnosis import write_diagnosis_figures
from ..io import save_params
from ..progress import Steps
from ._common import (EXIT_ITEMS_FAILED, InputError, add_batch_options, add_points_option, check_out_dir,
                      check_points_dir, count_option, list_failures)
from ._points import MISSING_HINT, lookup_points, points_problem

NAME = "diagnose"
ORDER = 60
HELP = "name the physical cause of the friction model's discrepancies and measure the gain"
DESCRIPTION = """Diagnose a study against the friction model (Sec. IV-B).

Calibrates the baseline (k_lin, k_mid, mu_d; for a real tube the model
`notchfit identify` calibrates: E_lin, E_se, strain_lower, mu_d and each
tube's rest angles and cut depths) on training experiments, compares it with
held-out experiments (cross-validation by experiment), reports discrepancy
signatures, fits every candidate extension the study can reveal
(proximal_friction, static_friction, joint_hysteresis, external_load,
stiffness_gradient, calibration_error; the others are skipped with the
reason and the experiment that would reveal them), names the cause (or
"none" / "unexplained": where trials repeat, only with a significant lack of
fit beyond the trials' scatter), then tries a second cause with it (named
when it removes a further significant part of the held-out discrepancy),
saves the extended model and the held-out gain.

Writes into --out: diagnosis.json (docs/data-formats.md), extended_model.toml
(read by `notchfit simulate --model`), diagnosis_*.png and their data
(diagnosis_cause_<id>.png: one per named cause).

Notch points come from each experiment's own notch_points.csv, else from
detections.csv of the `notchfit detect` run given with --points DIR
(--detections is the old name), else from detections.csv in the --out
folder, else an experiment's own angles.csv (the log says which).
Experiments measured as joint angles are compared in degrees (--metric:
auto takes notch points when every experiment has them, else angles). The
protocol is [protocol] ramp_time_s of experiment.toml; where it is absent
the diagnosis estimates it (--assume-step: take a step instead).
The baseline is judged against a floor of the measurement noise plus each
fold's own prediction uncertainty (a fold that must extrapolate to the
heaviest trial is uncertain where its training trials do not reach);
--noise-floor-only judges it against the noise alone.
The (model x fold) calibrations run in parallel (--jobs, or a Dask cluster
with --scheduler); --seed seeds the noise floor's Monte Carlo draws.

Examples:
  notchfit diagnose study/ --out results/
  notchfit diagnose study/ --out results/ --jobs 2 --points detections/
  notchfit diagnose study/ --out results/ --causes proximal_friction,static_friction
  notchfit diagnose wrist_study/ --out results/ --metric angles --one-cause
  notchfit diagnose study/ --out results/ --scheduler tcp://10.0.0.5:8786
"""

#: The files every run writes (the figures besides, unless --no-figures).
OUTPUTS = ("diagnosis.json", "extended_model.toml")


def add_arguments(parser) -> None:
    parser.add_argument("study", help="a study folder (or one experiment folder)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--force", action="store_true", help="replace existing diagnosis outputs")
    add_points_option(parser, "--detections",
                      help="a detect run's output folder, for experiments without notch_points.csv "
                           "(looked for after them, before --out; --detections: the old name)")
    parser.add_argument("--causes", help="comma-separated candidate causes to try (default: all)")
    parser.add_argument("--max-folds", type=count_option(1), default=6,
                        help="leave-one-experiment-out up to this many experiments, else k-fold")
    parser.add_argument("--seed", type=count_option(0), default=0, help="seed of the noise floor's draws (default 0)")
    parser.add_argument("--metric", choices=("auto", "points", "angles"), default="auto",
                        help="compare notch points (mm) or joint angles (deg); auto: points when every "
                             "experiment has them, else angles")
    parser.add_argument("--one-cause", action="store_true", help="name at most one cause (no second-cause step)")
    parser.add_argument("--assume-step", action="store_true",
                        help="where experiment.toml gives no [protocol], assume a step instead of estimating it")
    parser.add_argument("--noise-floor-only", action="store_true",
                        help="judge the baseline against the measurement noise alone, without the folds' "
                             "prediction uncertainty")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    add_batch_options(parser)


def write_diagnosis(diag: Diagnosis, out_dir, *, figures: bool = True) -> dict:
    """Write ``diagnosis.json``, ``extended_model.toml`` and (``figures``) ``diagnosis_*.png`` into ``out_dir``.

    Returns
    -------
    dict
        The content of ``diagnosis.json``.
    """
    out = Path(out_dir)
    params, meta = diag.extension_model()
    model_path = save_params(params, out / "extended_model.toml", **meta)
    names = None
    if figures:
        names = [Path(p).name for p in write_diagnosis_figures(diag, out)]
    data = diag.to_dict(extended_model_file=Path(model_path).name, figures=names)
    io.write_json_atomic(data, out / "diagnosis.json")
    return data


def _experiments(args) -> tuple[list, dict]:
    """The study's experiments, each with notch points (its own, or detect's), and the sub-folders
    that are not valid experiments ``{name: reason}`` (listed; the run goes on without them).

    An experiment without usable notch points is an input error naming it and its points file.
    """
    scan = io.scan_study(args.study, missing_images="keep")
    lookup = lookup_points(scan.experiments, args, "diagnose")
    if lookup.problems:
        raise InputError("no notch points for " + "; ".join(f"{k}: {v}" for k, v in lookup.problems.items())
                         + f"; {MISSING_HINT}")
    exps = list(lookup.experiments)
    try:
        if choose_metric(exps, args.metric) == "angles":
            return exps, scan.problems
    except ValueError as exc:
        raise InputError(str(exc)) from None
    bad = {e.name: points_problem(e, lookup.sources[e.name][1], "the diagnosis") for e in exps}
    bad = {k: v for k, v in bad.items() if v is not None}
    if bad:
        raise InputError("; ".join(f"experiment {k}: {v}" for k, v in bad.items()))
    return exps, scan.problems


def run(args) -> int:
    causes = tuple(c.strip() for c in args.causes.split(",")) if args.causes else CAUSES
    bad = [c for c in causes if c not in CAUSES]
    if bad:
        raise InputError(f"unknown cause(s) {', '.join(bad)}; known: {', '.join(CAUSES)}")
    check_out_dir(args.out, args.study, outputs=OUTPUTS, force=args.force)
    check_points_dir(args.points)
    exps, unread = _experiments(args)
    with io.OutputRun(args.out, outputs=list(OUTPUTS), force=args.force, name="diagnose") as run_, \
            Steps("diagnose") as steps:
        diag = diagnose(exps, jobs=args.jobs, scheduler=args.scheduler, seed=args.seed,
                        causes=causes, max_folds=args.max_folds, metric=args.metric,
                        second_cause=not args.one_cause, estimate_protocol=not args.assume_step,
                        fold_band=not args.noise_floor_only, progress=steps)
        steps("writing diagnosis.json and the figures")
        write_diagnosis(diag, run_.stage, figures=not args.no_figures)
    print(diag.summary())
    print(f"protocol: {diag.protocol['text']}", file=sys.stderr)
    print(f"wrote {Path(args.out) / 'diagnosis.json'}")
    if unread:
        print(f"diagnosed {len(exps)} experiments; {len(unread)} sub-folder(s) of the study left out:")
        list_failures(unread, limit=len(unread))
        return EXIT_ITEMS_FAILED
    return 0
