"""Benchmark of the real-time predictor (issue 18): time per tension sample.

``notchfit.physics.predictor.Predictor`` advances the friction simulator (Sec. IV-B,
fast solver) by one interval per new sample. In one run, for the seed tube
(27 joints, channel law, paper parameters) and the 5-joint asymmetric-notch
wrist (``datasets/geometry/wrist_asymmetric.toml``, material springs, capstan
law, mu_d = 0.15), on two tension streams:

* ``stream``: a real-time feed, 100 samples/s, the pulled tension ramped up
  and down over 4 s (401 samples);
* ``paper``: the paper's protocol, one sample every 5 s at rest (Fig. 11,
  38 samples).

Printed per step [us]: ``Predictor.step`` without and with the notch points,
beside ``simulate`` on the whole history divided by its samples (the
reference: the same solver, whole history at once), and what re-simulating
the whole history at the last sample would cost (the naive real-time use).
Also checks that the predictor equals ``simulate`` (max |dtheta|). Target:
<= 20 us per step at 27 joints on the real-time stream.

Usage::

    python benchmarks/bench_predictor.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from notchfit.physics.friction import FrictionParams, default_params, simulate
from notchfit.physics.geometry import default_geometry
from notchfit.io import datasets_dir, load_geometry
from notchfit.physics.predictor import Predictor
from notchfit.physics.protocols import bend_unbend


def streams(peak: float, counter: float, tendons):
    """(name, time, left, right) of the two streams; the right tendon is pulled."""
    t = 0.01 * np.arange(1, 402)
    up = np.minimum(t / 2.0, (4.0 - t) / 2.0).clip(0.0, 1.0)
    right = counter + (peak - counter) * up
    p = bend_unbend(peak, counter, pull="right")
    out = [("stream 100/s", t, np.full_like(t, counter), right),
           ("paper 5 s", np.asarray(p.time), np.asarray(p.tension_left), np.asarray(p.tension_right))]
    if "left" not in tendons:
        out = [(name, tt, None, r) for name, tt, _, r in out]
    return out


def run_predictor(params, geom, t, left, right, points):
    pred = Predictor(params, geom, settle_time=5.0, points=points)
    lv = [None] * len(t) if left is None else left.tolist()
    th = []
    t0 = time.perf_counter()
    for a, b, c in zip(t.tolist(), lv, right.tolist()):
        th.append(pred.step(a, b, c).theta)
    return time.perf_counter() - t0, np.array(th)


def best(fn, repeat):
    return min(fn() for _ in range(repeat))


def case(label, params, geom, peak, counter, repeat):
    for name, t, left, right in streams(peak, counter, geom.tendons):
        S = len(t)
        res = simulate(t, left, right, params, geom, settle_time=5.0)
        run_predictor(params, geom, t[:3], None if left is None else left[:3], right[:3], True)   # compile

        def sim_time():
            t0 = time.perf_counter()
            simulate(t, left, right, params, geom, settle_time=5.0)
            return time.perf_counter() - t0

        t_sim = best(sim_time, repeat)
        t_bare = best(lambda: run_predictor(params, geom, t, left, right, False)[0], repeat)
        t_pts = best(lambda: run_predictor(params, geom, t, left, right, True)[0], repeat)
        err = np.abs(run_predictor(params, geom, t, left, right, False)[1] - res.theta).max()
        print(f"{label:28s} {name:13s} S={S:4d}  step {t_bare / S * 1e6:7.1f} us  step+points "
              f"{t_pts / S * 1e6:7.1f} us  | simulate/sample {t_sim / S * 1e6:7.1f} us  "
              f"(ratio {t_sim / t_bare:5.2f})  re-simulate at last sample {t_sim * 1e3:7.2f} ms  "
              f"max|dtheta| {err:.1e} rad")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    seed = default_geometry()
    wrist = load_geometry(datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    print("== Predictor.step vs simulate (fast solver), best of", args.repeat, "runs")
    case("seed tube, 27 joints", FrictionParams(), seed, 25.0, 0.45, args.repeat)
    case("wrist, 5 joints, capstan", default_params(wrist).replace(mu_d=0.15, mu_s=0.16), wrist, 2.5, 0.0,
         args.repeat)


if __name__ == "__main__":
    main()
