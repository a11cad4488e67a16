"""``notchfit review``: look at every detection of a detect run and correct it in the browser."""

from __future__ import annotations

import errno
import signal
from pathlib import Path

from .. import io
from ..review.server import make_server
from ..review.session import ExperimentReview, ReviewSession
from ._common import InputError, add_points_option, check_points_dir, list_failures

NAME = "review"
ORDER = 35
HELP = "look at every detected corner in the browser and correct it (review.csv beside detections.csv)"
DESCRIPTION = """Start a local web page (http://127.0.0.1:PORT/, this machine only) over a detect run:
a strip of every sample with its count of ok / ambiguous / missing corners, one photograph at a
time at full resolution (zoom and pan), the numbered corners coloured by status, the live
free-theta fit of the sample with the residual of every corner, and the angles by hand (the two
cut faces of each notch and their angle; writes angles.csv). Drag a corner to move it, click to
place the selected missing corner, delete it, mark it occluded, accept an ambiguous one; undo.

Corrections are data: every change is written at once to review.csv beside the experiment's
detections.csv (the detector's file is never changed); fit, simulate, identify and diagnose
then use the reviewed points and say so. A corner placed by hand has the uncertainty of
--manual-sigma-px image pixels (its size on the plane, in mm, is written in review.csv).

Give the study (or experiment) and --points DIR (the --out folder of `notchfit detect`), or
just that detect folder (it names its study in detect_run.json). Ctrl-C stops the server.

Examples:
  notchfit review study/ --points out/
  notchfit review out/                       # the study named in out/detect_run.json
  notchfit review study/L045 --points out_L045/ --port 8800
  notchfit review notchfit-demo/results      # the demo's detections
"""

#: The port unless --port says otherwise (0: any free port).
DEFAULT_PORT = 8765


def add_arguments(parser) -> None:
    parser.add_argument("input", type=Path, help="study or experiment folder, or the --out folder of a detect run")
    add_points_option(parser, help="the --out folder of the `notchfit detect` run to review")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"port on 127.0.0.1 (default {DEFAULT_PORT}; 0 = any free port)")
    parser.add_argument("--manual-sigma-px", type=float, default=1.0, metavar="PX",
                        help="uncertainty of a corner placed by hand, in image pixels (default 1)")


def study_and_points(path, points=None) -> tuple[Path, Path]:
    """The study and the detect run to review: ``path`` and ``points`` as given, or, without ``points``,
    ``path`` as the detect run and the study its ``detect_run.json`` names."""
    if points is not None:
        return Path(path), check_points_dir(points)
    record = Path(path) / "detect_run.json"
    if record.is_file():
        study = Path(io.read_json(record).get("input") or "")
        if not study.is_dir():
            raise InputError(f"{record}: the study it names ({study}) is not a folder: give the study and "
                             f"--points {path}")
        return study, check_points_dir(path)
    raise InputError(f"{path}: give --points DIR (the --out folder of `notchfit detect`) or the detect "
                     "folder itself")


def load_session(study, points, *, manual_sigma_px: float = 1.0) -> tuple[ReviewSession, dict]:
    """The review session of every experiment of ``study`` with detections in ``points``, and the
    ``{name: reason}`` of those that cannot be reviewed."""
    scan = io.scan_study(study, missing_images="keep")
    failed = dict(scan.problems)
    found = io.find_output(points, "detections.csv")
    reviews = []
    for e in scan.experiments:
        det = found.get(e.name) or (found.get("") if len(scan.experiments) == 1 else None)
        if det is None:
            failed[e.name] = f"no detections.csv for it in {points}"
            continue
        try:
            reviews.append(ExperimentReview.load(e, det))
        except (ValueError, OSError) as exc:
            failed[e.name] = str(exc)
    if not reviews:
        raise InputError("nothing to review: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    return ReviewSession(reviews, manual_sigma_px=manual_sigma_px), failed


def run(args) -> int:
    if not args.manual_sigma_px > 0:
        raise InputError(f"--manual-sigma-px must be positive, got {args.manual_sigma_px}")
    if not 0 <= args.port <= 65535:
        raise InputError(f"--port must be in 0..65535, got {args.port}")
    study, points = study_and_points(args.input, args.points)
    session, failed = load_session(study, points, manual_sigma_px=args.manual_sigma_px)
    try:
        server = make_server(session, args.port)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise InputError(f"--port {args.port}: in use (another review?): choose another port, or 0") from None
        raise
    n = sum(r.exp.n_samples for r in session.experiments)
    print(f"review: {len(session.experiments)} experiment(s), {n} samples; corrections go to review.csv "
          "beside each detections.csv")
    list_failures(failed, limit=len(failed))
    print(f"review: open {server.url}  (this machine only; Ctrl-C stops)", flush=True)
    try:
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt as exc:
        print("\nreview: stopped; every change was saved when it was made")
        return 128 + getattr(exc, "signum", signal.SIGINT)
    finally:
        server.server_close()
    return 0
