"""A tip load on a real tube's pivot chain (Eqs. 18-20 on the wrist's own chain: pivots on the notches'
neutral axes, off the tube axis): the external_load candidate applies to every tube, is fitted on a
one-sided wrist measured as joint angles, and is named when a wrist study hides one.

The shipped ``wrist_tip_load`` recipe hides a force of 15-30 mN in each of x and z at the tool point of
the one-sided 5-notch wrist (capstan friction, material springs, loading and unloading trials). The
diagnosis's baseline here is the one of this branch (the material moduli and μ_d); with a baseline
that also fits rest angles (identify's calibrated model) a tip load must still be named, since its
torques change with the bend while a rest angle does not: the slow test checks the verdict and the gain.
"""
import json

import numpy as np
import pytest

from notchfit.analysis.diagnosis.calibration import calibrate
from notchfit.analysis.diagnosis.scope import applicable_causes, base_model
from notchfit.analysis.diagnosis.specs import CAUSES
from notchfit.analysis.estimation.observations import observe_study
from notchfit.cli import main
from notchfit.io import read_study
from notchfit.studies.synth import generate_study, load_recipe, synthesize, write_study


def test_a_tip_load_is_a_candidate_on_a_section_backbone_and_is_fitted(tmp_path):
    """external_load is not skipped on a wrist whose pivots are off its axis; fitted on a reduced
    noise-free wrist study (the candidate's own law, Eqs. 18-20) it finds the hidden force's direction
    and the size of its lateral component to within a half, and lowers the baseline's error.

    Within a half, not closer: the baseline's rest angles are tied to the angles the trials show at zero
    tension (identify's prior), and those already hold the load's deflection at zero tension, so the rest
    angles take up part of the lateral force (fitted 0.67 and 0.50 of the hidden x and z components on this
    study; within a third of both while the rest angles were free: a known limit, the zero-tension angles
    should be read as the rest shape under the candidate's load). The slow test checks the verdict."""
    r = load_recipe("wrist_tip_load").scaled(n_experiments=3, n_up=6, n_down=5)
    r = r.replace(angle_sigma_deg=0.0, tension_sigma_N=0.0)
    st = synthesize(r, seed=3, method="fast")
    write_study(st, tmp_path / "study")
    preps = observe_study(read_study(tmp_path / "study"), "angles")
    assert preps[0].geom.backbone != "axis"
    usable, skipped, _ = applicable_causes(preps, CAUSES)
    assert "external_load" in usable and "external_load" not in skipped
    base = base_model(preps)
    truth = {k: getattr(st.params, k) for k in ("E_lin", "E_se", "mu_d")}
    baseline = calibrate(preps, None, truth, base=base, errors=False)
    cal = calibrate(preps, "external_load", truth, base=base, errors=False, paper_start=False)
    f = np.array([cal.values["tip_force_x"], cal.values["tip_force_z"]])
    f_true = np.array([st.effect["tip_force_x"], st.effect["tip_force_z"]])
    assert np.all(np.sign(f) == np.sign(f_true)), (f, f_true)
    assert abs(f[0] - f_true[0]) < abs(f_true[0]) / 2 and 0.4 * abs(f_true[1]) < abs(f[1]) < 1.5 * abs(f_true[1])
    assert cal.train_rms < 0.7 * baseline.train_rms          # 0.58 here (0.5 or less with free rest angles)


@pytest.mark.slow
def test_a_tip_load_hidden_in_a_wrist_study_is_named_with_gain(tmp_path):
    study = tmp_path / "study"
    generate_study(load_recipe("wrist_tip_load"), study, seed=1)
    (study / "truth.json").unlink()
    out = tmp_path / "out"
    assert main(["diagnose", str(study), "--out", str(out), "--jobs", "2", "--no-figures"]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["metric"] == "angles"
    assert d["causes"] == ["external_load"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 25.0
