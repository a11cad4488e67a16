"""Hidden-effect confusion matrix (issue 8): which cause diagnose names for each hidden one.

Every recipe of ``datasets/recipes/`` for the six causes and the null study, reduced as in the
default test job (4 experiments, 9 + 11 samples, 2 folds) or full (``--full``: six experiments,
leave-one-out), several seeds. The generator's truth.json is deleted before each diagnosis.
Prints a Markdown table: counts of the named cause per hidden cause, and the held-out gains.

Usage: python benchmarks/confusion_matrix.py [--seeds 1,2,3] [--full] [--jobs 2]
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from collections import Counter
from pathlib import Path

from notchfit.diagnosis import CAUSES, diagnose
from notchfit.io import read_study
from notchfit.synth import generate_study, load_recipe

SMALL = dict(n_experiments=4, n_up=8, n_down=10)   # as tests/test_diagnosis_hidden.py
COLUMNS = ("none",) + CAUSES + ("unexplained",)


def run(recipe_name: str, seed: int, full: bool, jobs: int, tmp: Path):
    recipe = load_recipe(recipe_name)
    if not full:
        recipe = recipe.scaled(**SMALL)
    study = tmp / f"{recipe_name}-{seed}"
    shutil.rmtree(study, ignore_errors=True)
    generate_study(recipe, study, seed=seed)
    (study / "truth.json").unlink()
    d = diagnose(read_study(study), jobs=jobs, max_folds=6 if full else 2)
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    tmp = Path(tempfile.mkdtemp(prefix="confusion-"))
    t0 = time.perf_counter()
    try:
        head = " | ".join(c.replace("_friction", "").replace("joint_", "").replace("_load", "")
                          .replace("stiffness_", "").replace("_error", "") for c in COLUMNS)
        print(f"| hidden \\ named | {head} | held-out gain (seeds {a.seeds}) |")
        print("|" + "---|" * (len(COLUMNS) + 2))
        for hidden in ("null",) + CAUSES:
            named, gains = Counter(), []
            for s in seeds:
                d = run(hidden, s, a.full, a.jobs, tmp)
                named[d.cause] += 1
                gains.append(f"{d.gain.reduction_pct:.0f}%" if d.cause not in ("none", "unexplained")
                             else d.cause)
            want = "none" if hidden == "null" else hidden
            cells = [(f"**{named[c]}**" if c == want else str(named[c])) if named[c] else "" for c in COLUMNS]
            print(f"| {hidden} | " + " | ".join(cells) + f" | {', '.join(gains)} |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\n{len(seeds) * (len(CAUSES) + 1)} diagnoses in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
