"""Cables of real tubes (notchfit.physics.cables, docs/models.md "Real tubes: kinematics"): a lumen tendon across
circular-arc notches, one-tendon coupling matrices, per-link spacings in the channel law; seed unchanged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from notchfit.physics import cables as C
from notchfit.physics import kinematics as K
from notchfit.physics.geometry import default_geometry
from notchfit.io import load_geometry

DATA = Path(__file__).resolve().parent.parent / "datasets" / "geometry"


def wrist(name="wrist_asymmetric"):
    return load_geometry(DATA / f"{name}.toml")


def world(point, link, phi, O, g):
    """A straight-configuration point on ``link`` placed by the planar chain (link_origins)."""
    a = np.zeros(2) if link == 0 else K.chain(g).pivots[link - 1]
    d = np.asarray(point) - a
    c, s = np.cos(phi[link]), np.sin(phi[link])
    return O[link] + np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


@pytest.mark.parametrize("name", ["wrist_asymmetric", "wrist_tip_first"])
def test_one_tendon_coupling_is_minus_the_moment_arm(name):
    """tendons = ("right",): P is (n, 1), the column -arm_j (geom.moment_arms(+1)); Δℓ_j = -arm_j θ_j."""
    g = wrist(name)
    assert C.tendon_columns(g) == (C.RIGHT,)
    th = np.random.default_rng(1).uniform(-0.3, 0.3, (4, g.n_joints))
    P = C.coupling_matrix(th, g, "simple")
    assert P.shape == (4, g.n_joints, 1)
    np.testing.assert_array_equal(P[0, :, 0], -g.moment_arms(+1))
    L = C.cable_lengths(th, g, "simple")
    np.testing.assert_allclose(L[..., 0] - C.rest_lengths(g)[0], -(th * g.moment_arms(+1)).sum(-1),
                               rtol=0, atol=1e-18)
    # θ -> 0: the exact (chord) law has the same slope
    np.testing.assert_allclose(C.coupling_matrix(np.zeros(g.n_joints), g, "exact")[:, 0],
                               -g.moment_arms(+1), rtol=1e-15, atol=0)


def test_lumen_tendon_exact_length_is_the_chord_across_the_arc_notch():
    """The exact lumen law = distance between the tendon's exits on the two faces of each notch, placed
    by the arc-model kinematics (an independent construction)."""
    g = wrist()
    th = np.array([0.0, 0.1, -0.2, 0.4, g.closure_angles[-1]])
    phi, O = K.link_origins(th, g, "arc")
    xt = g.inner_radius - g.cable_radius                     # the right tendon's x (docs: moment_arms)
    dl = C.tendon_notch_lengths(th, g, +1, "exact")
    for j in range(1, g.n_joints + 1):
        z, h = g.joint_z[j - 1], g.slot_widths[j - 1]
        a = world([xt, z - h / 2], j - 1, phi, O, g)
        b = world([xt, z + h / 2], j, phi, O, g)
        assert np.linalg.norm(b - a) - h == pytest.approx(dl[j - 1], abs=1e-15)
    # the arc ("simple") law is the fibre's arc: longer than the chord by (ρ - c)(θ - 2 sin(θ/2))
    simple = C.tendon_notch_lengths(th, g, +1, "simple")
    c = g.moment_arms(+1)
    rho_c = np.where(th != 0, g.slot_widths / np.where(th != 0, th, 1) - c, 0)
    np.testing.assert_allclose(simple - dl, rho_c * (th - 2 * np.sin(th / 2)), rtol=0, atol=1e-17)


@pytest.mark.parametrize("t", [0.0, 1e-4, 0.05, 0.1, -0.3, 0.5])
def test_lumen_exact_derivatives_fd(t):
    g = wrist("wrist_tip_first")
    th = np.full(g.n_joints, t)
    e = 1e-6
    P = C.coupling_matrix(th, g, "exact")
    H = C.cable_length_hessian(th, g)
    assert P.shape == (g.n_joints, 1) and H.shape == (1, g.n_joints, g.n_joints)
    for k in range(g.n_joints):
        d = np.zeros(g.n_joints)
        d[k] = e
        fd = (C.cable_lengths(th + d, g) - C.cable_lengths(th - d, g)) / (2 * e)
        assert P[k, 0] == pytest.approx(fd[0], abs=1e-12)
        fdh = (C.coupling_matrix(th + d, g)[:, 0] - C.coupling_matrix(th - d, g)[:, 0]) / (2 * e)
        np.testing.assert_allclose(H[0, :, k], fdh, rtol=0, atol=1e-9)


def test_channel_law_with_per_link_spacings_matches_the_chain():
    """Per-link spacings: each free segment equals the distance between the channel mouths placed by
    the kinematics (A at (x_c, z_i + r_z) on link i-1, B at (x_c, z_{i+1} - r_z) on link i+1, Sec. II-B)."""
    g0 = default_geometry()
    p = tuple(1.21e-3 + 0.1e-3 * np.sin(np.arange(g0.n_joints - 1)))
    g = g0.replace(p=p)
    th = np.random.default_rng(2).uniform(-0.12, 0.12, g.n_joints)
    phi, O = K.link_origins(th, g)
    sp = C.segment_spacings(g)
    zj = np.concatenate([[-sp[0]], g.joint_z, [g.joint_z[-1] + sp[-1]]])     # virtual joints 0, n+1
    pad = np.concatenate([[0.0], th, [0.0]])
    total = C.cable_lengths(th, g, "exact")
    for col, side in enumerate(C.tendon_columns(g)):
        a, b = C.segment_joints(g.n_joints, side)
        seg = C.segment_length(pad[a], pad[b], g, side, p=sp[a])
        for i, (ja, jb) in enumerate(zip(a, b)):
            xc = side * g.r_x
            if 1 <= ja and jb <= g.n_joints:
                A = world([xc, zj[ja] + g.r_z], ja - 1, phi, O, g)
                B = world([xc, zj[jb] - g.r_z], jb, phi, O, g)
                assert np.linalg.norm(B - A) == pytest.approx(seg[i], abs=1e-15)
        assert total[col] == pytest.approx(C.rest_lengths(g)[col] + np.sum(seg - (sp[a] - 2 * g.r_z)),
                                           abs=1e-15)
    e = 1e-6
    P = C.coupling_matrix(th, g)
    for k in range(g.n_joints):
        d = np.zeros(g.n_joints)
        d[k] = e
        fd = (C.cable_lengths(th + d, g) - C.cable_lengths(th - d, g)) / (2 * e)
        np.testing.assert_allclose(P[k], fd, rtol=0, atol=1e-9)      # FD of 0.22 m totals
    with pytest.raises(ValueError, match="per-link spacings"):
        C.segment_length(0.0, 0.0, g)


def test_seed_with_equal_per_link_spacings_is_unchanged():
    g = default_geometry()
    ga = g.replace(p=(g.p,) * (g.n_joints - 1))
    th = np.random.default_rng(3).uniform(-0.14, 0.14, (3, g.n_joints))
    for model in ("exact", "simple", "min"):
        np.testing.assert_array_equal(C.cable_lengths(th, g, model), C.cable_lengths(th, ga, model))
    np.testing.assert_array_equal(C.coupling_matrix(th, g), C.coupling_matrix(th, ga))
    np.testing.assert_array_equal(C.cable_length_hessian(th, g), C.cable_length_hessian(th, ga))
    np.testing.assert_array_equal(C.coupling_matrix_simple(g), C.coupling_matrix_simple(ga))
    assert C.tendon_columns(g) == (C.RIGHT, C.LEFT)


def test_one_channel_tendon_is_a_column_of_the_two():
    g = default_geometry()
    th = np.random.default_rng(4).uniform(-0.14, 0.14, g.n_joints)
    gl = g.replace(tendons=("left",))
    np.testing.assert_array_equal(C.coupling_matrix(th, gl), C.coupling_matrix(th, g)[:, 1:])
    np.testing.assert_array_equal(C.cable_lengths(th, gl), C.cable_lengths(th, g)[1:])


def test_channel_law_needs_joints_on_the_axis():
    g = default_geometry().replace(backbone="section", inner_radius=2.0e-3)
    with pytest.raises(ValueError, match="tube axis"):
        C.coupling_matrix(np.zeros(g.n_joints), g, "exact")
    np.testing.assert_allclose(C.coupling_matrix_simple(g)[:, 0], -g.moment_arms(+1))
