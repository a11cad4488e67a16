"""Flexure springs: Fig. 7 (dual rate) and Fig. 17 (friction model)."""
import numpy as np
import pytest

from notchfit.physics.springs import PiecewiseLinearSpring, dual_rate_spring, friction_spring


def test_fig7_dual_rate_matches_paper_formula():
    s = dual_rate_spring()
    k1, k2, tt = 0.36, 10.0, 0.135
    th = np.linspace(-0.2, 0.2, 801)
    k_paper = np.where(np.abs(th) <= tt, k1,
                       np.where(th > tt, k2 + tt * (k1 - k2) / np.where(th == 0, 1, th),
                                k2 - tt * (k1 - k2) / np.where(th == 0, 1, th)))
    np.testing.assert_allclose(s.torque(th), k_paper * th, atol=1e-15)
    np.testing.assert_allclose(s.secant(th), k_paper, atol=1e-12)


def test_fig17_friction_spring_rates():
    s = friction_spring()
    assert s.stiffness(0.03) == pytest.approx(0.4829)
    assert s.stiffness(0.1) == pytest.approx(0.25)
    assert s.stiffness(0.15) == pytest.approx(10.0)
    assert s.torque(0.07) == pytest.approx(0.4829 * 0.07)


def test_odd_continuous_inverse_and_stiffness_fd():
    s = friction_spring()
    th = np.linspace(-0.2, 0.2, 2001)
    tq = s.torque(th)
    np.testing.assert_allclose(s.torque(-th), -tq)
    np.testing.assert_allclose(s.angle(tq), th, atol=1e-14)
    h = 1e-7
    fd = (s.torque(th + h) - s.torque(th - h)) / (2 * h)
    away = np.min(np.abs(np.abs(th)[:, None] - np.array([0.07, 0.14])), axis=1) > 1e-6
    np.testing.assert_allclose(s.stiffness(th)[away], fd[away], rtol=1e-6)


def test_per_joint_scale():
    scale = np.linspace(1.2, 0.8, 27)
    s = friction_spring(scale=scale)
    tq = s.torque(np.full(27, 0.05))
    np.testing.assert_allclose(tq, 0.4829 * 0.05 * scale)
    np.testing.assert_allclose(s.angle(tq), 0.05)


def test_bad_springs():
    with pytest.raises(ValueError, match="increasing"):
        PiecewiseLinearSpring([0.1, 0.05], [1, 2, 3])
    with pytest.raises(ValueError, match="positive"):
        PiecewiseLinearSpring([0.1], [1, -2])
    with pytest.raises(ValueError, match="NaN"):
        friction_spring().angle(np.nan)
