"""The report's first sections (:mod:`notchfit.report`): at a glance, the study, camera and detection, files.

Each takes the report's inputs (:class:`notchfit.report.Inputs`) and returns
typed blocks (:mod:`notchfit.report.forms`). The first section says first what
the model gets wrong — where, when and how much above the one noise floor of
the study, defined where it is stated — then the cause; every number it shows
carries its unit.
"""

from __future__ import annotations

import math

import numpy as np

from .. import io as nio
from ..figures.summary import thumbnails_figure
from ..units import DEG
from .causes import cause_text
from .diagnosis import misses_text, params_text, quantity, what_of
from .forms import Glance, NotAvailable, Para, Table
from .page import figure, link, newton, num, pct
from .steps import fit_summary_text
from .tables import detection_rows, thumbnail_panels

__all__ = ["detection_section", "files_section", "glance_section", "study_section"]


# ----------------------------------------------------------------------------- at a glance
def _source_text(inp) -> str:
    exps = inp.exps
    det = inp.once(detection_rows)
    if det:
        sig = np.nanmedian([r["_sigma"] for r in det])
        return (f"{exps[0].geometry.n_points} notch corners per sample found by `detect` in "
                f"{sum(r['images'] for r in det)} images (median corner uncertainty σ {num(sig, 2)} mm)")
    counts = sorted({g.n_joints for _, g, _ in inp.tubes}, reverse=True)
    if inp.angles:
        return f"{' or '.join(map(str, counts))} joint angles per sample (one per notch) given in angles.csv"
    return f"{exps[0].geometry.n_points} notch points per sample given in notch_points.csv"


def _tubes_text(inp) -> str:
    if len(inp.tubes) < 2:
        return ""
    parts = [f"`{label}` ({g.n_joints} notches: {', '.join(names)})" for label, g, names in inp.tubes]
    return f"{len(inp.tubes)} tubes, " + " and ".join(parts) + "; "


def _measured_text(inp) -> str:
    exps = inp.exps
    if not exps:
        return f"not available: {inp.why}"
    n_s = sum(e.n_samples for e in exps)
    left = [e.name for e in exps if inp.pulled[e.name] < 0]
    peak = [max(np.nanmax(e.tension_left), np.nanmax(e.tension_right)) for e in exps]
    counter = [float(np.nanmedian(e.tension_right if inp.pulled[e.name] < 0 else e.tension_left)) for e in exps]
    d = inp.decimals

    def span(vals) -> str:
        lo, hi = newton(min(vals), d), newton(max(vals), d)
        return lo if lo == hi else f"{lo}–{hi}"

    tendons = exps[0].geometry.tendons
    tests = "bend–unbend tests" if inp.unloads else "loading trials (never released)"
    if len(tendons) == 1:
        pulls = f"one tendon ({tendons[0]}) pulled, up to {span(peak)} N"
    else:
        pulls = (f"the left cable pulled in {len(left)}, the right in {len(exps) - len(left)}, up to "
                 f"{span(peak)} N against {span(counter)} N on the other cable")
    return (f"{_tubes_text(inp)}{len(exps)} {tests} ({', '.join(e.name for e in exps)}), {n_s} samples: "
            f"{pulls}; {_source_text(inp)}.")


def _cause_row(inp) -> tuple[str, str]:
    d = inp.diagnosis
    if d is None:
        why = inp.diagnosis_error or "no diagnosis.json (run `notchfit diagnose STUDY --out DIR`)"
        return f"not available: {why}", f"not available: {why}"
    ans = "; ".join(f"**{cause_text(c).label}**: {cause_text(c).meaning}" for c in d.named) + "."
    g, u = d.gain, d.unit
    if d.causes:
        gain = (f"held-out {what_of(d)} error {num(g.baseline)} {u} → {num(g.extended)} {u} rms "
                f"(**{pct(g.reduction_pct)} lower**) on experiments left out of every fit.")
    else:
        gain = (f"none: no extension lowers the held-out error significantly (it stays {quantity(g.baseline, u)} "
                "rms).")
    return ans, gain


