"""Identifiability verdicts from the Fisher information (notchfit.analysis.estimation.identifiability).

Checked against closed forms of linear least squares (the covariance of an
ordinary regression is σ² (XᵀX)⁻¹, Bates & Watts 1988 Sec. 1.1), against a
Monte Carlo spread of refits, and on the structural cases: a parameter with
no effect, two parameters that act only as a sum, and the friction of a
frictionless study pulled in one direction (its residuals do not depend on μ).
"""

import numpy as np
import pytest

from notchfit.analysis.estimation.identifiability import assess


def test_standard_errors_are_the_regression_closed_form():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(200, 3))
    sigma = 0.1
    J = X / sigma
    ident = assess(J, ["a", "b", "c"], [1.0, 2.0, 3.0], [1.0, 1.0, 1.0])
    se = np.sqrt(np.diag(np.linalg.inv(X.T @ X)) * sigma ** 2)
    np.testing.assert_allclose([p.se for p in ident.parameters], se, rtol=1e-10)
    assert ident.undetermined() == []


def test_standard_errors_match_the_spread_of_refits():
    """The SE equals the standard deviation of the estimates over seeded noise draws (a second method)."""
    rng = np.random.default_rng(2)
    t = np.linspace(0.0, 1.0, 50)
    X = np.c_[np.ones_like(t), t]
    sigma = 0.05
    est = [np.linalg.lstsq(X, X @ [0.3, 1.2] + rng.normal(0, sigma, t.size), rcond=None)[0] for _ in range(2000)]
    ident = assess(X / sigma, ["offset", "slope"], [0.3, 1.2], [1.0, 1.0])
    np.testing.assert_allclose([p.se for p in ident.parameters], np.std(est, axis=0), rtol=0.05)


def test_a_parameter_without_effect_is_not_determined():
    rng = np.random.default_rng(3)
    J = np.c_[rng.normal(size=100), np.zeros(100)]
    ident = assess(J, ["k", "mu"], [1.0, 0.1], [1.0, 0.5])
    assert ident["mu"].verdict == "not determined" and ident["k"].determined
    assert np.isinf(ident["mu"].se)
    assert "mu: not determined" in ident.summary()


def test_two_parameters_seen_only_as_a_sum_are_not_determined():
    rng = np.random.default_rng(4)
    g = rng.normal(size=(100, 1))
    J = np.c_[g, g, rng.normal(size=100)]
    ident = assess(J, ["a", "b", "c"], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    assert ident["a"].verdict == ident["b"].verdict == "not determined"
    assert ident["c"].determined
    assert ident.condition == np.inf or ident.condition > 1e12


def test_large_standard_error_against_the_range_is_flagged():
    J = np.array([[1.0], [1.0]])          # SE 0.707 per unit of scale
    assert assess(J, ["x"], [0.0], [1.0])["x"].verdict == "not determined"
    assert assess(J * 5, ["x"], [0.0], [1.0])["x"].verdict == "weakly determined"   # SE 0.14
    assert assess(J * 50, ["x"], [0.0], [1.0])["x"].verdict == "determined"


def _wrist_information(tension_max):
    """Finite-difference Jacobian of a loading-only wrist's angles in (E_lin, E_se), σ = 0.5°."""
    from notchfit.physics.friction import default_params, simulate
    from notchfit.io import load_geometry
    from notchfit.io.resources import datasets_dir

    geom = load_geometry(datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    base = default_params(geom)
    tension = np.linspace(0.0, tension_max, 9)
    time = np.arange(tension.size) * 5.0

    def angles(**kw):
        return simulate(time, np.zeros_like(tension), tension, base.replace(**kw), geom, method="fast").theta.ravel()

    E0, S0 = base.E_lin, base.E_se
    J = np.c_[(angles(E_lin=E0 * 1.01) - angles(E_lin=E0 * 0.99)) / (0.02 * E0),
              (angles(E_se=S0 * 1.01) - angles(E_se=S0 * 0.99)) / (0.02 * S0)] / np.radians(0.5)
    return J, (E0, S0)


def test_plateau_modulus_of_a_study_in_the_linear_range_is_not_determined():
    """A wrist bent only within its linear range (outer-fibre strain below strain_lower, models.md's
    material law) says nothing of the superelastic plateau modulus E_se; bent into the plateau it does."""
    J, x = _wrist_information(0.3)
    ident = assess(J, ["E_lin", "E_se"], x, x)
    assert ident.undetermined() == ["E_se"]
    assert "E_se: not determined" in ident.summary()
    J, x = _wrist_information(2.0)
    assert assess(J, ["E_lin", "E_se"], x, x).undetermined() == []
