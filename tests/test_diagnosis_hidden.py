"""Hidden-effect tests (issues 8, 19): a synthetic study hides one physical effect, or two at
once; `notchfit diagnose` must name them from the data alone and gain >= 30% held-out rms.

The test knows the causes only because it chose the recipe; it deletes the generator's
truth.json before the analysis and decides what was found from diagnosis.json alone.
Joint hysteresis is also hidden by laws the candidate does not have (the generator's
Bouc-Wen loops and two-branch superelastic flag, notchfit.physics._hysteresis_kernels), and a
one-tendon wrist is diagnosed from measured joint angles.
The default job runs reduced studies (4 experiments, 9 + 11 samples, two folds) with the
candidates narrowed to the hidden cause(s) and their likely rivals (``--causes``): each cause's
candidate is fitted, scored, named and its gain checked, the null study fits every candidate, the
pair covers the second-cause step, the figures and the report. A candidate's held-out fit does not
depend on which other candidates are tried, so narrowing them changes no verdict of these studies.
The slow job (`pytest -m slow`) runs the same reduced studies against every candidate, more seeds
on the full six-experiment recipes and every pair of the five nameable causes.
"""
import itertools
import json

import pytest

from notchfit.cli import main
from notchfit.analysis.diagnosis import CAUSES
from notchfit.studies.recipes import combine_recipes
from notchfit.studies.synth import generate_study, load_recipe

# reduced studies for the default job: 4 experiments (3 counter-tensions, both directions),
# 9 + 11 samples each, two folds
SMALL = dict(n_experiments=4, n_up=8, n_down=10)

# static_friction is tested separately: see test_static_friction_is_not_misattributed
IDENTIFIABLE = tuple(c for c in CAUSES if c != "static_friction")


#: the causes a diagnosis can name (static friction is not identifiable at the paper's load cells)
NAMEABLE = ("proximal_friction", "joint_hysteresis", "external_load", "stiffness_gradient", "calibration_error")
PAIRS = tuple(itertools.combinations(NAMEABLE, 2))


def _recipe(spec):
    """A shipped recipe by name, or the combination of several (``"a+b"``)."""
    names = spec.split("+")
    return load_recipe(names[0]) if len(names) == 1 else combine_recipes(*[load_recipe(n) for n in names])


def _diagnose(tmp_path, recipe_name, seed, *, small=True, jobs=2, figures=False, causes=None, one_cause=False):
    recipe = _recipe(recipe_name)
    args = []
    if small:
        recipe = recipe.scaled(**SMALL)
        args = ["--max-folds", "2"]
    study = tmp_path / "study"
    generate_study(recipe, study, seed=seed)
    (study / "truth.json").unlink()  # the analysis must never need it
    out = tmp_path / "out"
    if not figures:
        args.append("--no-figures")
    if causes is not None:
        args += ["--causes", ",".join(causes)]
    if one_cause:
        args.append("--one-cause")
    rc = main(["diagnose", str(study), "--out", str(out), "--jobs", str(jobs), *args])
    assert rc == 0
    return json.loads((out / "diagnosis.json").read_text())


#: per hidden cause, the candidate whose signatures resemble it most (tried beside it in the default job)
RIVAL = {"proximal_friction": "joint_hysteresis", "joint_hysteresis": "proximal_friction",
         "external_load": "stiffness_gradient", "stiffness_gradient": "external_load",
         "calibration_error": "stiffness_gradient"}


