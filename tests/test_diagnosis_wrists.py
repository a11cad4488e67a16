"""Hidden-effect tests on real tubes (issue 28): the shipped wrist recipes with no hidden effect end in
``none``, and a cause the protocol cannot reveal is skipped with its reason and the experiment that would.

The diagnosis baseline of a real tube is identify's calibrated model (shared material and friction, each
tube's rest angles and cut depths under the cutting-tolerance prior): a baseline without them left an
excess over the noise that the candidates then "explained" (false alarms on the shipped wrist recipes).
Each study is synthesised from a seeded recipe, its truth.json deleted before the analysis, and the verdict
read from diagnosis.json alone. The default job runs one reduced null study and the loading-only
hysteresis study; the slow job (`pytest -m slow`) every shipped null wrist recipe (joint angles of two
tubes, notch points of one), over three seeds, against every candidate, and the two tubes as notch points
(seed 1, the last null false alarm: its noise floor's draws and its folds' band, docs/history.md). ``benchmarks/null_wrists.py``
also measures each recipe the other way.
"""
import json

import numpy as np
import pytest

from notchfit.cli import main
from notchfit.studies.synth import generate_study, load_recipe

#: the shipped wrist recipes without a hidden effect, measured as each recipe says: (recipe, observe, changes)
NULL_WRISTS = (
    ("wrist_stock", "angles", {}),                                  # two tubes, joint angles, loading only
    ("wrist_asymmetric", "points", {}),                             # one tube, notch points, frictionless
    ("wrist_tip_first", "points", {}),                              # one pre-curved tube, notch points
)


def _diagnose(tmp_path, recipe, seed, args=()):
    study = tmp_path / "study"
    generate_study(recipe, study, seed=seed)
    (study / "truth.json").unlink()  # the analysis must never need it
    out = tmp_path / "out"
    assert main(["diagnose", str(study), "--out", str(out), "--jobs", "2", "--no-figures", *args]) == 0
    return json.loads((out / "diagnosis.json").read_text())


def _null(name, observe, changes):
    return load_recipe(name).replace(observe=observe, **changes)


def _check_none(d):
    u = "deg" if d["metric"] == "angles" else "mm"
    assert d["cause"] == "none" and d["causes"] == [], d["explanation"]
    # the baseline is identify's model: every tube's rest angles and cut depths are fitted
    assert d["baseline"]["tubes"] and all(t["rest_angle_deg"] for t in d["baseline"]["tubes"].values())
    assert set(d["baseline"]["params"]) >= {"E_lin", "E_se", "strain_lower", "mu_d"}
    assert d["baseline"][f"heldout_rms_{u}"] > 0 and d[f"noise_rms_{u}"] > 0


def test_reduced_null_wrist_gives_none(tmp_path):
    """One tube measured as notch points, unloaded (hysteresis and a proximal band testable), two folds:
    the baseline of rest angles and cut depths explains it; neither candidate is named."""
    recipe = _null("wrist_asymmetric", "points", {}).scaled(n_up=7, n_down=7)
    d = _diagnose(tmp_path, recipe, 1, ["--max-folds", "2", "--causes", "joint_hysteresis,stiffness_gradient"])
    _check_none(d)
    assert {c["cause"] for c in d["candidates"]} == {"joint_hysteresis", "stiffness_gradient"}
    lof = d["lack_of_fit"]["baseline"]
    assert lof["unit"] == "mm" and "verdict" in lof


def test_hysteresis_in_a_loading_only_study_is_not_named(tmp_path):
    """The superelastic flag hidden in a wrist whose trials never unload: no loop opens, so the candidate
    is skipped with that reason and the experiment that would reveal it, never fitted nor named."""
    recipe = load_recipe("wrist_hysteresis").scaled(n_down=0)
    d = _diagnose(tmp_path, recipe, 1, ["--max-folds", "2", "--causes", "joint_hysteresis,proximal_friction"])
    assert "joint_hysteresis" not in d["causes"] and d["cause"] in ("none", "unexplained"), d["explanation"]
    assert d["candidates"] == []
    why = d["skipped"]["candidates"]["joint_hysteresis"]
    assert "unloads" in why and "loop" in why
    test = d["skipped"]["experiments"]["joint_hysteresis"]
    assert test.startswith("unload one trial") and "joint hysteresis" in test
    assert test in d["explanation"]


