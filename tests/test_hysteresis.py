"""The joint-hysteresis family and the generator's laws (notchfit.physics._hysteresis_kernels).

Closed forms at μ = 0 (every joint sees the drive torque F = r_x ΔT and comes to rest):
* the play of constant width (the seed's hysteresis_torque): test_friction.py;
* the play with an onset (flag-shaped loops): the first rest point of
  τ(x) ± r(|x|) = F in the direction of motion (Al Janaideh, Rakheja & Su,
  IEEE/ASME TMECH 16(4), 2011: a generalized play);
* the stop (Prandtl's elastic-plastic element; Brokate & Sprekels 1996, Ch. 2)
  in parallel with a linear spring: bilinear virgin curve and Masing's rule
  (Masing 1926: after a reversal the elastic range is twice the virgin one);
* the Bouc-Wen law (Wen 1976, n = 1, β = γ): virgin curve z_u (1 - e^{-A x / z_u}),
  elastic unloading at stiffness A;
* the two-branch superelastic plateau (after Auricchio, Taylor & Lubliner 1997):
  the loading branch is the Fig. 17 spring, the reverse plateau lies lower,
  nothing is left at zero load.
"""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from notchfit.physics import _hysteresis_kernels as H
from notchfit.physics.friction import FrictionParams, simulate
from notchfit.io import load_params, save_params
from notchfit.physics.protocols import bend_unbend


def _drive(F_values, *, interval=2.0, counter=0.45, r_x=0.0025):
    """Times and tensions whose drive torque r_x (T_R - T_L) takes the values F (right pulled for F > 0)."""
    F = np.asarray(F_values, float)
    t = interval * np.arange(1, len(F) + 1)
    tr = counter + np.maximum(F, 0.0) / r_x
    tl = counter + np.maximum(-F, 0.0) / r_x
    return t, tl, tr


def _rest_play(F_seq, sp, h, on):
    """Independent rest states of the generalized play: first root of τ(x) ± r(|x|) = F toward F."""
    def r(a):
        return H.hyst_threshold(abs(a), h, on)
    x, out = 0.0, []
    for F in F_seq:
        q = F - float(sp.torque(x))
        if q > r(x):
            x = brentq(lambda y: float(sp.torque(y)) + r(y) - F, x, x + 1.0, xtol=1e-15)
        elif q < -r(x):
            x = brentq(lambda y: float(sp.torque(y)) - r(y) - F, x - 1.0, x, xtol=1e-15)
        out.append(x)
    return np.array(out)


def test_threshold_and_stiffness_of_the_family():
    assert H.hyst_threshold(0.3, 2e-3, 0.0) == 2e-3                     # no onset: constant width
    assert H.hyst_threshold(0.04, 2e-3, 0.08) == 0.0                    # below (1 - ρ) θ_h
    assert H.hyst_threshold(0.06, 2e-3, 0.08) == pytest.approx(1e-3)    # half way up the ramp
    assert H.hyst_threshold(0.09, 2e-3, 0.08) == 2e-3
    assert H.hyst_stiffness(2e-3, 0.0, 0.0) == math.inf                 # θ_y = 0: the play
    assert H.hyst_stiffness(2e-3, 0.0, 4e-3) == pytest.approx(0.5)
    # the stop stays at least as stiff as the threshold's slope h / (ρ θ_h)
    assert H.hyst_stiffness(2e-3, 0.02, 0.05) == pytest.approx(2e-3 / (H.HYST_RAMP * 0.02))


@pytest.mark.parametrize("method", ["fast", "reference"])
def test_flag_shaped_play_closed_form_and_no_residual_bend(method):
    """μ = 0: each joint follows the generalized play's rest states exactly; the loops are confined to
    deflections above (1 - ρ) θ_h and nothing is left at zero load."""
    h, on = 4e-3, 0.08
    p = FrictionParams(mu_d=0.0, mu_s=0.0, hysteresis_torque=h, hysteresis_onset=on)
    F = np.r_[np.linspace(0, 0.05, 11), np.linspace(0.045, 0.0, 10)]
    t, tl, tr = _drive(F)
    r = simulate(t, tl, tr, p, method=method)
    expect = _rest_play(F, p.spring(), h, on)
    np.testing.assert_allclose(r.theta[:, 0], expect, atol=1e-9)
    assert np.ptp(r.theta, axis=1).max() < 1e-9                        # every joint alike at μ = 0
    assert abs(r.theta[-1, 0]) < 1e-15
    up, down = expect[:10], expect[11:][::-1]                            # the same F values up and down
    wide = up > on
    assert wide.sum() >= 1 and (down[wide] - up[wide] > 1e-3).all()      # a loop where the plateau is
    assert np.abs(down[up < 0.5 * on] - up[up < 0.5 * on]).max() < 1e-12  # none below the onset


