"""Friction simulator (Sec. IV-B, Figs. 11, 15-19; models.md invariants)."""
import dataclasses
import math

import numpy as np
import pytest

from notchfit.physics import _friction_kernels as K
from notchfit.physics.friction import FrictionParams, SimulationResult, cable_displacement, simulate, simulation_table
from notchfit.physics.friction import stepwise_regimes as classify_regimes
from notchfit.physics.shapes import line_fit as shape_ab
from notchfit.physics.geometry import Geometry
from notchfit.io import load_params, save_params
from notchfit.physics.kinematics import joint_torques_from_tip_wrench
from notchfit.physics.protocols import bend_unbend, paper_protocols
from notchfit.physics.springs import friction_spring


def loop_area(load, tip):
    """Shoelace area of the closed tension-vs-tip-angle path [N rad]."""
    return 0.5 * abs(np.sum(load * np.roll(tip, -1) - np.roll(load, -1) * tip))


def same_grid_protocol(peak=25.0, counter=0.45, pull="left", n_up=13):
    """Up and down through the same tension values (so a friction-free loop has zero area)."""
    return bend_unbend(peak, counter, pull=pull, n_up=n_up, n_down=n_up - 1)


@pytest.fixture(scope="module")
def paper():
    """The Fig. 11 test (0.45 N counter-tension, left pulled) with both solvers."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45)
    return t, tl, tr, simulate(t, tl, tr), simulate(t, tl, tr, method="reference")


# ----------------------------------------------------------------------------- kernels
def test_fig17_kernel_spring_matches_springs_module():
    p = FrictionParams(k_mid=0.21, theta_mid=0.06, theta_stop=0.13)
    sp = p.spring()
    th = np.linspace(-0.3, 0.3, 1201)
    for s in (1.0, 0.7, 1.4):
        ref = sp.with_scale(s).torque(th)
        got = np.array([K.spring_torque(x, p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, s) for x in th])
        np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-16)
        back = np.array([K.spring_angle(y, p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, s) for y in ref])
        np.testing.assert_allclose(back, th, atol=1e-14)
        assert all(K.spring_torque(-x, p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, s)
                   == -K.spring_torque(x, p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, s) for x in th)


def test_eq18_20_kernel_tip_torques_match_kinematics(geom, rng):
    th = rng.normal(0, 0.08, geom.n_joints)
    out = np.zeros(geom.n_joints)
    J = FrictionParams().joint_table(geom)          # the seed chain: d = (0, p) for every joint
    np.testing.assert_array_equal(J[K.J_DZ], geom.p)
    assert not J[K.J_DX].any()
    K.tip_torques(th, J[K.J_DX], J[K.J_DZ], 0.7, -1.3, out)
    np.testing.assert_allclose(out, joint_torques_from_tip_wrench(th, geom, 0.7, -1.3), rtol=1e-12, atol=1e-16)


@pytest.mark.parametrize("th0,y", [(0.0, 0.02), (0.0, 0.06), (0.16, 0.0), (-0.1, 0.05), (0.03, -0.08),
                                   (0.12, 0.03)])
def test_relax_is_the_exact_piecewise_exponential(th0, y):
    """relax(θ0, y, h) vs a fine RK4 integration of b θ̇ = y - τ(θ), across the breaks."""
    p = FrictionParams()
    args = (p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, 1.0)
    f = lambda x: (y - K.spring_torque(x, *args)) / p.b  # noqa: E731
    x, dt = th0, 1e-5
    for i in range(1, 30001):
        k1 = f(x); k2 = f(x + dt / 2 * k1); k3 = f(x + dt / 2 * k2); k4 = f(x + dt * k3)  # noqa: E702
        x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if i in (3000, 10000, 30000):
            assert K.relax(th0, y, p.b, i * dt, *args) == pytest.approx(x, abs=2e-9)
    assert K.relax(th0, y, p.b, 1e3, *args) == pytest.approx(K.spring_angle(y, *args), abs=1e-15)


def test_slide_law_solves_the_implicit_tension_relation():
    """Step 1: T[j+1] = T[j] ∓ μ (T[j+1] sb + T[j] sa), solved exactly for T[j+1]."""
    for st in (1, -1):
        t1 = K.slide_next(7.0, 0.1, 0.13, 0.29, st)
        assert t1 == pytest.approx(7.0 - st * 0.29 * (t1 * 0.13 + 7.0 * 0.1), rel=1e-15)


# ----------------------------------------------------------------------------- invariants
@pytest.mark.parametrize("method", ["fast", "reference"])
def test_eq11_12_mu0_gives_constant_curvature_at_the_spring_equilibrium(method):
    """models.md: μ = 0 -> every rest state is θ_j = τ⁻¹(r_x ΔT) for all j (incl. the nonlinear range)."""
    p = FrictionParams(mu_d=0.0, mu_s=0.0)
    t, tl, tr, _ = bend_unbend(32.0, 0.45, n_up=7, n_down=6, interval=2.0)
    r = simulate(t, tl, tr, p, method=method)
    g = r.geom
    expect = p.spring().angle(g.r_x * (tr - tl))
    np.testing.assert_allclose(r.theta, np.repeat(expect[:, None], g.n_joints, axis=1), atol=1e-12)
    assert np.abs(expect).max() > 0.14  # reached the hard stop
    np.testing.assert_allclose(r.tension_left, np.repeat(tl[:, None], g.n_joints, axis=1), rtol=1e-14)


@pytest.mark.parametrize("method", ["fast", "reference"])
def test_mirror_symmetry_swapping_cables_negates_theta_bit_exact(method):
    t, tl, tr, _ = bend_unbend(28.0, 1.0, n_up=8, n_down=7, interval=2.0)
    for p in (FrictionParams(), FrictionParams(tip_force_x=0.2, tip_force_z=-0.3, hysteresis_torque=1e-3,
                                               proximal_beta=0.1, stiffness_gradient=0.2)):
        a = simulate(t, tl, tr, p, method=method)
        b = simulate(t, tr, tl, p.replace(tip_force_x=-p.tip_force_x), method=method)
        assert np.array_equal(b.theta, -a.theta)
        assert np.array_equal(b.tension_left, a.tension_right)
        assert np.array_equal(b.state_left, a.state_right)


def test_determinism_bit_identical_on_repeat(paper):
    t, tl, tr, fast, _ = paper
    again = simulate(t, tl, tr)
    for f in dataclasses.fields(SimulationResult):
        x, y = getattr(fast, f.name), getattr(again, f.name)
        if isinstance(x, np.ndarray):
            assert np.array_equal(x, y), f.name
    r1 = simulate(t[:8], tl[:8], tr[:8], method="reference")
    r2 = simulate(t[:8], tl[:8], tr[:8], method="reference")
    assert np.array_equal(r1.theta, r2.theta) and np.array_equal(r1.tension_left, r2.tension_left)


def test_regime_I_loading_bends_base_joints_more_than_tip_joints(paper):
    """models.md: base joints bend more while loading. For a pull toward negative θ that is b > 0
    (θ_1 most negative), not b < 0 as models.md writes: the sign of b is opposite to that of a."""
    t, tl, tr, fast, ref = paper
    for r in (fast, ref):
        load = r.regime == "I"
        big = load & (np.abs(r.a) > 0.01)
        assert big.sum() >= 15
        assert (r.a[big] < 0).all() and (r.b[big] > 0).all()
        assert (np.abs(r.theta[big, 0]) > np.abs(r.theta[big, 20])).all()
        # mirror image for the other pull direction
    m = simulate(t, tr, tl)
    assert (m.b[big] < 0).all() and (m.a[big] > 0).all()


def test_unloading_the_base_joints_move_first(paper):
    """Sec. IV-A / models.md: on unloading the base joints (most loaded) move before the tip joints."""
    t, tl, tr, fast, ref = paper
    for r in (fast, ref):
        k = int(np.argmax(tl))
        d = np.abs(r.theta[k + 4] - r.theta[k])
        assert d[0] > 0.01 and d[-5:].max() < 1e-9
        moved = np.abs(r.theta[k + 1:] - r.theta[k]) > 1e-4      # (samples, joints)
        first = np.where(moved.any(0), moved.argmax(0), 10 ** 6)  # first sample each joint moves
        assert (np.diff(first) >= 0).all()                        # base to tip, in order


def test_hysteresis_loop_area_is_measurable_and_grows_with_mu():
    """Tension vs tip angle (Fig. 18's hysteresis): zero area without friction, a measurable loop with it.

    The raw area grows with μ only while friction is small (0 -> 0.1); beyond that friction also
    cuts the tension reaching the distal joints, the peak bend shrinks and so does the raw area.
    The loop's area relative to its bounding box (peak tip angle × tension range) grows throughout.
    """
    t, tl, tr, _ = same_grid_protocol(n_up=10)
    load = tl - tr
    raw, rel = [], []
    for mu in (0.0, 0.02, 0.05, 0.1, 0.2, 0.29, 0.35):
        r = simulate(t, tl, tr, FrictionParams(mu_d=mu, mu_s=mu + 0.01 if mu else 0.0))
        tip = -r.tip_angle
        raw.append(loop_area(load, tip))
        rel.append(raw[-1] / (np.ptp(load) * tip.max()))
    assert raw[0] < 1e-9
    assert raw[1] > 1.0 and np.all(np.diff(raw[:4]) > 0.5)     # N rad; ~7.6 at the paper's μ_d
    assert np.all(np.diff(rel) > 0.002)
    assert raw[5] > 5.0


# ----------------------------------------------------------------------------- fast vs reference
@pytest.mark.parametrize("name", ["L020", "R020", "L045", "R045", "L150", "R150"])
def test_fast_solver_agrees_with_reference_within_1e3_rad(name):
    """Paper-like bend/unbend tests (three counter-tensions, both pulls): every joint, every sample."""
    t, tl, tr, _ = paper_protocols()[name]
    fast = simulate(t, tl, tr)
    ref = simulate(t, tl, tr, method="reference")
    assert np.abs(fast.theta - ref.theta).max() < 1e-3
    # a slip decision that flips at a marginal link moves its frozen tension by ~(μ_s - μ_d) N
    assert np.abs(fast.tension_left - ref.tension_left).max() < 0.15
    assert (fast.regime == ref.regime).all()


def test_fast_solver_agrees_with_reference_for_each_extension():
    """Within 1e-3 rad, except where a much larger static coefficient makes a release decision
    marginal: the rest state then jumps by ~(μ_s - μ_d) N r_x / k at that sample (the reference
    itself moves by 6e-4 rad there between dt = 1e-4 and 2.5e-5 s)."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=10, n_down=10)
    for kw, tol in ((dict(proximal_beta=0.3), 1e-3), (dict(mu_s=0.45), 2e-3), (dict(hysteresis_torque=2e-3), 1e-3),
                    (dict(tip_force_x=0.3, tip_force_z=-0.3), 1e-3), (dict(stiffness_gradient=0.3), 1e-3)):
        p = FrictionParams(**kw)
        d = np.abs(simulate(t, tl, tr, p).theta - simulate(t, tl, tr, p, method="reference").theta)
        assert d.max() < tol, (kw, d.max())
        assert np.quantile(d.max(axis=1), 0.9) < 2e-4, kw


# ----------------------------------------------------------------------------- extensions
def test_proximal_band_is_a_play_operator_that_widens_the_loop_and_delays_unloading():
    t, tl, tr, _ = same_grid_protocol(n_up=10)
    beta = 0.3
    base = simulate(t, tl, tr)
    r = simulate(t, tl, tr, FrictionParams(proximal_beta=beta))
    # play operator on log T, applied to the samples (the input is monotone between them)
    tb = np.empty_like(tl)
    x = tl[0]
    for k, m in enumerate(tl):
        x = min(max(x, m * math.exp(-beta)), m * math.exp(beta))
        tb[k] = x
    np.testing.assert_allclose(r.base_tension_left, tb, rtol=1e-15)
    np.testing.assert_allclose(r.base_tension_right, tr, rtol=1e-15)
    assert loop_area(tl - tr, -r.tip_angle) > 1.2 * loop_area(tl - tr, -base.tip_angle)
    assert (r.regime == "II").sum() > (base.regime == "II").sum()


def test_static_friction_widens_the_loop_and_delays_unloading():
    t, tl, tr, _ = same_grid_protocol(n_up=10)
    base = simulate(t, tl, tr)
    r = simulate(t, tl, tr, FrictionParams(mu_s=0.6))
    k = int(np.argmax(tl))
    # the shape holds longer: joints 2.. have moved less 3-4 samples into unloading (joint 1 sees
    # the base tension directly and moves alike in both). The effect is weak: μ_s only adds
    # (μ_s - μ_d) N_j at the release front, while the front's progress is set by 2 μ_d N per link.
    for j in (3, 4):
        moved = np.abs(r.theta[k + j, 1:] - r.theta[k, 1:]).sum()
        assert moved < np.abs(base.theta[k + j, 1:] - base.theta[k, 1:]).sum() - 1e-4
    assert loop_area(tl - tr, -r.tip_angle) > loop_area(tl - tr, -base.tip_angle)


@pytest.mark.parametrize("method", ["fast", "reference"])
def test_step4_static_coefficient_acts_only_at_break_away(method):
    """Sec. IV-B Step 4: μ_s enters only the stick -> slide test, and a link that slides
    comes to rest at |ΔT| = μ_d N. So (1) when every tension step exceeds (μ_s - μ_d) N,
    the loading rest states do not depend on μ_s at all; (2) a step smaller than
    (μ_s - μ_d) N_1 at the base link stalls the whole cable: no joint beyond the first
    moves (joint 1 sees the base tension directly). This is why a larger static
    coefficient is nearly invisible in sampled bend/unbend tests (docs/diagnosis.md)."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=6, n_down=5)
    k = int(np.argmax(tl))
    t, tl, tr = t[:k + 1], tl[:k + 1], tr[:k + 1]
    paper = simulate(t, tl, tr, FrictionParams(mu_s=0.30), method=method)
    sticky = simulate(t, tl, tr, FrictionParams(mu_s=0.49), method=method)
    T, th = paper.tension_left, paper.theta
    N = T[:, 1:] * np.abs(np.sin(th[:, 1:])) + T[:, :-1] * np.abs(np.sin(th[:, :-1]))
    assert np.diff(tl).min() > (0.49 - 0.29) * N.max()          # every step breaks every link
    np.testing.assert_array_equal(sticky.theta, paper.theta)     # (1)

    t2, tl2, tr2 = np.r_[t, t[-1] + 5.0], np.r_[tl, tl[-1] + 0.4], np.r_[tr, tr[-1]]
    assert 0.4 < (0.6 - 0.29) * N[-1, 0]                         # below the break-away excess
    moved = {mu_s: np.abs(np.diff(simulate(t2, tl2, tr2, FrictionParams(mu_s=mu_s), method=method)
                                  .theta[-2:], axis=0))[0] for mu_s in (0.30, 0.6)}
    assert moved[0.30][1:].max() > 1e-3                         # the paper's μ_s: the shape follows
    assert moved[0.6][1:].max() == 0.0                          # (2) stalled
    assert 0 < moved[0.6][0] < 2e-4


def test_joint_hysteresis_is_a_play_operator_with_a_residual_bend():
    """μ = 0: each joint follows θ_k = clamp(θ_{k-1}, τ⁻¹(F - h), τ⁻¹(F + h)) exactly."""
    h = 3e-3
    p = FrictionParams(mu_d=0.0, mu_s=0.0, hysteresis_torque=h)
    t, tl, tr, _ = bend_unbend(20.0, 0.45, n_up=6, n_down=5, interval=2.0)
    sp = p.spring()
    for method in ("fast", "reference"):
        r = simulate(t, tl, tr, p, method=method)
        x, exp = 0.0, []
        for F in r.geom.r_x * (tr - tl):
            x = min(max(x, sp.angle(F - h)), sp.angle(F + h))
            exp.append(x)
        np.testing.assert_allclose(r.theta[:, 5], exp, atol=1e-9)
        assert r.theta[-1, 0] == pytest.approx(-h / p.k_lin, abs=1e-9)  # residual at ΔT = 0
    r = simulate(t, tl, tr, FrictionParams(hysteresis_torque=h))
    assert (r.theta[-1] < -0.5 * h / p.k_lin).all()


def test_tip_force_bends_the_unloaded_shape_to_the_static_equilibrium():
    """No tension difference: τ(θ) = J_X(θ)^T (f_x, f_z) (Eqs. 10, 18-20), solved independently."""
    from scipy.optimize import fsolve

    p = FrictionParams(tip_force_x=0.4, tip_force_z=-0.5)
    t = np.array([0.0, 5.0])
    r = simulate(t, [0.45, 0.45], [0.45, 0.45], p)
    g = r.geom
    sp = p.spring()
    sol = fsolve(lambda th: sp.torque(th) - joint_torques_from_tip_wrench(th, g, 0.4, -0.5),
                 np.full(g.n_joints, 0.01), xtol=1e-14)
    np.testing.assert_allclose(r.theta[-1], sol, atol=1e-9)
    assert (r.theta[-1] > 0).all() and r.theta[-1, 0] > r.theta[-1, -1]  # base carries the largest moment
    ref = simulate(t, [0.45, 0.45], [0.45, 0.45], p, method="reference")
    np.testing.assert_allclose(ref.theta[-1], sol, atol=1e-9)


def test_stiffness_gradient_changes_b_in_the_mu0_limit():
    """μ = 0: θ_j = τ_j⁻¹(r_x ΔT) with τ_j scaled by 1 + g (2 (j-1)/(n-1) - 1)."""
    t, tl, tr, _ = bend_unbend(15.0, 0.45, n_up=5, n_down=4, interval=2.0)
    for g_ in (-0.4, 0.0, 0.4):
        p = FrictionParams(mu_d=0.0, mu_s=0.0, stiffness_gradient=g_)
        r = simulate(t, tl, tr, p)
        n = r.geom.n_joints
        scale = 1 + g_ * (2 * np.arange(n) / (n - 1) - 1)
        expect = friction_spring(scale=scale).angle(r.geom.r_x * (tr - tl)[:, None])
        np.testing.assert_allclose(r.theta, expect, atol=1e-12)
        k = int(np.argmax(tl))
        assert np.sign(r.b[k]) == (np.sign(g_) if g_ else 0.0) or (g_ == 0 and abs(r.b[k]) < 1e-12)


def test_extension_parameters_change_predictions_continuously():
    """Least squares needs small parameter steps to give small changes (away from slip flips)."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=8, n_down=8)
    base = simulate(t, tl, tr).theta
    for name, step in (("tip_force_x", 1e-3), ("stiffness_gradient", 1e-3), ("hysteresis_torque", 1e-5),
                       ("proximal_beta", 1e-3), ("k_lin", 1e-3)):
        p = FrictionParams().replace(**{name: getattr(FrictionParams(), name) + step})
        d = np.abs(simulate(t, tl, tr, p).theta - base).max()
        assert 0 < d < 2e-3, (name, d)


# ----------------------------------------------------------------------------- outputs
def test_outputs_shapes_ab_displacement_and_points(paper):
    t, tl, tr, r, _ = paper
    S, n = r.theta.shape
    assert r.tension_left.shape == (S, n) and r.state_left.shape == (S, n - 1)
    assert r.state_left.dtype == np.int8 and set(np.unique(r.state_left)) <= {-1, 0, 1}
    j = np.arange(1, n + 1)
    k = 15
    A = np.stack([np.ones(n), j], 1)
    a, b = np.linalg.lstsq(A, r.theta[k], rcond=None)[0]
    assert r.a[k] == pytest.approx(a, abs=1e-14) and r.b[k] == pytest.approx(b, abs=1e-15)
    kc = r.geom.cable_E * r.geom.cable_A / r.geom.cable_L0
    assert r.displacement_left[k] == pytest.approx(-r.geom.r_x * r.theta[k].sum() + tl[k] / kc, rel=1e-13)
    dl, dr = cable_displacement(r.theta, tl, tr, r.geom)
    assert np.array_equal(dl, r.displacement_left) and np.array_equal(dr, r.displacement_right)
    assert r.points().shape == (S, r.geom.n_points, 2)
    # loading: the left cable slides toward the base in every link, the right one sticks
    assert (r.state_left[5] == 1).all() and (r.state_right[5] == 0).all()
    np.testing.assert_allclose(r.base_tension_left, tl)


def test_simulation_table_columns(paper):
    t, tl, tr, r, _ = paper
    df = simulation_table(r, np.arange(101, 101 + len(t)))
    n = r.geom.n_joints
    assert list(df.columns[:5]) == ["sample", "time_s", "regime", "a", "b"]
    assert [f"theta_{j}" for j in range(1, n + 1)] == list(df.columns[5:5 + n])
    for c in ("tension_base_left_N", "tension_base_right_N", "displacement_left_mm", "displacement_right_mm"):
        assert c in df.columns
    assert df["sample"].iloc[0] == 101 and df["displacement_left_mm"].iloc[7] == r.displacement_left[7] * 1e3
    with pytest.raises(ValueError, match="sample_ids"):
        simulation_table(r, [1, 2])


def test_regimes_from_the_data(paper):
    """Fig. 11: I while the tension rises, II while it falls with the shape held, then III."""
    t, tl, tr, r, _ = paper
    k = int(np.argmax(tl))
    assert (r.regime[:k + 1] == "I").all()
    down = "".join("2" if x == "II" else "3" for x in r.regime[k + 1:])
    assert down.startswith("22") and down.endswith("33") and "32" not in down
    # the classifier only sees data: a shuffled index does not matter, constant tension holds the label
    lab = classify_regimes([0.5, 5, 10, 10, 8, 6, 3, 0.5], [0.4] * 8, [0, 1, 2, 2, 2, 1.9, 1.0, 0.1])
    assert list(lab) == ["I", "I", "I", "I", "II", "II", "III", "III"]


def test_shape_ab_matches_lstsq(rng):
    th = rng.normal(size=(4, 27))
    a, b = shape_ab(th)
    A = np.stack([np.ones(27), np.arange(1, 28)], 1)
    coef = np.linalg.lstsq(A, th.T, rcond=None)[0]
    np.testing.assert_allclose(a, coef[0], atol=1e-13)
    np.testing.assert_allclose(b, coef[1], atol=1e-14)


def test_five_joint_geometry(geom5):
    t, tl, tr, _ = bend_unbend(12.0, 0.45, n_up=5, n_down=4, interval=2.0)
    f = simulate(t, tl, tr, geom=geom5)
    r = simulate(t, tl, tr, geom=geom5, method="reference")
    assert f.theta.shape == (9, 5)
    assert np.abs(f.theta - r.theta).max() < 1e-3


# ----------------------------------------------------------------------------- bad input, files
@pytest.mark.parametrize("args,match", [
    (([0, 5, 10], [1, -0.1, 2], [0.4] * 3), "tension_left must be >= 0"),
    (([0, 5, 10], [1, 2, 3], [0.4, np.nan, 0.4]), "tension_right contains NaN"),
    (([0, 5, 5], [1, 2, 3], [0.4] * 3), "time must increase strictly"),
    (([0, 5, 10], [1, 2], [0.4] * 3), "shape of time"),
    (([], [], []), "non-empty"),
])
def test_bad_input_raises_clear_value_error(args, match):
    with pytest.raises(ValueError, match=match):
        simulate(*args)


def test_bad_options_and_params():
    t, tl, tr = [0.0, 5.0], [1.0, 2.0], [0.4, 0.4]
    with pytest.raises(ValueError, match="method"):
        simulate(t, tl, tr, method="euler")
    with pytest.raises(ValueError, match="dt"):
        simulate(t, tl, tr, method="reference", dt=0.0)
    with pytest.raises(ValueError, match="ramp_time"):
        simulate(t, tl, tr, ramp_time=-1.0)
    for kw, match in ((dict(mu_s=0.2), "mu_s"), (dict(mu_d=1.0, mu_s=1.2), "mu_d"),
                      (dict(stiffness_gradient=1.0), "stiffness_gradient"), (dict(b=0.0), "b"),
                      (dict(theta_stop=0.05), "theta_mid < theta_stop"), (dict(k_lin=float("nan")), "finite"),
                      (dict(proximal_beta=-0.1), "proximal_beta"), (dict(hysteresis_torque=-1.0), "hysteresis")):
        with pytest.raises(ValueError, match=match):
            FrictionParams(**kw)
    FrictionParams(mu_s=1.1)  # static coefficient above 1 is allowed (only compared)


def test_params_toml_round_trip_and_errors(tmp_path):
    p = FrictionParams(k_lin=0.51234567890123, mu_d=0.2, mu_s=0.37, proximal_beta=0.3, tip_force_x=-0.1,
                       stiffness_gradient=0.25)
    path = save_params(p, tmp_path / "m.toml", cause="proximal_friction", heldout_rms_mm=0.0312,
                       experiments=["L045", "R045"], fit={"n_params": 4, "converged": True})
    assert load_params(path) == p
    text = path.read_text()
    assert "k_lin_Nm_per_rad = 0.51234567890123" in text and "[metadata]" in text
    (tmp_path / "bad.toml").write_text("mu_d = 0.2\nmu_k = 0.3\n")
    with pytest.raises(ValueError, match="bad.toml: line 2: unknown friction parameter 'mu_k'"):
        load_params(tmp_path / "bad.toml")
    (tmp_path / "bad2.toml").write_text("mu_d = 0.5\nmu_s = 0.3\n")
    with pytest.raises(ValueError, match="bad2.toml: line 2: mu_s must be >= mu_d"):
        load_params(tmp_path / "bad2.toml")
    (tmp_path / "short.toml").write_text("k_mid = 0.3\n")
    assert load_params(tmp_path / "short.toml") == FrictionParams(k_mid=0.3)
    with pytest.raises(ValueError, match="not found"):
        load_params(tmp_path / "none.toml")


def test_geometry_cable_parameters_are_used():
    g = Geometry(r_x=3e-3)
    p = FrictionParams(mu_d=0.0, mu_s=0.0)
    r = simulate([0.0, 5.0], [0.45, 5.0], [0.45, 0.45], p, geom=g)
    assert r.theta[-1, 0] == pytest.approx(float(p.spring().angle(-3e-3 * 4.55)), abs=1e-13)


def test_friction_figures_write_data_and_png(tmp_path, paper):
    """Figs. 11, 17, 18, 19 and the hysteresis loop: CSV + PNG, with measured data when given."""
    import pandas as pd

    from notchfit.figures.friction import FIGURES, plot_fig18, plot_fig19

    assert {"fig11", "fig17", "fig18", "fig19", "hysteresis"} <= set(FIGURES)
    for name in ("fig11", "fig17", "hysteresis"):
        paths = FIGURES[name](tmp_path)
        assert sorted(p.suffix for p in paths) == [".csv", ".png"] and all(p.stat().st_size > 0 for p in paths)
    h = pd.read_csv(tmp_path / "hysteresis.csv")
    assert set(h["model"]) == {"mu_d = 0", "mu_d = 0.1", "mu_d = 0.29"}
    r = paper[3]
    plot_fig18(r, tmp_path, measured_theta=r.theta + 0.001)
    plot_fig19(r, tmp_path, measured_a=r.a, measured_b=r.b)
    d = pd.read_csv(tmp_path / "fig19.csv")
    assert {"a_pred_rad", "b_meas_rad", "tension_left_N", "regime"} <= set(d.columns)
    assert len(pd.read_csv(tmp_path / "fig18.csv")) == r.theta.size