def _protocol_text(inp) -> str:
    d = inp.diagnosis
    src = set(d.protocol_source.values()) if d is not None else set()
    if src == {"experiment.toml"}:
        return "the drive's protocol as experiment.toml gives it ([protocol])"
    ramps = sorted({v for k, v in d.protocol_ramp_s.items() if d.protocol_source.get(k) != "experiment.toml"}) \
        if d is not None else []
    how = ("a step" if not any(ramps) else "a ramp over " + ", ".join(f"{num(r, 2)} s" for r in ramps)
           + " of each interval, then rest")
    if "estimated" in src:
        return (f"each sample's tensions applied as {how} (experiment.toml gives no [protocol]: estimated by the "
                "diagnosis)")
    if d is not None or any(e.ramp_time is None for e in inp.exps or []):
        return ("each sample's tensions applied as a step, the tube at rest when measured (experiment.toml gives "
                "no [protocol]: assumed)")
    return ""


def _assumed_text(inp) -> str:
    d = inp.diagnosis
    parts = []
    if d is not None and d.baseline is not None:
        b = d.baseline
        names = ", ".join(params_text(b.params, symbols_only=True))
        fixed = "; ".join(params_text(b.fixed)) if b.model == "moses2015" else \
            "; ".join(params_text({k: v for k, v in b.fixed.items() if k != "b"}))
        if b.model == "moses2015":
            parts.append(f"the paper's cable-friction model (Sec. IV-B) with {names} calibrated on the training "
                         "experiments" + (f", {fixed}" if fixed else "") + " and the spring's break points at the "
                         "paper's values; judged on experiments held out of every fit (cross-validation by experiment)")
        else:
            law = b.model.rsplit("-", 1)[-1]
            parts.append(f"the tube's default model (`{b.model}`: springs from the material and each notch's "
                         f"section, {law} friction, damping at the quasi-static time constant) with {names} "
                         "calibrated on the training experiments" + (f", {fixed}" if fixed else "")
                         + "; judged on experiments held out of every fit (cross-validation by experiment)")
    if inp.exps:
        parts.append("geometry " + ", ".join(f"`{g.name}` ({g.n_joints} joints)" for _, g, _ in inp.tubes))
        proto = _protocol_text(inp)
        if proto:
            parts.append(proto)
    parts.append("the tension measured at the load cell drives the model")
    return "; ".join(parts) + "."


def _synthetic_note(inp) -> Para | None:
    t = inp.truth
    if not t:
        return None
    img = any(e.has_images for e in inp.exps or [])
    return Para("**Synthetic data.** This study was generated by `notchfit synth` (recipe "
                f"`{t.get('recipe')}`, seed {t.get('seed')}): shapes from notchfit's own friction model plus the "
                "recipe's hidden effect(s), tensions with load-cell noise"
                + ("; the images are renders from an exactly known camera, sharp and evenly lit, so the detection "
                   "errors here are far below a photograph's" if img else "")
                + ". Real data add effects that no model has: expect larger errors.", style="note")


def _check_row(inp) -> list[tuple[str, str]]:
    t, d = inp.truth, inp.diagnosis
    if not t or d is None:
        return []
    cause = t.get("cause")
    hidden = [str(c) for c in cause] if isinstance(cause, list) else [str(cause)]
    eff = ", ".join(f"{k} = {num(v)}" for k, v in (t.get("effect") or {}).items())
    named = list(d.causes)
    what = " and ".join(cause_text(c).label for c in hidden)
    if hidden == ["none"]:
        what = "no effect (the model's own physics plus noise)"
        verdict = "found nothing beyond the noise." if d.cause == "none" else \
            f"answered {', '.join(cause_text(c).label for c in d.named)}."
    else:
        ok = sorted(c for c in hidden if c != "none") == sorted(named)
        verdict = (("named it." if len(hidden) == 1 else "named them.") if ok
                   else f"named {', '.join(cause_text(c).label for c in d.named)}.")
    return [("Check", f"the synthetic study hid **{what}**{' (' + eff + ')' if eff else ''}; the diagnosis {verdict}")]


