"""Stage 1: segment the object (tube + holder) on a downsampled copy.

Otsu split, polarity from the image border (dark on light or light on dark),
a quadratic background surface fitted to the background class and refitted
to the samples near it (uneven light, vignetting, a non-flat backdrop), a
threshold between the background surface and the object level, the largest region with its holes filled
except slot-sized ones (a nearly closed slot mouth segments as a hole;
shading and a specular streak inside the tube or the holder make larger
holes).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import find_objects

from ._kernels import block_mean_channels_u8, block_mean_u8, surface_threshold
from .lines import otsu, poly2

__all__ = ["Segmentation", "band_directions", "chroma_distance", "close_disk", "components_with_stats",
           "disk_rectangles", "downsample",
           "fill_holes", "fill_thin_lines", "grow_over_sharp_edges", "largest_region", "local_difference",
           "local_segmentation", "octagon_opening", "remove_thin", "segment"]


@dataclass(frozen=True)
class Segmentation:
    """The object mask of a downsampled image.

    Attributes
    ----------
    mask : ndarray (h, w) uint8
        1 on the object (every region), 0 on the background.
    contrast : float
        Object level minus background level (negative: dark object) [DN].
    noise : float
        Background noise of the downsampled copy [DN].
    message : str
        Why no object was found (empty otherwise).
    image : ndarray (h, w) float32 or None
        The downsampled copy that was segmented.
    """

    mask: np.ndarray | None
    contrast: float
    noise: float
    message: str = ""
    image: np.ndarray | None = None


def downsample(gray, factor: int) -> np.ndarray:
    """Block average by an integer ``factor`` (float32; the trailing rows/columns that do not fill a block are
    dropped); a colour image (H, W, C) channel by channel. An 8-bit image is averaged from its 8-bit pixels
    from a factor of 3 up (:func:`._kernels.block_mean_u8`, a colour one channel by channel: the same values,
    without a float copy of the whole file). At a factor of 2 a gray image goes through the float copy: the
    compiled means are faster by themselves, but the copy is a detection's largest array, and freeing it
    raises glibc's dynamic mmap and trim thresholds, so the detection's later arrays stay on the heap
    instead of being mapped and faulted in anew (about 1,800 page faults per 1920 x 1200 image without
    it; docs/history.md)."""
    f = int(factor)
    H, W = gray.shape[:2]
    hs, ws = H // f, W // f
    g = gray[:hs * f, :ws * f]
    if f == 1:
        return np.asarray(g, np.float32)
    if g.dtype == np.uint8 and 3 <= f <= 256 and g.ndim == 2:
        return block_mean_u8(g, f)
    if g.dtype == np.uint8 and f <= 256 and g.ndim == 3:
        C = g.shape[2]
        return block_mean_channels_u8(g.reshape(hs * f, ws * f * C), f, C).reshape(hs, ws, C)
    return cv2.resize(np.asarray(g, np.float32), (ws, hs), interpolation=cv2.INTER_AREA)


def chroma_distance(small_bgr, *, dark: float = 8.0) -> np.ndarray:
    """How far each pixel's colour is from the backdrop's, whatever its brightness (h, w) float32.

    The chromaticity ``((R - B) / S, (G - (R + B) / 2) / S)`` with ``S = R + G + B + 3 dark`` (``dark`` [DN]
    keeps the black end from amplifying noise) does not change when a shadow or the backdrop's shading
    scales all three channels alike; a neutral metal tube, its chuck and its highlights on a warm-grey
    card, or a white printed tube on blue paper, differ from the card in it. The distance from the median
    chromaticity of the image's border (the backdrop), times 255.

    Parameters
    ----------
    small_bgr : ndarray (h, w, 3)
        A downsampled colour copy (BGR).
    dark : float
        Added to every channel in the denominator [DN].
    """
    c = np.asarray(small_bgr, np.float32)
    S = c.sum(axis=2) + np.float32(3 * dark)
    ch = np.stack([(c[..., 2] - c[..., 0]) / S, (c[..., 1] - 0.5 * (c[..., 0] + c[..., 2])) / S], axis=2)
    border = np.concatenate([ch[0], ch[-1], ch[:, 0], ch[:, -1]])
    ref = np.median(border, axis=0).astype(np.float32)
    return np.float32(255.0) * np.sqrt(np.sum((ch - ref) ** 2, axis=2))


def segment(small, *, min_snr: float = 4.0, noise_scale: float = 1.0, max_fit_points: int = 6000,
            level: float = 0.5, rounds: int = 3, clear_snr: float = 5.0, opposite: float = 0.25,
            opposite_snr: float = 6.0, full=None) -> Segmentation:
    """Object mask of a downsampled image.

    Parameters
    ----------
    small : ndarray (h, w) float
    min_snr : float
        Smallest |contrast| in units of the full-resolution background noise.
    noise_scale : float
        Full-resolution noise over the downsampled copy's noise (the
        downsampling factor: noise averages down about as 1/factor).
    max_fit_points : int
        Background samples used for the surface fit.
    level : float
        Threshold between the background surface (0) and the object level
        (1): below 0.5, thin dark parts whose blurred or shaded level does not
        reach halfway (a backbone left by deep slots, limbs shaded toward the
        background) stay in the object.
    full : ndarray (H, W), optional
        The full-resolution image ``small`` was block-averaged from by the factor ``noise_scale``. Its
        own noise, measured at the background samples, is used for the ``min_snr`` test where it is
        smaller than the downsampled copy's times ``noise_scale``: a texture of the backdrop (grid
        paper, a chuck's knurl) does not average down as noise does, and on the copy it would pass for
        noise ``noise_scale`` times its amplitude there.
    rounds : int
        Refits of the background surface, each to the samples within a
        quarter of the contrast of the last one (vignetting darkens the image
        corners below an Otsu split; the refits take them back).
    clear_snr : float
        The surface starts from an Otsu split; when that gives an object less
        than ``clear_snr * min_snr`` times the noise, from a trimmed fit too
        (a small object in an unevenly lit image), whichever is clearer.
    opposite, opposite_snr : float
        Pixels that differ from the background surface the *other* way by
        more than ``opposite`` times the contrast and ``opposite_snr`` times
        the noise are object too: a specular line along a polished tube,
        brighter than the background, would cut the links apart if it were
        taken for background.

    Returns
    -------
    Segmentation
    """
    hs, ws = small.shape
    step = max(1, int(np.ceil(np.sqrt(hs * ws / max_fit_points))))
    sub = small[::step, ::step]
    A = poly2(*np.meshgrid(np.arange(0, ws, step) / ws - 0.5, np.arange(0, hs, step) / hs - 0.5)).reshape(-1, 6)
    vals = sub.ravel().astype(float)
    fits = []
    for start in (_otsu_background, lambda _: _trimmed_background(A, vals)):
        inl = start(sub)
        if inl is not None:
            fits.append(_refit(A, vals, inl, small, step, sub.shape, rounds))
            if abs(fits[-1][1]) >= clear_snr * min_snr * fits[-1][2] * noise_scale:
                break                                        # a clear object from the Otsu split
    if not fits:
        return Segmentation(None, 0.0, 0.0, "no manipulator found: no background visible")
    coef, contrast, noise = max(fits, key=lambda f: abs(f[1]) / f[2])   # the clearer object
    gate = noise * noise_scale
    if not abs(contrast) >= min_snr * gate and full is not None:
        gate = min(gate, full_noise(full, small, coef, int(noise_scale), 0.25 * abs(contrast)))
    if not abs(contrast) >= min_snr * gate:
        return Segmentation(None, contrast, noise,
                            f"no manipulator found: contrast {abs(contrast):.1f} is below {min_snr:g} x the "
                            f"background noise {gate:.1f}")
    X = np.arange(ws, dtype=np.float32) / ws - 0.5
    Y = np.arange(hs, dtype=np.float32) / hs - 0.5
    c_ = coef.astype(np.float32)
    # the quadratic background surface (c0 + c1 X + c3 X²) + (c2 Y + c5 Y²) + c4 Y X, evaluated with the
    # deviation from it and the threshold in one compiled pass: the object side of the threshold, and what
    # differs from the background as much the other way (a specular line brighter than the background along
    # a dark tube is tube, not background)
    other = max(opposite * abs(contrast), opposite_snr * noise)
    dt = np.result_type(small.dtype, np.float32)          # the type numpy would compute ``small - bg`` in
    mask = surface_threshold(np.ascontiguousarray(small, dt), c_[0] + c_[1] * X + c_[3] * X * X,
                             c_[2] * Y + c_[5] * Y * Y, X, Y, c_[4], np.float32(np.sign(contrast)),
                             dt.type(level * abs(contrast)), dt.type(-other))
    return Segmentation(mask, contrast, noise, image=small)


def _otsu_background(sub):
    """Background samples from an Otsu split, the background being the class on most of the border."""
    above = sub > otsu(sub.ravel())
    border = np.concatenate([above[0], above[-1], above[:, 0], above[:, -1]])
    obj0 = ~above if border.mean() > 0.5 else above
    bgm = cv2.erode((~obj0).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return bgm.ravel() if bgm.sum() >= 50 else None


def _surface(A, vals, sel):
    """Coefficients of the quadratic background surface fitted to the samples ``sel`` (lightly regularised)."""
    idx = np.flatnonzero(sel)
    As = A.take(idx, axis=0)                  # ``A[sel]``, gathered by index (about three times faster)
    # a second copy for the product's other side: numpy multiplies a matrix by its own transpose differently
    return np.linalg.solve(As.T @ As.copy() + 1e-9 * np.eye(6), As.T @ vals.take(idx))


def _trimmed_background(A, vals, keep: float = 0.5, rounds: int = 4):
    """Background samples from a trimmed fit: the half of the samples nearest a quadratic surface, refitted
    ``rounds`` times (an object covering a small part of an unevenly lit image)."""
    use = np.ones(len(vals), bool)
    for _ in range(rounds):
        coef = _surface(A, vals, use)
        r = np.abs(vals - A @ coef)
        use = r <= np.quantile(r, keep)
    return use if use.sum() >= 50 else None


def _refit(A, vals, inl, small, step, shape, rounds):
    """The background surface refitted to the samples within a quarter of the contrast; the object is the
    far side, dark or bright by the sign of most far samples. Returns (coefficients, contrast, noise)."""
    for it in range(rounds + 1):
        coef = _surface(A, vals, inl)
        res = vals - A @ coef
        if it in (0, rounds):
            noise = _noise(small, step, inl.reshape(shape))
        ares = np.abs(res)
        far = ares > max(5 * noise, 0.3 * float(np.percentile(ares, 99.5)))
        if far.sum() < 10:
            return coef, 0.0, noise
        dark = np.sum(res[far] < 0) >= np.sum(res[far] > 0)
        contrast = float(np.median(res[far & ((res < 0) if dark else (res > 0))]))
        if it < rounds:
            inl = ares <= 0.25 * abs(contrast)
    return coef, contrast, noise


def _noise(small, step: int, bg) -> float:
    """Noise of the background from differences of horizontally neighbouring pixels at the background
    samples (a smooth, non-quadratic background, such as a hot spot or vignetting, is not noise)."""
    yy, xx = np.nonzero(bg)
    yy, xx = yy * step, xx * step
    keep = xx + 1 < small.shape[1]
    if not keep.any():
        return 1e-6
    return _difference_noise(small[yy[keep], xx[keep] + 1] - small[yy[keep], xx[keep]])


def _difference_noise(d) -> float:
    """The noise σ of one pixel from differences ``d`` of neighbouring pixels: 1.4826 MAD / √2 [DN]."""
    return 1.4826 * float(np.median(np.abs(d))) / np.sqrt(2) + 1e-6


def full_noise(full, small, coef, factor: int, near: float, *, max_samples: int = 20000,
               seed: int = 0) -> float:
    """Noise of the background at full resolution [DN]: the median absolute difference of horizontally
    neighbouring pixels (times 1.4826 / sqrt 2) in the blocks of the downsampled copy whose level lies
    within ``near`` of the background surface ``coef`` (:func:`segment`'s quadratic in the copy's
    normalised coordinates). A texture of the backdrop (grid lines, a knurl) covers a minority of the
    pixels at full resolution, so the median sees the noise between them; on the downsampled copy the
    same texture is in every block.

    Parameters
    ----------
    full : ndarray (H, W)
        The full-resolution image.
    small : ndarray (h, w)
        Its block average by ``factor``.
    coef : ndarray (6,)
        The background surface of the copy (``poly2`` coefficients).
    factor : int
        The block-averaging factor.
    near : float
        Largest deviation of a block from the surface for it to count as background [DN].
    max_samples : int
        Blocks sampled (seeded, reproducible).
    seed : int
        Seed of the sample.
    """
    hs, ws = small.shape
    rng = np.random.default_rng(seed)
    n = min(max_samples, hs * ws)
    idx = rng.choice(hs * ws, n, replace=False)
    by, bx = idx // ws, idx % ws
    oy = rng.integers(0, factor, n)
    ox = rng.integers(0, max(factor - 1, 1), n)
    y, x = by * factor + oy, bx * factor + ox
    H, W = full.shape[:2]
    keep = (x + 1 < W) & (y < H)
    y, x, by, bx = y[keep], x[keep], by[keep], bx[keep]
    bg = poly2(bx / ws - 0.5, by / hs - 0.5) @ np.asarray(coef, float)
    sel = np.abs(np.asarray(small[by, bx], float) - bg) <= near
    if sel.sum() < 50:
        return np.inf
    y, x = y[sel], x[sel]
    return _difference_noise(np.asarray(full[y, x + 1], float) - np.asarray(full[y, x], float))


def largest_region(mask) -> tuple[np.ndarray, tuple]:
    """The largest 8-connected region of a mask (uint8, full size), and its bounding box (x, y, w, h)."""
    ext, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not ext:
        return np.zeros_like(mask), (0, 0, 0, 0)
    x0, y0, bw, bh = cv2.boundingRect(max(ext, key=cv2.contourArea))
    n, lab = cv2.connectedComponents(np.ascontiguousarray(mask[y0:y0 + bh, x0:x0 + bw]), connectivity=8)
    # the areas counted from the labels (OpenCV's statistics pass costs three times the labelling)
    big = 1 + int(np.argmax(np.bincount(lab.ravel(), minlength=n)[1:]))
    out = np.zeros_like(mask)
    out[y0:y0 + bh, x0:x0 + bw] = lab == big
    return out, (int(x0), int(y0), int(bw), int(bh))


def components_with_stats(mask):
    """``cv2.connectedComponentsWithStats(mask, connectivity=8)``'s output to the last bit (count, labels,
    stats (n, 5) int32, centroids (n, 2)) for a sparse mask, the stats counted from the labels of its pixels
    (``cv2.findNonZero``): areas, coordinate sums and each label's smallest and largest coordinates (the
    background's from the image's totals). OpenCV's statistics pass costs three times the labelling; a
    mask without background is left to it."""
    n, lab = cv2.connectedComponents(mask, connectivity=8)
    h, w = mask.shape
    pts = cv2.findNonZero(mask)
    if pts is None or len(pts) == h * w:
        return cv2.connectedComponentsWithStats(mask, connectivity=8)
    pts = pts.reshape(-1, 2).astype(np.intp)
    xx, yy = pts[:, 0], pts[:, 1]
    ll = lab[yy, xx]
    stats = np.empty((n, 5), np.int32)
    stats[:, 4] = np.bincount(ll, minlength=n)
    stats[0, 4] = h * w - len(ll)
    sums = np.stack([np.bincount(ll, xx, n), np.bincount(ll, yy, n)], 1)
    # the background's sums: every pixel's (exact integers) less the labelled ones'; its rows and columns:
    # those not wholly labelled
    sums[0] = h * (w * (w - 1) // 2) - int(xx.sum()), w * (h * (h - 1) // 2) - int(yy.sum())
    rows, cols = np.flatnonzero(np.bincount(yy, minlength=h) < w), np.flatnonzero(np.bincount(xx, minlength=w) < h)
    stats[0, :4] = cols[0], rows[0], cols[-1] + 1 - cols[0], rows[-1] + 1 - rows[0]
    order = np.argsort(ll, kind="stable")
    starts = np.flatnonzero(np.diff(ll[order], prepend=0))        # each label's first pixel, labels 1..n-1
    for c, v in ((0, xx[order]), (1, yy[order])):
        lo = np.minimum.reduceat(v, starts)
        stats[1:, c], stats[1:, c + 2] = lo, np.maximum.reduceat(v, starts) + 1 - lo
    return n, lab, stats, sums / stats[:, 4:5].astype(float)


def window_max_at(labels, ys, xs, half: int = 1) -> np.ndarray:
    """The largest value of ``labels`` (h, w) in the ``2 half + 1`` square window around each listed pixel
    ``(ys, xs)`` (n,), the window cut by the image border: ``cv2.dilate(labels, ones)`` read at those pixels
    (labels below 2**24 are exact in the float32 image the dilation would need), without dilating the whole
    image when only a few of its pixels are read. A pixel's clipped neighbour stays inside its window, so
    the maximum over clipped indices is the maximum over the window's part inside the image."""
    h, w = labels.shape
    cols = [np.clip(xs + dx, 0, w - 1) for dx in range(-half, half + 1)]
    out = labels[ys, xs]
    for dy in range(-half, half + 1):
        yy = np.clip(ys + dy, 0, h - 1)
        for xx in cols:
            np.maximum(out, labels[yy, xx], out=out)
    return out