def test_unexplained_needs_a_material_lack_of_fit():
    """Where trials repeat, ``unexplained`` needs a lack of fit beyond the scatter that is significant and larger
    than the excess over the floor the ``none`` rule tolerates. 300 replicate groups of three with 0.01 mm scatter:
    a systematic 0.005 mm error is significant (F ≈ 1.75 on 300 and 600 df) but, against a floor of 0.03 mm, not
    material (a false alarm of wrist_asymmetric as points, seed 1, was such a case: 0.005 mm against 0.026 mm);
    0.05 mm is material. Without replicates the verdict is left as it was."""
    from notchfit.analysis.diagnosis.replicates import lack_of_fit_first, lack_of_fit_material, lack_of_fit_mse
    from notchfit.analysis.lack_of_fit import lack_of_fit_table
    from notchfit.units import MM

    rng = np.random.default_rng(7)
    groups = np.repeat(np.arange(300), 3)
    force = groups * 0.01
    noise = 2 * (0.03 * MM) ** 2                        # the floor of a point [m²]
    verdicts = {}
    for offset in (0.005, 0.05):
        resid = offset + rng.normal(0.0, 0.01, (groups.size, 2))      # [mm], two coordinates of a point
        lof = lack_of_fit_table(resid, np.zeros_like(resid), groups, force, unit="mm", alpha=0.01)
        assert lof.has_replicates and lof.overall.significant(0.01)
        np.testing.assert_allclose(lack_of_fit_mse(lof, 2.0), 2 * (offset * MM) ** 2, rtol=0.3)
        verdicts[offset] = (lack_of_fit_material(lof, noise, 2.0), lack_of_fit_first("unexplained", lof, noise, 2.0))
    assert verdicts == {0.005: (False, "none"), 0.05: (True, "unexplained")}
    lone = lack_of_fit_table(np.ones((4, 2)), np.zeros((4, 2)), np.arange(4), np.arange(4.0), unit="mm")
    assert not lone.has_replicates and lack_of_fit_first("unexplained", lone, noise, 2.0) == "unexplained"
    # a named cause is never touched
    assert lack_of_fit_first("external_load", lof, noise, 2.0) == "external_load"


def test_summary_says_what_was_skipped_and_the_lack_of_fit():
    """The printed summary lists each skipped candidate with its reason and suggested experiment, and the
    held-out baseline's lack of fit against the trials' scatter."""
    import numpy as np

    from notchfit.analysis.diagnosis import Calibration, Diagnosis, Gain
    from notchfit.analysis.lack_of_fit import lack_of_fit_table

    y = np.array([[0.0], [0.1], [1.0], [1.1]])
    lof = lack_of_fit_table(y, np.zeros_like(y), np.array([0, 0, 1, 1]), np.array([0.0, 0.0, 1.0, 1.0]),
                            unit="deg")
    cal = Calibration((), {"mu_d": 0.1}, {"mu_d": 0.01}, 0.01, 1.0, 4, True, "", 1)
    d = Diagnosis(("A", "B"), cal, 0.01, (), (), "none", "", Gain(0.01, 0.01), None, {}, 0.01, metric="angles",
                  skipped={"signatures": {}, "candidates": {"joint_hysteresis": "no trial unloads"},
                           "experiments": {"joint_hysteresis": "unload one trial to test joint hysteresis"}},
                  lack_of_fit=lof)
    text = d.summary()
    assert "not tried: joint_hysteresis (no trial unloads); unload one trial to test joint hysteresis" in text
    assert "lack of fit (held-out baseline): trial-to-trial scatter" in text
    out = d.to_dict()
    assert out["lack_of_fit"]["baseline"]["overall"]["n_groups"] == 2
    assert out["skipped"]["experiments"] == {"joint_hysteresis": "unload one trial to test joint hysteresis"}


