"""Render the physically based test gallery (tests/data/pbr/) with Mitsuba 3 and write its ground truth.

Each scene of GALLERY (notchfit.vision.render.pbr.PbrScene) is rendered by a path tracer (variant scalar_rgb)
and written as <name>.jpg (or .png when the scene has no JPEG step) beside <name>.json: the scene, the
geometry file, the camera (intrinsics, distortion, the bending plane's pose), the tube's pose, every notch
point's corner in the image with whether the image shows it (and why not), and the render time. truth.csv
holds every scene's corners in one table. The default tests read these files and never need Mitsuba; the
slow test and `bench_detection.py --pbr --render` re-render.

Scene kinds (from what lab photographs of wrists show):
  polished-chuck  a polished nitinol wrist (rough conductor, the softbox's stripe along it) hanging from a
                  knurled steel chuck, a softbox and a fill light, its shadow on a warm-grey card (one scene at
                  the lab photograph's 130 px/mm in a dark room: a dark tube with a bright stripe)
  closed-grid     a nine-slot wrist bent until its slot mouths almost close, grid paper, a tendon leaving
                  the tip in a loop towards the border, a droplet at the tip
  tendon-loop     the five-slot wrist with the tendon loop and the droplet on the grey card
  printed-paper   a printed tube (OD 6 mm, 12 slots from alternating sides) in matte white plastic lying on
                  blue paper, seen by a phone-like lens (barrel distortion) from 55 mm (a cropped photo) or
                  29 mm (an ultrawide close-up), its base coming in from the image border, JPEG 85
  defocus         the polished wrist with a thin lens focused 0.8-1.2 mm behind it (edges spread a few px)

Run:  python benchmarks/make_pbr_gallery.py [--only NAME ...] [--out tests/data/pbr] [--list]
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from notchfit.io import load_geometry
from notchfit.io.outputs import atomic_write, write_json_atomic
from notchfit.vision.render import pivot_closure_angles
from notchfit.vision.render.pbr import PbrScene, render_pbr

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "data" / "pbr"
WRIST = "datasets/geometry/wrist_asymmetric.toml"
NINE = "tests/data/pbr/wrist_nine.toml"
PRINTED = "tests/data/pbr/printed_tube.toml"


def _closing(geom_file, fractions):
    """Joint angles at the given fractions of each slot's closure (the pivot model's)."""
    c = pivot_closure_angles(load_geometry(ROOT / geom_file))
    return tuple(float(x) for x in np.asarray(fractions) * c)


def gallery() -> list[tuple[PbrScene, str]]:
    """The gallery's scenes and their geometry files (repository-relative)."""
    dslr = dict(image_size=(480, 800), px_per_mm=80.0, focal_px=60.0 * 80.0, spp=30, jpeg_quality=92)
    out = [
        (PbrScene("chuck_a", "polished-chuck", (0.15, 0.2, 0.25, 0.25, 0.2), base_at=0.2, seed=1, **dslr), WRIST),
        (PbrScene("chuck_b", "polished-chuck", (0.05, 0.05, 0.06, 0.05, 0.04), base_at=0.2, angle_deg=95.0,
                  roughness=0.05, key_light=(60.0, 30.0), seed=2, **dslr), WRIST),
        (PbrScene("chuck_c", "polished-chuck", (0.3, 0.32, 0.35, 0.3, 0.3), base_at=0.2, angle_deg=84.0,
                  roughness=0.12, tilt_deg=2.0, seed=3, **dslr), WRIST),
        (PbrScene("chuck_full", "polished-chuck", (0.25, 0.3, 0.35, 0.35, 0.3), base_at=0.18, room=0.008, seed=11,
                  **{**dslr, "image_size": (800, 1000), "px_per_mm": 130.0, "focal_px": 60.0 * 130.0, "spp": 20}),
         WRIST),
        (PbrScene("closed_a", "closed-grid", _closing(NINE, [0.5, 0.6, 0.8, 0.9, 0.95, 0.97, 0.97, 0.9, 0.8]),
                  backdrop="grid", tendon=True, droplet=True, base_at=0.18, seed=4,
                  **{**dslr, "px_per_mm": 60.0, "focal_px": 3600.0, "image_size": (640, 800)}), NINE),
        (PbrScene("closed_b", "closed-grid", _closing(NINE, [0.97] * 9), backdrop="grid", tendon=True,
                  droplet=True, base_at=0.18, key_light=(150.0, 40.0), seed=5,
                  **{**dslr, "px_per_mm": 60.0, "focal_px": 3600.0, "image_size": (640, 800)}), NINE),
        (PbrScene("closed_c", "closed-grid", _closing(NINE, [0.9, 0.95, 0.98, 0.98, 0.98, 0.95, 0.9, 0.9, 0.9]),
                  backdrop="grid", tendon=True, droplet=True, base_at=0.18, angle_deg=100.0, seed=6,
                  **{**dslr, "px_per_mm": 50.0, "focal_px": 3000.0, "image_size": (640, 800)}), NINE),
        (PbrScene("tendon_a", "tendon-loop", (0.1, 0.12, 0.15, 0.15, 0.12), tendon=True, droplet=True,
                  base_at=0.15, seed=7, **{**dslr, "px_per_mm": 60.0, "focal_px": 3600.0,
                                           "image_size": (560, 800)}), WRIST),
        (PbrScene("tendon_b", "tendon-loop", (0.25, 0.28, 0.3, 0.3, 0.3), tendon=True, droplet=True,
                  base_at=0.15, angle_deg=80.0, key_light=(45.0, 35.0), seed=8,
                  **{**dslr, "px_per_mm": 60.0, "focal_px": 3600.0, "image_size": (560, 800)}), WRIST),
        (PbrScene("defocus_a", "defocus", (0.2, 0.2, 0.22, 0.2, 0.2), aperture=1.0e-3, focus_offset=0.8e-3,
                  base_at=0.2, seed=9, **dslr), WRIST),
        (PbrScene("defocus_b", "defocus", (0.1, 0.15, 0.2, 0.25, 0.3), aperture=1.5e-3, focus_offset=-1.2e-3,
                  base_at=0.2, angle_deg=92.0, seed=10, **dslr), WRIST),
    ]
    phone = dict(tube="printed", backdrop="blue", holder="none", backdrop_gap=3.0e-3, image_size=(540, 660),
                 px_per_mm=20.0, focal_px=580.0, dist=(-0.06, 0.01, 0.0, 0.0, 0.0), base_at=-0.08,
                 key_light=(100.0, 25.0), spp=20, jpeg_quality=85, noise_dn=1.5)
    for k, (amp, ang) in enumerate(((0.06, 90.0), (-0.08, 70.0), (0.1, 180.0))):
        rng = np.random.default_rng(20 + k)
        th = tuple(float(t) for t in np.clip(amp + rng.normal(0, 0.02, 12), -0.3, 0.3))
        lens = {"focal_px": 1100.0} if k < 2 else {}      # a cropped phone photo at 55 mm; an ultrawide at 29 mm
        out.append((PbrScene(f"printed_{'abc'[k]}", "printed-paper", th, angle_deg=ang, seed=20 + k,
                             **{**phone, **lens}), PRINTED))
    return out


