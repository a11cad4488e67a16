"""Quasi-static model, constant curvature and stiffness (Sec. III, Eqs. 10-25, Figs. 8, 10)."""
import numpy as np
import pytest

from notchfit.physics import cables as C
from notchfit.physics import kinematics as K
from notchfit.physics import statics as S
from notchfit.physics.geometry import Geometry
from notchfit.io import load_fea_reference
from notchfit.physics.springs import dual_rate_spring


def linear_spring(k):
    return dual_rate_spring(k, k, 1.0)


@pytest.fixture
def model(geom):
    return S.QuasiStaticModel(geom)


# ---------------------------------------------------------------- cable stiffness (Sec. III-B/C)
def test_sec3b_cable_stiffness(geom):
    """k_c = EA/L0 = 1.8e11 * 5.1e-8 / 0.22 = 4.17e4 N/m (the paper prints 4.1e4, truncated)."""
    kc = S.CableLaw.linear(geom).coefficient
    assert kc == pytest.approx(1.8e11 * 5.1e-8 / 0.22, rel=1e-12)
    assert 4.1e4 <= kc < 4.2e4
    assert kc == pytest.approx(4.17e4, rel=1e-3)


def test_sec3c1_PKcPT_rank_one(geom, model):
    """Sec. III-C1: every entry of P K_c P^T is 2 k_c r_x²; rank 1 with eigenvector (1, …, 1)."""
    kc = geom.cable_stiffness
    P = model.coupling_matrix(np.zeros(27))
    M = (P * [kc, kc]) @ P.T
    np.testing.assert_allclose(M, 2 * kc * geom.r_x ** 2, rtol=1e-14)
    assert np.linalg.matrix_rank(M) == 1
    w, V = np.linalg.eigh(M)
    np.testing.assert_allclose(w[-1], 27 * 2 * kc * geom.r_x ** 2, rtol=1e-12)
    np.testing.assert_allclose(np.abs(V[:, -1]), 1 / np.sqrt(27), rtol=1e-12)
    # K_m = K_θ + P K_c P^T (linear range: K_θ = diag(k1))
    Km = S.joint_stiffness(model, np.full(27, 0.01), [kc, kc])
    np.testing.assert_allclose(Km, 0.36 * np.eye(27) + M, rtol=1e-14)


# ---------------------------------------------------------------- Eq. (10): signs and loads
def test_eq10_load_directions(geom, model):
    """Eq. (10) sign: a force or moment pushing the tip toward +x, or a right-cable pull, bends toward +x."""
    for kw in ({"tip_load": [0.3, 0.0, 0.0]}, {"tip_load": [0.0, 0.0, 0.01]},
               {"tensions": [1.0, 0.2]}, {"positions": [2e-5, 0.0]}):
        eq = S.equilibrium(model, **kw)
        assert eq.success and np.all(eq.theta > 0), kw
        tr = S.simulate(model, (0.0, 2.0), **kw)
        np.testing.assert_allclose(tr.final, eq.theta, atol=1e-9)
        tip = K.tip_pose(eq.theta, geom)
        assert tip[0] > 0
    # opposite loads bend toward -x
    assert np.all(S.equilibrium(model, tip_load=[-0.3, 0, 0]).theta < 0)
    assert np.all(S.equilibrium(model, tensions=[0.2, 1.0]).theta < 0)


def test_eq28_world_wrench_conversion(geom, model, rng):
    """The model's load torques are J_st^s(θ)^T F_s with F_s from Eq. (28) (world force and torque)."""
    th = rng.uniform(-0.14, 0.14, 27)
    f, tau = rng.normal(size=3), rng.normal(size=3) * 0.01
    Fs = K.spatial_wrench_from_world(f, tau, K.tool_frame(th, geom))
    expect = K.spatial_jacobian(th, geom).T @ Fs
    np.testing.assert_allclose(model.load_torques(th, np.concatenate([f, tau])), expect, atol=1e-14)
    np.testing.assert_allclose(model.load_torques(th, [f[0], f[2], tau[1]]), expect, atol=1e-14)
    # out-of-plane parts (F1..F3 of Sec. III) produce no torque
    np.testing.assert_allclose(model.load_torques(th, [0, 1.0, 0, 1.0, 0, 1.0]), 0.0, atol=1e-15)


