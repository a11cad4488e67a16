"""``notchfit demo``: the main job on a built-in synthetic example."""

from __future__ import annotations

import numpy as np

NAME = "demo"
ORDER = 0
HELP = "run the pipeline on a built-in synthetic example"
DESCRIPTION = """Run notchfit on a built-in synthetic example.

Example:
  notchfit demo
"""


def add_arguments(parser) -> None:
    parser.add_argument("--geometry", default="default", help="geometry TOML (default: the paper's)")


def run(args) -> int:
    from ..geometry import load_geometry
    from ..notches import notch_points

    geom = load_geometry(args.geometry)
    j = np.arange(1, geom.n_joints + 1)
    theta = 0.10 - 0.003 * j  # a linear shape θ_j = a + b j (Sec. IV-A)
    pts = notch_points(theta, geom) * 1e3
    print(f"geometry {geom.name}: {geom.n_joints} joints, {geom.n_points} notch points")
    print(f"shape a=0.10 rad, b=-0.003 rad: tip corners at "
          f"({pts[28, 0]:.3f}, {pts[28, 1]:.3f}) mm and ({pts[29, 0]:.3f}, {pts[29, 1]:.3f}) mm")
    return 0