NULL_CASES = [pytest.param(name, observe, changes, seed, id=f"{name}-{observe}-{seed}")
              for name, observe, changes in NULL_WRISTS for seed in (1, 2, 3)]
# measured the other way: wrist_stock as notch points (5 µm), seed 1, was ``unexplained`` (held-out 0.045 mm
# against a floor of 0.021 mm) while its floor's four draws were shared by every trial and its folds' band
# ignored the training trials' tension noise (docs/history.md, "The last null false alarm")
NULL_CASES += [pytest.param("wrist_stock", "points", {"point_sigma_mm": 0.005}, 1, id="wrist_stock-points-1")]


@pytest.mark.slow
@pytest.mark.parametrize("name,observe,changes,seed", NULL_CASES)
def test_null_wrist_recipes_give_none(tmp_path, name, observe, changes, seed):
    """Every shipped wrist recipe without a hidden effect, full size, every candidate: ``none``. Two were named
    causes while a baseline fold had stopped at its evaluation limit far from its optimum (wrist_asymmetric
    points seed 2, wrist_tip_first points seed 3; docs/history.md): such a fold is now restarted from the
    other folds' optima."""
    _check_none(_diagnose(tmp_path, _null(name, observe, changes), seed))


def test_the_baseline_rest_angles_keep_their_zero_force_prior(tmp_path):
    """A pre-curved wrist (rest angles about 2° each): the baseline's rest angles are tied to the angles its
    trials show at zero force (identify's prior, centred on that measurement), so the fitted rest angles stay
    within a few tenths of a degree of the truth. A prior whose mean was dropped pulled them towards zero: the
    held-out baseline of wrist_tip_first (seed 1) rose from 0.016 to 0.095 mm and a tip load was named."""
    import numpy as np

    from notchfit.analysis.diagnosis.calibration import calibrate
    from notchfit.analysis.diagnosis.scope import base_model
    from notchfit.analysis.estimation.observations import observe_study
    from notchfit.io import read_study
    from notchfit.studies.synth import synthesize, write_study
    from notchfit.units import DEG

    r = load_recipe("wrist_tip_first").scaled(n_experiments=2, n_up=5, n_down=4)
    st = synthesize(r, seed=1, method="fast")
    write_study(st, tmp_path / "study")
    preps = observe_study(read_study(tmp_path / "study"), "points")
    truth = np.asarray(preps[0].geom.rest_angles, float)
    assert np.all(truth > 1.0 * DEG)
    cal = calibrate(preps, None, {}, base=base_model(preps), errors=False)
    (fitted,) = [t["rest_angle"] for t in cal.tubes.values()]
    np.testing.assert_allclose(fitted, truth, atol=0.3 * DEG)


