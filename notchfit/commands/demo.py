"""``notchfit demo``: the main job on a built-in synthetic study with one hidden effect."""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import time
from pathlib import Path

from .. import io
from ..analysis import diagnosis
from ..io.interrupts import deferred_interrupts
from ..progress import Steps, bar as progress_bar
from ..report import SECTIONS, build_report, summary_lines
from ..studies.synth import generate_study, load_recipe
from . import _common as common
from . import detect, fit, simulate
from ._common import EXIT_INPUT_ERROR, EXIT_ITEMS_FAILED, InputError, call, count_option, jobs_option
from ._points import MISSING_HINT, source_lines
from ._wrist_demo import run_wrist_demo
from .diagnose import write_diagnosis

NAME = "demo"
ORDER = 0
HELP = "run the whole pipeline on a built-in synthetic study with one hidden effect"
DESCRIPTION = """Run the main job on a built-in example: generate a small synthetic study in which
one physical effect the paper's model lacks is hidden (default: friction between the load
cell and the base), then run the pipeline a lab would run on its own data:

  synth -> [detect, when images are rendered] -> fit -> simulate -> diagnose -> report

and print where the report is and a three-line summary: the shape-fit errors, the cause the
diagnosis names, and the gain of the extended model on held-out experiments. The hidden
truth (OUT/study/truth.json) is read only to print it after the summary.

The full demo has 6 experiments and 162 rendered images (0.05 mm per pixel, lossless PNG);
--small has 4 experiments and notch points without images (much faster; docs/history.md has
measured run times and output sizes).

Outputs: OUT/study/ (the synthetic study) and OUT/results/ (detections and their overlays,
fits, simulation, diagnosis, report.html); about 150 MB for the full demo, 10 MB with --small.
The default OUT, ./notchfit-demo, is in the repository's .gitignore.

Examples:
  notchfit demo
  notchfit demo --out /tmp/demo --force
  notchfit demo --small                       # a smaller, faster study (points, no images)
  notchfit demo --no-images                   # the full study from notch points
  notchfit demo --cause stiffness_gradient --seed 3
  notchfit demo --tube wrist                  # two nitinol wrists of one stock, notch angles -> identify
"""

#: Built-in sizes: (experiments, samples on the loading ramp, on the unloading ramp).
SIZES = {"full": (6, 12, 14), "small": (4, 8, 10)}
#: Pixel size of the rendered images [mm/px] (unless the recipe's [images] sets one): every
#: corner is still found with 0.0035 mm rms (docs/robustness.md), and the study's lossless
#: images take a third of the space of 0.03 mm/px (docs/history.md).
IMAGE_MM_PER_PX = 0.05


def add_arguments(parser) -> None:
    parser.add_argument("--out", type=Path, default=Path("notchfit-demo"),
                        help="output folder (default ./notchfit-demo)")
    parser.add_argument("--small", action="store_true", help="a smaller study (faster)")
    parser.add_argument("--cause", default="proximal_friction",
                        help="hidden effect: a recipe name in datasets/recipes (default proximal_friction)")
    parser.add_argument("--seed", type=count_option(0), default=7, help="seed of the synthetic study (default 7)")
    parser.add_argument("--images", action=argparse.BooleanOptionalAction, default=None,
                        help="render one image per sample and run detect on them (default: yes for the "
                             "full demo, no with --small, which then uses the notch points directly)")
    parser.add_argument("--jobs", type=jobs_option, default=None, help="worker processes (default: up to 2)")
    parser.add_argument("--force", action="store_true", help="replace an earlier demo in --out")
    parser.add_argument("--tube", choices=("seed", "wrist"), default="seed",
                        help="seed: the paper's tube (default); wrist: two synthetic nitinol wrists of one stock "
                             "measured as notch angles, ending in identify and simulate with the identified model")


def _step(name: str, t0: float) -> float:
    t = time.perf_counter()
    print(f"[{t - t0:6.1f} s] {name}", flush=True)
    return t


def demo_study(study_dir, *, cause: str = "proximal_friction", small: bool = False, images=None, seed: int = 7,
               jobs: int = 1) -> tuple:
    """Write the demo's synthetic study into ``study_dir`` (what ``notchfit demo`` analyses).

    Returns
    -------
    recipe : notchfit.studies.synth.Recipe
        The recipe as scaled for the demo.
    images : bool
        Whether images were rendered (default: yes for the full demo, no with
        ``small``; never for ``calibration_error``, whose warp acts on points).
    """
    n_exp, n_up, n_down = SIZES["small" if small else "full"]
    images = (not small) if images is None else bool(images)
    recipe = load_recipe(cause)
    if images and recipe.cause == "calibration_error":
        images = False          # its warp acts on points (notchfit.studies.synth.write_study)
    recipe = recipe.scaled(n_experiments=n_exp, n_up=n_up, n_down=n_down)
    recipe = recipe.replace(image_options={"mm_per_px": IMAGE_MM_PER_PX, **recipe.image_options})
    generate_study(recipe, study_dir, seed=seed, force=True, jobs=jobs, images=images)
    return recipe, images


