"""The report's sections of the pipeline's steps: shape fits, simulation vs measurement, the identified model.

Each takes the report's inputs (:class:`notchfit.report.Inputs`) and returns
typed blocks (:mod:`notchfit.report.forms`). Notch-point studies in mm and
rad, joint-angle studies (``angle_fits.csv``) in degrees throughout.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import io as nio
from ..figures.summary import fit_errors_figure, simulation_figure
from ..physics.friction import FrictionParams
from ..units import DEG
from .forms import Heading, NotAvailable, Para, Table
from .diagnosis import quantity
from .page import figure, num
from .params import params_text
from .tables import fit_tables, peak_index, simulation_table

__all__ = ["FitSummary", "fit_section", "fit_summary", "fit_summary_text", "identify_section",
           "simulation_section"]

_PAPER = FrictionParams()


@dataclass(frozen=True)
class FitSummary:
    """Per shape model over every experiment: ``model, samples, failed, rms, max`` in ``unit``."""

    table: pd.DataFrame
    unit: str


def _read_fits(out_dir) -> tuple[list, str]:
    frames = []
    for p in nio.find_output(out_dir, "fits.csv").values():
        try:
            f = nio.read_fits(p)
            ok = f["success"].astype(str).str.lower().isin(["true", "1"]) if "success" in f else True
            frames.append(f.assign(ok=ok, rms=f["rms_mm"], max=f["max_mm"]))
        except (ValueError, FileNotFoundError):
            pass
    if frames:
        return frames, "mm"
    for p in nio.find_output(out_dir, "angle_fits.csv").values():
        try:
            f = nio.read_angle_fits(p)
            frames.append(f.assign(ok=f["success"] if "success" in f else True, rms=f["rms_deg"], max=f["max_deg"]))
        except (ValueError, FileNotFoundError):
            pass
    return frames, "deg"


def fit_summary(out_dir) -> FitSummary | None:
    """Per model over every experiment: samples, failed fits, rms of all points or angles, max error."""
    frames, unit = _read_fits(out_dir)
    if not frames:
        return None
    fits = pd.concat(frames, ignore_index=True)
    rows = []
    for model, g in fits.groupby("model", sort=False):
        ok = g["ok"].astype(bool)
        r = g.loc[ok, "rms"].to_numpy(float)
        r = r[np.isfinite(r)]
        rows.append({"model": model, "samples": len(g), "failed": int((~ok).sum()),
                     "rms": float(np.sqrt(np.mean(r ** 2))) if r.size else np.nan,
                     "max": float(np.nanmax(g.loc[ok, "max"])) if ok.any() else np.nan})
    return FitSummary(pd.DataFrame(rows), unit)


def _fit_summary(inp) -> FitSummary | None:
    return fit_summary(inp.out)


def fit_summary_text(inp) -> str:
    """The first section's line on the shape fits."""
    st = inp.once(_fit_summary)
    if st is None:
        return "not available: no fits.csv or angle_fits.csv (run `notchfit fit`)"
    u = "°" if st.unit == "deg" else " mm"
    txt = "; ".join(f"{r.model} {num(r.rms)}{u} rms (max {num(r.max, 2)}{u})" for r in st.table.itertuples())
    if st.unit == "mm":
        txt += " — the paper reports max 0.35 mm linear, 3.36 mm constant curvature (Sec. IV-A)"
    return txt + "."


