"""Section of a notched tube: closed forms (Roark Table A.1; York et al., ICRA 2015) against
numerical integration, and their limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from notchfit.physics.section import closure_angle, notch_section, segment_moments, tendon_moment_arm

MM = 1e-3


def integrated(R, r, g):
    """Area, centroid and I of the annulus part x > g - R by quadrature of the chord width."""
    d = g - R

    def width(x):
        w = 2.0 * math.sqrt(max(R * R - x * x, 0.0))
        if abs(x) < r:
            w -= 2.0 * math.sqrt(r * r - x * x)
        return w

    pts = [p for p in (-r, r) if d < p < R]
    opts = dict(points=pts or None, limit=200, epsabs=0, epsrel=1e-12)
    A = quad(width, d, R, **opts)[0]
    Q = quad(lambda x: x * width(x), d, R, **opts)[0]
    Ic = quad(lambda x: x * x * width(x), d, R, **opts)[0]
    y = Q / A
    return A, y, Ic - A * y * y


@pytest.mark.parametrize("R,r,g", [
    (0.81 * MM, 0.70 * MM, 1.40 * MM),    # one-sided nitinol wrists, OD 1.62 mm, ID 1.40 mm
    (0.81 * MM, 0.70 * MM, 1.36 * MM),
    (0.81 * MM, 0.70 * MM, 0.40 * MM),    # shallow: the chord does not reach the lumen
    (3.0 * MM, 2.5 * MM, 2.4 * MM),       # seed-like tube, chord through the lumen
    (3.0 * MM, 0.0, 2.4 * MM),            # solid rod (the seed tube is modelled as one)
    (1.0 * MM, 0.5 * MM, 1.7 * MM),       # chord beyond the lumen on the far side
])
def test_closed_form_equals_numerical_integration(R, r, g):
    s = notch_section(R, r, g)
    A, y, I = integrated(R, r, g)
    assert s.area == pytest.approx(A, rel=1e-9)
    assert s.neutral_offset == pytest.approx(y, rel=1e-8, abs=1e-15)
    assert s.second_moment == pytest.approx(I, rel=1e-8)


def test_uncut_tube_limit():
    """Cut depth -> 0: the whole annulus, neutral axis on the tube axis, I = π (R⁴ - r⁴)/4."""
    R, r = 0.81 * MM, 0.70 * MM
    s = notch_section(R, r, 0.0)
    assert s.neutral_offset == pytest.approx(0.0, abs=1e-18)
    assert s.area == pytest.approx(math.pi * (R**2 - r**2), rel=1e-12)
    assert s.second_moment == pytest.approx(math.pi * (R**4 - r**4) / 4, rel=1e-12)
    small = notch_section(R, r, 1e-9 * MM)
    assert small.second_moment == pytest.approx(s.second_moment, rel=1e-9)


def test_cut_to_the_axis_is_a_half_tube():
    """g = R: a half annulus, centroid 4 (R³ - r³) / (3π (R² - r²)), I = π (R⁴ - r⁴)/8 - A ȳ²."""
    R, r = 0.81 * MM, 0.70 * MM
    s = notch_section(R, r, R)
    A = math.pi * (R**2 - r**2) / 2
    y = 4 * (R**3 - r**3) / (3 * math.pi * (R**2 - r**2))
    assert s.area == pytest.approx(A, rel=1e-12)
    assert s.neutral_offset == pytest.approx(y, rel=1e-12)
    assert s.second_moment == pytest.approx(math.pi * (R**4 - r**4) / 8 - A * y * y, rel=1e-10)


def test_segment_limits():
    A, Q, I = segment_moments(2.0, np.array([-3.0, 2.0, 0.0]))
    np.testing.assert_allclose(A, [4 * math.pi, 0.0, 2 * math.pi], atol=1e-12)
    np.testing.assert_allclose(Q, [0.0, 0.0, 16 / 3], atol=1e-12)
    np.testing.assert_allclose(I, [4 * math.pi, 0.0, 2 * math.pi], atol=1e-12)   # π ρ⁴/4, π ρ⁴/8
    assert segment_moments(0.0, 0.3)[0] == 0.0


def test_deeper_cut_is_softer_and_moves_the_neutral_axis_out():
    g = np.linspace(0.2, 1.55, 12) * MM
    s = notch_section(0.81 * MM, 0.70 * MM, g)
    assert np.all(np.diff(s.second_moment) < 0)
    assert np.all(np.diff(s.neutral_offset) > 0)
    assert np.all(s.neutral_offset < 0.81 * MM)


def test_closure_angle_of_one_sided_wrists():
    """OD 1.62 / ID 1.40 mm, 0.8 mm slots cut 1.36-1.45 mm deep: faces meet near 30°
    (the measured saturation of such wrists is 30–31°), not at the 52.6° of an axis at the centre."""
    h = 0.8 * MM
    s = notch_section(0.81 * MM, 0.70 * MM, np.array([1.36, 1.45]) * MM)
    deg = np.degrees(closure_angle(h, s))
    assert np.all((deg > 29.0) & (deg < 31.5))
    assert math.degrees(2 * math.atan(h / (2 * 0.81 * MM))) == pytest.approx(52.6, abs=0.1)


def test_closure_angle_small_angle_form_on_the_axis():
    R, h = 3.0 * MM, 0.42 * MM
    s = notch_section(R, 0.0, 0.0)
    assert closure_angle(h, s) == pytest.approx(2 * math.atan(h / (2 * R)), rel=2e-3)


def test_tendon_arm_and_validation():
    s = notch_section(0.81 * MM, 0.70 * MM, 1.4 * MM)
    assert tendon_moment_arm(s, 0.70 * MM) == pytest.approx(0.70 * MM + s.neutral_offset)
    for args in [(0.0, 0.0, 0.1), (1.0, 1.0, 0.1), (1.0, 0.5, 2.0), (1.0, 0.5, -0.1), (1.0, 0.5, np.nan)]:
        with pytest.raises(ValueError):
            notch_section(*args)
