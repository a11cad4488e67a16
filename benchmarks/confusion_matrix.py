"""Hidden-effect confusion matrix (issues 8, 19, 28): which causes diagnose names for each hidden one, and pair.

Singles: every recipe of ``datasets/recipes/`` for the six causes, the null study, joint hysteresis
from the generator's other laws (``joint_hysteresis_flag``: a two-branch superelastic plateau,
``joint_hysteresis_masing``: Bouc-Wen loops) and a calibration error made by a tilted bending plane
(``calibration_tilt``: the plane seen in perspective). Wrists (``--wrists``): every shipped wrist
recipe (real tubes: material springs, a lumen tendon, per-tube rest angles and cut depths), null and
with each real-tube cause hidden alone (``wrist_tip_load``: a tip load, ``wrist_hysteresis``: the
superelastic flag), measured as joint angles and as notch points, full size (leave-one-out). Pairs: every pair of the five nameable causes, each effect
from its one-cause recipe's range (``notchfit.studies.recipes.combine_recipes``). Studies are reduced as in the
default test job (4 experiments, 9 + 11 samples, 2 folds) or full (``--full``: six experiments,
leave-one-out), several seeds. The generator's truth.json is deleted before each diagnosis.
Prints Markdown tables: counts of the first named cause per hidden cause (and of studies given a second
cause), per wrist study the verdict, the held-out baseline against the noise floor and the gain, and
per pair how many studies were named exactly that pair, with the held-out gains. Each single and pair
study also shows the attainable gain, where the truth is known: the held-out rms of the generating model
itself (true parameters and warp, true registration, driven by the measured tensions:
``notchfit.analysis.diagnosis.calibration.attainable_mse``) is the floor, so the attainable gain is
``1 − floor / baseline``, and the fraction of it the named model reached is
``(baseline − extended) / (baseline − floor)`` (1: the row is as good as its data allow).

``--studies DIR`` keeps every generated study in DIR and reads it from there when it exists: run once,
then run the same rows on other code (``PYTHONPATH=OLD_CHECKOUT python benchmarks/confusion_matrix.py
--studies DIR ...``) to compare the diagnoses of identical data, whatever that code's generator does.

Usage: python benchmarks/confusion_matrix.py [--seeds 1,2,3] [--pair-seeds 1,2] [--full] [--jobs 2]
                                              [--no-singles] [--no-pairs] [--pairs a+b,c+d] [--rows a,b]
                                              [--wrists] [--wrist-seeds 1] [--studies DIR]
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import shutil
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from notchfit.analysis.diagnosis import CAUSES, diagnose
from notchfit.analysis.diagnosis.calibration import attainable_mse
from notchfit.analysis.fitting.results import PlaneTransform
from notchfit.io import read_study
from notchfit.physics.friction import FrictionParams
from notchfit.studies.recipes import combine_recipes
from notchfit.studies.synth import generate_study, load_recipe
from notchfit.units import DEG, MM

SMALL = dict(n_experiments=4, n_up=8, n_down=10)   # as tests/test_diagnosis_hidden.py
COLUMNS = ("none",) + CAUSES + ("unexplained",)
NAMEABLE = ("proximal_friction", "joint_hysteresis", "external_load", "stiffness_gradient", "calibration_error")
OTHER_LAWS = {"joint_hysteresis_flag": "joint_hysteresis", "joint_hysteresis_masing": "joint_hysteresis",
              "calibration_tilt": "calibration_error"}
#: The wrist rows: (recipe, observe, recipe changes, the cause hidden). Point noise for a recipe measured
#: without it, angle noise for one whose angles the recipe does not set (as benchmarks/null_wrists.py).
WRISTS = (
    ("wrist_stock", "angles", {}, "none"),
    ("wrist_stock", "points", {"point_sigma_mm": 0.005}, "none"),
    ("wrist_asymmetric", "points", {}, "none"),
    ("wrist_asymmetric", "angles", {"angle_sigma_deg": 0.25}, "none"),
    ("wrist_tip_first", "points", {}, "none"),
    ("wrist_tip_first", "angles", {"angle_sigma_deg": 0.25}, "none"),
    ("wrist_tip_load", "angles", {}, "external_load"),
    ("wrist_tip_load", "points", {}, "external_load"),
    ("wrist_hysteresis", "angles", {}, "joint_hysteresis"),
    ("wrist_hysteresis", "points", {}, "joint_hysteresis"),
)


def short(c: str) -> str:
    return (c.replace("_friction", "").replace("joint_", "").replace("_load", "").replace("stiffness_", "")
            .replace("_error", ""))


def _truth_file(study: Path) -> Path:
    """Where a study's truth.json is kept, outside the study (the diagnosis never sees it)."""
    return study.parent / f"{study.name}.truth.json"


