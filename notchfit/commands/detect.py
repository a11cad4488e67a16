"""``notchfit detect``: the numbered notch corners in every image of an experiment or a study."""

from __future__ import annotations

import dataclasses
import functools
import sys
from pathlib import Path

import numpy as np

from .. import io
from .._version import __version__
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
(exit code 1 listing them); so is an image where no point at all was found (listed on
stderr, its rows NaN).

Each finished image is kept in OUT/.notchfit-resume-detect/ as it completes, so an
interrupted or killed run (Ctrl-C, SIGKILL, a full disk) is continued with --resume: only
the images not yet done, or whose file or options changed since, are detected again.

Examples:
  notchfit detect study/ --out out/
  notchfit detect study/ct045 --out out_ct045/ --jobs 2
  notchfit detect study/ --out out/ --no-overlays --force
  notchfit detect study/L045 --out out_L045/ --full-overlays
  notchfit detect study/ --out out/ --resume     (after an interrupted run)
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
    parser.add_argument("--force", action="store_true", help="replace existing detections in --out "
                        "(and start again over an interrupted run)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the interrupted run in --out: only the images not yet done, or changed "
                             "since, are detected")
    parser.add_argument("--drop-review", action="store_true",
                        help="also remove the corrections of `notchfit review` (review.csv) of the experiments "
                             "detected again (kept by default, also with --force)")


@functools.lru_cache(maxsize=8)
def _camera(path: str):
    """The camera file at ``path`` (cached per worker process)."""
    return io.read_camera(path)


def detect_one(item: dict) -> dict:
    """Detect the corners of one sample image (a batch item; module level so that it pickles).

    The worker reads the image from its path and returns what the run writes:
    the rows of ``detections.csv`` (CSV text without the header, bytes), the
    overlay (JPEG bytes, or None), the image file's SHA-256 and the sample's
    summary for ``detect_run.json``.
    """
    # slow optional dependency: the detector and the overlay are OpenCV
    from ..vision.detection import detect_notches, detections_table
    from ..figures.detection import detection_overlay

    img = io.load_image(item["image"])
    digest = io.file_sha256(item["image"])
    cam = _camera(str(item["calibration"])) if item["calibration"] is not None else None
    det = detect_notches(img, cam, item["geometry"], mirror=item["mirror"], base=item["base"],
                         tone_gamma=item.get("tone_gamma", 1.0))
    overlay = None
    if item["overlay"] is not None:
        ov = detection_overlay(img, det, item["sample"], full=item.get("full_overlay", False))
        overlay = io.encode_image(ov, ".jpg", jpeg_quality=OVERLAY_JPEG_QUALITY, name=item["overlay"])
    table = detections_table(item["sample"], det)
    return {"table_csv": table.to_csv(index=False, header=False, lineterminator="\n").encode("utf-8"),
            "overlay_jpg": overlay, "input_sha256": digest,
            "summary": {"image_status": det.image_status, "message": det.message, "n_ok": det.n_ok,
                        "n_found": int(np.isfinite(det.points[:, 0]).sum()), "base_side": det.base_side,
                        "scale_mm_per_px": det.scale_mm_per_px, "scale_sigma_mm_per_px": det.scale_sigma,
                        "assumption": det.assumption or None, "image_gamma": item.get("tone_gamma", 1.0),
                        "exif_orientation": io.image_orientation(item["image"]) or None}}


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


