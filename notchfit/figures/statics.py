"""Figs. 7 and 8 (Sec. III) and the FEA cross-check of Sec. III-D (Fig. 10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..physics import kinematics, statics
from ..physics.geometry import Geometry, default_geometry
from ..io import load_fea_reference
from ..physics.springs import PiecewiseLinearSpring, dual_rate_spring
from ..units import MM
from . import new_figure, save_png, write_csv


def fig7(out_dir: Path, spring: PiecewiseLinearSpring | None = None, limit: float = 0.2,
         n: int = 401, **_) -> list[Path]:
    """Fig. 7: dual-rate spring torque ``τ(θ) = k(θ) θ`` (k1 0.36, k2 10 N m/rad, 0.135 rad)."""
    spring = spring or dual_rate_spring()
    th = np.linspace(-limit, limit, n)
    tau, k, ks = spring.torque(th), spring.stiffness(th), spring.secant(th)
    out = [write_csv(Path(out_dir) / "fig7.csv", {"theta_rad": th, "torque_Nm": tau,
                                                   "tangent_Nm_per_rad": k, "secant_Nm_per_rad": ks})]
    fig = new_figure(5.5, 4.0)
    ax = fig.add_subplot()
    ax.plot(th, tau, "k-")
    ax.axhline(0, color="0.7", lw=0.5)
    ax.axvline(0, color="0.7", lw=0.5)
    ax.set_xlabel(r"$\theta_i$ [rad]")
    ax.set_ylabel(r"$\tau_i$ [N m]")
    ax.set_title("Fig. 7: dual-rate spring (flexure + slot closure)", fontsize=9)
    out.append(save_png(fig, Path(out_dir) / "fig7.png"))
    return out


def fig8(out_dir: Path, geom: Geometry | None = None, f_x: float = 4.0, m_y: float = -0.05,
         **_) -> list[Path]:
    """Fig. 8: moment-then-force (A) and force-then-moment (B) reach different equilibria."""
    geom = geom or default_geometry()
    model = statics.QuasiStaticModel(geom)
    t_eval = np.linspace(0.0, 6.0, 121)
    r = statics.path_dependence(model, f_x=f_x, m_y=m_y, t_eval=t_eval)
    out_dir = Path(out_dir)
    rows = {"solution": [], "joint": [], "theta_rad": [], "x_mm": [], "z_mm": []}
    shapes = {}
    for name, tr in (("A", r.a), ("B", r.b)):
        q = kinematics.joint_positions(tr.final, geom.p) / MM
        shapes[name] = q
        for j in range(geom.n_joints + 1):
            rows["solution"].append(name)
            rows["joint"].append(j + 1)  # n + 1 = the tip point
            rows["theta_rad"].append(tr.final[j] if j < geom.n_joints else np.nan)
            rows["x_mm"].append(q[j, 0])
            rows["z_mm"].append(q[j, 1])
    out = [write_csv(out_dir / "fig8.csv", rows)]
    hist = {"time_s": r.a.t}
    for name, tr in (("A", r.a), ("B", r.b)):
        tip = kinematics.tip_pose(tr.theta, geom)
        hist[f"tip_x_mm_{name}"] = tip[:, 0] / MM
        hist[f"tip_z_mm_{name}"] = tip[:, 1] / MM
        hist[f"tip_phi_rad_{name}"] = tip[:, 2]
    out.append(write_csv(out_dir / "fig8_history.csv", hist))
    fig = new_figure(9.0, 4.2)
    ax, ax2 = fig.subplots(1, 2)
    for name, style in (("A", "C0o-"), ("B", "C3s-")):
        q = shapes[name]
        ax.plot(q[:, 0], q[:, 1], style, ms=2.5, lw=1,
                label=f"{name}: {'moment, then force' if name == 'A' else 'force, then moment'}")
        ax.annotate("", xy=(q[-1, 0] + 4 * np.sign(f_x), q[-1, 1]), xytext=(q[-1, 0], q[-1, 1]),
                    arrowprops={"arrowstyle": "->", "color": style[:2]})
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title(f"Fig. 8: f_x = {f_x:g} N, m_y = {m_y:g} N m; "
                 f"max |Δθ| = {r.max_dtheta:.3f} rad, tips {r.tip_distance / MM:.1f} mm apart", fontsize=8)
    ax2.plot(hist["time_s"], hist["tip_phi_rad_A"], "C0-", label="A")
    ax2.plot(hist["time_s"], hist["tip_phi_rad_B"], "C3-", label="B")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel(r"tip angle $\phi = \Sigma\theta$ [rad]")
    ax2.legend(fontsize=7)
    out.append(save_png(fig, out_dir / "fig8.png"))
    return out


def fig_fea(out_dir: Path, **_) -> list[Path]:
    """Sec. III-D / Fig. 10: FEA joint angles vs the rigid-link model (4-joint segment)."""
    ref = load_fea_reference()
    g4 = Geometry(n_joints=ref.n_joints, name="fea4")
    k_m = statics.equivalent_stiffness_moment(ref.moment, ref.theta_moment)
    k_t, z_f = statics.equivalent_stiffness_transverse(ref.transverse_force, ref.theta_transverse, g4.p)
    lin = lambda k: dual_rate_spring(k, k, 1.0)  # noqa: E731 - a linear spring
    th_m = statics.equilibrium(statics.QuasiStaticModel(g4, spring=lin(k_m)),
                               tip_load=[0, 0, ref.moment]).theta
    th_tip = statics.equilibrium(statics.QuasiStaticModel(g4, spring=lin(k_t)),
                                 tip_load=[ref.transverse_force, 0, 0]).theta
    th_lev = statics.equilibrium(statics.QuasiStaticModel(g4, spring=lin(k_t), load_offset=z_f - g4.tip_z),
                                 tip_load=[ref.transverse_force, 0, 0]).theta
    j = np.arange(1, ref.n_joints + 1)
    out = [write_csv(Path(out_dir) / "fig_fea.csv", {
        "joint": j, "fea_moment_rad": ref.theta_moment, "model_moment_rad": th_m,
        "fea_transverse_rad": ref.theta_transverse, "model_transverse_tipface_rad": th_tip,
        "model_transverse_fea_lever_rad": th_lev})]
    fig = new_figure(8.0, 3.8)
    a1, a2 = fig.subplots(1, 2)
    w = 0.4
    a1.bar(j - w / 2, ref.theta_moment, w, label="FEA")
    a1.bar(j + w / 2, th_m, w, label=f"model, k = {k_m:.3f} N m/rad")
    a1.set_title(f"{ref.moment:g} N m pure moment", fontsize=9)
    a2.bar(j - w / 3, ref.theta_transverse, w / 1.5, label="FEA")
    a2.bar(j, th_lev, w / 1.5, label=f"model, k = {k_t:.3f}, load at z = {z_f / MM:.2f} mm")
    a2.bar(j + w / 3, th_tip, w / 1.5, label=f"model, load at tip face z = {g4.tip_z / MM:.2f} mm")
    a2.set_title(f"{ref.transverse_force:g} N transverse tip load", fontsize=9)
    for a in (a1, a2):
        a.set_xlabel("joint")
        a.set_ylabel(r"$\theta_j$ [rad]")
        a.legend(fontsize=6)
    out.append(save_png(fig, Path(out_dir) / "fig_fea.png"))
    return out


FIGURES = {"fig7": fig7, "fig8": fig8, "fig_fea": fig_fea}
