"""Where the detector loses the corners of the physically based gallery: one stage per visible corner.

For every render in tests/data/pbr (with its camera file) each corner the photo shows is put in the first
stage that loses it:

- segmentation / outline / base: no silhouette variant gets as far as numbered slots (no outline, no base
  end, the base side ambiguous);
- slot mouths / numbering: the corner's slot (or the tip) is not found or not numbered;
- refine: no edges: the sub-pixel refinement finds no usable edge profiles (``occluded``);
- refine: sigma / shift: refined, but its fit's sigma or its move exceeds the limits (``ambiguous``);
- width check: its link is not 2R wide beside it on its silhouette;
- plane checks: the rigid-link, base-edge or confirmation checks in the plane;
- ok (within 3 px of the truth) and ok but farther (no other corner nearer: not a wrong identity).

It also counts, of the corners lost after they were numbered, those whose first estimate (from the
silhouette) lies more than 5 px from the truth. With --oracle the first estimates of the numbered corners
are replaced by the true corners (+2 px in u and v) before the refinement: what the refinement and the
checks make of a perfect silhouette.

The stages are recorded by wrapping ``pipeline.refine_and_finish`` (the detector itself is not
changed; where several silhouette variants are refined, a corner counts in the furthest stage any of them
took it to). Run:  python benchmarks/pbr_losses.py [--pbr-dir tests/data/pbr] [--oracle]
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))   # this checkout's notchfit, not an installed one

import notchfit.vision.detection as detection  # noqa: E402
from notchfit.io import load_geometry, load_image  # noqa: E402
from notchfit.vision.detection import pipeline  # noqa: E402
from notchfit.vision.detection.subpixel import link_widths, statuses  # noqa: E402
from notchfit.vision.render.pbr import PbrTruth, score_detection  # noqa: E402

STAGES = ("segmentation / outline / base", "slot mouths / numbering", "refine: no edges", "refine: sigma / shift",
          "width check", "plane checks", "ok, > 3 px", "ok")


class Recorder:
    """Wraps ``refine_and_finish``: records the numbered points, their first estimates [px] and the stage at
    which each refined corner is withheld; with ``oracle`` moves the first estimates to the truth."""

    def __init__(self, original):
        self.original = original
        self.truth = None
        self.oracle = False
        self.reset()

    def reset(self):
        self.specs, self.first, self.stage = None, {}, {}

    def __call__(self, gray, seg, ctx, setup, **kw):
        geom, opts = setup.geom, setup.opts
        origin = ctx.full(np.zeros((1, 2)))[0]
        factor = ctx.full(np.ones((1, 2)))[0] - origin
        specs = ctx.specs
        if self.oracle:
            pts, vis = self.truth.points_px, self.truth.visible
            specs = [dataclasses.replace(s, xy=(pts[s.point] + 2.0 - origin) / factor)
                     if vis[s.point] and np.all(np.isfinite(pts[s.point])) else s for s in specs]
            ctx = dataclasses.replace(ctx, specs=specs)
        run = self.original(gray, seg, ctx, setup, **kw)
        ref = run.refinement
        # every silhouette variant that located corners is refined: the union of their corners, each in the
        # furthest stage any variant took it to, its first estimate from the first variant that located it
        self.specs = (self.specs or set()) | {s.point for s in specs}
        for s in specs:
            self.first.setdefault(s.point, s.xy * factor + origin)
        if ref is not None:
            st = statuses(ref, geom.n_points, list(ctx.status), gray.shape, opts)[0]
            mask = kw.get("width_mask")
            wid = None if mask is None else link_widths(ref, mask, setup.f, setup.camera, setup.px_per_m,
                                                        geom.outer_radius)
            for q, i in enumerate(ref.pidx):
                if not ref.ok[q] or st[i] == "occluded":
                    stage = STAGES[2]
                elif st[i] != "ok":
                    stage = STAGES[3]
                elif wid is not None and abs(wid[q] / (2 * geom.outer_radius) - 1) > opts.width_tol:
                    stage = STAGES[4]
                else:
                    stage = STAGES[5]
                old = self.stage.get(int(i), STAGES[2])
                self.stage[int(i)] = max(old, stage, key=STAGES.index)
        return run


def losses(folder, oracle=False):
    """Per scene kind: a Counter of stages over the visible corners, and (lost after numbering, of them with
    the first estimate > 5 px off) per kind."""
    rec_ = Recorder(pipeline.refine_and_finish)
    rec_.oracle = oracle
    pipeline.refine_and_finish = rec_
    root = Path(__file__).resolve().parent.parent
    rows = collections.defaultdict(collections.Counter)
    far = collections.defaultdict(lambda: [0, 0])
    try:
        for p in sorted(Path(folder).glob("*.json")):
            rec = json.loads(p.read_text())
            truth = PbrTruth.from_dict(rec)
            geom = load_geometry(root / rec["geometry"])
            img = load_image(Path(folder) / rec["image"])
            rec_.reset()
            rec_.truth = truth
            det = detection.detect_notches(img, truth.camera, geom, mirror=truth.pose.plane[3])
            score = score_detection(det, truth, rec["px_per_mm"])
            assert score.wrong == 0, f"{p.stem}: a wrong identity"
            d = np.linalg.norm(np.asarray(det.points_px) - truth.points_px, axis=1)
            for i in np.nonzero(truth.visible)[0]:
                if rec_.specs is None:
                    stage = STAGES[0]
                elif i not in rec_.specs:
                    stage = STAGES[1]
                elif det.status[i] == "ok":
                    stage = STAGES[7] if d[i] <= 3 else STAGES[6]
                else:
                    stage = rec_.stage.get(int(i), STAGES[2])
                    far[rec["kind"]][0] += 1
                    far[rec["kind"]][1] += int(np.linalg.norm(rec_.first[i] - truth.points_px[i]) > 5)
                rows[rec["kind"]][stage] += 1
    finally:
        pipeline.refine_and_finish = rec_.original
    return rows, far


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pbr-dir", default=str(Path(__file__).resolve().parent.parent / "tests" / "data" / "pbr"))
    ap.add_argument("--oracle", action="store_true", help="first estimates at the true corners (+2 px)")
    a = ap.parse_args(argv)
    rows, far = losses(a.pbr_dir, a.oracle)
    print("| scene kind | " + " | ".join(STAGES) + " | lost after numbering, first estimate > 5 px off |")
    print("|---" * (len(STAGES) + 2) + "|")
    total, tf = collections.Counter(), [0, 0]
    for kind in sorted(rows):
        total.update(rows[kind])
        tf = [tf[0] + far[kind][0], tf[1] + far[kind][1]]
        print(f"| {kind} | " + " | ".join(str(rows[kind][s]) for s in STAGES) + f" | {far[kind][1]} of {far[kind][0]} |")
    print("| all | " + " | ".join(str(total[s]) for s in STAGES) + f" | {tf[1]} of {tf[0]} |")


if __name__ == "__main__":
    main()