def fill_holes(region, *, keep_area=(0.0, 0.0)) -> np.ndarray:
    """Fill the holes of a region (background parts enclosed by it).

    Holes whose area [px²] lies in ``keep_area`` stay open: nearly closed
    slots look like that.
    """
    cnts, hier = cv2.findContours(region, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    if hier is None:
        return region
    holes = [c for c, h in zip(cnts, hier[0]) if h[3] >= 0
             and not keep_area[0] <= cv2.contourArea(c) <= keep_area[1]]
    if not holes:
        return region
    out = region.copy()
    cv2.drawContours(out, holes, -1, 1, thickness=-1)
    return out


def local_difference(small, radius_px: float, *, contrast: float, highlight=None) -> np.ndarray:
    """How far each pixel of the working copy lies toward the object from its local background (h, w) float32
    (object positive): the background is a grey opening of the image turned object-bright, by an octagon
    (:func:`octagon_opening`, a disk within 8 %) of radius ``radius_px``, wider than the tube's half-width, so
    the tube and its slots drop out of it while
    what varies more slowly stays, such as a soft cast shadow, whose penumbra is as wide as the light source
    seen from the backdrop. A shadow as dark as the tube joins the tube on a threshold of the image; on this
    difference it is near 0 where its penumbra is wider than the disk, and the tube's sharp-edged band keeps
    its contrast.

    ``highlight``: pixels that differ from the backdrop the other way (a specular line along a polished tube,
    (h, w) bool); they are taken as object (the object's level) before the closing, else the closing would
    keep them as background and cut the tube along them."""
    img = np.asarray(small, np.float32)
    sign = 1.0 if contrast >= 0 else -1.0
    work = sign * img                                    # the object bright
    if highlight is not None and highlight.any():
        work = work.copy()
        work[highlight] = float(np.median(work[~highlight])) + abs(contrast)
    r = max(int(round(radius_px)), 1)
    pad = r + 2
    big = cv2.copyMakeBorder(work, pad, pad, pad, pad, cv2.BORDER_REFLECT)
    return work - octagon_opening(big, r)[pad:-pad, pad:-pad]


def octagon_opening(img, r: int) -> np.ndarray:
    """Grey opening by a regular octagon of inner radius ``r`` [px] (a disk within 8 %): the Minkowski sum of
    a square of half-side ``a = (√2 - 1) r`` and a diamond of radius ``r - a``, so the erosion and the
    dilation are each a separable square's and ``r - a`` passes of the 3 x 3 cross, about ten times faster
    than by the disk's own kernel at ``r`` = 20."""
    a = int(round((np.sqrt(2.0) - 1.0) * r))
    b = max(r - a, 0)
    sq = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * a + 1,) * 2)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    out = cv2.erode(img, sq)
    if b:
        out = cv2.dilate(cv2.erode(out, cross, iterations=b), cross, iterations=b)
    return cv2.dilate(out, sq)


