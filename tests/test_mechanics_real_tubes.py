"""Mechanics of real tubes (issue 14, docs/models.md "Real tubes: mechanics").

Closed forms used here and their sources:

* linear notch rate ``k_j = E I_j / h_j``: Euler–Bernoulli moment–curvature
  ``M = E I κ`` with ``κ = θ/h`` for a notch of height ``h`` bending as an arc
  (Gere & Timoshenko, Mechanics of Materials; York et al., ICRA 2015);
  ``I_j`` from the circular-segment closed forms of :mod:`notchfit.physics.section`
  (Roark, Table A.1; tested against quadrature in tests/test_section.py);
* outer-fibre strain ``ε = c θ / h`` (the same arc);
* capstan equation ``T_2 = T_1 e^{-μ φ}`` for a cord sliding over a wrap ``φ``
  (Euler–Eytelwein);
* μ = 0 rest state ``τ_j(θ_j - θ0_j) = a_j T`` (docs/models.md invariant, with
  per-joint arms and rest angles).
"""

from __future__ import annotations

import numpy as np
import pytest

from notchfit.physics import _friction_kernels as K
from notchfit.physics import statics
from notchfit.physics.friction import DEFAULT_DAMPING_TIME, FrictionParams, clip_load_cell, simulate
from notchfit.io import load_params, params_from_mapping, params_to_mapping, save_params
from notchfit.physics.geometry import default_geometry
from notchfit.io import datasets_dir, load_geometry
from notchfit.physics.protocols import bend_unbend
from notchfit.physics.springs import material_spring

E_LIN, E_SE = 40e9, 4e9


@pytest.fixture(scope="module")
def wrist():
    return _geom("wrist_asymmetric")


@pytest.fixture(scope="module")
def tip_first():
    return _geom("wrist_tip_first")


def _geom(name):
    return load_geometry(datasets_dir() / "geometry" / f"{name}.toml")


def _steps(values, dt=5.0):
    """A right-tendon history of held steps (one sample per value)."""
    v = np.asarray(values, dtype=float)
    return np.arange(1, v.size + 1) * dt, v


# ----------------------------------------------------------------------------- springs
def test_material_spring_linear_rate_plateau_and_stop(tip_first):
    g = tip_first
    sp = material_spring(g, E_LIN, E_SE, 0.015)
    sec = g.section
    h = g.slot_widths
    k = E_LIN * sec.second_moment / h                      # k_j = E I_j / h_j
    np.testing.assert_allclose(sp.stiffness(np.full(4, 1e-4)), k, rtol=1e-15)
    c = np.maximum(sec.back_fibre, sec.cut_fibre)
    np.testing.assert_allclose(sp.breaks[:, 0], 0.015 * h / c, rtol=1e-15)   # ε = c θ / h = ε_lower
    np.testing.assert_allclose(sp.breaks[:, 1], g.closure_angles - g.rest_angles, rtol=1e-15)
    mid = 0.5 * (sp.breaks[:, 0] + sp.breaks[:, 1])
    np.testing.assert_allclose(sp.stiffness(mid), E_SE * sec.second_moment / h, rtol=1e-15)
    np.testing.assert_allclose(sp.stiffness(sp.breaks[:, 1] + 1e-3), sp.rates[:, 2])
    assert np.all(sp.rates[:, 2] > 10 * k)                 # the stop


