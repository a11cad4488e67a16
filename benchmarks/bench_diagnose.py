"""Time full diagnoses of six-experiment studies: one hidden cause and two (issue 28 targets on 2 cores:
one cause <= 15 s, two causes <= 30 s with 2 workers; issue 19's were 30 s and 60 s).

Generates the shipped ``proximal_friction`` recipe (six bend/unbend tests, 31 samples each, seeded) and a
two-cause study (``--pair``, default ``external_load+stiffness_gradient``: both recipes' effects at once),
then times ``diagnose`` with ``--jobs 2`` and, as the straightforward reference in the same run, serially
(``--jobs 1``). Besides the wall time it prints the CPU time of this process and its workers (user +
system), which a machine shared with other jobs disturbs less. The serial run also prints its work: the
histories simulated (cache misses of the process-wide simulation cache, emptied before every run), those
served from the cache, and the CPU seconds spent in the simulator, against the rest of the diagnosis.

``--candidate-secant K`` fits the candidates with Broyden updates between finite-difference Jacobians
(``diagnose(candidate_secant=K)``; default 0, the reference's answers).

Usage: python benchmarks/bench_diagnose.py [--recipe NAME] [--pair A+B] [--seed N] [--no-serial | --serial-only]
       [--candidate-secant K]
"""
import argparse
import resource
import shutil
import tempfile
import time
from pathlib import Path

from notchfit.analysis.diagnosis import diagnose
from notchfit.analysis.estimation.problem import Simulations
from notchfit.io import read_study
from notchfit.studies.recipes import combine_recipes
from notchfit.studies.synth import generate_study, load_recipe
from notchfit.units import MM


def _cpu() -> float:
    """User + system CPU seconds of this process and its finished children."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def _study(spec: str, seed: int, folder: Path):
    names = spec.split("+")
    recipe = load_recipe(names[0]) if len(names) == 1 else combine_recipes(*[load_recipe(n) for n in names])
    t = time.perf_counter()
    generate_study(recipe, folder, seed=seed)
    print(f"synthesised {spec} (seed {seed}) in {time.perf_counter() - t:.1f} s")
    exps = read_study(folder)
    print(f"{len(exps)} experiments, {sum(e.n_samples for e in exps)} samples")
    return exps


def _time(exps, jobs: int, secant: int = 0) -> float:
    sims = Simulations.shared()
    sims.reset()                       # every run starts cold (a forked worker inherits the parent's cache)
    t, c = time.perf_counter(), _cpu()
    d = diagnose(exps, jobs=jobs, candidate_secant=secant)
    wall, cpu = time.perf_counter() - t, _cpu() - c
    print(f"jobs={jobs}: {wall:.1f} s wall, {cpu:.1f} s CPU  causes={', '.join(d.causes) or d.cause}  held-out rms "
          f"{d.gain.baseline / MM:.3f} -> {d.gain.extended / MM:.3f} mm ({d.gain.reduction_pct:.0f}% lower)")
    if jobs == 1 and sims.runs:
        print(f"  work: {sims.runs} simulations ({sims.hits} more from the cache), {sims.run_seconds:.1f} s CPU in "
              f"the simulator ({1e3 * sims.run_seconds / sims.runs:.2f} ms each, {100 * sims.run_seconds / cpu:.0f}%), "
              f"{cpu - sims.run_seconds:.1f} s in the rest")
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recipe", default="proximal_friction")
    ap.add_argument("--pair", default="external_load+stiffness_gradient")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--candidate-secant", type=int, default=0,
                    help="Broyden updates in a row in the candidates' fits (0: differences throughout)")
    runs = ap.add_mutually_exclusive_group()
    runs.add_argument("--no-serial", action="store_true", help="skip the serial reference runs")
    runs.add_argument("--serial-only", action="store_true", help="only the serial runs (with their simulation counts)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-diag-"))
    try:
        for spec, target in ((args.recipe, 15.0), (args.pair, 30.0)):
            exps = _study(spec, args.seed, tmp / spec)
            runs = [2] if args.no_serial else [1] if args.serial_only else [2, 1]
            times = {jobs: _time(exps, jobs, args.candidate_secant) for jobs in runs}
            if len(times) == 2:
                print(f"speed-up of 2 workers over serial: {times[1] / times[2]:.2f}x")
            if 2 in times:
                print(f"target <= {target:.0f} s with 2 workers: {'met' if times[2] <= target else 'NOT met'}")
            print()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
