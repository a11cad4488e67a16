"""Typed readers of the commands' result files, for programs that read results back (``notchfit report``).

``diagnosis.json``, ``identify.json`` and the ``*_run.json`` records become
frozen dataclasses with every field checked once here; the result tables
(``simulation_vs_measured.csv``, ``angle_fits.csv``, the diagnosis's CSVs)
are read through :func:`notchfit.io.read_csv_table` with their columns
validated. Errors are in the file's unit (``unit``: ``"mm"`` for notch
points, ``"deg"`` for joint angles: docs/data-formats.md), parameters SI by
model-file key. A problem is an :class:`InputFileError` naming the file and
the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from .errors import InputFileError
from .outputs import read_diagnosis, read_json
from .tables import read_csv_table

__all__ = ["Candidate", "Contribution", "DiagnosisRecord", "FitRecord", "Gain", "IdentifyRecord", "RunRecord",
           "Signature", "TubeRecord", "read_angle_fits", "read_diagnosis_csv", "read_diagnosis_record",
           "read_identify", "read_run_records", "read_simulation_vs_measured"]


# ----------------------------------------------------------------------------- field checks
class _Fields:
    """Typed access to one JSON object of a file; a wrong type is an error naming the file and key."""

    def __init__(self, path: Path, data, where: str = ""):
        self.path, self.where = path, where
        if not isinstance(data, dict):
            self._bad(where or "(top level)", "a JSON object", data)
        self.data = data

    def _bad(self, key, want, got):
        raise InputFileError(f"{self.path}: key {self.where}{key}: expected {want}, got {type(got).__name__}",
                             path=self.path, key=f"{self.where}{key}")

    def num(self, key: str, default=math.nan) -> float:
        v = self.data.get(key, default)
        if v is None:
            return math.nan
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self._bad(key, "a number", v)
        return float(v)

    def text(self, key: str, default: str = "") -> str:
        v = self.data.get(key, default)
        if v is None:
            return default
        if not isinstance(v, str):
            self._bad(key, "a string", v)
        return v

    def flag(self, key: str) -> bool:
        return bool(self.data.get(key, False))

    def texts(self, key: str) -> tuple[str, ...]:
        v = self.data.get(key) or []
        if not isinstance(v, list):
            self._bad(key, "a list", v)
        return tuple(str(x) for x in v)

    def numbers(self, key: str) -> dict[str, float]:
        """A ``{name: number}`` object (non-numbers such as a law's name are left out)."""
        v = self.data.get(key) or {}
        if not isinstance(v, dict):
            self._bad(key, "an object", v)
        return {str(k): float(x) for k, x in v.items() if isinstance(x, (int, float)) and not isinstance(x, bool)}

    def values(self, key: str) -> dict:
        """A ``{name: number or text}`` object, numbers as float."""
        v = self.data.get(key) or {}
        if not isinstance(v, dict):
            self._bad(key, "an object", v)
        return {str(k): (float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else x)
                for k, x in v.items()}

    def sub(self, key: str) -> _Fields | None:
        v = self.data.get(key)
        return None if v is None else _Fields(self.path, v, f"{self.where}{key}.")

    def items(self, key: str) -> list[_Fields]:
        v = self.data.get(key) or []
        if not isinstance(v, list):
            self._bad(key, "a list", v)
        return [_Fields(self.path, x, f"{self.where}{key}[{i}].") for i, x in enumerate(v)]


# ----------------------------------------------------------------------------- diagnosis.json
@dataclass(frozen=True)
class FitRecord:
    """A calibrated model of a diagnosis: the baseline, or the extended model (``causes`` named)."""

    model: str
    params: dict
    se: dict
    fixed: dict
    heldout_rms: float
    train_rms: float
    causes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Candidate:
    """One candidate cause (or pair ``a+b``) tried by the diagnosis, its held-out error and significance."""

    cause: str
    params: dict
    heldout_rms: float
    z: float
    excess_removed: float
    significant: bool


@dataclass(frozen=True)
class Contribution:
    """A named cause: what adding it removes on held-out data (``gain_pct``, Shapley ``share_pct``)."""

    cause: str
    params: dict
    gain_pct: float
    share_pct: float
    heldout_rms_alone: float
    heldout_rms_without: float
    heldout_rms_with: float
    z: float
    removes: str


@dataclass(frozen=True)
class Signature:
    """A discrepancy signature of the held-out baseline: ``value`` in ``unit`` (``"-"``: a ratio)."""

    signature: str
    value: float
    unit: str
    text: str


@dataclass(frozen=True)
class Gain:
    """Held-out rms of the baseline and of the extended model, and the reduction [%]."""

    baseline: float
    extended: float
    reduction_pct: float


@dataclass(frozen=True)
class DiagnosisRecord:
    """``diagnosis.json`` (``notchfit diagnose``), errors in ``unit``."""

    experiments: tuple[str, ...]
    metric: str
    unit: str
    baseline: FitRecord
    noise_rms: float
    discrepancies: tuple[Signature, ...]
    candidates: tuple[Candidate, ...]
    pair_candidates: tuple[Candidate, ...]
    cause: str
    causes: tuple[str, ...]
    contributions: tuple[Contribution, ...]
    explanation: str
    extended: FitRecord | None
    gain: Gain
    per_regime: dict
    protocol_source: dict
    protocol_ramp_s: dict
    protocol_text: str
    skipped_signatures: dict
    extended_model_file: str
    floor_rms: float = math.nan

    @property
    def floor(self) -> float:
        """The floor the ``none`` rule compared with: the noise and the baseline folds' prediction band
        (``floor_rms_<unit>``), the noise alone in files written before the band."""
        return self.floor_rms if math.isfinite(self.floor_rms) else self.noise_rms

    @property
    def named(self) -> tuple[str, ...]:
        """The named causes: ``causes``, else the one ``cause`` (``none``, ``unexplained``)."""
        return self.causes or (self.cause,)


def _fit_record(f: _Fields | None, unit: str) -> FitRecord | None:
    if f is None:
        return None
    return FitRecord(model=f.text("model", "moses2015"), params=f.numbers("params"), se=f.numbers("se"),
                     fixed=f.numbers("fixed"), heldout_rms=f.num(f"heldout_rms_{unit}"),
                     train_rms=f.num(f"train_rms_{unit}"),
                     causes=f.texts("causes") or ((f.text("cause"),) if f.text("cause") else ()))


def _candidate(f: _Fields, unit: str) -> Candidate:
    return Candidate(cause=f.text("cause"), params=f.numbers("params"), heldout_rms=f.num(f"heldout_rms_{unit}"),
                     z=f.num("z"), excess_removed=f.num("excess_removed"), significant=f.flag("significant"))


def _contribution(f: _Fields, unit: str) -> Contribution:
    return Contribution(cause=f.text("cause"), params=f.numbers("params"), gain_pct=f.num("gain_pct"),
                        share_pct=f.num("share_pct"), heldout_rms_alone=f.num(f"heldout_rms_alone_{unit}"),
                        heldout_rms_without=f.num(f"heldout_rms_without_{unit}"),
                        heldout_rms_with=f.num(f"heldout_rms_with_{unit}"), z=f.num("z"), removes=f.text("removes"))


def read_diagnosis_record(path) -> DiagnosisRecord:
    """Read ``diagnosis.json`` (:func:`notchfit.io.read_diagnosis` checks its keys) into a
    :class:`DiagnosisRecord`; errors in degrees for ``metric = "angles"``, else mm."""
    path = Path(path)
    f = _Fields(path, read_diagnosis(path))
    metric = f.text("metric", "points")
    unit = "deg" if metric == "angles" else "mm"
    g = f.sub("gain") or _Fields(path, {}, "gain.")
    regimes = f.sub(f"per_regime_rms_{unit}")
    per_regime = {k: Gain(s.num("baseline"), s.num("extended"), s.num("reduction_pct"))
                  for k, s in ((k, regimes.sub(k)) for k in (regimes.data if regimes else {}))}
    proto = f.sub("protocol") or _Fields(path, {}, "protocol.")
    skipped = f.sub("skipped")
    sk = skipped.sub("signatures") if skipped else None
    cause = f.text("cause")
    causes = f.texts("causes") or (() if cause in ("none", "unexplained", "") else (cause,))   # the one-cause form
    return DiagnosisRecord(
        experiments=f.texts("experiments"), metric=metric, unit=unit,
        baseline=_fit_record(f.sub("baseline"), unit), noise_rms=f.num(f"noise_rms_{unit}"),
        discrepancies=tuple(Signature(s.text("signature"), s.num("value"), s.text("unit"), s.text("text"))
                            for s in f.items("discrepancies")),
        candidates=tuple(_candidate(c, unit) for c in f.items("candidates")),
        pair_candidates=tuple(_candidate(c, unit) for c in f.items("pair_candidates")),
        cause=cause, causes=causes,
        contributions=tuple(_contribution(c, unit) for c in f.items("contributions")),
        explanation=f.text("explanation"), extended=_fit_record(f.sub("extended_model"), unit),
        gain=Gain(g.num("baseline"), g.num("extended"), g.num("reduction_pct")), per_regime=per_regime,
        protocol_source={k: str(v) for k, v in proto.values("source").items()},
        protocol_ramp_s=proto.numbers("ramp_time_s"), protocol_text=proto.text("text"),
        skipped_signatures={k: str(v) for k, v in (sk.data if sk else {}).items()},
        extended_model_file=f.text("extended_model_file", "extended_model.toml"),
        floor_rms=f.num(f"floor_rms_{unit}"))


# ----------------------------------------------------------------------------- identify.json
@dataclass(frozen=True)
class TubeRecord:
    """One tube (geometry) of an identification: its experiments, rest angles [deg] and cut depths [mm]
    with standard errors (NaN where not fitted), and its error predicted from the other tubes' fit."""

    label: str
    experiments: tuple[str, ...]
    rest_angle_deg: tuple[float, ...]
    rest_angle_se_deg: tuple[float, ...]
    slot_depth_mm: tuple[float, ...]
    slot_depth_offset_um: tuple[float, ...]
    slot_depth_offset_se_um: tuple[float, ...]
    heldout_by_geometry: float
    model_file: str


@dataclass(frozen=True)
class IdentifyRecord:
    """``identify.json`` (``notchfit identify``): the identified model, its errors in ``unit``, per tube."""

    free: tuple[str, ...]
    free_per_tube: tuple[str, ...]
    params: dict
    se: dict
    unit: str
    train_rms: float
    heldout_rms: float
    heldout: dict
    train: dict
    tubes: tuple[TubeRecord, ...]
    model_file: str
    converged: bool
    message: str


def _floats(f: _Fields, key: str) -> tuple[float, ...]:
    v = f.data.get(key) or []
    if not isinstance(v, list):
        f._bad(key, "a list", v)
    return tuple(math.nan if x is None else float(x) for x in v)


def read_identify(path) -> IdentifyRecord:
    """Read ``identify.json`` into an :class:`IdentifyRecord` (docs/data-formats.md)."""
    path = Path(path)
    f = _Fields(path, read_json(path))
    if "params" not in f.data:
        raise InputFileError(f"{path}: missing key params (identify.json schema)", path=path, key="params")
    by_geom = f.numbers("heldout_by_geometry")
    files = f.values("tube_model_files")
    tubes_f = f.sub("tubes")
    tubes = tuple(TubeRecord(label=k, experiments=t.texts("experiments"), rest_angle_deg=_floats(t, "rest_angle_deg"),
                             rest_angle_se_deg=_floats(t, "rest_angle_se_deg"),
                             slot_depth_mm=_floats(t, "slot_depth_mm"),
                             slot_depth_offset_um=_floats(t, "slot_depth_offset_um"),
                             slot_depth_offset_se_um=_floats(t, "slot_depth_offset_se_um"),
                             heldout_by_geometry=by_geom.get(k, math.nan), model_file=str(files.get(k, "")))
                  for k, t in ((k, tubes_f.sub(k)) for k in (tubes_f.data if tubes_f else {})))
    fit = f.sub("fit") or _Fields(path, {}, "fit.")
    return IdentifyRecord(free=f.texts("free"), free_per_tube=f.texts("free_per_tube"), params=f.numbers("params"),
                          se=f.numbers("se"), unit=f.text("metric", "mm"), train_rms=f.num("train_rms"),
                          heldout_rms=f.num("heldout_rms"), heldout=f.numbers("heldout"), train=f.numbers("train"),
                          tubes=tubes, model_file=f.text("model_file", "model.toml"),
                          converged=bool(fit.data.get("success", True)), message=fit.text("message"))


# ----------------------------------------------------------------------------- run records
@dataclass(frozen=True)
class RunRecord:
    """A ``<command>_run.json`` provenance record: what ran, on which input, with which parameters."""

    command: str
    input: str
    params: dict | None
    params_by_experiment: dict = field(default_factory=dict)
    model_file: str = ""
    param_overrides: tuple[str, ...] = ()
    angle_rms_deg: dict = field(default_factory=dict)


def read_run_records(out_dir) -> dict[str, RunRecord]:
    """``{command: RunRecord}`` of the ``*_run.json`` files of an output folder (unreadable ones skipped)."""
    out = {}
    for p in sorted(Path(out_dir).glob("*_run.json")):
        try:
            f = _Fields(p, read_json(p))
            by_exp = f.sub("params_by_experiment")
            rec = RunRecord(command=f.text("command", p.stem[:-4]), input=f.text("input"),
                            params=f.values("params") if f.data.get("params") is not None else None,
                            params_by_experiment={k: by_exp.values(k) for k in by_exp.data} if by_exp else {},
                            model_file=f.text("model_file"), param_overrides=f.texts("param_overrides"),
                            angle_rms_deg=f.numbers("angle_rms_deg"))
        except (ValueError, OSError):
            continue
        out[rec.command] = rec
    return out


# ----------------------------------------------------------------------------- result tables
#: Layouts of the result tables the report reads: (required columns, text columns, integer columns).
_TABLES = {
    "simulation_vs_measured.csv": (("sample", "tension_left_N", "tension_right_N", "a_meas", "b_meas", "a_sim",
                                    "b_sim", "point_rms_mm"), ("regime",), ("sample",)),
    "angle_fits.csv": (("sample", "model", "a", "b", "rms_deg", "max_deg"), ("model", "message", "success"),
                       ("sample",)),
    "diagnosis_candidates.csv": (("model",), ("model",), ()),
    "diagnosis_loops.csv": (("experiment", "sample", "tension_pulled_N", "series", "tip_angle_rad"),
                            ("experiment", "series", "pulled_cable"), ("sample",)),
    "diagnosis_point_errors.csv": (("point",), ("tube",), ("point",)),
    "diagnosis_residual_map.csv": (("experiment", "sample", "point"), ("experiment",), ("sample", "point")),
    "diagnosis_joint_errors.csv": (("joint",), ("tube",), ("joint",)),
}


def _read_result_table(path, name: str) -> pd.DataFrame:
    required, text, integer = _TABLES[name]
    header = Path(path).open(encoding="utf-8", errors="replace").readline().strip().split(",")
    numeric = [h for h in header if h not in text and h not in integer]
    df, _ = read_csv_table(path, required=required, integer=integer, nan_ok=numeric, text=text)
    return df


def read_simulation_vs_measured(path) -> pd.DataFrame:
    """``simulation_vs_measured.csv`` (``simulate`` with measured points): per sample the tensions [N],
    ``a``, ``b`` measured and simulated [rad, rad per joint] and the point rms [mm]."""
    return _read_result_table(path, "simulation_vs_measured.csv")


def read_angle_fits(path) -> pd.DataFrame:
    """``angle_fits.csv`` (``fit`` on measured joint angles): per sample and model ``a``, ``b`` [rad] and the
    rms and max angle error [deg]."""
    df = _read_result_table(path, "angle_fits.csv")
    if "success" in df:
        df["success"] = df["success"].str.lower().isin(["true", "1"])
    return df


def read_diagnosis_csv(path) -> pd.DataFrame:
    """A table ``diagnose`` writes beside its figures, by file name: ``diagnosis_candidates.csv``,
    ``diagnosis_loops.csv``, ``diagnosis_point_errors.csv``, ``diagnosis_residual_map.csv`` or
    ``diagnosis_joint_errors.csv`` (columns as docs/data-formats.md lists them)."""
    path = Path(path)
    if path.name not in _TABLES:
        raise ValueError(f"{path}: not a diagnosis table ({', '.join(k for k in _TABLES if k.startswith('diag'))})")
    return _read_result_table(path, path.name)