def test_material_spring_continuity_and_limits(wrist):
    sp = material_spring(wrist, E_LIN, E_SE, 0.015)
    for j in range(2):
        b = sp.breaks[:, j]
        lo, hi = sp.torque(b * (1 - 1e-12)), sp.torque(b * (1 + 1e-12))
        np.testing.assert_allclose(lo, hi, rtol=1e-9)      # continuous at each break
    th = np.linspace(-0.6, 0.6, 241)[:, None] * np.ones(5)
    np.testing.assert_array_equal(sp.torque(-th), -sp.torque(th))
    np.testing.assert_allclose(sp.angle(sp.torque(th)), th, atol=1e-13)
    # E_se = E_lin: linear up to closure; a threshold beyond closure: no plateau piece
    same = material_spring(wrist, E_LIN, E_LIN, 0.015)
    x = 0.9 * same.breaks[:, 1]
    np.testing.assert_allclose(same.torque(x), same.rates[:, 0] * x, rtol=1e-14)
    late = material_spring(wrist, E_LIN, E_SE, 0.5)
    np.testing.assert_array_equal(late.breaks[:, 0], late.breaks[:, 1])
    np.testing.assert_allclose(late.torque(late.breaks[:, 1] + 0.01),
                               late.rates[:, 0] * late.breaks[:, 1] + late.rates[:, 2] * 0.01, rtol=1e-14)
    with pytest.raises(ValueError, match="E_se"):
        material_spring(wrist, E_LIN, 0.0, 0.015)


def test_damping_time_reproduces_the_seed_b_exactly():
    assert DEFAULT_DAMPING_TIME * 0.4829 == 0.03
    p = FrictionParams(damping_time=DEFAULT_DAMPING_TIME)
    np.testing.assert_array_equal(p.joint_damping(p.joint_spring(_seed())), np.full(27, 0.03))
    np.testing.assert_array_equal(FrictionParams().joint_damping(FrictionParams().joint_spring(_seed())),
                                  np.full(27, 0.03))
    q = FrictionParams(spring_law="material")
    g = _geom("wrist_tip_first")
    sp = q.joint_spring(g)
    np.testing.assert_allclose(q.joint_damping(sp), DEFAULT_DAMPING_TIME * sp.rates[:, 0], rtol=1e-15)


def _seed():
    return default_geometry()


# ----------------------------------------------------------------------------- μ = 0, linear range
@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
@pytest.mark.parametrize("law", ["channel", "capstan"])
def test_frictionless_linear_equilibrium_closed_form(name, law):
    """θ_j = θ0_j + T a_j h_j / (E I_j) (μ = 0, linear range): both solvers and the statics."""
    g = _geom(name)
    p = FrictionParams(spring_law="material", friction_law=law, mu_d=0.0, mu_s=0.0, E_lin=E_LIN, E_se=E_SE)
    t, T = _steps([0.1, 0.3, 0.45, 0.2, 0.0])
    expect = g.rest_angles + T[:, None] * g.moment_arms(+1) * g.slot_widths / (E_LIN * g.section.second_moment)
    sp = p.joint_spring(g)
    assert np.all(np.abs(expect - g.rest_angles) < sp.breaks[:, 0])     # linear range
    for method in ("fast", "reference"):
        th = simulate(t, None, T, p, g, method=method).theta
        np.testing.assert_allclose(th, expect, rtol=0, atol=1e-9, err_msg=method)
    model = statics.QuasiStaticModel(g, spring=sp)
    for k, Tk in enumerate(T):
        eq = statics.equilibrium(model, tensions=(Tk, 0.0), theta0=g.rest_angles)
        assert eq.success
        np.testing.assert_allclose(eq.theta, expect[k], rtol=0, atol=1e-9)


def test_statics_rejects_a_missing_tendons_tension(wrist):
    model = statics.QuasiStaticModel(wrist, spring=FrictionParams(spring_law="material").joint_spring(wrist))
    with pytest.raises(ValueError, match="no left tendon"):
        model.residual(np.zeros(5), tensions=(0.2, 0.1))


