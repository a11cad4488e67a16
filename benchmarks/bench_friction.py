"""Benchmark and accuracy study of the friction simulator (Sec. IV-B, issue 5).

In one run:

1. **Speed**: the reference solver (the paper's four steps, explicit Euler,
   dt = ``friction.DEFAULT_DT``) and the fast solver on the same 38-sample
   bend/unbend test (Fig. 11: 0.45 N counter-tension, 25 N peak, 5 s apart);
   time per test and the ratio. Targets: fast < 5 ms per test, >= 50x.
2. **Agreement**: max |Δθ| (every joint, every sample) between the fast
   solver and the reference, on paper-like tests (counter-tensions 0.2–3 N,
   both pull directions) for the paper's parameters and some extensions.
   Target: < 1e-3 rad.
3. **Convergence in dt** (``--convergence``): max over samples of the change
   of every joint angle between dt and dt/4 for dt = 4e-4, 1e-4, 2.5e-5 s
   (``--fine`` adds 6.25e-6 s; ~15 s more).
4. **Input protocol** (``--protocols``): how the reference's rest states
   depend on the ramp time (step vs linear ramps of 0.1–5 s) and, for each
   ramp, on dt — why the default input is a step followed by a hold.
5. **Real tubes** (``--real-tubes``): a one-tendon 5-joint asymmetric-notch
   wrist (``datasets/geometry/wrist_asymmetric.toml``, springs from material
   and section) with the channel and the capstan law, time per 38-sample test
   beside the seed tube's; fast vs reference on it with damping as a time
   constant, and with the seed's absolute ``b`` (the issue-14 failure).
6. **Step budget** (``--steps``): the fast solver's steps per test and CPU per step with the
   default step controls, and with a larger ``dtheta_max``, ``h_max`` or ``h_min`` or without
   landing on the sticking events (``land_sticks``): how much time each saves
   and how far the joint angles move from the defaults' (what a diagnosis would trade for speed,
   issue 28).

Usage::

    python benchmarks/bench_friction.py [--repeat 20] [--ref-dt 2.5e-5] [--convergence] [--fine] [--protocols]
                                        [--real-tubes] [--no-agreement] [--steps]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from notchfit.physics.friction import DEFAULT_DT, FrictionParams, simulate
from notchfit.io import datasets_dir, load_geometry
from notchfit.physics.protocols import bend_unbend


def best_time(fn, repeat, clock=time.perf_counter):
    """Best of ``repeat`` calls in seconds of ``clock`` (``time.process_time``: CPU time, which a shared
    machine disturbs less than wall time)."""
    best = np.inf
    for _ in range(repeat):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def speed(repeat):
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    simulate(t, tl, tr)                                   # compile / load the cache
    simulate(t[:2], tl[:2], tr[:2], method="reference")
    tf = best_time(lambda: simulate(t, tl, tr), repeat)
    tr_ = best_time(lambda: simulate(t, tl, tr, method="reference"), 2)
    nf = simulate(t, tl, tr).n_steps
    print("== speed: one 38-sample bend/unbend test (Fig. 11 protocol), best of runs")
    print(f"reference (explicit Euler, dt = {DEFAULT_DT:g} s): {tr_ * 1e3:9.1f} ms per test")
    print(f"fast (exact relaxation + events):          {tf * 1e3:9.3f} ms per test  ({nf} steps)")
    print(f"ratio reference / fast: {tr_ / tf:.0f}x   (targets: fast < 5 ms, ratio >= 50)")


def steps(repeat):
    print("\n== step budget: fast solver on the 38-sample test, paper values and a proximal band, "
          "best CPU of runs")
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    for name, params in (("paper values", FrictionParams()), ("proximal_beta = 0.3", FrictionParams(proximal_beta=0.3))):
        ref = simulate(t, tl, tr, params)
        print(f"{name}:")
        for opts in ({}, {"dtheta_max": 1e-3}, {"dtheta_max": 2e-3}, {"h_max": 0.1}, {"h_min": 1e-2},
                     {"land_sticks": False}):
            res = simulate(t, tl, tr, params, **opts)
            cpu = best_time(lambda: simulate(t, tl, tr, params, **opts), repeat, time.process_time)
            label = ", ".join(f"{k} = {v:g}" for k, v in opts.items()) or "defaults"
            print(f"  {label:20s} {res.n_steps:6d} steps  {cpu * 1e3:7.3f} ms  {cpu / res.n_steps * 1e6:5.2f} us/step"
                  f"  max |dtheta| from the defaults {np.abs(res.theta - ref.theta).max():.1e} rad")


def agreement(ref_dt):
    print(f"\n== agreement: max |θ_fast - θ_ref| over every joint and sample [rad], reference dt = {ref_dt:g} s "
          "(target < 1e-3)")
    tests = [(0.2, 20.0), (0.45, 25.0), (1.0, 28.0), (1.5, 32.0), (3.0, 32.0)]
    variants = [("paper values", FrictionParams()),
                ("mu_s = 0.35", FrictionParams(mu_s=0.35)),
                ("mu_s = 0.45", FrictionParams(mu_s=0.45)),
                ("proximal_beta = 0.3", FrictionParams(proximal_beta=0.3)),
                ("hysteresis 2e-3 Nm", FrictionParams(hysteresis_torque=2e-3)),
                ("tip force (0.3, -0.3) N", FrictionParams(tip_force_x=0.3, tip_force_z=-0.3)),
                ("gradient 0.3", FrictionParams(stiffness_gradient=0.3))]
    head = "".join(f"  {p[0]}{c:4.2f}/{pk:2.0f}" for c, pk in tests for p in ("L", "R"))
    print(f"{'model':24s}{head}   (L/R pulled cable, counter N / peak N)")
    for name, params in variants:
        errs = []
        for c, pk in tests:
            for pull in ("left", "right"):
                t, tl, tr, _ = bend_unbend(pk, c, pull=pull)
                f = simulate(t, tl, tr, params).theta
                r = simulate(t, tl, tr, params, method="reference", dt=ref_dt).theta
                errs.append(np.abs(f - r).max())
        print(f"{name:24s}" + "".join(f"  {e:11.1e}" for e in errs) + f"   max {max(errs):.1e}")


def convergence(fine):
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    dts = [4e-4, 1e-4, 2.5e-5] + ([6.25e-6] if fine else [])
    th = {}
    for dt in dts:
        t0 = time.perf_counter()
        th[dt] = simulate(t, tl, tr, method="reference", dt=dt).theta
        print(f"   (reference dt = {dt:g} s: {time.perf_counter() - t0:.1f} s)")
    print("\n== convergence of the reference in dt (Fig. 11 test, step input): max over samples of "
          "|θ_j(dt) - θ_j(dt/4)| [rad]")
    print("joint " + "".join(f"  {d:g}->{d / 4:g}" for d in dts[:-1]))
    for j in range(th[dts[0]].shape[1]):
        print(f"{j + 1:5d} " + "".join(f"  {np.abs(th[d][:, j] - th[d / 4][:, j]).max():13.1e}"
                                       for d in dts[:-1]))
    print("  all " + "".join(f"  {np.abs(th[d] - th[d / 4]).max():13.1e}" for d in dts[:-1]))
    f = simulate(t, tl, tr).theta
    print("fast vs each dt: " + ", ".join(f"{d:g}: {np.abs(f - th[d]).max():.1e}" for d in dts))


def protocols():
    print("\n== input protocol: reference rest states vs ramp time (Fig. 11 test)")
    print("ramp_time  |θ(dt=1e-4) - θ(dt=2.5e-5)|   |θ - θ_step| (dt=2.5e-5)   |θ_fast - θ_ref(2.5e-5)|")
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    step = None
    for ramp in (0.0, 0.1, 0.5, 5.0):
        a = simulate(t, tl, tr, method="reference", dt=1e-4, ramp_time=ramp).theta
        b = simulate(t, tl, tr, method="reference", dt=2.5e-5, ramp_time=ramp).theta
        step = b if step is None else step
        f = simulate(t, tl, tr, ramp_time=ramp).theta
        print(f"{ramp:9.2f}  {np.abs(a - b).max():26.1e}  {np.abs(b - step).max():26.1e}  "
              f"{np.abs(f - b).max():24.1e}")


def real_tubes(repeat):
    """Time per test and solver agreement on a one-tendon 5-joint wrist, channel and capstan law."""
    wrist = load_geometry(datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    tw, _, trw, _ = bend_unbend(2.5, 0.0, pull="right")
    simulate(t, tl, tr)
    seed = best_time(lambda: simulate(t, tl, tr), repeat)
    print("\n== real tubes: time per 38-sample bend/unbend test, fast solver (best of runs)")
    print(f"{'seed tube, 27 joints, two cables (paper values)':58s} {seed * 1e3:8.3f} ms")
    rows = [("wrist 5 joints, one lumen tendon, material law, channel", dict(friction_law="channel")),
            ("wrist 5 joints, one lumen tendon, material law, capstan", dict(friction_law="capstan"))]
    for name, kw in rows:
        p = FrictionParams(spring_law="material", mu_d=0.15, mu_s=0.16, **kw)
        simulate(tw, None, trw, p, wrist)
        tf = best_time(lambda: simulate(tw, None, trw, p, wrist), repeat)
        f = simulate(tw, None, trw, p, wrist)
        r = simulate(tw, None, trw, p, wrist, method="reference")
        print(f"{name:58s} {tf * 1e3:8.3f} ms  ({f.n_steps} steps)  max |θ_fast - θ_ref| "
              f"{np.abs(f.theta - r.theta).max():.1e} rad, peak θ {np.abs(f.theta).max():.3f} rad")
    k = (0.006, 0.006, 0.005, 0.004, 0.004)
    for label, tau in (("absolute b = 0.03 N m s/rad (b/k = 5-7.5 s)", 0.0),
                       ("damping time 0.0621 s (the seed's b/k_lin)", 0.03 / 0.4829)):
        p = FrictionParams(k_lin=k, k_mid=tuple(0.3 * x for x in k), k_stop=tuple(20 * x for x in k),
                           theta_mid=0.15, theta_stop=0.5, mu_d=0.15, mu_s=0.16, damping_time=tau)
        f = simulate(tw, None, trw, p, wrist).theta
        r = simulate(tw, None, trw, p, wrist, method="reference").theta
        print(f"per-joint rates on the wrist, {label:45s} max |θ_fast - θ_ref| = "
              f"{np.degrees(np.abs(f - r).max()):.3g} deg")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--fine", action="store_true", help="with --convergence: add dt = 6.25e-6 s")
    ap.add_argument("--protocols", action="store_true")
    ap.add_argument("--real-tubes", action="store_true", help="one-tendon 5-joint wrist, channel and capstan law")
    ap.add_argument("--no-agreement", action="store_true", help="skip the agreement table (~1 min)")
    ap.add_argument("--steps", action="store_true", help="steps per test and CPU per step, larger step controls")
    ap.add_argument("--ref-dt", type=float, default=DEFAULT_DT,
                    help="reference step for the agreement table (2.5e-5: converged to ~4e-5 rad, ~3 s per test)")
    args = ap.parse_args()
    speed(args.repeat)
    if not args.no_agreement:
        agreement(args.ref_dt)
    if args.real_tubes:
        real_tubes(args.repeat)
    if args.convergence:
        convergence(args.fine)
    if args.protocols:
        protocols()
    if args.steps:
        steps(args.repeat)


if __name__ == "__main__":
    main()