def glance_section(inp) -> list:
    """What the model gets wrong first, then the cause, the gain, what was measured and assumed."""
    ans, gain = _cause_row(inp)
    question = ("Does the paper's cable-friction model (Moses et al. 2015, Sec. IV-B) predict the measured shapes "
                "of this tube, and if not, which physical effect does it miss?")
    rows = [("Model misses", misses_text(inp)), ("Cause", ans), ("Gain", gain), ("Measured", _measured_text(inp)),
            ("Assumed", _assumed_text(inp)), ("Shape fits", fit_summary_text(inp))] + _check_row(inp)
    rows.append(("Question", question))
    return [Glance(tuple(rows)), _synthetic_note(inp)]


# ----------------------------------------------------------------------------- study
def _tube_table(inp) -> Table | None:
    rows = []
    for label, g, names in inp.tubes:
        rows.append({"tube": label, "experiments": ", ".join(names), "joints": g.n_joints,
                     "outer / inner radius [mm]": f"{num(g.outer_radius * 1e3, 3)} / "
                                                  f"{num(g.inner_radius * 1e3, 3) if g.inner_radius else '–'}",
                     "cut depths [mm]": ", ".join(num(v * 1e3, 3) for v in g.slot_depths),
                     "spacing [mm]": ", ".join(sorted({num(v * 1e3, 3) for v in np.atleast_1d(g.pitches)})),
                     "rest angles [deg]": ", ".join(num(v / DEG, 2) for v in g.rest_angles)
                     if np.any(g.rest_angles) else "0",
                     "tendons": ", ".join(g.tendons) + (f" ({g.tendon_path})" if g.tendon_path else "")})
    return Table.of(rows, text_columns=("experiments", "cut depths [mm]", "rest angles [deg]", "tendons"))


def study_section(inp) -> list:
    if inp.exps is None:
        return [NotAvailable(inp.why)]
    rows, d = [], inp.decimals
    several = len(inp.tubes) > 1
    tube_of = {n: label for label, _, names in inp.tubes for n in names}
    for e in inp.exps:
        side = inp.pulled[e.name]
        pulled, other = (e.tension_right, e.tension_left) if side > 0 else (e.tension_left, e.tension_right)
        other = np.nan_to_num(np.asarray(other, float))
        rows.append({"experiment": e.name, **({"tube": tube_of[e.name]} if several else {}),
                     "pulled cable": "right" if side > 0 else "left",
                     "peak [N]": newton(np.nanmax(pulled), d), "other cable [N]": newton(np.median(other), d),
                     "samples": e.n_samples,
                     "measured": "notch_points.csv" if e.points is not None else
                     ("images (detect)" if e.has_images else ("angles.csv" if e.angles is not None else "–")),
                     "tensions": "step" if not e.ramp_time else f"ramp {num(e.ramp_time, 2)} s"})
    if several:
        head = f"{len(inp.exps)} experiments of {len(inp.tubes)} tubes, each with its own geometry file:"
    else:
        g = inp.exps[0].geometry
        head = f"{len(inp.exps)} experiment(s), geometry `{g.name}` ({g.n_joints} joints, {g.n_points} notch points)."
    return [Para(f"Study `{inp.rel(inp.study_path)}`: {head}"), _tube_table(inp) if several else None,
            Table.of(rows)]