def test_eq10_residual_jacobian_fd(geom, rng):
    """The analytic ∂G/∂θ (spring, exact cable Hessian, P K_c P^T, load Hessian) equals finite differences."""
    th = rng.uniform(-0.12, 0.12, 27)
    h = 1e-7
    for m in (S.QuasiStaticModel(geom, coupling="exact", load_offset=1.5e-3),
              S.QuasiStaticModel(geom, coupling="simple", cable_law=S.CableLaw.quadratic(5e8))):
        for kw in ({"tensions": [3.0, 0.5], "tip_load": [0.4, -0.3, 0.02]},
                   {"positions": [3e-5, 2e-5], "tip_load": [0.1, 0.2, -0.01]}):
            J = m.residual_jacobian(th, **kw)
            fd = np.stack([(m.residual(th + h * e, **kw) - m.residual(th - h * e, **kw)) / (2 * h)
                           for e in np.eye(27)], axis=1)
            np.testing.assert_allclose(J, fd, atol=2e-7 * np.abs(J).max())
            np.testing.assert_allclose(J, J.T, atol=1e-12)   # a potential: symmetric


# ---------------------------------------------------------------- Eqs. (11)-(12)
@pytest.mark.parametrize("T", [(0.5, 0.0), (1.2, 0.45), (0.45, 2.0), (0.0, 1.9)])
def test_eq12_constant_curvature_equals_solver(geom, model, T):
    """Eqs. (11)-(12): linear range, no tip load: θ_i = (r_x/k1)(T_R - T_L) = the solver's equilibrium."""
    cc = S.constant_curvature(geom, T)
    assert abs(cc.theta) <= 0.135                       # linear range of Fig. 7
    eq = S.equilibrium(model, tensions=T)
    np.testing.assert_allclose(eq.theta, cc.theta, rtol=0, atol=1e-9)
    assert cc.theta == pytest.approx(-(geom.r_x / 0.36) * (T[1] - T[0]), abs=1e-15)
    assert cc.curvature == pytest.approx(geom.r_x * abs(T[1] - T[0]) / (geom.p * 0.36), rel=1e-12)
    # the joint axes lie on a circle (chord p, turning θ per joint): radius p / (2 sin(θ/2)),
    # which Eq. (12)'s R = p/θ approximates to relative order θ²/24
    if cc.theta:
        q = K.joint_positions(eq.theta, geom.p)
        a, b, c = q[0], q[13], q[26]
        area2 = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        kappa = 2 * area2 / (np.linalg.norm(b - a) * np.linalg.norm(c - b) * np.linalg.norm(c - a))
        assert kappa == pytest.approx(2 * np.sin(abs(cc.theta) / 2) / geom.p, rel=1e-9)
        assert kappa == pytest.approx(cc.curvature, rel=cc.theta ** 2 / 20)


def test_eq11_beyond_linear_range(geom, model):
    """Eq. (11) with the dual-rate spring: θ_i = τ^{-1}(r_x (T_R - T_L)) past θ_thresh."""
    T = (25.0, 0.5)
    cc = S.constant_curvature(geom, T, spring=model.spring)
    assert cc.theta > 0.135
    np.testing.assert_allclose(S.equilibrium(model, tensions=T).theta, cc.theta, atol=1e-12)
    np.testing.assert_allclose(S.simulate(model, (0, 3.0), tensions=T).final, cc.theta, atol=1e-9)


