"""``notchfit demo --tube wrist``: two synthetic nitinol wrists of one stock, measured as notch angles.

The real-tube counterpart of the default demo (``notchfit.commands.demo``): the
recipe ``wrist_stock`` (a 5-notch asymmetric wrist and a 4-notch tip-first,
pre-curved wrist, repeated loading-only trials, the angle of every notch
measured with 0.5° noise) is generated, then the job a lab runs on its own
wrists:

  synth -> fit (angle-space shape models) -> identify -> simulate --model (the identified model) -> report

and the identified material is printed beside the hidden truth (read from
``truth.json`` only for that line). Outputs: ``OUT/study/`` and ``OUT/results/``.
"""

from __future__ import annotations

import time
from pathlib import Path

from .. import io
from ..report import build_report
from ..studies.synth import generate_study, load_recipe
from . import fit, simulate
from . import identify as identify_cmd
from ._common import EXIT_INPUT_ERROR, EXIT_ITEMS_FAILED, InputError, call

__all__ = ["RECIPE", "run_wrist_demo"]

#: The shipped recipe of the wrist demo.
RECIPE = "wrist_stock"
#: Samples per loading ramp: full demo, ``--small``.
N_UP = {"full": 14, "small": 8}


def _step(name: str, t0: float) -> None:
    print(f"[{time.perf_counter() - t0:6.1f} s] {name}", flush=True)


def _truth_line(study_dir: Path, results: Path) -> list[str]:
    """Identified material beside the hidden truth (read only to print it)."""
    try:
        truth = io.read_json(study_dir / "truth.json")["params"]
        found = io.read_json(results / "identify.json")
    except (OSError, ValueError, KeyError):
        return []
    keys = {"E_lin_Pa": "E_lin", "E_se_Pa": "E_se", "strain_lower": "strain_lower", "mu_d": "mu_d"}
    parts = [f"{k} {found['params'][k]:.4g} ± {found['se'][k]:.2g} (truth {truth[f]:.4g})"
             for k, f in keys.items() if k in found["params"] and f in truth]
    return ["identified: " + "; ".join(parts)]


def run_wrist_demo(args) -> int:
    """The wrist demo (module docstring); ``args`` as ``notchfit demo`` parses them."""
    jobs = args.jobs if args.jobs is not None else 1
    out = Path(args.out)
    study_dir, res_dir = out / "study", out / "results"
    if out.exists() and any(out.iterdir()) and not args.force:
        raise FileExistsError(f"{out}: holds an earlier demo; use --force to replace it or --out elsewhere")
    recipe = load_recipe(RECIPE).scaled(n_up=N_UP["small" if args.small else "full"])
    t0 = time.perf_counter()
    _step(f"synth: recipe {recipe.name} (two wrists of one stock, notch angles), seed {args.seed} -> {study_dir}",
          t0)
    generate_study(recipe, study_dir, seed=args.seed, force=True, jobs=jobs)
    common = ["--out", str(res_dir), "--jobs", str(jobs), "--force"]
    steps = [(fit, [str(study_dir), "--models", "cc,linear", "--no-figures", *common]),
             (identify_cmd, [str(study_dir), *common]),
             (simulate, [str(study_dir), "--model", str(res_dir / "model.toml"), *common])]
    failed = []
    for command, argv in steps:
        _step(command.NAME, t0)
        rc = call(command, argv)
        if rc == EXIT_INPUT_ERROR:
            raise InputError(f"the {command.NAME} step failed (see the message above)")
        if rc == EXIT_ITEMS_FAILED:
            failed.append(command.NAME)
    _step("report", t0)
    report = build_report(res_dir, study=study_dir, force=True,
                          title=f"notchfit demo: two synthetic wrists of one stock (seed {args.seed})")
    print(f"\nreport: {report}   (open it in a browser)")
    print(f"results: {res_dir.resolve()}   ({time.perf_counter() - t0:.0f} s); "
          f"angle noise {recipe.angle_sigma_deg:g} deg")
    for line in _truth_line(study_dir, res_dir):
        print(line)
    if failed:
        print(f"some items failed in: {', '.join(failed)} (listed above)")
        return EXIT_ITEMS_FAILED
    return 0
