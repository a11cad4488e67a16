"""Figures that make the diagnosis's case (written by ``notchfit diagnose``).

Functions take the :class:`notchfit.analysis.diagnosis.Diagnosis` (which carries the
prepared experiments and every held-out prediction); they write
``diagnosis_*.png`` (and the plotted data as CSV) into the output folder,
where ``notchfit report`` embeds them:

* ``diagnosis_candidates`` — held-out rms of the baseline and every candidate;
* ``diagnosis_loops`` — pulled tension vs tip angle and ``b``, per experiment;
* ``diagnosis_residuals`` — free-θ residuals across the plane and the error per
  notch point (notch points), or the error per joint (joint angles);
* ``diagnosis_cause_<id>`` — one per named cause: the held-out prediction
  without that cause (the baseline, or the other cause's model) against the
  extended model and the measurement, in the view that shows what it removes
  (:attr:`notchfit.analysis.causes.Cause.figure`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.causes import REGISTRY
from ..analysis.estimation.observations import metric_unit, tube_labels
from ..physics.shapes import line_fit
from ..units import MM
from . import new_figure, save_png, write_csv
from .summary import DPI, candidates_figure, loops_figure, residual_map_figure

FIGURES: dict = {}  # no standalone paper figure: these need a diagnosis


def _lines(diag, i):
    """Measured, baseline and extended tip angle and ``b`` of experiment i, signed in the manipulator
    frame (θ > 0 bends toward +x) [rad, rad per joint]."""
    p = diag.prepared[i]
    out = {"measured": (p.pulled * p.tip_angle, p.b)}       # Prepared.tip_angle is toward the pulled side
    for key, label in _models(diag):
        th = diag.heldout[key].theta[i]
        out[label] = (th.sum(1), line_fit(th)[1])
    return out


def loops_table(diag) -> pd.DataFrame:
    """``diagnosis_loops.csv``: tip angle and ``b`` per sample of every experiment, measured and held-out
    predictions, signed in the manipulator frame; ``pulled_cable`` says which cable the test pulls."""
    frames = []
    for i, p in enumerate(diag.prepared):
        for name, (tip, b) in _lines(diag, i).items():
            frames.append(pd.DataFrame({"experiment": p.name, "sample": np.arange(1, len(tip) + 1),
                                        "pulled_cable": "right" if p.pulled > 0 else "left",
                                        "tension_pulled_N": p.pulled_tension, "series": name,
                                        "tip_angle_rad": tip, "b_rad": b}))
    return pd.concat(frames, ignore_index=True)


def plot_loops(diag, out_dir) -> list[Path]:
    """Hysteresis loops: the tip angle against the pulled tension, held-out predictions, one panel per
    experiment (:func:`notchfit.figures.summary.loops_figure`)."""
    out_dir = Path(out_dir)
    table = loops_table(diag)
    table.to_csv(out_dir / "diagnosis_loops.csv", index=False, float_format="%.9g")
    return [save_png(loops_figure(table), out_dir / "diagnosis_loops.png", dpi=DPI),
            out_dir / "diagnosis_loops.csv"]


def tube_groups(preps) -> list[tuple[str, list[int]]]:
    """``(tube, experiment indices)`` per tube (geometry, labelled as ``identify`` labels it:
    :func:`notchfit.analysis.estimation.tube_labels`) in order of first appearance. A study of several tubes
    has as many joints and notch points per tube as each tube's geometry, so per-joint and per-point
    errors are pooled within a tube only."""
    groups: dict = {}
    for i, label in enumerate(tube_labels([p.geom for p in preps])):
        groups.setdefault(label, []).append(i)
    return list(groups.items())


def residual_tables(diag) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Held-out point errors [mm]: rms by notch point (baseline, extension, free-θ fit residual, noise
    floor) and the error of every point of every sample (baseline, extension); with several tubes the
    rows by point carry a ``tube`` column (each tube's points pooled over its experiments)."""
    preps = diag.prepared
    series = {tag: diag.heldout[key] for tag, (key, _) in zip(("baseline", "extended"), _models(diag))}
    groups = tube_groups(preps)
    tables, cells = [], {key: [] for key in series}
    for tube, idx in groups:
        m = preps[idx[0]].geom.n_points
        by_point = {**({"tube": tube} if len(groups) > 1 else {}), "point": np.arange(1, m + 1)}
        for key, src in series.items():
            errs = [np.linalg.norm(src.predicted[i] - preps[i].measured, axis=-1) / MM for i in idx]
            by_point[f"rms_mm_{key}"] = np.sqrt(np.nanmean(np.concatenate(errs) ** 2, axis=0))
        free = np.concatenate([np.where(preps[i].valid, np.linalg.norm(preps[i].free_residuals, axis=-1), np.nan)
                               for i in idx])
        by_point["rms_mm_free_fit"] = np.sqrt(np.nanmean(free ** 2, axis=0)) / MM
        by_point["noise_mm"] = np.full(m, diag.noise_rms / MM)
        tables.append(pd.DataFrame(by_point))
    for key, src in series.items():
        cells[key] = np.concatenate([(np.linalg.norm(src.predicted[i] - p.measured, axis=-1) / MM).ravel()
                                     for i, p in enumerate(preps)])
    idx = pd.MultiIndex.from_tuples([(p.name, s + 1, j + 1) for p in preps for s in range(len(p.measured))
                                     for j in range(p.geom.n_points)], names=["experiment", "sample", "point"])
    grid = pd.DataFrame({f"err_mm_{k}": v for k, v in cells.items()}, index=idx).reset_index()
    return pd.concat(tables, ignore_index=True), grid


