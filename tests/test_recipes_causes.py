"""Recipes with several hidden effects, with laws no candidate has, and with a recorded protocol."""
import json

import numpy as np
import pytest

from notchfit.io import read_study
from notchfit.studies.recipes import EFFECT_LAWS, combine_recipes, load_recipe, recipe_from_dict
from notchfit.studies.synth import generate_study, synthesize

TINY = dict(n_experiments=2, n_up=3, n_down=3)


def test_two_causes_draw_both_effects_and_the_warp(tmp_path):
    r = combine_recipes(load_recipe("joint_hysteresis"), load_recipe("calibration_error")).scaled(**TINY)
    assert r.causes == ("joint_hysteresis", "calibration_error")
    assert r.effect_order == ("hysteresis_torque", "scale_error", "k_radial")
    st = generate_study(r, tmp_path / "s", seed=3)
    lo, hi = load_recipe("joint_hysteresis").effect["hysteresis_torque"]
    assert lo <= st.params.hysteresis_torque <= hi
    assert st.warp is not None and st.warp["scale_error"] == st.effect["scale_error"]
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    assert truth["cause"] == ["joint_hysteresis", "calibration_error"]
    # the first cause's draw is what the one-cause recipe draws with the same seed
    one = synthesize(load_recipe("joint_hysteresis").scaled(**TINY), 3)
    assert one.effect["hysteresis_torque"] == st.effect["hysteresis_torque"]


def test_causes_from_toml_and_their_checks():
    base = {"name": "x", "experiments": [{"name": "L", "pull": "left", "counter_N": 0.45}]}
    r = recipe_from_dict({**base, "causes": ["proximal_friction", "external_load"],
                          "effect": {"proximal_beta": 0.05, "tip_force_x": 0.1, "tip_force_z": 0.0}})
    assert r.causes == ("proximal_friction", "external_load")
    for bad, match in (({"causes": ["proximal_friction"], "effect": {"proximal_beta": 0.1, "tip_force_x": 0.1}},
                        "do not belong"),
                       ({"causes": ["proximal_friction", "proximal_friction"], "effect": {"proximal_beta": 0.1}},
                        "distinct"),
                       ({"cause": "joint_hysteresis", "effect": {"bouc_wen_torque": 0.004}}, "needs effect"),
                       ({"cause": "none", "causes": ["none"]}, "not both")):
        with pytest.raises(ValueError, match=match):
            recipe_from_dict({**base, **bad})


@pytest.mark.parametrize("name,fields", [("joint_hysteresis_flag", ("superelastic_gap",)),
                                         ("joint_hysteresis_masing", ("bouc_wen_torque", "bouc_wen_stiffness"))])
def test_generator_law_recipes_hide_joint_hysteresis_by_another_law(name, fields):
    r = load_recipe(name)
    assert r.cause == "joint_hysteresis" and r.effect_order == fields and fields in EFFECT_LAWS["joint_hysteresis"]
    st = synthesize(r.scaled(**TINY), 1)
    assert all(getattr(st.params, f) > 0 for f in fields) and st.params.hysteresis_torque == 0.0
    assert st.truth_solver == "reference"


def test_recorded_ramp_protocol(tmp_path):
    r = load_recipe("null").scaled(**TINY).replace(ramp_time_s=4.0, record_protocol=True)
    generate_study(r, tmp_path / "s", seed=1)
    exps = read_study(tmp_path / "s")
    assert [e.ramp_time for e in exps] == [4.0, 4.0]
    step = synthesize(load_recipe("null").scaled(**TINY), 1)
    ramp = synthesize(r, 1)
    assert np.abs(ramp.experiments[0].theta - step.experiments[0].theta).max() > 1e-6  # the protocol is in the data
