"""``notchfit identify``: the model's parameters calibrated on a study, with held-out errors.

A lab measures its tubes (joint angles or notch points against tendon
tension, several trials each) and wants the model that predicts new trials,
and — for tubes cut from one stock — new tubes from their geometry alone
(docs/models.md, "Identification"). :func:`identify`:

1. reduces every experiment to its inputs and observations
   (:class:`notchfit.analysis.estimation.Observations`: one metric per study, joint
   angles preferred, else notch points; experiments that share a geometry
   are one tube);
2. fits the free parameters (:mod:`notchfit.analysis.identify.specs`: by default the
   material law's ``E_lin``, ``E_se``, ``strain_lower`` (and its tension–compression
   asymmetry ``strain_ratio`` where the sections let it act) or the seed tube's
   ``k_lin``, ``k_mid``; ``μ_d``; each real tube's rest angles and effective
   cut depths, with Gaussian priors: the angles its trials measured at zero
   force, the drawing's tolerance) to every experiment at once — every tube
   shares the scalar parameters — by bounded least squares from the best of a
   grid of probe starts (:mod:`notchfit.analysis.identify.problem`);
3. refits without each experiment and predicts it (leave one experiment
   out: ``heldout``), and, when the study has several tubes, without each
   tube and predicts its experiments from its geometry file
   (``heldout_by_tube``), each refit started from the fit on every experiment;
4. splits the fit's error into the trials' scatter and the lack of fit beyond it
   (:mod:`notchfit.analysis.lack_of_fit`), and says what the model knows of a tube
   it has never seen (:class:`notchfit.analysis.estimation.bands.NewTubePrior`:
   the prediction bands).

It returns an :class:`Identification` and writes nothing; ``notchfit
identify`` writes ``model.toml`` and ``identify.json``.
"""

from __future__ import annotations

from ..estimation.observations import METRICS, Observations, tube_labels, zero_tension_samples
from .problem import Problem, Solution, make_problem, solve
from .specs import DEPTH, MATERIAL, REST, SPECS, default_free, parse_free, specs_for
from .study import Identification, TubeFit, identify

#: The experiment type of an identification (the estimation core's :class:`notchfit.analysis.estimation.Observations`).
Observed = Observations

#: identify's own names; the estimation core's types it uses (Observations, Problem, Solution,
#: tube_labels, ...) stay importable from here but are documented in notchfit.analysis.estimation
__all__ = [
    "DEPTH",
    "MATERIAL",
    "REST",
    "SPECS",
    "Identification",
    "TubeFit",
    "default_free",
    "identify",
    "make_problem",
    "parse_free",
    "solve",
    "specs_for",
]
