"""Study-level figures that read at 100 % zoom: the report's figures and the diagnosis's own PNGs.

Each function takes plain tables (what the commands wrote as CSV, read
back) and returns a matplotlib Figure sized for a page 1,050 px wide at
:data:`DPI` (10 pt text is 14 px high); nothing is written here. Signs and
units are the report's one convention: ``a``, joint and tip angles [rad] and
``b`` [rad per joint] signed in the manipulator frame (θ > 0 bends toward
+x, the right cable), lengths [mm].
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import new_figure

__all__ = ["DPI", "WIDTH", "candidates_figure", "fit_errors_figure", "loops_figure", "residual_map_figure",
           "simulation_figure", "thumbnails_figure"]

#: Resolution of the report's figures [dots per inch]: at 100 % zoom one figure pixel is one screen pixel.
DPI = 100
#: Width of a full-width figure [inch] (1,040 px at :data:`DPI`).
WIDTH = 10.4
#: Colours of the series compared throughout (measured, baseline/simulated, extended).
SERIES = {"measured": "black", "baseline": "tab:red", "simulated": "tab:red", "extended": "tab:blue",
          "noise": "0.45", "free": "tab:purple"}
STATUS_COLOURS = {"ok": "#1a9641", "ambiguous": "#fdae61", "occluded": "#d7191c"}


def _experiment_colours(names) -> dict:
    """One colour per experiment, left pulls in warm and right pulls in cool tones when named so."""
    import matplotlib  # slow optional dependency: only when drawing

    cmap = matplotlib.colormaps["tab10"]
    return {n: cmap(i % 10) for i, n in enumerate(names)}


def _outward(uv, i: int, distance: float = 9.0) -> tuple[float, float]:
    """Label offset [points] of corner ``i``: along the outline's outward normal there.

    The corners, in their numbering order, go around the tube's silhouette
    (docs/geometry.md), so the normal to the chord between the neighbours of
    ``i`` points across the outline; the side that is outside the polygon of
    the corners is the outward one.
    """
    from matplotlib.path import Path as _Path  # slow optional dependency: only when drawing

    ok = np.isfinite(uv).all(1)
    m = len(uv)
    prev = next((uv[(i - k) % m] for k in range(1, m) if ok[(i - k) % m]), uv[i])
    nxt = next((uv[(i + k) % m] for k in range(1, m) if ok[(i + k) % m]), uv[i])
    t = nxt - prev
    n = np.array([t[1], -t[0]]) / (np.linalg.norm(t) or 1.0)
    step = 0.02 * float(np.ptp(uv[ok], axis=0).max() or 1.0)
    if _Path(uv[ok]).contains_point(tuple(uv[i] + step * n)):
        n = -n
    return float(distance * n[0]), float(-distance * n[1])      # image rows point down, offsets up


def thumbnails_figure(panels: list[dict], *, labels=(1, 10, 20, 29, 30, 40, 50, 58)):
    """Detected corners on crops around the tube, one panel per chosen sample.

    Parameters
    ----------
    panels : list of dict
        ``image`` (H, W) gray crop, ``uv`` (m, 2) corner pixels in the crop
        (NaN: not found), ``status`` (m,) str, ``title`` str.
    labels : sequence of int
        Point numbers written beside their corner (all 58 would not be legible).
    """
    n = max(len(panels), 1)
    fig = new_figure(WIDTH, 3.3)
    axes = np.atleast_1d(fig.subplots(1, n))
    for ax, p in zip(axes, panels):
        ax.imshow(p["image"], cmap="gray", vmin=0, vmax=255, interpolation="antialiased")
        uv, st = np.asarray(p["uv"], float), np.asarray(p["status"]).astype(str)
        for s, c in STATUS_COLOURS.items():
            sel = (st == s) & np.isfinite(uv).all(1)
            if sel.any():
                ax.plot(uv[sel, 0], uv[sel, 1], "o", ms=3.5, mfc="none", mec=c, mew=1.0, label=s)
        m = len(uv)
        for k in labels:
            if k - 1 < m and np.isfinite(uv[k - 1]).all():
                ax.annotate(str(k), uv[k - 1], xytext=_outward(uv, k - 1), textcoords="offset points",
                            fontsize=8, color="#c00000", weight="bold", ha="center", va="center")
        ax.set_title(p["title"], fontsize=9)
        ax.set_axis_off()
    axes[0].legend(loc="lower left", fontsize=7, framealpha=0.8)
    return fig


def fit_errors_figure(by_point: pd.DataFrame, by_sample: pd.DataFrame):
    """Shape-fit errors: rms by notch point (Figs. 13–14 pooled) and rms per sample against tension.

    Parameters
    ----------
    by_point : DataFrame
        ``model, point, rms_mm`` (rms over every sample of every experiment).
    by_sample : DataFrame
        ``experiment, model, dT_N (T_left − T_right), rms_mm``.
    """
    fig = new_figure(WIDTH, 3.1)
    ax1, ax2 = fig.subplots(1, 2)
    for model, g in by_point.groupby("model", sort=False):
        ax1.plot(g["point"], g["rms_mm"], marker=".", lw=1, label=model)
    ax1.set_xlabel("notch point (right side 2–29 base → tip, left side 30–58 tip → base)")
    ax1.set_ylabel("fit error, rms [mm]")
    ax1.set_title("where along the tube the fits miss", fontsize=10)
    ax1.legend(fontsize=8)
    styles = {m: s for m, s in zip(by_sample["model"].unique(), ("o", "^", "s", "D"))}
    for model, g in by_sample.groupby("model", sort=False):
        ax2.plot(g["dT_N"], g["rms_mm"], styles[model], ms=3, alpha=0.7, label=model)
    ax2.set_xlabel("T_left − T_right [N]")
    ax2.set_ylabel("fit error of the sample, rms [mm]")
    ax2.set_title("when: the error grows with the bend", fontsize=10)
    ax2.legend(fontsize=8)
    return fig


def simulation_figure(cmp: pd.DataFrame):
    """Simulated against measured ``a``, ``b`` (Fig. 19) and the prediction's point error, every experiment.

    Parameters
    ----------
    cmp : DataFrame
        ``experiment, dT_N, a_meas, a_sim, b_meas, b_sim, point_rms_mm`` (frame signs, rad).
    """
    fig = new_figure(WIDTH, 3.2)
    axes = fig.subplots(1, 3)
    colours = _experiment_colours(cmp["experiment"].unique())
    for name, g in cmp.groupby("experiment", sort=False):
        c = colours[name]
        for ax, key in ((axes[0], "a"), (axes[1], "b")):
            ax.plot(g["dT_N"], g[f"{key}_meas"], "-", color=c, lw=1.2, label=name)
            ax.plot(g["dT_N"], g[f"{key}_sim"], "--", color=c, lw=1.0)
        axes[2].plot(g["dT_N"], g["point_rms_mm"], ".", color=c, ms=4)
    axes[0].set_ylabel("a [rad]")
    axes[1].set_ylabel("b [rad per joint]")
    axes[2].set_ylabel("point error of the simulation, rms [mm]")
    for ax in axes:
        ax.set_xlabel("T_left − T_right [N]")
    axes[0].set_title("a: solid measured, dashed simulated", fontsize=10)
    axes[1].set_title("b: solid measured, dashed simulated", fontsize=10)
    axes[0].legend(fontsize=7, ncol=2)
    return fig


def candidates_figure(candidates: pd.DataFrame, noise: float, named=(), regimes: pd.DataFrame | None = None,
                      *, unit: str = "mm", floor: float | None = None):
    """Held-out error of the baseline and of each candidate extension; and by regime.

    Parameters
    ----------
    candidates : DataFrame
        ``model, heldout_rms_<unit>`` with the baseline as ``model == "baseline"``.
    noise : float
        The noise floor [unit].
    named : sequence of str
        The causes the diagnosis named (green).
    regimes : DataFrame, optional
        ``regime, baseline, extended`` [unit].
    unit : {"mm", "deg"}
        Notch-point errors [mm] or joint-angle errors [deg].
    floor : float, optional
        The floor the verdict compares with [unit] (the noise and the baseline folds' prediction band),
        drawn dashed where it is above the noise floor.
    """
    what = "point" if unit == "mm" else "joint-angle"
    col = f"heldout_rms_{unit}"
    fig = new_figure(WIDTH, 2.9 + 0.12 * max(0, len(candidates) - 8))
    axes = fig.subplots(1, 2 if regimes is not None and len(regimes) else 1, squeeze=False)[0]
    c = candidates.sort_values(col, ascending=False)
    colours = ["tab:red" if m == "baseline" else ("tab:green" if m in named else "0.7") for m in c["model"]]
    axes[0].barh(c["model"], c[col], color=colours)
    axes[0].axvline(noise, color="k", ls=":", label=f"noise floor {noise:.3g} {unit}")
    if floor is not None and floor > noise:
        axes[0].axvline(floor, color="k", ls="--", lw=0.8, label=f"with the folds' band {floor:.3g} {unit}")
    axes[0].set_xlabel(f"held-out {what} error, rms [{unit}]")
    axes[0].set_title("shorter is better; green: named", fontsize=10)
    axes[0].legend(fontsize=8, loc="lower right")
    if len(axes) > 1:
        x = np.arange(len(regimes))
        if named:       # an extended model exists only when a cause is named
            axes[1].bar(x - 0.2, regimes["baseline"], 0.4, color=SERIES["baseline"], label="baseline")
            axes[1].bar(x + 0.2, regimes["extended"], 0.4, color=SERIES["extended"], label="extended")
        else:
            axes[1].bar(x, regimes["baseline"], 0.4, color=SERIES["baseline"], label="baseline")
        axes[1].axhline(noise, color="k", ls=":")
        axes[1].set_xticks(x, [f"regime {r}" for r in regimes["regime"]])
        axes[1].set_ylabel(f"held-out {what} error, rms [{unit}]")
        axes[1].set_title("by regime (I loading, II holding, III releasing)", fontsize=10)
        axes[1].legend(fontsize=8)
    return fig


def loops_figure(loops: pd.DataFrame, *, columns: int = 3, degrees: bool = False):
    """Tip angle against the pulled tension per experiment: measured, baseline and extended (held out).

    Parameters
    ----------
    loops : DataFrame
        ``experiment, tension_pulled_N, series, tip_angle_rad`` (frame sign);
        ``series`` is ``measured``, ``baseline`` or ``extended (<cause>)``.
    degrees : bool
        Draw the tip angle in degrees (a study measured as joint angles), else rad.
    """
    f, unit = (180.0 / np.pi, "deg") if degrees else (1.0, "rad")
    names = list(loops["experiment"].unique())
    rows = -(-len(names) // columns)
    fig = new_figure(WIDTH, 2.0 * rows + 0.5)
    axes = np.atleast_1d(fig.subplots(rows, columns, squeeze=False)).ravel()
    for ax, name in zip(axes, names):
        g = loops[loops["experiment"] == name]
        for series, s in g.groupby("series", sort=False):
            key = "measured" if series == "measured" else ("baseline" if series == "baseline" else "extended")
            style = dict(color=SERIES[key], lw=1.0, ls="--" if key == "baseline" else "-",
                         marker="o" if key == "measured" else None, ms=2.5)
            ax.plot(s["tension_pulled_N"], s["tip_angle_rad"] * f, label=series, **style)
        ax.set_title(name, fontsize=9, pad=2)
        ax.tick_params(labelsize=8)
    for ax in axes[len(names):]:
        ax.set_visible(False)
    for ax in axes[::columns]:
        ax.set_ylabel(f"tip angle Σθ [{unit}]", fontsize=9)
    for ax in axes[(rows - 1) * columns:]:
        ax.set_xlabel("pulled-cable tension [N]", fontsize=9)
    axes[0].legend(fontsize=7)
    return fig


def residual_map_figure(by_point: pd.DataFrame, cells: pd.DataFrame | None = None):
    """Where and when the models miss: held-out error by notch point, and by point and sample.

    Parameters
    ----------
    by_point : DataFrame
        ``point`` and ``rms_mm_<series>`` columns (baseline, extended, the
        free-θ fit's residual) [mm], optionally ``noise_mm``.
    cells : DataFrame, optional
        ``experiment, sample, point, err_mm_baseline[, err_mm_extended]``:
        the held-out error of each point of each sample, drawn as maps
        (rows: samples grouped by experiment; columns: notch points).
    """
    maps = [c for c in ("err_mm_baseline", "err_mm_extended") if cells is not None and c in cells]
    fig = new_figure(WIDTH, 3.6)
    axes = fig.subplots(1, 1 + len(maps), width_ratios=[1.3] + [1.0] * len(maps))
    axes = np.atleast_1d(axes)
    ax = axes[0]
    for col in [c for c in by_point.columns if c.startswith("rms_mm_")]:
        label = col[len("rms_mm_"):].replace("_", " ")
        key = "baseline" if label == "baseline" else ("free" if "free" in label else "extended")
        ax.plot(by_point["point"], by_point[col], marker=".", lw=1, color=SERIES[key], label=label)
    if "noise_mm" in by_point:
        ax.axhline(float(by_point["noise_mm"].iloc[0]), color=SERIES["noise"], ls=":", label="noise floor")
    ax.set_xlabel("notch point")
    ax.set_ylabel("held-out error, rms [mm]")
    ax.set_title("by notch point", fontsize=10)
    ax.legend(fontsize=7)
    if maps:
        vmax = float(np.nanpercentile(cells[maps].to_numpy(float), 99)) or 1.0
        rows = cells.groupby(["experiment", "sample"], sort=False).size().index
        for ax, col in zip(axes[1:], maps):
            grid = cells.pivot_table(index=["experiment", "sample"], columns="point", values=col, sort=False)
            grid = grid.reindex(rows)
            im = ax.imshow(grid.to_numpy(float), aspect="auto", cmap="magma", vmin=0, vmax=vmax,
                           interpolation="nearest", extent=(0.5, grid.shape[1] + 0.5, len(grid) - 0.5, -0.5))
            exps = [r[0] for r in rows]
            starts = [i for i in range(len(exps)) if i == 0 or exps[i] != exps[i - 1]]
            for i in starts[1:]:
                ax.axhline(i - 0.5, color="white", lw=0.8)
            ax.set_yticks(starts, [exps[i] for i in starts], fontsize=8, va="top")
            ax.set_xlabel("notch point")
            ax.set_title(f"{col[len('err_mm_'):]}: each point and sample", fontsize=10)
        fig.colorbar(im, ax=list(axes[1:]), label="held-out error [mm]", shrink=0.9)
    return fig
