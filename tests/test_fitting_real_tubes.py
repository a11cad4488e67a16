"""The notch-point fitter on one-sided wrists (docs/models.md "Real tubes: kinematics"): synthetic points
from the projector (pivot model, joints on the neutral axes), fitted back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from notchfit.analysis.fitting import fit_experiment
from notchfit.analysis.fitting.first_pass import estimate_angles
from notchfit.io import load_geometry
from notchfit.physics.notches import notch_points, to_plane

DATA = Path(__file__).resolve().parent.parent / "datasets" / "geometry"
PLANE = (2.0e-3, -1.0e-3, 0.25, False)          # tx, ty [m], phi [rad], mirror


def study(name, sigma, S=6, seed=0):
    """A tendon pull: every joint from its rest angle toward 0.8 of its closure angle, with noise."""
    g = load_geometry(DATA / f"{name}.toml")
    frac = np.linspace(0.0, 0.8, S)[:, None]
    rng = np.random.default_rng(seed)
    theta = g.rest_angles + frac * (0.8 * g.closure_angles - g.rest_angles) * rng.uniform(0.8, 1.2, g.n_joints)
    Q = to_plane(notch_points(theta, g), *PLANE)
    return g, theta, Q + rng.normal(0.0, sigma, Q.shape)


@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
def test_first_pass_is_exact_on_clean_points(name):
    g, theta, Q = study(name, 0.0)
    np.testing.assert_allclose(estimate_angles(Q, g, PLANE), theta, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
def test_fit_experiment_recovers_joint_angles_of_a_one_sided_wrist(name):
    sigma = 10e-6
    g, theta, Q = study(name, sigma)
    fit = fit_experiment(Q, g, models=("free", "cc"), sigma=sigma)
    T = fit.transform
    assert np.hypot(T.tx - PLANE[0], T.ty - PLANE[1]) < 5 * sigma and abs(T.phi - PLANE[2]) < 0.01
    for s, f in enumerate(fit.model_fits("free")):
        assert f.success
        se = np.sqrt(np.diag(f.theta_cov))
        assert np.all(np.abs(f.theta - theta[s]) <= 3 * se), (f.theta - theta[s]) / se
        assert f.rms < 3 * sigma
