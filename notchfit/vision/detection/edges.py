"""A local edge model for the refinement's profiles: one blurred step per profile, its own levels and sign.

The image-wide model (:func:`.refine.edge_crossings`) takes an edge's two
levels and its polarity from the whole image's contrast and places the edge
at the 50 % crossing between them. On a polished tube the strip next to the
silhouette mirrors the backdrop: the step against the backdrop is small, of
either sign, and shading changes the levels along the tube, so those levels
do not describe the profile. Here every profile is described by itself:

- the step is the significant gradient peak (either sign) nearest the
  profile's centre (the predicted edge), so a highlight's boundary or a
  strip a few blur widths inside the object is not taken for the edge;
- the step is fitted by least squares around that peak, ``p(t) = a + b
  Φ((t - t0) / s) + c (t - t0)``: its own levels ``a``, ``a + b`` and blur
  ``s``, and a shading slope ``c``; only samples within a few blur widths
  are used, so shading farther away and a second edge do not move ``t0``;
- each profile's position uncertainty comes from its own fit (its residual
  variance times the Gauss-Newton covariance of ``t0``).

Everything is vectorised over the profiles (a fixed number of Gauss-Newton
steps on an (Np, n) window).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from scipy.special import ndtr
from skimage.measure import LineModelND, ransac

__all__ = ["Crossings", "EdgeChoice", "EdgeFits", "Profiles", "choose_edges", "consensus_lines", "dense_profiles", "fit_steps", "profile_steps"]

_SQRT2PI = math.sqrt(2.0 * math.pi)


@dataclass
class Profiles:
    """Profiles across the edges (Np profiles on an axis of T samples, each sampled in its window only)."""

    values: np.ndarray      # (sum of 2 half + 1,) float32: each profile's window, one after the other
    base: np.ndarray        # (Np, 2) profile centre in ROI px
    normal: np.ndarray      # (Np, 2) unit, object -> background
    edge: np.ndarray        # (Np,) edge index 0..2K-1
    t: np.ndarray           # (T,) offsets along the normal [px]
    half: np.ndarray        # (Np,) half window [samples]: profile i covers t[n_t - half_i .. n_t + half_i]
    n_t: int
    start: np.ndarray       # (Np,) where each profile's window starts in ``values``

    def at(self, rows, cols) -> np.ndarray:
        """Samples (float64) of profiles ``rows`` at axis positions ``cols`` inside their windows."""
        return self.values[self.start[rows] + cols - (self.n_t - self.half[rows])].astype(float)


@dataclass(frozen=True)
class Crossings:
    """The image-wide model's 50 % crossings of every profile (Np of them) (:func:`.refine.edge_crossings`).

    Attributes
    ----------
    tc : ndarray (Np,)
        Crossing offset along each profile's normal [px] (NaN where invalid).
    valid : ndarray (Np,) bool
    noise : ndarray (Np,)
        Normalised object-side plateau (noise measure) [1].
    rise : ndarray (Np,)
        The 25 % -> 75 % rise of every profile [px] (NaN where it does not rise).
    """

    tc: np.ndarray
    valid: np.ndarray
    noise: np.ndarray
    rise: np.ndarray


@dataclass(frozen=True)
class _Window:
    """The samples a step is fitted to (Np profiles, n samples each): positions ``x`` [px], values ``y``,
    weights ``w`` (Np, n)."""

    x: np.ndarray
    y: np.ndarray
    w: np.ndarray


@dataclass(frozen=True)
class _Step:
    """Every profile's step ``a + b Φ((x - t0) / s) + c (x - t0)`` (Np,) each."""

    a: np.ndarray
    b: np.ndarray
    t0: np.ndarray
    s: np.ndarray
    c: np.ndarray


