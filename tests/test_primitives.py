"""The shared primitives: units, validation, line fit, pulled cable, shoelace area, gray images."""

from __future__ import annotations

import math

import numpy as np
import pytest

from notchfit import paper
from notchfit.physics.cables import LEFT, RIGHT, pulled_side
from notchfit.imaging import to_gray, to_gray8
from notchfit.polygon import polygon_area
from notchfit.physics.shapes import line_fit, linear
from notchfit.units import DEG, MM
from notchfit.validation import as_finite, as_joint_angles, readonly


def test_units():
    assert 2.5 * MM == pytest.approx(0.0025)
    assert 0.0025 / MM == pytest.approx(2.5)
    assert 180 * DEG == pytest.approx(math.pi)


def test_readonly_copies_and_freezes():
    a = np.arange(3.0)
    r = readonly(a, shape=(3, 1))
    assert r.shape == (3, 1) and not r.flags.writeable
    a[0] = 9.0
    assert r[0, 0] == 0.0
    assert readonly(None) is None
    assert readonly([1, 2], dtype=np.int8).dtype == np.int8


def test_validators_name_the_quantity():
    with pytest.raises(ValueError, match="tensions contains NaN"):
        as_finite([1.0, np.nan], "tensions")
    with pytest.raises(ValueError, match="joint angles"):
        as_joint_angles(0.1)
    with pytest.raises(ValueError, match="last axis n=3"):
        as_joint_angles(np.zeros(4), 3)
    with pytest.raises(ValueError, match="joint angles contain NaN"):
        as_joint_angles([0.0, np.inf])
    assert as_joint_angles([[0.1, 0.2]], 2).shape == (1, 2)


def test_line_fit_equals_least_squares_on_the_linear_basis():
    """Sec. IV-A's θ_j = a + b j: the closed form equals the lstsq of the linear model's basis."""
    rng = np.random.default_rng(4)
    th = rng.normal(size=(5, 7, 27))
    a, b = line_fit(th)
    coef = np.linalg.lstsq(linear(27).basis, th.reshape(-1, 27).T, rcond=None)[0]
    np.testing.assert_allclose(a.ravel(), coef[0], atol=1e-12)
    np.testing.assert_allclose(b.ravel(), coef[1], atol=1e-12)
    # an exact line is returned exactly; one joint gives b = 0
    j = np.arange(1, 28)
    a1, b1 = line_fit(0.05 - 0.002 * j)
    assert a1 == pytest.approx(0.05, abs=1e-15) and b1 == pytest.approx(-0.002, abs=1e-15)
    assert line_fit(np.array([[0.3]]))[1][0] == 0.0


def test_pulled_side_rule_and_tie():
    assert pulled_side([0, 5, 0], [1, 1, 1]) == LEFT
    assert pulled_side([1, 1, 1], [0, 5, 0]) == RIGHT
    assert pulled_side([2, 2], [3, 3]) == LEFT          # a tie counts as the left cable


def test_polygon_area_shoelace():
    x, y = np.array([0, 2, 2, 0.0]), np.array([0, 0, 1, 1.0])
    assert polygon_area(x, y) == pytest.approx(2.0)
    assert polygon_area(x, y, signed=True) == pytest.approx(2.0)            # anticlockwise
    assert polygon_area(x[::-1], y[::-1], signed=True) == pytest.approx(-2.0)
    assert polygon_area([0, 1, np.nan, 1, 0], [0, 0, 5, 1, 1]) == pytest.approx(1.0)
    assert polygon_area([0, 1], [0, 1]) == 0.0
    # a regular polygon tends to the circle's area
    t = np.linspace(0, 2 * np.pi, 2001)[:-1]
    assert polygon_area(np.cos(t), np.sin(t)) == pytest.approx(np.pi, rel=1e-5)


def test_gray_images():
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 1] = 100
    g = to_gray(bgr)
    assert g.shape == (4, 5) and g.dtype == np.float32
    assert to_gray8(np.full((2, 2), 7, np.uint8))[0, 0] == 7                  # uint8 kept as is
    img16 = np.array([[1000, 3000], [2000, 1000]], np.uint16)
    g8 = to_gray8(img16)
    assert g8.dtype == np.uint8 and g8.min() == 0 and g8.max() == 255      # stretched
    with pytest.raises(ValueError, match="gray or colour"):
        to_gray(np.zeros((2, 2, 2)))


def test_paper_values():
    """Sec. III (Fig. 7) and Sec. IV-B."""
    assert (paper.DUAL_RATE_K1, paper.DUAL_RATE_K2, paper.DUAL_RATE_THRESH) == (0.36, 10.0, 0.135)
    assert (paper.FRICTION_K_LIN, paper.FRICTION_THETA_MID, paper.FRICTION_THETA_STOP) == (0.4829, 0.07, 0.14)
    assert (paper.MU_D, paper.MU_S, paper.DAMPING, paper.V_THR) == (0.29, 0.30, 0.03, 5e-5)