def plot_residual_map(diag, out_dir) -> list[Path]:
    """Where and when the models miss on held-out data: rms by notch point (with the free-θ fit's
    residual, what no joint configuration explains, and the noise floor) and maps of the error of every
    point and sample (:func:`notchfit.figures.summary.residual_map_figure`); for joint-angle data the
    held-out error by joint."""
    out_dir = Path(out_dir)
    if diag.metric == "angles":
        return _joint_errors(diag, out_dir)
    by_point, grid = residual_tables(diag)
    by_point.to_csv(out_dir / "diagnosis_point_errors.csv", index=False, float_format="%.9g")
    grid.to_csv(out_dir / "diagnosis_residual_map.csv", index=False, float_format="%.6g")
    return [save_png(residual_map_figure(by_point, grid), out_dir / "diagnosis_residuals.png", dpi=DPI),
            out_dir / "diagnosis_point_errors.csv", out_dir / "diagnosis_residual_map.csv"]


def _models(diag) -> list[tuple[str, str]]:
    """(held-out key, label) of the baseline and, when a cause is named, the extended model."""
    out = [("baseline", "baseline")]
    key = diag.extended_key
    if key != "baseline" and key in diag.heldout:
        out.append((key, f"extended ({key})"))
    return out


def _joint_errors(diag, out_dir: Path) -> list[Path]:
    """Held-out rms joint-angle error per joint [deg] (angle data)."""
    _, f = metric_unit("angles")
    preps = diag.prepared
    groups = tube_groups(preps)
    fig = new_figure(7, 4)
    ax = fig.subplots()
    tables = []
    for tube, idx in groups:
        n = preps[idx[0]].geom.n_joints
        table = {**({"tube": tube} if len(groups) > 1 else {}), "joint": np.arange(1, n + 1)}
        for (tag, (key, label)), ls in zip(zip(("baseline", "extended"), _models(diag)), ("-", "--")):
            src = diag.heldout[key]
            e = np.concatenate([np.where(preps[i].valid, src.predicted[i] - preps[i].measured, np.nan) for i in idx])
            table[f"rms_deg_{tag}"] = np.sqrt(np.nanmean(e**2, axis=0)) / f
            ax.plot(table["joint"], table[f"rms_deg_{tag}"], marker="o", ls=ls,
                    label=label if len(groups) == 1 else f"{tube}: {label}")
        tables.append(pd.DataFrame(table))
    ax.axhline(diag.noise_rms / f, color="0.5", ls=":", label="noise floor")
    ax.set_xticks(np.arange(1, max(preps[idx[0]].geom.n_joints for _, idx in groups) + 1))
    ax.set_xlabel("joint (base to tip)")
    ax.set_ylabel("held-out rms joint-angle error [deg]")
    ax.legend(fontsize=7)
    table = pd.concat(tables, ignore_index=True)
    return [save_png(fig, out_dir / "diagnosis_residuals.png", dpi=DPI),
            write_csv(out_dir / "diagnosis_joint_errors.csv", {c: table[c].to_numpy() for c in table})]


