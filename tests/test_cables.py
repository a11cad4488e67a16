"""Cable kinematics (Sec. II-B to II-D, Eqs. 2-5, Figs. 3-6)."""
import numpy as np
import pytest

from notchfit.physics import cables as C
from notchfit.physics import kinematics as K

OP = 0.14  # operating range |θ| ≤ 0.14 rad (Sec. II-B, Figs. 3-6)


def _grid(n=281, lim=OP):
    t = np.linspace(-lim, lim, n)
    return np.meshgrid(t, t, indexing="ij")


def test_fig3_nominal_segment_810um(geom):
    """Fig. 3 caption: nominal segment length p - 2 r_z = 810 µm."""
    for side in (C.RIGHT, C.LEFT):
        for f in (C.segment_length, C.segment_length_simple, C.segment_length_min):
            assert f(0.0, 0.0, geom, side) == pytest.approx(810e-6, abs=1e-12)


def test_sec2b_exact_vector_from_link_frames(geom, rng):
    """The exact L_Ri is the distance between the channel points carried by link frames g_si."""
    th = rng.uniform(-OP, OP, 27)
    g = K.link_frames(th, geom)
    rx, rz, p = geom.r_x, geom.r_z, geom.p
    for i in range(2, 26):  # segment over link i: exit on link i-1 at joint i, entrance on link i+1
        # link frame l has its origin at joint l, i.e. local z measured from (l-1)p
        A = g[i - 1] @ np.array([rx, 0, p + rz, 1])         # joint i is p above joint i-1
        B = g[i + 1] @ np.array([rx, 0, -rz, 1])
        A_l = g[i - 1] @ np.array([-rx, 0, p + rz, 1])
        B_l = g[i + 1] @ np.array([-rx, 0, -rz, 1])
        assert C.segment_length(th[i - 1], th[i], geom, C.RIGHT) == pytest.approx(
            np.linalg.norm(B - A), abs=1e-15)
        assert C.segment_length(th[i - 1], th[i], geom, C.LEFT) == pytest.approx(
            np.linalg.norm(B_l - A_l), abs=1e-15)


def test_sec2b_simplified_and_mirror(geom, rng):
    """L_RSi = p - (θ_i+θ_{i+1}) r_x - 2 r_z; left twin with +; L_L(θ) = L_R(-θ) (mirror)."""
    a, b = rng.uniform(-OP, OP, (2, 100))
    np.testing.assert_allclose(C.segment_length_simple(a, b, geom),
                               geom.p - (a + b) * geom.r_x - 2 * geom.r_z, atol=1e-18)
    np.testing.assert_allclose(C.segment_length_simple(a, b, geom, C.LEFT),
                               geom.p + (a + b) * geom.r_x - 2 * geom.r_z, atol=1e-18)
    np.testing.assert_allclose(C.segment_length(a, b, geom, C.LEFT), C.segment_length(-a, -b, geom),
                               atol=1e-18)
    # pulling the right cable shortens it for positive θ (geometry.md sign)
    assert C.segment_length(0.1, 0.1, geom) < C.segment_length(0.0, 0.0, geom)


def test_fig3_error_below_5um_nearly_everywhere(geom):
    """Fig. 3: |L_Ri - L_RSi| < 5 µm over nearly all of |θ_i|, |θ_{i+1}| ≤ 0.14.

    Measured on cell centres of a 1120 x 1120 grid: 93.9% of the square is below
    5 µm; the error is never negative and at most 6.28 µm (along the edges
    where θ_i or θ_{i+1} reaches +0.14 rad, cable side concave).
    """
    t = np.linspace(-OP, OP, 1121)
    tc = 0.5 * (t[1:] + t[:-1])
    a, b = np.meshgrid(tc, tc, indexing="ij")
    err = C.segment_length(a, b, geom) - C.segment_length_simple(a, b, geom)
    frac = np.mean(np.abs(err) < 5e-6)
    assert frac == pytest.approx(0.939, abs=0.001)
    assert err.min() > -1e-15
    assert 6.2e-6 < err.max() < 6.3e-6
    # inside |θ| ≤ 0.1 the claim holds everywhere
    inner = (np.abs(a) <= 0.1) & (np.abs(b) <= 0.1)
    assert np.abs(err[inner]).max() < 5e-6


