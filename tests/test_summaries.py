"""Each result prints its own summary (Diagnosis, Identification, StudyFit): the numbers of the result, in
the file units of its metric, formatted once."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from notchfit.analysis.diagnosis import Calibration, Diagnosis, Gain
from notchfit.analysis.fitting import StudyFit
from notchfit.analysis.identify import Identification, TubeFit
from notchfit.figures.summary import candidates_figure
from notchfit.report.diagnosis import loops_caption
from notchfit.units import DEG


def _cal(values):
    return Calibration(cause=(), values=values, se={k: 0.0 for k in values}, train_rms=1e-4, cost=1.0,
                       n_residuals=10, success=True, message="", nfev=1)


def test_diagnosis_summary_in_the_metric_unit():
    d = Diagnosis(experiments=("a", "b"), baseline=_cal({"mu_d": 0.3}), baseline_heldout_rms=4e-4,
                  discrepancies=(), candidates=(), cause="proximal_friction", explanation="",
                  gain=Gain(4e-4, 1e-4), extended=None, per_regime={}, noise_rms=1e-4,
                  causes=("proximal_friction", "joint_hysteresis"))
    assert d.summary().splitlines() == [
        "cause: proximal_friction (causes: proximal_friction, joint_hysteresis)",
        "held-out rms: baseline 0.400 mm, extended 0.100 mm (75.0% lower); noise floor 0.100 mm"]
    angles = Diagnosis(experiments=("a",), baseline=_cal({}), baseline_heldout_rms=2 * DEG, discrepancies=(),
                       candidates=(), cause="none", explanation="", gain=Gain(2 * DEG, 2 * DEG), extended=None,
                       per_regime={}, noise_rms=DEG, metric="angles")
    assert angles.summary().splitlines()[1] == ("held-out rms: baseline 2.000 deg, extended 2.000 deg (0.0% lower); "
                                                "noise floor 1.000 deg")


def test_identification_summary_lists_values_tubes_and_heldout_errors():
    n = 2
    tube = TubeFit(name="w", experiments=("T1", "T2"), rest_angles=np.radians([1.0, 2.5]),
                   rest_se=np.full(n, 0.01), slot_depths=np.array([1.4e-3, 1.41e-3]), depth_offsets=np.zeros(n),
                   depth_se=np.zeros(n), model=None)
    r = Identification(metric="angles", free=("E_lin", "mu_d"), values={"E_lin": 5e10, "mu_d": 0.12},
                       se={"E_lin": 2e9, "mu_d": 0.01}, tube_free=("rest_angle",), tubes={"w": tube}, model=None,
                       experiment_tubes={"T1": "w", "T2": "w"}, train_rms=0.5, train={"T1": 0.5, "T2": 0.5},
                       heldout_rms=0.7, heldout={"T1": 0.6, "T2": 0.8})
    lines = r.summary().splitlines()
    assert lines[0] == "identify: 2 experiments, 1 tube(s), errors in deg"
    assert lines[1].split() == ["E_lin_Pa", "=", "5e+10", "±", "2e+09"]
    assert lines[3] == "  w: rest angles [deg] 1.00, 2.50"
    assert lines[4].startswith("train rms 0.500 deg; held-out rms 0.700 deg")
    assert lines[5].split() == ["T1", "held", "out", "0.600", "deg"]
    one = Identification(metric="points", free=(), values={}, se={}, tube_free=(), tubes={}, model=None,
                         experiment_tubes={"T1": "w"}, train_rms=0.02, train={}, heldout_rms=math.nan, heldout={})
    assert one.summary().splitlines()[-1] == "train rms 0.020 mm"


def test_study_fit_summary_over_successful_fits():
    pts = pd.DataFrame({"model": ["linear", "linear", "free"], "rms_mm": [0.03, 0.04, 0.01],
                        "max_mm": [0.05, 0.09, 0.02], "success": [True, True, True]})
    ang = pd.DataFrame({"model": ["linear", "linear"], "rms_deg": [0.3, 0.4], "max_deg": [0.5, 9.0],
                        "success": [True, False]})
    lines = StudyFit(pts, ang, 3, 4, 1.25).summary().splitlines()
    assert lines[0].split()[:5] == ["linear", "rms", f"{math.sqrt((0.03**2 + 0.04**2) / 2):.4f}", "mm,", "max"]
    assert "0.0900 mm over 2 samples" in lines[0]
    assert lines[2].split()[:7] == ["linear", "rms", "0.300", "deg,", "max", "0.500", "deg"]
    assert lines[-1] == "fit: 3 of 4 experiments fitted in 1.2 s"


def test_the_regime_bars_show_an_extended_model_only_when_a_cause_is_named():
    """With no cause named there is no extended model: the regime panel draws the baseline alone (it used
    to draw an 'extended' bar equal to the baseline beside it)."""
    cands = pd.DataFrame({"model": ["baseline", "external_load"], "heldout_rms_deg": [0.55, 0.54]})
    regimes = pd.DataFrame({"regime": ["I", "II"], "baseline": [0.5, 0.6], "extended": [0.5, 0.6]})
    none = candidates_figure(cands, 0.5, named=(), regimes=regimes, unit="deg")
    named = candidates_figure(cands, 0.5, named=("external_load",), regimes=regimes, unit="deg")
    assert len(none.axes[1].patches) == 2
    assert [t.get_text() for t in none.axes[1].get_legend().get_texts()] == ["baseline"]
    assert len(named.axes[1].patches) == 4


def test_the_candidates_figure_draws_the_floor_with_the_folds_band_above_the_noise():
    """The verdict compares with the noise and the baseline folds' prediction band together: that floor is
    drawn (dashed) beside the noise floor when it is higher, and not at all when it is not."""
    cands = pd.DataFrame({"model": ["baseline", "external_load"], "heldout_rms_mm": [0.05, 0.04]})
    labels = [t.get_text() for t in candidates_figure(cands, 0.03, floor=0.045).axes[0].get_legend().get_texts()]
    assert labels == ["noise floor 0.03 mm", "with the folds' band 0.045 mm"]
    assert len(candidates_figure(cands, 0.03, floor=0.03).axes[0].get_legend().get_texts()) == 1


def test_the_loops_caption_names_an_extended_model_only_when_a_cause_is_named():
    """With no cause named the figure draws measured and baseline only; its caption must not describe a
    blue extended model that is not there (seen on a wrist study's report)."""
    assert "extended model (blue)" in loops_caption(named=True, unloads=True)
    none = loops_caption(named=False, unloads=True)
    assert "(blue)" not in none and "no cause named" in none
    assert "loading only" in loops_caption(named=False, unloads=False)
