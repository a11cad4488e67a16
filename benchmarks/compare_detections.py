"""Whether two checkouts detect the same: points, sigma and statuses to the last bit.

A speed change to the detector must not change what it reports. Each checkout runs
``detect_notches`` in a fresh interpreter (``PYTHONPATH`` = that checkout) on seeded
1920x1200 renders of the seed tube (random bends, mirror flags and angles in the image)
and on the physically based gallery in ``tests/data/pbr``, each image with its camera and
without one; the outputs (points, pixel points, sigma, statuses, image status, message,
scale, base side) are compared exactly. Make a read-only checkout of the old version with
``git worktree add --detach /tmp/before main``.

Usage::

    python benchmarks/compare_detections.py BEFORE_DIR AFTER_DIR [--seed-images 20] [--seed 7]
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

_DUMP = """
import json, pickle, sys
from pathlib import Path
import numpy as np
from notchfit.io import load_geometry, load_image
from notchfit.physics.geometry import default_geometry
from notchfit.vision.camera import CameraModel
from notchfit.vision.detection import detect_notches, mirror_without_camera
from notchfit.vision.render import place_in_view, render_manipulator
from notchfit.vision.render.pbr import PbrTruth

root, n_seed, seed, path = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
out = {}

def both(key, image, camera, geom, mirror):
    for cal in (True, False):
        m = mirror if cal else mirror_without_camera(camera, image.shape[:2], mirror)
        d = detect_notches(image, camera if cal else None, geom, mirror=m)
        out[key + (cal,)] = (np.asarray(d.points).tobytes(), np.asarray(d.points_px).tobytes(),
                             np.asarray(d.sigma).tobytes(), tuple(d.status), d.image_status, d.message,
                             repr(d.scale_mm_per_px), d.base_side)

geom = default_geometry()
cam = CameraModel.synthetic(1920, 1200, mm_per_px=0.03)
rng = np.random.default_rng(seed)
n = 0
while n < n_seed:
    th = rng.uniform(-0.12, 0.12, geom.n_joints)
    mirror = bool(rng.integers(2))
    plane, fits = place_in_view(th, geom, cam, phi=rng.uniform(0, 2 * np.pi), mirror=mirror)
    if fits:
        both(("seed", n), render_manipulator(th, geom, cam, plane=plane, rng=rng).image, cam, geom, mirror)
        n += 1
gallery = root / "tests" / "data" / "pbr"
for p in sorted(gallery.glob("*.json")):
    rec = json.loads(p.read_text())
    truth = PbrTruth.from_dict(rec)
    both(("pbr", p.stem), load_image(gallery / rec["image"]), truth.camera, load_geometry(root / rec["geometry"]),
         truth.pose.plane[3])
with open(path, "wb") as fh:
    pickle.dump(out, fh)
"""


def outputs(checkout: Path, n_seed: int, seed: int) -> dict:
    """{(kind, image, with camera): outputs} of one checkout, computed in a fresh interpreter."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "out.pkl")
        subprocess.run([sys.executable, "-c", _DUMP, str(checkout), str(n_seed), str(seed), path], check=True,
                       env={**os.environ, "PYTHONPATH": str(checkout)}, cwd=checkout)
        with open(path, "rb") as fh:
            return pickle.load(fh)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--seed-images", type=int, default=20)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args(argv)
    a_out, b_out = (outputs(p.resolve(), a.seed_images, a.seed) for p in (a.before, a.after))
    differ = sorted(k for k in a_out.keys() | b_out.keys() if a_out.get(k) != b_out.get(k))
    print(f"{len(a_out)} detections ({a.seed_images} seed images and {len(a_out) // 2 - a.seed_images} gallery "
          f"scenes, with and without a camera file): {len(differ)} differ")
    for k in differ:
        print("  differs:", k)
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