def plot_candidates(diag, out_dir) -> list[Path]:
    """Held-out rms of the baseline and of every candidate extension, and by regime
    (:func:`notchfit.figures.summary.candidates_figure`)."""
    out_dir = Path(out_dir)
    u, f = metric_unit(diag.metric)
    c = sorted(list(diag.candidates) + list(diag.pair_candidates), key=lambda d: d.heldout_rms)
    names = ["baseline"] + [d.cause for d in c]
    vals = [diag.baseline_heldout_rms / f] + [d.heldout_rms / f for d in c]
    ext = diag.extended_key
    regimes = pd.DataFrame([{"regime": r, "baseline": g.baseline / f, "extended": g.extended / f}
                            for r, g in (diag.per_regime or {}).items()])
    fig = candidates_figure(pd.DataFrame({"model": names, f"heldout_rms_{u}": vals}), diag.noise_rms / f,
                            named={ext, *diag.causes}, regimes=regimes if ext != "baseline" else None, unit=u)
    return [save_png(fig, out_dir / "diagnosis_candidates.png", dpi=DPI),
            write_csv(out_dir / "diagnosis_candidates.csv", {"model": names, f"heldout_rms_{u}": vals})]


# ----------------------------------------------------------------------------- one figure per cause
def _series(diag, contrib):
    """(key, label) of the held-out model without the cause and of the extended model."""
    w = contrib.without_key
    return [(w, f"without {contrib.cause} ({w})"), (diag.extended_key, f"with it ({diag.extended_key})")]


def _most_changed(diag, contrib, k: int = 3) -> list[int]:
    """The experiments whose held-out error the cause lowers most (at most ``k``)."""
    preps = diag.prepared
    w = diag.heldout[contrib.without_key].sample_mse(preps)
    e = diag.heldout[diag.extended_key].sample_mse(preps)
    gain = [float(np.nanmean(a) - np.nanmean(b)) for a, b in zip(w, e)]
    return sorted(np.argsort(gain)[::-1][:k].tolist())


def _view_loop(diag, contrib, fig) -> dict:
    """Pulled tension vs tip angle (the loop and the bend left after unloading), measured and held-out."""
    idx = _most_changed(diag, contrib)
    axs = fig.subplots(1, len(idx), squeeze=False)[0]
    rows = {"experiment": [], "sample": [], "tension_pulled_N": [], "series": [], "tip_angle_rad": []}
    for ax, i in zip(axs, idx):
        p = diag.prepared[i]
        T = p.pulled_tension
        lines = [("measured", p.tip_angle, dict(color="k", marker="o", ms=3, lw=1))]
        for (key, label), col in zip(_series(diag, contrib), ("tab:red", "tab:blue")):
            lines.append((label, p.pulled * diag.heldout[key].theta[i].sum(1),
                          dict(color=col, lw=1.3, ls="--" if col == "tab:red" else "-")))
        for label, tip, st in lines:
            ax.plot(T, tip, label=label, **st)
            rows["experiment"] += [p.name] * len(T)
            rows["sample"] += list(range(1, len(T) + 1))
            rows["tension_pulled_N"] += list(T)
            rows["series"] += [label] * len(T)
            rows["tip_angle_rad"] += list(tip)
        ax.set_title(p.name)
        ax.set_xlabel("pulled-tendon tension [N]")
    axs[0].set_ylabel("tip angle toward the pulled side [rad]")
    axs[0].legend(fontsize=7)
    return rows


def _view_asymmetry(diag, contrib, fig) -> dict:
    """Mean tip-angle error (measured − model) in the manipulator frame per experiment: a steady load
    bends both pull directions the same way."""
    ax = fig.subplots()
    preps = diag.prepared
    rows = {"experiment": [p.name for p in preps], "pull": ["right" if p.pulled > 0 else "left" for p in preps]}
    x = np.arange(len(preps))
    for j, ((key, label), col) in enumerate(zip(_series(diag, contrib), ("tab:red", "tab:blue"))):
        err = [float(np.nanmean(np.nansum(p.theta_free, 1) - diag.heldout[key].theta[i].sum(1)))
               for i, p in enumerate(preps)]
        ax.bar(x + (j - 0.5) * 0.38, err, width=0.38, color=col, label=label)
        rows[f"tip_error_rad_{'without' if j == 0 else 'with'}"] = err
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(x, [f"{p.name}\n({r})" for p, r in zip(preps, rows["pull"])], fontsize=7)
    ax.set_ylabel("mean tip-angle error, measured − model [rad]")
    ax.legend(fontsize=7)
    return rows