def test_swapping_tensions_mirrors_theta(geom, model):
    """Mirror symmetry: swapping (T_R, T_L) negates θ (exactly with Eq. 5; the exact lengths pair
    the joints differently for the two cables, so there it holds to 1e-4 rad)."""
    for T in ([2.0, 0.45], [30.0, 1.0]):
        a = S.equilibrium(model, tensions=T, tip_load=[0, 0.1, 0]).theta
        b = S.equilibrium(model, tensions=T[::-1], tip_load=[0, 0.1, 0]).theta
        np.testing.assert_allclose(a, -b, atol=1e-12)
    mx = S.QuasiStaticModel(geom, coupling="exact")
    a = S.equilibrium(mx, tensions=[2.0, 0.45]).theta
    b = S.equilibrium(mx, tensions=[0.45, 2.0]).theta
    assert np.abs(a + b).max() < 1e-4
    assert np.abs(a + b).max() > 0      # the asymmetry is real, and small


# ---------------------------------------------------------------- Eqs. (13)-(14)
def test_eq13_14_cable_positions_linear(geom, model):
    """Eqs. (13)-(14), linear cables (simple P): θ = r_x k_c (u_R - u_L) / (k1 + 2 n r_x² k_c)."""
    kc, rx = geom.cable_stiffness, geom.r_x
    u = np.array([4e-5, 1e-5])
    eq = S.equilibrium(model, positions=u)
    theta = rx * kc * (u[0] - u[1]) / (0.36 + 2 * 27 * rx ** 2 * kc)
    np.testing.assert_allclose(eq.theta, theta, atol=1e-12)
    d = model.elongation(eq.theta, u)
    np.testing.assert_allclose(d, C.cable_lengths(eq.theta, geom, "simple") - geom.cable_L0 + u)
    np.testing.assert_allclose(model.tensions_from_positions(eq.theta, u), kc * d)
    # both cables stay taut here; the same tensions as a tension input give the same shape
    T = model.tensions_from_positions(eq.theta, u)
    assert np.all(T > 0)
    np.testing.assert_allclose(S.equilibrium(model, tensions=T).theta, eq.theta, atol=1e-12)


def test_eq14_slack_cable_carries_no_tension(geom, model):
    """A cable cannot push: d ≤ 0 gives T = 0 (slack), for both laws."""
    for law in (S.CableLaw.linear(geom), S.CableLaw.quadratic(1e9)):
        np.testing.assert_array_equal(law.tension([-1e-4, 0.0]), [0.0, 0.0])
        np.testing.assert_array_equal(law.stiffness([-1e-4]), [0.0])
    eq = S.equilibrium(model, positions=[3e-5, -1e-3])     # left cable slack
    T = model.tensions_from_positions(eq.theta, [3e-5, -1e-3])
    assert T[1] == 0.0 and T[0] > 0
    np.testing.assert_allclose(eq.theta, geom.r_x * T[0] / 0.36, atol=1e-12)


def test_eq10_integration_agrees_with_solver_at_rest(geom):
    """Integrating Eq. (10) to rest and the direct solver reach the same θ (positions + tip load)."""
    m = S.QuasiStaticModel(geom, coupling="exact", cable_law=S.CableLaw.quadratic(2e9))
    u = S.Schedule([0.0, 1.0], [[0.0, 0.0], [6e-5, 2e-5]])
    F = S.Schedule([0.0, 0.5, 1.0], [[0, 0, 0], [0, 0, 0], [-0.2, -0.1, 0.0]])
    tr = S.simulate(m, (0.0, 4.0), positions=u, tip_load=F)
    assert tr.success and tr.rate < 1e-9
    eq = S.equilibrium(m, positions=u(4.0), tip_load=F(4.0))
    assert eq.success
    np.testing.assert_allclose(tr.final, eq.theta, atol=1e-9)
    assert np.ptp(eq.theta) > 1e-3          # not constant curvature: the tip force matters


