"""Typed results of a diagnosis; :meth:`Diagnosis.to_dict` is the content of ``diagnosis.json``.

Inside, lengths are in metres; the dictionaries (the file format,
docs/data-formats.md) give them in millimetres under ``*_mm`` keys or with
``"unit": "mm"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..friction import FrictionParams
from ..units import MM
from .calibration import Calibration
from .specs import BASELINE_MU_EXCESS, WARP_RADIUS, model_params

__all__ = ["CandidateResult", "Diagnosis", "Gain", "Signature"]


@dataclass(frozen=True)
class Signature:
    """One discrepancy signature of the held-out baseline, with its number and words.

    Attributes
    ----------
    name : str
        E.g. ``unloading_hold``, ``loop_area_ratio`` (docs/diagnosis.md).
    value : float
        In ``unit`` (SI: lengths in m).
    unit : str
        ``"m"``, ``"N"``, ``"rad"`` or ``"-"``.
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
    """A candidate extension fitted on the training folds and scored on the held-out experiments.

    Attributes
    ----------
    cause : str
    params : dict
        The extension's parameters (mean over folds) by name [SI].
    n_params : int
        Number of extension parameters.
    train_rms, heldout_rms : float
        Notch-point rms on the training (mean over folds) and held-out experiments [m].
    aic : float
        Akaike information criterion of the fold fits.
    z : float
        Significance of the held-out improvement (:func:`notchfit.diagnosis.noise.paired_z`).
    excess_removed : float
        Fraction of the baseline's excess over the noise floor removed.
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

    def to_dict(self) -> dict:
        return {"cause": self.cause, "params": dict(self.params), "n_params": self.n_params,
                "train_rms_mm": self.train_rms / MM, "heldout_rms_mm": self.heldout_rms / MM,
                "aic": self.aic, "z": self.z, "excess_removed": self.excess_removed,
                "significant": self.significant}


@dataclass(frozen=True)
class Gain:
    """Held-out notch-point rms of the baseline and of the extended model [m]."""

    baseline: float
    extended: float

    @property
    def reduction_pct(self) -> float:
        """How much lower the extended model's rms is [%] (0 when the baseline's is 0)."""
        return 100.0 * (self.baseline - self.extended) / self.baseline if self.baseline > 0 else 0.0

    def to_dict(self) -> dict:
        """``{"baseline", "extended", "reduction_pct"}`` with the rms in mm."""
        return {"baseline": self.baseline / MM, "extended": self.extended / MM,
                "reduction_pct": self.reduction_pct}


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`notchfit.diagnosis.diagnose`.

    Attributes
    ----------
    experiments : tuple of str
    baseline : Calibration
        The baseline fitted on all experiments.
    baseline_heldout_rms : float
        Held-out notch-point rms of the baseline [m].
    discrepancies : tuple of Signature
    candidates : tuple of CandidateResult
        In the order they were tried.
    cause : str
        A cause of :data:`notchfit.diagnosis.CAUSES`, ``"none"`` or ``"unexplained"``.
    explanation : str
    gain : Gain
    extended : Calibration or None
        The chosen candidate fitted on all experiments (None for none/unexplained).
    per_regime : dict
        ``{"I" | "II" | "III": Gain}`` for the regimes that occur.
    noise_rms : float
        Root of the noise floor [m].
    seed : int
        Seed of the noise floor's draws.
    heldout : dict
        ``{"baseline" | cause: HeldOut}``: the held-out predictions.
    prepared : tuple of Prepared
        The experiments as analysed.
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

    def to_dict(self, *, extended_model_file: str | None = None, figures=None) -> dict:
        """The content of ``diagnosis.json`` (docs/data-formats.md).

        Parameters
        ----------
        extended_model_file : str, optional
            Name of the model TOML written beside it.
        figures : list of str, optional
            Names of the figures written beside it (the key is left out when None).
        """
        ext = None
        if self.extended is not None:
            ext = {"cause": self.extended.cause, "params": self.extended.values,
                   "se": self.extended.se, "train_rms_mm": self.extended.train_rms / MM}
        defaults = FrictionParams()
        out = {
            "experiments": list(self.experiments),
            "baseline": {"model": "moses2015", "params": self.baseline.values,
                         "se": self.baseline.se,
                         "fixed": {"mu_s_minus_mu_d": BASELINE_MU_EXCESS, "b": defaults.b,
                                   "v_thr": defaults.v_thr},
                         "heldout_rms_mm": self.baseline_heldout_rms / MM,
                         "train_rms_mm": self.baseline.train_rms / MM},
            "noise_rms_mm": self.noise_rms / MM,
            "discrepancies": [s.to_dict() for s in self.discrepancies],
            "candidates": [c.to_dict() for c in self.candidates],
            "cause": self.cause,
            "explanation": self.explanation,
            "extended_model": ext,
            "gain": {"metric": "heldout_rms_mm", **self.gain.to_dict()},
            "per_regime_rms_mm": {k: g.to_dict() for k, g in self.per_regime.items()},
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
            What ``notchfit simulate --model FILE`` reads back.
        metadata : dict
            ``cause``, ``source``, standard errors ``se`` and, for a
            calibration_error extension, the ``point_warp`` (with its ``radius`` [m]).
        """
        cal = self.extended or self.baseline
        params, warp = model_params(cal.values)
        meta = {"cause": self.cause, "source": "notchfit diagnose",
                "se": {k: float(v) for k, v in cal.se.items()}}
        if warp:
            meta["point_warp"] = {**{k: float(v) for k, v in warp.items()}, "radius": WARP_RADIUS}
        return params, meta
