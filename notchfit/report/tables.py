"""The report's numbers, read back from what the commands wrote (``notchfit report``).

Each function takes the report's inputs (:class:`notchfit.report.Inputs`)
and returns plain tables or formatted rows; signs are converted to the
report's one convention (manipulator frame) where a file used another.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import io as nio
from ..units import DEG
from .page import num, pct

__all__ = ["b_at_peak_rows", "detection_rows", "diagnosis_loops", "fit_tables", "peak_index",
           "simulation_table", "thumbnail_panels"]


def peak_index(tension_left, tension_right) -> int:
    """Index of the sample with the largest ``|T_left − T_right|`` (the peak of the bend)."""
    return int(np.argmax(np.abs(np.asarray(tension_left, float) - np.asarray(tension_right, float))))


def _by_name(inp, filename: str) -> dict:
    """``{experiment: path}`` of an output file, with the single-experiment key resolved to its name."""
    out = {}
    for name, path in nio.find_output(inp.out, filename).items():
        e = inp.experiment(name)
        out[e.name if e is not None else (name or "(single experiment)")] = path
    return out


# ----------------------------------------------------------------------------- detection
def detection_rows(inp) -> list[dict]:
    """Per experiment: images, share of corners ok, ambiguous, not found, σ; ``_sigma`` the median [mm]."""
    rows = []
    for name, path in _by_name(inp, "detections.csv").items():
        try:
            det = nio.read_detections(path)
        except (ValueError, FileNotFoundError):
            continue
        st = det["status"].astype(str).str.lower()
        sig = det.loc[st == "ok", "sigma_mm"].to_numpy(float)
        sig = sig[np.isfinite(sig)]
        rows.append({"experiment": name, "images": int(det["sample"].nunique()),
                     "corners ok": pct(100.0 * float((st == "ok").mean()) if len(det) else np.nan, 3),
                     "ambiguous": int((st == "ambiguous").sum()), "not found": int((st != "ok").sum()
                                                                                   - (st == "ambiguous").sum()),
                     "median σ [mm]": num(np.median(sig), 2) if sig.size else "–",
                     "95 % σ [mm]": num(np.percentile(sig, 95), 2) if sig.size else "–",
                     "_sigma": float(np.median(sig)) if sig.size else np.nan})
    return rows


def _panel(e, det: pd.DataFrame, index: int, title: str, margin: float = 0.2) -> dict | None:
    """A crop of sample ``index``'s image around its detected corners, the corners in crop pixels."""
    path = e.image_paths[index] if e.image_paths else None
    d = det[det["sample"] == int(e.sample_ids[index])].sort_values("point")
    if path is None or d.empty:
        return None
    try:
        img = nio.load_image(path)
    except (FileNotFoundError, ValueError):
        return None
    if img.ndim == 3:
        img = img[..., :3].mean(-1)
    uv = d[["u_px", "v_px"]].to_numpy(float)
    good = np.isfinite(uv).all(1)
    if not good.any():
        return None
    lo, hi = uv[good].min(0), uv[good].max(0)
    pad = margin * np.maximum(hi - lo, 20.0)
    u0, v0 = np.maximum(lo - pad, 0).astype(int)
    u1, v1 = np.minimum(hi + pad, [img.shape[1] - 1, img.shape[0] - 1]).astype(int) + 1
    crop = np.asarray(img[v0:v1, u0:u1], float)
    lo_v, hi_v = np.percentile(crop, [1, 99])
    crop = np.clip((crop - lo_v) / max(hi_v - lo_v, 1e-9) * 255, 0, 255)
    full = np.full((e.geometry.n_points, 2), np.nan)
    status = np.full(e.geometry.n_points, "occluded", dtype=object)
    pts = d["point"].to_numpy(int) - 1
    full[pts] = uv - [u0, v0]
    status[pts] = d["status"].astype(str).str.lower().to_numpy()
    n_ok = int((status == "ok").sum())
    return {"image": crop, "uv": full, "status": status,
            "title": f"{title}: {n_ok} of {e.geometry.n_points} ok"}


