"""The report's diagnosis: what the calibrated model gets wrong, each named cause, every candidate.

Read from ``diagnosis.json`` and its tables through :mod:`notchfit.io`
(:class:`notchfit.io.DiagnosisRecord`); cause words through
:func:`notchfit.report.causes.cause_text`. The study's one noise floor is
``noise_rms`` of the diagnosis, stated once with its definition in the first
section (:func:`misses_text`); the signatures' own sentences, which quote the
baseline's floor, are not repeated: each signature is shown as its value in
the page's units and a meaning without numbers.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import io as nio
from ..figures.summary import candidates_figure, loops_figure, residual_map_figure
from ..units import DEG
from .causes import cause_text
from .forms import Details, Heading, NotAvailable, Para, Table
from .page import figure, image, link, newton, num, pct
from .params import params_text
from .tables import b_at_peak_rows, diagnosis_loops

__all__ = ["diagnosis_section", "misses_text", "params_text", "quantity", "signature_rows", "what_of"]

#: The regimes of a bend–unbend test (Sec. IV, Fig. 11), in words.
REGIMES = {"I": "while loading", "II": "while holding after the peak", "III": "while releasing"}
#: Signatures only a test that releases its tension can show.
UNLOADING_SIGNATURES = ("unloading_hold", "b_unloading_error", "residual_bend", "loop_area_ratio")
#: What each signature measures, without numbers (its value is shown beside it in the page's units).
SIGNATURE_MEANING = {
    "unloading_hold": "extra tension the measured shape holds while unloading, beyond the baseline's prediction "
                      "(at half release)",
    "loading_stalls": "share of the upper loading steps on which the measured shape moved less than 30 % of the "
                      "baseline's prediction (a cable that stuck where the model slides)",
    "loop_area_ratio": "area of the measured hysteresis loop (pulled tension against tip angle) over the baseline's",
    "b_loading_error": "measured b minus the baseline's on the loading branch, toward the pulled side",
    "b_unloading_error": "measured b minus the baseline's on the unloading branch, toward the pulled side",
    "residual_bend": "tip angle left after unloading, measured minus predicted, toward the pulled side",
    "backbone_residual": "joint-angle error (measured − baseline) of the base third minus that of the tip third",
    "direction_asymmetry": "mean tip-angle error (measured − baseline) in the manipulator frame over both pull "
                           "directions: a mirror-symmetric model error averages out, a steady load does not",
    "spatial_pattern": "residual of the free-θ fits over the point noise (about 1: no pattern beyond noise)",
    "counter_tension_dependence": "correlation of the held-out error with the counter-tension",
}


def what_of(d) -> str:
    return "joint-angle" if d.unit == "deg" else "notch-point"


def _measured_of(unit: str) -> str:
    return "joint angles" if unit == "deg" else "notch points"


def quantity(v, unit: str, digits: int = 3) -> str:
    """A value with its unit as the page writes it: ``0.654 mm``, ``0.670°``."""
    return f"{num(v, digits)}°" if unit == "deg" else f"{num(v, digits)} {unit}"


# ----------------------------------------------------------------------------- the first line
def _where(inp, d) -> str:
    """Where along the tube the baseline misses most (notch point or joint, from the diagnosis's tables)."""
    name = "diagnosis_joint_errors.csv" if d.unit == "deg" else "diagnosis_point_errors.csv"
    path = inp.out / name
    col = f"rms_{d.unit}_baseline"
    if not path.is_file():
        return ""
    try:
        t = nio.read_diagnosis_csv(path)
    except ValueError:
        return ""
    if col not in t or not np.isfinite(t[col]).any():
        return ""
    r = t.loc[int(np.nanargmax(t[col].to_numpy(float)))]
    tube = f" of `{r['tube']}`" if "tube" in t else ""
    if d.unit == "deg":
        n = int((t["tube"] == r["tube"]).sum()) if "tube" in t else len(t)
        return f"joint {int(r['joint'])} of {n}{tube} ({quantity(r[col], 'deg')}; joint 1 at the base)"
    m = int((t["tube"] == r["tube"]).sum()) if "tube" in t else len(t)
    k = int(r["point"])
    along = min(k, m + 1 - k) / (m / 2)
    near = "near the tip" if along > 2 / 3 else ("near the base" if along < 1 / 3 else "mid-way along the tube")
    return f"notch point {k} of {m}{tube}, {near} ({quantity(r[col], 'mm')})"


def _misses_from_diagnosis(inp, d) -> str:
    u, b = d.unit, d.baseline
    which = "the paper's model" if b.model == "moses2015" else "the tube's default model"
    noise = (f"the noise floor, {quantity(d.noise_rms, u)}, is the rms error a perfect model would leave with this "
             f"study's measurement noise ({'angles' if u == 'deg' else 'points'} and load cells), the one noise "
             "floor of this page")
    ratio = b.heldout_rms / d.noise_rms if d.noise_rms > 0 else math.nan
    band = (f" With the baseline folds' own prediction uncertainty the floor the verdict compares with is "
            f"{quantity(d.floor, u)}." if d.floor > d.noise_rms else "")
    if d.cause == "none":
        return (f"Nothing beyond the noise: {which}, calibrated, predicts the held-out {_measured_of(u)} with "
                f"{quantity(b.heldout_rms, u)} rms, {num(ratio, 2)}× the noise floor; {noise}.{band}")
    worst = max(d.per_regime.items(), key=lambda kv: kv[1].baseline if math.isfinite(kv[1].baseline) else -1,
                default=None)
    regime = (f"{REGIMES.get(worst[0], 'in regime ' + worst[0])} (regime {worst[0]}: {quantity(worst[1].baseline, u)})"
              if worst and len(d.per_regime) > 1 else "")
    where = _where(inp, d)
    most = [p for p in (regime, f"at {where}" if where else "") if p]
    text = (f"{which[0].upper()}{which[1:]}, calibrated, misses the held-out {_measured_of(u)} by "
            f"**{quantity(b.heldout_rms, u)} rms**, {num(ratio, 2)}× the noise floor"
            + (f"; most {' and '.join(most)}" if most else "") + f"; {noise}.{band}")
    if inp.identify is not None:
        ident = _misses_from_identify(inp, inp.identify, noise=False)
        text += f" {ident[0].upper()}{ident[1:]}"
    return text


def _misses_from_identify(inp, r, *, noise: bool = True) -> str:
    u = r.unit
    what = "joint angles" if u == "deg" else "notch points"
    sig = [e.angle_sigma / DEG for e in inp.exps or [] if e.angle_sigma] if u == "deg" else \
        [e.point_sigma * 1e3 for e in inp.exps or [] if e.point_sigma]
    noise = (f", against a measurement noise of {quantity(max(sig), u, 2)} per "
             f"{'angle' if u == 'deg' else 'point coordinate'} (experiment.toml)") if sig and noise else ""
    text = (f"the identified model (its per-tube unknowns fitted too) misses held-out {what} by "
            f"**{quantity(r.heldout_rms, u)} rms** (each experiment "
            f"predicted by a model fitted without it; {quantity(r.train_rms, u)} on the experiments it was fitted "
            f"to){noise}")
    far = [t for t in r.tubes if math.isfinite(t.heldout_by_geometry)]
    if far:
        worst = max(far, key=lambda t: t.heldout_by_geometry)
        text += (f"; a tube predicted from the other tubes' fit and its geometry file is off by up to "
                 f"{quantity(worst.heldout_by_geometry, u)} (`{worst.label}`)")
    return text + "."


def misses_text(inp) -> str:
    """The first line of the report: what the model gets wrong, where, when and how much above the noise."""
    if inp.diagnosis is not None and inp.diagnosis.baseline is not None:
        return _misses_from_diagnosis(inp, inp.diagnosis)
    if inp.identify is not None:
        return _misses_from_identify(inp, inp.identify)
    why = inp.diagnosis_error or "no diagnosis.json or identify.json (run `notchfit diagnose STUDY --out DIR`)"
    return f"not available: {why}"


# ----------------------------------------------------------------------------- the diagnosis section
def _diag_params(d, angles: bool) -> Para:
    b, ext = d.baseline, d.extended
    paper = b.model == "moses2015"
    which = "the paper's model" if paper else f"the tube's default model ({b.model})"
    fixed = {k: v for k, v in b.fixed.items() if paper or k != "b"}
    txt = (f"**Parameters:** baseline = {which} calibrated on this study: "
           f"{', '.join(params_text(b.params, b.se, angles=angles))}"
           + (f"; fixed {', '.join(params_text(fixed, angles=angles))}" if fixed else "")
           + ("; the rest at the paper's values." if paper else "; the rest at the tube's defaults."))
    if ext is not None and ext.params:
        named = ", ".join(cause_text(c).label for c in ext.causes)
        txt += (f" Extended ({named}, `{d.extended_model_file}`, refitted on all experiments): "
                f"{', '.join(params_text(ext.params, ext.se, angles=angles))}.")
    return Para(txt, style="params")


def _cause_blocks(inp, d, cause: str, k: int) -> list:
    """A named cause: what it means, what it removes on held-out data, and its figure."""
    u, words = d.unit, cause_text(cause)
    blocks = [Heading(f"Cause {k}: {words.label}"), Para(f"{words.meaning}.")]
    contrib = {c.cause: c for c in d.contributions}.get(cause)
    c = {c.cause: c for c in d.candidates}.get(cause)
    if contrib is not None:
        blocks.append(Para(
            f"Fitted with its parameter(s) {', '.join(params_text(contrib.params, angles=inp.angles))}, it lowers the "
            f"held-out error from {quantity(contrib.heldout_rms_without, u)} (the model without it) to "
            f"{quantity(contrib.heldout_rms_with, u)} ({pct(contrib.gain_pct)} lower; z = {num(contrib.z, 3)}, the "
            "per-sample improvement in units of its standard error, serial correlation accounted for; 3 or more "
            f"counts) and accounts for {pct(contrib.share_pct)} of the discrepancy the extended model removes; "
            f"alone it reaches {quantity(contrib.heldout_rms_alone, u)}."))
    elif c is not None:
        blocks.append(Para(
            f"Fitted with its parameter(s) {', '.join(params_text(c.params, angles=inp.angles))} on the training "
            f"experiments, it lowers the held-out error from {quantity(d.baseline.heldout_rms, u)} to "
            f"{quantity(c.heldout_rms, u)} (z = {num(c.z, 3)}: the per-sample improvement in units of its standard "
            f"error, serial correlation accounted for; 3 or more counts) and removes {pct(100 * c.excess_removed)} "
            "of the baseline's error above the noise floor (in mean squares: (baseline² − extended²) / "
            "(baseline² − noise²); above 100 % when it ends below the estimated noise)."))
    else:
        blocks.append(Para(f"Baseline held-out error {quantity(d.baseline.heldout_rms, u)}."))
    png = inp.out / f"diagnosis_cause_{cause}.png"
    if png.is_file():
        blocks.append(image(png.read_bytes(), "image/png",
                            f"What {words.label} changes: the held-out prediction without it against the extended "
                            "model and the measurement, in the view that shows its effect.",
                            f"figure of the cause {cause}"))
    return blocks


def _candidates_table(d, angles: bool) -> Table | None:
    named = {*d.causes, "+".join(d.causes)}
    u = d.unit
    cands = sorted(d.candidates + d.pair_candidates,
                   key=lambda c: c.heldout_rms if math.isfinite(c.heldout_rms) else math.inf)
    rows = [{"cause": c.cause, "parameters": ", ".join(params_text(c.params, angles=angles)),
             f"held-out rms [{u}]": num(c.heldout_rms), "z": num(c.z, 2),
             "excess removed": pct(100 * c.excess_removed), "significant": "yes" if c.significant else "no"}
            for c in cands]
    return Table.of(rows, text_columns=("parameters",), named=lambda r: r["cause"] in named)


def loops_caption(*, named: bool, unloads: bool) -> str:
    """The loops figure's caption: the extended model is drawn (and named) only when a cause is named,
    and a loop is only compared when some trial is released."""
    models = ("calibrated baseline (red dashed) and extended model (blue)" if named else
              "calibrated baseline (red dashed; no cause named, so no extended model)")
    shape = ("the loop's width is the friction hysteresis the models must reproduce" if unloads else
             "loading only: these trials are never released, so there is no loop to compare")
    return f"Tip angle against the pulled tension for each held-out experiment: measured (dots), {models}; {shape}."


def _diagnosis_figures(inp, d) -> list:
    out, parts, u = inp.out, [], d.unit
    if (out / "diagnosis_candidates.csv").is_file():
        reg = pd.DataFrame([{"regime": r, "baseline": g.baseline, "extended": g.extended}
                            for r, g in d.per_regime.items()])
        parts.append(figure(candidates_figure(nio.read_diagnosis_csv(out / "diagnosis_candidates.csv"),
                                              d.noise_rms, named={*d.causes, "+".join(d.causes)} - {""},
                                              regimes=reg if len(reg) else None, unit=u, floor=d.floor),
                            f"Held-out {what_of(d)} error of the calibrated baseline (red) and of each candidate "
                            "extension (green: named), and by regime: the named cause must beat the baseline clearly "
                            "and come close to the noise floor (dotted).", "held-out error of the candidates"))
    loops = inp.once(diagnosis_loops)
    if loops is not None:
        parts.append(figure(loops_figure(loops, degrees=inp.angles),
                            loops_caption(named=any(d.causes), unloads=inp.unloads), "hysteresis loops"))
    pe = out / "diagnosis_point_errors.csv"
    if pe.is_file():
        by_point = nio.read_diagnosis_csv(pe)
        by_point = by_point.rename(columns={c: "rms_mm_extended" for c in by_point if c.startswith("rms_mm_ext")})
        rm = out / "diagnosis_residual_map.csv"
        cells = nio.read_diagnosis_csv(rm) if rm.is_file() else None
        parts.append(figure(residual_map_figure(by_point, cells),
                            "Where and when the models miss on held-out data: error by notch point (left; the free "
                            "fit's residual is what no joint configuration explains) and the error of each point "
                            "(columns) of each sample (rows, in test order per experiment); bright bands mark the "
                            "samples and points a model misses.", "held-out error by point and sample"))
    elif (out / "diagnosis_joint_errors.csv").is_file() and (out / "diagnosis_residuals.png").is_file():
        parts.append(image((out / "diagnosis_residuals.png").read_bytes(), "image/png",
                           "Held-out joint-angle error by joint, base to tip (one line per tube): baseline and "
                           "extended model against the noise floor (dotted).", "held-out error by joint"))
    return parts


def _signature_value(inp, s) -> str:
    angles = inp.angles
    if s.unit == "N":
        return f"{newton(s.value, inp.decimals)} N"
    if s.unit == "rad":
        per = " per joint" if s.signature.startswith("b_") else ""
        return f"{num(s.value / DEG, 2, sign=True)} deg{per}" if angles else f"{num(s.value, 2, sign=True)} rad{per}"
    if s.unit in ("mm", "deg"):
        return quantity(s.value, s.unit)
    if s.signature == "loading_stalls":
        return pct(100 * s.value)
    if s.signature == "counter_tension_dependence":
        return f"r = {num(s.value, 2, sign=True)}"
    return f"{num(s.value, 3)}×" if s.signature in ("loop_area_ratio", "spatial_pattern") else num(s.value)


def signature_rows(inp, d) -> list[dict]:
    """The signatures the data can show (none of unloading for trials that never release), each as its value
    in the page's units and its meaning in words."""
    rows = []
    for s in d.discrepancies:
        if not inp.unloads and s.signature in UNLOADING_SIGNATURES:
            continue
        reg = s.signature.rsplit("_", 1)[-1] if s.signature.startswith("heldout_rms_regime_") else None
        meaning = (f"held-out error of the calibrated baseline in regime {reg} ({REGIMES.get(reg, '')})" if reg
                   else SIGNATURE_MEANING.get(s.signature, s.text))
        rows.append({"signature": s.signature, "value": _signature_value(inp, s), "meaning": meaning})
    return rows


def _protocol_para(d) -> Para | None:
    text = d.protocol_text
    if not text or "×" not in text:
        return None
    return Para(f"Protocol: {text} (each × is the calibrated baseline's mean squared error with that protocol in "
                "units of its noise floor's: 1 means within the noise.)")


def diagnosis_section(inp) -> list:
    d = inp.diagnosis
    if d is None:
        return [NotAvailable(inp.diagnosis_error or "no diagnosis.json in the output folder "
                                                    "(run `notchfit diagnose STUDY --out DIR`)")]
    parts = [_diag_params(d, inp.angles)]
    for k, c in enumerate(d.named, 1):
        parts += _cause_blocks(inp, d, c, k)
    parts += [Heading("Every candidate"), _candidates_table(d, inp.angles)]
    parts += _diagnosis_figures(inp, d)
    b_rows = b_at_peak_rows(inp)
    if b_rows:
        parts += [Heading("Shape at peak, held out"), Table.of(b_rows)]
    sig = signature_rows(inp, d)
    if sig:
        parts += [Heading("What the calibrated baseline gets wrong"), Table.of(sig, text_columns=("meaning",))]
    parts.append(_protocol_para(d))
    parts.append(Details("The diagnosis's own explanation", d.explanation))
    parts.append(Para("All numbers:", links=(link(inp.out / "diagnosis.json", inp.out),)))
    parts.append(Para("The extended model (`notchfit simulate STUDY --model FILE` runs it):",
                      links=(link(inp.out / d.extended_model_file, inp.out),)))
    return parts
