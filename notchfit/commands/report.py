"""``notchfit report``: one HTML report of an output folder that reads at a glance."""

from __future__ import annotations

from pathlib import Path

from .. import io
from ..progress import bar as progress_bar
from ..report import SECTIONS, build_report, summary_lines
from ._common import InputError, check_out_dir

NAME = "report"
ORDER = 80
HELP = "build one HTML report (report.html) that reads at a glance from an output folder"
DESCRIPTION = """Build DIR/report.html from what the other commands wrote into DIR: first the
question and the answer (what was measured, the cause, the gain, what was assumed) and the
units and signs used throughout, then the study, the camera and the detected corners,
shape-fit errors (Figs. 12-15), simulation vs measurement with its parameters (Figs. 18-19)
and the diagnosis with the parameters of the calibrated baseline and of the extended model.
Its figures are drawn for the page and embedded (the file opens alone in any browser); the
per-experiment figures and the raw files are linked relative to DIR (keep the folder
together). A section whose input is absent says "not available" and why.

The study folder is found from the provenance files (fit_run.json, simulate_run.json) in
DIR, or given with --study.

Examples:
  notchfit report out/
  notchfit report out/ --study study/ --force
"""


def add_arguments(parser) -> None:
    parser.add_argument("dir", type=Path, help="output folder of fit/simulate/diagnose/detect")
    parser.add_argument("--study", type=Path, default=None, help="the study (or experiment) folder")
    parser.add_argument("--title", default=None, help="report title")
    parser.add_argument("--force", action="store_true", help="replace an existing report.html")


def run(args) -> int:
    # DIR is an output folder: never a study or experiment (the report would land in the raw data),
    # and written under the folder's lock like every other command's outputs
    check_out_dir(args.dir, args.study, option="", hint=f"run `notchfit report OUT --study {args.dir}` on "
                  "the --out folder of fit/simulate/diagnose", outputs=["report.html"], force=args.force)
    if not args.dir.is_dir():
        raise InputError(f"{args.dir}: output folder not found")
    with io.OutputRun(args.dir, outputs=["report.html"], force=args.force, name="report"), \
            progress_bar(len(SECTIONS), "report", unit="sections") as bar:
        path = build_report(args.dir, study=args.study, title=args.title, force=args.force,
                            progress=lambda _: bar.update(1))
    for line in summary_lines(args.dir):
        print(line)
    print(f"report: {path}")
    return 0