def thumbnail_panels(inp, limit: int = 3) -> list[dict]:
    """Up to ``limit`` crops: the rest shape and the peak bend of each pull direction."""
    found = _by_name(inp, "detections.csv")
    picks = []
    exps = [inp.by_name[n] for n in found if n in inp.by_name and inp.by_name[n].has_images]
    if not exps:
        return []
    picks.append((exps[0], 0, f"{exps[0].name} sample {exps[0].sample_ids[0]} (rest)"))
    for side in (-1, 1):
        e = next((x for x in exps if inp.pulled[x.name] == side), None)
        if e is not None:
            k = peak_index(e.tension_left, e.tension_right)
            picks.append((e, k, f"{e.name} sample {e.sample_ids[k]} (peak)"))
    panels = []
    for e, k, title in picks[:limit]:
        try:
            det = nio.read_detections(found[e.name])
        except (ValueError, FileNotFoundError):
            continue
        p = _panel(e, det, k, title)
        if p is not None:
            panels.append(p)
    return panels


# ----------------------------------------------------------------------------- fit
def fit_tables(inp):
    """Shape-fit tables: rms by model and notch point, rms by sample against ``T_left − T_right``, and
    per experiment the linear fit's rms and ``a``, ``b`` at the peak (formatted rows)."""
    pw = []
    for name, path in _by_name(inp, "pointwise.csv").items():
        try:
            pw.append(nio.read_pointwise(path))
        except (ValueError, FileNotFoundError):
            pass
    by_point = None
    if pw:
        p = pd.concat(pw, ignore_index=True)
        by_point = (p.groupby(["model", "point"], sort=False)["err_mm"]
                    .apply(lambda v: float(np.sqrt(np.nanmean(np.square(v))))).rename("rms_mm").reset_index())
    samples, per_exp = [], []
    if inp.angles:
        return None, pd.DataFrame(columns=["experiment", "model", "dT_N", "rms_mm"]), _angle_fit_rows(inp)
    for name, path in _by_name(inp, "fits.csv").items():
        try:
            fits = nio.read_fits(path)
        except (ValueError, FileNotFoundError):
            continue
        e = inp.by_name.get(name)
        if e is not None:
            dT = pd.Series(e.tension_left - e.tension_right, index=e.sample_ids)
            samples.append(fits.assign(experiment=name, dT_N=fits["sample"].map(dT))[
                ["experiment", "model", "dT_N", "rms_mm"]])
        lin = fits[fits["model"] == "linear"]
        if lin.empty:
            continue
        row = {"experiment": name, "linear rms [mm]": num(np.sqrt(np.nanmean(lin["rms_mm"] ** 2)))}
        if e is not None:
            s = int(e.sample_ids[peak_index(e.tension_left, e.tension_right)])
            pk = lin[lin["sample"] == s]
            if len(pk):
                row["a at peak [rad]"] = num(pk["a"].iloc[0], sign=True)
                row["b at peak [rad/joint]"] = num(pk["b"].iloc[0], 2, sign=True)
        per_exp.append(row)
    by_sample = pd.concat(samples, ignore_index=True) if samples else \
        pd.DataFrame(columns=["experiment", "model", "dT_N", "rms_mm"])
    return by_point, by_sample, per_exp


