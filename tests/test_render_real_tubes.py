"""Renders of real-tube geometries agree with the projector (pivot model): one-sided wrists with
the section backbone, per-notch depths and spacings, and a detect -> points round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from notchfit.io import load_geometry
from notchfit.physics.notches import notch_points
from notchfit.vision.render import manipulator_outline, pivot_closure_angles

DATA = Path(__file__).resolve().parent.parent / "datasets" / "geometry"


@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first", "default"])
def test_every_notch_point_is_an_outline_vertex(name):
    g = load_geometry(DATA / f"{name}.toml")
    rng = np.random.default_rng(5)
    th = g.rest_angles + rng.uniform(0.1, 0.9, g.n_joints) * (pivot_closure_angles(g) - g.rest_angles)
    outline = manipulator_outline(th, g)
    pts = notch_points(th, g)
    d = np.linalg.norm(outline[None, :, :] - pts[:, None, :], axis=-1).min(axis=1)
    assert d.max() < 1e-12


def test_pivot_closure_is_the_seed_formula_on_the_axis():
    g = load_geometry(DATA / "default.toml")
    np.testing.assert_allclose(pivot_closure_angles(g), g.closure_angles, rtol=1e-15)
    w = load_geometry(DATA / "wrist_asymmetric.toml")
    assert np.all(pivot_closure_angles(w) < w.closure_angles)          # slightly before the arc model's


def test_outline_refuses_overlapping_faces():
    g = load_geometry(DATA / "wrist_asymmetric.toml")
    with pytest.raises(ValueError, match="slot-closure angle"):
        manipulator_outline(1.01 * pivot_closure_angles(g), g)
