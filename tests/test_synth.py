"""The synthetic study generator (issue 7): recipes, ground truth beside the data, files."""
import json

import numpy as np
import pytest

from notchfit.cli import main
from notchfit.analysis.diagnosis import CAUSES
from notchfit.io import read_study
from notchfit.physics.notches import notch_points, to_plane
from notchfit.studies.synth import list_recipes, load_recipe, recipe_from_dict, synthesize, write_study


def test_every_cause_has_a_recipe_and_all_recipes_load():
    names = list_recipes()
    for cause in CAUSES + ("null", "paper8"):
        assert cause in names
    for name in names:
        r = load_recipe(name)
        assert r.experiments
    assert load_recipe("paper8").cause == "none" and len(load_recipe("paper8").experiments) == 8


def test_truth_is_returned_beside_the_observations():
    r = load_recipe("calibration_error").scaled(n_experiments=2, n_up=4, n_down=5)
    st = synthesize(r, seed=3)
    assert st.cause == "calibration_error" and st.warp is not None
    e = st.experiments[0]
    S = len(e.samples)
    assert e.theta.shape == (S, 27) and e.points.shape == (S, 58, 2)
    # the true points are the projector's points of the true angles in the true plane frame
    P = to_plane(notch_points(e.theta, st.geometry), e.plane["tx"], e.plane["ty"], e.plane["phi"],
                 e.plane["mirror"])
    np.testing.assert_allclose(P, e.true_points, atol=1e-12)
    # the measured points carry the warp and 0.02 mm noise: far from the truth, not absurdly
    d = np.linalg.norm(e.points - e.true_points, axis=-1)
    assert 2e-5 < np.nanmedian(d) < 2e-3


def test_seeded_and_deterministic():
    r = load_recipe("joint_hysteresis").scaled(n_experiments=1, n_up=4, n_down=4)
    a, b, c = synthesize(r, seed=5), synthesize(r, seed=5), synthesize(r, seed=6)
    np.testing.assert_array_equal(a.experiments[0].points, b.experiments[0].points)
    assert a.effect == b.effect and a.effect != c.effect


def test_base_parameters_drawn_away_from_the_paper():
    r = load_recipe("null").scaled(n_experiments=1, n_up=3, n_down=3)
    for seed in range(5):
        p = synthesize(r, seed=seed).params
        assert abs(p.k_lin / 0.4829 - 1) >= r.min_rel_offset - 1e-12
        assert abs(p.mu_d / 0.29 - 1) >= r.min_rel_offset - 1e-12


def test_written_study_follows_data_format(tmp_path):
    r = load_recipe("external_load").scaled(n_experiments=2, n_up=4, n_down=5)
    st = synthesize(r, seed=2)
    write_study(st, tmp_path / "s")
    exps = read_study(tmp_path / "s")
    assert [e.name for e in exps] == [e.name for e in st.experiments]
    np.testing.assert_allclose(exps[0].points, st.experiments[0].points, atol=1e-9)
    assert exps[0].point_sigma == pytest.approx(2e-5) and exps[0].tension_sigma == pytest.approx(0.11)
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    assert truth["cause"] == "external_load" and set(truth["effect"]) == {"tip_force_x", "tip_force_z"}


def test_bad_recipe_messages():
    with pytest.raises(ValueError, match="unknown key"):
        recipe_from_dict({"name": "x", "bogus": 1})
    with pytest.raises(ValueError, match="needs effect range"):
        recipe_from_dict({"name": "x", "cause": "joint_hysteresis",
                          "experiments": [{"name": "a", "pull": "left", "counter_N": 0.4}]})


def test_static_friction_effect_is_mu_s_excess_and_the_old_name_still_reads():
    """μ_s − μ_d is ``mu_s_excess`` (as in the diagnosis); ``static_excess`` is read as an alias."""
    exp = [{"name": "a", "pull": "left", "counter_N": 0.4}]
    new = recipe_from_dict({"name": "x", "cause": "static_friction", "effect": {"mu_s_excess": 0.2},
                            "experiments": exp})
    old = recipe_from_dict({"name": "x", "cause": "static_friction", "effect": {"static_excess": 0.2},
                            "experiments": exp})
    assert new == old and new.effect == {"mu_s_excess": (0.2, 0.2)}
    r = load_recipe("static_friction")
    assert set(r.effect) == {"mu_s_excess"}
    assert r.replace(effect={"static_excess": (0.3, 0.3)}).effect == {"mu_s_excess": (0.3, 0.3)}
    st = synthesize(r.scaled(n_experiments=1, n_up=2, n_down=2), seed=1, method="fast")
    assert st.params.mu_s - st.params.mu_d == pytest.approx(st.effect["mu_s_excess"])


def test_synth_command_refuses_to_overwrite(tmp_path):
    out = tmp_path / "s"
    assert main(["synth", "null", "--out", str(out), "--seed", "1", "--experiments", "1", "--samples", "3", "3"]) == 0
    assert (out / "truth.json").is_file()
    assert main(["synth", "null", "--out", str(out), "--seed", "1"]) == 2
