"""Kinematics and the notch-point projector of real tubes (docs/models.md, "Real tubes: kinematics").

Joints at the geometry's per-joint z, bending about each slot's neutral axis; two models: mid-notch
pivots (the paper's revolute joints, default) and circular-arc notches (constant curvature over the slot
height: Webster & Jones, IJRR 29(13) 2010, Eq. 1 for the arc's chord). The arc is the pivot followed by
``δ(θ) = h (sinc(θ/2) - cos(θ/2)) (sin(θ/2), cos(θ/2))`` (derived in ``kinematics.arc_translation``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from notchfit.physics import kinematics as K
from notchfit.physics.geometry import default_geometry, notch_layout
from notchfit.io import load_geometry
from notchfit.physics.notches import notch_points, notch_points_and_jacobian

DATA = Path(__file__).resolve().parent.parent / "datasets" / "geometry"
MODELS = ("pivot", "arc")


def wrist(name="wrist_asymmetric"):
    return load_geometry(DATA / f"{name}.toml")


def geometries():
    return [wrist(), wrist("wrist_tip_first"), default_geometry()]


# ---------------------------------------------------------------------------- the arc transform
def test_arc_translation_is_chord_minus_pivot():
    """δ = h((1 - cos θ)/θ, sin θ/θ) - (h/2)(sin θ, 1 + cos θ): the arc's chord less the pivot's."""
    h = 0.8e-3
    th = np.array([-0.6, -0.2, -1e-2, 2e-3, 0.1, 0.53, 1.0])
    chord = h * np.stack([(1 - np.cos(th)) / th, np.sin(th) / th], -1)
    pivot = 0.5 * h * np.stack([np.sin(th), 1 + np.cos(th)], -1)
    # atol: the direct difference cancels (h·eps/θ²-level rounding); arc_translation does not
    np.testing.assert_allclose(K.arc_translation(th, h), chord - pivot, rtol=0, atol=5e-17)
    np.testing.assert_array_equal(K.arc_translation(0.0, h), [0.0, 0.0])


@pytest.mark.parametrize("t", [0.0, 1e-7, 1.9e-3, 2.1e-3, 0.05, -0.3, 0.6])
def test_arc_translation_derivative_fd(t):
    h, e = 0.5e-3, 1e-6
    _, dd = K.arc_translation(t, h, derivative=True)
    fd = (K.arc_translation(t + e, h) - K.arc_translation(t - e, h)) / (2 * e)
    np.testing.assert_allclose(dd, fd, rtol=0, atol=1e-13)


def test_series_branch_is_continuous():
    """The Taylor branch (|θ/2| < series_below) and the closed form agree where they meet."""
    h, t = 1e-3, 2e-3
    a = K.arc_translation(t, h, derivative=True, series_below=1e-3 * (1 - 1e-9))
    b = K.arc_translation(t, h, derivative=True, series_below=1e-3 * (1 + 1e-9))
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-20)


def test_pivot_error_orders():
    """Pivot vs arc, per notch: |δ| = h θ²/12 + O(h θ⁴) along the chord (the pivot chain is short),
    δ_x = h θ³/24 + O(h θ⁵) across the tube, nothing across the chord (same end orientation)."""
    h = 1e-3
    for t in (1e-2, 2e-2, 4e-2):
        d = K.arc_translation(t, h)
        assert np.linalg.norm(d) / (h * t**2 / 12) == pytest.approx(1.0, abs=t**2)
        assert d[0] / (h * t**3 / 24) == pytest.approx(1.0, abs=t**2)
        assert d[0] * np.cos(t / 2) - d[1] * np.sin(t / 2) == pytest.approx(0.0, abs=1e-20)


# ---------------------------------------------------------------------------- the chain
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("g", geometries(), ids=lambda g: g.name)
def test_projector_equals_se3_oracle(g, model):
    """Notch points from the planar chain = link_frames (SE(3) products) applied to the layout."""
    rng = np.random.default_rng(3)
    th = rng.uniform(-0.5, 0.5, g.n_joints)
    lay = notch_layout(g)
    F = K.link_frames(th, g, model)
    loc = np.zeros((lay.n_points, 4))
    loc[:, 0], loc[:, 2], loc[:, 3] = lay.local[:, 0], lay.local[:, 1], 1.0
    P = np.einsum("mij,mj->mi", F[lay.link], loc)[:, [0, 2]]
    np.testing.assert_allclose(notch_points(th, g, model), P, rtol=0, atol=1e-15)
    pts, _ = notch_points_and_jacobian(th, g, model)
    np.testing.assert_allclose(pts, P, rtol=0, atol=1e-15)
    np.testing.assert_allclose(K.tip_pose(th, g, model)[:2], K.tool_frame(th, g, model)[[0, 2], 3],
                               rtol=0, atol=1e-15)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("g", geometries(), ids=lambda g: g.name)
def test_jacobians_fd(g, model):
    """Projector, planar and spatial Jacobians against central differences."""
    rng = np.random.default_rng(4)
    th = rng.uniform(-0.5, 0.5, g.n_joints)
    th[0] = 0.0                                            # the θ → 0 limit of the arc
    e = 1e-6
    _, J = notch_points_and_jacobian(th, g, model)
    Jp, Js = K.planar_jacobian(th, g, model), K.spatial_jacobian(th, g, model)
    gt = K.tool_frame(th, g, model)
    for k in range(g.n_joints):
        d = np.zeros(g.n_joints)
        d[k] = e
        fd = (notch_points(th + d, g, model) - notch_points(th - d, g, model)) / (2 * e)
        np.testing.assert_allclose(J[..., k], fd, rtol=0, atol=1e-10)
        fdp = (K.tip_pose(th + d, g, model) - K.tip_pose(th - d, g, model)) / (2 * e)
        np.testing.assert_allclose(Jp[:, k], fdp, rtol=0, atol=1e-9)
        dg = (K.tool_frame(th + d, g, model) - K.tool_frame(th - d, g, model)) / (2 * e)
        np.testing.assert_allclose(Js[:, k], K.vee6(dg @ K.inverse_se3(gt)), rtol=0, atol=1e-9)


@pytest.mark.parametrize("model", MODELS)
def test_world_load_torques_match_spatial_jacobian(model):
    """J_X^T (f_x, f_z, m_y) = J_st^s(θ)^T F_s with F_s from Eq. (28), for both models."""
    g = wrist()
    th = np.random.default_rng(5).uniform(-0.5, 0.5, g.n_joints)
    f, tau = np.array([0.3, 0.0, -0.2]), np.array([0.0, 0.01, 0.0])
    Fs = K.spatial_wrench_from_world(f, tau, K.tool_frame(th, g, model))
    np.testing.assert_allclose(K.joint_torques_from_tip_wrench(th, g, 0.3, -0.2, 0.01, model=model),
                               K.spatial_jacobian(th, g, model).T @ Fs, rtol=0, atol=1e-15)


def test_batched_kernel_equals_numpy_path():
    g = wrist("wrist_tip_first")
    th = np.random.default_rng(6).uniform(-0.4, 0.4, (3, 2, g.n_joints))
    for model in MODELS:
        pts, J = notch_points_and_jacobian(th, g, model)
        assert pts.shape == (3, 2, g.n_points, 2) and J.shape == (3, 2, g.n_points, 2, g.n_joints)
        np.testing.assert_allclose(pts, notch_points(th, g, model), rtol=0, atol=1e-16)


def test_joints_sit_where_the_geometry_puts_them():
    """Straight tube: joint j at (x_na,j, z_j); the arc model's joint is the arc's midpoint."""
    g = wrist("wrist_tip_first")
    q = K.joint_positions(np.zeros(g.n_joints), g)
    np.testing.assert_allclose(q[:-1], np.stack([g.neutral_axis_x, g.joint_z], -1), rtol=0, atol=1e-18)
    np.testing.assert_allclose(q[-1], [0.0, g.tip_z], rtol=0, atol=1e-18)
    th = np.full(g.n_joints, 0.3)
    qa, qp = K.joint_positions(th, g, "arc"), K.joint_positions(th, g)
    # the arc bulges from the chord toward the side it bends away from: its midpoint lies
    # h(1 - cos(θ/2))/θ... off the pivot's, a fraction of h θ
    assert np.all(np.linalg.norm(qa - qp, axis=-1)[:-1] < 0.5 * g.slot_widths * 0.3)


def test_arc_notch_closes_at_the_closure_angle():
    """In the arc model a slot's two outer corners meet at θ_c = h/(R + ȳ) (notchfit.physics.section)."""
    g = wrist()
    lay = notch_layout(g)
    th = g.closure_angles.copy()
    P = notch_points(th, g, "arc")
    for j in range(1, g.n_joints + 1):
        prox = np.flatnonzero((lay.joint == j) & (np.array(lay.kind) == "proximal"))[0]
        dist = np.flatnonzero((lay.joint == j) & (np.array(lay.kind) == "distal"))[0]
        assert np.linalg.norm(P[prox] - P[dist]) < 1e-15
        P2 = notch_points(0.9 * th, g, "arc")
        assert np.linalg.norm(P2[prox] - P2[dist]) > 1e-5