def test_an_unconverged_baseline_fold_is_restarted_from_the_other_folds_optima():
    """A fold whose fit stopped at its evaluation limit is refitted from each converged fold's optimum and keeps
    the lower training cost, with that fit's held-out predictions; converged folds are never refitted."""
    from notchfit.analysis.diagnosis import Calibration
    from notchfit.analysis.diagnosis.crossval import HeldOut
    from notchfit.analysis.diagnosis.study import restart_unconverged

    def cal(cost, ok, e):
        return Calibration((), {"E_lin": e}, {}, 0.0, cost, 10, ok, "", 1)

    folds = [np.array([0]), np.array([1]), np.array([2])]
    held = HeldOut((), {i: np.full((2, 1), i) for i in range(3)}, {i: np.zeros((2, 1)) for i in range(3)},
                   {i: np.ones(2) for i in range(3)}, (cal(5.0, True, 1.0), cal(900.0, False, 9.0), cal(6.0, True, 2.0)))
    calls = []

    def run(fs, causes, starts):
        calls.append(([int(f[0]) for f in fs], causes, [s["E_lin"] for s in starts]))
        e = starts[0]["E_lin"]       # the fit from fold 1's optimum reaches a lower cost than from fold 3's
        return {"baseline": HeldOut((), {1: np.full((2, 1), 10 * e)}, {1: np.zeros((2, 1))}, {1: np.ones(2)},
                                    (cal(7.0 if e == 1.0 else 8.0, True, e),))}

    out = restart_unconverged(held, folds, run)
    assert calls == [([1], [None], [1.0]), ([1], [None], [2.0])]
    assert [c.cost for c in out.calibrations] == [5.0, 7.0, 6.0] and out.calibrations[1].values == {"E_lin": 1.0}
    np.testing.assert_array_equal(out.predicted[1], np.full((2, 1), 10.0))
    np.testing.assert_array_equal(out.predicted[0], held.predicted[0])
    done = HeldOut((), held.predicted, held.theta, held.floor, (cal(5.0, True, 1.0),) * 3)
    assert restart_unconverged(done, folds, run) is done and len(calls) == 2


def test_the_noise_floor_of_a_superelastic_snap_is_the_linearised_propagation(tmp_path):
    """On a wrist's superelastic snap a few samples carry the floor (the tip moves 0.08 mm per 0.01 N there,
    0.007 mm elsewhere). The floor's draws are moment-matched per sample, so for this smooth response driven
    by each sample's own tension it equals the linearised propagation ``σ_T² Σ_k ‖∂y_s/∂T_k‖²`` (central
    differences: the small-noise limit) with four draws, whatever the seed; four independent draws put it
    anywhere from 0.5 to 1.6 times that (the floor of the null wrist_stock as points, seed 1, was 25 % low
    in rms and the study called ``unexplained``; docs/diagnosis.md). Each experiment draws its own noise."""
    import dataclasses

    from notchfit.analysis.estimation.noise import noise_floor
    from notchfit.analysis.estimation.observations import observe_study
    from notchfit.io import read_study
    from notchfit.physics.friction import simulate_angles
    from notchfit.physics.notches import notch_points
    from notchfit.studies.synth import synthesize, write_study

    recipe = _null("wrist_stock", "points", {"point_sigma_mm": 0.005}).scaled(n_experiments=1)
    st = synthesize(recipe, seed=1, method="fast")
    write_study(st, tmp_path / "study")
    (obs,) = observe_study(read_study(tmp_path / "study"), "points")
    T, sig, h = obs.tension_right, obs.tension_sigma, 0.2 * obs.tension_sigma

    def points(t):
        return notch_points(simulate_angles(obs.time, None, t, st.params, obs.geom, ramp_time=obs.ramp_time),
                            obs.geom)

    lin = np.zeros(T.size)
    for k in range(T.size):
        up, dn = T.copy(), T.copy()
        up[k] += h
        dn[k] -= h
        lin += sig**2 * np.mean(np.sum(((points(up) - points(dn)) / (2 * h)) ** 2, axis=-1), axis=1)
    assert lin.max() > 0.3 * lin.sum()                          # one sample carries a third of the floor
    tension_term = lambda **kw: noise_floor(obs, st.params, **kw) - 2 * obs.sigma**2  # noqa: E731
    matched = [tension_term(seed=s).mean() / lin.mean() for s in range(4)]
    independent = [tension_term(seed=s, matched=False).mean() / lin.mean() for s in range(4)]
    np.testing.assert_allclose(matched, 1.0, atol=0.03)
    assert max(abs(np.log(independent))) > 0.3
    other = dataclasses.replace(obs, name="A2")
    assert not np.array_equal(noise_floor(obs, st.params, matched=False), noise_floor(other, st.params, matched=False))
