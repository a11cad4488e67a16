"""``notchfit detect``: the numbered notch corners in every image of an experiment or a study."""

from __future__ import annotations

import functools
from pathlib import Path

import pandas as pd

from .. import io
from ..batch import run_batch
from ..units import MM
from ._common import EXIT_ITEMS_FAILED, InputError, add_batch_options, check_out_dir, list_failures

NAME = "detect"
ORDER = 30
HELP = "find the notch corners in the images of an experiment or a study (detections.csv + overlays)"
DESCRIPTION = """Find the 4 + 2n numbered notch corners (docs/geometry.md) in every sample image of an
experiment, or of every experiment of a study, with the experiment's camera file
(experiment.toml `calibration`, written by `notchfit calibrate`; without one, the scale comes
from the tube's outer diameter, stated in the log and in detect_run.json with its uncertainty).
experiment.toml `base = "top" | "bottom" | "left" | "right"` states where the tube enters the
photographs (found from the holder or the image border otherwise). The detector works on the
silhouette only (no kinematic model): sharp corners of the outline in the calibrated plane,
slots recognised by their width and depth, sub-pixel line fits to edge profiles.

Writes detections.csv (sample,point,x_mm,y_mm,u_px,v_px,sigma_mm,status; status ok,
ambiguous or occluded; NaN where a point was not found, never a guess), an overlay per
sample in overlays/NNNN.jpg (a crop around the tube, its longer side 1000 px, with the outline
and the numbered corners coloured by status; --full-overlays adds the whole view beside it), and
detect_run.json (per-sample image status and messages); for a study, into
OUT/<experiment>/. A missing or corrupt image is reported and the other samples finish
(exit code 1 listing them).

Examples:
  notchfit detect study/ --out out/
  notchfit detect study/ct045 --out out_ct045/ --jobs 2
  notchfit detect study/ --out out/ --no-overlays --force
  notchfit detect study/L045 --out out_L045/ --full-overlays
"""

#: JPEG quality of the overlays (they are looked at, never measured again: lossy is fine).
OVERLAY_JPEG_QUALITY = 85
#: The tone curve assumed for a camera's JPEG files when experiment.toml gives no ``image_gamma``
#: (sRGB-like encoding; edges are found in linear light, where a blurred edge's 50 % crossing
#: is the edge). Other formats (PNG, TIFF: renders, scientific cameras) are taken as linear.
JPEG_GAMMA = 2.2
_JPEG_SUFFIXES = (".jpg", ".jpeg")


def image_gamma(exp, image) -> tuple[float, bool]:
    """The tone-curve exponent to undo for ``image`` of ``exp``, and whether it was assumed.

    ``image_gamma`` of experiment.toml when given; else :data:`JPEG_GAMMA` for a
    JPEG file and 1 (linear light) for any other format.
    """
    if exp.image_gamma is not None:
        return exp.image_gamma, False
    return (JPEG_GAMMA if Path(image).suffix.lower() in _JPEG_SUFFIXES else 1.0), True