# ---------------------------------------------------------------------------- the item 8
def rms_mm(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, -1)))) * 1e3


@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
def test_neutral_axis_pivots_reproduce_arc_notches(name):
    """Bends up to the closure angle: pivots on the neutral axis at mid-notch reproduce the
    circular-arc notch points to <= 0.07 mm (max), joints on the tube axis miss them by 0.5-0.9 mm rms
    at closure (issue 14, item 8). wrist_asymmetric at closure: 0.046 mm rms / 0.069 max vs 0.87 mm rms."""
    g = wrist(name)
    ga = g.replace(backbone="axis")
    for f in (0.25, 0.5, 1.0):
        th = f * g.closure_angles
        arc = notch_points(th, g, "arc")
        piv = notch_points(th, g)
        assert np.max(np.linalg.norm(piv - arc, axis=-1)) < 0.07e-3
        assert rms_mm(notch_points(th, ga), arc) > 10 * rms_mm(piv, arc)
    th = g.closure_angles
    assert 0.5 < rms_mm(notch_points(th, ga), notch_points(th, g, "arc")) < 1.0


def test_pivot_and_arc_agree_to_second_order():
    """The two models differ by O(h θ²) per notch: halving θ quarters the point difference."""
    g = wrist()
    th = 0.1 * g.closure_angles
    d1 = np.abs(notch_points(th, g, "arc") - notch_points(th, g)).max()
    d2 = np.abs(notch_points(th / 2, g, "arc") - notch_points(th / 2, g)).max()
    assert d1 / d2 == pytest.approx(4.0, rel=0.02)


