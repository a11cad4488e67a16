"""Compiled (numba) row loops of the edge-profile refinement (:mod:`.refine`) and of the segmentation.

Each profile's levels, its normalised copy, its 50 % crossing nearest the
centre and its 25 % -> 75 % rise in one pass over its samples, instead of a
dozen full-array numpy passes. The arithmetic is the numpy formulation's,
operation for operation (no fastmath, numpy's division semantics), so the
results are the same to the last bit; ``tests/test_detection_stages.py``
compares them with the plain numpy versions kept there as references.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["block_mean_channels_u8", "block_mean_u8", "level_crossings", "line_levels", "nearest_crossings",
           "profile_crossings", "profile_levels", "profile_maps", "surface_threshold"]


@njit(cache=True, nogil=True)
def profile_maps(base, nrm, t, kp, n_t, width):
    """The sample positions ``base + t nrm`` of every profile's window (``t[n_t - kp] .. t[n_t + kp]``), one
    profile after the other, computed in float64 and rounded to float32: ``cv2.remap``'s maps, ``width``
    samples a row (a map's side stays below OpenCV's limit), the last row filled up with positions outside
    the image."""
    n = len(base)
    total = 0
    for i in range(n):
        total += 2 * kp[i] + 1
    rows = (total + width - 1) // width
    mx = np.full(rows * width, np.float32(-10.0))
    my = np.full(rows * width, np.float32(-10.0))
    p = 0
    for i in range(n):
        for c in range(n_t - kp[i], n_t + kp[i] + 1):
            mx[p] = np.float32(nrm[i, 0] * t[c] + base[i, 0])
            my[p] = np.float32(nrm[i, 1] * t[c] + base[i, 1])
            p += 1
    return mx.reshape(rows, width), my.reshape(rows, width)


@njit(cache=True, nogil=True)
def _sample(values, s0, k, n_t, c):
    """The sample at axis position ``c`` of a profile whose window ``n_t ± k`` is stored from ``values[s0]``
    (float64; NaN outside the window)."""
    if c < n_t - k or c > n_t + k:
        return np.nan
    return np.float64(values[s0 + c - (n_t - k)])


@njit(cache=True, nogil=True, error_model="numpy")
def profile_levels(values, start, kp, n_t, T, cs):
    """Per profile (its window ``n_t ± kp`` on an axis of ``T`` samples, stored from ``values[start]``; NaN
    outside it): the mean of the two outermost object-side and background-side samples (Np,) x 2, and the
    largest and the smallest ``cs`` times the 3-sample mean (float32; NaN counted as 0; the axis' ends
    replicated) over the object side (``n_t - kp`` to ``n_t - 1``), -inf and +inf where it is empty (Np,)
    float32 x 2. The samples are read from the window directly (NaN outside it), each mean added in the
    same order as on the full axis."""
    n = len(kp)
    lo_v = np.empty(n)
    hi_v = np.empty(n)
    ext = np.empty(n, np.float32)
    least = np.empty(n, np.float32)
    third = 1.0 / 3.0
    z = np.empty(T + 2)
    for i in range(n):
        k = kp[i]
        s0 = start[i]
        lo_v[i] = 0.5 * (_sample(values, s0, k, n_t, n_t - k) + _sample(values, s0, k, n_t, n_t - k + 1))
        hi_v[i] = 0.5 * (_sample(values, s0, k, n_t, n_t + k) + _sample(values, s0, k, n_t, n_t + k - 1))
        # z[c + 1]: the sample at axis position c (clamped to the axis), 0 for NaN, for c = n_t - k - 1 .. n_t
        for c in range(n_t - k - 1, n_t + 1):
            v = np.float32(_sample(values, s0, k, n_t, min(max(c, 0), T - 1)))
            z[c + 1] = 0.0 if np.isnan(v) else np.float64(v)
        a = n_t - k
        big = np.float32(-np.inf)
        small = np.float32(np.inf)
        for c in range(a, n_t):
            s = ((0.0 + z[c]) + z[c + 1]) + z[c + 2]
            m = np.float32(cs) * np.float32(s * third)
            big = max(big, m)
            small = min(small, m)
        ext[i] = big
        least[i] = small
    return lo_v, hi_v, ext, least


@njit(cache=True, nogil=True, error_model="numpy")
def _to_num(v):
    """``np.nan_to_num(v, nan=-1.0)`` for one value."""
    if np.isnan(v):
        return -1.0
    if np.isinf(v):
        return 1.7976931348623157e308 if v > 0 else -1.7976931348623157e308
    return v


@njit(cache=True, nogil=True, error_model="numpy")
def profile_crossings(values, start, kp, lo_c, den, t, order, step, rise_step):
    """Per profile (stored as for :func:`profile_levels` on the axis ``t`` of ``2 n_t + 1`` samples, centre
    ``n_t``), normalised as ``(prof - lo_c) / den``: the count of its finite samples, the largest of its samples at ``t > 0`` (NaN: none), the 50 %
    crossing nearest the centre (``order``: the sample intervals by distance from the centre, on a tie the
    first; interval 0 where there is none) as an offset [px] (interpolated over ``step``) and whether one
    was found, and the 25 % -> 75 % rise [px] (interpolated over ``rise_step``; NaN where it does not
    rise)."""
    n, T = len(kp), len(t)
    n_t = (T - 1) // 2
    n_fin = np.empty(n, np.int64)
    q_peak = np.empty(n)
    tc = np.empty(n)
    found = np.zeros(n, np.bool_)
    rise = np.empty(n)
    qa = np.empty(T)
    for i in range(n):
        qa[:] = np.nan                          # (NaN - lo_c) / den outside the window
        cnt = 0
        peak = np.nan
        k = kp[i]
        for j in range(n_t - k, n_t + k + 1):
            q = (np.float64(values[start[i] + j - (n_t - k)]) - lo_c[i]) / den[i]
            qa[j] = q
            if np.isfinite(q):
                cnt += 1
            if t[j] > 0 and not np.isnan(q) and (np.isnan(peak) or q > peak):
                peak = q
        n_fin[i] = cnt
        q_peak[i] = peak
        j = 0
        for jj in order:
            if qa[jj] < 0.5 and qa[jj + 1] >= 0.5:
                j = jj
                found[i] = True
                break
        q0, q1 = qa[j], qa[j + 1]
        tc[i] = t[j] + (0.5 - q0) / (q1 - q0) * step
        pos0 = 0.0
        wd = 0.0
        for lvl in (0.25, 0.75):
            i1 = 0
            for jj in range(T):
                if qa[jj] >= lvl:
                    i1 = jj
                    break
            i0 = max(i1 - 1, 0)
            a0, a1 = _to_num(qa[i0]), _to_num(qa[i1])
            frac = (lvl - a0) / (a1 - a0) if a1 > a0 else 0.0
            pos = t[i0] + frac * rise_step
            if lvl == 0.25:
                pos0 = pos
            else:
                wd = pos - pos0
        rise[i] = wd if np.isfinite(wd) and wd > 0 else np.nan
    return n_fin, q_peak, tc, found, rise


@njit(cache=True, nogil=True)
def _block_rows(img, i, f, rows):
    """The sums of the ``f`` rows of block row ``i``, column by column, into ``rows`` (16-bit: at most
    ``255 f``)."""
    n = len(rows)
    line = img[i * f]
    for c in range(n):
        rows[c] = line[c]
    for r in range(i * f + 1, i * f + f):
        line = img[r]
        for c in range(n):
            rows[c] += line[c]


@njit(cache=True, nogil=True)
def block_mean_u8(img, f):
    """Means of the ``f`` x ``f`` blocks of an 8-bit image (h // f, w // f) float32: the exact integer sum
    times ``float32(1 / f²)``, as ``cv2.resize(..., INTER_AREA)`` computes it for an integer factor.

    The ``f`` rows of a block are added column by column (16-bit: at most ``255 f``, exact up to f = 257),
    then the ``f`` columns of each block one offset at a time: contiguous loops the compiler vectorises.
    The sums are integers below 2²⁴ (f ≤ 256), so their float32 values are exact in any order."""
    hs, ws = img.shape[0] // f, img.shape[1] // f
    n = ws * f
    out = np.empty((hs, ws), np.float32)
    rows = np.empty(n, np.uint16)
    acc = np.empty(ws, np.int32)
    scale = np.float32(1.0 / (f * f))
    for i in range(hs):
        _block_rows(img, i, f, rows)
        for j in range(ws):
            acc[j] = rows[j * f]
        for q in range(1, f):
            for j in range(ws):
                acc[j] += rows[j * f + q]
        for j in range(ws):
            out[i, j] = np.float32(acc[j]) * scale
    return out


@njit(cache=True, nogil=True)
def block_mean_channels_u8(img, f, C):
    """:func:`block_mean_u8` of an 8-bit image of ``C`` interleaved channels seen as (h, w C) (a colour
    image's rows without a copy), channel by channel: (h // f, (w // f) C) float32, the exact integer sums
    times ``float32(1 / f²)`` as ``cv2.resize(..., INTER_AREA)`` computes them for an integer factor."""
    hs = img.shape[0] // f
    n = img.shape[1]
    ws = n // (f * C)
    out = np.empty((hs, ws * C), np.float32)
    rows = np.empty(n, np.uint16)
    acc = np.empty(ws * C, np.int32)
    scale = np.float32(1.0 / (f * f))
    for i in range(hs):
        _block_rows(img, i, f, rows)
        for j in range(ws):
            for c in range(C):
                acc[j * C + c] = rows[j * f * C + c]
        for q in range(1, f):
            for j in range(ws):
                b = (j * f + q) * C
                for c in range(C):
                    acc[j * C + c] += rows[b + c]
        for j in range(ws * C):
            out[i, j] = np.float32(acc[j]) * scale
    return out


@njit(cache=True, nogil=True)
def surface_threshold(small, row, col, X, Y, c4, sign, hi, lo):
    """The object mask of :func:`.segment.segment` in one pass (h, w) uint8: with the background surface
    ``bg = (row[j] + col[i]) + c4 (Y[i] X[j])`` and ``dev = (small - bg) sign``, 1 where ``dev > hi`` or
    ``dev < lo``; float32 throughout, operation for operation as the numpy broadcasts compute it."""
    hs, ws = small.shape
    out = np.empty((hs, ws), np.uint8)
    for i in range(hs):
        ci, yi = col[i], Y[i]
        for j in range(ws):
            dev = (small[i, j] - ((row[j] + ci) + c4 * (yi * X[j]))) * sign
            out[i, j] = 1 if (dev > hi or dev < lo) else 0
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _nearest_crossing(t, p, lv, c, sign):
    """One row of :func:`nearest_crossings`."""
    n = len(p)
    best_j, best = 0, np.inf
    q_prev = sign * (p[0] - lv)
    for k in range(n - 1):
        q_next = sign * (p[k + 1] - lv)
        d = np.abs(t[k] - c) if (q_prev < 0 and q_next >= 0) else np.inf
        if k == 0 or np.isnan(d) or d < best:
            best_j, best = k, d
            if np.isnan(d):
                break
        q_prev = q_next
    if not np.isfinite(best):
        return np.nan
    j = best_j
    q0, q1 = sign * (p[j] - lv), sign * (p[j + 1] - lv)
    return t[j] + (0 - q0) / (q1 - q0) * (t[j + 1] - t[j])


@njit(cache=True, nogil=True, error_model="numpy")
def nearest_crossings(t, P, level, t0, sign):
    """Per row of ``P`` (rows, n): the interpolated crossing of ``level[row]`` nearest ``t0[row]`` where
    ``sign (P - level)`` goes from < 0 to >= 0, NaN where there is none (:func:`.width._crossings`, one
    pass per row; numpy's ``argmin`` semantics: the first nearest, a NaN distance first)."""
    rows = P.shape[0]
    out = np.empty(rows)
    for r in range(rows):
        out[r] = _nearest_crossing(t, P[r], level[r], t0[r], sign)
    return out


@njit(cache=True, nogil=True)
def _nan_to_inf(v):
    """``np.nan_to_num(v, nan=np.inf)`` of one value: NaN -> inf, an infinity -> the largest float of its sign."""
    if np.isnan(v):
        return np.inf
    if v == np.inf:
        return 1.7976931348623157e308
    if v == -np.inf:
        return -1.7976931348623157e308
    return v


@njit(cache=True, nogil=True, error_model="numpy")
def level_crossings(t, P, t0, obj_w0, obj_w1, bg_w0, bg_w1, sign):
    """Per row: the 50 % crossing nearest ``t0`` between the object's and the background's straight-line
    levels (:func:`line_levels` in [obj_w0, obj_w1] and [bg_w0, bg_w1] of ``t0``), taken at the crossing,
    three times and once more (:func:`.width._edges`, operation for operation)."""
    a_o, b_o = line_levels(t, P, t0, obj_w0, obj_w1)
    a_b, b_b = line_levels(t, P, t0, bg_w0, bg_w1)
    rows = P.shape[0]
    out = np.empty(rows)
    for r in range(rows):
        c = t0[r]
        tc = c
        for _ in range(3):
            mid = 0.5 * (a_o[r] + b_o[r] * (tc - c) + a_b[r] + b_b[r] * (tc - c))
            new = _nearest_crossing(t, P[r], _nan_to_inf(mid), c, sign)
            tc = new if np.isfinite(new) else c
        mid = 0.5 * (a_o[r] + b_o[r] * (tc - c) + a_b[r] + b_b[r] * (tc - c))
        out[r] = _nearest_crossing(t, P[r], _nan_to_inf(mid), c, sign)
    return out


@njit(cache=True, nogil=True)
def _pairwise_block(a, lo, n):
    """A block of numpy's pairwise summation (``n`` <= 128): eight running sums, then the rest in turn."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, n):
    """``a[:n].sum()`` as numpy sums a contiguous float64 row, to the last bit: blocks of at most 128
    (:func:`_pairwise_block`), longer runs split in two at a multiple of 8 and their sums added. The split
    tree is walked with an explicit stack (numba's on-disk cache does not hold recursive functions)."""
    if n <= 128:
        return _pairwise_block(a, 0, n)
    los, ns, split = np.empty(64, np.int64), np.empty(64, np.int64), np.zeros(64, np.bool_)
    vals = np.empty(64)
    top, nv = 0, 0
    los[0], ns[0] = 0, n
    while top >= 0:
        lo, m = los[top], ns[top]
        if m <= 128:
            vals[nv] = _pairwise_block(a, lo, m)
            nv += 1
            top -= 1
        elif not split[top]:
            split[top] = True
            m2 = m // 2
            m2 -= m2 % 8
            los[top + 1], ns[top + 1], split[top + 1] = lo + m2, m - m2, False
            los[top + 2], ns[top + 2], split[top + 2] = lo, m2, False
            top += 2
        else:
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return vals[0]


@njit(cache=True, nogil=True, error_model="numpy")
def line_levels(t, P, t0, w0, w1):
    """Per row of ``P`` (rows, n): the straight line (offset at ``t0[row]``, slope) fitted to the finite
    samples with ``t - t0`` in [w0, w1] (NaN offset under 3 samples) (:func:`.width._line_levels`): the
    masked rows and their four sums as numpy forms and sums them, without the full-array temporaries."""
    rows, n = P.shape
    a_out, b_out = np.empty(rows), np.empty(rows)
    xz, pz, xx, xp = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for r in range(rows):
        cnt = 0
        for k in range(n):
            x = t[k] - t0[r]
            p = P[r, k]
            if x >= w0 and x <= w1 and np.isfinite(p):
                cnt += 1
                xz[k], pz[k] = x, p
            else:
                xz[k], pz[k] = 0.0, 0.0
            xx[k], xp[k] = xz[k] * xz[k], xz[k] * pz[k]
        sx, sy = 0.0 + _pairwise_sum(xz, n), 0.0 + _pairwise_sum(pz, n)
        sxx, sxy = 0.0 + _pairwise_sum(xx, n), 0.0 + _pairwise_sum(xp, n)
        fn = float(cnt)
        den = fn * sxx - sx * sx
        b = (fn * sxy - sx * sy) / den if np.abs(den) > 1e-12 else 0.0
        a0 = (sy - b * sx) / fn
        a_out[r] = a0 if cnt >= 3 else np.nan
        b_out[r] = b
    return a_out, b_out
