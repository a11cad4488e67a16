"""Benchmark: notch-point projector + analytic Jacobian vs the general PoE path.

Times, in one run on the same random configurations (|θ| ≤ 0.14 rad, default
27-joint geometry):

* ``notches.notch_points_and_jacobian`` (compiled kernel) for one θ and for
  10,000 θ at once;
* the same closed form written with plain numpy (the pre-numba implementation,
  kept here as a reference);
* the general SE(3) path: ``kinematics.link_frames`` (product of exponentials)
  plus the point Jacobian from the spatial twists ``ξ'_k = Ad_{h_k} ξ_k``
  (``∂P/∂θ_k = v'_k + ω'_k × P``), one configuration at a time.

Usage::

    python benchmarks/bench_kinematics.py [--batch 10000] [--poe-sample 200]

Target (issue 2): one call under 50 µs.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from notchfit.physics import kinematics as K
from notchfit.physics.geometry import default_geometry, notch_layout
from notchfit.physics.notches import notch_points_and_jacobian


def numpy_reference(theta, geom):
    """Closed form with numpy broadcasting (the straightforward vectorized path)."""
    lay = notch_layout(geom)
    n = geom.n_joints
    th = np.asarray(theta, dtype=float)
    lead = th.shape[:-1]
    phi = np.zeros(lead + (n + 1,))
    np.cumsum(th, axis=-1, out=phi[..., 1:])
    s, c = np.sin(phi), np.cos(phi)
    q = np.zeros(lead + (n + 1, 2))
    np.cumsum(geom.p * s[..., 1:], axis=-1, out=q[..., 1:, 0])
    np.cumsum(geom.p * c[..., 1:], axis=-1, out=q[..., 1:, 1])
    link, lx, lz = lay.link, lay.local[:, 0], lay.local[:, 1]
    org = q[..., np.maximum(link - 1, 0), :]
    sl, cl = s[..., link], c[..., link]
    pts = np.stack([org[..., 0] + cl * lx + sl * lz, org[..., 1] - sl * lx + cl * lz], axis=-1)
    mask = (np.arange(1, n + 1)[None, :] <= link[:, None]).astype(float)
    qj = q[..., :-1, :]
    jac = np.empty(pts.shape[:-1] + (2, n))
    np.multiply(pts[..., :, 1, None] - qj[..., None, :, 1], mask, out=jac[..., 0, :])
    np.multiply(qj[..., None, :, 0] - pts[..., :, 0, None], mask, out=jac[..., 1, :])
    return pts, jac


def poe_reference(theta, geom):
    """General SE(3) path for one configuration: PoE link frames + twist point Jacobian."""
    lay = notch_layout(geom)
    g = K.link_frames(theta, geom)                      # (n+1, 4, 4)
    loc = np.zeros((lay.n_points, 4))
    loc[:, 0], loc[:, 2], loc[:, 3] = lay.local[:, 0], lay.local[:, 1], 1.0
    P = np.einsum("mij,mj->mi", g[lay.link], loc)[:, :3]
    Js = K.spatial_jacobian(theta, geom)                # columns ξ'_k = (v'_k, ω'_k)
    v, w = Js[:3].T, Js[3:].T                           # (n, 3)
    vel = v[None, :, :] + np.cross(w[None, :, :], P[:, None, :])      # (m, n, 3)
    vel *= (np.arange(1, geom.n_joints + 1)[None, :] <= lay.link[:, None])[..., None]
    pts = P[:, [0, 2]]
    jac = np.moveaxis(vel[..., [0, 2]], -1, 1)          # (m, 2, n)
    return pts, jac


def best_time(f, repeat=7, number=1):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            f()
        ts.append((time.perf_counter() - t0) / number)
    return min(ts)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=10000)
    ap.add_argument("--poe-sample", type=int, default=200, help="configurations timed on the PoE path")
    args = ap.parse_args(argv)
    geom = default_geometry()
    rng = np.random.default_rng(1)
    th1 = rng.uniform(-0.14, 0.14, geom.n_joints)
    thb = rng.uniform(-0.14, 0.14, (args.batch, geom.n_joints))

    # agreement first (the three paths compute the same thing)
    a, b, c = notch_points_and_jacobian(th1, geom), numpy_reference(th1, geom), poe_reference(th1, geom)
    err = max(np.abs(a[0] - c[0]).max(), np.abs(a[1] - c[1]).max(),
              np.abs(a[0] - b[0]).max(), np.abs(a[1] - b[1]).max())
    print(f"max |difference| between the three paths: {err:.2e} m")

    t_one = best_time(lambda: notch_points_and_jacobian(th1, geom), number=2000)
    t_one_np = best_time(lambda: numpy_reference(th1, geom), number=2000)
    t_one_poe = best_time(lambda: poe_reference(th1, geom), number=20)
    t_b = best_time(lambda: notch_points_and_jacobian(thb, geom), repeat=3)
    t_b_np = best_time(lambda: numpy_reference(thb, geom), repeat=3)
    sub = thb[: args.poe_sample]
    t_b_poe = best_time(lambda: [poe_reference(t, geom) for t in sub], repeat=1) * args.batch / len(sub)

    print(f"\nprojector + Jacobian, {geom.n_points} points x {geom.n_joints} joints")
    print(f"{'path':34s} {'one θ [µs]':>12s} {f'{args.batch} θ [ms]':>14s} {'per θ [µs]':>11s}")
    rows = [("notchfit (numba kernel)", t_one, t_b),
            ("numpy closed form", t_one_np, t_b_np),
            (f"general PoE (est. from {len(sub)})", t_one_poe, t_b_poe)]
    for name, t1, tb in rows:
        print(f"{name:34s} {t1 * 1e6:12.1f} {tb * 1e3:14.1f} {tb / args.batch * 1e6:11.2f}")
    print(f"\nratio PoE / notchfit:   one θ {t_one_poe / t_one:7.0f}x   batch {t_b_poe / t_b:7.0f}x")
    print(f"ratio numpy / notchfit: one θ {t_one_np / t_one:7.1f}x   batch {t_b_np / t_b:7.1f}x")
    print(f"target one call < 50 µs: {'met' if t_one < 50e-6 else 'NOT met'} ({t_one * 1e6:.1f} µs)")


if __name__ == "__main__":
    main()