def _check_named(d, cause, tried, figures, tmp_path):
    assert d["cause"] == cause, d["explanation"]
    assert d["causes"] == [cause], d["explanation"]       # one effect: never a second cause
    assert d["gain"]["reduction_pct"] >= 30.0
    cand = {c["cause"]: c for c in d["candidates"]}
    assert cand[cause]["heldout_rms_mm"] < d["baseline"]["heldout_rms_mm"]
    # every candidate tried: cross-validated, or fitted on all experiments and left out because its
    # in-sample error could not beat the named cause's held-out one
    screened = d["skipped"].get("screened", {})
    assert set(cand) | set(screened) == set(tried) and not set(cand) & set(screened)
    for reg in d["per_regime_rms_mm"].values():
        assert reg["extended"] <= reg["baseline"] * 1.1
    if figures:
        from notchfit.io import load_params
        out = tmp_path / "out"
        for name in d["figures"]:
            assert (out / name).stat().st_size > 1000
        p = load_params(out / d["extended_model_file"])
        assert p.hysteresis_torque == pytest.approx(d["extended_model"]["params"]["hysteresis_torque"])
        assert p.hysteresis_torque > 0


@pytest.mark.parametrize("cause", IDENTIFIABLE)
def test_hidden_effect_is_named_with_heldout_gain(tmp_path, cause):
    """Reduced study, the hidden cause against its closest rival: named alone, >= 30 % held-out gain."""
    figures = cause == "joint_hysteresis"
    tried = (cause, RIVAL[cause])
    _check_named(_diagnose(tmp_path, cause, seed=1, figures=figures, causes=tried), cause, tried, figures, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("cause", IDENTIFIABLE)
def test_hidden_effect_is_named_against_every_candidate(tmp_path, cause):
    """The same reduced studies with every candidate tried (and the second-cause step among all)."""
    _check_named(_diagnose(tmp_path, cause, seed=1), cause, CAUSES, False, tmp_path)


def test_null_study_gives_none_and_never_reads_truth(tmp_path, monkeypatch):
    """A study with no hidden effect gives `none`. The analysis runs with truth.json
    deleted and opens no file of that name."""
    import builtins
    import io as _io

    study = tmp_path / "study"
    generate_study(load_recipe("null").scaled(**SMALL), study, seed=1)
    (study / "truth.json").unlink()
    opened = []

    def spy(opener):
        def f(file, *a, **k):
            opened.append(str(file))
            return opener(file, *a, **k)
        return f

    monkeypatch.setattr(builtins, "open", spy(builtins.open))
    monkeypatch.setattr(_io, "open", spy(_io.open))
    out = tmp_path / "out"
    rc = main(["diagnose", str(study), "--out", str(out), "--jobs", "2", "--no-figures",
               "--max-folds", "2"])
    monkeypatch.undo()
    assert rc == 0
    assert any(p.endswith("samples.csv") for p in opened)  # the spy saw the reads
    assert not any(p.endswith("truth.json") for p in opened)
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["cause"] == "none", d["explanation"]
    assert d["causes"] == []


@pytest.mark.parametrize("law", ["joint_hysteresis_flag",
                                 pytest.param("joint_hysteresis_masing", marks=pytest.mark.slow)])
def test_other_hysteresis_laws_are_named(tmp_path, law):
    """Flag-shaped loops confined to the plateau (the generator's two-branch superelastic law) and
    Masing loops (its Bouc-Wen law), not the candidate's stop: named joint_hysteresis with >= 30%
    held-out gain, alone."""
    d = _diagnose(tmp_path, law, seed=1, causes=("joint_hysteresis", "proximal_friction"))
    assert d["causes"] == ["joint_hysteresis"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0


@pytest.mark.slow
def test_masing_loops_get_no_false_second_cause_from_the_screen(tmp_path):
    """Bouc-Wen loops, seed 2: the hysteresis candidate's fit on all experiments stops at 0.80 mm against
    0.78 mm held-out for proximal friction, so the candidates' screen leaves it out; the second-cause step
    cross-validates it alone for its pair and names it first, alone (it was named with proximal friction
    as a false second cause; docs/history.md, 2026-11-28)."""
    d = _diagnose(tmp_path, "joint_hysteresis_masing", seed=2, causes=("joint_hysteresis", "proximal_friction"))
    assert d["causes"] == ["joint_hysteresis"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0


@pytest.mark.slow
def test_masing_loops_are_named_with_one_cause_though_the_screen_fit_stalls(tmp_path):
    """The same study with one cause (no second-cause step to recover it): the hysteresis candidate's fit on
    all experiments does not leave its best probe (0.80 mm in-sample, proximal friction's held-out 0.78 mm), so
    it is cross-validated and named (proximal friction was named before; docs/history.md, 2026-11-28)."""
    d = _diagnose(tmp_path, "joint_hysteresis_masing", seed=2, causes=("joint_hysteresis", "proximal_friction"),
                  one_cause=True)
    assert d["causes"] == ["joint_hysteresis"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0


def test_two_hidden_causes_are_both_named_with_their_figures(tmp_path):
    """A tip load and a stiffness gradient at once: both named, each with its contribution and the
    figure that makes its case; the saved model holds both; combined gain >= 30%."""
    from notchfit.io import load_params

    d = _diagnose(tmp_path, "external_load+stiffness_gradient", seed=1, figures=True,
                  causes=("external_load", "stiffness_gradient", "joint_hysteresis"))
    assert sorted(d["causes"]) == ["external_load", "stiffness_gradient"], d["explanation"]
    assert d["cause"] == d["causes"][0]
    assert d["gain"]["reduction_pct"] >= 30.0
    shares = [c["share_pct"] for c in d["contributions"]]
    assert [c["cause"] for c in d["contributions"]] == d["causes"] and shares == sorted(shares, reverse=True)
    assert sum(shares) == pytest.approx(100.0)
    assert all(c["gain_pct"] > 0 and c["removes"] for c in d["contributions"])
    out = tmp_path / "out"
    for c in d["causes"]:
        assert f"diagnosis_cause_{c}.png" in d["figures"] and (out / f"diagnosis_cause_{c}.csv").is_file()
    p = load_params(out / d["extended_model_file"])
    assert p.tip_force_x != 0.0 and p.stiffness_gradient != 0.0
    # the report shows each cause with its figure (issue 19, item 5)
    assert main(["report", str(out), "--study", str(tmp_path / "study")]) == 0
    page = (out / "report.html").read_text()
    for k, c in enumerate(d["causes"], 1):
        assert f"Cause {k}: {c.replace('_', ' ')}" in page
        assert f'alt="figure of the cause {c}"' in page


@pytest.mark.parametrize("small", [True, pytest.param(False, marks=pytest.mark.slow, id="full")])
def test_angle_data_of_a_one_tendon_wrist(tmp_path, small):
    """A one-sided 5-notch wrist with a lumen tendon, measured as joint angles only, hiding the
    superelastic flag: named joint_hysteresis from degrees, with a tip load (Eqs. 18-20 on the wrist's own
    pivot chain) among the rivals of the full study; what needs notch points (a calibration warp) or both pull directions (the
    direction-asymmetry signature) is skipped with its reason. The default job runs the reduced study, the
    slow job the recipe's full one."""
    # the reduced study leaves the tip load (fitted on any chain, tests/test_diagnosis_tip_load_wrist.py) to
    # the full one: it is the dearest rival (a simulation with a tip load costs 2.5 times one without)
    rivals = ("proximal_friction", "calibration_error") + (() if small else ("external_load",))
    d = _diagnose(tmp_path, "wrist_hysteresis", seed=1, small=small, causes=("joint_hysteresis",) + rivals)
    assert d["metric"] == "angles" and d["gain"]["metric"] == "heldout_rms_deg"
    assert d["causes"] == ["joint_hysteresis"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0
    assert set(d["skipped"]["candidates"]) == {"calibration_error"}
    assert set(d["skipped"]["signatures"]) == {"spatial_pattern", "direction_asymmetry"}
    assert "heldout_rms_deg" in d["candidates"][0] and "heldout_rms_mm" not in d["candidates"][0]
    # the report speaks degrees and names the wrist's data and model
    assert main(["report", str(tmp_path / "out"), "--study", str(tmp_path / "study")]) == 0
    page = (tmp_path / "out" / "report.html").read_text()
    assert "held-out joint-angle error" in page and "joint angles per sample (one per notch) given in angles.csv" in page
    assert "the tube&#x27;s default model" in page or "the tube's default model" in page


#: static friction and the causes it could be mistaken for (a hold while unloading, a wider loop)
STATIC_RIVALS = ("static_friction", "proximal_friction", "joint_hysteresis")


def test_static_friction_is_not_misattributed(tmp_path):
    """A larger static coefficient acts only at break-away (Sec. IV-B Step 4; see
    test_friction.py::test_step4_static_coefficient_acts_only_at_break_away): with the
    recipe's ±0.11 N load cells even the true model beats the baseline at the true
    parameters by at most 1-11 % held-out rms (`benchmarks/static_friction_bound.py`,
    docs/diagnosis.md), so no analysis can show the 30 % gain. The diagnosis must not
    name another cause for it: none, unexplained or static_friction."""
    d = _diagnose(tmp_path, "static_friction", seed=1, causes=STATIC_RIVALS)
    assert d["cause"] in ("none", "unexplained", "static_friction"), d["explanation"]


def test_large_static_friction_shows_as_loading_stalls(tmp_path):
    """μ_s − μ_d = 0.45–0.6: some steps of the upper loading ramp do not break the cables
    away and the shape stalls (test_friction.py::test_step4_...). The diagnosis measures
    the stalls, names static_friction or says `unexplained` and points to static friction
    (docs/diagnosis.md) — never another cause."""
    recipe = load_recipe("static_friction").replace(effect={"static_excess": (0.45, 0.6)})
    study = tmp_path / "study"
    generate_study(recipe.scaled(**SMALL), study, seed=1)
    (study / "truth.json").unlink()
    out = tmp_path / "out"
    assert main(["diagnose", str(study), "--out", str(out), "--jobs", "2", "--no-figures",
                 "--max-folds", "2", "--causes", ",".join(STATIC_RIVALS)]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    sig = {x["signature"]: x["value"] for x in d["discrepancies"]}
    assert sig["loading_stalls"] >= 0.05
    assert d["cause"] in ("static_friction", "unexplained"), d["explanation"]
    assert "static friction" in d["explanation"] or d["cause"] == "static_friction"


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12, 13])
@pytest.mark.parametrize("cause", CAUSES + ("null",))
def test_hidden_effect_full_studies(tmp_path, cause, seed):
    d = _diagnose(tmp_path, cause, seed=seed, small=False)
    if cause == "static_friction":  # see test_static_friction_is_not_misattributed
        assert d["cause"] in ("none", "unexplained", "static_friction"), d["explanation"]
        assert len(d["causes"]) <= 1
        return
    want = "none" if cause == "null" else cause
    assert d["cause"] == want, d["explanation"]
    assert d["causes"] == ([] if want == "none" else [want]), d["explanation"]
    if want != "none":
        assert d["gain"]["reduction_pct"] >= 30.0


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12, 13])
@pytest.mark.parametrize("law", ["joint_hysteresis_flag", "joint_hysteresis_masing"])
def test_other_hysteresis_laws_full_studies(tmp_path, law, seed):
    """Flag-shaped (superelastic) and Masing (Bouc-Wen) loops: joint_hysteresis, alone, >= 30%."""
    d = _diagnose(tmp_path, law, seed=seed, small=False)
    assert d["causes"] == ["joint_hysteresis"], d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0


@pytest.mark.slow
@pytest.mark.parametrize("pair", PAIRS, ids=["+".join(p) for p in PAIRS])
def test_two_hidden_causes_full_studies(tmp_path, pair):
    """Every pair of the five nameable causes, each effect from its shipped recipe's range: both named,
    combined gain >= 30% (docs/diagnosis.md lists the measured outcome of each pair)."""
    d = _diagnose(tmp_path, "+".join(pair), seed=11, small=False)
    assert sorted(d["causes"]) == sorted(pair), d["explanation"]
    assert d["gain"]["reduction_pct"] >= 30.0