# ---------------------------------------------------------------- Fig. 8
def test_fig8_path_dependence(geom, model):
    """Fig. 8: moment then force (A) and force then moment (B) end in different stable equilibria.

    4 N toward +x and 0.05 N m toward -x at the tip, Fig. 7 spring: A curls the
    chain against its stops (tip angle -3.754 rad, tip at (-15.3, -6.2) mm), B
    ends at +0.148 rad with the tip at (19.3, 25.1) mm: max |Δθ| = 0.273 rad,
    tips 46.7 mm apart.
    """
    r = S.path_dependence(model)
    assert r.a.rate < 1e-8 and r.b.rate < 1e-8                 # both at rest
    assert r.max_dtheta == pytest.approx(0.2728, abs=2e-3)
    assert r.tip_distance == pytest.approx(46.65e-3, abs=0.2e-3)
    assert r.tip_a[2] == pytest.approx(-3.754, abs=5e-3)
    assert r.tip_b[2] == pytest.approx(0.148, abs=5e-3)
    for tr in (r.a, r.b):          # both are stable equilibria of the same final load
        eq = S.equilibrium(model, tip_load=r.load, theta0=tr.final)
        np.testing.assert_allclose(eq.theta, tr.final, atol=1e-8)
        assert np.linalg.eigvalsh(model.residual_jacobian(eq.theta, tip_load=r.load)).min() > 0
    # same loads applied together from θ = 0 pick one of them: the order matters, not the loads
    assert r.a.t[-1] == r.b.t[-1]


# ---------------------------------------------------------------- stiffness (Sec. III-C)
def _state(model, u):
    eq = S.equilibrium(model, positions=u)
    d = model.elongation(eq.theta, u)
    Km = S.joint_stiffness(model, eq.theta, model.cable_law.stiffness(d))
    return eq.theta, Km, K.planar_jacobian(eq.theta, model.geom), d


def test_eq22_23_24_25_workspace_stiffness(geom, model, rng):
    """Eq. (23) K_w equals the Lagrange solution of Eq. (22); Eq. (24) δθ reproduces Eq. (25) energy."""
    th0, Km, J, _ = _state(model, [6e-5, 1e-5])
    Kw = S.workspace_stiffness(Km, J)
    Kw_l, D = S.workspace_stiffness_lagrange(Km, J)
    np.testing.assert_allclose(Kw, Kw_l, rtol=1e-8, atol=1e-10 * np.abs(Kw).max())
    np.testing.assert_allclose(Kw, Kw.T, rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(Kw) > 0)
    scale = np.array([1e-5, 1e-5, 1e-3])
    for _ in range(5):
        dX = rng.normal(size=3) * scale
        dth = S.joint_displacement(Km, J, dX)
        np.testing.assert_allclose(dth, D @ dX, atol=1e-15)
        np.testing.assert_allclose(J @ dth, dX, atol=1e-14)              # the constraint of Eq. (22)
        V = 0.5 * dth @ Km @ dth                                          # Eq. (21)
        assert V == pytest.approx(0.5 * dX @ Kw @ dX, rel=1e-9)           # Eq. (25)
        # δθ is the minimum: moving along the nullspace of J_X costs energy
        N = np.linalg.svd(J)[2][3:]
        for v in rng.normal(size=(3, 24)) @ N:
            v = 1e-4 * v / np.linalg.norm(v)
            assert 0.5 * (dth + v) @ Km @ (dth + v) > V
        # the reaction force (Eq. 26) is K_w δX and equals -λ of Eq. (22)
        n = 27
        A = np.block([[Km, J.T], [J, np.zeros((3, 3))]])
        sol = np.linalg.solve(A, np.concatenate([np.zeros(n), dX]))
        np.testing.assert_allclose(-sol[n:], Kw @ dX, rtol=1e-7, atol=1e-12)


def test_sec3c3_linear_cables_stiffness_independent_of_tension(geom, model):
    """Sec. III-C3: with linear cables, pretensioning both cables changes neither θ0 nor K_w."""
    base = np.array([6e-5, 1e-5])
    out = []
    for pre in (0.0, 2e-5, 1e-4):
        th0, Km, J, d = _state(model, base + pre)
        out.append((th0, S.workspace_stiffness(Km, J), model.cable_law.tension(d)))
    for th0, Kw, T in out[1:]:
        np.testing.assert_allclose(th0, out[0][0], atol=1e-13)
        np.testing.assert_allclose(Kw, out[0][1], rtol=1e-9)
        assert T.sum() > out[0][2].sum() + 1.0           # the tensions did change (by >1 N)