# ----------------------------------------------------------------------------- capstan law
def test_capstan_full_sliding_tension_ratio(wrist):
    """Full sliding toward the base: T[j+1] = T[j] e^{-μ (|θ_j| + |θ_{j+1}|)/2} per link (the
    tendon wraps half of each notch's angle at each cut edge), so from the load cell, through
    the first notch's proximal edge (half of |θ_1|), to the anchor beyond the last notch's distal
    edge (half of |θ_n|), T_anchor / T_base = e^{-μ Σ|θ|} (capstan equation), in both solvers'
    propagation to 1e-9."""
    mu = 0.3
    rng = np.random.default_rng(14)
    p = FrictionParams(spring_law="material", friction_law="capstan", mu_d=mu, mu_s=mu)
    J = p.joint_table(wrist)
    par = p.packed(wrist, J)
    n = wrist.n_joints
    for _ in range(5):
        th = rng.uniform(-0.5, 0.5, n)
        a = np.abs(th)
        # reference solver's slide law, link by link
        T = [2.0]
        for i in range(n - 1):
            T.append(K.slide_law(T[-1], a[i], a[i + 1], mu, 1, K.LAW_CAPSTAN))
        # fast solver's propagation at a frozen configuration
        G = np.zeros((7, n))
        K._geometry_terms(th, par, J, G)
        TL, TR, F, thd = (np.zeros(n) for _ in range(4))
        v, vL = np.zeros(n - 1), np.zeros(n - 1)
        slide = np.ones(n - 1, np.int8)
        K._forces(TL, TR, slide * 0, slide, 0.0, 2.0, par, J, 1.0 / J[K.J_B], G, F, thd, v, vL, th, np.zeros(n))
        for prof in (np.array(T), TR):
            anchor_over_base = prof[-1] / prof[0] * np.exp(-mu * 0.5 * (a[0] + a[-1]))
            assert anchor_over_base == pytest.approx(np.exp(-mu * a.sum()), abs=1e-9)


def test_capstan_rest_state_after_loading_sits_at_the_sliding_bound(wrist):
    """After each loading step every link slid toward the base and stuck at the capstan bound
    (a tiny v_thr so that the links stick only once the joints are at rest)."""
    mu = 0.2
    p = FrictionParams(spring_law="material", friction_law="capstan", mu_d=mu, mu_s=mu, v_thr=1e-12)
    t, T = _steps([0.2, 0.4, 0.6, 0.8])
    for method in ("fast", "reference"):
        r = simulate(t, None, T, p, wrist, method=method)
        assert np.all(r.state_right == 1)
        a, Tr = np.abs(r.theta), r.tension_right
        link = np.exp(-mu * 0.5 * (a[:, :-1] + a[:, 1:]))
        np.testing.assert_allclose(Tr[:, 1:] / Tr[:, :-1], link, rtol=0, atol=1e-6, err_msg=method)


def test_capstan_and_channel_agree_without_friction(wrist):
    t, T = _steps([0.3, 0.6, 0.2])
    a = simulate(t, None, T, FrictionParams(spring_law="material", mu_d=0.0, mu_s=0.0), wrist)
    b = simulate(t, None, T, FrictionParams(spring_law="material", mu_d=0.0, mu_s=0.0, friction_law="capstan"), wrist)
    np.testing.assert_array_equal(a.theta, b.theta)


# ----------------------------------------------------------------------------- solvers agree
@pytest.mark.parametrize("law", ["channel", "capstan"])
def test_fast_and_reference_agree_on_a_16mm_wrist(wrist, law):
    p = FrictionParams(spring_law="material", friction_law=law, mu_d=0.15, mu_s=0.16)
    t, tl, tr, _ = bend_unbend(1.2, 0.0, pull="right")
    f = simulate(t, None, tr, p, wrist).theta
    r = simulate(t, None, tr, p, wrist, method="reference").theta
    assert np.abs(f - r).max() <= 1e-3
    assert np.abs(f - wrist.rest_angles).max() > 0.05      # it bends


def test_fast_and_reference_agree_on_the_seed_tube():
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    f = simulate(t, tl, tr).theta
    r = simulate(t, tl, tr, method="reference").theta
    assert np.abs(f - r).max() <= 1e-3