def _study(make, name: str, seed: int, tmp: Path, keep: Path | None) -> Path:
    """The study ``name`` of ``seed`` without its truth.json (moved beside it, :func:`_truth_file`): read
    from ``keep`` when it holds it, else generated from the recipe ``make()`` (into ``keep`` when given)."""
    study = (keep or tmp) / f"{name}-{seed}"
    if keep is not None and (study / ".complete").exists():
        return study
    shutil.rmtree(study, ignore_errors=True)
    generate_study(make(), study, seed=seed)
    (study / "truth.json").replace(_truth_file(study))
    (study / ".complete").touch()
    return study


def attainable(d, study: Path):
    """``(attainable gain [%], fraction of it reached)`` of diagnosis ``d`` from the study's kept truth
    (None without a truth file, e.g. a study kept by older code; the fraction None without a named cause)."""
    tf = _truth_file(study)
    if not tf.exists():
        return None
    truth = json.loads(tf.read_text())
    params = FrictionParams(**{k: tuple(v) if isinstance(v, list) else v for k, v in truth["params"].items()})
    w = truth.get("warp")
    warp = None if w is None else {"scale_error": w["scale_error"], "k_radial": w["k_radial"],
                                   "center": np.array(w["center_mm"]) * MM, "radius": w["radius_mm"] * MM,
                                   "tilt": tuple(w.get("tilt_rad", (0.0, 0.0))),
                                   "distance": w.get("distance_mm", 250.0) * MM}
    mse = []
    for p in d.prepared:
        pl = truth["experiments"][p.name]["plane"]
        T = PlaneTransform(pl["tx_mm"] * MM, pl["ty_mm"] * MM, pl["phi_rad"], pl["mirror"])
        mse.append(attainable_mse(p, params, transform=T, warp=warp))
    floor = math.sqrt(float(np.nanmean(np.concatenate(mse))))
    base, ext = d.gain.baseline, d.gain.extended
    frac = (base - ext) / (base - floor) if d.causes and base > floor else None
    return 100.0 * (1.0 - floor / base), frac


def _attainable_cell(a) -> str:
    """``"40% (0.61)"``: the attainable gain and the fraction of it reached ("–" unknown)."""
    if a is None:
        return "–"
    return f"{a[0]:.0f}%" + (f" ({a[1]:.2f})" if a[1] is not None else "")


def run(spec: str, seed: int, full: bool, jobs: int, tmp: Path, keep: Path | None = None):
    def make():
        names = spec.split("+")
        recipe = load_recipe(names[0]) if len(names) == 1 else combine_recipes(*[load_recipe(n) for n in names])
        return recipe if full else recipe.scaled(**SMALL)

    study = _study(make, spec + ("-full" if full else ""), seed, tmp, keep)
    d = diagnose(read_study(study), jobs=jobs, max_folds=6 if full else 2)
    a = attainable(d, study)
    if keep is None:
        shutil.rmtree(study, ignore_errors=True)
        _truth_file(study).unlink(missing_ok=True)
    return d, a


def singles(seeds, full, jobs, tmp, keep=None, rows=None) -> int:
    hiddens = [h for h in ("null",) + CAUSES + tuple(OTHER_LAWS) if rows is None or h in rows]
    if not hiddens:
        return 0
    head = " | ".join(short(c) for c in COLUMNS)
    print(f"| hidden \\ named | {head} | 2nd cause | held-out gain (seeds {','.join(map(str, seeds))}) | "
          "attainable gain (fraction reached) |")
    print("|" + "---|" * (len(COLUMNS) + 4))
    for hidden in hiddens:
        named, gains, second, atts = Counter(), [], 0, []
        for s in seeds:
            d, a = run(hidden, s, full, jobs, tmp, keep)
            named[d.cause] += 1
            second += len(d.causes) > 1
            gains.append(f"{d.gain.reduction_pct:.0f}%" if d.causes else d.cause)
            atts.append(_attainable_cell(a))
        want = "none" if hidden == "null" else OTHER_LAWS.get(hidden, hidden)
        cells = [(f"**{named[c]}**" if c == want else str(named[c])) if named[c] else "" for c in COLUMNS]
        print(f"| {hidden} | " + " | ".join(cells) + f" | {second} | {', '.join(gains)} | {', '.join(atts)} |",
              flush=True)
    return len(hiddens) * len(seeds)


