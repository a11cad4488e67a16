"""A small rendered study and its detect run for the tests of ``notchfit review``, and a server in a thread."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from notchfit import io
from notchfit.cli import main
from notchfit.commands.review import load_session
from notchfit.physics.geometry import default_geometry
from notchfit.vision.render import camera_for_shapes, render_manipulator
from notchfit.review.server import make_server

#: The corner the tests blank out in sample 1's detections (to be placed by hand).
BLANKED = 10


def rendered_study(root: Path, *, n_samples: int = 3, seed: int = 3) -> tuple[Path, Path, np.ndarray]:
    """A one-experiment study of rendered photographs (0.03 mm/px, about 1.5 Mpx), detected.

    Corner :data:`BLANKED` of sample 1 is removed from detections.csv, so that one
    corner is missing. Returns the experiment folder, the detect run folder and the
    true plane points (S, m, 2) [m].
    """
    geom = default_geometry()
    thetas = [np.full(geom.n_joints, 0.02 * k) for k in range(n_samples)]
    cam, planes = camera_for_shapes(thetas, geom, mm_per_px=0.03, phi=0.4)
    folder = Path(root) / "study" / "exp"
    (folder / "images").mkdir(parents=True)
    io.write_camera(cam, folder / "camera.yml")
    rng = np.random.default_rng(seed)
    rows, truth = [], []
    for s, th in enumerate(thetas, start=1):
        r = render_manipulator(th, geom, cam, plane=planes[0], rng=rng)
        cv2.imwrite(str(folder / "images" / f"{s:04d}.png"), r.image)
        truth.append(r.points_plane)
        rows.append({"sample": s, "time_s": float(s), "tension_left_N": 1.0 + s, "tension_right_N": 0.5,
                     "displacement_left_mm": np.nan, "displacement_right_mm": np.nan,
                     "image": f"images/{s:04d}.png"})
    (folder / "experiment.toml").write_text('name = "exp"\ngeometry = "default"\nmirror = false\n'
                                            'calibration = "camera.yml"\n')
    pd.DataFrame(rows).to_csv(folder / "samples.csv", index=False)
    out = Path(root) / "det"
    assert main(["detect", str(folder), "--out", str(out), "--no-overlays"]) == 0
    det = pd.read_csv(out / "detections.csv")
    blank = (det["sample"] == 1) & (det["point"] == BLANKED)
    det.loc[blank, ["x_mm", "y_mm", "u_px", "v_px", "sigma_mm"]] = np.nan
    det.loc[blank, "status"] = "occluded"
    io.write_table_atomic(det, out / "detections.csv")
    return folder, out, np.stack(truth)


def work_copy(det: Path, tmp_path: Path) -> Path:
    """A fresh detect-run folder holding a copy of ``det``'s detections.csv (and no review yet)."""
    work = Path(tmp_path) / "det"
    work.mkdir()
    (work / "detections.csv").write_bytes((Path(det) / "detections.csv").read_bytes())
    return work


@contextlib.contextmanager
def running_server(study, points, **kw):
    """A review server on a free port of 127.0.0.1, serving in a thread; yields it."""
    session, failed = load_session(study, points)
    assert not failed, failed
    server = make_server(session, 0, **kw)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)