@dataclass(frozen=True)
class EdgeFits:
    """The fitted step of every profile (Np of them).

    Attributes
    ----------
    t0 : ndarray (Np,)
        Edge position along the profile's normal [px] (NaN where invalid).
    valid : ndarray (Np,) bool
        The fit converged to a significant step that describes the profile.
    sigma_t : ndarray (Np,)
        Standard deviation of ``t0`` from the fit's own residuals [px].
    blur : ndarray (Np,)
        Gaussian σ of the step [px]; its 25 % -> 75 % rise is ``1.349 blur``.
    level_obj, level_bg : ndarray (Np,)
        The fitted levels on the object side and the background side at the
        edge [image units]; their difference has either sign.
    noise : ndarray (Np,)
        Residual standard deviation of the fit relative to the step [1].
    """

    t0: np.ndarray
    valid: np.ndarray
    sigma_t: np.ndarray
    blur: np.ndarray
    level_obj: np.ndarray
    level_bg: np.ndarray
    noise: np.ndarray

    def summary(self) -> str:
        v = self.valid
        if not v.any():
            return f"EdgeFits: 0 of {len(v)} profiles valid"
        return (f"EdgeFits: {int(v.sum())} of {len(v)} profiles valid, median blur {np.median(self.blur[v]):.2f} px, "
                f"median sigma(t0) {np.median(self.sigma_t[v]):.3f} px")


def dense_profiles(values, start, half, n_t: int) -> np.ndarray:
    """Ragged profile windows on one axis of ``2 n_t + 1`` samples (NaN outside each window) (Np, T).

    Parameters
    ----------
    values : ndarray (sum of 2 half + 1,)
        Each profile's window, one after the other.
    start, half : ndarray (Np,) int
        Where each window starts in ``values``; its half length [samples].
    """
    T = 2 * n_t + 1
    cols = np.arange(T)
    first = n_t - half
    inside = (cols[None, :] >= first[:, None]) & (cols[None, :] <= (n_t + half)[:, None])
    idx = np.where(inside, start[:, None] + cols[None, :] - first[:, None], 0)
    return np.where(inside, values[idx], np.nan).astype(float)