# ---------------------------------------------------------------------------- the seed tube unchanged
def test_per_joint_arrays_with_equal_values_reproduce_the_seed_exactly():
    g = default_geometry()
    n = g.n_joints
    ga = g.replace(p=(g.p,) * (n - 1), slot_width=(g.slot_width,) * n, slot_depth=(g.slot_depth,) * n)
    th = np.random.default_rng(7).uniform(-0.14, 0.14, (4, n))
    for a, b in zip(notch_points_and_jacobian(th, g), notch_points_and_jacobian(th, ga)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(notch_points(th, g), notch_points(th, ga))
    np.testing.assert_array_equal(K.planar_jacobian(th, g), K.planar_jacobian(th, ga))
    np.testing.assert_array_equal(K.tip_pose(th, g), K.tip_pose(th, ga))
    np.testing.assert_array_equal(K.link_frames(th[0], g), K.link_frames(th[0], ga))


def test_seed_general_path_equals_the_papers_closed_forms():
    """The general chain (used for real tubes) reproduces Eqs. 18-20 on the seed tube."""
    g = default_geometry()
    th = np.random.default_rng(8).uniform(-0.14, 0.14, (5, g.n_joints))
    np.testing.assert_array_equal(K.joint_positions(th, g), K.joint_positions(th, g.p))
    ch = K.chain(g)
    assert ch.uniform_axis
    phi, O, ds = K.link_origins(th, g, derivative=True)
    tip = K.tip_pose(th, g)[..., None, :2]
    J = K.planar_jacobian(th, g)
    np.testing.assert_allclose(J[..., 0, :], (tip - O[..., 1:, :])[..., 1], rtol=0, atol=1e-16)
    np.testing.assert_allclose(J[..., 1, :], -(tip - O[..., 1:, :])[..., 0], rtol=0, atol=1e-16)
    assert not ds.any()


def test_unknown_model_is_rejected():
    g = wrist()
    with pytest.raises(ValueError, match="model"):
        notch_points(np.zeros(g.n_joints), g, "spline")
    with pytest.raises(ValueError, match="model"):
        notch_points_and_jacobian(np.zeros(g.n_joints), g, "spline")