def test_rates_law_on_a_wrist_with_a_time_constant(tip_first):
    """Per-joint rates (the paper's law) on a 1.6 mm wrist: with the absolute seed b the joints
    need tens of seconds to settle; as a time constant both solvers agree."""
    k = (0.012, 0.009, 0.006, 0.004)
    p = FrictionParams(k_lin=k, k_mid=tuple(0.5 * x for x in k), k_stop=tuple(20 * x for x in k),
                       theta_mid=0.2, theta_stop=0.3, mu_d=0.15, mu_s=0.16, damping_time=DEFAULT_DAMPING_TIME)
    t, tl, tr, _ = bend_unbend(0.6, 0.0, pull="right")
    f = simulate(t, None, tr, p, tip_first).theta
    r = simulate(t, None, tr, p, tip_first, method="reference").theta
    assert np.abs(f - r).max() <= 1e-3


# ----------------------------------------------------------------------------- per-joint = scalar
def test_per_joint_arrays_with_equal_values_reproduce_the_scalar_results_exactly():
    n = 27
    scalar = FrictionParams(stiffness_gradient=0.2, hysteresis_torque=1e-3)
    arrays = FrictionParams(k_lin=(scalar.k_lin,) * n, k_mid=(scalar.k_mid,) * n, k_stop=(scalar.k_stop,) * n,
                            theta_mid=(scalar.theta_mid,) * n, theta_stop=(scalar.theta_stop,) * n,
                            stiffness_gradient=0.2, hysteresis_torque=1e-3)
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=6, n_down=6)
    for method in ("fast", "reference"):
        a = simulate(t, tl, tr, scalar, method=method)
        b = simulate(t, tl, tr, arrays, method=method)
        np.testing.assert_array_equal(a.theta, b.theta)
        np.testing.assert_array_equal(a.tension_left, b.tension_left)
    g = _seed()
    tuples = g.replace(slot_width=(g.slot_width,) * n, slot_depth=(g.slot_depth,) * n, rest_angle=(0.0,) * n,
                       p=(g.p,) * (n - 1))
    np.testing.assert_array_equal(simulate(t, tl, tr, geom=tuples).theta, simulate(t, tl, tr).theta)


def test_per_joint_lengths_must_match(wrist):
    with pytest.raises(ValueError, match="one length"):
        FrictionParams(k_lin=(0.1, 0.2), k_mid=(0.1, 0.1, 0.1))
    with pytest.raises(ValueError, match="5"):
        simulate([5.0], None, [0.1], FrictionParams(k_lin=(0.5,) * 27), wrist)


# ----------------------------------------------------------------------------- one tendon, load cells
def test_one_tendon(wrist):
    t, T = _steps([0.2, 0.4])
    p = FrictionParams(spring_law="material")
    a = simulate(t, None, T, p, wrist)
    b = simulate(t, np.zeros(2), T, p, wrist)
    np.testing.assert_array_equal(a.theta, b.theta)
    assert np.all(a.tension_left == 0)
    with pytest.raises(ValueError, match="no left tendon"):
        simulate(t, [0.0, 0.1], T, p, wrist)
    with pytest.raises(ValueError, match="right tendon"):
        simulate(t, None, None, p, wrist)


def test_load_cell_offsets_clipped_down_to_three_sigma():
    x, n = clip_load_cell([0.2, -0.004, -0.15, 0.0], sigma=0.05)
    np.testing.assert_array_equal(x, [0.2, 0.0, 0.0, 0.0])
    assert n == 2
    with pytest.raises(ValueError, match="sample index 1"):
        clip_load_cell([0.2, -0.16], sigma=0.05)
    t, tl, tr, _ = bend_unbend(20.0, 0.45, n_up=4, n_down=4)
    tl2 = tl.copy()
    tl2[-1] = -0.005
    r = simulate(t, tr, tl2, tension_sigma=0.05)
    assert r.n_clipped == 1 and r.input_right[-1] == 0.0
    with pytest.raises(ValueError, match="tension_right must be >= 0"):
        simulate(t, tr, tl2)                               # no σ_T given: every reading >= 0
    tl2[-1] = -0.2
    with pytest.raises(ValueError, match="-0.15 N count as zero"):
        simulate(t, tr, tl2, tension_sigma=0.05)


