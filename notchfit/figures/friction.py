"""Figures of the friction model (Sec. IV-B): Figs. 11, 17, 18, 19 and the hysteresis loop.

Each ``plot_*`` function takes a :class:`notchfit.physics.friction.SimulationResult`
(and optionally measured data) and writes CSV + PNG; the ``FIGURES`` entries
run the paper's Fig. 11 protocol (0.45 N counter-tension on the right cable,
the left cable pulled to 25 N and back, 38 samples 5 s apart) with the
paper's parameters and plot it:

* ``fig11``: pulled-cable tension vs its displacement, regimes I–III shaded,
  and both against time;
* ``fig17``: the piecewise-linear spring of the friction model;
* ``fig18``: joint angles over the test (prediction; measured best fit below
  when given);
* ``fig19``: shape parameters ``a``, ``b`` of ``θ_j = a + b j`` against the
  pulled tension (predicted dashed, measured solid when given);
* ``hysteresis``: tension difference vs tip angle loops for several ``μ_d``
  with their areas.

``notchfit simulate`` draws each experiment's Figs. 18–19 with
:func:`plot_fig18` and :func:`plot_fig19`, the measured data coming from
:func:`notchfit.analysis.comparison.compare_simulation`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..physics.cables import LEFT
from ..physics.cables import pulled_side as pulled_cable
from ..physics.friction import FrictionParams, SimulationResult, simulate
from ..polygon import polygon_area
from ..physics.protocols import bend_unbend
from ..units import MM
from . import new_figure, save_png, write_csv

__all__ = ["FIGURES", "plot_fig11", "plot_fig18", "plot_fig19", "plot_hysteresis", "pulled_side"]

REGIME_COLORS = {"I": "#4c72b0", "II": "#dd8452", "III": "#55a868"}


def pulled_side(result: SimulationResult) -> str:
    """``"left"`` or ``"right"``: the pulled cable of the test (:func:`notchfit.physics.cables.pulled_side`)."""
    return "left" if pulled_cable(result.input_left, result.input_right) == LEFT else "right"


def _shade(ax, x, regime):
    """Shade runs of equal regime along the x axis (sample positions ``x``)."""
    regime = np.asarray(regime).astype(str)
    if x.size == 0:
        return
    edges = np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]])
    start = 0
    for k in range(1, x.size + 1):
        if k == x.size or regime[k] != regime[start]:
            ax.axvspan(edges[start], edges[k], color=REGIME_COLORS.get(regime[start], "0.8"), alpha=0.15, lw=0)
            ax.text(0.5 * (edges[start] + edges[k]), 0.97, regime[start], transform=ax.get_xaxis_transform(),
                    ha="center", va="top", fontsize=8)
            start = k


def plot_fig11(result: SimulationResult, out_dir, measured_displacement=None, name: str = "fig11"):
    """Fig. 11: tension and displacement of the pulled cable, regimes I–III (Sec. IV).

    Parameters
    ----------
    result : SimulationResult
    out_dir : path
    measured_displacement : array_like (S,) [m], optional
        The pulled cable's measured displacement (plotted beside the model's).
    """
    out_dir = Path(out_dir)
    side = pulled_side(result)
    T = result.input_left if side == "left" else result.input_right
    d = result.displacement_left if side == "left" else result.displacement_right
    d_mm = (d - d[0]) / MM
    cols = {"sample": np.arange(1, result.n_samples + 1), "time_s": result.time,
            "regime": np.asarray(result.regime).astype(str), f"tension_{side}_N": T,
            f"displacement_{side}_mm": d_mm}
    dm = None
    if measured_displacement is not None:
        dm = (np.asarray(measured_displacement, float) - measured_displacement[0]) / MM
        cols[f"displacement_{side}_measured_mm"] = dm
    out = [write_csv(out_dir / f"{name}.csv", cols)]
    fig = new_figure(10.0, 4.0)
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(d_mm, T, "-", color="0.6", lw=0.8, zorder=1)
    for reg, c in REGIME_COLORS.items():
        sel = np.asarray(result.regime) == reg
        ax1.plot(d_mm[sel], T[sel], "o", ms=4, color=c, label=f"regime {reg}", zorder=2)
    if dm is not None:
        ax1.plot(dm, T, "k--", lw=0.8, label="measured")
    ax1.set_xlabel(f"{side} cable displacement [mm] (from the first sample)")
    ax1.set_ylabel(f"{side} cable tension [N]")
    ax1.legend(fontsize=8)
    x = result.time
    _shade(ax2, x, result.regime)
    ax2.plot(x, T, "k.-", lw=0.8, label="tension")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("tension [N]")
    ax3 = ax2.twinx()
    ax3.plot(x, d_mm, "-", color="tab:red", lw=1.0, label="displacement")
    ax3.set_ylabel("displacement [mm]", color="tab:red")
    fig.suptitle("Fig. 11: bend/unbend test, regimes I (loading), II (holding), III (releasing)", fontsize=9)
    out.append(save_png(fig, out_dir / f"{name}.png"))
    return out


def plot_fig18(result: SimulationResult, out_dir, measured_theta=None, name: str = "fig18"):
    """Fig. 18: joint angles over the test, model prediction (top) and measured best fit (bottom).

    Parameters
    ----------
    measured_theta : array_like (S, n) [rad], optional
        Measured joint angles (e.g. the linear-model fit ``a + b j`` per sample).
    """
    out_dir = Path(out_dir)
    S, n = result.theta.shape
    samples = np.repeat(np.arange(1, S + 1), n)
    joints = np.tile(np.arange(1, n + 1), S)
    cols = {"sample": samples, "joint": joints, "theta_pred_rad": result.theta.ravel()}
    mt = None
    if measured_theta is not None:
        mt = np.asarray(measured_theta, float)
        if mt.shape != (S, n):
            raise ValueError(f"measured_theta must have shape {(S, n)}, got {mt.shape}")
        cols["theta_meas_rad"] = mt.ravel()
    out = [write_csv(out_dir / f"{name}.csv", cols)]
    import matplotlib  # slow optional dependency: only when drawing

    cmap = matplotlib.colormaps["viridis"]
    rows = 2 if mt is not None else 1
    fig = new_figure(7.0, 3.2 * rows)
    axes = np.atleast_1d(fig.subplots(rows, 1, sharex=True))
    for ax, th, title in zip(axes, (result.theta, mt), ("model prediction", "best fit to image data")):
        for j in range(n):
            ax.plot(np.arange(1, S + 1), th[:, j], color=cmap(j / max(n - 1, 1)), lw=0.8)
        _shade(ax, np.arange(1, S + 1), result.regime)
        ax.set_ylabel(r"$\theta_j$ [rad]")
        ax.set_title(title, fontsize=9)
    axes[-1].set_xlabel("sample")
    sm = matplotlib.cm.ScalarMappable(cmap=cmap, norm=matplotlib.colors.Normalize(1, n))
    fig.colorbar(sm, ax=axes, label="joint j", shrink=0.8)
    fig.suptitle("Fig. 18: joint angles (base: dark, tip: light)", fontsize=9)
    out.append(save_png(fig, out_dir / f"{name}.png"))
    return out


def plot_fig19(result: SimulationResult, out_dir, measured_a=None, measured_b=None, name: str = "fig19",
               point_rms_mm=None):
    """Fig. 19: shape parameters a, b vs the pulled tension; predicted dashed, measured solid.

    Parameters
    ----------
    result : SimulationResult
    out_dir : path
    measured_a, measured_b : array_like (S,) [rad], optional
        The measured shape parameters (e.g. the linear-model fit per sample).
    name : str
        File stem of the CSV and PNG.
    point_rms_mm : array_like (S,) [mm], optional
        Notch-point rms error of the prediction per sample; drawn in a third
        panel against the sample number when given.
    """
    out_dir = Path(out_dir)
    side = pulled_side(result)
    T = result.input_left if side == "left" else result.input_right
    cols = {"sample": np.arange(1, result.n_samples + 1), f"tension_{side}_N": T,
            "regime": np.asarray(result.regime).astype(str), "a_pred_rad": result.a, "b_pred_rad": result.b}
    if measured_a is not None:
        cols["a_meas_rad"] = np.asarray(measured_a, float)
    if measured_b is not None:
        cols["b_meas_rad"] = np.asarray(measured_b, float)
    if point_rms_mm is not None:
        cols["point_rms_mm"] = np.asarray(point_rms_mm, float)
    out = [write_csv(out_dir / f"{name}.csv", cols)]
    fig = new_figure(13.0 if point_rms_mm is not None else 9.0, 3.6)
    axes = fig.subplots(1, 3 if point_rms_mm is not None else 2)
    for ax, key, lab in ((axes[0], "a", "a [rad]"), (axes[1], "b", "b [rad per joint]")):
        ax.plot(T, cols[f"{key}_pred_rad"], "k--", lw=1.0, label="predicted")
        meas = cols.get(f"{key}_meas_rad")
        if meas is not None:
            ax.plot(T, meas, "k-", lw=1.0, label="measured")
        for reg, c in REGIME_COLORS.items():
            sel = np.asarray(result.regime) == reg
            ax.plot(T[sel], cols[f"{key}_pred_rad"][sel], "o", ms=3, color=c, label=f"regime {reg}")
        ax.set_xlabel(f"{side} cable tension [N]")
        ax.set_ylabel(lab)
    axes[0].legend(fontsize=7)
    if point_rms_mm is not None:
        axes[2].plot(cols["sample"], cols["point_rms_mm"], "k-o", ms=3)
        axes[2].set_xlabel("sample")
        axes[2].set_ylabel("notch-point rms of the prediction [mm]")
    fig.suptitle(r"Fig. 19: shape parameters of $\theta_j = a + b j$ (dashed: predicted)", fontsize=9)
    out.append(save_png(fig, out_dir / f"{name}.png"))
    return out


def plot_hysteresis(results: dict, out_dir, name: str = "hysteresis"):
    """Tension difference (pulled - counter) vs tip angle loops, with their areas.

    Parameters
    ----------
    results : dict
        ``{label: SimulationResult}``.
    """
    out_dir = Path(out_dir)
    rows = {"model": [], "sample": [], "load_N": [], "tip_angle_rad": []}
    fig = new_figure(6.0, 4.5)
    ax = fig.add_subplot()
    for label, r in results.items():
        side = pulled_side(r)
        load = (r.input_left - r.input_right) if side == "left" else (r.input_right - r.input_left)
        tip = r.tip_angle * (-1.0 if side == "left" else 1.0)
        area = polygon_area(load, tip)
        ax.plot(tip, load, ".-", lw=1.0, ms=3, label=f"{label}: area {area:.2f} N rad")
        rows["model"] += [label] * r.n_samples
        rows["sample"] += list(range(1, r.n_samples + 1))
        rows["load_N"] += list(load)
        rows["tip_angle_rad"] += list(tip)
    out = [write_csv(out_dir / f"{name}.csv", rows)]
    ax.set_xlabel("tip angle toward the pulled side [rad]")
    ax.set_ylabel("tension difference, pulled - counter [N]")
    ax.legend(fontsize=8)
    ax.set_title("Hysteresis of the friction model (tension vs tip angle)", fontsize=9)
    out.append(save_png(fig, out_dir / f"{name}.png"))
    return out


# ----------------------------------------------------------------------------- FIGURES entries
def _paper_result(params: FrictionParams | None = None, method: str = "fast") -> SimulationResult:
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    return simulate(t, tl, tr, params, method=method)


def fig11(out_dir: Path, result: SimulationResult | None = None, **_) -> list[Path]:
    """Fig. 11: pulled-cable tension vs displacement with regimes I-III (simulated paper test)."""
    return plot_fig11(result or _paper_result(), out_dir)


def fig17(out_dir: Path, params: FrictionParams | None = None, limit: float = 0.2, n: int = 401,
          **_) -> list[Path]:
    """Fig. 17: piecewise-linear spring of the friction model (0.4829, k_mid, 10 N m/rad)."""
    params = params or FrictionParams()
    sp = params.spring()
    th = np.linspace(-limit, limit, n)
    out_dir = Path(out_dir)
    out = [write_csv(out_dir / "fig17.csv", {"theta_rad": th, "torque_Nm": sp.torque(th),
                                             "tangent_Nm_per_rad": sp.stiffness(th)})]
    fig = new_figure(5.5, 4.0)
    ax = fig.add_subplot()
    ax.plot(th, sp.torque(th), "k-")
    for x in (params.theta_mid, params.theta_stop):
        ax.axvline(x, color="0.7", lw=0.5, ls=":")
        ax.axvline(-x, color="0.7", lw=0.5, ls=":")
    ax.set_xlabel(r"$\theta_i$ [rad]")
    ax.set_ylabel(r"$\tau_i$ [N m]")
    ax.set_title(f"Fig. 17: friction-model spring ({params.k_lin:g} / {params.k_mid:g} / "
                 f"{params.k_stop:g} N m/rad)", fontsize=9)
    out.append(save_png(fig, out_dir / "fig17.png"))
    return out


def fig18(out_dir: Path, result: SimulationResult | None = None, measured_theta=None, **_) -> list[Path]:
    """Fig. 18: predicted joint angles over the paper test (measured fit below when given)."""
    return plot_fig18(result or _paper_result(), out_dir, measured_theta)


def fig19(out_dir: Path, result: SimulationResult | None = None, measured_a=None, measured_b=None,
          **_) -> list[Path]:
    """Fig. 19: shape parameters a, b vs tension, predicted (dashed) and measured (solid when given)."""
    return plot_fig19(result or _paper_result(), out_dir, measured_a, measured_b)


def hysteresis(out_dir: Path, mus=(0.0, 0.1, 0.29), **_) -> list[Path]:
    """Hysteresis loops of tension vs tip angle for several mu_d (areas in the legend)."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=19, n_down=18)   # same tensions up and down
    res = {f"mu_d = {mu:g}": simulate(t, tl, tr, FrictionParams(mu_d=mu, mu_s=mu + 0.01 if mu else 0.0))
           for mu in mus}
    return plot_hysteresis(res, out_dir)


FIGURES = {"fig11": fig11, "fig17": fig17, "fig18": fig18, "fig19": fig19, "hysteresis": hysteresis}
