"""``notchfit report``: one self-contained HTML report of an output folder."""

from __future__ import annotations

from pathlib import Path

from .. import io
from ..report import build_report, summary_lines
from ._common import InputError, check_out_dir

NAME = "report"
ORDER = 80
HELP = "build one self-contained HTML report (report.html) from an output folder"
DESCRIPTION = """Build DIR/report.html from what the other commands wrote into DIR: calibration
quality, detection statistics and overlays, shape-fit errors (Figs. 12-15), simulation vs
measurement (Figs. 18-19) and the diagnosis (diagnosis.json and its figures). Figures are
embedded as PNG data: the file opens from disk in any browser, with no server and no other
file. A section whose input is absent says "not available" and why.

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
                  "the --out folder of fit/simulate/diagnose")
    if not args.dir.is_dir():
        raise InputError(f"{args.dir}: output folder not found")
    with io.OutputRun(args.dir, outputs=["report.html"], force=args.force, name="report"):
        path = build_report(args.dir, study=args.study, title=args.title, force=args.force)
    for line in summary_lines(args.dir):
        print(line)
    print(f"report: {path}")
    return 0
