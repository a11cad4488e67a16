"""The sections of ``report.html`` (:mod:`notchfit.report`): each takes the report's inputs, returns HTML.

Every figure has a one-sentence caption saying what it shows and how to read
it; every section that shows a simulation states its parameters in a
``<p class="params">``; ``a``, ``b`` and angles keep the one convention the
page states at the top (manipulator frame, rad and rad per joint).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from .. import io as nio
from ..causes import REGISTRY
from ..figures.summary import (candidates_figure, fit_errors_figure, loops_figure, residual_map_figure,
                               simulation_figure, thumbnails_figure)
from ..friction import FrictionParams
from .page import esc, figure_html, image_html, link, na, num, pct, table
from .tables import (b_at_peak_rows, detection_rows, diagnosis_loops, fit_tables, simulation_table,
                            thumbnail_panels)

__all__ = ["CAUSE_TEXT", "causes_of", "unit_of", "detection_section", "diagnosis_section", "files_section",
           "fit_section", "fit_summary", "glance_section", "simulation_section", "study_section"]

#: What each cause means for the robot, in a phrase (the ids of docs/data-formats.md).
CAUSE_TEXT = {
    **{c.id: c.label for c in REGISTRY.values()},
    "none": "nothing beyond the measurement noise: the calibrated paper model explains the data",
    "unexplained": "a significant error that none of the candidate effects removes",
}
#: Symbols and units of the model parameters, for the parameter statements (and the factor from the SI
#: value in diagnosis.json to the unit shown: lengths in mm).
PARAM_TEXT = {"k_lin": ("k_lin", "N m/rad"), "k_mid": ("k_mid", "N m/rad"), "k_stop": ("k_stop", "N m/rad"),
              "theta_mid": ("θ_mid", "rad"), "theta_stop": ("θ_stop", "rad"), "mu_d": ("μ_d", ""),
              "mu_s": ("μ_s", ""), "b": ("damping b", "N m s/rad"), "v_thr": ("v_thr", "m/s"),
              "proximal_beta": ("β", ""), "hysteresis_torque": ("hysteresis torque", "N m"),
              "hysteresis_onset": ("hysteresis onset", "rad"), "hysteresis_yield": ("yield angle", "rad"),
              "E_lin": ("E_lin", "GPa", 1e-9), "E_se": ("E_se", "GPa", 1e-9),
              "tip_force_x": ("F_x", "N"), "tip_force_z": ("F_z", "N"), "stiffness_gradient": ("gradient", ""),
              "mu_s_minus_mu_d": ("μ_s − μ_d", ""), "mu_s_excess": ("μ_s − μ_d", ""),
              "scale_error": ("scale error", ""), "k_radial": ("radial k", ""),
              "warp_center_x": ("warp centre x", "mm", 1e3), "warp_center_y": ("warp centre y", "mm", 1e3)}
_PAPER = FrictionParams()


def unit_of(d: dict) -> str:
    """The file unit of a diagnosis's errors: ``"mm"`` (notch points) or ``"deg"`` (joint angles)."""
    return "deg" if d.get("metric") == "angles" else "mm"


def _what(d: dict) -> str:
    return "joint-angle" if unit_of(d) == "deg" else "notch-point"


def _named_models(d: dict) -> set[str]:
    """The candidate rows of the named model: each named cause, and their pair (``a+b``) when two."""
    causes = causes_of(d)
    return {*causes, "+".join(causes)}


def causes_of(d: dict) -> list[str]:
    """The named causes: ``causes`` when the diagnosis lists them (first removes most), else ``[cause]``."""
    causes = d.get("causes")
    return [str(c) for c in causes] if isinstance(causes, list) and causes else [str(d.get("cause"))]


def _param(name: str, value, se=None) -> str:
    sym, unit, *factor = PARAM_TEXT.get(name, (name, ""))
    f = factor[0] if factor else 1.0
    txt = f"{sym} = {num(value * f, 4, trim=True)}" + (f" ± {num(se * f, 2)}" if se is not None else "")
    return txt + (f" {unit}" if unit else "")


