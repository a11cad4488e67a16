"""``notchfit simulate``: the friction simulator driven by measured tensions (Sec. IV-B)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

NAME = "simulate"
ORDER = 50
HELP = "simulate an experiment or a study from its measured tensions (friction model)"
DESCRIPTION = """Run the cable-friction simulator (Sec. IV-B) on the measured tension history of
each experiment: the manipulator is at rest at every sample, tensions ramp linearly in
between. Parameters are the paper's values, or those of a model file (--model: a TOML file
written by notchfit.friction.save_params, e.g. the extended model that `notchfit diagnose`
saves), then any --param overrides (SI units: k_lin N m/rad, mu_d, b N m s/rad, ...).

Writes simulation.csv (sample, regime, a, b, theta_1..theta_n, base tensions, predicted
cable displacements) and, when the experiment has measured points, simulation_vs_measured.csv
(measured vs predicted shape parameters a, b of theta_j = a + b j and the notch-point error of
the prediction, Sec. IV-A) with Figs. 18 (joint angles) and 19 (a and b vs tension); for a
study, into OUT/<experiment>/.

Examples:
  notchfit simulate study/ --out out/
  notchfit simulate study/L045 --out out/ --param mu_d=0.25 --param k_mid=0.3
  notchfit simulate study/ --out ext/ --model out/extended_model.toml --jobs 2
"""

_MM = 1e-3


def add_arguments(parser) -> None:
    parser.add_argument("input", type=Path, help="experiment folder or study folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--model", type=Path, default=None, help="friction parameters TOML (save_params)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="override one parameter (repeatable), e.g. --param mu_d=0.25")
    parser.add_argument("--method", default="fast", help="solver: fast (default) or reference")
    parser.add_argument("--points", type=Path, default=None,
                        help="folder with detect's detections.csv for experiments without notch_points.csv")
    parser.add_argument("--no-figures", action="store_true", help="skip Figs. 18-19")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1; 0 = all CPUs)")
    parser.add_argument("--scheduler", default=None, help="Dask distributed scheduler address")
    parser.add_argument("--force", action="store_true", help="replace existing outputs in --out")


def parse_params(model_file, overrides):
    """FrictionParams from a model file and ``NAME=VALUE`` overrides (raises ValueError on a bad one)."""
    import dataclasses

    from ..friction import FrictionParams
    from ..io import load_params

    params = load_params(model_file) if model_file is not None else FrictionParams()
    fields = {f.name for f in dataclasses.fields(FrictionParams)}
    changes = {}
    for text in overrides:
        if "=" not in text:
            raise ValueError(f"--param {text!r}: expected NAME=VALUE")
        k, v = (s.strip() for s in text.split("=", 1))
        if k not in fields:
            raise ValueError(f"--param {k!r}: unknown parameter (known: {', '.join(sorted(fields))})")
        try:
            changes[k] = float(v)
        except ValueError:
            raise ValueError(f"--param {k}={v!r}: not a number") from None
    try:
        return dataclasses.replace(params, **changes) if changes else params
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--param: {exc}") from None


def linear_ab(theta) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``θ_j = a + b j`` (j = 1..n) of joint angles (..., n) [rad] (Sec. IV-A)."""
    th = np.asarray(theta, dtype=float)
    n = th.shape[-1]
    j = np.arange(1, n + 1, dtype=float)
    A = np.stack([np.ones(n), j], axis=1)
    coef = np.linalg.lstsq(A, th.reshape(-1, n).T, rcond=None)[0]
    return coef[0].reshape(th.shape[:-1]), coef[1].reshape(th.shape[:-1])


def simulate_one(item: dict) -> dict:
    """Simulate one experiment and compare with its points (a batch item)."""

    from ..friction import simulate, simulation_table

    res = simulate(item["time"], item["tension_left"], item["tension_right"], item["params"],
                   item["geometry"], method=item["method"])
    table = simulation_table(res, item["samples"])
    out = {"table": table, "theta_sim": np.asarray(res.theta), "regime": np.asarray(res.regime)}
    if item["points"] is not None:
        try:
            out.update(_compare(item, res))
        except (ValueError, np.linalg.LinAlgError) as exc:
            # the simulation stands; only the comparison with the measured points failed
            out["compare_error"] = f"{type(exc).__name__}: {exc}"
    return out


def _nan_rms_max(err) -> tuple[np.ndarray, np.ndarray]:
    """Per-row rms and max over the finite entries of ``err`` (S, m); NaN for an empty row."""
    ok = np.isfinite(err)
    n = ok.sum(axis=1)
    sq = np.where(ok, err, 0.0) ** 2
    rms = np.full(err.shape[0], np.nan)
    mx = np.full(err.shape[0], np.nan)
    has = n > 0
    rms[has] = np.sqrt(sq[has].sum(axis=1) / n[has])
    mx[has] = np.where(ok, err, -np.inf)[has].max(axis=1)
    return rms, mx


def _compare(item: dict, res) -> dict:
    """Measured (linear fit, Sec. IV-A) vs predicted shape parameters and the prediction's point error."""
    import pandas as pd

    from ..fitting import fit_experiment
    from ..notches import notch_points

    fit = fit_experiment(item["points"], item["geometry"], ("linear",), mirror=item["mirror"],
                         sigma=item["sigma"], samples=item["samples"])
    a_m, b_m, _, _ = fit.ab("linear")
    pred = fit.transform.to_plane(notch_points(np.asarray(res.theta), item["geometry"]))
    err = np.linalg.norm(pred - item["points"], axis=-1) / _MM         # (S, m), NaN where missing
    a_s, b_s = linear_ab(res.theta)
    rms, mx = _nan_rms_max(err)
    compare = pd.DataFrame({
        "sample": item["samples"], "tension_left_N": item["tension_left"],
        "tension_right_N": item["tension_right"], "regime": np.asarray(res.regime).astype(str),
        "a_meas": a_m, "b_meas": b_m, "a_sim": a_s, "b_sim": b_s,
        "point_rms_mm": rms, "point_max_mm": mx})
    return {"compare": compare, "theta_meas": fit.theta("linear")}


