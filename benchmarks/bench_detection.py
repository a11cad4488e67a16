"""Detection speed and accuracy on 1920x1200 rendered images, next to a generic OpenCV pipeline.

Images: the default manipulator through CameraModel.synthetic(1920, 1200) (0.03 mm/px at the centre,
lens distortion, tilted plane), default render settings (blur sigma 1 px, noise 2 % of contrast,
uneven illumination, textured background), random shapes with |theta| up to 0.1395 rad (the slots
close at 0.1397 rad: on the closing side the outer corners almost touch), both directions,
mirrored views, the tube at any angle in the image.

Reference ("generic"): cv2.goodFeaturesToTrack (Shi-Tomasi, 400 corners) + cv2.cornerSubPix, then
each true notch point takes the nearest detected corner (an oracle assignment that the generic
pipeline cannot do by itself: it favours the reference). Its time excludes the assignment.

Real scenes (--scenes): a one-sided wrist like the lab's (OD 1.62 mm, five notches 0.8 mm high, one
side) in 4928x3264 renders at 130 px/mm (notchfit.vision.render.scenes: a chuck, collet, clamp or none,
plain tube, cylinder shading, specular streak, either polarity, defocus, JPEG, any orientation), with
the calibrated camera and without one (scale from the tube's diameter).

Seeded random lab scenes (--variety N): everything a lab photograph varies in (notchfit.vision.render.variety:
holders incl. a chuck's jaws as dark as the tube or brighter, polarity, shading, streak, uneven backdrop
and vignetting, the lens's perspective and a tilt out of the plane up to 4 deg, blur, defocus, motion,
ISO noise, sharpening, JPEG 75-95, any angle, bends to 0.98 of each slot's closure, per-notch depths),
tables per holder kind and per factor, with the camera and without it.

Physically based gallery (--pbr): the Mitsuba 3 renders committed in tests/data/pbr (made by
benchmarks/make_pbr_gallery.py: a polished wrist on a knurled chuck, closed slot mouths on grid paper, a
tendon loop at the tip, a printed tube on blue paper through a phone-like lens, depth of field), per scene
kind with the camera and without it: corners ok / present, wrong identities, invented points, rms and max
error, the spread of (found - true) / sigma; --pbr-render re-renders the gallery first (needs Mitsuba).

Speed side by side (--speed): ms per 1920x1200 seed image, per 16 MP photograph (the lab's wrist in a
chuck, 4928x3264 at 130 px/mm) and per 2 MP phone photograph (a large printed tube on coloured paper,
1320x1629 at 20 px/mm, its base entering from the image border), with the camera and without it, all
in one run (best of --repeat each, wall and CPU time), with the corners found; then what the first
seed image costs in a fresh interpreter (as the CLI on one image), with the numba kernels loaded from
their on-disk cache and compiled into an empty one.

Run:  python benchmarks/bench_detection.py [--images 12] [--repeat 3]
      python benchmarks/bench_detection.py --speed [--repeat 5]
      python benchmarks/bench_detection.py --robustness [--per-row 4]   (the table of docs/robustness.md)
      python benchmarks/bench_detection.py --scenes [--per-scene 2]     (the real-scene table)
      python benchmarks/bench_detection.py --variety 40 [--seed 1] [--size 4928x3264] [--px-per-mm 130]
      python benchmarks/bench_detection.py --pbr [--pbr-dir tests/data/pbr] [--pbr-render]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))            # this checkout's notchfit, not an installed one
from notchfit.vision.camera import CameraModel  # noqa: E402
from notchfit.vision.detection import detect_notches, mirror_without_camera  # noqa: E402
from notchfit.physics.geometry import default_geometry  # noqa: E402
from notchfit.vision.render import place_in_view, render_manipulator  # noqa: E402


def generic(image, max_corners=400, quality=0.01, min_distance=5, win=5):
    g = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    pts = cv2.goodFeaturesToTrack(g, max_corners, quality, min_distance, blockSize=7)
    if pts is None:
        return np.zeros((0, 2))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    pts = cv2.cornerSubPix(g, pts.astype(np.float32), (win, win), (-1, -1), crit)
    return pts.reshape(-1, 2).astype(float)


ROBUSTNESS = [  # (factor, values, how to apply); default: blur 1 px, noise 2 %, contrast 160 DN, 0.03 mm/px
    ("blur sigma [px]", (0.5, 1.0, 1.5, 2.0, 3.0), lambda v: ({"blur_sigma": v}, {})),
    ("noise [% of contrast]", (1, 2, 5, 10, 20), lambda v: ({"noise": v / 100}, {})),
    ("contrast [DN], noise 3.2 DN", (160, 60, 30, 15, 8),
     lambda v: ({"background": 120 + v / 2, "foreground": 120 - v / 2, "noise": 3.2 / v}, {})),
    ("resolution [mm/px]", (0.02, 0.03, 0.04, 0.05, 0.06), lambda v: ({}, {"mm_per_px": v})),
    ("rotation phi [deg]", (0, 30, 60, 90, 135, 180), lambda v: ({}, {"phi": np.radians(v)})),
    ("bend |theta| [rad]", (0.0, 0.07, 0.12, 0.135, 0.1395), lambda v: ({}, {"bend": v})),
]
CLOSE = 0.1395        # just below the default slot-closure angle 0.13970 rad


def robustness_row(render_kw, cam_kw, n, seed):
    """Detect n seeded random shapes (|theta| <= 0.1395 rad, half mirrored); (ok fraction, rms mm, max mm)."""
    from notchfit.vision.render import camera_for_shapes

    geom = default_geometry()
    rng = np.random.default_rng(seed)
    errs, n_ok = [], 0
    for k in range(n):
        if "bend" in cam_kw:
            b = cam_kw["bend"] * (1 if k % 2 else -1)
            th = np.clip(b + rng.normal(0, 0.002, geom.n_joints), -max(abs(b), 1e-9), max(abs(b), 1e-9))
        else:
            th = np.clip(rng.uniform(-CLOSE, CLOSE) + rng.normal(0, 0.01, geom.n_joints), -CLOSE, CLOSE)
        mirror = bool(k % 2)
        kw = {"mm_per_px": 0.03, "phi": rng.uniform(-np.pi, np.pi), **cam_kw}
        cam, planes = camera_for_shapes([th], geom, mm_per_px=kw["mm_per_px"], phi=kw["phi"], mirror=mirror)
        r = render_manipulator(th, geom, cam, plane=planes[0], rng=rng, **render_kw)
        det = detect_notches(r.image, cam, geom, mirror=mirror)
        ok = np.array(det.status) == "ok"
        n_ok += ok.sum()
        errs.append(np.linalg.norm(det.points[ok] - r.points_plane[ok], axis=1) * 1e3)
    e = np.concatenate(errs)
    if e.size == 0:
        return 0.0, float("nan"), float("nan")
    return n_ok / (n * geom.n_points), float(np.sqrt(np.mean(e ** 2))), float(e.max())


def robustness(per_row, seed):
    print("| factor | value | points ok | rms [mm] | max [mm] |")
    print("|---|---|---|---|---|")
    for name, values, make in ROBUSTNESS:
        for v in values:
            rk, ck = make(v)
            frac, rms, mx = robustness_row(rk, ck, per_row, seed)
            print(f"| {name} | {v:g} | {100 * frac:.1f} % | {rms:.4f} | {mx:.4f} |", flush=True)


WRIST = dict(n_joints=5, p=1.6e-3, outer_radius=0.81e-3, slot_width=0.8e-3, slot_depth=1.3e-3,
             slot_sides=(1,) * 5, mount_half_width=2.5e-3, name="wrist", inner_radius=0.7e-3,
             tendons=("right",), tendon_path="lumen", r_x=None, r_z=None, cable_radius=None, channel_radius=None)
SCENES = [  # (name, Scene keywords); blur 2 px (a DSLR at 130 px/mm), chuck 8 mm wide unless said
    ("chuck, dark tube on grey", dict(holder="chuck")),
    ("chuck, plain tube 1.5 mm", dict(holder="chuck", plain_length=1.5e-3)),
    ("collet", dict(holder="collet", plain_length=0.5e-3)),
    ("clamp", dict(holder="clamp")),
    ("no holder (from the border)", dict(holder="none")),
    ("polished tube on dark", dict(holder="chuck", background=30.0, tube_level=190.0, holder_level=160.0)),
    ("specular streak 0.7", dict(holder="chuck", streak=0.7, highlights=0.3)),
    ("specular streak 1.2", dict(holder="chuck", streak=1.2, highlights=0.3)),
    ("JPEG q 85", dict(holder="chuck", jpeg_quality=85)),
    ("defocus 4 px", dict(holder="chuck", blur_sigma=4.0)),
]


def big_timing(repeat, seed):
    """ms per 4928x3264 image (the lab's wrist in a chuck at 130 px/mm), with and without the camera."""
    from notchfit.physics.geometry import Geometry
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    geom = Geometry(**WRIST)
    th = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
    cam, plane = scene_camera(th, geom, image_size=(4928, 3264), mm_per_px=1 / 130, angle_deg=90, base_at=0.05)
    r = render_scene(th, geom, cam, plane=plane, scene=Scene(holder_half_width=4e-3, blur_sigma=2.0),
                     rng=np.random.default_rng(seed))
    for calibrated in (True, False):
        ts = []
        for _ in range(max(repeat, 3)):
            t0 = time.perf_counter()
            det = detect_notches(r.image, cam, geom) if calibrated else \
                detect_notches(r.image, None, geom, mirror=mirror_without_camera(cam, r.image.shape[:2], False))
            ts.append(time.perf_counter() - t0)
        print(f"4928x3264 wrist in a chuck, {'calibrated' if calibrated else 'no calibration'}: "
              f"{1e3 * min(ts):.0f} ms per image (best of {len(ts)}), {det.n_ok}/{len(det.status)} ok")


PRINTED = dict(n_joints=6, p=4e-3, outer_radius=3e-3, slot_width=1.5e-3, slot_depth=4.2e-3,
               slot_sides=(1, -1, 1, -1, 1, -1), name="printed", inner_radius=2e-3, tendon_path="lumen",
               r_x=None, r_z=None, cable_radius=None, channel_radius=None)


def _best_ms(fn, repeat):
    """Best wall time and best process CPU time (all threads) of ``repeat`` calls [ms], and the last result.
    On a machine shared with other jobs the CPU time is the detector's own cost."""
    best, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        best, cpu = min(best, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return 1e3 * best, 1e3 * cpu, out


def speed(repeat, seed):
    """ms per image of the three photograph kinds the targets name, measured in one run."""
    from notchfit.physics.geometry import Geometry
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    rng = np.random.default_rng(seed)
    geom = default_geometry()
    cam = CameraModel.synthetic(1920, 1200, mm_per_px=0.03)
    th = np.full(geom.n_joints, 0.03)
    plane, fits = place_in_view(th, geom, cam, phi=0.2, mirror=False)
    assert fits
    cases = [("1920x1200 seed tube (target 40 ms)", render_manipulator(th, geom, cam, plane=plane, rng=rng), cam,
              geom, False)]
    wrist = Geometry(**WRIST)
    thw = np.array([0.2, 0.25, 0.3, 0.3, 0.25])
    camw, planew = scene_camera(thw, wrist, image_size=(4928, 3264), mm_per_px=1 / 130, angle_deg=90, base_at=0.05)
    cases.append(("4928x3264 wrist in a chuck (target 150 ms)",
                  render_scene(thw, wrist, camw, plane=planew, scene=Scene(holder_half_width=4e-3, blur_sigma=2.0),
                               rng=rng), camw, wrist, False))
    printed = Geometry(**PRINTED)
    thp = np.array([0.1, -0.1, 0.15, -0.05, 0.1, 0.0])
    camp, planep = scene_camera(thp, printed, image_size=(1320, 1629), mm_per_px=1 / 20, angle_deg=80, base_at=0.03)
    cases.append(("1320x1629 phone photo, printed tube (target 60 ms)",
                  render_scene(thp, printed, camp, plane=planep, scene=Scene(holder="none", background=70.0,
                                                                             tube_level=225.0, blur_sigma=1.5),
                               rng=rng), camp, printed, False))
    print("| image | camera | ms / image | CPU ms / image | corners ok / visible |")
    print("|---|---|---|---|---|")
    for name, r, c, g, mirror in cases:
        for cal in (True, False):
            m = mirror if cal else mirror_without_camera(c, r.image.shape[:2], mirror)
            ms, cpu, det = _best_ms(lambda: detect_notches(r.image, c if cal else None, g, mirror=m), repeat)
            print(f"| {name} | {'yes' if cal else 'no'} | {ms:.0f} | {cpu:.0f} | {det.n_ok}/{int(r.visible.sum())} |",
                  flush=True)
    ms, cpu, _ = _best_ms(lambda: generic(cases[0][1].image), repeat)
    print(f"(reference in the same run: goodFeaturesToTrack + cornerSubPix on the 1920x1200 image, {ms:.0f} ms, "
          f"{cpu:.0f} ms CPU)")
    name, r, c, g, _ = cases[0]
    for cold in (False, True):
        t = _first_images(r.image, c, g, cold)
        how = "numba kernels compiled into an empty cache" if cold else "numba kernels from their on-disk cache"
        print(f"first seed image in a fresh interpreter ({how}): import {t['import_cpu']:.0f} ms CPU, first image "
              f"{t['first_cpu']:.0f} ms CPU ({t['first_wall']:.0f} ms), second {t['second_cpu']:.0f} ms CPU",
              flush=True)


_FIRST = """
import json, pickle, sys, time
c0 = time.process_time()
from notchfit.vision.detection import detect_notches
out = {"import_cpu": 1e3 * (time.process_time() - c0)}
image, camera, geom = pickle.load(open(sys.argv[1], "rb"))
for k in ("first", "second"):
    c0, w0 = time.process_time(), time.perf_counter()
    detect_notches(image, camera, geom)
    out[k + "_cpu"], out[k + "_wall"] = 1e3 * (time.process_time() - c0), 1e3 * (time.perf_counter() - w0)
print(json.dumps(out))
"""


def _first_images(image, camera, geom, cold: bool) -> dict:
    """CPU and wall ms of importing the detector and of its first and second image in a fresh interpreter
    (this checkout); ``cold``: the numba kernels compile into an empty cache (a fresh install, a changed
    kernel) instead of loading from theirs."""
    import json
    import os
    import pickle
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "case.pkl")
        with open(path, "wb") as fh:
            pickle.dump((image, camera, geom), fh)
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        if cold:
            env["NUMBA_CACHE_DIR"] = os.path.join(tmp, "numba")
        else:
            # the kernels' cache filled before the timed run
            subprocess.run([sys.executable, "-c", _FIRST, path], env=env, capture_output=True, check=True)
        done = subprocess.run([sys.executable, "-c", _FIRST, path], env=env, capture_output=True, text=True,
                              check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def scene_rows(per_scene, seed, size=(4928, 3264), px_per_mm=130.0, repeat=2):
    """Per scene kind: corners ok / real corners, rms and max error [mm], ms per image, with the camera
    and without it (scale error [%])."""
    from notchfit.physics.geometry import Geometry
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    geom = Geometry(**WRIST)
    rng = np.random.default_rng(seed)
    print(f"{per_scene} images per kind, {size[0]}x{size[1]}, {px_per_mm:g} px/mm, angles and bends at random")
    print("| scene | camera | corners ok | rms [mm] | max [mm] | ms / image | scale error |")
    print("|---|---|---|---|---|---|---|")
    for name, kw in SCENES:
        kw = {"blur_sigma": 2.0, "holder_half_width": 4e-3, **kw}
        res = {True: [0, 0, [], []], False: [0, 0, [], [], []]}
        for k in range(per_scene):
            th = rng.uniform(0.05, 0.3) * (1 + 0.1 * rng.normal(size=geom.n_joints)) * rng.choice([-1, 1])
            angle = rng.uniform(0, 360) if k % 2 else float(rng.choice([90, 0, 180, 270]))
            cam, plane = scene_camera(th, geom, image_size=size, mm_per_px=1 / px_per_mm, angle_deg=angle,
                                      base_at=0.15)
            r = render_scene(th, geom, cam, plane=plane, scene=Scene(**kw), rng=rng)
            for calibrated in (True, False):
                best = np.inf
                for _ in range(repeat):
                    t0 = time.perf_counter()
                    det = detect_notches(r.image, cam, geom) if calibrated else detect_notches(
                        r.image, None, geom, mirror=mirror_without_camera(cam, r.image.shape[:2], False))
                    best = min(best, time.perf_counter() - t0)
                ok = np.array(det.status) == "ok"
                row = res[calibrated]
                row[0] += int((ok & r.visible).sum())
                row[1] += int(r.visible.sum())
                row[2].append(np.linalg.norm(det.points_px[ok] - r.points_px[ok], axis=1) / px_per_mm)
                row[3].append(best)
                if not calibrated and np.isfinite(det.scale_mm_per_px):
                    row[4].append(100 * (det.scale_mm_per_px * px_per_mm - 1))
                if (ok & ~r.visible).any():
                    print(f"  ({name}: {int((ok & ~r.visible).sum())} points reported that are not corners)")
        for calibrated in (True, False):
            n_ok, n_vis, errs, ts = res[calibrated][:4]
            e = np.concatenate(errs)
            sc = "" if calibrated else (f"{np.max(np.abs(res[False][4])):.2f} % max" if res[False][4] else "-")
            print(f"| {name} | {'yes' if calibrated else 'no'} | {n_ok}/{n_vis} | "
                  f"{np.sqrt(np.mean(e ** 2)) if len(e) else float('nan'):.4f} | "
                  f"{e.max() if len(e) else float('nan'):.4f} | {1e3 * np.median(ts):.0f} | {sc} |", flush=True)


def _variety_geometries():
    """The lab's wrist with joints on each slot's section, and the shipped wrists (per-notch dimensions)."""
    from pathlib import Path

    from notchfit.physics.geometry import Geometry
    from notchfit.io import load_geometry

    here = Path(__file__).resolve().parent.parent / "datasets" / "geometry"
    return [Geometry(**{**WRIST, "backbone": "section", "name": "lab_wrist"})] + \
        [load_geometry(here / f"{n}.toml") for n in ("wrist_asymmetric", "wrist_tip_first")]


def _table(title, rows, key):
    """Print found / real corners, invented, rms and max error [mm], ms and scale error per group."""
    print(f"| {title} | camera | images | corners found | invented | rms [mm] | max [mm] | ms / image | scale error |")
    print("|---|---|---|---|---|---|---|---|---|")
    groups = sorted({key(r) for r in rows}, key=str)
    for g in groups + ["all"]:
        for cal in (True, False):
            sel = [r for r in rows if (g == "all" or key(r) == g) and r["cal"] == cal]
            if not sel:
                continue
            e = np.concatenate([r["err"] for r in sel])
            sc = [abs(r["scale"]) for r in sel if np.isfinite(r["scale"])]
            print(f"| {g} | {'yes' if cal else 'no'} | {len(sel)} | {sum(r['found'] for r in sel)}/"
                  f"{sum(r['corners'] for r in sel)} | {sum(r['invented'] for r in sel)} | "
                  f"{np.sqrt(np.mean(e ** 2)) if len(e) else float('nan'):.4f} | {e.max() if len(e) else float('nan'):.4f}"
                  f" | {1e3 * np.median([r['t'] for r in sel]):.0f} | "
                  f"{'' if cal else (f'{100 * max(sc):.2f} % max' if sc else '-')} |", flush=True)


def variety(n, seed, size=(4928, 3264), px_per_mm=130.0):
    """n seeded random lab scenes (notchfit.vision.render.variety), detected with and without the camera; tables
    per holder kind and per factor."""
    from notchfit.vision.render.variety import draw_scene, render_draw, score

    rng = np.random.default_rng(seed)
    geoms = _variety_geometries()
    rows = []
    for k in range(n):
        d = draw_scene(rng, geoms, size=size, px_per_mm=px_per_mm)
        r = render_draw(d, rng)
        for cal in (True, False):
            t0 = time.perf_counter()
            det = detect_notches(r.image, d.camera, d.geom) if cal else detect_notches(
                r.image, None, d.geom, mirror=mirror_without_camera(d.camera, r.image.shape[:2], d.plane[3]))
            t = time.perf_counter() - t0
            s = score(det, r, px_per_mm)
            scale = det.scale_mm_per_px * px_per_mm - 1 if not cal and det.n_ok else math.nan
            rows.append({**s, "err": s["errors_mm"], "cal": cal, "t": t, "scale": scale, "kind": d.kind, **d.labels})
    print(f"{n} random lab scenes, {size[0]}x{size[1]}, {px_per_mm:g} px/mm, seed {seed} "
          "(notchfit.vision.render.variety; the tube tilted out of the plane up to 4 deg, lens 150-500 mm away)")
    _table("holder", rows, lambda r: r["kind"])
    print()
    _table("tilt out of the plane", rows, lambda r: "0-2 deg" if r["tilt_deg"] < 2 else "2-4 deg")
    print()
    _table("bend (largest joint / its closure)", rows,
           lambda r: "< 0.5" if r["closure"] < 0.5 else ("0.5-0.9" if r["closure"] < 0.9 else ">= 0.9"))
    print()
    _table("specular streak", rows, lambda r: "yes" if r["streak"] > 0 else "no")
    print()
    _table("polarity", rows, lambda r: r["polarity"])
    print()
    _table("geometry", rows, lambda r: r["geometry"])


def _pbr_gallery(folder):
    """The gallery's scenes: (record, scene, truth, geometry, image) per JSON record in ``folder``."""
    import json
    from pathlib import Path

    from notchfit.io import load_geometry, load_image
    from notchfit.vision.render.pbr import PbrScene, PbrTruth

    root = Path(__file__).resolve().parent.parent
    out = []
    for p in sorted(Path(folder).glob("*.json")):
        rec = json.loads(p.read_text())
        out.append((rec, PbrScene.from_dict(rec["scene"]), PbrTruth.from_dict(rec),
                    load_geometry(root / rec["geometry"]), load_image(Path(folder) / rec["image"])))
    return out


def _pbr_row(kind, cal, sel):
    """One table row from (kind, calibrated, PbrScore, seconds, px/mm) tuples."""
    def stat(a, fn):
        return f"{fn(a):.4f}" if a.size else "-"

    def rms(a):
        return np.sqrt(np.mean(a ** 2))

    e_mm = np.concatenate([r[2].errors_mm for r in sel])
    e_px = np.concatenate([r[2].errors_px for r in sel])
    z = np.concatenate([r[2].z for r in sel])
    ok, present = sum(r[2].ok for r in sel), sum(r[2].present for r in sel)
    counts = [sum(getattr(r[2], k) for r in sel) for k in ("wrong", "invented", "located")]
    return (f"| {kind} | {'yes' if cal else 'no'} | {len(sel)} | {ok}/{present} ({100 * ok / max(present, 1):.0f} %) | "
            + " | ".join(str(c) for c in counts) + f" | {stat(e_mm, rms)} | {stat(e_mm, np.max)} | {stat(e_px, rms)} | "
            f"{stat(z, rms)} | {stat(z, lambda a: 1.4826 * np.median(np.abs(a)))} | "
            f"{1e3 * np.median([r[3] for r in sel]):.0f} |")


def pbr(folder, repeat=1, render=False, tone_gamma=1.0):
    """Per scene kind of the physically based gallery, with the camera file and without it: corners ok /
    present, wrong identities (target 0), invented points, rms and max error [mm] (target rms <= 0.01 mm),
    the spread of (found - true) / sigma (1 = honest), ms per image; the overall fraction (target >= 95 %).

    ``tone_gamma``: the detector's ``DetectorOptions.tone_gamma``; 2.2 is what ``notchfit detect`` assumes
    for a JPEG without ``image_gamma`` in experiment.toml (the gallery's files carry an sRGB tone curve)."""
    import tempfile

    from notchfit.vision.render.pbr import score_detection
    from notchfit.vision.render.scenes import Scene, render_scene

    if render:
        import make_pbr_gallery

        folder = tempfile.mkdtemp(prefix="pbr_gallery_")
        make_pbr_gallery.main(["--out", folder])
    scenes = _pbr_gallery(folder)
    rows, own, scales = [], {}, []
    for rec, scene, truth, geom, img in scenes:
        for cal in (True, False):
            best = np.inf
            for _ in range(max(repeat, 1)):
                t0 = time.perf_counter()
                # without the camera file the plane frame is the image's (x right, y down): the flag a
                # user would write for this view (mirror_without_camera)
                mirror = truth.pose.plane[3] if cal else mirror_without_camera(truth.camera, img.shape[:2],
                                                                                truth.pose.plane[3])
                det = detect_notches(img, truth.camera if cal else None, geom, mirror=mirror,
                                     tone_gamma=tone_gamma)
                best = min(best, time.perf_counter() - t0)
            rows.append((scene.kind, cal, score_detection(det, truth, scene.px_per_mm), best, scene.px_per_mm))
            if not cal:
                scales.append((rec["image"], det.n_ok, det.scale_mm_per_px * scene.px_per_mm - 1,
                               det.scale_sigma * scene.px_per_mm))
        # the same tube, camera and pose drawn by notchfit's own renderer (a solid, flat shading, blur 1 px):
        # what the view's geometry alone allows, apart from the physically based appearance
        r = render_scene(np.asarray(scene.theta), geom, truth.camera, plane=truth.pose.plane,
                         scene=Scene(holder="none" if scene.holder == "none" else "chuck", solid=True,
                                     holder_half_width=scene.holder_half_width, tilt_deg=scene.tilt_deg,
                                     tilt_axis_deg=scene.tilt_axis_deg, blur_sigma=1.0),
                         rng=np.random.default_rng(scene.seed))
        s = score_detection(detect_notches(r.image, truth.camera, geom, mirror=truth.pose.plane[3]), truth,
                            scene.px_per_mm)
        k = own.setdefault(scene.kind, [0, 0])
        k[0] += s.ok
        k[1] += s.present
    print(f"{len(scenes)} physically based renders ({folder}), {min(r[4] for r in rows):g}-"
          f"{max(r[4] for r in rows):g} px/mm")
    print("| scene kind | camera | images | corners ok | wrong ids | invented | withheld within 5 px | rms [mm] | "
          "max [mm] | rms [px] | z rms | z robust | ms / image |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for kind in sorted({r[0] for r in rows}) + ["all"]:
        for cal in (True, False):
            sel = [r for r in rows if (kind == "all" or r[0] == kind) and r[1] == cal]
            print(_pbr_row(kind, cal, sel), flush=True)
    print("Without the camera file, the scale's error / its stated sigma (the scene's nominal px/mm as truth; "
          "no sigma is stated where no corner is ok): " + ", ".join(
              f"{n.split('.')[0]} {100 * e:+.1f} % / {sg * 100:.1f} % ({n_ok} ok)" for n, n_ok, e, sg in scales
              if np.isfinite(e)))
    print("Same tubes, cameras and poses drawn by notchfit's own renderer (solid, blur 1 px), with the camera: "
          + ", ".join(f"{k} {v[0]}/{v[1]}" for k, v in sorted(own.items())))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--robustness", action="store_true", help="print the robustness table instead")
    ap.add_argument("--per-row", type=int, default=4, help="images per robustness row")
    ap.add_argument("--scenes", action="store_true", help="print the real-scene table instead")
    ap.add_argument("--per-scene", type=int, default=2, help="images per scene kind")
    ap.add_argument("--variety", type=int, default=0, help="detect this many seeded random lab scenes instead")
    ap.add_argument("--size", default="4928x3264", help="image size of --variety (WxH)")
    ap.add_argument("--speed", action="store_true", help="ms per seed image, 16 MP photo and 2 MP phone photo")
    ap.add_argument("--px-per-mm", type=float, default=130.0, help="scale of --variety")
    ap.add_argument("--pbr", action="store_true", help="score the physically based gallery instead")
    ap.add_argument("--pbr-dir", default=None, help="gallery folder of --pbr (default tests/data/pbr)")
    ap.add_argument("--pbr-render", action="store_true", help="re-render the gallery first (needs Mitsuba 3)")
    ap.add_argument("--tone-gamma", type=float, default=1.0,
                    help="--pbr: undo this tone curve first (2.2: what `notchfit detect` assumes for a JPEG)")
    a = ap.parse_args(argv)
    if a.pbr:
        from pathlib import Path

        pbr(a.pbr_dir or Path(__file__).resolve().parent.parent / "tests" / "data" / "pbr", 1, a.pbr_render, a.tone_gamma)
        return
    if a.variety:
        variety(a.variety, a.seed, tuple(int(v) for v in a.size.split("x")), a.px_per_mm)
        return
    if a.robustness:
        robustness(a.per_row, a.seed)
        return
    if a.speed:
        speed(max(a.repeat, 3), a.seed)
        return
    if a.scenes:
        scene_rows(a.per_scene, a.seed)
        return
    geom = default_geometry()
    cam = CameraModel.synthetic(1920, 1200, mm_per_px=0.03)
    rng = np.random.default_rng(a.seed)
    cases = []
    while len(cases) < a.images:
        amp = rng.uniform(-CLOSE, CLOSE)
        slope = rng.uniform(-0.004, 0.004)
        th = np.clip(amp + slope * (np.arange(geom.n_joints) - 13) + rng.normal(0, 0.005, geom.n_joints),
                     -CLOSE, CLOSE)
        mirror = bool(rng.integers(2))
        phi = rng.uniform(-0.4, 0.4) + (np.pi / 2 if rng.integers(2) else 0.0)
        plane, fits = place_in_view(th, geom, cam, phi=phi, mirror=mirror)
        if not fits:
            continue
        r = render_manipulator(th, geom, cam, plane=plane, rng=rng)
        cases.append((r, mirror))
    mm_per_px = 1e3 / cam.plane_scale()
    t_ours, t_gen, e_ours, e_gen, n_ok, zs = [], [], [], [], 0, []
    not_ok, worst = [], []
    for k, (r, mirror) in enumerate(cases):
        best = np.inf
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            det = detect_notches(r.image, cam, geom, mirror=mirror)
            best = min(best, time.perf_counter() - t0)
        t_ours.append(best)
        ok = np.array(det.status) == "ok"
        n_ok += ok.sum()
        if not ok.all():
            not_ok.append(f"image {k + 1} (max |theta| {np.abs(r.theta).max():.4f}): {det.message}")
        e_ours.append(np.linalg.norm(det.points[ok] - r.points_plane[ok], axis=1) * 1e3)
        worst.append((e_ours[-1].max() if ok.any() else 0.0, k + 1, int(np.nonzero(ok)[0][np.argmax(e_ours[-1])]) + 1
                      if ok.any() else 0, float(np.abs(r.theta).max())))
        zs.append(e_ours[-1] * 1e-3 / (np.sqrt(2) * det.sigma[ok]))
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
    for line in not_ok:
        print("not ok:", line)
    e_max, k_max, p_max, th_max = max(worst)
    print(f"largest error {e_max:.4f} mm: image {k_max}, point {p_max} (max |theta| {th_max:.4f} rad)")
    big_timing(a.repeat, a.seed)
    z = np.concatenate(zs)
    print(f"reported sigma: rms of |error| / (sqrt(2) sigma) = {np.sqrt(np.mean(z ** 2)):.2f} (1 = calibrated); "
          f"max |theta| over the images {max(np.abs(r.theta).max() for r, _ in cases):.4f} rad")


if __name__ == "__main__":
    main()