def add_arguments(parser) -> None:
    parser.add_argument("input", type=Path, help="experiment folder or study folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    add_batch_options(parser)
    parser.add_argument("--no-overlays", action="store_true", help="skip the overlay images")
    parser.add_argument("--full-overlays", action="store_true",
                        help="overlays show the whole view beside the crop around the tube (larger files)")
    parser.add_argument("--force", action="store_true", help="replace existing detections in --out")
    parser.add_argument("--drop-review", action="store_true",
                        help="also remove the corrections of `notchfit review` (review.csv) of the experiments "
                             "detected again (kept by default, also with --force)")


@functools.lru_cache(maxsize=8)
def _camera(path: str):
    """The camera file at ``path`` (cached per worker process)."""
    return io.read_camera(path)


def detect_one(item: dict) -> dict:
    """Detect the corners of one sample image (a batch item; module level so that it pickles)."""
    # slow optional dependency: the detector and the overlay are OpenCV
    from ..detection import detect_notches, detections_table
    from ..figures.detection import detection_overlay

    img = io.load_image(item["image"])
    cam = _camera(str(item["calibration"])) if item["calibration"] is not None else None
    det = detect_notches(img, cam, item["geometry"], mirror=item["mirror"], base=item["base"],
                         tone_gamma=item.get("tone_gamma", 1.0))
    if item["overlay"] is not None:
        ov = detection_overlay(img, det, item["sample"], full=item.get("full_overlay", False))
        # the run made the folder in its staging area; no mkdir here: a task still running on a Dask
        # worker after the run was interrupted must not bring back the staging folder it removed
        io.write_image(item["overlay"], ov, jpeg_quality=OVERLAY_JPEG_QUALITY, make_folder=False)
    return {"table": detections_table(item["sample"], det), "image_status": det.image_status,
            "message": det.message, "n_ok": det.n_ok, "base_side": det.base_side,
            "scale_mm_per_px": det.scale_mm_per_px, "scale_sigma_mm_per_px": det.scale_sigma,
            "assumption": det.assumption or None, "image_gamma": item.get("tone_gamma", 1.0),
            "exif_orientation": io.image_orientation(item["image"]) or None}


def _say_assumed_gamma(exps) -> list[str]:
    """One line per experiment whose JPEG images are taken as a camera's tone curve (assumed, not
    stated); returns their names, sorted (``image_gamma_assumed`` of detect_run.json)."""
    names = []
    for e in exps:
        if any(p is not None and image_gamma(e, p) == (JPEG_GAMMA, True) for p in e.image_paths or ()):
            names.append(e.name)
            print(f"  {e.name}: JPEG images and no image_gamma in experiment.toml: assumed a camera's tone "
                  f"curve (gamma {JPEG_GAMMA:g}), undone before the edges are found (image_gamma = 1 if "
                  "the files hold linear light)")
    return sorted(names)


def run(args) -> int:
    check_out_dir(args.out, args.input)
    scan = io.scan_study(args.input, missing_images="keep")
    exps, study = scan.experiments, scan.study
    failed: dict[str, str] = dict(scan.problems)
    plan = []           # (experiment, items, keys)
    for e in exps:
        if e.image_paths is None:
            failed[e.name] = "samples.csv has no image column"
            continue
        if e.calibration_path is None:
            print(f"  {e.name}: no camera file: the scale comes from the tube's outer diameter "
                  f"({2 * e.geometry.outer_radius / MM:g} mm) in a fronto-parallel view, x_mm/y_mm in the "
                  "image axes (x right, y down); detect_run.json gives the scale and its uncertainty")
            plan.append(e)
            continue
        if not Path(e.calibration_path).is_file():
            failed[e.name] = f"camera file not found: {e.calibration_path}"
            continue
        try:
            _camera(str(e.calibration_path))
        except ValueError as exc:
            failed[e.name] = str(exc)
            continue
        plan.append(e)
    assumed = _say_assumed_gamma(plan)
    if not plan:
        raise InputError("nothing to detect: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    outputs = ["detect_run.json"] + [str(io.experiment_output_dir("", e.name, study) / "detections.csv")
                                     for e in plan]
    summary = {}
    n_total = n_ok_images = 0
    with io.OutputRun(args.out, outputs=outputs, force=args.force, name="detect") as run_:
        items, keys, owners = [], [], []
        for e in plan:
            sub = io.experiment_output_dir("", e.name, study)
            for s, img in zip(e.sample_ids, e.image_paths):
                ov = None if args.no_overlays else run_.path(sub / "overlays" / f"{int(s):04d}.jpg")
                items.append({"image": img, "calibration": e.calibration_path, "geometry": e.geometry,
                              "base": e.base, "mirror": e.mirror, "sample": int(s), "overlay": ov,
                              "full_overlay": args.full_overlays, "tone_gamma": image_gamma(e, img)[0]})
                keys.append(f"{e.name}/{int(s)}" if study else f"sample {int(s)}")
                owners.append(e.name)
        res = run_batch(detect_one, items, keys=keys, jobs=args.jobs, scheduler=args.scheduler, desc="detect",
                        unit="images")
        n_total = len(items)
        for e in plan:
            sub = io.experiment_output_dir("", e.name, study)
            rows = [r for r, o in zip(res.items, owners) if o == e.name]
            tables = [r.value["table"] for r in rows if r.ok]
            df = (pd.concat(tables, ignore_index=True) if tables
                  else pd.DataFrame(columns=list(io.DETECTION_COLUMNS)))
            io.write_table_atomic(df, run_.path(sub / "detections.csv"))
            summary[e.name] = {r.key: ({k: v for k, v in r.value.items() if k != "table"} if r.ok
                                       else {"error": r.error}) for r in rows}
            n_ok_images += sum(1 for r in rows if r.ok and r.value["image_status"] == "ok")
        for r in res.failures:
            failed[r.key] = r.error
        turned = [(r.key, r.value["exif_orientation"]) for r in res.items if r.ok and r.value.get("exif_orientation")]
        if turned:
            print(f"  {len(turned)} images turned upright by their EXIF orientation tag (base and pixel coordinates "
                  f"refer to the picture as a photo viewer shows it), e.g. {turned[0][0]}: {turned[0][1]}")
        io.write_json_atomic(io.provenance("detect", args.input, experiments=[e.name for e in plan],
                                           samples=summary, image_gamma_assumed=assumed, failures=failed),
                             run_.path("detect_run.json"))
    n_done = sum(r.ok for r in res.items)
    print(f"detect: {n_done} of {n_total} images processed ({n_ok_images} with every point ok) "
          f"in {res.seconds:.1f} s; outputs in {args.out}")
    _say_reviews(args, plan, study)
    list_failures(failed, limit=len(failed))
    return EXIT_ITEMS_FAILED if failed else 0


def _say_reviews(args, plan, study) -> None:
    """``notchfit review``'s corrections beside the new detections: kept (said), or removed with --drop-review."""
    for e in plan:
        rev = io.review_path(Path(args.out) / io.experiment_output_dir("", e.name, study) / "detections.csv")
        if rev.is_file() and args.drop_review:
            rev.unlink()
            print(f"  {e.name}: removed the corrections {rev} (--drop-review)")
        elif rev.is_file():
            print(f"  {e.name}: kept the corrections {rev} (notchfit review); fit and the others apply them to "
                  "the new detections (--drop-review removes them)")