def _params(values: dict, se: dict | None = None) -> str:
    se = se or {}
    return ", ".join(_param(k, v, se.get(k)) for k, v in values.items() if isinstance(v, (int, float)))


def _fit_summary(inp) -> pd.DataFrame | None:
    return fit_summary(inp.out)


def fit_summary(out_dir) -> pd.DataFrame | None:
    """Per model over every experiment: samples, failed fits, rms of all points [mm], max error [mm]."""
    frames = []
    for p in nio.find_output(out_dir, "fits.csv").values():
        try:
            frames.append(nio.read_fits(p))
        except (ValueError, FileNotFoundError):
            pass
    if not frames:
        return None
    fits = pd.concat(frames, ignore_index=True)
    rows = []
    for model, g in fits.groupby("model", sort=False):
        ok = g["success"].astype(str).str.lower().isin(["true", "1"]) if "success" in g else \
            pd.Series(True, index=g.index)
        r = g.loc[ok, "rms_mm"].to_numpy(float)
        r = r[np.isfinite(r)]
        rows.append({"model": model, "samples": len(g), "failed": int((~ok).sum()),
                     "rms_mm": float(np.sqrt(np.mean(r ** 2))) if r.size else np.nan,
                     "max_mm": float(np.nanmax(g.loc[ok, "max_mm"])) if ok.any() else np.nan})
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- at a glance
def _measured_text(inp) -> str:
    exps = inp.exps
    if not exps:
        return na(inp.why)
    n_s = sum(e.n_samples for e in exps)
    left = [e.name for e in exps if inp.pulled[e.name] < 0]
    peak = [max(np.max(e.tension_left), np.max(e.tension_right)) for e in exps]
    counter = [float(np.median(e.tension_right if inp.pulled[e.name] < 0 else e.tension_left)) for e in exps]
    det = inp.once(detection_rows)
    if det:
        sig = np.nanmedian([r["_sigma"] for r in det])
        src = (f"{exps[0].geometry.n_points} notch corners per sample found by <code>detect</code> in "
               f"{sum(r['images'] for r in det)} images (median σ {num(sig, 2)} mm)")
    elif _angles_only(exps):
        src = f"{exps[0].geometry.n_joints} joint angles per sample given in angles.csv"
    else:
        src = f"{exps[0].geometry.n_points} notch points per sample given in notch_points.csv"
    tendons = exps[0].geometry.tendons
    if len(tendons) == 1:
        pulls = f"one tendon ({tendons[0]}) pulled, up to {num(min(peak), 2)}–{num(max(peak), 2)} N"
    else:
        pulls = (f"the left cable pulled in {len(left)}, the right in {len(exps) - len(left)}, up to "
                 f"{num(min(peak), 2)}–{num(max(peak), 2)} N against {num(min(counter), 2)}–"
                 f"{num(max(counter), 2)} N on the other cable")
    return (f"{len(exps)} bend–unbend tests ({esc(', '.join(e.name for e in exps))}), {n_s} samples: "
            f"{pulls}; {src}.")


def _angles_only(exps) -> bool:
    """Every experiment measured as joint angles (angles.csv), none as notch points or images."""
    return bool(exps) and all(e.points is None and not e.has_images and e.angles is not None for e in exps)


def _answer_text(inp) -> tuple[str, str]:
    d = inp.diagnosis
    if d is None:
        why = inp.diagnosis_error or "no diagnosis.json (run `notchfit diagnose STUDY --out DIR`)"
        return na(why), na(why)
    causes = causes_of(d)
    ans = "; ".join(f"<b>{esc(c.replace('_', ' '))}</b>: {esc(CAUSE_TEXT.get(c, ''))}" for c in causes) + "."
    g = d.get("gain") or {}
    u = unit_of(d)
    noise = d.get(f"noise_rms_{u}")
    gain = (f"held-out {_what(d)} error {num(g.get('baseline'))} {u} → {num(g.get('extended'))} {u} rms "
            f"(<b>{pct(g.get('reduction_pct'))} lower</b>) on experiments left out of every fit"
            + (f"; measurement noise floor {num(noise)} {u}" if noise is not None else "") + ".")
    return ans, gain