def grow_over_sharp_edges(small, seeds, within) -> np.ndarray:
    """The object of ``seeds`` grown over the rest of ``within`` up to the image's sharp edges (uint8 0/1):
    OpenCV's watershed, flooded from the seeds and from everything outside ``within`` in the order of the
    step between neighbouring pixels. A holder wider than the local background's disk drops out of
    :func:`local_difference`, but it meets the tube without an edge and the backdrop across a sharp one, so
    the seeds' flood takes it; a soft shadow meets the backdrop across its penumbra, in small steps, and the
    tube across the tube's sharp edge, so the backdrop's flood takes it."""
    img = np.asarray(small, np.float32)
    lo, hi = float(img.min()), float(img.max())
    g8 = np.round((img - lo) * (255.0 / max(hi - lo, 1e-6))).astype(np.uint8)
    markers = np.zeros(img.shape, np.int32)
    markers[cv2.dilate(np.asarray(within, np.uint8), np.ones((3, 3), np.uint8)) == 0] = 1
    markers[np.asarray(seeds) > 0] = 2
    cv2.watershed(cv2.merge([g8, g8, g8]), markers)
    obj = (markers == 2).astype(np.uint8)
    # the flood's boundary pixels (-1) are the object's where they touch it, as in the seeds' own mask
    return obj | ((markers == -1) & (cv2.dilate(obj, np.ones((3, 3), np.uint8)) > 0)).astype(np.uint8)