def _row_median(X) -> np.ndarray:
    """Median of the finite values of every row of ``X`` (Np, n) (NaN: none), by one sort of the rows."""
    S = np.sort(X, axis=1)                        # NaN sorts last
    n_fin = np.isfinite(X).sum(axis=1)
    rows = np.arange(len(X))
    lo = S[rows, np.maximum((n_fin - 1) // 2, 0)]
    hi = S[rows, np.maximum(n_fin // 2, 0)]
    return np.where(n_fin > 0, 0.5 * (lo + hi), np.nan)


def _peaks(P, step: float, k_noise: float, rel: float):
    """The significant gradient peak nearest each profile's centre: its interval index (Np,) (-1: none), and
    the nearest other significant peaks before and after it (Np,) x 2 (far outside the axis: none)."""
    d = np.diff(P, axis=1) / step
    # smoothed (1 2 1) for the peak search only: a noisy derivative has many local maxima
    ds = d.copy()
    ds[:, 1:-1] = 0.25 * d[:, :-2] + 0.5 * d[:, 1:-1] + 0.25 * d[:, 2:]
    fin = np.isfinite(ds)
    sz = np.where(fin, np.abs(ds), 0.0)
    big = sz.max(axis=1)
    # the samples' noise from their second differences (a blurred step hardly bends them), carried to the
    # smoothed derivative: (p[i+2] + p[i+1] - p[i] - p[i-1]) / (4 step) has the standard deviation σ / (2 step)
    sd_p = 1.4826 * _row_median(np.abs(np.diff(P, 2, axis=1))) / math.sqrt(6.0)
    noise = sd_p / (2.0 * step)
    thr = np.maximum(rel * big, k_noise * noise)
    left = np.concatenate([np.zeros((len(P), 1)), sz[:, :-1]], axis=1)
    right = np.concatenate([sz[:, 1:], np.zeros((len(P), 1))], axis=1)
    peak = fin & (sz >= left) & (sz > right) & (sz >= thr[:, None]) & (sz > 0)
    centre = 0.5 * (P.shape[1] - 2)
    dist = np.where(peak, np.abs(np.arange(d.shape[1]) - centre)[None, :], np.inf)
    j = np.argmin(dist, axis=1)
    j = np.where(np.isfinite(dist[np.arange(len(P)), j]), j, -1)
    # the neighbouring significant peaks on either side (a highlight's boundary, a strip's inner edge)
    idx = np.arange(d.shape[1])[None, :]
    before = np.where(peak & (idx < j[:, None]), idx, -10 ** 6).max(axis=1)
    after = np.where(peak & (idx > j[:, None]), idx, 10 ** 6).min(axis=1)
    return j, before, after


def _residuals(win: _Window, p: _Step):
    """Weighted residuals (Np, n) of ``y`` from the step ``a + b Φ((x - t0) / s) + c (x - t0)`` and their
    Jacobian (Np, n, 5) with respect to (a, b, t0, s, c)."""
    x, y, w, a, b, t0, s, c = win.x, win.y, win.w, p.a, p.b, p.t0, p.s, p.c
    u = x - t0[:, None]
    z = u / s[:, None]
    phi = np.exp(-0.5 * z * z) / _SQRT2PI
    cdf = ndtr(z)
    r = w * (y - (a[:, None] + b[:, None] * cdf + c[:, None] * u))
    J = w[..., None] * np.stack([np.ones_like(x), cdf, -b[:, None] * phi / s[:, None] - c[:, None],
                                 -b[:, None] * phi * z / s[:, None], u], axis=2)
    return r, J


def _gauss_newton(win: _Window, p: _Step, *, n_iter: int, max_move: float, s_range) -> _Step:
    """``n_iter`` Gauss-Newton steps of every profile's step (:func:`_residuals`) at once; ``t0`` moves at
    most ``max_move`` [px] a step, ``s`` stays in ``s_range`` [px]."""
    a, b, t0, s, c = p.a, p.b, p.t0, p.s, p.c
    for _ in range(n_iter):
        r, J = _residuals(win, _Step(a, b, t0, s, c))
        Jt = J.transpose(0, 2, 1)
        A = np.matmul(Jt, J)
        A = A + 1e-9 * np.eye(5)[None] * np.maximum(np.trace(A, axis1=1, axis2=2), 1.0)[:, None, None]
        dx = np.linalg.solve(A, np.matmul(Jt, r[..., None]))[..., 0]
        dx = np.where(np.isfinite(dx), dx, 0.0)
        a, b, c = a + dx[:, 0], b + dx[:, 1], c + dx[:, 4]
        t0 = t0 + np.clip(dx[:, 2], -max_move, max_move)
        s = np.clip(s + dx[:, 3], *s_range)
    return _Step(a, b, t0, s, c)


def fit_steps(P, t, *, blur0: float = 1.0, reach: float = 3.0, k_noise: float = 5.0, rel: float = 0.5,
              max_noise: float = 0.25, n_iter: int = 6, blur_range=(0.25, 4.0), min_samples: int = 8) -> EdgeFits:
    """Fit a blurred step of either sign to every profile, around its significant gradient peak nearest the
    centre.

    Parameters
    ----------
    P : ndarray (Np, T)
        Profiles along their normals (object side first), NaN outside their windows [image units].
    t : ndarray (T,)
        Offsets along the normal [px], evenly spaced.
    blur0 : float
        Expected Gaussian σ of the edges [px].
    reach : float
        The fit uses the samples within ``reach blur0`` [px] of the peak, and none past the midpoint to a
        neighbouring significant peak.
    k_noise, rel : float
        A gradient peak is significant above ``k_noise`` times the noise of the smoothed derivative (from
        the profile's second differences) and above ``rel`` times the profile's steepest gradient.
    max_noise : float
        Largest residual standard deviation relative to the step [1] of a valid fit.
    n_iter : int
        Gauss-Newton steps.
    blur_range : (float, float)
        Valid fitted blur as multiples of ``blur0``.
    min_samples : int
        Fewest samples a valid fit uses.

    Returns
    -------
    EdgeFits
    """
    Np, T = P.shape
    step = float(t[1] - t[0])
    rows = np.arange(Np)
    j, before, after = _peaks(P, step, k_noise, rel)
    m = int(math.ceil(reach * blur0 / step))
    n = 2 * m + 2                                 # samples j - m .. j + m + 1 around the interval (j, j + 1)
    cols = j[:, None] - m + np.arange(n)[None, :]
    ok = (j >= 0) & (cols[:, 0] >= 0) & (cols[:, -1] < T)
    cols = np.clip(cols, 0, T - 1)
    y = P[rows[:, None], cols]
    ok &= np.isfinite(y).all(axis=1)
    y = np.where(ok[:, None], y, 0.0)
    x = t[cols]
    # only the samples nearer this step than the neighbouring ones: weight 0 beyond the midpoints
    w = ((cols >= (j + before)[:, None] * 0.5 + 0.5) & (cols <= (j + after)[:, None] * 0.5 + 0.5)).astype(float)
    n_w = w.sum(axis=1)
    # start: the peak's interval midpoint, the window's end levels, the expected blur, no slope
    t0 = 0.5 * (t[np.clip(j, 0, T - 2)] + t[np.clip(j + 1, 0, T - 1)])
    w_lo, w_hi = w * (x < t0[:, None]), w * (x > t0[:, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        a = (w_lo * y).sum(axis=1) / w_lo.sum(axis=1)
        b = (w_hi * y).sum(axis=1) / w_hi.sum(axis=1) - a
    ok &= np.isfinite(a) & np.isfinite(b)
    a, b = np.nan_to_num(a), np.nan_to_num(b)
    lo_s, hi_s = blur_range[0] * blur0, blur_range[1] * blur0
    win = _Window(x, y, w)
    fit = _gauss_newton(win, _Step(a, b, t0, np.full(Np, float(blur0)), np.zeros(Np)), n_iter=n_iter,
                        max_move=blur0, s_range=(0.5 * lo_s, 2.0 * hi_s))
    a, b, t0, s = fit.a, fit.b, fit.t0, fit.s
    r, J = _residuals(win, fit)
    A = np.matmul(J.transpose(0, 2, 1), J)
    s2 = (r * r).sum(axis=1) / np.maximum(n_w - 5, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        det_ok = np.abs(np.linalg.det(A)) > 0
        Ainv = np.linalg.inv(np.where(det_ok[:, None, None], A, np.eye(5)[None]))
        var_t = s2 * Ainv[:, 2, 2]
        noise = np.sqrt(s2) / np.abs(b)
    inside = (t0 >= x[:, 0]) & (t0 <= x[:, -1]) & (np.abs(t0 - 0.5 * (x[:, m] + x[:, m + 1])) <= reach * blur0)
    valid = ok & (n_w >= min_samples) & det_ok & inside & np.isfinite(t0) & (s >= lo_s) & (s <= hi_s) \
        & (noise < max_noise) & (var_t > 0)
    nan = np.full(Np, np.nan)
    return EdgeFits(np.where(valid, t0, np.nan), valid, np.where(valid, np.sqrt(np.abs(var_t)), nan),
                    np.where(valid, s, nan), np.where(valid, a, nan), np.where(valid, a + b, nan),
                    np.where(valid, noise, nan))


def profile_steps(values, start, half, n_t: int, t, *, blur0: float = 1.0, max_noise: float = 0.35,
                  max_sigma_t: float = 0.5) -> EdgeFits:
    """:func:`fit_steps` on the refinement's ragged profile windows (:func:`dense_profiles`), valid only where
    the crossing's own standard deviation is at most ``max_sigma_t`` [px]."""
    fits = fit_steps(dense_profiles(values, start, half, n_t), t, blur0=blur0, max_noise=max_noise)
    keep = fits.valid & (fits.sigma_t <= max_sigma_t)
    if keep.all():
        return fits
    out = {f.name: np.where(keep, getattr(fits, f.name), np.nan) for f in fields(EdgeFits) if f.name != "valid"}
    return EdgeFits(valid=keep, **out)


@dataclass(frozen=True)
class EdgeChoice(Crossings):
    """The crossings of every profile (Np of them) after the per-edge choice of the edge model
    (:class:`Crossings`; ``noise`` is the image-wide model's plateau deviation, or the local fit's residual
    standard deviation over its step).

    Attributes
    ----------
    local : ndarray (n_edges,) bool
        The edges whose profiles took the local model.
    sigma_t : ndarray (Np,)
        The local fits' own standard deviation of ``tc`` [px] (NaN on the image-wide model's profiles).
    """

    local: np.ndarray
    sigma_t: np.ndarray

    def consensus(self, pts, edge, *, blur: float, min_fraction: float = 0.6, min_points: int = 5,
                  seed: int = 0) -> np.ndarray:
        """(Np,) bool: the valid crossings kept after a consensus line of every local edge (:func:`consensus_lines`);
        the image-wide model's crossings are all kept. ``pts`` (n_valid, 2): the valid crossings' positions [px],
        in the order of the valid profiles."""
        keep = self.valid.copy()
        e_valid = edge[self.valid]
        on_local = self.local[e_valid]
        if on_local.any():
            inl = consensus_lines(pts[on_local], e_valid[on_local], blur=blur, min_fraction=min_fraction,
                                  min_points=min_points, seed=seed)
            rows = np.nonzero(self.valid)[0][on_local]
            keep[rows] = inl
        return keep

    def summary(self) -> str:
        return (f"EdgeChoice: {int(self.valid.sum())} of {len(self.valid)} profiles valid, "
                f"{int(self.local.sum())} of {len(self.local)} edges on the local model")


def consensus_lines(pts, edge, *, blur: float, min_fraction: float = 0.6, second: float = 0.2,
                    min_points: int = 5, seed: int = 0, max_trials: int = 100) -> np.ndarray:
    """The crossings (n,) bool that agree with one straight edge, per edge: RANSAC consensus lines.

    The local model takes, on every profile, the step nearest the predicted
    edge; along a polished limb that is the limb on some profiles and a
    highlight's boundary, a few pixels inside, on others. Two steps the
    profiles resolve as separate gradient peaks lie at least about two blur
    widths apart, while the crossings of one step scatter by their noise
    (spatially correlated noise, such as a JPEG's or a path tracer's, makes
    that scatter larger than a single profile's fit residuals say). So each
    edge's crossings are split by a RANSAC line (scikit-image
    ``measure.ransac`` with ``LineModelND``) whose inliers lie within one blur
    σ (at least 0.5 px) of it: the edge is one step where the consensus holds
    at least ``min_fraction`` of its crossings (and ``min_points``); its
    outliers are dropped. Where no line holds that many, the profiles took
    different steps at random; where the outliers hold a second line of
    ``second`` of the crossings (and ``min_points``), the profiles saw two
    edges and which one is the tube's is not known: the whole edge is dropped.

    Parameters
    ----------
    pts : ndarray (n, 2)
        Crossings [px].
    edge : ndarray (n,) int
        Each crossing's edge.
    blur : float
        Gaussian σ of the edges [px] (NaN: 1 px).
    seed : int
        Seed of the RANSAC samples (reproducible results).
    """
    thr = max(0.5, float(blur) if np.isfinite(blur) else 1.0)
    keep = np.zeros(len(pts), bool)
    rng = np.random.default_rng(seed)
    for e in np.unique(edge):
        rows = np.nonzero(edge == e)[0]
        if len(rows) < max(min_points, 3):
            continue
        P = pts[rows].astype(float)
        model, inl = ransac(P, LineModelND, min_samples=2, residual_threshold=thr, max_trials=max_trials,
                            stop_probability=0.999, rng=rng)
        if model is None or inl is None:
            continue
        inl = model.residuals(P) < thr                   # about the line fitted to the consensus (not its sample)
        if inl.sum() < max(min_points, min_fraction * len(rows)):
            continue
        # a second line among the rest: the profiles saw two edges (the limb and a highlight's boundary)
        rest = P[~inl]
        if len(rest) >= max(min_points, second * len(rows)):
            m2, inl2 = ransac(rest, LineModelND, min_samples=2, residual_threshold=thr, max_trials=max_trials,
                              stop_probability=0.999, rng=rng)
            if m2 is not None and inl2 is not None and inl2.sum() >= max(min_points, second * len(rows)):
                continue
        keep[rows[inl]] = True
    return keep


def choose_edges(pr: Profiles, n_edges: int, crossings: Crossings, *, face=None, contrast: float = 0.0,
                 min_valid: float = 0.5, min_count: int = 10, blur0: float = 1.0, max_noise: float = 0.35,
                 max_sigma_t: float = 0.5, face_level_tol: float = 0.5) -> EdgeChoice:
    """Keep the image-wide model's crossings on the edges it describes, the local fit on the others.

    An edge whose profiles are valid under the image-wide levels (their
    50 % crossings, ``crossings``) for at least ``min_valid`` of its
    profiles or ``min_count`` of them keeps them (a slot face beside a nearly closed mouth, whose closed part the
    image-wide model drops on purpose, is among these): there the image-wide
    levels are the edge's (a matte tube on a plain backdrop), and its
    crossings are as exact as before. The profiles of every other edge (a
    polished limb mirroring the backdrop, levels changing along it) are
    fitted one by one (:func:`profile_steps`).

    Parameters
    ----------
    pr : Profiles
        The ragged profile windows (:func:`dense_profiles`), their axis [px] and each profile's edge
        0 .. n_edges - 1.
    face : ndarray (n_edges,) bool, optional
        Slot faces. A face's profile runs along the tube's axis, and the tube's shading and highlights
        change around it, not along it: the object side of the face's own step is at the level of the
        profile's object end (within ``face_level_tol`` of the step). A step whose object side is not
        (beside a nearly closed mouth, the partner face's step seen from the slot) is not the face's.
    contrast : float
        The image's object level minus its background's: a face's step goes from the tube to the
        background seen through the slot, so it keeps that sign (a limb, which mirrors the backdrop, may
        take either). 0: either sign.
    """
    edge, valid = pr.edge, crossings.valid
    n_all = np.bincount(edge, minlength=n_edges).astype(float)
    n_ok = np.bincount(edge, valid.astype(float), minlength=n_edges)
    local = (n_ok < min_valid * n_all) & (n_ok < min_count)
    rows = np.nonzero(local[edge])[0]
    tc, valid, noise, rise = crossings.tc.copy(), valid.copy(), crossings.noise.copy(), crossings.rise.copy()
    sigma_t = np.full(len(tc), np.nan)
    if len(rows):
        fits = profile_steps(pr.values, pr.start[rows], pr.half[rows], pr.n_t, pr.t, blur0=blur0, max_noise=max_noise,
                             max_sigma_t=max_sigma_t)
        ok = fits.valid
        if face is not None:
            # the object end of each face profile (its first 3 samples) against the step's object side
            f_rows = face[edge[rows]]
            end = np.mean([pr.values[pr.start[rows] + i].astype(float) for i in range(3)], axis=0)
            with np.errstate(invalid="ignore"):
                off = np.abs(fits.level_obj - end) > face_level_tol * np.abs(fits.level_bg - fits.level_obj)
                wrong_sign = np.sign(fits.level_obj - fits.level_bg) != np.sign(contrast)
            ok = ok & ~(f_rows & (off | (wrong_sign & (contrast != 0))))
        tc[rows], valid[rows], noise[rows], rise[rows] = np.where(ok, fits.t0, np.nan), ok, fits.noise, \
            1.349 * fits.blur
        sigma_t[rows] = fits.sigma_t
    return EdgeChoice(tc, valid, noise, rise, local, sigma_t)