def _assumed_text(inp) -> str:
    d = inp.diagnosis or {}
    b = d.get("baseline") or {}
    fixed = b.get("fixed") or {}
    parts = []
    model = b.get("model", "moses2015")
    names = ", ".join(PARAM_TEXT.get(k, (k, ""))[0] for k in (b.get("params") or {}))
    if b and model == "moses2015":
        parts.append(f"the paper's cable-friction model (Sec. IV-B) with {names} calibrated on the training "
                     "experiments" + (f", {_params(fixed)}" if fixed else "") + " and the spring's break "
                     "points at the paper's values; judged on experiments held out of every fit "
                     "(cross-validation by experiment)")
    elif b:
        law = model.rsplit("-", 1)[-1]
        fixed = {k: v for k, v in fixed.items() if k != "b"}
        parts.append(f"the tube's default model (<code>{esc(model)}</code>: springs from the material and each "
                     f"notch's section, {esc(law)} friction, damping at the quasi-static time constant) with "
                     f"{names} calibrated on the training experiments" + (f", {_params(fixed)}" if fixed else "")
                     + "; judged on experiments held out of every fit (cross-validation by experiment)")
    if inp.exps:
        g = inp.exps[0].geometry
        parts.append(f"geometry <code>{esc(g.name)}</code> ({g.n_joints} joints)")
        text = (d.get("protocol") or {}).get("text")
        if text:
            parts.append(f"the drive's protocol: {esc(text.rstrip('.'))}")
        elif any(e.ramp_time is None for e in inp.exps):
            parts.append("each sample's tensions applied as a step, the tube at rest when imaged (no "
                         "[protocol] in experiment.toml)")
    parts.append("the tension measured at the load cell drives the model")
    return "; ".join(parts) + "."


def _synthetic_note(inp) -> str:
    t = inp.truth
    if not t:
        return ""
    img = any(e.has_images for e in inp.exps or [])
    return ('<p class="note"><b>Synthetic data.</b> This study was generated by <code>notchfit synth</code> '
            f"(recipe <code>{esc(t.get('recipe'))}</code>, seed {esc(t.get('seed'))}): shapes from notchfit's "
            "own friction model plus the recipe's hidden effect(s), tensions with load-cell noise"
            + ("; the images are renders from an exactly known camera, sharp and evenly lit, so the "
               "detection errors here are far below a photograph's" if img else "")
            + ". Real data add effects that no model has: expect larger errors.</p>")


def _check_row(inp) -> list[tuple[str, str]]:
    t, d = inp.truth, inp.diagnosis
    if not t or not d:
        return []
    cause = t.get("cause")
    hidden = [str(c) for c in cause] if isinstance(cause, list) else [str(cause)]
    eff = ", ".join(f"{k} = {num(v)}" for k, v in (t.get("effect") or {}).items())
    named = causes_of(d) if causes_of(d) != ["none"] else []
    ok = sorted(c for c in hidden if c != "none") == sorted(named)
    what = " and ".join(c.replace("_", " ") for c in hidden)
    return [("Check", f"the synthetic study hid <b>{esc(what)}</b>"
                      f"{' (' + esc(eff) + ')' if eff else ''}; the diagnosis "
                      + (("named it." if len(hidden) == 1 else "named them.") if ok
                         else f"named {esc(', '.join(causes_of(d)))}."))]


