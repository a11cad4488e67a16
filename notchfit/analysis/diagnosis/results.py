"""Typed results of a diagnosis; :meth:`Diagnosis.to_dict` is the content of ``diagnosis.json``.

Inside, errors are in SI: metres (notch points) or radians (joint angles).
The dictionaries (the file format, docs/data-formats.md) give them in the
metric's file unit under suffixed keys: ``*_mm`` for notch points (the
paper's metric, Sec. IV-A), ``*_deg`` for measured joint angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ...physics.friction import FrictionParams
from ...units import DEG, MM
from ..lack_of_fit import LackOfFit
from .calibration import Calibration
from ..estimation.observations import metric_unit
from .specs import BASELINE_MU_EXCESS, WARP_RADIUS, model_key, model_params

__all__ = ["CandidateResult", "Contribution", "Diagnosis", "Gain", "Signature", "metric_unit"]


def _tubes_dict(tubes: dict) -> dict:
    """Per-tube values of a real tube's baseline in file units: rest angles [deg], depth offsets [µm]."""
    names = {"rest_angle": ("rest_angle_deg", 1.0 / DEG), "slot_depth_offset": ("slot_depth_offset_um", 1e6)}
    return {t: {names[k][0]: [float(x) * names[k][1] for x in v] for k, v in blocks.items() if k in names}
            for t, blocks in tubes.items()}


def _lof_dict(lof: LackOfFit | None) -> dict | None:
    """A lack-of-fit table for diagnosis.json; without repeated trials only its unit and verdict."""
    if lof is None:
        return None
    if not lof.has_replicates:
        return {"unit": lof.unit, "alpha": lof.alpha, "verdict": lof.verdict()}
    return lof.as_dict()


@dataclass(frozen=True)
class Signature:
    """One discrepancy signature of the held-out baseline, with its number and words.

    Attributes
    ----------
    name : str
        E.g. ``unloading_hold``, ``loop_area_ratio`` (docs/diagnosis.md).
    value : float
        In ``unit`` (SI: lengths in m; angle errors of angle data in degrees).
    unit : str
        ``"m"``, ``"N"``, ``"rad"``, ``"deg"`` or ``"-"``.
    text : str
        One sentence for the report.
    """

    name: str
    value: float
    unit: str
    text: str

    def to_dict(self) -> dict:
        """``{"signature", "value", "unit", "text"}``, lengths in mm."""
        if self.unit == "m":
            return {"signature": self.name, "value": self.value / MM, "unit": "mm", "text": self.text}
        return {"signature": self.name, "value": self.value, "unit": self.unit, "text": self.text}


@dataclass(frozen=True)
class CandidateResult:
    """A candidate extension (one cause, or a pair) fitted on the training folds and scored on the
    held-out experiments.

    Attributes
    ----------
    cause : str
        The cause id, or ``"a+b"`` for a pair.
    params : dict
        The extension's parameters (mean over folds) by name [SI].
    n_params : int
        Number of extension parameters.
    train_rms, heldout_rms : float
        Rms error on the training (mean over folds) and held-out experiments
        [m per notch point, or rad per joint angle].
    aic : float
        Akaike information criterion of the fold fits.
    z : float
        Significance of the held-out improvement over the model it extends
        (the baseline; for a pair, its first cause) (:func:`notchfit.analysis.diagnosis.noise.paired_z`).
    excess_removed : float
        Fraction of that model's excess over the noise floor removed.
    significant : bool
        ``z >= z_crit`` and ``excess_removed >= min_excess_removed``.
    """

    cause: str
    params: dict
    n_params: int
    train_rms: float
    heldout_rms: float
    aic: float
    z: float
    excess_removed: float
    significant: bool

    def to_dict(self, metric: str = "points") -> dict:
        u, f = metric_unit(metric)
        return {"cause": self.cause, "params": dict(self.params), "n_params": self.n_params,
                f"train_rms_{u}": self.train_rms / f, f"heldout_rms_{u}": self.heldout_rms / f,
                "aic": self.aic, "z": self.z, "excess_removed": self.excess_removed,
                "significant": self.significant}


@dataclass(frozen=True)
class Gain:
    """Held-out rms of the baseline and of the extended model [m or rad]."""

    baseline: float
    extended: float

    @property
    def reduction_pct(self) -> float:
        """How much lower the extended model's rms is [%] (0 when the baseline's is 0)."""
        return 100.0 * (self.baseline - self.extended) / self.baseline if self.baseline > 0 else 0.0

    def to_dict(self, metric: str = "points") -> dict:
        """``{"baseline", "extended", "reduction_pct"}`` with the rms in the metric's file unit."""
        _, f = metric_unit(metric)
        return {"baseline": self.baseline / f, "extended": self.extended / f,
                "reduction_pct": self.reduction_pct}