# ----------------------------------------------------------------------------- model files
def test_model_mapping_round_trip():
    seed = params_to_mapping(FrictionParams())
    assert "spring_law" not in seed and "E_lin_Pa" not in seed and len(seed) == 14
    p = FrictionParams(spring_law="material", friction_law="capstan", E_lin=35e9, E_se=3e9, strain_lower=0.02,
                       damping_time=0.05, k_lin=(0.1, 0.2, 0.3), k_mid=0.05)
    m = params_to_mapping(p)
    assert m["k_lin_Nm_per_rad"] == [0.1, 0.2, 0.3] and m["spring_law"] == "material"
    assert params_from_mapping(m) == p
    with pytest.raises(ValueError, match="friction_law"):
        params_from_mapping({"friction_law": "rope"})


def test_model_file_round_trip(tmp_path):
    p = FrictionParams(spring_law="material", friction_law="capstan", E_lin=35e9, theta_mid=(0.05, 0.06))
    assert load_params(save_params(p, tmp_path / "m.toml")) == p


def test_default_model_follows_the_geometry(wrist):
    from notchfit.physics.friction import default_params
    assert default_params(default_geometry()) == FrictionParams()
    p = default_params(wrist)
    assert p.spring_law == "material" and p.friction_law == "capstan"
    t, T = _steps([0.3, 0.6])
    np.testing.assert_array_equal(simulate(t, None, T, geom=wrist).theta, simulate(t, None, T, p, wrist).theta)


# ----------------------------------------------------------------------------- tip load on real tubes
@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
def test_kernel_tip_torques_equal_the_kinematic_jacobian(name):
    """The kernels' J_X^T f (Eqs. 18-20 on the pivot chain: per-joint spacing, neutral-axis
    pivots, the tool point on the tip face) equals kinematics.joint_torques_from_tip_wrench."""
    from notchfit.physics.kinematics import joint_torques_from_tip_wrench

    g = _geom(name)
    J = FrictionParams(spring_law="material").joint_table(g)
    rng = np.random.default_rng(11)
    for _ in range(5):
        th = rng.uniform(-0.4, 0.4, g.n_joints)
        fx, fz = rng.uniform(-1.0, 1.0, 2)
        out = np.empty(g.n_joints)
        K.tip_torques(th, J[K.J_DX], J[K.J_DZ], fx, fz, out)
        np.testing.assert_allclose(out, joint_torques_from_tip_wrench(th, g, fx, fz), rtol=1e-12, atol=1e-16)


@pytest.mark.parametrize("method", ["fast", "reference"])
def test_frictionless_tip_load_on_a_wrist_matches_the_statics(wrist, method):
    """μ = 0 with a tip force on a section backbone: the simulator's rest states are the
    quasi-static equilibria of Eq. (10) with J_st^T F (an independent Newton solve)."""
    fx, fz = 0.02, -0.01
    p = FrictionParams(spring_law="material", friction_law="capstan", mu_d=0.0, mu_s=0.0, E_lin=E_LIN,
                       E_se=E_SE, tip_force_x=fx, tip_force_z=fz)
    t, T = _steps([0.0, 0.2, 0.5, 0.3, 0.0])
    th = simulate(t, None, T, p, wrist, method=method).theta
    model = statics.QuasiStaticModel(wrist, spring=p.joint_spring(wrist))
    prev = wrist.rest_angles
    for k, Tk in enumerate(T):
        eq = statics.equilibrium(model, tensions=(Tk, 0.0), tip_load=(fx, fz, 0.0), theta0=prev)
        assert eq.success
        prev = eq.theta
        np.testing.assert_allclose(th[k], eq.theta, rtol=0, atol=1e-6 if method == "reference" else 1e-9)