CONVENTIONS = ("<p class=\"conv\"><b>Units and signs in every section.</b> Lengths in mm; joint angles "
               "θ<sub>j</sub>, the tip angle Σθ and <i>a</i> in rad, <i>b</i> in rad per joint, from the "
               "linear shape θ<sub>j</sub> = <i>a</i> + <i>b</i> j (j = 1 at the base). Signs are those of "
               "the manipulator frame: θ &gt; 0 bends toward +x, the right cable (CONVENTIONS.md), so a "
               "test that pulls the left cable has <i>a</i> &lt; 0. Errors are distances between "
               "measured and modelled notch points in the bending plane (Sec. IV-A), rms over points and "
               "samples; for joint angles measured directly (angles.csv) they are joint-angle differences "
               "in degrees, rms over joints and samples. The diagnosis's signatures pool both pull directions and are signed toward the "
               "pulled cable. “At peak”: the sample with the largest |T_left − T_right|.</p>")


def glance_section(inp) -> str:
    ans, gain = _answer_text(inp)
    st = inp.once(_fit_summary)
    shape = na("no fits.csv (run `notchfit fit`)") if st is None else "; ".join(
        f"{esc(r.model)} {num(r.rms_mm)} mm rms (max {num(r.max_mm, 2)} mm)" for r in st.itertuples()) + \
        " — the paper reports max 0.35 mm linear, 3.36 mm constant curvature (Sec. IV-A)."
    rows = [("Question", "Does the paper's cable-friction model (Moses et al. 2015, Sec. IV-B) predict the "
                         "measured shapes of this tube, and if not, which physical effect does it miss?"),
            ("Measured", _measured_text(inp)), ("Cause", ans), ("Gain", gain),
            ("Assumed", _assumed_text(inp)), ("Shape fits", shape)] + _check_row(inp)
    body = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="glance">{body}</table>{_synthetic_note(inp)}{CONVENTIONS}'


# ----------------------------------------------------------------------------- study
def study_section(inp) -> str:
    if inp.exps is None:
        return na(inp.why)
    rows = []
    for e in inp.exps:
        side = inp.pulled[e.name]
        pulled, other = (e.tension_right, e.tension_left) if side > 0 else (e.tension_left, e.tension_right)
        rows.append({"experiment": e.name, "pulled cable": "right" if side > 0 else "left",
                     "peak [N]": num(np.max(pulled)), "other cable [N]": num(np.median(other)),
                     "samples": e.n_samples,
                     "points from": "notch_points.csv" if e.points is not None else
                     ("images (detect)" if e.has_images else "–"),
                     "tensions": "step" if not e.ramp_time else f"ramp {num(e.ramp_time, 2)} s"})
    g = inp.exps[0].geometry
    return (f"<p>Study <code>{esc(inp.rel(inp.study_path))}</code>: {len(inp.exps)} experiment(s), geometry "
            f"<code>{esc(g.name)}</code> ({g.n_joints} joints, {g.n_points} notch points).</p>" + table(rows))


# ----------------------------------------------------------------------------- detection
def _camera_text(inp) -> str:
    files = []
    for e in inp.exps or []:
        if e.calibration_path is not None and e.calibration_path.resolve() not in files:
            files.append(e.calibration_path.resolve())
    if not files:
        return "<p>No camera file: the experiments give notch points, or the scale came from the tube's " \
               "diameter (detect_run.json).</p>"
    parts = []
    for f in files:
        try:
            cam = nio.read_camera(f)
        except Exception as exc:  # noqa: BLE001 - a report shows what it can
            parts.append(na(str(exc)))
            continue
        K = cam.camera_matrix
        rms = cam.rms if np.isfinite(cam.rms) and cam.rms >= 0 else None
        parts.append(f"<p>Camera file <code>{esc(inp.rel(f))}</code>: {cam.image_size[0]} × {cam.image_size[1]} px, "
                     f"f = {num(K[0, 0])} px, bending plane {num(np.linalg.norm(cam.plane_tvec) * 1e3)} mm "
                     "from the camera; reprojection error "
                     + (f"{num(rms, 2)} px" if rms is not None else "not measured (a camera file written "
                        "with the renders, not calibrated from views)") + ".</p>")
    return "".join(parts)