def test_sec3c3_quadratic_cables_change_only_kphiphi(geom):
    """Sec. III-C3: T = K d², K_c = diag(2 K d): more counter-tension at the same θ0 raises only k_φφ,
    by exactly Δ(r_x² (k_R + k_L)): x-z translations at constant φ lie in the nullspace of P K_c P^T."""
    law = S.CableLaw.quadratic(1e9)     # 1 N at 31.6 µm elongation
    model = S.QuasiStaticModel(geom, cable_law=law)
    L0 = model.rest_lengths
    dT = 1.5                                               # T_R - T_L fixes θ0 ...
    th_cc = S.constant_curvature(geom, [dT, 0.0], spring=model.spring).theta
    res = []
    for TL in (0.2, 2.0, 8.0):                             # ... at several counter-tensions
        d = np.sqrt(np.array([TL + dT, TL]) / law.coefficient)
        u = d - C.cable_lengths(np.full(27, th_cc), geom, "simple") + L0
        th0, Km, J, d_eq = _state(model, u)
        np.testing.assert_allclose(th0, th_cc, atol=1e-12)
        res.append((S.workspace_stiffness(Km, J), law.stiffness(d_eq)))
    Kw0, kc0 = res[0]
    for Kw, kc in res[1:]:
        dK = Kw - Kw0
        expect = geom.r_x ** 2 * (kc.sum() - kc0.sum())
        assert dK[2, 2] == pytest.approx(expect, rel=1e-6)
        assert dK[2, 2] > 0.1 * Kw0[2, 2]                   # a real change in k_φφ ...
        mask = np.ones((3, 3), bool)
        mask[2, 2] = False
        np.testing.assert_allclose(dK[mask], 0.0, atol=1e-8 * np.abs(Kw0).max())  # ... and only there


# ---------------------------------------------------------------- FEA cross-check (Sec. III-D)
def test_sec3d_fea_reference_file():
    ref = load_fea_reference()
    assert ref.n_joints == 4 and ref.E == 60e9 and ref.nu == 0.3
    np.testing.assert_array_equal(ref.theta_moment, [0.129] * 4)
    np.testing.assert_array_equal(ref.theta_transverse, [0.096, 0.074, 0.053, 0.032])
    assert ref.moment == 0.1 and ref.transverse_force == 10.0
    assert ref.axial_max_displacement == pytest.approx(0.015e-3)
    assert "III-D" in ref.source


def test_sec3d_fea_moment_equal_angles_and_stiffness():
    """A pure moment loads every joint equally (equal angles, as the FEA); k = 0.1/0.129 = 0.775 N m/rad."""
    ref = load_fea_reference()
    k = S.equivalent_stiffness_moment(ref.moment, ref.theta_moment)
    assert k == pytest.approx(0.7752, abs=1e-4)
    g4 = Geometry(n_joints=4)
    th = S.equilibrium(S.QuasiStaticModel(g4, spring=linear_spring(k)), tip_load=[0, 0, ref.moment]).theta
    np.testing.assert_allclose(th, ref.theta_moment, atol=1e-12)
    # a pure moment is the same as a cable tension difference (Sec. III): T_R - T_L = M / r_x
    th_c = S.equilibrium(S.QuasiStaticModel(g4, spring=linear_spring(k)),
                         tensions=[ref.moment / g4.r_x, 0.0]).theta
    np.testing.assert_allclose(th_c, th, atol=1e-12)


