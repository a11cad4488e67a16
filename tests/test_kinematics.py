"""Kinematics against the paper (Sec. II-A, III, Appendix) and against itself."""
import numpy as np
import pytest

from notchfit.physics import kinematics as K


def _fd(f, x, h=1e-7):
    cols = []
    for k in range(len(x)):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


def test_hat_vee_roundtrip(rng):
    w = rng.normal(size=3)
    v = rng.normal(size=3)
    np.testing.assert_allclose(K.hat(w) @ v, np.cross(w, v))
    np.testing.assert_allclose(K.vee(K.hat(w)), w)
    xi = rng.normal(size=6)
    np.testing.assert_allclose(K.vee6(K.hat6(xi)), xi)


def test_exp_twist_matches_matrix_exponential(rng):
    from scipy.linalg import expm
    w = rng.normal(size=3)
    w /= np.linalg.norm(w)
    xi = np.concatenate([rng.normal(size=3), w])
    np.testing.assert_allclose(K.exp_twist(xi, 0.7), expm(K.hat6(xi) * 0.7), atol=1e-12)


def test_sec2a_twists(geom):
    xi = K.joint_twists(geom)
    np.testing.assert_allclose(xi[3], [-3 * geom.p, 0, 0, 0, 1, 0])  # ((1-i)p, 0,0, 0,1,0), i=4


def test_poe_equals_planar_chain(geom, rng):
    for _ in range(5):
        th = rng.uniform(-0.14, 0.14, geom.n_joints)
        g = K.link_frames(th, geom)
        q = K.joint_positions(th, geom.p)
        phi = np.cumsum(th)
        # link i frame origin = joint i position; orientation = R_y(phi_i)
        np.testing.assert_allclose(g[1:, 0, 3], q[:-1, 0], atol=1e-12)
        np.testing.assert_allclose(g[1:, 2, 3], q[:-1, 1], atol=1e-12)
        np.testing.assert_allclose(g[1:, 0, 2], np.sin(phi), atol=1e-12)
        np.testing.assert_allclose(K.tool_frame(th, geom)[[0, 2], 3], q[-1], atol=1e-12)
        np.testing.assert_allclose(K.tip_pose(th, geom), [*q[-1], phi[-1]], atol=1e-12)


def test_positive_theta_bends_toward_plus_x(geom):
    x, z, phi = K.tip_pose(np.full(geom.n_joints, 0.05), geom)
    assert x > 0 and phi > 0


def test_eq18_20_planar_jacobian_fd(geom, rng):
    th = rng.uniform(-0.14, 0.14, geom.n_joints)
    J = K.planar_jacobian(th, geom)
    np.testing.assert_allclose(J, _fd(lambda t: K.tip_pose(t, geom), th), atol=1e-8)


def test_eq1_spatial_jacobian_fd(geom, rng):
    """V^s = (ġ g^{-1})^∨ = J^s θ̇ (Eq. 1), by central differences of g_st."""
    th = rng.uniform(-0.14, 0.14, geom.n_joints)
    g = K.tool_frame(th, geom)
    ginv = K.inverse_se3(g)
    dg = _fd(lambda t: K.tool_frame(t, geom).ravel(), th).reshape(4, 4, -1)
    Vs = np.stack([K.vee6(dg[..., k] @ ginv) for k in range(geom.n_joints)], axis=-1)
    np.testing.assert_allclose(K.spatial_jacobian(th, geom), Vs, atol=1e-7)


def test_eq27_body_jacobian(geom, rng):
    th = rng.uniform(-0.14, 0.14, geom.n_joints)
    g = K.tool_frame(th, geom)
    np.testing.assert_allclose(K.adjoint(g) @ K.body_jacobian(th, geom),
                               K.spatial_jacobian(th, geom), atol=1e-14)
    # body twist: (g^{-1} ġ)^∨
    dg = _fd(lambda t: K.tool_frame(t, geom).ravel(), th).reshape(4, 4, -1)
    Vb = np.stack([K.vee6(K.inverse_se3(g) @ dg[..., k]) for k in range(geom.n_joints)], -1)
    np.testing.assert_allclose(K.body_jacobian(th, geom), Vb, atol=1e-7)


def test_sec3_rank(geom, rng):
    assert np.linalg.matrix_rank(K.spatial_jacobian(rng.uniform(-0.1, 0.1, 27), geom)) == 3
    assert np.linalg.matrix_rank(K.spatial_jacobian(np.zeros(27), geom)) == 2


def test_sec3_wrench_nullspace_F1_F3(geom, rng):
    """Eq. (8): F_s = Ad^T_{g^-1}(a1 F1 + a2 F2 + a3 F3) gives zero joint torque."""
    th = rng.uniform(-0.14, 0.14, geom.n_joints)
    g = K.tool_frame(th, geom)
    Js = K.spatial_jacobian(th, geom)
    AdT = K.adjoint(K.inverse_se3(g)).T
    for Fb in np.eye(6)[[1, 3, 5]]:
        assert np.abs(Js.T @ (AdT @ Fb)).max() < 1e-14
    # the in-plane body wrenches do produce torque
    assert np.abs(Js.T @ (AdT @ np.eye(6)[0])).max() > 1e-3
    # at theta = 0, F4 = (0,0,1,0,0,0) (axial force) joins the nullspace
    Js0 = K.spatial_jacobian(np.zeros(27), geom)
    Ad0 = K.adjoint(K.inverse_se3(K.tool_frame(np.zeros(27), geom))).T
    assert np.abs(Js0.T @ (Ad0 @ np.eye(6)[2])).max() < 1e-15


def test_eq28_world_load_torques_match_planar(geom, rng):
    th = rng.uniform(-0.14, 0.14, geom.n_joints)
    g = K.tool_frame(th, geom)
    f, tau = np.array([0.3, 0.0, -0.2]), np.array([0.0, 0.01, 0.0])
    Fs = K.spatial_wrench_from_world(f, tau, g)
    tq = K.spatial_jacobian(th, geom).T @ Fs
    np.testing.assert_allclose(tq, K.joint_torques_from_tip_wrench(th, geom, 0.3, -0.2, 0.01),
                               atol=1e-15)
    # a force toward +x bends toward +x: positive torque on every joint near straight
    assert np.all(K.joint_torques_from_tip_wrench(np.zeros(27), geom, f_x=1.0) > 0)


def test_planar_vectorized(geom, rng):
    th = rng.uniform(-0.14, 0.14, (4, 3, geom.n_joints))
    J = K.planar_jacobian(th, geom)
    assert J.shape == (4, 3, 3, geom.n_joints)
    np.testing.assert_allclose(J[2, 1], K.planar_jacobian(th[2, 1], geom))


@pytest.mark.parametrize("bad", [np.zeros(26), np.full(27, np.nan), 0.1])
def test_bad_angles(geom, bad):
    with pytest.raises(ValueError, match="joint angles"):
        K.tip_pose(bad, geom)