@pytest.mark.parametrize("method", ["fast", "reference"])
def test_stop_gives_masing_loops_with_the_springs_hardening(method):
    """A stop (k_e = h/θ_y) in parallel with the linear spring k: virgin curve F = (k + k_e) x up to θ_y,
    then F = k x + h; after a reversal the joint unloads along slope k + k_e over 2 θ_y (Masing's
    doubled elastic range) and then along F = k x - h."""
    h, y = 4e-3, 5e-3
    p = FrictionParams(mu_d=0.0, mu_s=0.0, hysteresis_torque=h, hysteresis_yield=y)
    k, ke = p.k_lin, h / y
    Fmax = 0.028                                                         # x stays below θ_mid = 0.07
    F = np.r_[np.linspace(0, Fmax, 8), np.linspace(Fmax, -Fmax, 15)[1:]]
    t, tl, tr = _drive(F)
    x = simulate(t, tl, tr, p, method=method).theta[:, 0]
    xr = (Fmax - h) / k
    expect = []
    for i, f in enumerate(F):
        if i < 8:
            expect.append(f / (k + ke) if f <= (k + ke) * y else (f - h) / k)
        elif Fmax - f <= 2 * y * (k + ke):
            expect.append(xr - (Fmax - f) / (k + ke))
        else:
            expect.append((f + h) / k)
    np.testing.assert_allclose(x, expect, atol=1e-9)


def test_stop_tends_to_the_play_as_its_yield_angle_vanishes():
    """A Prandtl-Ishlinskii element with one stop and θ_y -> 0 is the play (constant width 2h): at μ = 0
    the rest states differ by at most the stop's elastic range 2 θ_y."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=8, n_down=8)
    play = simulate(t, tl, tr, FrictionParams(mu_d=0.0, mu_s=0.0, hysteresis_torque=3e-3)).theta
    for y in (1e-3, 1e-4, 1e-6):
        stop = simulate(t, tl, tr, FrictionParams(mu_d=0.0, mu_s=0.0, hysteresis_torque=3e-3,
                                                  hysteresis_yield=y)).theta
        d = np.abs(stop - play).max()
        assert 0 < d <= 2 * y + 1e-12


@pytest.mark.parametrize("x0,S0,F,d", [(0.0, 0.0, 0.05, 1), (0.09, 3e-3, 0.0, -1), (-0.02, -1e-3, 0.06, 1),
                                       (0.12, 3e-3, 0.02, -1)])
def test_relaxation_is_the_exact_piecewise_exponential(x0, S0, F, d):
    """hyst_relax solves b ẋ = F - τ(x) - S(x) along the motion exactly (vs a stiff ODE solver);
    its long-time limit is hyst_rest."""
    p = FrictionParams()
    sp = (p.k_lin, p.k_mid, p.k_stop, p.theta_mid, p.theta_stop, 1.0)
    h, on, ke = 3e-3, 0.08, H.hyst_stiffness(3e-3, 0.08, 4e-3)

    def rhs(_, x):
        return [(F - H._law(x[0], x0, S0, d, ke, h, on, *sp)) / p.b]

    sol = solve_ivp(rhs, (0, 0.5), [x0], method="LSODA", rtol=1e-11, atol=1e-13, dense_output=True)
    for t in (1e-3, 0.01, 0.05, 0.2):
        got = H.hyst_relax(x0, S0, F, p.b, t, d, ke, h, on, *sp)
        assert got == pytest.approx(sol.sol(t)[0], abs=2e-9)
    rest = H.hyst_rest(x0, S0, F, d, ke, h, on, *sp)
    assert H.hyst_relax(x0, S0, F, p.b, 1e3, d, ke, h, on, *sp) == pytest.approx(rest, abs=1e-12)
    assert H._law(rest, x0, S0, d, ke, h, on, *sp) == pytest.approx(F, abs=1e-12)


def test_fast_solver_agrees_with_reference_for_the_hysteresis_family():
    """Friction and hysteresis together: within 1e-3 rad (9 of 10 samples within 2e-4 rad), as for
    the other extensions (test_friction.py)."""
    t, tl, tr, _ = bend_unbend(25.0, 0.45, n_up=10, n_down=10)
    for kw in (dict(hysteresis_torque=4e-3, hysteresis_onset=0.08), dict(hysteresis_torque=4e-3, hysteresis_yield=4e-3),
               dict(hysteresis_torque=4e-3, hysteresis_onset=0.06, hysteresis_yield=0.01)):
        p = FrictionParams(**kw)
        d = np.abs(simulate(t, tl, tr, p).theta - simulate(t, tl, tr, p, method="reference").theta)
        assert d.max() < 1e-3, (kw, d.max())
        assert np.quantile(d.max(axis=1), 0.9) < 2e-4, kw


def test_bouc_wen_virgin_curve_and_elastic_unloading():
    """μ = 0, linear spring: F = k x + z_u (1 - e^{-A x / z_u}) on the virgin curve, and after the
    reversal dz/dx = A while z > 0 (β = γ): F = F_r - (k + A)(x_r - x). Euler in the reference
    solver's steps: within 1e-5 rad."""
    zu, A = 5e-3, 1.0
    p = FrictionParams(mu_d=0.0, mu_s=0.0, bouc_wen_torque=zu, bouc_wen_stiffness=A)
    k = p.k_lin
    F = np.r_[np.linspace(0, 0.028, 8), [0.026, 0.024]]
    t, tl, tr = _drive(F)
    x = simulate(t, tl, tr, p, method="reference", dt=2e-5).theta[:, 0]
    for i in range(8):
        assert k * x[i] + zu * (1 - math.exp(-A * x[i] / zu)) == pytest.approx(F[i], abs=1e-5 * (k + A))
    zr = zu * (1 - math.exp(-A * x[7] / zu))
    for i in (8, 9):
        assert zr - A * (x[7] - x[i]) > 0
        assert F[7] - (k + A) * (x[7] - x[i]) == pytest.approx(F[i], abs=1e-5 * (k + A))
    with pytest.raises(ValueError, match="reference solver only"):
        simulate(t, tl, tr, p)