# ----------------------------------------------------------------------------- detection
def _camera_blocks(inp) -> list:
    files = []
    for e in inp.exps or []:
        if e.calibration_path is not None and e.calibration_path.resolve() not in files:
            files.append(e.calibration_path.resolve())
    if not files:
        return [Para("No camera file: the experiments give notch points, or the scale came from the tube's "
                     "diameter (detect_run.json).")]
    parts = []
    for f in files:
        try:
            cam = nio.read_camera(f)
        except Exception as exc:  # noqa: BLE001 - a report shows what it can
            parts.append(NotAvailable(str(exc)))
            continue
        K = cam.camera_matrix
        rms = cam.rms if math.isfinite(cam.rms) and cam.rms >= 0 else None
        parts.append(Para(f"Camera file `{inp.rel(f)}`: {cam.image_size[0]} × {cam.image_size[1]} px, "
                          f"f = {num(K[0, 0])} px, bending plane {num(np.linalg.norm(cam.plane_tvec) * 1e3)} mm "
                          "from the camera; reprojection error "
                          + (f"{num(rms, 2)} px" if rms is not None else "not measured (a camera file written "
                             "with the renders, not calibrated from views)") + "."))
    return parts


def detection_section(inp) -> list:
    rows = inp.once(detection_rows)
    if not rows:
        if inp.exps is not None and not any(e.has_images for e in inp.exps):
            given = "joint angles were given in angles.csv" if inp.angles else \
                "notch points were given in notch_points.csv"
            return [NotAvailable(f"the study has no images: {given}, nothing was detected")]
        return [NotAvailable("no detections.csv in the output folder (run `notchfit detect STUDY --out DIR`)")]
    parts = _camera_blocks(inp) + [Table.of([{k: v for k, v in r.items() if not k.startswith("_")} for r in rows])]
    sig = np.nanmedian([r["_sigma"] for r in rows])
    note = (" On these renders it is the edge-fit uncertainty of an ideal image; on photographs blur, "
            "noise, contrast and resolution raise it (docs/robustness.md measures each)." if inp.truth else "")
    parts.append(Para(f"σ is each corner's uncertainty from its edge-line fits (median {num(sig, 2)} mm).{note}"))
    panels = thumbnail_panels(inp)
    if panels:
        parts.append(figure(thumbnails_figure(panels),
                            "Detected corners on a crop around the tube (green: ok, orange: ambiguous, red: "
                            "occluded; a few point numbers written beside their corner): check that every notch "
                            "has its two corners and the numbers run base → tip → base.",
                            "detected corners on three samples"))
    return parts


# ----------------------------------------------------------------------------- files
FILE_COLUMNS = (("Fig. 12", "fig12_overlay.png"), ("Fig. 13", "fig13_pointwise.png"),
                ("Fig. 14", "fig14_pointwise.png"), ("Fig. 15", "fig15_shape_parameters.png"),
                ("Fig. 18", "fig18_joint_angles.png"), ("Fig. 19", "fig19_shape_parameters.png"),
                ("fits", "fits.csv"), ("angle fits", "angle_fits.csv"), ("simulation", "simulation.csv"),
                ("detections", "detections.csv"))


def files_section(inp) -> list:
    names = sorted({n for f in ("fits.csv", "angle_fits.csv", "simulation.csv", "detections.csv")
                    for n in nio.find_output(inp.out, f)})
    rows = []
    for n in names:
        d = inp.out / n if n else inp.out
        row = {"experiment": n or "(single experiment)"}
        for label, f in FILE_COLUMNS:
            row[label] = link(d / f, inp.out, label.split()[-1]) if (d / f).is_file() else "–"
        if (d / "overlays").is_dir():
            row["overlays"] = link(d / "overlays", inp.out, "overlays/")
        rows.append(row)
    if rows:      # a column no experiment has is left out
        keep = [c for c in rows[0] if c == "experiment" or any(r.get(c, "–") != "–" for r in rows)]
        rows = [{c: r.get(c, "–") for c in keep} for r in rows]
    top = tuple(link(p, inp.out) for p in sorted(inp.out.glob("*"))
                if p.is_file() and p.suffix in (".json", ".toml", ".csv", ".png"))
    blocks = [Table.of(rows), Para("In this folder:", links=top) if top else None]
    return blocks if any(blocks) else [NotAvailable("no output files")]