@dataclass(frozen=True)
class Contribution:
    """What one named cause contributes to the extended model (held-out, docs/diagnosis.md).

    Attributes
    ----------
    cause : str
    params : dict
        Its parameters in the model fitted on all experiments [SI].
    alone_rms : float
        Held-out rms of this cause alone (its single-cause candidate).
    without_rms : float
        Held-out rms of the extended model without this cause (the baseline
        when it is the only one).
    with_rms : float
        Held-out rms of the extended model.
    share : float
        Its share of the held-out mean squared discrepancy the extended model
        removes (Shapley: averaged over the orders of adding the causes; the
        shares add to 1).
    z : float
        Significance of adding it to the model without it.
    removes : str
        The discrepancy it removes, in words (signatures and regimes).
    without_key : str
        The held-out predictions of the model without it (a key of
        :attr:`Diagnosis.heldout`).
    """

    cause: str
    params: dict
    alone_rms: float
    without_rms: float
    with_rms: float
    share: float
    z: float
    removes: str
    without_key: str = "baseline"

    @property
    def gain_pct(self) -> float:
        """Held-out rms reduction from adding this cause to the model without it [%]."""
        return 100.0 * (self.without_rms - self.with_rms) / self.without_rms if self.without_rms > 0 else 0.0

    def to_dict(self, metric: str = "points") -> dict:
        u, f = metric_unit(metric)
        return {"cause": self.cause, "params": dict(self.params), "gain_pct": self.gain_pct,
                "share_pct": 100.0 * self.share, f"heldout_rms_alone_{u}": self.alone_rms / f,
                f"heldout_rms_without_{u}": self.without_rms / f, f"heldout_rms_with_{u}": self.with_rms / f,
                "z": self.z, "removes": self.removes}


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`notchfit.analysis.diagnosis.diagnose`.

    Attributes
    ----------
    experiments : tuple of str
    baseline : Calibration
        The baseline fitted on all experiments.
    baseline_heldout_rms : float
        Held-out rms of the baseline [m or rad].
    discrepancies : tuple of Signature
    candidates : tuple of CandidateResult
        The single causes, in the order they were tried.
    cause : str
        The first of :attr:`causes`, ``"none"`` or ``"unexplained"``.
    explanation : str
    gain : Gain
        Of the extended model (every named cause).
    extended : Calibration or None
        The extended model fitted on all experiments (None for none/unexplained).
    per_regime : dict
        ``{"I" | "II" | "III": Gain}`` for the regimes that occur.
    noise_rms : float
        Root of the noise floor [m or rad].
    seed : int
        Seed of the noise floor's draws.
    heldout : dict
        ``{"baseline" | model key: HeldOut}``: the held-out predictions.
    prepared : tuple of Prepared
        The experiments as analysed.
    causes : tuple of str
        Every named cause, ordered by contribution (empty for none/unexplained).
    contributions : tuple of Contribution
        One per named cause, in the same order.
    pair_candidates : tuple of CandidateResult
        The second causes tried after the first (``"a+b"``), scored against ``a``.
    metric : {"points", "angles"}
    protocol : dict
        ``{"ramp_time_s": {experiment: s}, "source": {experiment: "experiment.toml" |
        "estimated" | "assumed"}, "text": str}``.
    skipped : dict
        ``{"signatures": {name: reason}, "candidates": {cause: reason}, "experiments": {cause: the
        experiment that would reveal it}}`` (:func:`notchfit.analysis.diagnosis.scope.applicable_causes`), and
        ``"screened"``: ``{cause: reason}`` of the candidates fitted on all experiments but not
        cross-validated (:func:`notchfit.analysis.diagnosis.study._singles`).
    base : FrictionParams or None
        The model the fitted values change (None: the paper's).
    lack_of_fit : LackOfFit or None
        The held-out baseline's error against the trials' scatter (pure error and lack of fit,
        :mod:`notchfit.analysis.diagnosis.replicates`).
    extended_lack_of_fit : LackOfFit or None
        The same for the extended model (None without a named cause).
    band_rms : float
        Root of the mean prediction variance of the baseline's folds from their parameter uncertainty [m or
        rad] (:func:`notchfit.analysis.diagnosis.calibration.fold_band`; 0 when not computed).
    """

    experiments: tuple
    baseline: Calibration
    baseline_heldout_rms: float
    discrepancies: tuple
    candidates: tuple
    cause: str
    explanation: str
    gain: Gain
    extended: Calibration | None
    per_regime: dict
    noise_rms: float
    seed: int = 0
    heldout: dict = field(repr=False, default_factory=dict)
    prepared: tuple = field(repr=False, default=())
    causes: tuple = ()
    contributions: tuple = ()
    pair_candidates: tuple = ()
    metric: str = "points"
    protocol: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    base: FrictionParams | None = None
    lack_of_fit: LackOfFit | None = field(default=None, repr=False)
    extended_lack_of_fit: LackOfFit | None = field(default=None, repr=False)
    band_rms: float = 0.0

    @property
    def floor_rms(self) -> float:
        """The baseline's floor [m or rad]: ``√(noise_rms² + band_rms²)``, what its ``none`` rule compares with."""
        return math.hypot(self.noise_rms, self.band_rms)

    @property
    def extended_key(self) -> str:
        """Key of the extended model's held-out predictions in :attr:`heldout` (``"baseline"`` if none)."""
        return model_key(self.extended.cause) if self.extended is not None else "baseline"

    def summary(self) -> str:
        """What ``notchfit diagnose`` prints: the named cause(s) and the held-out rms of the baseline and the
        extended model, in the metric's file unit."""
        u, f = metric_unit(self.metric)
        g = self.gain
        causes = f" (causes: {', '.join(self.causes)})" if len(self.causes) > 1 else ""
        lines = [f"cause: {self.cause}{causes}",
                 f"held-out rms: baseline {g.baseline / f:.3f} {u}, extended {g.extended / f:.3f} {u} "
                 f"({g.reduction_pct:.1f}% lower); noise floor {self.noise_rms / f:.3f} {u}"
                 + (f", with the baseline folds' prediction uncertainty {self.band_rms / f:.3f} {u}: floor "
                    f"{self.floor_rms / f:.3f} {u}" if self.band_rms > 0 else "")]
        if self.lack_of_fit is not None:
            lines.append(f"lack of fit (held-out baseline): {self.lack_of_fit.verdict()}")
        if self.extended_lack_of_fit is not None and self.extended_lack_of_fit.has_replicates:
            lines.append(f"lack of fit (held-out extended model): {self.extended_lack_of_fit.verdict()}")
        reveal = self.skipped.get("experiments", {})
        for c, why in self.skipped.get("candidates", {}).items():
            lines.append(f"not tried: {c} ({why})" + (f"; {reveal[c]}" if c in reveal else ""))
        for c, why in self.skipped.get("screened", {}).items():
            lines.append(f"not cross-validated: {c} ({why})")
        return "\n".join(lines)

    def to_dict(self, *, extended_model_file: str | None = None, figures=None) -> dict:
        """The content of ``diagnosis.json`` (docs/data-formats.md).

        Parameters
        ----------
        extended_model_file : str, optional
            Name of the model TOML written beside it.
        figures : list of str, optional
            Names of the figures written beside it (the key is left out when None).
        """
        u, f = metric_unit(self.metric)
        ext = None
        if self.extended is not None:
            ext = {"cause": self.cause, "causes": list(self.causes), "params": self.extended.values,
                   "se": self.extended.se, f"train_rms_{u}": self.extended.train_rms / f}
        defaults = self.base or FrictionParams()
        out = {
            "experiments": list(self.experiments),
            "metric": self.metric,
            "baseline": {"model": ("moses2015" if defaults.spring_law == "rates"
                                   else f"moses2015-{defaults.spring_law}-{defaults.friction_law}"),
                         "params": self.baseline.values,
                         "se": self.baseline.se,
                         "fixed": {"mu_s_minus_mu_d": BASELINE_MU_EXCESS, "b": defaults.b,
                                   "v_thr": defaults.v_thr},
                         f"heldout_rms_{u}": self.baseline_heldout_rms / f,
                         f"train_rms_{u}": self.baseline.train_rms / f,
                         "tubes": _tubes_dict(self.baseline.tubes)},
            f"noise_rms_{u}": self.noise_rms / f,
            f"fold_band_rms_{u}": self.band_rms / f,
            f"floor_rms_{u}": self.floor_rms / f,
            "protocol": dict(self.protocol),
            "discrepancies": [s.to_dict() for s in self.discrepancies],
            "candidates": [c.to_dict(self.metric) for c in self.candidates],
            "pair_candidates": [c.to_dict(self.metric) for c in self.pair_candidates],
            "skipped": {k: dict(v) for k, v in self.skipped.items()},
            "lack_of_fit": {"baseline": _lof_dict(self.lack_of_fit), "extended": _lof_dict(self.extended_lack_of_fit)},
            "cause": self.cause,
            "causes": list(self.causes),
            "contributions": [c.to_dict(self.metric) for c in self.contributions],
            "explanation": self.explanation,
            "extended_model": ext,
            "gain": {"metric": f"heldout_rms_{u}", **self.gain.to_dict(self.metric)},
            f"per_regime_rms_{u}": {k: g.to_dict(self.metric) for k, g in self.per_regime.items()},
            "seed": self.seed,
            "extended_model_file": extended_model_file,
        }
        if figures is not None:
            out["figures"] = list(figures)
        return out

    def extension_model(self) -> tuple[FrictionParams, dict]:
        """The extended model (for none/unexplained, the baseline) as simulator parameters.

        Returns
        -------
        params : FrictionParams
            What ``notchfit simulate --model FILE`` reads back (every named cause).
        metadata : dict
            ``cause``, ``causes``, ``source``, standard errors ``se`` and, with a
            calibration_error, the ``point_warp`` (with its ``radius`` [m]).
        """
        cal = self.extended or self.baseline
        params, warp = model_params(cal.values, self.base)
        if len(cal.tubes) == 1:                 # one tube: its rest angles and cut depths belong to the model
            params = cal.params(self.base, next(iter(cal.tubes)))
        meta = {"cause": self.cause, "causes": list(self.causes), "source": "notchfit diagnose",
                "se": {k: float(v) for k, v in cal.se.items()}}
        if warp:
            meta["point_warp"] = {**{k: float(v) for k, v in warp.items()}, "radius": WARP_RADIUS}
        return params, meta
