"""Figs. 3, 5 and 6: cable segment length models over the operating range (Sec. II-D)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..physics import cables
from ..physics.geometry import Geometry, default_geometry
from . import new_figure, save_png, write_csv

UM = 1e6


def segment_maps(geom: Geometry, limit: float = 0.14, n_grid: int = 141, side: int = cables.RIGHT):
    """Grids of one segment's lengths over ``|θ_i|, |θ_{i+1}| ≤ limit``.

    Returns
    -------
    dict with ``theta_i``, ``theta_ip1`` (n_grid, n_grid) [rad] and the exact
    ``L``, simplified ``LS`` and lower bound ``LDM`` [m].
    """
    t = np.linspace(-limit, limit, n_grid)
    a, b = np.meshgrid(t, t, indexing="ij")
    return {"theta_i": a, "theta_ip1": b,
            "L": cables.segment_length(a, b, geom, side),
            "LS": cables.segment_length_simple(a, b, geom, side),
            "LDM": cables.segment_length_min(a, b, geom, side)}


def _contour(path_png, a, b, val, title, levels):
    fig = new_figure(5.6, 4.8)
    ax = fig.add_subplot()
    cf = ax.contourf(a, b, val, levels=levels, cmap="viridis")
    cs = ax.contour(a, b, val, levels=levels, colors="k", linewidths=0.5)
    ax.clabel(cs, fmt="%g", fontsize=7)
    fig.colorbar(cf, ax=ax, label="µm")
    ax.set_xlabel(r"$\theta_i$ [rad]")
    ax.set_ylabel(r"$\theta_{i+1}$ [rad]")
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal")
    return save_png(fig, path_png)


def _csv(path, m, name, val):
    return write_csv(path, {"theta_i_rad": m["theta_i"].ravel(), "theta_ip1_rad": m["theta_ip1"].ravel(),
                            name: val.ravel()})


def fig3(out_dir: Path, geom: Geometry | None = None, n_grid: int = 141, **_) -> list[Path]:
    """Fig. 3: error ``L_Ri - L_RSi`` of the simplified segment length [µm]."""
    geom = geom or default_geometry()
    m = segment_maps(geom, n_grid=n_grid)
    err = (m["L"] - m["LS"]) * UM
    frac = float(np.mean(np.abs(err) < 5.0))
    out = [_csv(Path(out_dir) / "fig3.csv", m, "error_um", err)]
    out.append(_contour(Path(out_dir) / "fig3.png", m["theta_i"], m["theta_ip1"], err,
                        f"Fig. 3: $L_{{Ri}} - L_{{RSi}}$ [µm]\n< 5 µm on {100 * frac:.1f}% "
                        f"of the grid (nominal {(geom.p - 2 * geom.r_z) * UM:.0f} µm)",
                        [0, 0.5, 1, 2, 3, 4, 5, 6, 7]))
    return out


def fig5(out_dir: Path, geom: Geometry | None = None, n_grid: int = 141, **_) -> list[Path]:
    """Fig. 5: ``max(|L_RSi - L_Ri|, |L_RSi - L_DMi|)`` [µm] with channel side play."""
    geom = geom or default_geometry()
    m = segment_maps(geom, n_grid=n_grid)
    worst = np.maximum(np.abs(m["LS"] - m["L"]), np.abs(m["LS"] - m["LDM"])) * UM
    out = [_csv(Path(out_dir) / "fig5.csv", m, "max_error_um", worst)]
    play = (geom.channel_radius - geom.cable_radius) * UM
    out.append(_contour(Path(out_dir) / "fig5.png", m["theta_i"], m["theta_ip1"], worst,
                        f"Fig. 5: max(|$L_{{RSi}}-L_{{Ri}}$|, |$L_{{RSi}}-L_{{DMi}}$|) [µm], "
                        f"side play ±{play:.0f} µm", 10))
    return out


def fig6(out_dir: Path, geom: Geometry | None = None, n_grid: int = 141, **_) -> list[Path]:
    """Fig. 6: simplified segment length ``L_RSi = p - (θ_i + θ_{i+1}) r_x - 2 r_z`` [µm]."""
    geom = geom or default_geometry()
    m = segment_maps(geom, n_grid=n_grid)
    ls = m["LS"] * UM
    out = [_csv(Path(out_dir) / "fig6.csv", m, "length_um", ls)]
    out.append(_contour(Path(out_dir) / "fig6.png", m["theta_i"], m["theta_ip1"], ls,
                        "Fig. 6: $L_{RSi}$ [µm]", np.arange(100, 1600, 100)))
    return out


FIGURES = {"fig3": fig3, "fig5": fig5, "fig6": fig6}
