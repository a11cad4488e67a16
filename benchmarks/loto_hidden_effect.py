"""Leave-one-tube-out on synthetic stocks with a hidden effect: which physics did the per-tube freedom absorb?

A stock of three wrists (:func:`notchfit.studies.stock.synthetic_stock`: 13 loading-only trials, each
notch cut off its drawing by N(0, 10 um) clipped at 15 um, 0.5 deg angle noise) is made with a
hidden effect in its truth; ``identify`` predicts each wrist from the other two (``heldout_by_tube``)
with its default unknowns (the per-tube priors; and without the rest angles' prior, as before it)
and with each candidate added (``--free``). The reference is the true
model's error: the truth's material and effect, each wrist as drawn (its cut errors unknown, as for
any new tube). Printed per wrist and pooled (rms per notch, deg) with the ratio to the truth's.

Usage::

    python benchmarks/loto_hidden_effect.py [--seed 0] [--effect strain_ratio=1.5] [--jobs 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from notchfit.analysis.identify import identify
from notchfit.analysis.identify.specs import default_free
from notchfit.physics.friction import default_params, simulate_angles
from notchfit.studies.stock import synthetic_stock

#: what is tried: shared parameters added to the unknowns of the release before issue 27 (FrictionParams
#: fields), and identify's options
CANDIDATES = {
    "before: rest angles free": ((), {"rest_prior": False}),
    "priors": ((), {}),
    "priors + asymmetry (default)": (("strain_ratio",), {}),
    "priors + stop stiffness": (("stop_ratio",), {}),
}


def pooled(per_tube: dict, counts: dict) -> float:
    """rms over every value of every tube from per-tube rms figures and value counts."""
    tot = sum(counts.values())
    return float(np.sqrt(sum(per_tube[t] ** 2 * counts[t] for t in per_tube) / tot))


def true_errors(exps, truth) -> dict:
    """Tube -> rms [deg] of its trials under the true model with the drawing's depths (cut errors unknown)."""
    sq: dict = {}
    for e in exps:
        p = truth.params[e.geometry.name].replace(slot_depth_offset=None)
        d = simulate_angles(e.time, None, e.tension_right, p, e.geometry) - e.angles
        sq.setdefault(e.geometry.name, []).append(d[np.isfinite(d)])
    return {t: float(np.degrees(np.sqrt(np.mean(np.concatenate(v) ** 2)))) for t, v in sq.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--effect", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--candidates", default=",".join(CANDIDATES))
    args = ap.parse_args(argv)
    effect = {k: float(v) for k, v in (e.split("=") for e in args.effect)}
    exps, truth = synthetic_stock(args.seed, effect=effect)
    counts: dict = {}
    for e in exps:
        counts[e.geometry.name] = counts.get(e.geometry.name, 0) + int(np.isfinite(e.angles).sum())
    ref = true_errors(exps, truth)
    print(f"stock seed {args.seed}, hidden effect {effect or 'none'}; true model (as drawn): "
          + ", ".join(f"{t} {v:.2f}" for t, v in ref.items()) + f"; pooled {pooled(ref, counts):.3f} deg")
    base = [f for f in default_free([default_params(e.geometry) for e in exps], [e.geometry for e in exps])
            if f != "strain_ratio"]
    for name in args.candidates.split(","):
        extra, opts = CANDIDATES[name]
        t0 = time.perf_counter()
        r = identify(exps, free=base + list(extra), heldout=False, jobs=args.jobs, **opts)
        loto = r.heldout_by_tube
        vals = ", ".join(f"{k} {r.values[k]:.4g}" for k in extra if k in r.values) or "-"
        print(f"{name:30s} LOTO " + ", ".join(f"{t} {v:.2f}" for t, v in loto.items())
              + f"; pooled {pooled(loto, counts):.3f} deg = {pooled(loto, counts) / pooled(ref, counts):.2f}x the "
              f"truth's; train {r.train_rms:.3f}; fitted {vals}; {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