# ----------------------------------------------------------------------------- fit
def fit_section(inp) -> list:
    st = inp.once(_fit_summary)
    if st is None:
        return [NotAvailable("no fits.csv or angle_fits.csv in the output folder (run `notchfit fit STUDY --out DIR`)")]
    u = st.unit
    models = Table.of([{"model": r.model, "samples": r.samples, "failed": r.failed, f"rms [{u}]": num(r.rms),
                        f"max [{u}]": num(r.max)} for r in st.table.itertuples()])
    by_point, by_sample, per_exp = fit_tables(inp)
    what = ("Each sample's measured joint angles fitted alone by each shape model (no simulation)."
            if u == "deg" else "Each sample's measured points fitted alone by each shape model, after one plane "
            "transform per experiment (no simulation; Sec. IV-A).")
    parts = [Para(what), models, Table.of(per_exp)]
    if by_point is not None and len(by_point):
        parts.append(figure(fit_errors_figure(by_point, by_sample),
                            "Left: fit error by notch point over all samples (Figs. 13–14 pooled), right: each "
                            "sample's fit error against the tension difference; a model that captures the shape "
                            "stays flat and low in both.", "fit errors by point and by sample"))
    return parts


# ----------------------------------------------------------------------------- simulation
def _sim_params(inp) -> Para:
    rec = inp.runs.get("simulate")
    if rec is None or (rec.params is None and not rec.params_by_experiment):
        return Para("**Parameters:** not recorded (no simulate_run.json).", style="params")
    ang = inp.angles
    if rec.params is None:
        return Para("**Parameters** differ per experiment (simulate_run.json): " + "; ".join(
            f"{k}: {', '.join(params_text(v, angles=ang))}" for k, v in rec.params_by_experiment.items()) + ".",
            style="params")
    params = rec.params
    numeric = {k: v for k, v in params.items() if isinstance(v, float)}
    paper = {f.name: getattr(_PAPER, f.name) for f in dataclasses.fields(FrictionParams)}
    changed = {k: v for k, v in numeric.items() if isinstance(paper.get(k), (int, float))
               and not isinstance(paper.get(k), bool) and not np.isclose(v, paper[k])}
    material = params.get("spring_law") == "material"
    core_keys = ("E_lin", "E_se", "strain_lower", "mu_d", "mu_s") if material else \
        ("k_lin", "k_mid", "mu_d", "mu_s", "b", "v_thr")
    core = {k: numeric[k] for k in core_keys if k in numeric}
    if rec.model_file:
        what = f"from the model file `{inp.rel(rec.model_file) if rec.model_file.startswith('/') else rec.model_file}`"
    elif not changed:
        what = "**the paper's default values**, not calibrated to this tube (the diagnosis below calibrates them)"
    elif rec.param_overrides:
        what = f"the defaults with `--param {' --param '.join(rec.param_overrides)}`"
    else:
        what = "**notchfit's default values for this geometry** (notchfit.physics.friction.default_params), not calibrated"
    laws = (f" (springs from the material, {params.get('friction_law', '')} friction)" if material else "")
    ext = {k: v for k, v in changed.items() if k in ("proximal_beta", "hysteresis_torque", "tip_force_x",
                                                      "tip_force_z", "stiffness_gradient")}
    return Para(f"**Parameters:** {what}{laws}: {', '.join(params_text(core, angles=ang))}"
                + (f"; extension {', '.join(params_text(ext, angles=ang))}" if ext else "; no extension") + ".",
                style="params")


def _angle_simulation_rows(inp) -> list[dict]:
    """Per experiment of an angle study: the simulation's joint-angle rms [deg] (simulate_run.json) and the
    tip angle at peak, measured (angles.csv) and simulated (simulation.csv) [deg]."""
    rec = inp.runs.get("simulate")
    rms = rec.angle_rms_deg if rec is not None else {}
    rows = []
    for name, path in nio.find_output(inp.out, "simulation.csv").items():
        e = inp.experiment(name)
        if e is None or e.angles is None:
            continue
        sim = nio.read_simulation(path)
        cols = [f"theta_{j}" for j in range(1, e.geometry.n_joints + 1)]
        k = peak_index(np.nan_to_num(e.tension_left), np.nan_to_num(e.tension_right))
        row = {"experiment": e.name, "joint-angle rms [deg]": num(rms.get(e.name, math.nan))}
        row["tip angle at peak, measured [deg]"] = num(np.nansum(e.angles[k]) / DEG, sign=True)
        if all(c in sim for c in cols) and k < len(sim):
            row["tip angle at peak, simulated [deg]"] = num(sim[cols].to_numpy(float)[k].sum() / DEG, sign=True)
        rows.append(row)
    return rows


