"""Shape models of Sec. IV-A (θ_j = a, θ_j = a + b j, and richer families)."""

import numpy as np
import pytest

from notchfit.physics.shapes import DEFAULT_SMOOTH_WEIGHT, ShapeModel, constant_curvature, free, get_model, linear, piecewise, quadratic

N = 27


def test_sec4a_constant_curvature_theta_equals_a():
    m = constant_curvature(N)
    assert m.param_names == ("a",) and m.n_params == 1
    np.testing.assert_array_equal(m.theta([0.07]), np.full(N, 0.07))


def test_sec4a_linear_model_a_plus_b_j_with_j_from_1():
    m = linear(N)
    th = m.theta([0.1, -0.003])
    j = np.arange(1, N + 1)
    np.testing.assert_allclose(th, 0.1 - 0.003 * j, rtol=0, atol=1e-15)
    assert th[0] == pytest.approx(0.097)          # joint 1 is a + b, not a


def test_quadratic_model():
    th = quadratic(N).theta([0.1, -0.003, 2e-5])
    j = np.arange(1, N + 1)
    np.testing.assert_allclose(th, 0.1 - 0.003 * j + 2e-5 * j * j, atol=1e-15)


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 26, 27])
def test_piecewise_segments_partition_the_joints(k):
    m = get_model(f"pw{k}", N)
    assert m.name == f"pw{k}" and m.param_names == tuple(f"s{g}" for g in range(1, k + 1))
    B = m.basis
    np.testing.assert_array_equal(B.sum(1), np.ones(N))        # every joint in exactly one segment
    seg = B.argmax(1)
    assert np.all(np.diff(seg) >= 0)                          # contiguous, base to tip
    sizes = B.sum(0)
    assert sizes.max() - sizes.min() <= 1                     # as even as possible
    s = np.arange(1, k + 1) * 0.01
    np.testing.assert_array_equal(m.theta(s), s[seg])


def test_free_model_is_identity_and_vectorized():
    m = free(N)
    rng = np.random.default_rng(3)
    P = rng.normal(size=(4, 5, N))
    np.testing.assert_array_equal(m.theta(P), P)
    assert m.param_names[0] == "theta_1" and m.param_names[-1] == f"theta_{N}"
    assert m.n_prior == 0


@pytest.mark.parametrize("name", ["cc", "linear", "quadratic", "pw3", "free", "free_smooth"])
def test_jacobian_equals_finite_difference(name):
    m = get_model(name, N)
    rng = np.random.default_rng(7)
    p = rng.normal(scale=0.05, size=m.n_params)
    h = 1e-6
    fd = np.stack([(m.theta(p + h * e) - m.theta(p - h * e)) / (2 * h)
                   for e in np.eye(m.n_params)], axis=1)
    np.testing.assert_allclose(m.jacobian(p), fd, atol=1e-8)
    assert m.jacobian().shape == (N, m.n_params)


@pytest.mark.parametrize("name", ["cc", "linear", "quadratic", "pw3", "free"])
def test_initial_recovers_parameters_of_an_in_family_theta(name):
    m = get_model(name, N)
    rng = np.random.default_rng(11)
    p = rng.normal(scale=0.05, size=m.n_params)
    if name == "quadratic":
        p[2] *= 1e-2
    np.testing.assert_allclose(m.initial(m.theta(p)), p, atol=1e-12)
    np.testing.assert_array_equal(m.initial(), np.zeros(m.n_params))


def test_cc_projection_is_the_mean_angle():
    """Least-squares projection onto θ_j = a gives the mean joint angle."""
    th = np.random.default_rng(5).normal(0.05, 0.02, N)
    assert get_model("cc", N).initial(th)[0] == pytest.approx(th.mean(), abs=1e-15)


def test_free_smooth_prior_second_difference():
    m = get_model("free_smooth", N)
    assert m.smooth_weight == DEFAULT_SMOOTH_WEIGHT and m.n_prior == N - 2
    j = np.arange(1, N + 1)
    np.testing.assert_allclose(m.prior_residuals(0.1 - 0.003 * j), 0.0, atol=1e-12)  # linear: null space
    c = 2e-4
    np.testing.assert_allclose(m.prior_residuals(c * j * j), DEFAULT_SMOOTH_WEIGHT * 2 * c, rtol=1e-9)
    m2 = get_model("free_smooth=5", N)
    assert m2.smooth_weight == 5.0 and m2.name == "free_smooth=5"
    np.testing.assert_allclose(m2.prior_jacobian() @ (c * j * j), 5 * 2 * c, rtol=1e-9)
    assert get_model("free", N).prior_jacobian().shape == (0, N)


def test_registry_five_joint_tube(geom5):
    for name in ("cc", "linear", "quadratic", "pw2", "pw5", "free", "free_smooth"):
        m = get_model(name, geom5.n_joints)
        assert m.basis.shape == (5, m.n_params)
        assert m.theta(np.zeros(m.n_params)).shape == (5,)


def test_registry_passes_models_through_and_is_case_insensitive():
    m = get_model("Linear", N)
    assert m.name == "linear"
    assert get_model(m, N) is m
    assert get_model("cc", N) == constant_curvature(N)       # frozen value objects
    assert hash(get_model("pw3", N)) == hash(piecewise(N, 3))


@pytest.mark.parametrize("name", ["spline", "pw0", "pw28", "pw", "free_smooth=-1", "free_smooth=x", 3])
def test_registry_rejects_bad_names(name):
    with pytest.raises(ValueError):
        get_model(name, N)


def test_bad_inputs_raise_value_error():
    m = linear(N)
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        m.theta([0.1])
    with pytest.raises(ValueError):
        m.initial(np.zeros(5))
    with pytest.raises(ValueError):
        get_model("cc", 0)
    with pytest.raises(ValueError):
        get_model(linear(5), N)
    with pytest.raises(ValueError):
        ShapeModel("bad", 3, ("a",), np.ones((2, 1)))
    with pytest.raises(ValueError):
        free(N, smooth_weight=-1.0)
    with pytest.raises(Exception):
        m.basis[0, 0] = 2.0                                     # read-only
