"""Time a full diagnosis of a six-experiment study (issue 8 target: < 2 min on 2 cores).

Generates the shipped ``proximal_friction`` recipe (six bend/unbend tests, 31
samples each, seeded), then times ``diagnose`` with ``--jobs 2`` and, as the
straightforward reference in the same run, serially (``--jobs 1``).

Usage: python benchmarks/bench_diagnose.py [--recipe NAME] [--seed N] [--no-serial]
"""
import argparse
import shutil
import tempfile
import time
from pathlib import Path

from notchfit.diagnosis import diagnose
from notchfit.io import read_study
from notchfit.synth import generate_study, load_recipe
from notchfit.units import MM


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipe", default="proximal_friction")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--no-serial", action="store_true", help="skip the serial reference run")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-diag-"))
    try:
        t = time.perf_counter()
        generate_study(load_recipe(args.recipe), tmp / "study", seed=args.seed)
        print(f"synthesised {args.recipe} (seed {args.seed}) in {time.perf_counter() - t:.1f} s")
        exps = read_study(tmp / "study")
        print(f"{len(exps)} experiments, {sum(e.n_samples for e in exps)} samples")
        runs = [2] if args.no_serial else [2, 1]
        times = {}
        for jobs in runs:
            t = time.perf_counter()
            d = diagnose(exps, jobs=jobs)
            times[jobs] = time.perf_counter() - t
            print(f"jobs={jobs}: {times[jobs]:.1f} s  cause={d.cause}  held-out rms "
                  f"{d.gain.baseline / MM:.3f} -> {d.gain.extended / MM:.3f} mm "
                  f"({d.gain.reduction_pct:.0f}% lower)")
        if 1 in times:
            print(f"speed-up of 2 workers over serial: {times[1] / times[2]:.2f}x")
        print(f"target < 120 s with 2 workers: {'met' if times[2] < 120 else 'NOT met'}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