def simulation_section(inp) -> list:
    if not nio.find_output(inp.out, "simulation.csv"):
        return [NotAvailable("no simulation.csv in the output folder (run `notchfit simulate STUDY --out DIR`)")]
    parts = [_sim_params(inp), Para("The friction simulator driven by each experiment's measured tensions, compared "
                                    "with the measured shapes.")]
    if inp.angles:
        rows = _angle_simulation_rows(inp)
        parts.append(Table.of(rows) if rows else NotAvailable("the study's measured angles could not be read"))
        return parts
    cmp, rows = simulation_table(inp)
    if not rows:
        parts.append(NotAvailable("no simulation_vs_measured.csv: the experiments had no measured points when "
                                  "`simulate` ran (run `notchfit detect` first and give simulate the same --out, or "
                                  "--points DIR)"))
        return parts
    parts.append(Table.of(rows))
    parts.append(figure(simulation_figure(cmp),
                        "a and b of the measured shapes (solid) and of the simulation (dashed) against the tension "
                        "difference, one colour per experiment (Fig. 19), and the simulation's point error per "
                        "sample: where dashed leaves solid, the model misses the shape.",
                        "simulated and measured shape parameters"))
    return parts


# ----------------------------------------------------------------------------- identify
def _tube_rows(r, u) -> list[dict]:
    rows = []
    for t in r.tubes:
        def pm(vals, ses, digits=2):
            return ", ".join(f"{num(v, digits)}" + (f" ± {num(s, 1)}" if math.isfinite(s) else "")
                             for v, s in zip(vals, ses or (math.nan,) * len(vals)))
        rows.append({"tube": t.label, "experiments": ", ".join(t.experiments),
                     "rest angles [deg]": pm(t.rest_angle_deg, t.rest_angle_se_deg),
                     "cut-depth offsets [µm]": pm(t.slot_depth_offset_um, t.slot_depth_offset_se_um),
                     f"predicted from the other tubes [{u}]": num(t.heldout_by_geometry)})
    return rows


#: The per-tube unknowns of identify.json (``free_per_tube``), in words.
_PER_TUBE = {"rest_angle_rad": "rest angles", "slot_depth_offset_m": "cut-depth offsets"}


def identify_section(inp) -> list:
    r = inp.identify
    if r is None:
        return [NotAvailable(inp.identify_error or "no identify.json in the output folder "
                                                   "(run `notchfit identify STUDY --out DIR`)")]
    u = r.unit
    parts = [Para(f"**Identified** on every experiment ({'converged' if r.converged else 'not converged: ' + r.message}"
                  f"), `{r.model_file}`: {', '.join(params_text(r.params, r.se, angles=inp.angles))}"
                  + (f"; per tube: {', '.join(_PER_TUBE.get(k, k) for k in r.free_per_tube)}"
                     if r.free_per_tube else "") + ".", style="params"),
             Para(f"Training rms {quantity(r.train_rms, u)}; held-out rms {quantity(r.heldout_rms, u)} (each "
                  "experiment predicted by a model fitted without it).")]
    per = [{"experiment": k, f"held out [{u}]": num(v), f"trained [{u}]": num(r.train.get(k, math.nan))}
           for k, v in r.heldout.items()]
    parts.append(Table.of(per))
    if r.tubes:
        parts += [Heading("Each tube"), Table.of(_tube_rows(r, u), text_columns=("rest angles [deg]",
                                                                                  "cut-depth offsets [µm]"))]
        if len(r.tubes) > 1:
            parts.append(Para(f"The last column is each tube predicted by a model fitted on the other tubes only, "
                              "from its geometry file (its rest angles and cut depths as the file gives them): the "
                              "error a tube never measured would have."))
    return parts