def _angle_fit_rows(inp) -> list[dict]:
    """Per experiment of an angle study: the linear fit's rms [deg] and ``a``, ``b`` at the peak [deg, deg per
    joint] (``angle_fits.csv``)."""
    rows = []
    for name, path in _by_name(inp, "angle_fits.csv").items():
        try:
            fits = nio.read_angle_fits(path)
        except (ValueError, FileNotFoundError):
            continue
        lin = fits[fits["model"] == "linear"]
        if lin.empty:
            continue
        row = {"experiment": name, "linear rms [deg]": num(np.sqrt(np.nanmean(lin["rms_deg"] ** 2)))}
        e = inp.by_name.get(name)
        if e is not None:
            s = int(e.sample_ids[peak_index(np.nan_to_num(e.tension_left), np.nan_to_num(e.tension_right))])
            pk = lin[lin["sample"] == s]
            if len(pk):
                row["a at peak [deg]"] = num(pk["a"].iloc[0] / DEG, sign=True)
                row["b at peak [deg/joint]"] = num(pk["b"].iloc[0] / DEG, 2, sign=True)
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------- simulation
def simulation_table(inp):
    """Simulation against measurement: every sample (frame signs) and a formatted row per experiment."""
    frames, rows = [], []
    for name, path in _by_name(inp, "simulation.csv").items():
        cpath = path.parent / "simulation_vs_measured.csv"
        if not cpath.is_file():
            continue
        c = nio.read_simulation_vs_measured(cpath)
        c = c.assign(experiment=name, dT_N=c["tension_left_N"] - c["tension_right_N"])
        frames.append(c)
        k = peak_index(c["tension_left_N"], c["tension_right_N"])
        v = c["point_rms_mm"].to_numpy(float)
        rows.append({"experiment": name, "point rms [mm]": num(np.sqrt(np.nanmean(v ** 2))),
                     "a at peak, measured [rad]": num(c["a_meas"].iloc[k], sign=True),
                     "a at peak, simulated [rad]": num(c["a_sim"].iloc[k], sign=True),
                     "b at peak, measured [rad/joint]": num(c["b_meas"].iloc[k], 2, sign=True),
                     "b at peak, simulated [rad/joint]": num(c["b_sim"].iloc[k], 2, sign=True)})
    cmp = pd.concat(frames, ignore_index=True) if frames else None
    return cmp, rows


# ----------------------------------------------------------------------------- diagnosis
def diagnosis_loops(inp) -> pd.DataFrame | None:
    """``diagnosis_loops.csv`` signed in the manipulator frame (files without ``pulled_cable`` were signed
    toward the pulled cable: converted with the study's pulled side)."""
    path = inp.out / "diagnosis_loops.csv"
    if not path.is_file():
        return None
    loops = nio.read_diagnosis_csv(path)
    if "pulled_cable" not in loops:
        if not inp.pulled:
            return None                          # the sign cannot be told without the study
        sign = loops["experiment"].map(inp.pulled).astype(float)
        loops = loops.assign(tip_angle_rad=sign * loops["tip_angle_rad"], b_rad=sign * loops["b_rad"])
    return loops


def b_at_peak_rows(inp) -> list[dict]:
    """Per experiment, ``b`` at the peak of the pulled tension: measured and the held-out predictions."""
    loops = inp.once(diagnosis_loops)
    if loops is None or "b_rad" not in loops:
        return []
    rows = []
    for name, g in loops.groupby("experiment", sort=False):
        meas = g[g["series"] == "measured"]
        if meas.empty:
            continue
        s = meas["sample"].iloc[int(np.argmax(meas["tension_pulled_N"].to_numpy(float)))]
        row = {"experiment": name}
        f, u = (DEG, "deg") if inp.angles else (1.0, "rad")
        for series, h in g.groupby("series", sort=False):
            label = series.split(" (")[0]
            val = h.loc[h["sample"] == s, "b_rad"]
            row[f"b at peak, {label} [{u}/joint]"] = num(val.iloc[0] / f, 2, sign=True) if len(val) else "–"
            if label == "measured":
                tip = h.loc[h["sample"] == s, "tip_angle_rad"]
                row[f"tip angle at peak, measured [{u}]"] = num(tip.iloc[0] / f, sign=True) if len(tip) else "–"
        rows.append(row)
    return rows