def test_fig4_lower_bound(geom):
    """Fig. 4: L_DMi ≤ L_Ri, equal without side play; more play -> shorter."""
    a, b = _grid(141)
    L, Ldm = C.segment_length(a, b, geom), C.segment_length_min(a, b, geom)
    assert np.all(Ldm <= L + 1e-15)
    np.testing.assert_allclose(C.segment_length_min(a, b, geom, play=0.0), L, atol=1e-15)
    assert np.all(C.segment_length_min(a, b, geom, play=2e-4) <= Ldm + 1e-15)
    # brute force over the side positions of both ends (a coarse grid cannot beat it)
    play = geom.channel_radius - geom.cable_radius
    s = np.linspace(-play, play, 41)
    ta, tb = 0.12, 0.09
    best = np.inf
    for da in s:
        for db in s:
            A = np.array([np.cos(ta) * (geom.r_x + da) - np.sin(ta) * geom.r_z,
                          np.sin(ta) * (geom.r_x + da) + np.cos(ta) * geom.r_z])
            B = np.array([np.cos(tb) * (geom.r_x + db) + np.sin(tb) * (-geom.r_z),
                          geom.p - np.sin(tb) * (geom.r_x + db) + np.cos(tb) * (-geom.r_z)])
            best = min(best, np.linalg.norm(B - A))
    assert C.segment_length_min(ta, tb, geom) == pytest.approx(best, abs=1e-9)
    assert C.segment_length_min(ta, tb, geom) <= best + 1e-15


def test_fig5_bounds_bracket_simplified(geom):
    """Fig. 5: L_DMi ≤ L_RSi ≤ L_Ri over the operating range; worst error ~33 µm at the corner."""
    a, b = _grid(141)
    L, LS, Ldm = (f(a, b, geom) for f in (C.segment_length, C.segment_length_simple,
                                          C.segment_length_min))
    assert np.all(Ldm <= LS + 1e-15) and np.all(LS <= L + 1e-15)
    worst = np.maximum(np.abs(LS - L), np.abs(LS - Ldm))
    assert 30e-6 < worst.max() < 35e-6          # "somewhat higher" than Fig. 3 ...
    assert worst.max() < 0.05 * (geom.p - 2 * geom.r_z)   # ... but small against the segment (Fig. 6)


def test_eq2_eq3_totals(geom, geom5, rng):
    """Eqs. (2)-(3): L_R = L_R0 - r_x Σθ, L_L = L_L0 + r_x Σθ; L_R0 = offset + n p - 2 r_z."""
    for g in (geom, geom5):
        th = rng.uniform(-OP, OP, (5, g.n_joints))
        L0 = C.rest_lengths(g, offset=0.1)
        np.testing.assert_allclose(L0, 0.1 + g.n_joints * g.p - 2 * g.r_z)
        Ls = C.cable_lengths(th, g, "simple", offset=0.1)
        s = th.sum(-1)
        np.testing.assert_allclose(Ls[:, 0], L0[0] - g.r_x * s, rtol=0, atol=1e-15)
        np.testing.assert_allclose(Ls[:, 1], L0[1] + g.r_x * s, rtol=0, atol=1e-15)
        # straight: all models give L0; the default offset makes L0 = cable_L0
        for model in ("exact", "simple", "min"):
            np.testing.assert_allclose(C.cable_lengths(np.zeros(g.n_joints), g, model), g.cable_L0)
        # exact = sum of segment lengths (+ fixed channels), within µm of Eq. (2)
        Le = C.cable_lengths(th, g, "exact", offset=0.1)
        nseg = len(C.segment_joints(g.n_joints, C.RIGHT)[0])
        assert np.all(np.abs(Le - Ls) < nseg * 6.3e-6)
        assert np.all(C.cable_lengths(th, g, "min", offset=0.1) <= Le + 1e-15)


def test_sec2b_paper_sum_structure(geom):
    """Right cable: segments (θ_0=0, θ_1), (θ_2, θ_3), … (θ_26, θ_27); left (θ_1, θ_2), … (θ_27, 0)."""
    a, b = C.segment_joints(27, C.RIGHT)
    assert a[0] == 0 and b[0] == 1 and a[-1] == 26 and b[-1] == 27 and len(a) == 14
    a, b = C.segment_joints(27, C.LEFT)
    assert a[0] == 1 and a[-1] == 27 and b[-1] == 28 and len(a) == 14
    for side in (C.RIGHT, C.LEFT):
        a, b = C.segment_joints(27, side)
        joints = np.concatenate([a, b])
        assert sorted(joints[(joints >= 1) & (joints <= 27)]) == list(range(1, 28))
    # exact total = L0 + Σ (L_seg - nominal) with the virtual joints at 0
    th = np.linspace(-0.1, 0.12, 27)
    pad = np.concatenate([[0.0], th, [0.0]])
    a, b = C.segment_joints(27, C.RIGHT)
    tot = C.rest_lengths(geom)[0] + np.sum(C.segment_length(pad[a], pad[b], geom) - 810e-6)
    assert C.cable_lengths(th, geom)[0] == pytest.approx(tot, abs=1e-15)


