"""Detection speed and accuracy on 1920x1200 rendered images, next to a generic OpenCV pipeline.

Images: the default manipulator through CameraModel.synthetic(1920, 1200) (0.03 mm/px at the centre,
lens distortion, tilted plane), default render settings (blur sigma 1 px, noise 2 % of contrast,
uneven illumination, textured background), several shapes (|theta| up to 0.10 rad, both
directions, mirrored views).

Reference ("generic"): cv2.goodFeaturesToTrack (Shi-Tomasi, 400 corners) + cv2.cornerSubPix, then
each true notch point takes the nearest detected corner (an oracle assignment that the generic
pipeline cannot do by itself: it favours the reference). Its time excludes the assignment.

Run:  python benchmarks/bench_detection.py [--images 12] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from notchfit.camera import CameraModel
from notchfit.detection import detect_notches
from notchfit.geometry import default_geometry
from notchfit.render import place_in_view, render_manipulator


def generic(image, max_corners=400, quality=0.01, min_distance=5, win=5):
    g = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    pts = cv2.goodFeaturesToTrack(g, max_corners, quality, min_distance, blockSize=7)
    if pts is None:
        return np.zeros((0, 2))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    pts = cv2.cornerSubPix(g, pts.astype(np.float32), (win, win), (-1, -1), crit)
    return pts.reshape(-1, 2).astype(float)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    geom = default_geometry()
    cam = CameraModel.synthetic(1920, 1200, mm_per_px=0.03)
    rng = np.random.default_rng(a.seed)
    cases = []
    while len(cases) < a.images:
        amp = rng.uniform(-0.10, 0.10)
        slope = rng.uniform(-0.004, 0.004)
        th = np.clip(amp + slope * (np.arange(geom.n_joints) - 13) + rng.normal(0, 0.005, geom.n_joints), -0.10, 0.10)
        mirror = bool(rng.integers(2))
        phi = rng.uniform(-0.4, 0.4) + (np.pi / 2 if rng.integers(2) else 0.0)
        plane, fits = place_in_view(th, geom, cam, phi=phi, mirror=mirror)
        if not fits:
            continue
        r = render_manipulator(th, geom, cam, plane=plane, rng=rng)
        cases.append((r, mirror))
    mm_per_px = 1e3 / cam.plane_scale()
    t_ours, t_gen, e_ours, e_gen, n_ok = [], [], [], [], 0
    for r, mirror in cases:
        best = np.inf
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            det = detect_notches(r.image, cam, geom, mirror=mirror)
            best = min(best, time.perf_counter() - t0)
        t_ours.append(best)
        ok = np.array(det.status) == "ok"
        n_ok += ok.sum()
        e_ours.append(np.linalg.norm(det.points[ok] - r.points_plane[ok], axis=1) * 1e3)
        best = np.inf
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            pts = generic(r.image)
            best = min(best, time.perf_counter() - t0)
        t_gen.append(best)
        d = np.linalg.norm(r.points_px[:, None] - pts[None], axis=2)
        near = pts[np.argmin(d, axis=1)]
        e_gen.append(np.linalg.norm(cam.pixel_to_plane(near) - r.points_plane, axis=1) * 1e3)
    e_ours, e_gen = np.concatenate(e_ours), np.concatenate(e_gen)
    m = geom.n_points * len(cases)
    print(f"{len(cases)} images 1920x1200, {mm_per_px:.4f} mm/px, {geom.n_points} points each")
    print(f"{'method':34s} {'ms/image':>9s} {'found ok':>9s} {'rms mm':>8s} {'max mm':>8s} {'rms px':>7s}")
    print(f"{'notchfit.detect_notches':34s} {1e3 * np.median(t_ours):9.1f} {n_ok:>4d}/{m:<4d} "
          f"{np.sqrt(np.mean(e_ours ** 2)):8.4f} {e_ours.max():8.4f} {np.sqrt(np.mean(e_ours ** 2)) / mm_per_px:7.3f}")
    print(f"{'goodFeatures+cornerSubPix+nearest':34s} {1e3 * np.median(t_gen):9.1f} {m:>4d}/{m:<4d} "
          f"{np.sqrt(np.mean(e_gen ** 2)):8.4f} {e_gen.max():8.4f} {np.sqrt(np.mean(e_gen ** 2)) / mm_per_px:7.3f}")
    print(f"time ratio notchfit/generic: {np.median(t_ours) / np.median(t_gen):.2f}; "
          f"rms error ratio generic/notchfit: {np.sqrt(np.mean(e_gen ** 2)) / np.sqrt(np.mean(e_ours ** 2)):.1f}")
    print("(the generic errors use an oracle nearest-true-point assignment; it also cannot number the points)")


if __name__ == "__main__":
    main()