def detection_section(inp) -> str:
    rows = inp.once(detection_rows)
    if not rows:
        if inp.exps is not None and not any(e.has_images for e in inp.exps):
            given = "joint angles were given in angles.csv" if _angles_only(inp.exps) else \
                "notch points were given in notch_points.csv"
            return na(f"the study has no images: {given}, nothing was detected")
        return na("no detections.csv in the output folder (run `notchfit detect STUDY --out DIR`)")
    parts = [_camera_text(inp), table([{k: v for k, v in r.items() if not k.startswith("_")} for r in rows])]
    sig = np.nanmedian([r["_sigma"] for r in rows])
    note = (" On these renders it is the edge-fit uncertainty of an ideal image; on photographs blur, "
            "noise, contrast and resolution raise it (docs/robustness.md measures each)." if inp.truth else "")
    parts.append(f"<p>σ is each corner's uncertainty from its edge-line fits (median {num(sig, 2)} mm)."
                 f"{note}</p>")
    panels = thumbnail_panels(inp)
    if panels:
        parts.append(figure_html(thumbnails_figure(panels),
                                 "Detected corners on a crop around the tube (green: ok, orange: ambiguous, red: "
                                 "occluded; a few point numbers written beside their corner): check that "
                                 "every notch has its two corners and the numbers run base → tip → base.",
                                 "detected corners on three samples"))
    return "\n".join(parts)


# ----------------------------------------------------------------------------- fit
def fit_section(inp) -> str:
    st = inp.once(_fit_summary)
    if st is None:
        return na("no fits.csv in the output folder (run `notchfit fit STUDY --out DIR`)")
    models = table([{"model": r.model, "samples": r.samples, "failed": r.failed, "rms [mm]": num(r.rms_mm),
                     "max [mm]": num(r.max_mm)} for r in st.itertuples()])
    by_point, by_sample, per_exp = fit_tables(inp)
    parts = ["<p>Each sample's measured points fitted alone by each shape model, after one plane "
             "transform per experiment (no simulation; Sec. IV-A).</p>", models]
    if per_exp:
        parts.append(table(per_exp))
    if by_point is not None and len(by_point):
        parts.append(figure_html(fit_errors_figure(by_point, by_sample),
                                 "Left: fit error by notch point over all samples (Figs. 13–14 pooled), "
                                 "right: each sample's fit error against the tension difference; a model "
                                 "that captures the shape stays flat and low in both.",
                                 "fit errors by point and by sample"))
    return "\n".join(parts)


# ----------------------------------------------------------------------------- simulation
def _sim_params_text(inp) -> str:
    rec = inp.runs.get("simulate") or {}
    params, model = rec.get("params"), rec.get("model_file")
    if params is None and rec.get("params_by_experiment"):
        return ('<p class="params"><b>Parameters</b> differ per experiment (simulate_run.json): '
                + "; ".join(f"{esc(k)}: {esc(_params(v))}" for k, v in rec["params_by_experiment"].items())
                + ".</p>")
    if params is None:
        return '<p class="params"><b>Parameters:</b> not recorded (no simulate_run.json).</p>'
    fields = {f.name for f in dataclasses.fields(FrictionParams)}
    paper = {k: getattr(_PAPER, k) for k in fields}
    changed = {k: v for k, v in params.items() if k in paper and not np.isclose(v, paper[k])}
    core = {k: params[k] for k in ("k_lin", "k_mid", "mu_d", "mu_s", "b", "v_thr") if k in params}
    overrides = rec.get("param_overrides") or []
    if model:
        what = f"from the model file <code>{esc(model)}</code>"
    elif not changed:
        what = "<b>the paper's default values</b>, not calibrated to this tube (the diagnosis below calibrates them)"
    elif overrides:
        what = f"the defaults with <code>--param {esc(' --param '.join(overrides))}</code>"
    else:
        what = "<b>notchfit's default values for this geometry</b> (notchfit.friction.default_params), not calibrated"
    ext = {k: v for k, v in changed.items() if k in ("proximal_beta", "hysteresis_torque", "tip_force_x",
                                                      "tip_force_z", "stiffness_gradient")}
    return (f'<p class="params"><b>Parameters:</b> {what}: {esc(_params(core))}'
            + (f"; extension {esc(_params(ext))}" if ext else "; no extension") + ".</p>")


