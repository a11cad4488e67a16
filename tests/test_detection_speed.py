"""The detector's faster implementations give the same outputs as the straightforward numpy / OpenCV
formulations they replace (issue 25), bit for bit: the compiled loops over the refinement's edge profiles,
the working copy of an 8-bit image, the segmentation's one-pass threshold and its background fit, the
distance transforms cut to the box they are needed in, the disk closing by rectangles, the ridge radii's
histogram, the parts' areas and boxes counted from their labels, the labels' window maxima read at
listed pixels; and the grouped median is each group's median, through a layout shared by several value
sets as through one sort per call."""

import cv2
import numpy as np
import pytest
from scipy.special import erf

from notchfit.vision.detection._kernels import profile_crossings, profile_levels, surface_threshold
from notchfit.vision.detection.base import _distance_near
from notchfit.vision.detection.chain import _best


def _profiles(rng, n=400, n_t=12, step=0.5):
    """Blurred steps (either polarity, a streak on some), NaN outside each row's window and, on a few rows,
    inside it (the image border)."""
    t = np.arange(-n_t, n_t + 1) * step
    kp = rng.integers(3, n_t + 1, n)
    edge = rng.normal(0, 1.5, n)[:, None]
    prof = 40.0 + 160.0 * 0.5 * (1 + erf((t[None, :] - edge) / (np.sqrt(2) * rng.uniform(0.5, 2.5, n)[:, None])))
    prof += rng.normal(0, 2.0, prof.shape)
    streak = rng.random(n) < 0.2
    prof[streak, : n_t // 2] += 200.0
    prof = prof.astype(np.float32).astype(float)            # sampled from a float32 image
    prof[np.abs(np.arange(-n_t, n_t + 1))[None, :] > kp[:, None]] = np.nan
    cut = rng.random(n) < 0.05
    prof[cut, n_t + 1:] = np.nan
    return prof, kp, n_t, t


def _levels_numpy(prof, kp, n_t, cs):
    rows = np.arange(len(prof))
    lo_v = 0.5 * (prof[rows, n_t - kp] + prof[rows, n_t - kp + 1])
    hi_v = 0.5 * (prof[rows, n_t + kp] + prof[rows, n_t + kp - 1])
    idx = np.arange(prof.shape[1])[None, :]
    obj_side = (idx >= (n_t - kp)[:, None]) & (idx < n_t)
    smooth = cv2.blur(np.nan_to_num(prof).astype(np.float32), (3, 1), borderType=cv2.BORDER_REPLICATE)
    return (lo_v, hi_v, np.max(np.where(obj_side, cs * smooth, -np.inf), axis=1),
            np.min(np.where(obj_side, cs * smooth, np.inf), axis=1))


def _crossings_numpy(prof, lo_c, den, t, step, rise_step):
    rows = np.arange(len(prof))
    with np.errstate(invalid="ignore", divide="ignore"):
        qa = (prof - lo_c[:, None]) / den[:, None]
        q_peak = np.max(np.where(t[None, :] > 0, np.nan_to_num(qa, nan=-np.inf), -np.inf), axis=1)
        cr = (qa[:, :-1] < 0.5) & (qa[:, 1:] >= 0.5)
    dist = np.where(cr, np.abs(0.5 * (t[:-1] + t[1:]))[None, :], np.inf)
    j = np.argmin(dist, axis=1)
    q0, q1 = qa[rows, j], qa[rows, j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = t[j] + (0.5 - q0) / (q1 - q0) * step
    qv = np.nan_to_num(qa, nan=-1.0)
    pos = []
    for lvl in (0.25, 0.75):
        i1 = np.argmax(qv >= lvl, axis=1)
        i0 = np.maximum(i1 - 1, 0)
        a0, a1 = qv[rows, i0], qv[rows, i1]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            pos.append(t[i0] + np.where(a1 > a0, (lvl - a0) / (a1 - a0), 0.0) * rise_step)
    wd = pos[1] - pos[0]
    return qa, np.isfinite(qa).sum(1), q_peak, tc, np.isfinite(dist[rows, j]), np.where(np.isfinite(wd) & (wd > 0),
                                                                                       wd, np.nan)


def _ragged(prof, kp, n_t):
    """Each row's window, one after the other (float32, as sampled), and where each starts."""
    n_w = 2 * kp + 1
    values = np.concatenate([prof[i, n_t - k:n_t + k + 1] for i, k in enumerate(kp)]).astype(np.float32)
    return values, np.cumsum(n_w) - n_w


@pytest.mark.parametrize("short", [False, True])
@pytest.mark.parametrize("cs", [1.0, -1.0])
def test_profile_levels_equal_the_numpy_formulation(cs, short):
    """Bit for bit; ``short``: windows of 1 to 3 samples each side (the 3-sample means reach the NaN
    outside them), some as long as the axis (its ends replicated)."""
    rng = np.random.default_rng(1)
    prof, kp, n_t, t = _profiles(rng)
    if short:
        kp = np.where(rng.random(len(kp)) < 0.8, np.minimum(kp, rng.integers(1, 4, len(kp))), n_t)
        prof = prof.copy()
        prof[np.abs(np.arange(-n_t, n_t + 1))[None, :] > kp[:, None]] = np.nan
    values, start = _ragged(prof, kp, n_t)
    for got, want in zip(profile_levels(values, start, kp, n_t, len(t), cs), _levels_numpy(prof, kp, n_t, cs)):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)


def test_profile_crossings_equal_the_numpy_formulation():
    """Every output bit for bit, on rows with levels from their own ends, a zero span and NaN levels; the
    largest background sample where a row has an infinite one stands in the comparison the detector makes."""
    rng = np.random.default_rng(2)
    prof, kp, n_t, t = _profiles(rng)
    rows = np.arange(len(prof))
    lo_c = 0.5 * (prof[rows, n_t - kp] + prof[rows, n_t - kp + 1]) + rng.normal(0, 3, len(prof))
    den = 0.5 * (prof[rows, n_t + kp] + prof[rows, n_t + kp - 1]) - lo_c
    den[::37], lo_c[::53] = 0.0, np.nan
    step = t[1] - t[0]
    order = np.argsort(np.abs(0.5 * (t[:-1] + t[1:])), kind="stable")
    values, start = _ragged(prof, kp, n_t)
    got = profile_crossings(values, start, kp, lo_c, den, t, order, step, 0.5)
    want = _crossings_numpy(prof, lo_c, den, t, step, 0.5)[1:]
    for k in (0, 2, 3, 4):
        np.testing.assert_array_equal(got[k], want[k])
    assert got[3].sum() > 0.8 * len(prof)
    for level in (0.9, 0.5, -1e300):
        with np.errstate(invalid="ignore"):
            np.testing.assert_array_equal(got[1] > level, want[1] > level)


def test_profile_maps_hold_each_window_as_the_numpy_formulation():
    """The maps hold every profile's window in turn (float64 positions rounded to float32), rows of the given
    width, the rest outside the image."""
    from notchfit.vision.detection._kernels import profile_maps

    rng = np.random.default_rng(3)
    base, nrm = rng.uniform(0, 500, (300, 2)), rng.normal(size=(300, 2))
    kp = rng.integers(1, 16, 300)
    t = np.arange(-15, 16) * 0.37
    n = int(np.sum(2 * kp + 1))
    for a, m in enumerate(profile_maps(base, nrm, t, kp, 15, 1000)):
        assert m.shape == (-(-n // 1000), 1000) and m.dtype == np.float32
        dense = (base[:, a, None] + t[None, :] * nrm[:, a, None]).astype(np.float32)
        np.testing.assert_array_equal(m.ravel()[:n], _ragged(dense, kp, 15)[0])
        assert (m.ravel()[n:] < -1).all()


@pytest.mark.parametrize("channels", [0, 3])
@pytest.mark.parametrize("f", [2, 3, 5, 8, 16])
def test_working_copy_of_an_8bit_image_equals_the_float_one(f, channels):
    """Block means read from the 8-bit pixels equal OpenCV's area resize of the float copy, bit for bit
    (trailing rows and columns that fill no block dropped), gray and colour."""
    from notchfit.vision.detection.segment import downsample

    shape = (203 + f, 317 + 2 * f) + ((channels,) if channels else ())
    img = np.random.default_rng(f).integers(0, 256, shape, dtype=np.uint8)
    got = downsample(img, f)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, downsample(img.astype(np.float32), f))


def test_group_median_is_each_groups_median():
    """Groups in any order, NaN and infinities ignored, an empty group NaN, even and odd counts."""
    from notchfit.vision.detection.lines import group_median

    rng = np.random.default_rng(4)
    g = rng.integers(0, 40, 3000)
    v = np.round(rng.normal(0, 5, 3000), 1)               # ties within groups
    v[rng.random(3000) < 0.05] = np.nan
    v[rng.random(3000) < 0.01] = np.inf
    got = group_median(v, g, 41)
    for k in range(41):
        vals = v[(g == k) & np.isfinite(v)]
        assert (np.isnan(got[k]) and not len(vals)) or got[k] == np.median(vals)


def _group_median_one_sort(values, groups, n_groups):
    """The grouped median as the refinement took it before the group layout: one stable sort of the group
    plus the value scaled below 1, per call."""
    fin = np.isfinite(values)
    v, g = values[fin], groups[fin]
    out = np.full(n_groups, np.nan)
    if not len(v):
        return out
    lo, hi = float(v.min()), float(v.max())
    key = g + (v - lo) * (0.999 / (hi - lo) if hi > lo else 0.0)
    vs = v[np.argsort(key, kind="stable")]
    cnt = np.bincount(g, minlength=n_groups)
    start = np.cumsum(cnt) - cnt
    has = cnt > 0
    out[has] = 0.5 * (vs[start[has] + (cnt[has] - 1) // 2] + vs[start[has] + cnt[has] // 2])
    return out


@pytest.mark.parametrize("ordered", [True, False])
@pytest.mark.parametrize("one_long_edge", [False, True])
def test_group_median_with_a_shared_layout_equals_the_one_sort_median(ordered, one_long_edge):
    """Several value sets over the same edges (levels, slopes, their deviations: float32 image samples, NaN
    where a profile is not used, ties) take the same medians through one :func:`group_layout` as through
    the single sort per call the refinement used before, bit for bit; with the profiles in edge order (as
    sampled) and shuffled, and with one edge far longer than the rest (the sorted-pairs path)."""
    from notchfit.vision.detection.lines import group_layout, group_median

    rng = np.random.default_rng(11)
    n_edges = 116
    n_per = rng.integers(0, 90, n_edges)
    n_per[7] = 0                                                  # an edge without profiles
    if one_long_edge:
        n_per[3] = 40000
    edge = np.repeat(np.arange(n_edges), n_per)
    if not ordered:
        edge = rng.permutation(edge)
    lay = group_layout(edge, n_edges)
    assert lay.table is not one_long_edge and (lay.order is None) is ordered
    n = len(edge)
    for scale in (1.0, 0.01, 300.0):
        for _ in range(3):
            v = (rng.normal(0, scale, n) + rng.normal(0, scale, n_edges)[edge]).astype(np.float32).astype(float)
            v[rng.random(n) < 0.1] = np.nan
            v[rng.random(n) < 0.2] = v[0]                          # ties across and within edges
            v[rng.random(n_edges)[edge] < 0.05] = np.nan           # edges whose profiles are all unused
            want = _group_median_one_sort(v, edge, n_edges)
            np.testing.assert_array_equal(group_median(v, edge, n_edges, layout=lay), want)
            np.testing.assert_array_equal(group_median(v, edge, n_edges), want)
    assert np.isnan(group_median(np.full(n, np.nan), edge, n_edges, layout=lay)).all()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_surface_threshold_equals_the_numpy_broadcasts(dtype):
    """The background surface, the deviation from it and both thresholds in one pass equal the numpy
    formulation (float32 surface, Python-float thresholds cast as numpy casts them), ties included."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        hs, ws = (int(v) for v in rng.integers(20, 200, 2))
        small = rng.normal(100, 30, (hs, ws)).astype(dtype)
        c = rng.normal(0, 50, 6).astype(np.float32)
        sign = np.float32(rng.choice([-1.0, 1.0]))
        X = (np.arange(ws, dtype=np.float32) / ws - 0.5)[None, :]
        Y = (np.arange(hs, dtype=np.float32) / hs - 0.5)[:, None]
        bg = (c[0] + c[1] * X + c[3] * X * X) + (c[2] * Y + c[5] * Y * Y) + c[4] * (Y * X)
        dev = (small - bg) * sign
        hi, lo = float(dev[rng.integers(hs), rng.integers(ws)]), -abs(float(rng.normal(10, 5)))   # a tie at hi
        ref = ((dev > hi) | (dev < lo)).astype(np.uint8)
        X, Y = X[0], Y[:, 0]
        got = surface_threshold(small, c[0] + c[1] * X + c[3] * X * X, c[2] * Y + c[5] * Y * Y, X, Y, c[4], sign,
                                small.dtype.type(hi), small.dtype.type(lo))
        np.testing.assert_array_equal(got, ref)


def test_distance_cut_to_its_box_equals_the_full_transform():
    """Up to the reach, the 5x5 chamfer distance computed in the box around the mask equals the whole
    image's, and it is above the reach exactly where the whole image's is (sparse and solid masks)."""
    rng = np.random.default_rng(6)
    for k in range(100):
        h, w = rng.integers(30, 250, 2)
        m = np.zeros((h, w), np.uint8)
        for _ in range(rng.integers(1, 5)):
            cv2.circle(m, (int(rng.integers(w)), int(rng.integers(h))), int(rng.integers(1, 20)), 1, -1)
        if k % 2:
            m &= (rng.random((h, w)) > 0.3).astype(np.uint8)
        reach = float(rng.uniform(1, 30))
        full = cv2.distanceTransform(1 - m, cv2.DIST_L2, cv2.DIST_MASK_5)
        got = _distance_near(m, reach)
        near = full <= reach
        np.testing.assert_array_equal(got <= reach, near)
        np.testing.assert_array_equal(got[near], full[near])


def test_closings_sharing_the_distance_to_the_region_equal_separate_ones():
    """A series of disk closings that takes its dilation's distances from one transform of the most padded
    copy equals closings computed one by one, bit for bit (a region touching the image border included)."""
    from notchfit.vision.detection.width import _close_disk, _distance_to

    rng = np.random.default_rng(7)
    for k in range(20):
        h, w = (int(v) for v in rng.integers(40, 200, 2))
        m = np.zeros((h, w), np.uint8)
        for _ in range(rng.integers(1, 6)):
            cv2.circle(m, (int(rng.integers(w)), int(rng.integers(h))), int(rng.integers(2, 25)), 1, -1)
        m &= (rng.random((h, w)) > 0.05 * (k % 3)).astype(np.uint8)
        near = _distance_to(m, 30)
        for r in (1, 2, 3, 6, 12, 28):
            a, pa = _close_disk(m, r)
            b, pb = _close_disk(m, r, near=near)
            assert pa == pb
            np.testing.assert_array_equal(a, b)


def _width_crossings_numpy(t, P, level, t0, sign):
    """The numpy formulation of the width profiles' nearest crossing (the reference)."""
    q = sign * (P - level[:, None])
    with np.errstate(invalid="ignore"):
        cr = (q[:, :-1] < 0) & (q[:, 1:] >= 0)
    d = np.where(cr, np.abs(t[None, :-1] - t0[:, None]), np.inf)
    j = np.argmin(d, axis=1)
    rows = np.arange(len(P))
    q0, q1 = q[rows, j], q[rows, j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = t[j] + (0 - q0) / (q1 - q0) * (t[j + 1] - t[j])
    return np.where(np.isfinite(d[rows, j]), tc, np.nan)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_width_profile_crossings_equal_the_numpy_formulation(sign):
    """Several crossings per row (the nearest taken, ties to the first), none, NaN samples (outside the
    image), an infinite level (no level fitted) and a NaN centre."""
    from notchfit.vision.detection.width import _crossings

    rng = np.random.default_rng(8)
    prof, _, _, t = _profiles(rng)
    prof[:, ::7] += rng.normal(0, 60, prof[:, ::7].shape)           # extra crossings
    level = rng.uniform(60, 180, len(prof))
    level[rng.random(len(prof)) < 0.05] = np.inf
    t0 = np.round(rng.normal(0, 2, len(prof)) * 2) / 2               # on the samples: equidistant ties
    t0[rng.random(len(prof)) < 0.03] = np.nan
    np.testing.assert_array_equal(_crossings(t, prof, level, t0, sign), _width_crossings_numpy(t, prof, level, t0, sign))


def _line_levels_numpy(t, P, t0, win):
    """The width profiles' straight-line levels as numpy formulates them (the reference of the compiled
    :func:`notchfit.vision.detection._kernels.line_levels`)."""
    x = t[None, :] - t0[:, None]
    m = (x >= win[0]) & (x <= win[1]) & np.isfinite(P)
    n = m.sum(1)
    Pz = np.where(m, P, 0.0)
    xz = np.where(m, x, 0.0)
    sx, sy = xz.sum(1), Pz.sum(1)
    sxx, sxy = (xz * xz).sum(1), (xz * Pz).sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        den = n * sxx - sx * sx
        b = np.where(np.abs(den) > 1e-12, (n * sxy - sx * sy) / den, 0.0)
        a0 = (sy - b * sx) / n
    return np.where(n >= 3, a0, np.nan), b


@pytest.mark.parametrize("n", [5, 40, 129, 641, 1500])
def test_width_line_levels_equal_the_numpy_formulation(n):
    """Row lengths below, inside and beyond one block of numpy's pairwise sums; windows anywhere (one or two
    samples, across a block's end, none), NaN samples (outside the image), a NaN centre, whole rows."""
    from notchfit.vision.detection.width import _line_levels

    rng = np.random.default_rng(n)
    t = np.arange(n) * 0.5 - 0.25 * n
    P = rng.normal(100, 40, (60, n)) * 10.0 ** rng.uniform(-3, 3, (60, 1))
    P[rng.random(P.shape) < 0.05] = np.nan
    t0 = rng.uniform(t[0] - 5, t[-1] + 5, 60)
    t0[3] = np.nan
    for win in ((2.0, 9.5), (-9.5, -2.0), (0.0, 0.5), (-1e9, 1e9), (3.0, 2.0)):
        a, b = _line_levels(t, P, t0, win)
        a_ref, b_ref = _line_levels_numpy(t, P, t0, win)
        np.testing.assert_array_equal(a, a_ref)
        np.testing.assert_array_equal(b, b_ref)


def _edges_numpy(t, P, t0, obj_win, bg_win, sign, rising=True):
    """The width profiles' 50 % crossings between straight-line levels as numpy formulates them (the
    reference of the compiled :func:`notchfit.vision.detection._kernels.level_crossings`)."""
    a_o, b_o = _line_levels_numpy(t, P, t0, obj_win)
    a_b, b_b = _line_levels_numpy(t, P, t0, bg_win)
    tc = t0.astype(float)
    s = sign if rising else -sign
    for _ in range(3):
        mid = 0.5 * (a_o + b_o * (tc - t0) + a_b + b_b * (tc - t0))
        tc = _width_crossings_numpy(t, P, np.nan_to_num(mid, nan=np.inf), t0, s)
        tc = np.where(np.isfinite(tc), tc, t0)
    return _width_crossings_numpy(t, P, np.nan_to_num(0.5 * (a_o + b_o * (tc - t0) + a_b + b_b * (tc - t0)),
                                                          nan=np.inf), t0, s)


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("rising", [True, False])
def test_width_edges_equal_the_numpy_formulation(sign, rising):
    """Rising and falling edges of either polarity with shading, NaN samples (outside the image), a NaN
    centre, rows without an edge, windows with too few samples."""
    from notchfit.vision.detection.width import _edges

    rng = np.random.default_rng(11)
    t = np.arange(-160, 160.5, 0.5)
    pos = rng.normal(0, 3, 40)
    prof = 100 + 60 * sign * erf((t[None, :] - pos[:, None]) / 2.0) * (1 if rising else -1)
    prof += rng.normal(0, 2, prof.shape) + 0.05 * t[None, :] * rng.normal(0, 1, (40, 1))
    prof[rng.random(prof.shape) < 0.02] = np.nan
    prof[5] = 100.0
    t0 = np.round(pos + rng.normal(0, 1.5, 40))
    t0[7] = np.nan
    for obj_win, bg_win in (((4.0, 10.0), (-10.0, -4.0)), ((-10.0, -4.0), (4.0, 10.0)), ((4.0, 4.2), (-1.0, -0.9))):
        np.testing.assert_array_equal(_edges(t, prof, t0, obj_win, bg_win, sign, rising),
                                      _edges_numpy(t, prof, t0, obj_win, bg_win, sign, rising))


def test_disk_closing_by_rectangles_equals_the_elliptic_kernel():
    """The closing by the union of rectangles equals OpenCV's closing by its elliptic kernel, bit for bit,
    on 0/1 masks and on gray images, radius 1 to 40."""
    from notchfit.vision.detection.segment import close_disk, disk_rectangles

    rng = np.random.default_rng(8)
    for r in range(1, 41):
        ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)
        union = np.zeros_like(ker)
        for a, b in disk_rectangles(r):
            union[r - b:r + b + 1, r - a:r + a + 1] = 1
        np.testing.assert_array_equal(union, ker)
        for img in ((rng.random((40 + r, 90)) < 0.2).astype(np.uint8), rng.integers(0, 256, (50, 70), dtype=np.uint8)):
            pad = r + 2
            big = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
            ref = cv2.morphologyEx(big, cv2.MORPH_CLOSE, ker)[pad:-pad, pad:-pad]
            np.testing.assert_array_equal(close_disk(img, r), ref)


def test_background_surface_gathered_by_index_equals_the_boolean_formulation():
    """The background surface's fit from rows gathered by index equals the boolean-mask formulation to the
    last bit (the same BLAS product: a matrix times a copy of itself)."""
    from notchfit.vision.detection.segment import _surface

    rng = np.random.default_rng(9)
    for _ in range(20):
        n = int(rng.integers(60, 7000))
        A, vals = rng.normal(size=(n, 6)), rng.normal(100, 30, n)
        sel = rng.random(n) < rng.uniform(0.05, 1.0)
        As = A[sel]
        ref = np.linalg.solve(As.T @ A[sel] + 1e-9 * np.eye(6), As.T @ vals[sel])
        np.testing.assert_array_equal(_surface(A, vals, sel), ref)


def _random_lines(rng, size, count, width):
    """A 0/1 mask (h, w in ``size``) with ``count`` random straight lines ``width`` px wide (half-open ranges)."""
    h, w = (int(v) for v in rng.integers(*size, 2))
    m = np.zeros((h, w), np.uint8)
    for _ in range(rng.integers(*count)):
        p0, p1 = rng.integers(0, [w, h]), rng.integers(0, [w, h])
        cv2.line(m, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), 1, int(rng.integers(*width)))
    return m


def test_ridge_peaks_equal_the_histogram_formulation():
    """The ridge radii from unit-bin counts, the closed band's transform cut to its box and the medians read
    from the sorted values equal those from ``np.histogram``, the whole padded transform and boolean
    selections (random bands and blobs, some touching the border, closings 1 to 30 px, the dilation's
    distances shared or not)."""
    import math

    from notchfit.vision.detection import width

    def reference(region, close_px, min_radius_px=2.0, peak_fraction=0.3):
        closed, pad = width._close_disk(region, max(int(close_px), 1))
        dt = cv2.distanceTransform(closed, cv2.DIST_L2, 5)[pad:-pad, pad:-pad]
        v = dt[width._ridge(dt) & (dt >= min_radius_px)]
        if len(v) < 10:
            return []
        h, edges = np.histogram(v, bins=np.arange(0, int(math.ceil(v.max())) + 3, 1.0))
        h = np.convolve(h, [0.25, 0.5, 0.25], mode="same")
        peaks = [i for i in range(1, len(h) - 1) if h[i] >= h[i - 1] and h[i] >= h[i + 1] and h[i] > 0]
        top = max((h[i] for i in peaks), default=0)
        return [float(np.median(v[(v >= edges[max(i - 1, 0)]) & (v < edges[min(i + 2, len(edges) - 1)])])) + 0.5
                for i in peaks if h[i] >= peak_fraction * top]

    rng = np.random.default_rng(10)
    for k in range(30):
        m = _random_lines(rng, (40, 160), (1, 4), (3, 25))
        h, w = m.shape
        cv2.circle(m, (int(rng.integers(w)), int(rng.integers(h))), int(rng.integers(2, 20)), 1, -1)
        near = width._distance_to(m, 32) if k % 3 else None
        for c in (1, 3, 7, 12, 21, 30):
            assert width.ridge_peaks(m, c, peak_fraction=0.05 if k % 2 else 0.3, near=near) == \
                reference(m, c, peak_fraction=0.05 if k % 2 else 0.3)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_sorted_median_equals_numpys(dtype):
    """Odd and even counts, repeated values, one value."""
    from notchfit.vision.detection.width import sorted_median

    rng = np.random.default_rng(13)
    for n in list(range(1, 40)) + [1001, 1002]:
        v = np.sort(rng.normal(5, 3, n).astype(dtype) if n % 3 else np.round(rng.normal(5, 3, n)).astype(dtype))
        got, want = sorted_median(v), np.median(v)
        assert got.dtype == want.dtype and got == want


def test_distance_in_box_equals_the_full_transform():
    """Masks away from the border, touching it, and empty."""
    from notchfit.vision.detection.width import _distance_in_box

    rng = np.random.default_rng(14)
    for k in range(40):
        m = _random_lines(rng, (20, 200), (0 if k == 0 else 1, 4), (1, 20))
        if k % 2:
            m[:3], m[-3:], m[:, :3], m[:, -3:] = 0, 0, 0, 0
        np.testing.assert_array_equal(_distance_in_box(m), cv2.distanceTransform(m, cv2.DIST_L2, 5))


def test_largest_region_equals_the_statistics_formulation():
    """The largest region from labels and counted areas equals the one from OpenCV's statistics pass, and
    the labels of the two OpenCV calls are the same (masks of many parts, ties in area included)."""
    from notchfit.vision.detection.segment import largest_region

    def reference(mask):
        ext, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        x0, y0, bw, bh = cv2.boundingRect(max(ext, key=cv2.contourArea))
        _, lab, st, _ = cv2.connectedComponentsWithStats(np.ascontiguousarray(mask[y0:y0 + bh, x0:x0 + bw]),
                                                         connectivity=8)
        out = np.zeros_like(mask)
        out[y0:y0 + bh, x0:x0 + bw] = lab == 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
        return out, (x0, y0, bw, bh)

    rng = np.random.default_rng(11)
    for k in range(60):
        h, w = (int(v) for v in rng.integers(20, 700, 2))
        m = (rng.random((h, w)) < rng.uniform(0.05, 0.6)).astype(np.uint8)
        if k % 2:
            m = cv2.morphologyEx(m, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        if not m.any():
            continue
        n, lab, st, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        n2, lab2 = cv2.connectedComponents(m, connectivity=8)
        assert n == n2
        np.testing.assert_array_equal(lab, lab2)
        np.testing.assert_array_equal(np.bincount(lab2.ravel(), minlength=n2), st[:, cv2.CC_STAT_AREA])
        got, want = largest_region(m), reference(m)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]


def test_remove_thin_with_boxes_from_labels_equals_the_statistics_formulation():
    """Thin parts' boxes from their labels (``scipy.ndimage.find_objects``) remove the same parts as the
    boxes of OpenCV's statistics pass (random lines 1 to 14 px wide)."""
    from notchfit.vision.detection.segment import remove_thin

    def reference(m, thin_px, max_length_px):
        r = max(int(round(0.35 * thin_px)), 1)
        opened = cv2.morphologyEx(m, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        n, lab, st, _ = cv2.connectedComponentsWithStats((m & (1 - opened)).astype(np.uint8), connectivity=8)
        if n <= 1:
            return m
        long_ = np.hypot(st[:, cv2.CC_STAT_WIDTH], st[:, cv2.CC_STAT_HEIGHT]) > max_length_px
        long_[0] = False
        return (m & ~long_[lab]).astype(np.uint8)

    rng = np.random.default_rng(12)
    for _ in range(100):
        m = _random_lines(rng, (20, 400), (1, 8), (1, 15))
        thin, length = rng.uniform(2, 20), rng.uniform(3, 80)
        np.testing.assert_array_equal(remove_thin(m, thin_px=thin, max_length_px=length), reference(m, thin, length))


def test_centreline_from_the_scale_searchs_slots_equals_its_own():
    """The band's slots that :func:`tube_band` found (in the region's trimmed box) give the same centreline
    points as slots found again in the whole region (slotted bands at random places and angles, some cut by
    the border, with a clamp's bar; the slots' labels in the box are the whole region's)."""
    from notchfit.physics.geometry import Geometry
    from notchfit.vision.detection import width

    g = Geometry(n_joints=5, p=1.6e-3, outer_radius=1e-3, slot_width=0.8e-3, slot_depth=1.6e-3, slot_sides=(1,) * 5,
                 mount_half_width=None, mount_bottom_z=None, name="t", inner_radius=0.7e-3, tendons=("right",),
                 tendon_path="lumen", r_x=None, r_z=None, cable_radius=None, channel_radius=None)
    rng = np.random.default_rng(15)
    kw = dict(slot_width=0.8e-3, slot_depth=1.6e-3, radius=1e-3, close_factor=1.25, area_range=(0.3, 2.5))
    found = 0
    for k in range(16):
        m = np.zeros((300, 420), np.uint8)
        m[50:80, 180:420 if k % 2 else 380] = 1                          # a clamp's bar, to the border or not
        tube = np.zeros((400, 400), np.uint8)
        R = float(rng.uniform(8, 12))
        tube[40:360 if k % 3 else 400, 200 - int(R):200 + int(R)] = 1
        for j in range(5):
            v = 100 + int(2.6 * R) * j
            tube[v:v + int(0.8 * R), 200 + int(R) - int(1.6 * R):200 + int(R)] = 0
        rot = cv2.getRotationMatrix2D((200, 200), float(rng.uniform(-40, 40)), 1.0)
        rot[:, 2] += rng.uniform(-60, 60, 2) + [10, -50]
        m |= cv2.warpAffine(tube, rot, (420, 300), flags=cv2.INTER_NEAREST)
        region = m
        r, n, gaps, _ = width.tube_band(region, g, max_close_px=26, close_factor=1.25, area_range=(0.3, 2.5))
        if gaps is None:
            continue
        found += 1
        box = width.trim_box(region)
        closed, lab, ids = width._slot_gaps(region, r, **kw)
        assert ids == gaps.ids
        np.testing.assert_array_equal(closed[box], gaps.closed)
        np.testing.assert_array_equal(lab[box], gaps.lab)
        outside = np.ones(region.shape, bool)
        outside[box] = False
        assert not closed[outside].any() and not lab[outside].any()
        want = width.band_centreline(region, r, **kw)
        got = width.band_centreline(region, r, gaps=gaps, **kw)
        assert len(want) > 0
        np.testing.assert_array_equal(got, want)
    assert found >= 10


def test_components_with_stats_equal_opencvs():
    """Labels, boxes, areas and centroids bit for bit (sparse and dense masks, parts on the border, an empty
    mask, a mask without background)."""
    from notchfit.vision.detection.segment import components_with_stats

    rng = np.random.default_rng(16)
    masks = [np.zeros((7, 9), np.uint8), np.ones((5, 8), np.uint8)]
    for k in range(60):
        h, w = (int(v) for v in rng.integers(5, 400, 2))
        m = (rng.random((h, w)) < rng.uniform(0.01, 0.7)).astype(np.uint8)
        masks.append(cv2.morphologyEx(m, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) if k % 2 else m)
    for m in masks:
        got, want = components_with_stats(m), cv2.connectedComponentsWithStats(m, connectivity=8)
        assert got[0] == want[0]
        for a, b in zip(got[1:], want[1:]):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("half", [1, 2])
def test_window_max_at_listed_pixels_equals_the_dilated_labels(half):
    """The largest label in each listed pixel's window equals OpenCV's dilation of the float32 label image
    read there (pixels on and next to every border listed, labels of touching parts, an image one pixel
    high), as the slot search read it before."""
    from notchfit.vision.detection.segment import window_max_at

    rng = np.random.default_rng(17)
    ker = np.ones((2 * half + 1, 2 * half + 1), np.uint8)
    for k in range(40):
        h, w = (1, int(rng.integers(2, 30))) if k == 0 else (int(v) for v in rng.integers(2, 120, 2))
        m = (rng.random((h, w)) < rng.uniform(0.05, 0.6)).astype(np.uint8)
        _, lab = cv2.connectedComponents(m, connectivity=8 if k % 2 else 4)
        n = int(rng.integers(1, 3 * h * w))
        ys, xs = rng.integers(0, h, n), rng.integers(0, w, n)
        want = cv2.dilate(lab.astype(np.float32), ker).astype(np.intp)[ys, xs]
        got = window_max_at(lab, ys, xs, half=half)
        assert got.dtype == lab.dtype
        np.testing.assert_array_equal(got, want)


def _band_mask(rng):
    """A slotted band at a random angle, with blobs and lines (uint8)."""
    m = _random_lines(rng, (60, 260), (1, 3), (8, 30))
    h, w = m.shape
    for _ in range(int(rng.integers(0, 8))):
        p = rng.integers(0, [w, h])
        cv2.circle(m, (int(p[0]), int(p[1])), int(rng.integers(2, 6)), 0, -1)
    return m


def test_band_directions_read_where_coherent_equal_the_whole_field():
    """The directions computed only at the coherent pixels (the only ones read) equal those of the whole
    field, bit for bit (random bands with holes, radii 3 to 15 px)."""
    from notchfit.vision.detection.segment import band_directions, close_disk, fill_holes

    def reference(mask, bridge_px, radius_px, min_coherence=0.8):
        band = fill_holes(close_disk(mask, max(int(round(bridge_px)), 1))).astype(np.float32)
        k = max(1, int(radius_px // 4))
        h, w = band.shape
        small = cv2.resize(band, (max(w // k, 1), max(h // k, 1)), interpolation=cv2.INTER_AREA) if k > 1 else band
        s1, s2 = max(0.5 * radius_px / k, 0.7), max(float(radius_px) / k, 1.0)
        b = cv2.GaussianBlur(small, (0, 0), s1)
        gx, gy = cv2.Sobel(b, cv2.CV_32F, 1, 0), cv2.Sobel(b, cv2.CV_32F, 0, 1)
        jxx, jxy, jyy = (cv2.GaussianBlur(v, (0, 0), s2) for v in (gx * gx, gx * gy, gy * gy))
        if k > 1:
            jxx, jxy, jyy = (cv2.resize(v, (w, h), interpolation=cv2.INTER_LINEAR) for v in (jxx, jxy, jyy))
        ang = (0.5 * np.arctan2(2 * jxy, jxx - jyy)) % np.float32(np.pi)
        coherent = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) >= min_coherence * np.maximum(jxx + jyy, 1e-12)
        if not coherent.any():
            return np.full(mask.shape, np.nan, np.float32)
        _, lab = cv2.distanceTransformWithLabels((~coherent).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        src = np.zeros(int(lab.max()) + 1, np.float32)
        src[lab[coherent]] = ang[coherent]
        return src[lab]

    rng = np.random.default_rng(17)
    for _ in range(25):
        m = _band_mask(rng)
        bridge, radius = float(rng.uniform(1, 8)), float(rng.uniform(3, 15))
        np.testing.assert_array_equal(band_directions(m, bridge, radius), reference(m, bridge, radius))


def test_thin_lines_filled_from_opencvs_pixel_list_equal_the_boolean_formulation():
    """The closing's added pixels listed by ``cv2.findNonZero`` fill the same pixels as ``np.nonzero`` of the
    comparison (random bands with holes and thin gaps, with and without the directions across)."""
    from notchfit.vision.detection.segment import band_directions, fill_thin_lines

    def reference(mask, length_px, n_dirs=8, *, across=None, tol_deg=25.0):
        L = int(max(3, round(length_px)))
        L += 1 - L % 2
        pad = L
        big = cv2.copyMakeBorder(mask, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
        out = big.copy()
        c = L // 2
        tol = np.radians(tol_deg)
        for k in range(n_dirs):
            a = np.pi * k / n_dirs
            ker = np.zeros((L, L), np.uint8)
            d = np.array([np.cos(a), np.sin(a)]) * (L // 2)
            cv2.line(ker, (int(round(c - d[0])), int(round(c - d[1]))), (int(round(c + d[0])), int(round(c + d[1]))), 1)
            closed = cv2.morphologyEx(big, cv2.MORPH_CLOSE, ker)
            if across is not None:
                yy, xx = np.nonzero(closed[pad:-pad, pad:-pad] > big[pad:-pad, pad:-pad])
                diff = np.abs((across[yy, xx] - a + np.pi / 2) % np.pi - np.pi / 2)
                out[yy[diff <= tol] + pad, xx[diff <= tol] + pad] = 1
                continue
            out |= closed
        return out[pad:-pad, pad:-pad]

    rng = np.random.default_rng(18)
    for k in range(25):
        m = _band_mask(rng)
        h, w = m.shape
        for _ in range(3):                                   # thin background lines across
            p0, p1 = rng.integers(0, [w, h]), rng.integers(0, [w, h])
            cv2.line(m, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), 0, int(rng.integers(1, 3)))
        across = band_directions(m, 4.0, float(rng.uniform(4, 12))) if k % 2 else None
        length = float(rng.uniform(3, 12))
        np.testing.assert_array_equal(fill_thin_lines(m, length, across=across), reference(m, length, across=across))


def test_ridge_series_read_by_every_peak_fraction_equals_a_closing_series_each():
    """The band radii and the rough radius from one series of ridge values (shared by the candidates, the
    thinnest band and the other bands) equal those from a series of closings each (random bands, blobs)."""
    import math

    from notchfit.vision.detection import width

    def series(region, max_close_px, peak_fraction):
        region = width._trim(region)
        near = width._distance_to(region, int(math.ceil(max_close_px)) + 2)
        r, out = 2.0, []
        while r <= max_close_px:
            out += [(int(round(r)), e) for e in width.ridge_peaks(region, int(round(r)), peak_fraction=peak_fraction,
                                                                   near=near)]
            r *= 1.4
        return out

    def candidates(region, max_close_px, min_ratio=0.5, merge=0.12):
        out = []
        for e in sorted(e for r, e in series(region, max_close_px, 0.05) if e >= min_ratio * r):
            if out and e <= out[-1][-1] * (1 + merge):
                out[-1].append(e)
            else:
                out.append([e])
        return [float(np.median(g)) for g in out]

    def rough(region, max_close_px, min_ratio=0.5):
        r_, best = 2.0, math.nan
        reg = width._trim(region)
        near = width._distance_to(reg, int(math.ceil(max_close_px)) + 2)
        while r_ <= max_close_px:
            est = width.rough_radius(reg, int(round(r_)), near=near)
            if np.isfinite(est) and est >= min_ratio * int(round(r_)) and not est <= best:
                best = est
            r_ *= 1.4
        return best

    rng = np.random.default_rng(19)
    for k in range(12):
        m = _band_mask(rng)
        s = width.ridge_series(m, 26)
        want_c, want_r = candidates(m, 26), rough(m, 26)
        assert width.radius_candidates(m, max_close_px=26) == want_c
        assert width.radius_candidates(m, max_close_px=26, series=s) == want_c
        got_r = width.rough_tube_radius(m, max_close_px=26, series=s)
        assert got_r == want_r or (math.isnan(got_r) and math.isnan(want_r))


def _best_reference(feas, allowed, wgt, start, end, eps=1e-6):
    """The chain's dynamic programme as first written: each step reduces over every (candidate, node) pair,
    filled or not, and the candidates a best matching jumps over are collected one transition at a time."""
    NEG = -1e9
    C, M = allowed.shape
    gain = np.where(feas, 0.0, NEG)
    fwd = np.full((C, M), NEG)
    for c in range(C):
        prev = (fwd[:, :, None] + gain[:, :, c, :]).max(axis=(0, 1))
        fwd[c] = np.where(allowed[c], wgt[c] + np.maximum(np.where(start[c], 0.0, NEG), prev), NEG)
    bwd = np.full((C, M), NEG)
    for c in range(C - 1, -1, -1):
        nxt = (gain[c] + bwd[None, :, :]).max(axis=(1, 2))
        bwd[c] = np.where(allowed[c], wgt[c] + np.maximum(np.where(end[c], 0.0, NEG), nxt), NEG)
    ends = fwd[end]
    score = float(ends.max()) if ends.size else NEG
    if score <= 0:
        return score, None
    valid = (fwd > NEG / 2) & (bwd > NEG / 2)
    on = valid & (np.abs(fwd + bwd - wgt[:, None] - score) < eps)
    edges = feas & valid[:, :, None, None] & valid[None, None, :, :] \
        & (np.abs(fwd[:, :, None, None] + gain + bwd[None, None, :, :] - score) < eps)
    firsts = on & start & (np.abs(fwd - wgt[:, None]) < eps)
    lasts = on & end & (np.abs(bwd - wgt[:, None]) < eps)
    skipped = np.zeros(C, bool)
    cc = np.arange(C)
    for c1, _, c2, _ in zip(*np.nonzero(edges)):
        skipped |= (cc > c1) & (cc < c2)
    if firsts.any():
        skipped |= cc < np.nonzero(firsts.any(1))[0].max()
    if lasts.any():
        skipped |= cc > np.nonzero(lasts.any(1))[0].min()
    return score, (on, skipped, edges, firsts, lasts)


@pytest.mark.parametrize("ordered", [True, False])
def test_chain_programme_reading_filled_rows_equals_the_full_reduction(ordered):
    """The chain's best matchings (:func:`~notchfit.vision.detection.chain._best`), each step reading only the
    rows filled before it, equal the programme that reduces over every row: the score and every table, on
    random tables (transitions ordered by candidate and node as the chain builds them, and unordered)."""
    rng = np.random.default_rng(25)
    found = 0
    for _ in range(150):
        C, M = (int(v) for v in rng.integers(2, 12, 2))
        allowed = rng.random((C, M)) < rng.uniform(0.3, 1.0)
        feas = (rng.random((C, M, C, M)) < rng.uniform(0.05, 0.8)) & allowed[:, :, None, None] & allowed[None, None]
        if ordered:
            cc, uu = np.arange(C), np.arange(M)
            feas &= (cc[:, None] < cc[None, :])[:, None, :, None] & (uu[:, None] < uu[None, :])[None, :, None, :]
        wgt = np.where(rng.random(C) < 0.2, 0.5, 1.0)
        start, end = allowed & (rng.random((C, M)) < 0.7), allowed & (rng.random((C, M)) < 0.7)
        got = _best(feas, allowed, wgt, start=start, end=end)
        score, tables = _best_reference(feas, allowed, wgt, start, end)
        assert got.score == score
        if tables is None:
            continue
        found += 1
        for mine, ref in zip((got.on, got.skipped, got.edges, got.firsts, got.lasts), tables):
            np.testing.assert_array_equal(mine, ref)
    assert found > 100
