"""Benchmark: shape fits per sample, notchfit's fitter vs a finite-difference reference.

In one run, on the same synthetic experiment (default 27-joint geometry, S
paper-like friction shapes θ_j = a (1 − 0.03 j) with a from 0.01 to 0.12 rad
and back, a random plane transform, seeded 0.02 mm point noise), for each
shape model:

* **notchfit** — :func:`notchfit.analysis.fitting.fit_samples` (batched
  Levenberg–Marquardt over all samples, analytic Jacobians), transform fixed;
* **scipy/analytic** — one ``scipy.optimize.least_squares`` call per sample
  with the same analytic Jacobian (``solver="scipy"``);
* **reference** — one ``scipy.optimize.least_squares`` call per sample with a
  2-point finite-difference Jacobian (the straightforward implementation),

all from the same closed-form start (:func:`notchfit.analysis.fitting.estimate_angles`).
It prints ms per sample, the speed-up against the reference, and the largest
parameter difference in units of the standard error (agreement check). It
also times the whole :func:`notchfit.analysis.fitting.fit_experiment` (joint
transform estimate with the free model + cc + linear) per sample.

BLAS is pinned to one thread (the fitter's matrices are tiny; threading only
adds contention on a shared machine) unless ``OPENBLAS_NUM_THREADS`` is set.

Usage::

    python benchmarks/bench_fitting.py [--samples 38] [--repeat 3]

Targets (issue 4): linear under 2 ms per sample, free under 20 ms.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from notchfit.analysis.fitting import estimate_angles, fit_experiment, fit_samples  # noqa: E402
from notchfit.physics.geometry import default_geometry  # noqa: E402
from notchfit.physics.notches import notch_points, to_plane  # noqa: E402
from notchfit.physics.shapes import get_model  # noqa: E402
from notchfit.studies.synth import synthetic_points  # noqa: E402

MODELS = ("cc", "linear", "quadratic", "pw3", "free", "free_smooth")


def reference_fit(points, geom, model, transform, sigma, x0, max_nfev=200):
    """Per-sample least squares with a finite-difference Jacobian (the reference)."""
    tx, ty, phi, mirror = transform
    ok = np.isfinite(points).all(-1)
    Q = points[ok]
    D = model.prior_jacobian()

    def fun(x):
        P = to_plane(notch_points(model.theta(x), geom), tx, ty, phi, mirror)[ok]
        r = ((P - Q) / sigma).ravel()
        return np.concatenate([r, D @ x]) if D.shape[0] else r

    return least_squares(fun, x0, jac="2-point", method="trf", x_scale="jac",
                         max_nfev=max_nfev).x


def best_of(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=38, help="samples in the experiment (paper: 38)")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many runs")
    ap.add_argument("--seed", type=int, default=2015)
    args = ap.parse_args(argv)

    geom = default_geometry()
    rng = np.random.default_rng(args.seed)
    S, sig = args.samples, 2e-5
    half = S // 2
    a = -np.r_[np.linspace(0.01, 0.12, half), np.linspace(0.12, 0.0, S - half)]
    j = np.arange(1, geom.n_joints + 1)
    theta = a[:, None] * (1 - 0.03 * j)
    T = (0.021, 0.004, -0.12, True)
    pts, _ = synthetic_points(theta, geom, T[:3], mirror=True, noise=sig, rng=rng)
    th0 = estimate_angles(pts, geom, T)

    print(f"{S} samples, {geom.n_points} points, {geom.n_joints} joints, noise 0.02 mm, "
          f"BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}, best of {args.repeat}")
    print(f"{'model':<12}{'params':>7}{'notchfit ms':>13}{'scipy/an ms':>13}{'ref (FD) ms':>13}"
          f"{'speed-up':>10}{'max |Δ|/SE':>12}")
    for name in MODELS:
        model = get_model(name, geom.n_joints)
        t_fast, fits = best_of(lambda: fit_samples(pts, geom, model, T, sigma=sig, theta0=th0), args.repeat)
        t_sci, _ = best_of(lambda: fit_samples(pts, geom, model, T, sigma=sig, theta0=th0,
                                               solver="scipy"), args.repeat)
        x0 = model.initial(th0)
        t_ref, ref = best_of(lambda: [reference_fit(pts[s], geom, model, T, sig, x0[s])
                                      for s in range(S)], 1)
        diff = max(np.max(np.abs(f.params - r) / f.se) for f, r in zip(fits, ref))
        print(f"{name:<12}{model.n_params:>7}{t_fast / S * 1e3:>13.3f}{t_sci / S * 1e3:>13.3f}"
              f"{t_ref / S * 1e3:>13.3f}{t_ref / t_fast:>9.0f}x{diff:>12.1e}")

    t_exp, res = best_of(lambda: fit_experiment(pts, geom, ("cc", "linear"), mirror=True, sigma=sig),
                         args.repeat)
    print(f"fit_experiment (joint transform with 'free' + cc + linear): "
          f"{t_exp / S * 1e3:.3f} ms per sample ({t_exp * 1e3:.1f} ms total; "
          f"transform in {res.transform.nfev} iterations)")
    t_exp, _ = best_of(lambda: fit_experiment(pts, geom, MODELS, mirror=True, sigma=sig), args.repeat)
    print(f"fit_experiment (all six models): {t_exp / S * 1e3:.3f} ms per sample")


if __name__ == "__main__":
    main()