def simulation_section(inp) -> str:
    found = nio.find_output(inp.out, "simulation.csv")
    if not found:
        return na("no simulation.csv in the output folder (run `notchfit simulate STUDY --out DIR`)")
    cmp, rows = simulation_table(inp)
    parts = [_sim_params_text(inp),
             "<p>The friction simulator driven by each experiment's measured tensions, compared with the "
             "measured shapes.</p>"]
    if not rows:
        parts.append(na("no simulation_vs_measured.csv: the experiments had no measured points when "
                        "`simulate` ran (run `notchfit detect` first and give simulate the same --out, or "
                        "--points DIR)"))
        return "\n".join(parts)
    parts.append(table(rows))
    parts.append(figure_html(simulation_figure(cmp),
                             "a and b of the measured shapes (solid) and of the simulation (dashed) against "
                             "the tension difference, one colour per experiment (Fig. 19), and the "
                             "simulation's point error per sample: where dashed leaves solid, the model "
                             "misses the shape.", "simulated and measured shape parameters"))
    return "\n".join(parts)


# ----------------------------------------------------------------------------- diagnosis
def _diag_params_text(d: dict) -> str:
    b = d.get("baseline") or {}
    ext = d.get("extended_model") or {}
    model = b.get("model", "moses2015")
    paper = model == "moses2015"
    which = "the paper's model" if paper else f"the tube's default model ({model})"
    fixed = {k: v for k, v in (b.get("fixed") or {}).items() if paper or k != "b"}
    txt = (f"<b>Parameters:</b> baseline = {esc(which)} calibrated on this study: "
           f"{esc(_params(b.get('params') or {}, b.get('se')))}"
           + (f"; fixed {esc(_params(fixed))}" if fixed else "")
           + ("; the rest at the paper's values." if paper else "; the rest at the tube's defaults."))
    if ext.get("params"):
        named = ", ".join(ext.get("causes") or [ext.get("cause", "")])
        txt += (f" Extended ({esc(str(named).replace('_', ' '))}, "
                f"<code>{esc(d.get('extended_model_file', 'extended_model.toml'))}</code>, refitted on all "
                f"experiments): {esc(_params(ext['params'], ext.get('se')))}.")
    return f'<p class="params">{txt}</p>'


def _cause_html(inp, d: dict, cause: str, k: int) -> str:
    """A named cause: what it means, what it removes on held-out data, and its figure."""
    u = unit_of(d)
    head = f"<h3>Cause {k}: {esc(cause.replace('_', ' '))}</h3><p>{esc(CAUSE_TEXT.get(cause, ''))}.</p>"
    contrib = {c.get("cause"): c for c in d.get("contributions") or []}.get(cause)
    c = {c.get("cause"): c for c in d.get("candidates") or []}.get(cause)
    if contrib is None and c is None:
        b = d.get("baseline") or {}
        return head + (f"<p>Baseline held-out error {num(b.get(f'heldout_rms_{u}'))} {u}, noise floor "
                       f"{num(d.get(f'noise_rms_{u}'))} {u}.</p>")
    if contrib is not None:
        body = (f"<p>Fitted with its parameter(s) {esc(_params(contrib.get('params') or {}))}, it lowers the "
                f"held-out error from {num(contrib.get(f'heldout_rms_without_{u}'))} {u} (the model without "
                f"it) to {num(contrib.get(f'heldout_rms_with_{u}'))} {u} ({pct(contrib.get('gain_pct'))} "
                f"lower; z = {num(contrib.get('z'), 3)}, the per-sample improvement in units of its standard "
                "error, serial correlation accounted for; 3 or more counts) and accounts for "
                f"{pct(contrib.get('share_pct'))} of the discrepancy the extended model removes; alone it "
                f"reaches {num(contrib.get(f'heldout_rms_alone_{u}'))} {u}.</p>")
    else:
        base = (d.get("baseline") or {}).get(f"heldout_rms_{u}")
        body = (f"<p>Fitted with its parameter(s) {esc(_params(c.get('params') or {}))} on the training "
                f"experiments, it lowers the held-out error from {num(base)} {u} to "
                f"{num(c.get(f'heldout_rms_{u}'))} {u} (z = {num(c.get('z'), 3)}: the per-sample improvement "
                "in units of its standard error, serial correlation accounted for; 3 or more counts) and "
                f"removes {pct(100 * c.get('excess_removed', np.nan))} of the baseline's error above "
                "the noise floor (in mean squares: (baseline² − extended²) / (baseline² − noise²); "
                "above 100 % when it ends below the estimated noise).</p>")
    png = inp.out / f"diagnosis_cause_{cause}.png"
    if png.is_file():
        body += image_html(png.read_bytes(), "image/png",
                           f"What {esc(cause.replace('_', ' '))} changes: the held-out prediction without it "
                           "against the extended model and the measurement, in the view that shows its effect.",
                           f"figure of the cause {cause}")
    return head + body


