"""One self-contained HTML report per study (``notchfit report DIR``).

The report gathers what the pipeline commands wrote into one output folder
(docs/data-formats.md, "Outputs") and embeds every figure as a base64 PNG, so the
single ``report.html`` opens from disk in any browser with no server and no
other file. Sections, each present even when its input is absent (then it
says "not available: <why>"):

=================  ==========================================================
id                 content
=================  ==========================================================
``summary``        the three-line summary: fit errors, named cause, gain
``study``          the experiments (from the study folder, when known)
``calibration``    camera calibration quality (reprojection error, intrinsics)
``detection``      detection statistics and overlays of detected points
``fit``            shape-fit errors per model (Figs. 12–15)
``simulation``     simulation vs measurement (Figs. 18–19)
``diagnosis``      ``diagnosis.json``: baseline, discrepancies, candidates,
                   cause, explanation, gain, and the ``diagnosis_*.png`` figures
=================  ==========================================================

The study folder is the one given with ``--study``, or the ``input`` recorded
in a ``*_run.json`` provenance file that ``fit`` and ``simulate`` write.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import io as _pyio
import json
from pathlib import Path

import numpy as np
import pandas as pd

from . import io as nio
from ._version import __version__
from .units import MM

__all__ = ["SECTIONS", "build_report", "find_study", "summary_lines"]

SECTIONS = (
    ("summary", "Summary"),
    ("study", "Study"),
    ("calibration", "Calibration quality"),
    ("detection", "Detection"),
    ("fit", "Shape-fit errors (Figs. 12–15)"),
    ("simulation", "Simulation vs measurement (Figs. 18–19)"),
    ("diagnosis", "Diagnosis"),
)

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444}h2{margin-top:2em;border-bottom:1px solid #bbb}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#f0f0f0}
td:first-child,th:first-child{text-align:left}
.na{color:#a33;font-style:italic}.cause{font-size:1.2em;font-weight:bold}
figure{display:inline-block;margin:.5em;vertical-align:top}
figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:.8em;color:#555}
pre{background:#f7f7f7;padding:.5em;overflow-x:auto}.small{font-size:.85em;color:#555}
nav a{margin-right:1em}
"""


def _esc(x) -> str:
    return html.escape(str(x))


def _na(why: str) -> str:
    return f'<p class="na">not available: {_esc(why)}</p>'


def _png_data(data: bytes, caption: str) -> str:
    b64 = base64.b64encode(data).decode("ascii")
    return (f'<figure><img alt="{_esc(caption)}" src="data:image/png;base64,{b64}">'
            f"<figcaption>{_esc(caption)}</figcaption></figure>")


def _png(path: Path, root: Path) -> str:
    try:
        rel = path.relative_to(root)
    except ValueError:
        rel = path.name
    return _png_data(path.read_bytes(), str(rel))


def _fig_html(fig, caption: str) -> str:
    import matplotlib.pyplot as plt  # slow optional dependency: only when the report draws

    buf = _pyio.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return _png_data(buf.getvalue(), caption)


def _table(df: pd.DataFrame, floatfmt: str = "{:.4g}") -> str:
    return df.to_html(index=False, escape=True, na_rep="–", border=0,
                      float_format=lambda v: floatfmt.format(v))


def _pngs(root: Path, patterns) -> list[Path]:
    found = []
    for pat in patterns:
        for p in sorted(root.rglob(pat)):
            if p.is_file() and not any(part.startswith(".") for part in p.relative_to(root).parts):
                if p not in found:
                    found.append(p)
    return found