def truth_record(scene: PbrScene, geom_file: str, render, image_name: str) -> dict:
    import mitsuba

    return {"name": scene.name, "kind": scene.kind, "image": image_name, "geometry": geom_file,
            "px_per_mm": scene.px_per_mm, "theta_rad": list(scene.theta), "scene": scene.to_dict(),
            **render.truth.to_dict(), "render_seconds": round(render.seconds, 2),
            "renderer": f"mitsuba {mitsuba.__version__} scalar_rgb"}


def write_scene(scene: PbrScene, geom_file: str, out: Path) -> dict:
    """Render one scene and write its image and truth; the truth record."""
    geom = load_geometry(ROOT / geom_file)
    r = render_pbr(scene, geom)
    if r.encoded is not None:
        name = f"{scene.name}.jpg"
        atomic_write(out / name, lambda p: p.write_bytes(r.encoded))
    else:
        name = f"{scene.name}.png"
        ok, buf = cv2.imencode(".png", r.image)
        atomic_write(out / name, lambda p: p.write_bytes(buf.tobytes()))
    rec = truth_record(scene, geom_file, r, name)
    write_json_atomic(rec, out / f"{scene.name}.json")
    return rec


def write_table(out: Path) -> None:
    """truth.csv: every scene's corners (scene, kind, point, u_px, v_px, visible)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scene", "kind", "point", "u_px", "v_px", "visible"])
    for p in sorted(out.glob("*.json")):
        rec = json.loads(p.read_text())
        for q in rec["points"]:
            w.writerow([rec["name"], rec["kind"], q["point"], f"{q['u_px']:.4f}", f"{q['v_px']:.4f}",
                        int(q["visible"])])
    atomic_write(out / "truth.csv", lambda p: p.write_text(buf.getvalue()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", nargs="*", help="render only these scenes")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--list", action="store_true", help="list the scenes and exit")
    a = ap.parse_args(argv)
    scenes = [(s, g) for s, g in gallery() if not a.only or s.name in a.only]
    if a.list:
        for s, g in scenes:
            print(f"{s.name:12s} {s.kind:15s} {s.image_size[0]}x{s.image_size[1]} {s.px_per_mm:g} px/mm "
                  f"{s.spp} spp  {g}")
        return 0
    try:
        import mitsuba  # noqa: F401
    except ModuleNotFoundError:
        print("make_pbr_gallery: Mitsuba 3 is not installed (pip install notchfit[pbr])", file=sys.stderr)
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    total = time.perf_counter()
    for s, g in scenes:
        rec = write_scene(s, g, a.out)
        n_vis = sum(q["visible"] for q in rec["points"])
        print(f"{s.name:12s} {s.kind:15s} {rec['render_seconds']:6.1f} s  {n_vis}/{len(rec['points'])} corners "
              "visible", flush=True)
    write_table(a.out)
    print(f"{len(scenes)} scenes in {time.perf_counter() - total:.0f} s -> {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
