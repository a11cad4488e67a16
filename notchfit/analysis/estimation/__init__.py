"""The estimation core under ``identify`` and ``diagnose`` (docs/architecture.md, "Estimation").

* :mod:`~notchfit.analysis.estimation.specs` — fitted parameters (:class:`ParamSpec`), the
  study's scales and the baselines of both engines;
* :mod:`~notchfit.analysis.estimation.observations` — one :class:`Observations` type per
  measured experiment, one metric vocabulary (``"points"`` in mm, ``"angles"`` in
  degrees at the file boundary) and one rule for the load-cell noise;
* :mod:`~notchfit.analysis.estimation.problem` — one least-squares problem assembled from
  parameter blocks (shared, per tube, per experiment), with probe starts,
  standard errors and the leave-one-out splits;
* :mod:`~notchfit.analysis.estimation.identifiability` — which parameters the data
  determine (a verdict per parameter from the Fisher information);
* :mod:`~notchfit.analysis.estimation.bands` — prediction intervals carried from the
  parameters' covariance to every notch angle (sigma points), for a whole
  history or sample by sample.

It returns objects and writes nothing; it sits below :mod:`notchfit.analysis.identify`
and :mod:`notchfit.analysis.diagnosis` and imports neither.
"""

from .noise import noise_floor
from .observations import (METRICS, Observations, angle_residuals, choose_metric, metric_unit, observe,
                           observe_study, peak_regimes, sample_mse, tension_sigma, tube_labels, zero_tension_samples)
from .problem import Block, Problem, Simulations, measure_registered, predict, whitened, with_values
from .solve import (Solution, best_probe_starts, folds, forward_jacobian, grid_starts, se_values, solve,
                    standard_errors, tube_folds)
from .specs import (BASELINE, BASELINE_MU_EXCESS, CAPSTAN_MU, MATERIAL, MATERIAL_BASELINE, ParamSpec, StudyScales,
                    baseline_specs)

__all__ = ["BASELINE", "BASELINE_MU_EXCESS", "CAPSTAN_MU", "MATERIAL", "MATERIAL_BASELINE", "METRICS", "Block",
           "Observations", "ParamSpec", "Problem", "Simulations", "Solution", "StudyScales", "angle_residuals",
           "baseline_specs", "best_probe_starts", "choose_metric", "folds", "forward_jacobian", "grid_starts",
           "measure_registered", "metric_unit", "noise_floor", "observe", "observe_study", "peak_regimes", "predict",
           "sample_mse", "se_values", "solve", "standard_errors", "tension_sigma", "tube_folds", "whitened",
           "with_values", "zero_tension_samples"]