#: What a demo writes into its --out folder (all of it is replaced with --force, nothing else is touched).
PARTS = ("study", "results")


@contextlib.contextmanager
def whole_or_nothing(out: Path):
    """Run a demo into folder ``out`` as a whole: an error or Ctrl-C leaves ``out`` as it was.

    An earlier demo's ``study/`` and ``results/`` in ``out`` (replaced with
    ``--force``) are renamed aside while the new one runs, deleted once it has
    finished, and renamed back after an error or an interruption; what the
    new run wrote is removed, and so are the folders it created. Nothing
    else in ``out`` is touched. So an interrupted demo leaves the earlier
    one, or nothing, and a plain rerun works.
    """
    new = common.new_folders(out)
    asides = {}
    for name in PARTS:
        part = out / name
        if part.exists() or part.is_symlink():
            asides[part] = out / f".{name}.previous-{os.getpid()}"
            os.replace(part, asides[part])
    try:
        yield
    except BaseException:
        with deferred_interrupts():
            for name in PARTS:
                _remove(out / name)
            for part, aside in asides.items():
                os.replace(aside, part)
            common.remove_empty(new)
        raise
    for aside in asides.values():
        _remove(aside)


def _remove(path: Path) -> None:
    """Remove a file or a folder tree (nothing when absent)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


def run(args) -> int:
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: is a file, not a folder")
    if out.exists() and any(out.iterdir()) and not args.force:
        raise FileExistsError(f"{out}: holds an earlier demo; use --force to replace it or --out elsewhere")
    with whole_or_nothing(out):
        if args.tube == "wrist":
            return run_wrist_demo(args)
        return _run_seed(args)


def _run_seed(args) -> int:
    """The default demo (the paper's tube, one hidden effect) into the empty ``args.out``."""
    jobs = args.jobs if args.jobs is not None else max(1, min(2, os.cpu_count() or 1))
    out = Path(args.out)
    study_dir, res_dir = out / "study", out / "results"
    t0 = time.perf_counter()
    _step(f"synth: recipe {args.cause}, the {'small' if args.small else 'full'} study, seed {args.seed} "
          f"-> {study_dir}", t0)
    recipe, images = demo_study(study_dir, cause=args.cause, small=args.small, images=args.images,
                                seed=args.seed, jobs=jobs)
    common = ["--out", str(res_dir), "--jobs", str(jobs)]
    commands = []
    if images:
        commands.append((detect, [str(study_dir), *common]))
    commands += [(fit, [str(study_dir), "--models", "cc,linear", *common]),
                 (simulate, [str(study_dir), *common])]
    failed = []
    for command, argv in commands:
        _step(f"{command.NAME}", t0)
        rc = call(command, argv)
        if rc == EXIT_INPUT_ERROR:
            raise InputError(f"the {command.NAME} step failed (see the message above)")
        if rc == EXIT_ITEMS_FAILED:
            failed.append(command.NAME)
    _step("diagnose", t0)
    with Steps("diagnose") as steps:
        diagnose(study_dir, res_dir, jobs=jobs, seed=args.seed, progress=steps)
    _step("report", t0)
    with progress_bar(len(SECTIONS), "report", unit="sections") as bar:
        path = build_report(res_dir, study=study_dir, force=True, progress=lambda _: bar.update(1),
                            title=f"notchfit demo: a synthetic study with a hidden effect (seed {args.seed})")
    t = time.perf_counter() - t0
    print(f"\nreport: {path}   ({t:.0f} s; open it in a browser)")
    for line in summary_lines(res_dir):
        print(line)
    try:
        truth = io.read_json(study_dir / "truth.json")
        eff = ", ".join(f"{k} = {v:.4g}" for k, v in truth.get("effect", {}).items())
        print(f"(hidden in the synthetic data: {truth.get('cause')}" + (f", {eff})" if eff else ")"))
    except (ValueError, FileNotFoundError):
        pass
    if failed:
        print(f"some items failed in: {', '.join(failed)} (listed above)")
        return EXIT_ITEMS_FAILED
    return 0


def diagnose(study_dir: Path, out_dir: Path, *, jobs: int = 1, seed: int = 0, progress=None) -> dict:
    """The diagnose step: the study's experiments diagnosed, the results written into ``out_dir``.

    Points are looked for as ``notchfit diagnose`` looks for them (the
    experiments' own files, then ``out_dir``); ``progress`` is called with
    each step of the diagnosis.
    """
    lookup = io.find_points(io.read_study(study_dir), [("--out", out_dir)])
    for line in source_lines(lookup, "diagnose"):
        print(f"  {line}")
    for name, why in lookup.problems.items():
        print(f"  diagnose: leaving out {name}: {why}; {MISSING_HINT}")
    if not lookup.experiments:
        raise InputError("diagnose: no experiment has notch points")
    diag = diagnosis.diagnose(list(lookup.experiments), jobs=jobs, seed=seed, progress=progress)
    if progress is not None:
        progress("writing diagnosis.json and the figures")
    return write_diagnosis(diag, out_dir)