def local_segmentation(seg: Segmentation, radius_px: float, *, min_snr: float = 4.0, noise_scale: float = 1.0,
                       level: float = 0.5, opposite: float = 0.25, opposite_snr: float = 6.0) -> Segmentation:
    """The tube's silhouette against its local background: :func:`segment` of :func:`local_difference` (a
    disk of ``radius_px`` [working px]), the holder grown back over the sharp edges of the threshold's
    silhouette (:func:`grow_over_sharp_edges`). A soft cast shadow as dark as the tube is left out.

    ``seg``: the working copy's segmentation by a threshold (:func:`segment`); its pixels that differ from
    the backdrop the other way by ``opposite`` times the contrast and ``opposite_snr`` times the noise (a
    specular line along a polished tube) are object. The other keywords as for :func:`segment`."""
    small = np.asarray(seg.image, np.float32)
    if seg.mask is None or small.ndim != 2 or not (seg.mask == 0).any():
        return Segmentation(None, seg.contrast, seg.noise, seg.message)
    back = float(np.median(small[seg.mask == 0]))
    other = max(opposite * abs(seg.contrast), opposite_snr * seg.noise)
    highlight = (seg.mask > 0) & ((small - back) * np.sign(seg.contrast) < -other)
    loc = segment(local_difference(small, radius_px, contrast=seg.contrast, highlight=highlight),
                  min_snr=min_snr, noise_scale=noise_scale, level=level)
    if loc.mask is None:
        return loc
    return Segmentation(grow_over_sharp_edges(small, loc.mask, seg.mask), loc.contrast, loc.noise, image=small)