def test_superelastic_flag_loads_on_the_spring_and_leaves_no_bend():
    """The loading branch is the Fig. 17 spring; in the reverse plateau F = τ(x) - gap (1 - k_mid/k_lin)
    (the plateaus differ by gap at equal martensite fraction); the joint straightens at F = 0."""
    gap = 0.012
    p = FrictionParams(mu_d=0.0, mu_s=0.0, superelastic_gap=gap)
    sp = p.spring()
    F = np.r_[np.linspace(0, 0.05, 11), np.linspace(0.045, 0.0, 10)]
    t, tl, tr = _drive(F)
    x = simulate(t, tl, tr, p, method="reference").theta[:, 0]
    np.testing.assert_allclose(sp.torque(x[:11]), F[:11], atol=1e-9)
    assert x[10] > p.theta_mid                                           # the peak is on the plateau
    assert x[11] == pytest.approx(x[10] - (F[10] - F[11]) / p.k_lin, abs=1e-9)  # elastic after the reversal
    drop = gap * (1 - p.k_mid / p.k_lin)
    diff = sp.torque(x[11:]) - F[11:]
    assert (diff <= drop + 1e-9).all()                                  # the reverse plateau is the lowest branch
    assert (np.abs(diff - drop) < 1e-9).sum() >= 2                      # and the joints reach it
    assert abs(x[-1]) < 1e-12


def test_family_parameters_validate_and_round_trip(tmp_path):
    p = FrictionParams(hysteresis_torque=3e-3, hysteresis_onset=0.07, hysteresis_yield=2e-3)
    q = load_params(save_params(p, tmp_path / "m.toml"))
    assert q == p
    assert "hysteresis_onset" not in FrictionParams().to_dict()       # old model files are unchanged
    for bad in (dict(hysteresis_onset=-0.1), dict(hysteresis_yield=-1e-3), dict(superelastic_gap=-1.0),
                dict(bouc_wen_torque=1e-3)):
        with pytest.raises(ValueError):
            FrictionParams(**bad)