def test_sec3d_fea_transverse_ratios_and_lever_arm():
    """A transverse tip load gives angles decreasing linearly toward the tip.

    FEA: 0.096 : 0.074 : 0.053 : 0.032 = 3.0 : 2.31 : 1.66 : 1, equal steps (0.022, 0.021, 0.021)
    but not 4 : 3 : 2 : 1. The linear fit θ_j = (F/k)(z_F - (j-1)p) gives k = F p / step =
    0.568 N m/rad and the load point z_F = 5.44 mm = 4.49 p above joint 1, i.e. 1.49 p beyond
    joint 4 (0.49 p beyond the tip face at 4 p). With the load at the tip face the model gives
    4.03 : 3.02 : 2.00 : 1; with the FEA's lever arm it gives 3.04 : 2.36 : 1.67 : 1, within
    0.0024 rad of every FEA angle (the rest is the large-deflection shortening of the lever).
    """
    ref = load_fea_reference()
    g4 = Geometry(n_joints=4)
    fea = ref.theta_transverse
    steps = -np.diff(fea)
    assert np.ptp(steps) <= 0.0011 and np.all(steps > 0)            # linear within the 3-digit data
    k, zF = S.equivalent_stiffness_transverse(ref.transverse_force, fea, g4.p)
    assert k == pytest.approx(0.568, abs=1e-3)
    assert zF / g4.p == pytest.approx(4.49, abs=0.01)
    tip = S.equilibrium(S.QuasiStaticModel(g4, spring=linear_spring(k)),
                        tip_load=[ref.transverse_force, 0, 0]).theta
    np.testing.assert_allclose(tip / tip[-1], [4.03, 3.02, 2.00, 1.0], atol=0.01)
    assert np.all(np.abs(tip / tip[-1] - fea / fea[-1]) >= [0.9, 0.6, 0.3, 0.0])
    lev = S.equilibrium(S.QuasiStaticModel(g4, spring=linear_spring(k), load_offset=zF - g4.tip_z),
                        tip_load=[ref.transverse_force, 0, 0]).theta
    np.testing.assert_allclose(lev / lev[-1], fea / fea[-1], atol=0.05)
    np.testing.assert_allclose(lev, fea, atol=0.0025)
    assert np.ptp(-np.diff(lev)) < 0.001                             # the model's steps are equal too
    # Table I style, per joint, torque / angle with tip-face lever arms (4p, 3p, 2p, p)
    kj = ref.transverse_force * g4.p * np.arange(4, 0, -1) / fea
    np.testing.assert_allclose(kj, [0.504, 0.491, 0.457, 0.378], atol=1e-3)


# ---------------------------------------------------------------- bad input
def test_bad_input(geom, model):
    with pytest.raises(ValueError, match="singular"):        # Eq. (23) at θ = 0: J_z = 0
        S.workspace_stiffness(0.36 * np.eye(27), K.planar_jacobian(np.zeros(27), geom))
    with pytest.raises(ValueError, match="singular"):
        S.workspace_stiffness_lagrange(0.36 * np.eye(27), K.planar_jacobian(np.zeros(27), geom))
    J = K.planar_jacobian(np.full(27, 0.05), geom)
    with pytest.raises(ValueError, match="positive definite"):
        S.workspace_stiffness(-np.eye(27), J)
    with pytest.raises(ValueError, match="push"):
        S.equilibrium(model, tensions=[1.0, -0.5])
    with pytest.raises(ValueError, match="push"):
        S.simulate(model, (0, 1), tensions=S.Schedule([0, 1], [[0, 0], [-1, 0]]))
    with pytest.raises(ValueError, match="push"):
        S.constant_curvature(geom, [-1.0, 0.0])
    with pytest.raises(ValueError, match="NaN"):
        S.equilibrium(model, tip_load=[np.nan, 0, 0])
    with pytest.raises(ValueError, match="NaN"):
        S.simulate(model, (0, 1), tip_load=[0, 0, np.nan])
    with pytest.raises(ValueError, match="NaN"):
        S.equilibrium(model, positions=[np.nan, 0.0])
    with pytest.raises(ValueError, match="not both"):
        S.equilibrium(model, tensions=[1, 0], positions=[0, 0])
    with pytest.raises(ValueError, match="increasing"):
        S.Schedule([0, 0], [[0, 0], [1, 1]])
    with pytest.raises(ValueError, match="t1 > t0"):
        S.simulate(model, (1.0, 0.0))
    with pytest.raises(ValueError, match="tip load"):
        S.equilibrium(model, tip_load=[1.0, 2.0])
    with pytest.raises(ValueError, match="damping"):
        S.QuasiStaticModel(geom, damping=0.0)
    with pytest.raises(ValueError):
        S.CableLaw("cubic", 1.0)
