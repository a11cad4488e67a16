"""Diagnosis: what the friction simulation gets wrong, the cause, the extension, the gain.

Given measured experiments (tensions, and notch points or joint angles),
:func:`diagnose` answers four questions about the friction model (Sec. IV-B):

1. **What does the simulation get wrong?** The baseline (the friction
   simulator with ``k_lin``, ``k_mid`` and ``μ_d`` calibrated, docs/models.md;
   for a real tube identify's calibrated model, :mod:`~notchfit.analysis.diagnosis.tubes`)
   is fitted on training experiments and compared with held-out ones
   (cross-validation by experiment). Discrepancy *signatures* are measured
   (:mod:`~notchfit.analysis.diagnosis.signatures`).
2. **What is the cause?** Every candidate cause is a physical extension of
   the simulator (:data:`CANDIDATES`); each is fitted together with the
   baseline parameters on the training folds and scored on the held-out
   ones. The significance rule treats the residuals of one experiment as
   serially correlated and measures improvement against the noise floor
   (:mod:`~notchfit.analysis.diagnosis.noise`); the decision rule is in
   :mod:`~notchfit.analysis.diagnosis.decision`.
3. **Extend the model**: the chosen candidate refitted on all experiments,
   with standard errors (:meth:`Diagnosis.extension_model`), which the
   ``diagnose`` command saves as a parameter TOML that
   ``notchfit simulate --model FILE`` reads.
4. **Measure the gain**: held-out notch-point rms of baseline and extension,
   overall and per regime.

The analysis returns a :class:`Diagnosis` and writes nothing; it never reads
a study's ``truth.json``. It runs on the estimation core
(:mod:`notchfit.analysis.estimation`: the experiments' observations, the least-squares
problem, standard errors, folds, the noise floor), which ``identify`` shares;
each candidate cause is one record of :mod:`notchfit.analysis.causes`. Modules:

=================  ==========================================================
``specs``          the models (baseline plus causes) and their fitted parameters
``tubes``          a real tube's baseline: identify's per-tube unknowns
``scope``          the study's base model, what the study can reveal, protocol
``calibration``    predicted measurements, model calibration
``noise``          paired significance, pooled rms
``crossval``       folds and the (model × fold) fan-out (processes or Dask)
``signatures``     what the held-out baseline gets wrong
``replicates``     lack of fit against the trials' scatter (held-out)
``decision``       ranking, decision rule, explanation
``pairs``          the second cause and each cause's contribution
``results``        typed results; ``Diagnosis.to_dict()`` is diagnosis.json
``study``          :func:`diagnose`, the whole analysis
=================  ==========================================================
"""

from .calibration import Calibration, SimulationCache, calibrate, predict_points, reregister
from .crossval import HeldOut, folds_by_experiment, run_folds
from .decision import rank_candidates
from ..estimation.noise import noise_floor
from .noise import paired_z, pooled_rms
from ..estimation.observations import Observations, choose_metric, peak_regimes
from ..estimation.observations import observe as prepare_experiment
from .results import CandidateResult, Contribution, Diagnosis, Gain, Signature
from .signatures import loading_stalls
from .specs import (BASELINE, BASELINE_MU_EXCESS, CANDIDATES, CAUSES, MATERIAL_BASELINE, REGISTRATION_BOUNDS,
                    WARP_CENTER_RANGE, WARP_RADIUS, ParamSpec, StudyScales)
from .study import diagnose

#: The experiment type of the diagnosis (the estimation core's, :class:`notchfit.analysis.estimation.Observations`).
Prepared = Observations

__all__ = [
    "BASELINE",
    "BASELINE_MU_EXCESS",
    "CANDIDATES",
    "CAUSES",
    "MATERIAL_BASELINE",
    "REGISTRATION_BOUNDS",
    "WARP_CENTER_RANGE",
    "WARP_RADIUS",
    "Calibration",
    "CandidateResult",
    "Contribution",
    "Diagnosis",
    "Gain",
    "HeldOut",
    "ParamSpec",
    "Observations",
    "Prepared",
    "Signature",
    "SimulationCache",
    "StudyScales",
    "calibrate",
    "choose_metric",
    "diagnose",
    "folds_by_experiment",
    "loading_stalls",
    "peak_regimes",
    "noise_floor",
    "paired_z",
    "pooled_rms",
    "predict_points",
    "prepare_experiment",
    "rank_candidates",
    "reregister",
    "run_folds",
]
