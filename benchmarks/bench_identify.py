"""Benchmark of ``notchfit identify`` (issue 18): a 3-experiment study of one wrist.

The study: the 5-notch asymmetric wrist (``datasets/geometry/wrist_asymmetric.toml``),
three loading-only trials of 15 samples each, notch angles measured with 0.5 deg noise
and 5 mN load-cell noise, truth by the reference solver (recipe as in
``tests/test_identify.py``). In one run:

* ``identify`` with its defaults (4 material/friction parameters, 5 rest angles, 5 cut
  depths; probe grid, 2 least-squares starts; the fit on every trial and 3
  leave-one-out refits) with ``--jobs 1`` and ``--jobs 2``: wall time, the
  identified values beside the truth, held-out rms. Target: <= 10 s on 2 cores.
* The straightforward reference: the hand-written loop a lab would write, scipy's
  ``least_squares`` with its own finite differences around ``friction.simulate``
  (default solver options, every output built, no cache), the same 14 unknowns and
  prior, one start, one fit: time per fit and per evaluation, beside identify's.
* The fits' solver options (``identify.FIT_SOLVER``) against ``simulate``'s defaults:
  max |dtheta| on the study at the identified model.

* A stock of three wrists (issue 27; :func:`notchfit.studies.stock.synthetic_stock`, seed 0): 13
  loading-only trials (5, 4, 4) of 11 samples, cut errors of 10 um, 0.5 deg noise; the fit on every
  trial (4 shared parameters, 28 per-tube unknowns), 13 leave-one-trial-out and 3 leave-one-tube-out
  refits, with ``--jobs 1`` and ``--jobs 2``: wall and CPU time (the parent's and its workers'),
  beside the same with every held-out fit run from its probe grid (``warm_start=False``; ``--no-cold``
  leaves it out). Target: <= 10 s on 2 cores. On a shared machine compare CPU seconds, and wall times
  of runs alternated with the version before (``benchmarks/compare_versions.py``).

Usage::

    python benchmarks/bench_identify.py [--jobs 1,2] [--only stock] [--no-cold]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from notchfit import io
from notchfit.physics.friction import simulate
from notchfit.analysis.estimation import observe_study
from notchfit.analysis.identify import default_free, identify, make_problem
from notchfit.analysis.identify.problem import whitened
from notchfit.analysis.identify.specs import base_model, specs_for
from notchfit.analysis.identify.study import FIT_SOLVER
from notchfit.studies.recipes import recipe_from_dict
from notchfit.studies.stock import synthetic_stock
from notchfit.studies.synth import generate_study

TRUTH = {"E_lin": 45e9, "E_se": 3e9, "strain_lower": 0.014, "mu_d": 0.12}


def make_study(folder: Path):
    d = {"name": "bench", "seed": 1, "geometry": "wrist_asymmetric", "observe": "angles", "base": {},
         "fixed": {"spring_law": "material", "friction_law": "capstan", **TRUTH, "mu_s": 0.13, "damping_time": 2e-3},
         "noise": {"point_mm": 0.0, "tension_N": 0.005, "displacement_step_mm": 0.0, "angle_deg": 0.5},
         "plane": {"tx_mm": 0.0, "ty_mm": 0.0, "phi_deg": 0.0},
         "protocol": {"n_up": 14, "n_down": 0, "dt_s": 5.0, "pull": "right", "counter_N": 0.0},
         "experiments": [{"name": f"T{i + 1}", "peak_N": [2.4, 3.0]} for i in range(3)]}
    generate_study(recipe_from_dict(d), folder, force=True)
    return io.read_study(folder)


def reference_fit(exps):
    """The same unknowns (4 scalars, 5 rest angles, 5 cut depths, the same prior) fitted the straightforward
    way: scipy least_squares with its own 2-point differences, one start, friction.simulate with its default
    options and every output built, no cache."""
    obs = observe_study(exps, prefer="angles")
    base = {o.tube: base_model(o.geom) for o in obs}
    specs = specs_for(default_free(list(base.values()), [o.geom for o in obs]), list(base.values()))
    pb = make_problem(obs, base, specs, rest=True, depth=True, excess=0.01)

    def residuals(x):
        by_tube = pb.params(x)
        out = [whitened(o, simulate(o.time, None, o.tension_right, by_tube[o.tube], o.geom).theta) for o in obs]
        return np.concatenate(out + [pb.prior_residuals(x)])

    t0 = time.perf_counter()
    res = least_squares(residuals, pb.x0, bounds=(pb.lo, pb.hi), method="trf", x_scale="jac",
                        diff_step=np.r_[np.full(pb.k, 2e-3), np.full(pb.x0.size - pb.k, 1e-3)])
    return time.perf_counter() - t0, pb.values(res.x), res.nfev + res.njev * pb.x0.size


def _cpu() -> float:
    """CPU seconds of this process and its finished workers."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def bench_stock(jobs_list, cold: bool = True) -> None:
    """identify on the 3-tube, 13-trial stock: wall and CPU time, warm-started held-out fits (and not)."""
    exps, _ = synthetic_stock(0)
    identify(exps[:2], heldout=False)                      # compile / load the kernels' cache
    print(f"== identify on a stock of 3 wrists, {len(exps)} trials (17 fits: all, 13 trials and 3 tubes held out)")
    for warm in (True, False) if cold else (True,):
        for jobs in jobs_list:
            t0, c0 = time.perf_counter(), _cpu()
            r = identify(exps, jobs=jobs, warm_start=warm)
            dt, cpu = time.perf_counter() - t0, _cpu() - c0
            tubes = ", ".join(f"{k} {v:.4f}" for k, v in r.heldout_by_tube.items())
            print(f"warm_start={warm!s:5s} --jobs {jobs}: {dt:6.1f} s wall, {cpu:6.1f} s CPU; held-out rms "
                  f"{r.heldout_rms:.5f} deg, tubes held out: {tubes} deg")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", default="1,2")
    ap.add_argument("--only", choices=("stock",), default=None, help="run the stock benchmark alone")
    ap.add_argument("--no-cold", action="store_true", help="leave out the stock's fits without a warm start")
    args = ap.parse_args(argv)
    jobs_list = [int(j) for j in args.jobs.split(",")]
    bench_stock(jobs_list, cold=not args.no_cold)
    if args.only == "stock":
        return
    with tempfile.TemporaryDirectory() as tmp:
        exps = make_study(Path(tmp) / "study")
        identify(exps[:2], heldout=False)                      # compile / load the kernels' cache
        print("== identify on 3 loading-only trials of one wrist (15 samples each)")
        for jobs in jobs_list:
            t0 = time.perf_counter()
            r = identify(exps, jobs=jobs)
            dt = time.perf_counter() - t0
            vals = ", ".join(f"{k} {r.values[k]:.4g} (truth {v:.4g})" for k, v in TRUTH.items())
            print(f"--jobs {jobs}: {dt:6.1f} s for 4 fits (all + 3 held out); held-out rms "
                  f"{r.heldout_rms:.3f} deg, train {r.train_rms:.3f} deg; {vals}")
        t0 = time.perf_counter()
        r1 = identify(exps, heldout=False)
        t_one = time.perf_counter() - t0
        t_ref, ref_vals, nfev = reference_fit(exps)
        print(f"one fit of 14 unknowns: identify {t_one:.2f} s (probe grid + 2 starts, {r1.solution.nfev} "
              f"evaluations); reference loop {t_ref:.2f} s (one start, {nfev} evaluations); ratio "
              f"{t_ref / t_one:.2f}; per evaluation {t_one / r1.solution.nfev * 1e3:.2f} vs "
              f"{t_ref / nfev * 1e3:.2f} ms; reference E_se {ref_vals['E_se']:.4g}")
        err = 0.0
        for o in observe_study(exps, prefer="angles"):
            a = simulate(o.time, None, o.tension_right, r1.model, o.geom).theta
            b = simulate(o.time, None, o.tension_right, r1.model, o.geom, **FIT_SOLVER).theta
            err = max(err, float(np.abs(a - b).max()))
        print(f"fit solver {FIT_SOLVER} vs simulate's defaults at the identified model: max |dtheta| "
              f"{np.degrees(err):.4f} deg")


if __name__ == "__main__":
    main()