def test_eq4_coupling_matrix_fd(geom, geom5, rng):
    """Eq. (4): P = ∂L/∂θ (analytic) equals central differences of the exact lengths."""
    h = 1e-6
    for g in (geom, geom5):
        th = rng.uniform(-OP, OP, g.n_joints)
        P = C.coupling_matrix(th, g)
        assert P.shape == (g.n_joints, 2)
        fd = np.stack([(C.cable_lengths(th + h * e, g) - C.cable_lengths(th - h * e, g)) / (2 * h)
                       for e in np.eye(g.n_joints)])
        np.testing.assert_allclose(P, fd, atol=1e-10)
        H = C.cable_length_hessian(th, g)
        fdH = np.stack([(C.coupling_matrix(th + h * e, g) - C.coupling_matrix(th - h * e, g)) / (2 * h)
                        for e in np.eye(g.n_joints)])          # (m, k, c)
        np.testing.assert_allclose(H, np.moveaxis(fdH, -1, 0), atol=1e-8)
    # vectorized
    th = rng.uniform(-OP, OP, (3, 4, 27))
    P = C.coupling_matrix(th, geom)
    assert P.shape == (3, 4, 27, 2)
    np.testing.assert_allclose(P[2, 1], C.coupling_matrix(th[2, 1], geom))


def test_eq5_simplified_coupling(geom, rng):
    """Eq. (5): P^T = r_x [[-1…-1],[1…1]]; the exact P is within 6% of it over |θ| ≤ 0.14."""
    Ps = C.coupling_matrix_simple(geom)
    np.testing.assert_array_equal(Ps.T, geom.r_x * np.array([[-1.0] * 27, [1.0] * 27]))
    np.testing.assert_allclose(C.coupling_matrix(np.zeros(27), geom), Ps, atol=1e-15)
    th = rng.uniform(-OP, OP, (200, 27))
    rel = np.abs(C.coupling_matrix(th, geom) - Ps).max() / geom.r_x
    assert rel < 0.06   # measured 5.3% worst case over 200 random configurations
    # the simple model's derivative is Eq. (5) exactly
    h = 1e-6
    fd = np.stack([(C.cable_lengths(th[0] + h * e, geom, "simple")
                    - C.cable_lengths(th[0] - h * e, geom, "simple")) / (2 * h) for e in np.eye(27)])
    np.testing.assert_allclose(fd, Ps, atol=1e-9)


def test_eq5_rank_and_nullspace(geom, rng):
    """Sec. II-C: rank P^T = 1; its nullspace = motions that keep Σθ (the tip orientation)."""
    Pt = C.coupling_matrix_simple(geom).T
    assert np.linalg.matrix_rank(Pt) == 1
    _, s, Vt = np.linalg.svd(Pt)
    null = Vt[1:]                       # 26 vectors spanning the right nullspace
    assert null.shape == (26, 27)
    np.testing.assert_allclose(null.sum(axis=1), 0.0, atol=1e-12)   # keep Σθ
    v = rng.normal(size=27)
    v -= v.mean()                       # any motion keeping Σθ ...
    np.testing.assert_allclose(Pt @ v, 0.0, atol=1e-16)             # ... keeps both lengths
    th = rng.uniform(-0.05, 0.05, 27)
    np.testing.assert_allclose(K.tip_pose(th + 1e-3 * v, geom)[2], K.tip_pose(th, geom)[2])


@pytest.mark.parametrize("bad", [np.full(27, np.nan), np.zeros(26), 0.1])
def test_bad_input(geom, bad):
    with pytest.raises(ValueError):
        C.cable_lengths(bad, geom)
    with pytest.raises(ValueError):
        C.coupling_matrix(bad, geom)


def test_bad_options(geom):
    with pytest.raises(ValueError, match="side"):
        C.segment_length(0.0, 0.0, geom, side=0)
    with pytest.raises(ValueError, match="model"):
        C.cable_lengths(np.zeros(27), geom, model="dijkstra")
    with pytest.raises(ValueError, match="play"):
        C.segment_length_min(0.0, 0.0, geom, play=-1e-4)
    with pytest.raises(ValueError, match="NaN"):
        C.segment_length(np.nan, 0.0, geom)
