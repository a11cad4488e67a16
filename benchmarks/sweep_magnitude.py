"""Magnitude sweep (issue 8): the smallest effect of each cause that diagnose still finds.

For each cause, a reduced study (4 experiments, 19 samples each, 2 folds) is
generated with the effect fixed at several sizes, at the paper's load-cell
noise (0.11 N) and at a 10x better one (0.011 N); point noise 0.02 mm. Prints
a Markdown table: found (gain %) or the cause named instead.

Usage: python benchmarks/sweep_magnitude.py [--seed N] [--causes a,b] > table.md
"""
import argparse
import shutil
import tempfile
from pathlib import Path

from notchfit.analysis.diagnosis import diagnose
from notchfit.io import read_study
from notchfit.studies.synth import generate_study, load_recipe

SIZES = {
    "proximal_friction": [{"proximal_beta": v} for v in (0.01, 0.02, 0.04, 0.08)],
    "joint_hysteresis": [{"hysteresis_torque": v} for v in (0.0005, 0.001, 0.002, 0.004)],
    "external_load": [{"tip_force_x": v, "tip_force_z": 0.0} for v in (0.01, 0.02, 0.05, 0.1)],
    "stiffness_gradient": [{"stiffness_gradient": v} for v in (0.05, 0.1, 0.2, 0.3)],
    "calibration_error": [{"scale_error": v, "k_radial": v / 3} for v in (0.001, 0.002, 0.005, 0.01)],
    "static_friction": [{"static_excess": v} for v in (0.1, 0.2, 0.3, 0.45)],
}


def run(cause, effect, tension_sigma, seed, tmp):
    r = load_recipe(cause)
    r = r.replace(effect={k: (v, v) for k, v in effect.items()}, random_sign=(),
                  tension_sigma_N=tension_sigma).scaled(n_experiments=4, n_up=8, n_down=10)
    study = tmp / f"{cause}-{seed}"
    shutil.rmtree(study, ignore_errors=True)
    generate_study(r, study, seed=seed)
    (study / "truth.json").unlink()
    d = diagnose(read_study(study), jobs=2, max_folds=2)
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=21)
    ap.add_argument("--causes", default=",".join(SIZES))
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="sweep-"))
    try:
        print("| cause | effect size | σ_T = 0.11 N | σ_T = 0.011 N |")
        print("|---|---|---|---|")
        for cause in args.causes.split(","):
            for eff in SIZES[cause]:
                cells = []
                for sig in (0.11, 0.011):
                    d = run(cause, eff, sig, args.seed, tmp)
                    if d.cause == cause:
                        cells.append(f"found ({d.gain.reduction_pct:.0f}%)")
                    else:
                        cells.append(f"{d.cause}")
                size = ", ".join(f"{k} = {v:g}" for k, v in eff.items())
                print(f"| {cause} | {size} | {cells[0]} | {cells[1]} |", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
