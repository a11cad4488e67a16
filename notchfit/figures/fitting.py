"""Figs. 12–15 of Sec. IV-A: shape fits, pointwise error, shape parameters.

Plotting functions take a :class:`notchfit.analysis.fitting.ExperimentFit` and an
output path and write one PNG (matplotlib Agg canvas, no pyplot state):

- :func:`plot_overlay` — Fig. 12: measured notch points ``Q_i`` with the
  fitted virtual points ``Q̃_i`` of each model, in the plane frame [mm] or on
  the sample's image through a plane → pixel mapping.
- :func:`plot_pointwise` — Figs. 13–14: the pointwise error
  ``||Q_i − Q̃_i||`` of every point and sample, one panel per model and
  sample group, curves coloured by time with an arrow for the progression.
- :func:`plot_shape_parameters` — Fig. 15: ``a`` and ``b`` of
  ``θ_j = a + b j`` against time or tension, arrows for the progression.

:func:`experiment_figures` writes all of them (with their data as CSV) for
one experiment; ``notchfit fit`` calls it. ``FIGURES`` holds stand-alone
demonstrations on a synthetic bend/unbend sequence (``notchfit figure
fig12`` …), labelled as synthetic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis.fitting import fit_experiment, pointwise_table
from ..physics.geometry import default_geometry
from ..studies.synth import synthetic_points
from ..units import MM
from . import new_figure, save_png, write_csv

__all__ = [
    "FIGURES",
    "experiment_figures",
    "fig12_sample_index",
    "loading_unloading_groups",
    "plot_overlay",
    "plot_pointwise",
    "plot_shape_parameters",
    "synthetic_bend_unbend",
]

_MODEL_LABEL = {"cc": r"constant curvature $\theta_j = a$", "linear": r"linear $\theta_j = a + b j$",
                "quadratic": r"quadratic $\theta_j = a + b j + c j^2$", "free": r"free $\theta_j$"}


def _label(model: str) -> str:
    return _MODEL_LABEL.get(model, model)


def _models_present(result, models):
    present = [m for m in models if m in result.models]
    return present or list(result.models[:2])


# ---------------------------------------------------------------------------
# Fig. 12
# ---------------------------------------------------------------------------
def plot_overlay(result, sample, path, *, models=("cc", "linear"), image=None, to_pixel=None,
                 title: str = "", annotate=(1, 29, 58), dpi: int = 150) -> Path:
    """Fig. 12: measured points and the fitted virtual points of each model.

    Parameters
    ----------
    result : ExperimentFit
    sample : object
        Sample id (an entry of ``result.samples``).
    path : path-like
        PNG to write.
    models : sequence of str
        One panel per model (those fitted; default CC left, linear right as
        in Fig. 12).
    image : ndarray, shape (H, W) or (H, W, 3), optional
        The sample's image; requires ``to_pixel``.
    to_pixel : callable, optional
        Maps plane points (N, 2) [m] to pixels (N, 2) (u, v) (OpenCV
        convention: column, row).
    title : str
    annotate : sequence of int
        Point numbers (1-based) to label.

    Returns
    -------
    Path
    """
    if image is not None and to_pixel is None:
        raise ValueError("plot_overlay: an image needs to_pixel, a plane [m] -> pixel (u, v) mapping")
    models = _models_present(result, models)
    s = result.samples.index(sample) if sample in result.samples else None
    if s is None:
        raise ValueError(f"no sample {sample!r} in this experiment")
    Q = result.points[s]
    fig = new_figure(4.2 * len(models), 5.6)
    axes = fig.subplots(1, len(models), squeeze=False)[0]
    for ax, name in zip(axes, models):
        f = result.get(name, sample)
        if image is not None:
            ax.imshow(image, cmap="gray" if np.ndim(image) == 2 else None, origin="upper")

            def xy(P):
                P = np.asarray(P, dtype=float)
                out = np.full(P.shape, np.nan)
                ok = np.isfinite(P).all(-1)
                if ok.any():
                    out[ok] = np.asarray(to_pixel(P[ok]), dtype=float).reshape(-1, 2)
                return out
        else:
            def xy(P):
                return np.asarray(P, dtype=float) / MM
        q = xy(Q)
        ax.plot(q[:, 0], q[:, 1], "o", mfc="none", mec="k", ms=5, mew=0.8, label=r"measured $Q_i$")
        if f.success:
            p = xy(f.predicted)
            loop = np.vstack([p, p[:1]])
            ax.plot(loop[:, 0], loop[:, 1], "-", color="tab:red", lw=0.6, alpha=0.6)
            ax.plot(p[:, 0], p[:, 1], ".", color="red", ms=5, label=r"virtual $\tilde Q_i$")
            for i in annotate:
                if 1 <= i <= len(p) and np.isfinite(q[i - 1]).all():
                    ax.annotate(str(i), q[i - 1], textcoords="offset points", xytext=(4, 4), fontsize=7)
            sub = f"rms {f.rms / MM:.3f} mm, max {f.max_error / MM:.3f} mm"
        else:
            sub = f"fit failed: {f.message}"
        ax.set_title(f"{_label(name)}\n{sub}", fontsize=8)
        if image is None:
            ax.set_aspect("equal")
            ax.set_xlabel("x [mm]")
            ax.set_ylabel("y [mm]")
        else:
            ax.set_xlabel("u [px]")
            ax.set_ylabel("v [px]")
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or f"Fig. 12: sample {sample}", fontsize=9)
    return save_png(fig, Path(path), dpi=dpi)


# ---------------------------------------------------------------------------
# Figs. 13-14
# ---------------------------------------------------------------------------
def loading_unloading_groups(result, model: str = "linear") -> dict:
    """Split samples at the peak bend: ``{"loading": idx, "unloading": idx}``.

    The peak is the sample with the largest ``|Σ θ_j|`` (tip angle) of
    ``model`` (any fitted model if absent); the paper's regime I is the
    loading part, regimes II–III the unloading part (Figs. 13–14).
    """
    name = model if model in result.models else result.models[0]
    tip = np.abs(np.nansum(result.theta(name), axis=1))
    tip[~np.isfinite(tip)] = -1
    k = int(np.argmax(tip)) if len(tip) else 0
    idx = np.arange(len(result.samples))
    return {"loading": idx[:k + 1], "unloading": idx[k + 1:]}


def fig12_sample_index(result) -> int:
    """Index of the sample Fig. 12 shows by default: the last loading sample (end of regime I).

    The paper shows the last point of regime I; with no loading sample, the
    last sample.
    """
    load = loading_unloading_groups(result)["loading"]
    return int(load[-1]) if len(load) else len(result.samples) - 1


def plot_pointwise(result, path, *, models=("cc", "linear"), groups=None, title: str = "",
                   dpi: int = 150) -> Path:
    """Figs. 13–14: pointwise error ``||Q_i − Q̃_i||`` for all points and samples.

    Parameters
    ----------
    result : ExperimentFit
    path : path-like
    models : sequence of str
        One column of panels per model.
    groups : dict of str -> sequence of int, optional
        Sample index groups, one row of panels each (e.g. regimes I, II,
        III); all samples when omitted.
    title : str

    Returns
    -------
    Path
    """
    import matplotlib as mpl  # slow optional dependency: only when drawing

    models = _models_present(result, models)
    if groups is None:
        groups = {"all samples": np.arange(len(result.samples))}
    groups = {k: np.asarray(v, dtype=int) for k, v in groups.items() if len(v)}
    if not groups:
        raise ValueError("plot_pointwise: every sample group is empty")
    nr, nc = len(groups), len(models)
    fig = new_figure(4.6 * nc, 3.2 * nr + 0.4)
    axes = fig.subplots(nr, nc, squeeze=False)
    S = len(result.samples)
    cmap = mpl.colormaps["viridis"]
    norm = mpl.colors.Normalize(0, max(S - 1, 1))
    m = result.points.shape[1]
    pts = np.arange(1, m + 1)
    ymax = max(np.nanmax(np.r_[result.errors(mm).ravel(), 0.0]) for mm in models) / MM
    for r, (gname, idx) in enumerate(groups.items()):
        for c, name in enumerate(models):
            ax = axes[r, c]
            E = result.errors(name)[idx] / MM
            for s, e in zip(idx, E):
                ax.plot(pts, e, "-", color=cmap(norm(s)), lw=0.8)
            finite = np.isfinite(E).all(1) if E.size else np.array([], bool)
            if finite.sum() >= 2:
                first, last = E[finite][0], E[finite][-1]
                i = int(np.nanargmax(np.abs(last - first)))
                ax.annotate("", xy=(pts[i], last[i]), xytext=(pts[i], first[i]),
                            arrowprops=dict(arrowstyle="->", color="k", lw=1.0))
            with np.errstate(all="ignore"):
                mx = np.nanmax(E) if np.isfinite(E).any() else np.nan
            ax.set_title(f"{_label(name)} — {gname}\nmax {mx:.3f} mm", fontsize=8)
            ax.set_xlim(1, m)
            ax.set_ylim(0, ymax * 1.05 if np.isfinite(ymax) and ymax > 0 else 1)
            ax.set_xlabel("notch point i")
            ax.set_ylabel(r"$\|Q_i - \tilde Q_i\|$ [mm]")
    sm = mpl.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=axes, label="sample (time order)", shrink=0.8)
    fig.suptitle(title or "pointwise error (arrow: progression in time)", fontsize=9)
    return save_png(fig, Path(path), dpi=dpi)


# ---------------------------------------------------------------------------
# Fig. 15
# ---------------------------------------------------------------------------
def plot_shape_parameters(result, path, *, x=None, xlabel: str = "sample", model: str = "linear",
                          title: str = "", dpi: int = 150) -> Path:
    """Fig. 15: ``a`` and ``b`` of ``θ_j = a + b j`` with arrows for time.

    Parameters
    ----------
    result : ExperimentFit
    path : path-like
    x : array_like, shape (S,), optional
        Abscissa (time [s] or cable tension [N]); sample order when omitted.
    xlabel : str
    model : str
        Fitted model whose ``a``, ``b`` are shown (literal for linear; see
        :class:`notchfit.analysis.fitting.SampleFit` for the others).
    title : str

    Returns
    -------
    Path
    """
    name = model if model in result.models else result.models[0]
    a, b, sa, sb = result.ab(name)
    S = len(a)
    x = np.arange(S, dtype=float) if x is None else np.asarray(x, dtype=float)
    if x.shape != (S,):
        raise ValueError(f"x must have one value per sample ({S}), got shape {x.shape}")
    fig = new_figure(5.0, 6.0)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, y, se, lab in ((axes[0], a, sa, r"$a$ [rad]"), (axes[1], b, sb, r"$b$ [rad]")):
        ok = np.isfinite(y) & np.isfinite(x)
        ax.errorbar(x[ok], y[ok], yerr=np.where(np.isfinite(se[ok]), se[ok], 0), fmt="o",
                    ms=3, color="k", ecolor="0.6", lw=0.8)
        xi, yi = x[ok], y[ok]
        for k in range(len(xi) - 1):
            ax.annotate("", xy=(xi[k + 1], yi[k + 1]), xytext=(xi[k], yi[k]),
                        arrowprops=dict(arrowstyle="->", color="tab:blue", lw=0.8,
                                        shrinkA=2, shrinkB=2))
        ax.set_ylabel(lab)
        ax.axhline(0, color="0.8", lw=0.5)
    axes[1].set_xlabel(xlabel)
    fig.suptitle(title or rf"shape parameters ({_label(name)})", fontsize=9)
    return save_png(fig, Path(path), dpi=dpi)


# ---------------------------------------------------------------------------
# All figures of one experiment
# ---------------------------------------------------------------------------
def experiment_figures(result, out_dir, *, title: str = "", x=None, xlabel: str = "sample",
                       groups=None, sample=None, image=None, to_pixel=None) -> list[Path]:
    """Figs. 12–15 (PNG) and their data (CSV) for one experiment.

    Parameters
    ----------
    result : ExperimentFit
    out_dir : path-like
        Existing folder.
    title : str
        Experiment name for the titles.
    x, xlabel
        Abscissa of Fig. 15 (time [s] or tension [N]); sample order if omitted.
    groups : dict, optional
        Sample groups for Figs. 13–14; by default split at the peak bend
        (:func:`loading_unloading_groups`): Fig. 13 shows the loading samples
        (regime I) for CC and linear, Fig. 14 the unloading samples
        (regimes II–III) for the linear model.
    sample : object, optional
        Sample of Fig. 12; default the last loading sample (the paper shows
        the last point of regime I).
    image, to_pixel
        Optional image of that sample and plane → pixel mapping (Fig. 12).

    Returns
    -------
    list of Path
    """
    out = Path(out_dir)
    pre = f"{title}: " if title else ""
    if groups is None:
        groups = loading_unloading_groups(result)
    load = groups.get("loading", np.arange(len(result.samples)))
    unload = groups.get("unloading", np.array([], dtype=int))
    if sample is None:
        ok = [i for i in load if result.fits[0][i].success] or list(range(len(result.samples)))
        sample = result.samples[ok[-1]]
    written = []
    written.append(plot_overlay(result, sample, out / "fig12_overlay.png", image=image,
                                to_pixel=to_pixel, title=f"{pre}Fig. 12, sample {sample}"))
    written.append(write_csv(out / "fig13_14_pointwise.csv", pointwise_table(result).to_dict("list")))
    written.append(plot_pointwise(result, out / "fig13_pointwise.png", models=("cc", "linear"),
                                  groups={"loading (regime I)": load},
                                  title=f"{pre}Fig. 13: pointwise error, loading"))
    if len(unload) and "linear" in result.models:
        written.append(plot_pointwise(result, out / "fig14_pointwise.png", models=("linear",),
                                      groups={"unloading (regimes II-III)": unload},
                                      title=f"{pre}Fig. 14: pointwise error, unloading"))
    name = "linear" if "linear" in result.models else result.models[0]
    a, b, sa, sb = result.ab(name)
    xs = np.arange(len(a), dtype=float) if x is None else np.asarray(x, dtype=float)
    written.append(write_csv(out / "fig15_shape_parameters.csv",
                             {"sample": list(result.samples), "x": xs, "a_rad": a, "b_rad": b,
                              "se_a_rad": sa, "se_b_rad": sb}))
    written.append(plot_shape_parameters(result, out / "fig15_shape_parameters.png", x=x,
                                         xlabel=xlabel, model=name,
                                         title=f"{pre}Fig. 15: shape parameters"))
    return written


# ---------------------------------------------------------------------------
# Stand-alone demonstrations (synthetic data)
# ---------------------------------------------------------------------------
def synthetic_bend_unbend(geom=None, *, n_samples=(18, 8, 12), a_peak: float = -0.11,
                          b_ratio_peak: float = -0.03, noise: float = 2e-5,
                          transform=(0.02, 0.005, -0.1), mirror: bool = True, seed: int = 2015):
    """A paper-like synthetic sequence of linear shapes with ground truth.

    Regime I: ``a`` ramps from 0 to ``a_peak`` while ``b/a`` grows to
    ``b_ratio_peak`` (base joints bent more, Sec. IV-A); regime II: ``a``
    holds while ``b`` relaxes to zero; regime III: ``a`` returns to 0 at
    constant curvature. Tension is a synthetic ramp 0 → 30 N → 0.

    Returns
    -------
    points : ndarray (S, m, 2) [m]; truth : dict (theta, a, b, tension_N,
    regime, transform, mirror, noise)
    """
    geom = geom or default_geometry()
    n1, n2, n3 = n_samples
    a = np.r_[np.linspace(0, a_peak, n1), np.full(n2, a_peak), np.linspace(a_peak, 0, n3 + 1)[1:]]
    ratio = np.r_[np.linspace(0, b_ratio_peak, n1), np.linspace(b_ratio_peak, 0, n2), np.zeros(n3)]
    b = a * ratio
    tension = np.r_[np.linspace(0, 30, n1), np.linspace(30, 12, n2), np.linspace(12, 0, n3)]
    regime = np.array(["I"] * n1 + ["II"] * n2 + ["III"] * n3)
    j = np.arange(1, geom.n_joints + 1)
    theta = a[:, None] + b[:, None] * j
    rng = np.random.default_rng(seed)
    pts, truth = synthetic_points(theta, geom, transform, mirror=mirror, noise=noise, rng=rng)
    truth.update(a=a, b=b, tension_N=tension, regime=regime)
    return pts, truth


def _demo(out_dir, **kw):
    geom = default_geometry()
    pts, truth = synthetic_bend_unbend(geom, **kw)
    res = fit_experiment(pts, geom, ("cc", "linear"), mirror=truth["mirror"], sigma=truth["noise"])
    reg = truth["regime"]
    groups = {"I": np.nonzero(reg == "I")[0], "II": np.nonzero(reg == "II")[0],
              "III": np.nonzero(reg == "III")[0]}
    return res, truth, groups


def fig12(out_dir: Path, **kw) -> list[Path]:
    """Fig. 12 on synthetic data: CC vs linear fit at the last sample of regime I."""
    res, truth, groups = _demo(out_dir, **kw)
    s = res.samples[groups["I"][-1]]
    out = Path(out_dir)
    f_cc, f_lin = res.get("cc", s), res.get("linear", s)
    rows = {"point": np.arange(1, res.points.shape[1] + 1),
            "x_mm": res.points[s, :, 0] / MM, "y_mm": res.points[s, :, 1] / MM,
            "cc_x_mm": f_cc.predicted[:, 0] / MM, "cc_y_mm": f_cc.predicted[:, 1] / MM,
            "linear_x_mm": f_lin.predicted[:, 0] / MM, "linear_y_mm": f_lin.predicted[:, 1] / MM}
    return [write_csv(out / "fig12.csv", rows),
            plot_overlay(res, s, out / "fig12.png",
                         title=f"Fig. 12 (synthetic): last sample of regime I, a = {truth['a'][s]:.3f} rad")]


def fig13(out_dir: Path, **kw) -> list[Path]:
    """Fig. 13 on synthetic data: pointwise error, regime I, CC and linear."""
    res, truth, groups = _demo(out_dir, **kw)
    out = Path(out_dir)
    df = pointwise_table(res)
    df = df[df["sample"].isin(groups["I"])]
    return [write_csv(out / "fig13.csv", df.to_dict("list")),
            plot_pointwise(res, out / "fig13.png", models=("cc", "linear"),
                           groups={"regime I": groups["I"]},
                           title="Fig. 13 (synthetic): pointwise error, regime I")]


def fig14(out_dir: Path, **kw) -> list[Path]:
    """Fig. 14 on synthetic data: pointwise error of the linear model, regimes II and III."""
    res, truth, groups = _demo(out_dir, **kw)
    out = Path(out_dir)
    df = pointwise_table(res)
    df = df[(df["model"] == "linear") & df["sample"].isin(np.r_[groups["II"], groups["III"]])]
    return [write_csv(out / "fig14.csv", df.to_dict("list")),
            plot_pointwise(res, out / "fig14.png", models=("linear",),
                           groups={"regime II": groups["II"], "regime III": groups["III"]},
                           title="Fig. 14 (synthetic): pointwise error, linear model")]


def fig15(out_dir: Path, **kw) -> list[Path]:
    """Fig. 15 on synthetic data: a and b against (synthetic) tension."""
    res, truth, groups = _demo(out_dir, **kw)
    out = Path(out_dir)
    a, b, sa, sb = res.ab("linear")
    return [write_csv(out / "fig15.csv", {"sample": list(res.samples), "tension_N": truth["tension_N"],
                                          "a_rad": a, "b_rad": b, "se_a_rad": sa, "se_b_rad": sb,
                                          "a_true_rad": truth["a"], "b_true_rad": truth["b"]}),
            plot_shape_parameters(res, out / "fig15.png", x=truth["tension_N"],
                                  xlabel="cable tension [N] (synthetic)",
                                  title="Fig. 15 (synthetic): linear-model shape parameters")]


FIGURES = {"fig12": fig12, "fig13": fig13, "fig14": fig14, "fig15": fig15}