def _plan(scan) -> tuple[list, dict]:
    """The experiments to detect, and the failures (experiment name: reason) of the others."""
    failed: dict[str, str] = dict(scan.problems)
    plan = []
    for e in scan.experiments:
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
    if not plan:
        raise InputError("nothing to detect: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    return plan, failed


@dataclasses.dataclass
class _Items:
    """The run's batch items (one per image) with their keys, experiments and options hashes."""

    items: list
    keys: list
    owners: list
    options: list


def _items(plan, study: bool, args) -> _Items:
    out = _Items([], [], [], [])
    for e in plan:
        sub = io.experiment_output_dir("", e.name, study)
        # what shapes an experiment's results besides the image: a changed one redoes its images on --resume
        exp_hash = io.options_sha256({
            "notchfit": __version__, "geometry": dataclasses.asdict(e.geometry), "base": e.base,
            "mirror": e.mirror, "camera": None if e.calibration_path is None else io.file_sha256(e.calibration_path)})
        for s, img in zip(e.sample_ids, e.image_paths):
            ov = None if args.no_overlays else str(sub / "overlays" / f"{int(s):04d}.jpg")
            item = {"image": img, "calibration": e.calibration_path, "geometry": e.geometry, "base": e.base,
                    "mirror": e.mirror, "sample": int(s), "overlay": ov, "full_overlay": args.full_overlays,
                    "tone_gamma": image_gamma(e, img)[0]}
            out.items.append(item)
            out.keys.append(f"{e.name}/{int(s)}" if study else f"sample {int(s)}")
            out.owners.append(e.name)
            out.options.append(io.options_sha256({"experiment": exp_hash, **{k: item[k] for k in (
                "sample", "overlay", "full_overlay", "tone_gamma")}}))
    return out


def _keeper(run_, items: _Items, todo: list[int]):
    """The batch's ``on_result``: each finished image's rows, overlay and summary onto the disk at once."""
    def keep(i: int, r) -> None:
        if not r.ok:
            return                     # failed items are not kept: a resumed run tries them again
        k, v = todo[i], r.value
        ov = items.items[k]["overlay"]
        run_.keep(items.keys[k], input_sha256=v["input_sha256"], options_sha256=items.options[k],
                  value=v["summary"], stage_files={ov: v["overlay_jpg"]} if ov is not None else None,
                  own_files={".csv": v["table_csv"]})
    return keep


def _assemble(run_, plan, study: bool, items: _Items, failed: dict) -> dict:
    """Write each experiment's detections.csv from the kept items (one at a time: memory stays flat);
    returns the per-sample summaries for detect_run.json."""
    header = (",".join(io.DETECTION_COLUMNS) + "\n").encode("utf-8")
    summary = {}
    for e in plan:
        keys = [k for k, o in zip(items.keys, items.owners) if o == e.name]

        def write(tmp, keys=keys):
            with open(tmp, "wb") as fh:
                fh.write(header)
                for k in keys:
                    if run_.record(k) is not None:
                        fh.write(run_.own_file(k, ".csv").read_bytes())
        io.atomic_write(run_.path(io.experiment_output_dir("", e.name, study) / "detections.csv"), write)
        summary[e.name] = {k: (run_.record(k)["value"] if run_.record(k) is not None
                               else {"error": failed.get(k, "not detected")}) for k in keys}
    return summary


def _no_point(run_, items: _Items) -> dict[str, str]:
    """``{key: "file name: reason"}`` of the images where no point at all was found."""
    out = {}
    for k, item in zip(items.keys, items.items):
        rec = run_.record(k)
        if rec is not None and rec["value"]["n_found"] == 0:
            out[k] = f"{Path(item['image']).name}: {rec['value']['message'] or 'no point found'}"
    return out


def run(args) -> int:
    check_out_dir(args.out, args.input)
    # the folder's lock and its earlier outputs are checked before the study is read or anything printed
    earlier = ["detect_run.json"] + [str(Path(name) / "detections.csv")
                                     for name in io.find_output(args.out, "detections.csv")]
    with io.ResumableRun(args.out, name="detect", input_path=args.input, resume=args.resume, force=args.force,
                         outputs=earlier, unit="images") as run_:
        scan = io.scan_study(args.input, missing_images="keep")
        plan, failed = _plan(scan)
        assumed = _say_assumed_gamma(plan)
        items = _items(plan, scan.study, args)
        kept = run_.reconcile({k: (it["image"], h) for k, it, h in zip(items.keys, items.items, items.options)})
        todo = [i for i, k in enumerate(items.keys) if k not in kept]
        if args.resume:
            print(f"  resuming the interrupted run: {len(kept)} of {len(items.keys)} images kept, "
                  f"{len(todo)} to detect")
        res = run_batch(detect_one, [items.items[i] for i in todo], keys=[items.keys[i] for i in todo],
                        jobs=args.jobs, scheduler=args.scheduler, desc="detect", unit="images",
                        on_result=_keeper(run_, items, todo))
        for r in res.failures:
            failed[r.key] = r.error
        summary = _assemble(run_, plan, scan.study, items, failed)
        no_point = _no_point(run_, items)
        n_done = len(run_.records)
        n_all_ok = sum(run_.record(k)["value"]["image_status"] == "ok" for k in run_.records)
        turned = [(k, run_.record(k)["value"].get("exif_orientation")) for k in run_.records
                  if run_.record(k)["value"].get("exif_orientation")]
        if turned:
            print(f"  {len(turned)} images turned upright by their EXIF orientation tag (base and pixel coordinates "
                  f"refer to the picture as a photo viewer shows it), e.g. {turned[0][0]}: {turned[0][1]}")
        io.write_json_atomic(io.provenance("detect", args.input, experiments=[e.name for e in plan],
                                           samples=summary, image_gamma_assumed=assumed, failures=failed,
                                           no_point=sorted(no_point), kept_from_interrupted_run=len(kept)),
                             run_.path("detect_run.json"))
    rate = f", {len(todo) / res.seconds:.3g} images/s" if todo and res.seconds > 0 else ""
    print(f"detect: {n_done} of {len(items.keys)} images processed ({n_all_ok} with every point ok"
          + (f", {len(kept)} kept from the interrupted run" if kept else "")
          + f") in {res.seconds:.1f} s{rate}; outputs in {args.out}")
    _say_reviews(args, plan, scan.study)
    list_failures(failed, limit=len(failed))
    if no_point:
        print(f"notchfit detect: {len(no_point)} of {len(items.keys)} images gave no point at all (their rows "
              "in detections.csv are NaN):", file=sys.stderr)
        for k, why in no_point.items():
            print(f"  {k}: {why}", file=sys.stderr)
    return EXIT_ITEMS_FAILED if failed or no_point else 0


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
