"""Synthetic real-tube wrists with ground truth (issue 14, datasets/recipes/wrist_*.toml).

The one-sided wrist is frictionless: its truth is the quasi-static equilibrium of
every sample (notchfit.physics.statics, Newton's method on ``τ_j(θ_j - θ0_j) = a_j T``),
a formulation independent of the friction simulator; the simulator at μ = 0
must reproduce it to 1e-9 rad (docs/models.md invariant, real tubes). The
tip-first wrist has capstan friction: its truth is the reference solver's.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from notchfit.physics.friction import simulate
from notchfit.studies.synth import list_recipes, synthesize, write_study


@pytest.fixture(scope="module")
def asym():
    return synthesize("wrist_asymmetric")


def test_recipes_are_shipped():
    assert {"wrist_asymmetric", "wrist_tip_first"} <= set(list_recipes())


def test_frictionless_wrist_truth_from_the_statics(asym):
    assert asym.truth_solver == "statics" and asym.params.spring_law == "material"
    sp = asym.params.joint_spring(asym.geometry)
    reached = max(float(np.max(e.theta - asym.geometry.rest_angles)) for e in asym.experiments)
    assert reached > sp.breaks[0, 1]                      # the largest test reaches the stop
    # the fast solver's rest state is exact (closed form once every link sticks); the reference
    # relaxes on the superelastic plateau with b_j / k_se = τ_b E_lin / E_se (~0.5 s): after the
    # 5 s between samples it is within ~1e-6 rad of rest
    for e in asym.experiments:
        for method, tol in (("fast", 1e-9), ("reference", 1e-5)):
            r = simulate(e.samples["time_s"].to_numpy(), None, e.tension_right, asym.params, asym.geometry,
                         method=method)
            np.testing.assert_allclose(r.theta, e.theta, rtol=0, atol=tol, err_msg=f"{e.name} {method}")


def test_tip_first_wrist_bends_tip_first_and_solvers_agree():
    s = synthesize("wrist_tip_first")
    assert s.truth_solver == "reference" and s.params.friction_law == "capstan" and s.params.mu_d > 0
    e = s.experiments[0]
    peak = int(np.argmax(e.tension_right))
    dev = e.theta[peak] - s.geometry.rest_angles
    assert np.all(np.diff(dev) > 0)                        # deeper cuts toward the tip bend more
    np.testing.assert_array_equal(e.theta[0] > 0, True)   # pre-curved
    for e in s.experiments:
        r = simulate(e.samples["time_s"].to_numpy(), None, e.tension_right, s.params, s.geometry)
        assert np.abs(r.theta - e.theta).max() <= 1e-3


def test_written_study_has_truth_and_empty_columns_for_the_missing_tendon(asym, tmp_path):
    out = write_study(asym, tmp_path / "study")
    truth = json.loads((out / "truth.json").read_text())
    assert truth["truth_solver"] == "statics" and truth["params"]["spring_law"] == "material"
    assert truth["geometry"] == "wrist_asymmetric"
    e = asym.experiments[0]
    np.testing.assert_array_equal(np.array(truth["experiments"][e.name]["theta_rad"]), e.theta)
    df = pd.read_csv(out / e.name / "samples.csv")
    assert df["tension_left_N"].isna().all() and df["displacement_left_mm"].isna().all()
    assert df["tension_right_N"].notna().all()
    pts = pd.read_csv(out / e.name / "notch_points.csv")
    assert pts["point"].max() == 4 + 2 * 5


def test_moved_study_still_runs(asym, tmp_path):
    """A study names its geometry files relative to itself (a copy in ``STUDY/geometry``, never an
    absolute path): moved elsewhere, it is read with the same geometry and ``fit`` runs on it (issue 27)."""
    from notchfit import io
    from notchfit.cli import main

    written = write_study(asym, tmp_path / "a" / "study")
    toml = (written / asym.experiments[0].name / "experiment.toml").read_text()
    assert 'geometry = "../geometry/wrist_asymmetric.toml"' in toml and str(tmp_path) not in toml
    moved = tmp_path / "b" / "moved"
    moved.parent.mkdir()
    written.rename(moved)
    exps = io.read_study(moved)
    assert [e.name for e in exps] == [e.name for e in asym.experiments]
    assert exps[0].geometry.n_joints == asym.geometry.n_joints
    np.testing.assert_allclose(exps[0].geometry.rest_angles, asym.geometry.rest_angles)
    assert main(["fit", str(moved), "--out", str(tmp_path / "out"), "--no-figures"]) == 0
