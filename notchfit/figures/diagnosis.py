"""Figures that make the diagnosis's case (written by ``notchfit diagnose``).

Functions take the :class:`notchfit.diagnosis.Diagnosis` (which carries the
prepared experiments); they write ``diagnosis_*.png`` (and the plotted data as
CSV) into the output folder, where ``notchfit report`` embeds them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..shapes import line_fit
from ..units import MM
from . import new_figure, save_png, write_csv

FIGURES: dict = {}  # no standalone paper figure: these need a diagnosis


def _lines(diag, i):
    """Measured, baseline and extended tip angle and b toward the pulled side for experiment i [rad]."""
    p = diag.prepared[i]
    out = {"measured": (p.tip_angle, p.pulled * p.b)}
    base = diag.heldout["baseline"]
    out["baseline"] = (p.pulled * base.theta[i].sum(1), p.pulled * line_fit(base.theta[i])[1])
    if diag.cause in diag.heldout:
        th = diag.heldout[diag.cause].theta[i]
        out[f"extended ({diag.cause})"] = (p.pulled * th.sum(1), p.pulled * line_fit(th)[1])
    return out


def plot_loops(diag, out_dir) -> list[Path]:
    """Pulled tension vs tip angle (hysteresis loops) and b vs tension, held-out predictions."""
    out_dir = Path(out_dir)
    preps = diag.prepared
    n = len(preps)
    fig = new_figure(10, 2.6 * n)
    axs = fig.subplots(n, 2, squeeze=False)
    rows = {"experiment": [], "sample": [], "tension_pulled_N": [], "series": [], "tip_angle_rad": [],
            "b_rad": []}
    style = {"measured": dict(color="k", marker="o", ms=3, lw=1),
             "baseline": dict(color="tab:red", ls="--", lw=1.2)}
    for i, p in enumerate(preps):
        T = p.pulled_tension
        for name, (tip, b) in _lines(diag, i).items():
            st = style.get(name, dict(color="tab:blue", lw=1.2))
            axs[i, 0].plot(T, tip, label=name, **st)
            axs[i, 1].plot(T, b, label=name, **st)
            for s in range(len(T)):
                rows["experiment"].append(p.name)
                rows["sample"].append(s)
                rows["tension_pulled_N"].append(T[s])
                rows["series"].append(name)
                rows["tip_angle_rad"].append(tip[s])
                rows["b_rad"].append(b[s])
        axs[i, 0].set_ylabel(f"{p.name}\ntip angle [rad]")
        axs[i, 1].set_ylabel("b [rad/joint]")
    axs[0, 0].set_title("hysteresis loop (held-out)")
    axs[0, 1].set_title("shape parameter b (θ_j = a + b j)")
    axs[0, 0].legend(fontsize=7)
    for ax in axs[-1]:
        ax.set_xlabel("pulled-cable tension [N]")
    return [save_png(fig, out_dir / "diagnosis_loops.png"),
            write_csv(out_dir / "diagnosis_loops.csv", rows)]


def plot_residual_map(diag, out_dir) -> list[Path]:
    """Free-θ fit residuals across the plane (what no joint configuration explains) and the
    held-out baseline error by notch point."""
    out_dir = Path(out_dir)
    preps = diag.prepared
    fig = new_figure(11, 4.6)
    ax1, ax2 = fig.subplots(1, 2)
    P = np.concatenate([p.measured[p.valid] for p in preps]) / MM
    R = np.concatenate([p.free_residuals[p.valid] for p in preps]) / MM
    scale = np.nanpercentile(np.linalg.norm(R, axis=1), 95) or 1.0
    ax1.quiver(P[:, 0], P[:, 1], R[:, 0], R[:, 1], angles="xy", scale_units="xy",
               scale=scale / 2.0, width=0.002, color="tab:purple")
    ax1.set_aspect("equal")
    ax1.set_xlabel("x [mm]")
    ax1.set_ylabel("y [mm]")
    ax1.set_title(f"free-θ fit residuals (arrow 2 mm = {scale:.3f} mm)")
    base = diag.heldout["baseline"]
    m = preps[0].geom.n_points
    errs = {"baseline": np.zeros(m)}
    if diag.cause in diag.heldout:
        errs[f"extended ({diag.cause})"] = np.zeros(m)
    for key in errs:
        src = base if key == "baseline" else diag.heldout[diag.cause]
        e = [np.linalg.norm(src.points[i] - p.measured, axis=-1) for i, p in enumerate(preps)]
        errs[key] = np.sqrt(np.nanmean(np.concatenate(e) ** 2, axis=0)) / MM
        ax2.plot(np.arange(1, m + 1), errs[key], marker=".", label=key)
    ax2.axhline(diag.noise_rms / MM, color="0.5", ls=":", label="noise floor")
    ax2.set_xlabel("notch point")
    ax2.set_ylabel("held-out rms error [mm]")
    ax2.legend(fontsize=7)
    return [save_png(fig, out_dir / "diagnosis_residuals.png"),
            write_csv(out_dir / "diagnosis_point_errors.csv",
                      {"point": np.arange(1, m + 1), **{f"rms_mm_{k}": v for k, v in errs.items()}})]


def plot_candidates(diag, out_dir) -> list[Path]:
    """Held-out rms of the baseline and of every candidate extension."""
    out_dir = Path(out_dir)
    c = sorted(diag.candidates, key=lambda d: d.heldout_rms)
    names = ["baseline"] + [d.cause for d in c]
    vals = [diag.baseline_heldout_rms / MM] + [d.heldout_rms / MM for d in c]
    fig = new_figure(7, 3.6)
    ax = fig.subplots()
    colors = ["tab:red"] + ["tab:green" if d.cause == diag.cause else "tab:gray" for d in c]
    ax.barh(names[::-1], vals[::-1], color=colors[::-1])
    ax.axvline(diag.noise_rms / MM, color="k", ls=":", label="noise floor")
    ax.set_xlabel("held-out notch-point rms [mm]")
    ax.set_title(f"cause: {diag.cause}")
    ax.legend(fontsize=7)
    return [save_png(fig, out_dir / "diagnosis_candidates.png"),
            write_csv(out_dir / "diagnosis_candidates.csv", {"model": names, "heldout_rms_mm": vals})]


def write_diagnosis_figures(diag, out_dir) -> list[Path]:
    """All diagnosis figures; returns the PNG paths."""
    paths = plot_candidates(diag, out_dir) + plot_loops(diag, out_dir) + plot_residual_map(diag, out_dir)
    return [p for p in paths if str(p).endswith(".png")]