def _candidates_table(d: dict) -> str:
    named = _named_models(d)
    u = unit_of(d)
    rows = [{"cause": c.get("cause"), "parameters": _params(c.get("params") or {}),
             f"held-out rms [{u}]": num(c.get(f"heldout_rms_{u}")), "z": num(c.get("z"), 2),
             "excess removed": pct(100 * c.get("excess_removed", np.nan)),
             "significant": "yes" if c.get("significant") else "no", "_rms": c.get(f"heldout_rms_{u}", np.inf)}
            for c in list(d.get("candidates") or []) + list(d.get("pair_candidates") or [])]
    rows.sort(key=lambda r: r["_rms"] if r["_rms"] is not None else np.inf)
    rows = [{k: v for k, v in r.items() if k != "_rms"} for r in rows]
    return table(rows, row_cls=lambda r: "named" if r["cause"] in named else "", text_cols=("parameters",))


def _diagnosis_figures(inp, d: dict) -> list[str]:
    out, parts = inp.out, []
    u = unit_of(d)
    cand = out / "diagnosis_candidates.csv"
    if cand.is_file():
        reg = pd.DataFrame([{"regime": r, "baseline": v.get("baseline"), "extended": v.get("extended")}
                            for r, v in (d.get(f"per_regime_rms_{u}") or {}).items()])
        parts.append(figure_html(candidates_figure(pd.read_csv(cand), float(d.get(f"noise_rms_{u}") or np.nan),
                                                   named=_named_models(d), regimes=reg if len(reg) else None, unit=u),
                                 f"Held-out {_what(d)} error of the calibrated baseline (red) and of each candidate "
                                 "extension (green: named), and by regime: the named cause must beat the "
                                 "baseline clearly and come close to the noise floor (dotted).",
                                 "held-out error of the candidates"))
    loops = inp.once(diagnosis_loops)
    if loops is not None:
        parts.append(figure_html(loops_figure(loops),
                                 "Tip angle against the pulled tension for each held-out experiment: measured "
                                 "(dots), calibrated baseline (red dashed) and extended model (blue); the loop's "
                                 "width is the friction hysteresis the models must reproduce.",
                                 "hysteresis loops"))
    pe = out / "diagnosis_point_errors.csv"
    if pe.is_file():
        by_point = pd.read_csv(pe)
        by_point = by_point.rename(columns={c: "rms_mm_extended" for c in by_point if c.startswith("rms_mm_ext")})
        cells = pd.read_csv(out / "diagnosis_residual_map.csv") if (out / "diagnosis_residual_map.csv").is_file() \
            else None
        parts.append(figure_html(residual_map_figure(by_point, cells),
                                 "Where and when the models miss on held-out data: error by notch point "
                                 "(left; the free fit's residual is what no joint configuration explains) "
                                 "and the error of each point (columns) of each sample (rows, in test order "
                                 "per experiment); bright bands mark the samples and points a model misses.",
                                 "held-out error by point and sample"))
    elif (out / "diagnosis_joint_errors.csv").is_file() and (out / "diagnosis_residuals.png").is_file():
        parts.append(image_html((out / "diagnosis_residuals.png").read_bytes(), "image/png",
                                "Held-out joint-angle error by joint, base to tip: baseline and extended model "
                                "against the noise floor (dotted).", "held-out error by joint"))
    return parts