def simulation_figures(name: str, value: dict, out_dir: Path) -> list[Path]:
    """Fig. 18 (joint angles: prediction vs best linear fit) and Fig. 19 (a, b vs tension)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if "compare" not in value:
        return []
    c = value["compare"]
    paths = []
    th_s, th_m = value["theta_sim"], value["theta_meas"]
    lim = float(np.nanmax(np.abs(np.concatenate([th_s.ravel(), th_m.ravel()])))) or 1e-3
    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for ax, th, title in ((axes[0], th_s, "model prediction"),
                          (axes[1], th_m, "best fit to the points, θ_j = a + b j")):
        im = ax.imshow(th.T, aspect="auto", origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim,
                       extent=(c["sample"].iloc[0] - 0.5, c["sample"].iloc[-1] + 0.5, 0.5, th.shape[1] + 0.5))
        ax.set_ylabel("joint j")
        ax.set_title(f"{name}: {title}", fontsize=10)
    axes[1].set_xlabel("sample")
    fig.colorbar(im, ax=axes, label="θ_j [rad]")
    p = out_dir / "fig18_joint_angles.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    paths.append(p)

    dT = c["tension_left_N"].to_numpy() - c["tension_right_N"].to_numpy()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for ax, key, lab in ((axes[0], "a", "a [rad]"), (axes[1], "b", "b [rad]")):
        ax.plot(dT, c[f"{key}_meas"], "-o", ms=3, label="measured (fit)")
        ax.plot(dT, c[f"{key}_sim"], "--s", ms=3, label="predicted")
        ax.set_xlabel("T_left − T_right [N]")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].plot(c["sample"], c["point_rms_mm"], "-o", ms=3)
    axes[2].set_xlabel("sample")
    axes[2].set_ylabel("notch-point rms of the prediction [mm]")
    axes[2].grid(alpha=0.3)
    fig.suptitle(f"{name}: shape parameters, measured (solid) vs predicted (dashed)", fontsize=10)
    fig.tight_layout()
    p = out_dir / "fig19_shape_parameters.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    paths.append(p)
    return paths


def run(args) -> int:
    import dataclasses

    from .. import io
    from ..batch import run_batch

    if args.method not in ("fast", "reference"):
        raise ValueError(f"--method must be fast or reference, got {args.method!r}")
    params = parse_params(args.model, args.param)
    exps = io.read_study(args.input)
    study = not io.is_experiment_dir(args.input)
    with_pts, _ = io.attach_detections(exps, args.points if args.points is not None else args.out,
                                       require=False)
    pts = {e.name: e.points for e in with_pts}
    items = [{"time": e.time, "tension_left": np.maximum(e.tension_left, 0.0),
              "tension_right": np.maximum(e.tension_right, 0.0), "params": params, "geometry": e.geometry,
              "method": args.method, "samples": [int(s) for s in e.sample_ids], "points": pts.get(e.name),
              "mirror": e.mirror, "sigma": e.point_sigma} for e in exps]
    names = [e.name for e in exps]
    outputs = ["simulate_run.json"] + [str(io.experiment_output_dir("", n, study) / "simulation.csv")
                                       for n in names]
    with io.OutputRun(args.out, outputs=outputs, force=args.force, name="simulate") as run_:
        res = run_batch(simulate_one, items, keys=names, jobs=args.jobs, scheduler=args.scheduler,
                        desc="simulate")
        failed = {r.key: r.error for r in res.failures}
        for e, r in zip(exps, res.items):
            if not r.ok:
                continue
            sub = io.experiment_output_dir("", e.name, study)
            io.write_table_atomic(r.value["table"], run_.path(sub / "simulation.csv"))
            if "compare_error" in r.value:
                failed[f"{e.name} comparison with the points"] = r.value["compare_error"]
            if "compare" in r.value:
                io.write_table_atomic(r.value["compare"], run_.path(sub / "simulation_vs_measured.csv"))
                if not args.no_figures:
                    try:
                        simulation_figures(e.name, r.value, run_.path(sub / "x").parent)
                    except Exception as exc:  # noqa: BLE001
                        failed[f"{e.name} figures"] = f"{type(exc).__name__}: {exc}"
        io.write_json_atomic(io.provenance("simulate", args.input, params=dataclasses.asdict(params),
                                           model_file=str(args.model) if args.model else None,
                                           method=args.method, experiments=names, failures=failed),
                             run_.path("simulate_run.json"))
    for e, r in zip(exps, res.items):
        if r.ok and "compare" in r.value:
            c = r.value["compare"]
            v = c["point_rms_mm"].to_numpy(float)
            v = v[np.isfinite(v)]
            txt = f"{np.sqrt(np.mean(v ** 2)):.3f} mm" if v.size else "n/a (no measured points)"
            print(f"  {e.name:10s} prediction rms {txt} over {v.size} of {len(c)} samples")
        elif r.ok:
            print(f"  {e.name:10s} simulated ({len(r.value['table'])} samples; no measured points)")
    print(f"simulate: {res.n_ok} of {len(exps)} experiments in {res.seconds:.1f} s; outputs in {args.out}")
    for k, v in failed.items():
        print(f"  FAILED {k}: {v}")
    return 1 if failed else 0
