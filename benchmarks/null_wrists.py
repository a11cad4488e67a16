"""Diagnose every shipped wrist recipe without a hidden effect (issue 28): the verdict must be ``none``.

Each recipe is measured as joint angles and as notch points (the recipe's own way first), with one tube
(``wrist_asymmetric``, ``wrist_tip_first``) and two (``wrist_stock``), over the seeds given. Prints per
study the verdict, the held-out baseline rms against the noise floor, the p-value of the held-out lack of
fit against the trials' scatter (where trials repeat), the best candidate and the wall and CPU time.

The noise floor column is the noise alone; the verdict's floor adds the baseline folds' prediction
uncertainty (``band``: their parameters known up to the training trials' point or angle noise and their
load-cell noise, docs/diagnosis.md).

Usage: python benchmarks/null_wrists.py [--seeds 1,2,3] [--jobs 2] [--only wrist_stock] [--observe points]
"""
import argparse
import math
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))            # this checkout's notchfit, not an installed one
from notchfit.analysis.diagnosis import diagnose  # noqa: E402
from notchfit.io import read_study  # noqa: E402
from notchfit.studies.synth import generate_study, load_recipe  # noqa: E402
from notchfit.units import DEG, MM  # noqa: E402

#: (recipe, observe, recipe changes): point noise for a recipe measured without it, angle noise for one
#: whose angles the recipe does not set
NULL_WRISTS = (
    ("wrist_stock", "angles", {}),
    ("wrist_stock", "points", {"point_sigma_mm": 0.005}),
    ("wrist_asymmetric", "points", {}),
    ("wrist_asymmetric", "angles", {"angle_sigma_deg": 0.25}),
    ("wrist_tip_first", "points", {}),
    ("wrist_tip_first", "angles", {"angle_sigma_deg": 0.25}),
)


def _cpu() -> float:
    """User + system CPU seconds of this process and its finished children."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def _row(name, observe, changes, seed, jobs, folder) -> str:
    generate_study(load_recipe(name).replace(observe=observe, **changes), folder, seed=seed)
    exps = read_study(folder)
    t, c = time.perf_counter(), _cpu()
    d = diagnose(exps, jobs=jobs)
    wall, cpu = time.perf_counter() - t, _cpu() - c
    f, u = (MM, "mm") if d.metric == "points" else (DEG, "deg")
    lof = d.lack_of_fit
    p = f"{lof.overall.p_value:.2g}" if lof is not None and lof.has_replicates else "-"
    best = min(d.candidates, key=lambda c: c.heldout_rms, default=None)
    cand = f"{best.cause} {best.heldout_rms / f:.3f} (z {best.z:.1f})" if best else "-"
    ratio = d.baseline_heldout_rms / d.noise_rms if d.noise_rms > 0 else math.nan
    return (f"| {name} | {observe} | {seed} | {d.cause} | {d.baseline_heldout_rms / f:.3f} {u} | "
            f"{d.noise_rms / f:.3f} {u} | {d.band_rms / f:.3f} {u} | {ratio:.2f} | {p} | {cand} | "
            f"{wall:.0f} s / {cpu:.0f} s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default=None, help="one recipe name")
    ap.add_argument("--observe", default=None, choices=("angles", "points"), help="one way of measuring")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="null-wrists-"))
    print("| recipe | measured | seed | verdict | held-out baseline | noise floor | band | ratio | lack-of-fit p | "
          "best candidate | wall / CPU |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    try:
        for seed in (int(s) for s in args.seeds.split(",")):
            for name, observe, changes in NULL_WRISTS:
                if (args.only and name != args.only) or (args.observe and observe != args.observe):
                    continue
                print(_row(name, observe, changes, seed, args.jobs, tmp / f"{name}-{observe}-{seed}"), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
