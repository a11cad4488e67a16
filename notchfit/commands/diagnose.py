"""``notchfit diagnose``: what the simulation gets wrong, the cause, the extension, the gain."""

from __future__ import annotations

import sys
from pathlib import Path

NAME = "diagnose"
ORDER = 60
HELP = "name the physical cause of the friction model's discrepancies and measure the gain"
DESCRIPTION = """Diagnose a study against the paper's friction model (Sec. IV-B).

Calibrates the baseline (k_lin, k_mid, mu_d) on training experiments,
compares it with held-out experiments (cross-validation by experiment),
reports discrepancy signatures, fits every candidate extension
(proximal_friction, static_friction, joint_hysteresis, external_load,
stiffness_gradient, calibration_error), names the cause (or "none" /
"unexplained"), saves the extended model and the held-out gain.

Writes into --out: diagnosis.json (data-format.md), extended_model.toml
(read by `notchfit simulate --model`), diagnosis_*.png and their data.

Notch points come from each experiment's notch_points.csv, or from the
detections.csv files of a `notchfit detect` run given with --detections.

Examples:
  notchfit diagnose study/ --out results/
  notchfit diagnose study/ --out results/ --jobs 2 --detections detections/
  notchfit diagnose study/ --out results/ --causes proximal_friction,static_friction
"""


def add_arguments(parser) -> None:
    parser.add_argument("study", help="a study folder (or one experiment folder)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--force", action="store_true", help="replace existing diagnosis outputs")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--detections", help="folder of a `notchfit detect` run to take points from")
    parser.add_argument("--causes", help="comma-separated candidate causes to try (default: all)")
    parser.add_argument("--max-folds", type=int, default=6,
                        help="leave-one-experiment-out up to this many experiments, else k-fold")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")


def run(args) -> int:
    from ._common import InputError
    from ..diagnosis import CAUSES, diagnose_study
    from ..io import OutputRun, find_output, load_detected_points, read_study

    exps = read_study(args.study, missing_images="keep")
    if args.detections:
        found = find_output(args.detections, "detections.csv")
        if not found:
            raise InputError(f"{args.detections}: no detections.csv found")
        exps = [load_detected_points(e, found.get(e.name) or found.get("")) if
                (e.name in found or "" in found) else e for e in exps]
    missing = [e.name for e in exps if e.points is None]
    if missing:
        raise InputError(f"no notch points for {', '.join(missing)}: add notch_points.csv or "
                         "give --detections from `notchfit detect`")
    causes = tuple(c.strip() for c in args.causes.split(",")) if args.causes else CAUSES
    bad = [c for c in causes if c not in CAUSES]
    if bad:
        raise InputError(f"unknown cause(s) {', '.join(bad)}; known: {', '.join(CAUSES)}")
    if args.jobs < 1:
        raise InputError("--jobs must be at least 1")
    outputs = ["diagnosis.json", "extended_model.toml"]
    with OutputRun(args.out, outputs=outputs, force=args.force, name="diagnose") as run_:
        data = diagnose_study(exps, out_dir=run_.stage, jobs=args.jobs, causes=causes,
                              max_folds=args.max_folds, figures=not args.no_figures,
                              progress=lambda m: print(f"diagnose: {m}", file=sys.stderr))
    g = data["gain"]
    print(f"cause: {data['cause']}")
    print(f"held-out rms: baseline {g['baseline']:.3f} mm, extended {g['extended']:.3f} mm "
          f"({g['reduction_pct']:.1f}% lower)")
    print(f"wrote {Path(args.out) / 'diagnosis.json'}")
    return 0