def wrists(seeds, jobs, tmp, keep=None, rows=None) -> int:
    """The wrist rows (:data:`WRISTS`), full size: per study the verdict, baseline vs floor and the gain."""
    print(f"\n| wrist recipe | measured | hidden | named (seeds {','.join(map(str, seeds))}) | "
          "held-out baseline / noise floor | baseline lack of fit beyond the scatter (p) | held-out gain | wall |")
    print("|---|---|---|---|---|---|---|---|")
    n = 0
    order = list(rows or ())
    rank = lambda w: min((order.index(k) for k in (w[0], f"{w[0]}-{w[1]}") if k in order), default=len(order))  # noqa: E731
    for name, observe, changes, hidden in sorted(WRISTS, key=rank):
        if rows is not None and name not in rows and f"{name}-{observe}" not in rows:
            continue
        named, errs, lofs, gains, walls = [], [], [], [], []
        for s in seeds:
            t0 = time.perf_counter()
            study = _study(lambda: load_recipe(name).replace(observe=observe, **changes), f"{name}-{observe}", s,
                           tmp, keep)
            d = diagnose(read_study(study), jobs=jobs)
            walls.append(f"{time.perf_counter() - t0:.0f} s")
            f, u = (MM, "mm") if d.metric == "points" else (DEG, "°")
            named.append("+".join(short(c) for c in d.causes) or d.cause)
            errs.append(f"{d.baseline_heldout_rms / f:.3f} / {d.noise_rms / f:.3f} {u}")
            lof = getattr(d, "lack_of_fit", None)          # code before the lack-of-fit rule has none
            lofs.append(f"{lof.overall.lack_of_fit_rms:.3f} {u} ({lof.overall.p_value:.2g})"
                        if lof is not None and lof.has_replicates else "–")
            gains.append(f"{d.gain.reduction_pct:.0f}%" if d.causes else "–")
            n += 1
            if keep is None:
                shutil.rmtree(study, ignore_errors=True)
        want = "none" if hidden == "none" else short(hidden)
        cell = ", ".join(f"**{x}**" if x == want else x for x in named)
        print(f"| {name} | {observe} | {hidden} | {cell} | {'; '.join(errs)} | {'; '.join(lofs)} | {', '.join(gains)} | "
              f"{', '.join(walls)} |", flush=True)
    return n


def pairs(specs, seeds, full, jobs, tmp, keep=None) -> int:
    print(f"\n| hidden pair | both named | named (seeds {','.join(map(str, seeds))}) | combined held-out gain | "
          "attainable gain (fraction reached) |")
    print("|---|---|---|---|---|")
    for spec in specs:
        want = set(spec.split("+"))
        got, gains, n_both, atts = [], [], 0, []
        for s in seeds:
            d, a = run(spec, s, full, jobs, tmp, keep)
            n_both += set(d.causes) == want
            got.append("+".join(short(c) for c in d.causes) or d.cause)
            gains.append(f"{d.gain.reduction_pct:.0f}%")
            atts.append(_attainable_cell(a))
        print(f"| {spec} | {n_both}/{len(seeds)} | {', '.join(got)} | {', '.join(gains)} | {', '.join(atts)} |",
              flush=True)
    return len(specs) * len(seeds)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3", help="seeds of the one-cause studies")
    ap.add_argument("--pair-seeds", default="1,2", help="seeds of the two-cause studies")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--no-singles", action="store_true")
    ap.add_argument("--no-pairs", action="store_true")
    ap.add_argument("--pairs", help="comma-separated pairs a+b (default: every pair of the five nameable causes)")
    ap.add_argument("--rows", help="comma-separated single and wrist rows to run (default: all): hidden causes, "
                                   "laws, wrist recipes or recipe-observe (wrist_stock-points)")
    ap.add_argument("--wrists", action="store_true", help="also the wrist rows (full size)")
    ap.add_argument("--wrist-seeds", default="1", help="seeds of the wrist studies")
    ap.add_argument("--studies", type=Path, help="keep the generated studies here and reuse them")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="confusion-"))
    rows = a.rows.split(",") if a.rows else None
    t0, n = time.perf_counter(), 0
    try:
        if not a.no_singles:
            n += singles([int(s) for s in a.seeds.split(",")], a.full, a.jobs, tmp, a.studies, rows)
        if a.wrists:
            n += wrists([int(s) for s in a.wrist_seeds.split(",")], a.jobs, tmp, a.studies, rows)
        if not a.no_pairs:
            seeds = [int(s) for s in a.pair_seeds.split(",")]
            specs = a.pairs.split(",") if a.pairs else ["+".join(p) for p in itertools.combinations(NAMEABLE, 2)]
            n += pairs(specs, seeds, a.full, a.jobs, tmp, a.studies)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\n{n} diagnoses in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
