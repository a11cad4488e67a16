"""`notchfit diagnose` options: --points (with --detections as its old name), --jobs, --scheduler, --seed."""
from pathlib import Path

from notchfit.cli import build_parser


def _args(*extra):
    return build_parser().parse_args(["diagnose", "study", "--out", "res", *extra])


def test_points_option_and_its_alias():
    assert _args("--points", "det").points == Path("det")
    assert _args("--detections", "det").points == Path("det")
    assert _args().points is None          # then detections are looked for in --out


def test_parallel_and_seed_options():
    a = _args("--jobs", "2", "--scheduler", "tcp://127.0.0.1:8786", "--seed", "4")
    assert (a.jobs, a.scheduler, a.seed) == (2, "tcp://127.0.0.1:8786", 4)
    a = _args()
    assert (a.jobs, a.scheduler, a.seed) == (1, None, 0)