def _stat(fn, values) -> float:
    """``fn`` over the finite values (NaN when there are none, without a warning)."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    return float(fn(v)) if v.size else float("nan")


def _rms(values) -> float:
    return _stat(lambda v: np.sqrt(np.mean(v * v)), values)


def _label(name: str) -> str:
    return name or "(single experiment)"


# ----------------------------------------------------------------------------- study
def find_study(out_dir) -> Path | None:
    """The study folder recorded by ``fit``/``simulate``/``diagnose`` provenance files, if any."""
    out_dir = Path(out_dir)
    for p in sorted(out_dir.glob("*_run.json")):
        try:
            d = nio.read_json(p)
        except (ValueError, OSError):
            continue
        inp = d.get("input")
        if inp and Path(inp).is_dir():
            return Path(inp)
    return None


def _study_section(exps, study_path, why) -> str:
    if exps is None:
        return _na(why)
    rows = []
    for e in exps:
        rows.append({"experiment": e.name, "samples": e.n_samples,
                     "max tension left [N]": float(np.max(e.tension_left)),
                     "max tension right [N]": float(np.max(e.tension_right)),
                     "points": "yes" if e.points is not None else "no",
                     "images": "yes" if e.has_images else "no",
                     "mirror": e.mirror,
                     "σ point [mm]": (e.point_sigma * 1e3) if e.point_sigma else np.nan,
                     "σ tension [N]": e.tension_sigma if e.tension_sigma else np.nan,
                     "description": e.description})
    g = exps[0].geometry
    return (f"<p>Study folder <code>{_esc(study_path)}</code>: {len(exps)} experiment(s), "
            f"geometry <code>{_esc(g.name)}</code> ({g.n_joints} joints, {g.n_points} notch points).</p>"
            + _table(pd.DataFrame(rows)))


# ----------------------------------------------------------------------------- calibration
def _camera_row(path: Path, cam) -> dict:
    K, d = cam.camera_matrix, cam.dist_coeffs
    return {
        "file": str(path),
        "image [px]": f"{cam.image_size[0]}×{cam.image_size[1]}",
        # NaN: a camera that was not calibrated from views (a synthetic one)
        "reprojection error [px]": cam.rms,
        "f_x [px]": K[0, 0],
        "f_y [px]": K[1, 1],
        "c_x, c_y [px]": f"{K[0, 2]:.1f}, {K[1, 2]:.1f}",
        "distortion": " ".join(f"{v:.3g}" for v in np.ravel(d)[:5]),
        "plane distance [mm]": float(np.linalg.norm(cam.plane_tvec)) / MM if cam.has_plane else np.nan,
    }


def _calibration_section(out_dir: Path, exps) -> str:
    files = []
    if exps:
        for e in exps:
            if e.calibration_path is not None and e.calibration_path.resolve() not in files:
                files.append(e.calibration_path.resolve())
    for pat in ("camera*.yml", "camera*.yaml", "calibration*.yml", "calibration*.yaml"):
        for p in sorted(out_dir.rglob(pat)):
            if p.resolve() not in files and not any(s.startswith(".") for s in p.relative_to(out_dir).parts):
                files.append(p.resolve())
    figs = _pngs(out_dir, ["calibration*.png", "calib_*.png"])
    if not files and not figs:
        if exps is not None and not any(e.has_images for e in exps):
            return _na("the study has no images (notch points were given directly), so there is no "
                       "camera calibration to judge")
        return _na("no camera calibration file found (run `notchfit calibrate`, or give --study "
                   "so the experiments' calibration files can be read)")
    parts = []
    rows = []
    for f in files:
        try:
            cam = nio.read_camera(f)
        except Exception as exc:  # noqa: BLE001 - a report shows what it can
            parts.append(_na(str(exc)))
            continue
        rows.append(_camera_row(f, cam))
    if rows:
        parts.insert(0, _table(pd.DataFrame(rows)))
    parts += [_png(p, out_dir) for p in figs]
    return "\n".join(parts)


# ----------------------------------------------------------------------------- detection
def _overlay(exp, det: pd.DataFrame, sample: int) -> str | None:
    # slow optional dependency: matplotlib loads only when the report draws
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    i = int(np.flatnonzero(exp.sample_ids == sample)[0])
    path = exp.image_paths[i] if exp.image_paths else None
    if path is None:
        return None
    try:
        img = nio.load_image(path)
    except (FileNotFoundError, ValueError):
        return None
    d = det[det["sample"] == sample]
    ok = d["status"].str.lower() == "ok"
    fig, ax = plt.subplots(figsize=(6, 6 * img.shape[0] / img.shape[1]))
    ax.imshow(img, cmap="gray" if img.ndim == 2 else None)
    ax.plot(d.loc[ok, "u_px"], d.loc[ok, "v_px"], "+", color="lime", ms=7, label="ok")
    if (~ok).any():
        ax.plot(d.loc[~ok, "u_px"], d.loc[~ok, "v_px"], "x", color="red", ms=7, label="not ok")
    ax.set_axis_off()
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"{exp.name}, sample {sample}: {int(ok.sum())} of {len(d)} points ok", fontsize=9)
    return _fig_html(fig, f"{exp.name} sample {sample}: detected notch points")


def _detection_section(out_dir: Path, exps) -> str:
    found = nio.find_output(out_dir, "detections.csv")
    figs = _pngs(out_dir, ["overlay*.png", "detection*.png", "detect_*.png"])
    if not found and not figs:
        if exps is not None and not any(e.has_images for e in exps):
            return _na("the study has no images: notch points were given in notch_points.csv, "
                       "nothing was detected")
        return _na("no detections.csv in the output folder (run `notchfit detect STUDY --out DIR`)")
    parts, rows = [], []
    by_name = {e.name: e for e in exps} if exps else {}
    for name, path in found.items():
        try:
            det = nio.read_detections(path)
        except (ValueError, FileNotFoundError) as exc:
            parts.append(_na(str(exc)))
            continue
        status = det["status"].str.lower()
        row = {"experiment": _label(name), "samples": det["sample"].nunique(),
               "points": len(det), "ok": int((status == "ok").sum()),
               "ok [%]": 100.0 * float((status == "ok").mean()) if len(det) else np.nan,
               "median σ [mm]": _stat(np.median, det["sigma_mm"])}
        for s, n in status[status != "ok"].value_counts().items():
            row[f"{s}"] = int(n)
        rows.append(row)
        exp = by_name.get(name) or (exps[0] if exps and len(exps) == 1 and name == "" else None)
        if exp is not None and exp.has_images and len(det):
            ids = exp.sample_ids
            peak = ids[int(np.argmax(np.abs(exp.tension_left - exp.tension_right)))]
            for s in dict.fromkeys([ids[0], peak]):
                h = _overlay(exp, det, int(s))
                if h:
                    parts.append(h)
    if rows:
        parts.insert(0, _table(pd.DataFrame(rows).fillna(0)))
    parts += [_png(p, out_dir) for p in figs]
    return "\n".join(parts)


# ----------------------------------------------------------------------------- fit
def _fit_stats(fits: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for model, g in fits.groupby("model", sort=False):
        ok = g["success"].astype(str).str.lower().isin(["true", "1"]) if "success" in g else \
            pd.Series(True, index=g.index)
        r = g.loc[ok, "rms_mm"].to_numpy(float)
        rows.append({"model": model, "samples": len(g), "failed": int((~ok).sum()),
                     "mean rms [mm]": _stat(np.mean, r),
                     "rms of all points [mm]": _rms(r),
                     "max error [mm]": _stat(np.max, g.loc[ok, "max_mm"])})
    return pd.DataFrame(rows)


def _fit_section(out_dir: Path) -> str:
    found = nio.find_output(out_dir, "fits.csv")
    if not found:
        return _na("no fits.csv in the output folder (run `notchfit fit STUDY --out DIR`)")
    parts = []
    for name, path in found.items():
        parts.append(f"<h3>{_esc(_label(name))}</h3>")
        try:
            fits = nio.read_fits(path)
        except (ValueError, FileNotFoundError) as exc:
            parts.append(_na(str(exc)))
            continue
        parts.append(_table(_fit_stats(fits)))
        root = path.parent
        figs = [p for p in sorted(root.glob("fig1[2-5]*.png"))]
        parts += [_png(p, out_dir) for p in figs]
        if not figs:
            parts.append(_na("no Fig. 12–15 PNGs next to fits.csv"))
    return "\n".join(parts)


# ----------------------------------------------------------------------------- simulation
def _simulation_section(out_dir: Path) -> str:
    found = nio.find_output(out_dir, "simulation.csv")
    if not found:
        return _na("no simulation.csv in the output folder (run `notchfit simulate STUDY --out DIR`)")
    parts = []
    rows = []
    for name, path in found.items():
        try:
            sim = nio.read_simulation(path)
        except (ValueError, FileNotFoundError) as exc:
            parts.append(_na(str(exc)))
            continue
        row = {"experiment": _label(name), "samples": len(sim)}
        for reg in ("I", "II", "III"):
            row[f"regime {reg}"] = int((sim["regime"] == reg).sum())
        cmp_path = path.parent / "simulation_vs_measured.csv"
        if cmp_path.is_file():
            c = pd.read_csv(cmp_path)
            row["point rms [mm]"] = _rms(c["point_rms_mm"])
            row["a rms diff [rad]"] = _rms(c["a_sim"] - c["a_meas"])
            row["b rms diff [rad]"] = _rms(c["b_sim"] - c["b_meas"])
        rows.append(row)
    if rows:
        parts.insert(0, _table(pd.DataFrame(rows)))
    for name, path in found.items():
        figs = sorted(path.parent.glob("fig1[89]*.png"))
        if figs:
            parts.append(f"<h3>{_esc(_label(name))}</h3>")
            parts += [_png(p, out_dir) for p in figs]
    if not any(p.startswith("<figure") for p in parts):
        parts.append(_na("no Fig. 18–19 PNGs next to simulation.csv (measured points are needed "
                         "to compare)"))
    return "\n".join(parts)


# ----------------------------------------------------------------------------- diagnosis
def _fmt_params(p: dict) -> str:
    if not p:
        return "–"
    return ", ".join(f"{k} = {v:.4g}" if isinstance(v, (int, float)) else f"{k} = {v}" for k, v in p.items())


def _diagnosis_section(out_dir: Path) -> str:
    path = out_dir / "diagnosis.json"
    figs = _pngs(out_dir, ["diagnosis_*.png"])
    if not path.is_file():
        return _na("no diagnosis.json in the output folder (run `notchfit diagnose STUDY --out DIR`)") + \
            "".join(_png(p, out_dir) for p in figs)
    try:
        d = nio.read_diagnosis(path)
    except ValueError as exc:
        return _na(str(exc))
    parts = [f'<p class="cause">cause: {_esc(d.get("cause"))}</p>',
             f"<p>{_esc(d.get('explanation', ''))}</p>"]
    b = d.get("baseline", {}) or {}
    parts.append("<h3>Baseline</h3>"
                 f"<p>model <code>{_esc(b.get('model'))}</code>; calibrated parameters: "
                 f"{_esc(_fmt_params(b.get('params', {}) or {}))}; held-out rms "
                 f"{_esc(_num(b.get('heldout_rms_mm')))} mm.</p>")
    parts.append("<h3>What the baseline gets wrong</h3>")
    disc = d.get("discrepancies") or []
    if disc:
        parts.append("<ul>" + "".join(
            f"<li><b>{_esc(x.get('signature'))}</b> ({_esc(_num(x.get('value')))} {_esc(x.get('unit', ''))}): "
            f"{_esc(x.get('text', ''))}</li>" for x in disc) + "</ul>")
    else:
        parts.append("<p>no significant discrepancy reported.</p>")
    parts.append("<h3>Candidate causes</h3>")
    cands = d.get("candidates") or []
    if cands:
        rows = [{"cause": c.get("cause"), "parameters": _fmt_params(c.get("params", {}) or {}),
                 "n_params": c.get("n_params"), "train rms [mm]": c.get("train_rms_mm"),
                 "held-out rms [mm]": c.get("heldout_rms_mm"), "AIC": c.get("aic")} for c in cands]
        df = pd.DataFrame(rows)
        for col in ("train rms [mm]", "held-out rms [mm]", "AIC"):
            df[col] = pd.to_numeric(df[col], errors="coerce")
        parts.append(_table(df.sort_values("held-out rms [mm]", na_position="last")))
    else:
        parts.append("<p>no candidates were fitted.</p>")
    g = d.get("gain") or {}
    parts.append("<h3>Gain</h3>"
                 f"<p>{_esc(g.get('metric', 'heldout_rms_mm'))}: baseline {_esc(_num(g.get('baseline')))} → "
                 f"extended {_esc(_num(g.get('extended')))} "
                 f"(<b>{_esc(_num(g.get('reduction_pct')))} %</b> lower).</p>")
    extra = {k: v for k, v in d.items() if k not in ("experiments", "baseline", "discrepancies", "candidates",
                                                      "cause", "explanation", "gain")}
    if extra:
        parts.append("<details><summary>other fields of diagnosis.json</summary><pre>"
                     + _esc(_json_short(extra)) + "</pre></details>")
    if figs:
        parts.append("<h3>Figures</h3>" + "".join(_png(p, out_dir) for p in figs))
    return "\n".join(parts)


def _json_short(obj, limit: int = 20000) -> str:
    s = json.dumps(obj, indent=1, default=str)
    return s if len(s) <= limit else s[:limit] + "\n..."


def _num(v) -> str:
    if v is None:
        return "–"
    try:
        return f"{float(v):.4g}"
    except (TypeError, ValueError):
        return str(v)


# ----------------------------------------------------------------------------- summary
def summary_lines(out_dir) -> list[str]:
    """Three lines: fit errors, the named cause, the measured gain (what is available)."""
    out_dir = Path(out_dir)
    lines = []
    found = nio.find_output(out_dir, "fits.csv")
    if found:
        frames = []
        for p in found.values():
            try:
                frames.append(nio.read_fits(p))
            except (ValueError, FileNotFoundError):
                pass
        if frames:
            st = _fit_stats(pd.concat(frames, ignore_index=True))
            txt = "; ".join(f"{r['model']} {r['rms of all points [mm]']:.3f} mm rms "
                            f"(max {r['max error [mm]']:.3f} mm)" for _, r in st.iterrows())
            n = sum(len(f) for f in frames) // max(len(st), 1)
            lines.append(f"fit errors over {n} samples: {txt}")
    else:
        lines.append("fit errors: not available (no fits.csv)")
    path = out_dir / "diagnosis.json"
    if path.is_file():
        try:
            d = nio.read_diagnosis(path)
            b = d.get("baseline") or {}
            lines.append(f"cause: {d.get('cause')} (calibrated baseline held-out rms "
                         f"{_num(b.get('heldout_rms_mm'))} mm)")
            g = d.get("gain") or {}
            lines.append(f"gain: held-out rms {_num(g.get('baseline'))} -> {_num(g.get('extended'))} mm "
                         f"({_num(g.get('reduction_pct'))} % lower)")
        except ValueError as exc:
            lines += [f"cause: not available ({exc})", "gain: not available"]
    else:
        lines += ["cause: not available (no diagnosis.json)", "gain: not available (no diagnosis.json)"]
    return lines


# ----------------------------------------------------------------------------- build
def _refuse_input_folder(out_dir: Path) -> None:
    """An experiment or study folder is input data, not an output folder: refuse it with a hint."""
    try:
        subs = [p for p in out_dir.iterdir() if p.is_dir() and not p.name.startswith(".")]
    except OSError:
        subs = []
    if nio.is_experiment_dir(out_dir) or any(nio.is_experiment_dir(p) for p in subs):
        raise ValueError(f"{out_dir}: is an input study or experiment (it holds experiment.toml), not an "
                         "output folder; run `notchfit report OUT --study "
                         f"{out_dir}` on the --out folder of fit/simulate/diagnose")


def build_report(out_dir, *, study=None, title: str | None = None, filename: str = "report.html",
                 force: bool = False) -> Path:
    """Write ``out_dir/report.html``: one self-contained HTML file.

    Parameters
    ----------
    out_dir : path
        The folder the pipeline commands wrote into.
    study : path, optional
        The study (or experiment) folder; default: from the provenance files.
    title : str, optional
    force : bool
        Replace an existing report.

    Returns
    -------
    Path
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: output folder not found")
    _refuse_input_folder(out_dir)
    target = out_dir / filename
    if target.exists() and not force:
        raise FileExistsError(f"{target}: exists; use --force to replace it")
    study_path = Path(study) if study is not None else find_study(out_dir)
    exps, why = None, "no study folder known (give --study STUDY)"
    if study_path is not None:
        try:
            exps = nio.read_study(study_path, missing_images="keep")
        except (ValueError, FileNotFoundError) as exc:
            why = f"cannot read the study: {exc}"
    body = {}
    body["summary"] = "<ul>" + "".join(f"<li>{_esc(s)}</li>" for s in summary_lines(out_dir)) + "</ul>"
    body["study"] = _study_section(exps, study_path, why)
    for key, fn in (("calibration", lambda: _calibration_section(out_dir, exps)),
                    ("detection", lambda: _detection_section(out_dir, exps)),
                    ("fit", lambda: _fit_section(out_dir)),
                    ("simulation", lambda: _simulation_section(out_dir)),
                    ("diagnosis", lambda: _diagnosis_section(out_dir))):
        try:
            body[key] = fn()
        except Exception as exc:  # noqa: BLE001 - one broken input must not lose the report
            body[key] = _na(f"could not build this section: {type(exc).__name__}: {exc}")
    title = title or f"notchfit report: {study_path.name if study_path else out_dir.name}"
    now = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    nav = "".join(f'<a href="#{k}">{_esc(t)}</a>' for k, t in SECTIONS)
    secs = "\n".join(f'<section id="{k}"><h2>{_esc(t)}</h2>\n{body[k]}\n</section>' for k, t in SECTIONS)
    doc = (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
           f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>\n"
           f"<h1>{_esc(title)}</h1><p class=\"small\">notchfit {__version__}, {now}; output folder "
           f"<code>{_esc(out_dir.resolve())}</code>. Errors are notch-point distances in the "
           f"plane frame (Moses et al. 2015, Sec. IV-A).</p><nav>{nav}</nav>\n{secs}\n</body></html>\n")
    return nio.write_text_atomic(doc, target)