def diagnosis_section(inp) -> str:
    d = inp.diagnosis
    if d is None:
        return na(inp.diagnosis_error or "no diagnosis.json in the output folder "
                                         "(run `notchfit diagnose STUDY --out DIR`)")
    parts = [_diag_params_text(d)]
    parts += [_cause_html(inp, d, c, k) for k, c in enumerate(causes_of(d), 1)]
    parts.append("<h3>Every candidate</h3>" + _candidates_table(d))
    parts += _diagnosis_figures(inp, d)
    b_rows = b_at_peak_rows(inp)
    if b_rows:
        parts.append("<h3>Shape at peak, held out</h3>" + table(b_rows))
    disc = d.get("discrepancies") or []
    if disc:
        parts.append("<h3>What the calibrated baseline gets wrong</h3>" + table(
            [{"signature": x.get("signature"),
              "value": f"{num(x.get('value'))} {x.get('unit', '') if x.get('unit') != '-' else ''}".strip(),
              "meaning": x.get("text", "")} for x in disc], text_cols=("meaning",)))
    parts.append(f"<details><summary>The diagnosis's own explanation</summary><p>{esc(d.get('explanation', ''))}"
                 "</p></details>")
    parts.append("<p>All numbers: " + link(inp.out / "diagnosis.json", inp.out) + "; the extended model: "
                 + link(inp.out / d.get("extended_model_file", "extended_model.toml"), inp.out)
                 + " (<code>notchfit simulate STUDY --model FILE</code> runs it).</p>")
    return "\n".join(parts)


# ----------------------------------------------------------------------------- files
FILE_COLUMNS = (("Fig. 12", "fig12_overlay.png"), ("Fig. 13", "fig13_pointwise.png"),
                ("Fig. 14", "fig14_pointwise.png"), ("Fig. 15", "fig15_shape_parameters.png"),
                ("Fig. 18", "fig18_joint_angles.png"), ("Fig. 19", "fig19_shape_parameters.png"),
                ("fits", "fits.csv"), ("simulation", "simulation.csv"), ("detections", "detections.csv"))


def files_section(inp) -> str:
    names = sorted({n for f in ("fits.csv", "simulation.csv", "detections.csv")
                    for n in nio.find_output(inp.out, f)})
    rows = []
    for n in names:
        d = inp.out / n if n else inp.out
        row = {"experiment": esc(n or "(single experiment)")}
        for label, f in FILE_COLUMNS:
            row[label] = link(d / f, inp.out, label.split()[-1]) if (d / f).is_file() else "–"
        if (d / "overlays").is_dir():
            row["overlays"] = link(d / "overlays", inp.out, "overlays/")
        rows.append(row)
    top = [link(p, inp.out) for p in sorted(inp.out.glob("*")) if p.is_file() and p.suffix in (".json", ".toml",
                                                                                                ".csv", ".png")]
    html = ""
    if rows:
        cols = list(rows[0])
        html += ("<table><thead><tr>" + "".join(f"<th>{esc(c)}</th>" for c in cols) + "</tr></thead><tbody>"
                 + "".join("<tr>" + "".join(f"<td>{r.get(c, '–')}</td>" for c in cols) + "</tr>" for r in rows)
                 + "</tbody></table>")
    if top:
        html += "<p>In this folder: " + ", ".join(top) + ".</p>"
    return html or na("no output files")