def _view_backbone(diag, contrib, fig) -> dict:
    """Joint-angle error along the backbone while loading (toward the pulled side)."""
    ax = fig.subplots()
    preps = diag.prepared
    groups = tube_groups(preps)
    tables = []
    for tube, idx in groups:
        rows = {**({"tube": tube} if len(groups) > 1 else {}), "joint": np.arange(1, preps[idx[0]].geom.n_joints + 1)}
        for j, ((key, label), col) in enumerate(zip(_series(diag, contrib), ("tab:red", "tab:blue"))):
            e = [preps[i].pulled * (preps[i].theta_free - diag.heldout[key].theta[i])[preps[i].regime == "I"]
                 for i in idx]
            err = np.nanmean(np.concatenate(e), axis=0)
            ax.plot(rows["joint"], err, marker="o", color=col, label=label if len(groups) == 1 else f"{tube}: {label}")
            rows[f"loading_error_rad_{'without' if j == 0 else 'with'}"] = err
        tables.append(pd.DataFrame(rows))
    rows = {c: v.to_numpy() for c, v in pd.concat(tables, ignore_index=True).items()}
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("joint (base to tip)")
    ax.set_ylabel("joint-angle error while loading, measured − model [rad]")
    ax.legend(fontsize=7)
    return rows


def _view_plane(diag, contrib, fig) -> dict:
    """Held-out point errors across the plane (mean over samples), without and with the correction."""
    axs = fig.subplots(1, 2)
    i = _most_changed(diag, contrib, 1)[0]
    p = diag.prepared[i]
    P = np.nanmean(np.where(p.valid[..., None], p.measured, np.nan), axis=0) / MM
    rows = {"point": np.arange(1, P.shape[0] + 1), "x_mm": P[:, 0], "y_mm": P[:, 1]}
    for ax, (key, label), tag in zip(axs, _series(diag, contrib), ("without", "with")):
        R = np.nanmean(np.where(p.valid[..., None], p.measured - diag.heldout[key].predicted[i], np.nan), axis=0) / MM
        ax.quiver(P[:, 0], P[:, 1], R[:, 0], R[:, 1], angles="xy", scale_units="xy", scale=0.05, width=0.003)
        ax.set_aspect("equal")
        ax.set_title(f"{p.name}: {label}\n(mean error × 20)", fontsize=8)
        ax.set_xlabel("x [mm]")
        rows[f"err_x_mm_{tag}"], rows[f"err_y_mm_{tag}"] = R[:, 0], R[:, 1]
    axs[0].set_ylabel("y [mm]")
    return rows


#: The views a cause's figure can take, by kind (:attr:`notchfit.analysis.causes.Cause.figure`).
VIEWS = {"loop": _view_loop, "asymmetry": _view_asymmetry, "backbone": _view_backbone, "plane": _view_plane}


def plot_cause(diag, contrib, out_dir) -> list[Path]:
    """``diagnosis_cause_<id>.png`` and ``.csv``: the held-out prediction without the cause against the
    extended model and the measurement, in the view of the cause's kind (:data:`VIEWS`)."""
    out_dir = Path(out_dir)
    fig = new_figure(11, 3.8)
    rows = VIEWS[REGISTRY[contrib.cause].figure](diag, contrib, fig)
    fig.suptitle(f"{contrib.cause}: {contrib.gain_pct:.0f}% lower held-out rms when added "
                 f"({100 * contrib.share:.0f}% of the removed discrepancy)", fontsize=9)
    name = f"diagnosis_cause_{contrib.cause}"
    return [save_png(fig, out_dir / f"{name}.png", dpi=DPI), write_csv(out_dir / f"{name}.csv", rows)]


def write_diagnosis_figures(diag, out_dir) -> list[Path]:
    """All diagnosis figures, one per named cause included; returns the PNG paths."""
    paths = plot_candidates(diag, out_dir) + plot_loops(diag, out_dir) + plot_residual_map(diag, out_dir)
    for c in diag.contributions:
        paths += plot_cause(diag, c, out_dir)
    return [p for p in paths if str(p).endswith(".png")]
