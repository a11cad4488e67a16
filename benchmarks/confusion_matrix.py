"""Hidden-effect confusion matrix (issues 8, 19): which causes diagnose names for each hidden one, and pair.

Singles: every recipe of ``datasets/recipes/`` for the six causes, the null study, and joint hysteresis
from the generator's other laws (``joint_hysteresis_flag``: a two-branch superelastic plateau,
``joint_hysteresis_masing``: Bouc-Wen loops). Pairs: every pair of the five nameable causes, each effect
from its one-cause recipe's range (``notchfit.studies.recipes.combine_recipes``). Studies are reduced as in the
default test job (4 experiments, 9 + 11 samples, 2 folds) or full (``--full``: six experiments,
leave-one-out), several seeds. The generator's truth.json is deleted before each diagnosis.
Prints Markdown tables: counts of the first named cause per hidden cause (and of studies given a second
cause), and per pair how many studies were named exactly that pair, with the held-out gains.

Usage: python benchmarks/confusion_matrix.py [--seeds 1,2,3] [--pair-seeds 1,2] [--full] [--jobs 2]
                                              [--no-singles] [--no-pairs] [--pairs a+b,c+d]
"""
from __future__ import annotations

import argparse
import itertools
import shutil
import tempfile
import time
from collections import Counter
from pathlib import Path

from notchfit.analysis.diagnosis import CAUSES, diagnose
from notchfit.io import read_study
from notchfit.studies.recipes import combine_recipes
from notchfit.studies.synth import generate_study, load_recipe

SMALL = dict(n_experiments=4, n_up=8, n_down=10)   # as tests/test_diagnosis_hidden.py
COLUMNS = ("none",) + CAUSES + ("unexplained",)
NAMEABLE = ("proximal_friction", "joint_hysteresis", "external_load", "stiffness_gradient", "calibration_error")
OTHER_LAWS = {"joint_hysteresis_flag": "joint_hysteresis", "joint_hysteresis_masing": "joint_hysteresis"}


def short(c: str) -> str:
    return (c.replace("_friction", "").replace("joint_", "").replace("_load", "").replace("stiffness_", "")
            .replace("_error", ""))


def run(spec: str, seed: int, full: bool, jobs: int, tmp: Path):
    names = spec.split("+")
    recipe = load_recipe(names[0]) if len(names) == 1 else combine_recipes(*[load_recipe(n) for n in names])
    if not full:
        recipe = recipe.scaled(**SMALL)
    study = tmp / f"{spec}-{seed}"
    shutil.rmtree(study, ignore_errors=True)
    generate_study(recipe, study, seed=seed)
    (study / "truth.json").unlink()
    d = diagnose(read_study(study), jobs=jobs, max_folds=6 if full else 2)
    shutil.rmtree(study, ignore_errors=True)
    return d


def singles(seeds, full, jobs, tmp) -> None:
    head = " | ".join(short(c) for c in COLUMNS)
    print(f"| hidden \\ named | {head} | 2nd cause | held-out gain (seeds {','.join(map(str, seeds))}) |")
    print("|" + "---|" * (len(COLUMNS) + 3))
    for hidden in ("null",) + CAUSES + tuple(OTHER_LAWS):
        named, gains, second = Counter(), [], 0
        for s in seeds:
            d = run(hidden, s, full, jobs, tmp)
            named[d.cause] += 1
            second += len(d.causes) > 1
            gains.append(f"{d.gain.reduction_pct:.0f}%" if d.causes else d.cause)
        want = "none" if hidden == "null" else OTHER_LAWS.get(hidden, hidden)
        cells = [(f"**{named[c]}**" if c == want else str(named[c])) if named[c] else "" for c in COLUMNS]
        print(f"| {hidden} | " + " | ".join(cells) + f" | {second} | {', '.join(gains)} |", flush=True)


def pairs(specs, seeds, full, jobs, tmp) -> None:
    print(f"\n| hidden pair | both named | named (seeds {','.join(map(str, seeds))}) | combined held-out gain |")
    print("|---|---|---|---|")
    for spec in specs:
        want = set(spec.split("+"))
        got, gains, n_both = [], [], 0
        for s in seeds:
            d = run(spec, s, full, jobs, tmp)
            n_both += set(d.causes) == want
            got.append("+".join(short(c) for c in d.causes) or d.cause)
            gains.append(f"{d.gain.reduction_pct:.0f}%")
        print(f"| {spec} | {n_both}/{len(seeds)} | {', '.join(got)} | {', '.join(gains)} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3", help="seeds of the one-cause studies")
    ap.add_argument("--pair-seeds", default="1,2", help="seeds of the two-cause studies")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--no-singles", action="store_true")
    ap.add_argument("--no-pairs", action="store_true")
    ap.add_argument("--pairs", help="comma-separated pairs a+b (default: every pair of the five nameable causes)")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="confusion-"))
    t0, n = time.perf_counter(), 0
    try:
        if not a.no_singles:
            seeds = [int(s) for s in a.seeds.split(",")]
            singles(seeds, a.full, a.jobs, tmp)
            n += len(seeds) * (len(CAUSES) + 1 + len(OTHER_LAWS))
        if not a.no_pairs:
            seeds = [int(s) for s in a.pair_seeds.split(",")]
            specs = a.pairs.split(",") if a.pairs else ["+".join(p) for p in itertools.combinations(NAMEABLE, 2)]
            pairs(specs, seeds, a.full, a.jobs, tmp)
            n += len(seeds) * len(specs)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\n{n} diagnoses in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
