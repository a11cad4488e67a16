"""Figures that make the diagnosis's case (written by ``notchfit diagnose``).

Functions take the :class:`notchfit.diagnosis.Diagnosis` (which carries the
prepared experiments); they write ``diagnosis_*.png`` (and the plotted data as
CSV) into the output folder, where ``notchfit report`` embeds them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..shapes import line_fit
from ..units import MM
from . import save_png, write_csv
from .summary import DPI, candidates_figure, loops_figure, residual_map_figure

FIGURES: dict = {}  # no standalone paper figure: these need a diagnosis


def _lines(diag, i):
    """Measured, baseline and extended tip angle and ``b`` of experiment i, signed in the manipulator
    frame (θ > 0 bends toward +x) [rad, rad per joint]."""
    p = diag.prepared[i]
    out = {"measured": (p.pulled * p.tip_angle, p.b)}       # Prepared.tip_angle is toward the pulled side
    base = diag.heldout["baseline"]
    out["baseline"] = (base.theta[i].sum(1), line_fit(base.theta[i])[1])
    if diag.cause in diag.heldout:
        th = diag.heldout[diag.cause].theta[i]
        out[f"extended ({diag.cause})"] = (th.sum(1), line_fit(th)[1])
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


def residual_tables(diag) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Held-out point errors [mm]: rms by notch point (baseline, extension, free-θ fit residual, noise
    floor) and the error of every point of every sample (baseline, extension)."""
    preps = diag.prepared
    m = preps[0].geom.n_points
    series = {"baseline": diag.heldout["baseline"]}
    if diag.cause in diag.heldout:
        series["extended"] = diag.heldout[diag.cause]
    cells, by_point = [], {"point": np.arange(1, m + 1)}
    for key, src in series.items():
        errs = [np.linalg.norm(src.points[i] - p.measured, axis=-1) / MM for i, p in enumerate(preps)]
        by_point[f"rms_mm_{key}"] = np.sqrt(np.nanmean(np.concatenate(errs) ** 2, axis=0))
        cells.append(np.concatenate(errs).ravel())
    free = np.concatenate([np.where(p.valid, np.linalg.norm(p.free_residuals, axis=-1), np.nan) for p in preps])
    by_point["rms_mm_free_fit"] = np.sqrt(np.nanmean(free ** 2, axis=0)) / MM
    by_point["noise_mm"] = np.full(m, diag.noise_rms / MM)
    idx = pd.MultiIndex.from_tuples([(p.name, s + 1, j + 1) for p in preps for s in range(len(p.measured))
                                     for j in range(m)], names=["experiment", "sample", "point"])
    grid = pd.DataFrame({f"err_mm_{k}": v for k, v in zip(series, cells)}, index=idx).reset_index()
    return pd.DataFrame(by_point), grid


def plot_residual_map(diag, out_dir) -> list[Path]:
    """Where and when the models miss on held-out data: rms by notch point (with the free-θ fit's
    residual, what no joint configuration explains, and the noise floor) and maps of the error of every
    point and sample (:func:`notchfit.figures.summary.residual_map_figure`)."""
    out_dir = Path(out_dir)
    by_point, grid = residual_tables(diag)
    by_point.to_csv(out_dir / "diagnosis_point_errors.csv", index=False, float_format="%.9g")
    grid.to_csv(out_dir / "diagnosis_residual_map.csv", index=False, float_format="%.6g")
    return [save_png(residual_map_figure(by_point, grid), out_dir / "diagnosis_residuals.png", dpi=DPI),
            out_dir / "diagnosis_point_errors.csv", out_dir / "diagnosis_residual_map.csv"]


def plot_candidates(diag, out_dir) -> list[Path]:
    """Held-out rms of the baseline and of every candidate extension, and by regime
    (:func:`notchfit.figures.summary.candidates_figure`)."""
    out_dir = Path(out_dir)
    c = sorted(diag.candidates, key=lambda d: d.heldout_rms)
    names = ["baseline"] + [d.cause for d in c]
    vals = [diag.baseline_heldout_rms / MM] + [d.heldout_rms / MM for d in c]
    regimes = pd.DataFrame([{"regime": r, "baseline": g.baseline / MM, "extended": g.extended / MM}
                            for r, g in (diag.per_regime or {}).items()])
    fig = candidates_figure(pd.DataFrame({"model": names, "heldout_rms_mm": vals}), diag.noise_rms / MM,
                            named=(diag.cause,), regimes=regimes if diag.cause in diag.heldout else None)
    return [save_png(fig, out_dir / "diagnosis_candidates.png", dpi=DPI),
            write_csv(out_dir / "diagnosis_candidates.csv", {"model": names, "heldout_rms_mm": vals})]


def write_diagnosis_figures(diag, out_dir) -> list[Path]:
    """All diagnosis figures; returns the PNG paths."""
    paths = plot_candidates(diag, out_dir) + plot_loops(diag, out_dir) + plot_residual_map(diag, out_dir)
    return [p for p in paths if str(p).endswith(".png")]
