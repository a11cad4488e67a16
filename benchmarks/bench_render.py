"""Renderer speed: ms per 1920x1200 manipulator image, and the background fields against the
straightforward per-pixel evaluation in the same run.

The textured background (a sum of plane waves) and the illumination field (gradient + hot spot)
are separable in (u, v); notchfit.vision.render builds them from 1-D arrays (one small matrix product
for the waves). The reference evaluates the same formulas at every pixel.

Real scenes (notchfit.vision.render.scenes): the lab's wrist in a chuck at 130 px/mm in a 4928x3264 image,
exact coverage only in a box around the tube and the holder's visible part.

Run:  python benchmarks/bench_render.py [--repeat 5]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from notchfit.vision.camera import CameraModel
from notchfit.physics.geometry import default_geometry
from notchfit.vision.render import _illumination, _smooth_field, place_in_view, render_manipulator

H, W = 1200, 1920


def smooth_field_per_pixel(shape, rng, n_waves=4, min_wavelength=150.0, max_wavelength=600.0):
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    f = np.zeros((h, w), np.float32)
    for _ in range(n_waves):
        lam = rng.uniform(min_wavelength, max_wavelength)
        ang = rng.uniform(0, 2 * np.pi)
        ph = rng.uniform(0, 2 * np.pi)
        f += np.cos((np.cos(ang) * u + np.sin(ang) * v) * (2 * np.pi / lam) + ph).astype(np.float32)
    return (f - f.mean()) / float(f.max() - f.min())


def illumination_per_pixel(shape, rng, amplitude):
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    un, vn = u / (w - 1) - 0.5, v / (h - 1) - 0.5
    g = rng.normal(size=2)
    cu, cv = rng.uniform(-0.3, 0.3, size=2)
    f = (g[0] * un + g[1] * vn) + np.exp(-((un - cu) ** 2 + (vn - cv) ** 2) / 0.18)
    f = (f - f.min()) / float(f.max() - f.min())
    return (1.0 - amplitude / 2.0 + amplitude * f).astype(np.float32)


def best_ms(fn, repeat):
    t = []
    for k in range(repeat):
        t0 = time.perf_counter()
        out = fn(k)
        t.append(time.perf_counter() - t0)
    return 1e3 * min(t), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    print(f"{W}x{H}, best of {a.repeat}")
    for name, fast, ref, args in (("texture (4 plane waves)", _smooth_field, smooth_field_per_pixel, ()),
                                  ("illumination", _illumination, illumination_per_pixel, (0.2,))):
        tf, f = best_ms(lambda k: fast((H, W), np.random.default_rng(k), *args), a.repeat)
        tr, r = best_ms(lambda k: ref((H, W), np.random.default_rng(k), *args), a.repeat)
        print(f"{name:26s} notchfit {tf:7.1f} ms   per-pixel {tr:7.1f} ms   ratio {tr / tf:5.1f}x   "
              f"max |diff| {np.abs(f - r).max():.1e}")

    geom = default_geometry()
    cam = CameraModel.synthetic(W, H)
    rng = np.random.default_rng(0)
    shapes = [np.clip(rng.uniform(-0.13, 0.13) + rng.normal(0, 0.005, geom.n_joints), -0.139, 0.139)
              for _ in range(a.repeat)]
    planes = [place_in_view(th, geom, cam)[0] for th in shapes]
    t, _ = best_ms(lambda k: render_manipulator(shapes[k], geom, cam, plane=planes[k],
                                                rng=np.random.default_rng(k)), a.repeat)
    print(f"render_manipulator (default settings)  {t:.0f} ms per image")

    from notchfit.physics.geometry import Geometry
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera
    wrist = Geometry(n_joints=5, p=1.6e-3, outer_radius=0.81e-3, slot_width=0.8e-3, slot_depth=1.3e-3,
                     slot_sides=(1,) * 5, mount_half_width=2.5e-3, name="wrist", inner_radius=0.7e-3,
                     tendons=("right",), tendon_path="lumen", r_x=None, r_z=None, cable_radius=None,
                     channel_radius=None)
    th = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
    for name, sc in (("chuck", Scene(holder_half_width=4e-3)), ("chuck + streak + JPEG",
                     Scene(holder_half_width=4e-3, streak=1.0, jpeg_quality=85))):
        cam, plane = scene_camera(th, wrist, image_size=(4928, 3264), mm_per_px=1 / 130, angle_deg=90)
        t, _ = best_ms(lambda k: render_scene(th, wrist, cam, plane=plane, scene=sc, rng=np.random.default_rng(k)),
                       min(a.repeat, 3))
        print(f"render_scene 4928x3264, {name:22s} {t:.0f} ms per image")


if __name__ == "__main__":
    main()