def remove_thin(mask, *, thin_px: float, max_length_px: float) -> np.ndarray:
    """The mask without its thin, long parts (uint8): a wire, a tendon loop, a grid line.

    The pixels that an opening by a disk of radius ``0.35 thin_px`` (at
    least 1 px) removes are grouped into 8-connected parts; a part longer
    (its box's diagonal) than ``max_length_px`` is removed. ``thin_px`` is
    the narrowest part of the tube that must stay (the backbone left by the
    slots: it is thin too, but only as long as a slot is wide).
    """
    m = np.asarray(mask, np.uint8)
    r = max(int(round(0.35 * thin_px)), 1)
    opened = cv2.morphologyEx(m, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
    n, lab = cv2.connectedComponents((m & (1 - opened)).astype(np.uint8), connectivity=8)
    if n <= 1:
        return m
    # each part's box from its labels (OpenCV's statistics pass costs three times the labelling)
    boxes = find_objects(lab, max_label=n - 1)
    size = np.array([[0, 0]] + [[b[1].stop - b[1].start, b[0].stop - b[0].start] for b in boxes], np.int32)
    long_ = np.hypot(size[:, 0], size[:, 1]) > max_length_px
    long_[0] = False
    return (m & ~long_[lab]).astype(np.uint8)


def close_disk(mask, r: int):
    """Morphological closing of a 0/1 uint8 mask by a disk of radius ``r`` [px] (OpenCV's elliptic
    structuring element), with zero padding so that the closing never reaches the image border.

    The disk is the union of the rectangles :func:`disk_rectangles` gives, so the dilation is the largest of
    the dilations by each and the erosion the smallest of the erosions by each: the same pixels as
    ``cv2.morphologyEx(..., MORPH_CLOSE, ellipse)``, and OpenCV's rectangles are separable (about a third
    faster than the disk's own kernel at ``r`` = 10 and ``r`` = 18)."""
    pad = r + 2
    big = cv2.copyMakeBorder(mask, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    kers = [cv2.getStructuringElement(cv2.MORPH_RECT, (2 * a + 1, 2 * b + 1)) for a, b in disk_rectangles(r)]
    dil, tmp = cv2.dilate(big, kers[0]), np.empty_like(big)
    for k in kers[1:]:
        np.maximum(dil, cv2.dilate(big, k, dst=tmp), out=dil)
    out = cv2.erode(dil, kers[0], dst=big)
    for k in kers[1:]:
        np.minimum(out, cv2.erode(dil, k, dst=tmp), out=out)
    return out[pad:-pad, pad:-pad]


def disk_rectangles(r: int) -> list:
    """The half-sizes (a, b) of the centred rectangles ``|dx| <= a, |dy| <= b`` whose union is OpenCV's
    elliptic structuring element of radius ``r`` [px] (``2r + 1`` square): one per row offset where the
    row's half-width drops, the widest first."""
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    half = [int(ker[r + dy].sum()) // 2 for dy in range(r + 1)]            # row half-widths, centre out
    return [(half[dy], dy) for dy in range(r + 1) if dy == r or half[dy + 1] < half[dy]]


def band_directions(mask, bridge_px: float, radius_px: float, min_coherence: float = 0.8) -> np.ndarray:
    """The direction across the band at every pixel of a silhouette [rad, 0..π) (h, w) float32; where
    the edges nearby do not agree on one (coherence below ``min_coherence``: the tube's ends), that of
    the nearest pixel where they do.

    The silhouette with its slots bridged (a closing by a disk of
    ``bridge_px``, holes filled) is a band; the gradients of its edges point
    across it. Their structure tensor, smoothed over ``radius_px`` (about
    the band's half width), gives the dominant gradient orientation: across
    the band inside it, whatever its bend.
    """
    band = fill_holes(close_disk(mask, max(int(round(bridge_px)), 1))).astype(np.float32)
    # the tensor varies on the scale of the radius: computed on a copy reduced to about 4 px per radius
    k = max(1, int(radius_px // 4))
    h, w = band.shape
    small = cv2.resize(band, (max(w // k, 1), max(h // k, 1)), interpolation=cv2.INTER_AREA) if k > 1 else band
    s1, s2 = max(0.5 * radius_px / k, 0.7), max(float(radius_px) / k, 1.0)
    b = cv2.GaussianBlur(small, (0, 0), s1)
    gx, gy = cv2.Sobel(b, cv2.CV_32F, 1, 0), cv2.Sobel(b, cv2.CV_32F, 0, 1)
    jxx, jxy, jyy = (cv2.GaussianBlur(v, (0, 0), s2) for v in (gx * gx, gx * gy, gy * gy))
    if k > 1:
        jxx, jxy, jyy = (cv2.resize(v, (w, h), interpolation=cv2.INTER_LINEAR) for v in (jxx, jxy, jyy))
    # where the gradients do not agree on one direction (the tube's ends, the holder), the direction of
    # the nearest pixel where they do
    coherent = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) >= min_coherence * np.maximum(jxx + jyy, 1e-12)
    if not coherent.any():
        return np.full(mask.shape, np.nan, np.float32)
    _, lab = cv2.distanceTransformWithLabels((~coherent).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5,
                                             labelType=cv2.DIST_LABEL_PIXEL)
    src = np.zeros(int(lab.max()) + 1, np.float32)
    # the direction only where it is read (element by element the same values)
    src[lab[coherent]] = (0.5 * np.arctan2(2 * jxy[coherent], jxx[coherent] - jyy[coherent])) % np.float32(np.pi)
    return src[lab]


def fill_thin_lines(mask, length_px: float, n_dirs: int = 8, *, across=None, tol_deg: float = 25.0) -> np.ndarray:
    """The mask with background lines thinner than ``length_px`` filled (uint8).

    A union of closings by line segments of ``length_px`` at ``n_dirs``
    orientations. A specular streak along a dark tube, cut by deep slots into
    pieces that join the slots, disconnects the tube's halves; it is
    narrower than a slot, so a segment shorter than the slot width fills it
    and no slot. With ``across`` (:func:`band_directions`), a pixel is filled
    only by segments within ``tol_deg`` of the direction across the tube: a
    streak runs along the tube and is filled; the mouth of a nearly closed
    slot, thin along the tube, is not.
    """
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
            # the direction is tested only where the closing adds a pixel (a few % of the mask)
            # the pixels the closing adds (it only adds): their coordinates from OpenCV, row by row
            added = cv2.findNonZero(cv2.subtract(closed[pad:-pad, pad:-pad], big[pad:-pad, pad:-pad]))
            if added is None:
                continue
            xx, yy = added.reshape(-1, 2).T
            diff = np.abs((across[yy, xx] - a + np.pi / 2) % np.pi - np.pi / 2)
            out[yy[diff <= tol] + pad, xx[diff <= tol] + pad] = 1
            continue
        out |= closed
    return out[pad:-pad, pad:-pad]
