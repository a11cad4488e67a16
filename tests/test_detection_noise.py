"""Stage tests of the scale step without a camera file: the background noise behind the contrast test,
and the honesty of the scale's stated σ (issue 25, round 2: a 50-60 DN tube on grid paper or next to a
knurled chuck was refused as "below 4 x the background noise", and the scale's σ was 3-40 times too small)."""

import numpy as np

from notchfit.vision.detection import detect_notches, mirror_without_camera
from notchfit.vision.detection.segment import downsample, full_noise, segment


def _grid_scene(seed=3, size=1200, noise=3.0, tube=-60.0, line=-45.0, pitch=40, width=3):
    """A dark band (the tube, ``tube`` DN) across a 150 DN card with dark grid lines (``line`` DN, ``width`` px
    every ``pitch`` px) and white noise of ``noise`` DN: the truth is the card's noise."""
    rng = np.random.default_rng(seed)
    img = np.full((size, size), 150.0)
    grid = (np.arange(size) % pitch) < width
    img[grid, :] += line
    img[:, grid] = np.minimum(img[:, grid], 150.0 + line)
    img[size // 2 - 60:size // 2 + 60, size // 5:4 * size // 5] = 150.0 + tube
    return np.clip(img + rng.normal(0.0, noise, img.shape), 0, 255).astype(np.uint8)


def test_noise_behind_the_contrast_test_is_the_backgrounds_not_the_textures():
    """Grid paper at full resolution covers a minority of the pixels; on a copy 24 x smaller every block
    holds grid lines, whose spread times 24 passes for noise far above the card's. The full-resolution
    estimate is the card's noise (3 DN, within 25 %), and the 60 DN tube passes the 4 x noise test only
    with it."""
    img = _grid_scene()
    f = 24
    small = downsample(img, f)
    coarse = segment(small, noise_scale=f)
    assert coarse.mask is None and "below 4 x the background noise" in coarse.message   # the old estimate
    seg = segment(small, noise_scale=f, full=img)
    assert seg.mask is not None
    band = seg.mask[len(small) // 2 - 1:len(small) // 2 + 2, small.shape[1] // 4:3 * small.shape[1] // 4]
    assert band.all()
    est = full_noise(img, small, np.array([150.0, 0, 0, 0, 0, 0]), f, 15.0)
    assert abs(est / 3.0 - 1) <= 0.25
    # on a card without texture both estimates are the noise: the full-resolution one changes nothing there
    plain = _grid_scene(line=0.0)
    assert abs(full_noise(plain, downsample(plain, f), np.array([150.0, 0, 0, 0, 0, 0]), f, 15.0) / 3.0 - 1) <= 0.1


def test_scale_sigma_covers_the_scale_error_on_random_lab_scenes():
    """Seeded random lab scenes without a camera file (tilt out of the plane up to 4 deg, perspective,
    shading, defocus): wherever a corner is ok the scale error is within 3 stated σ (the spread of the
    width profiles; their standard error was 3-4 times too small), and where none is, no σ is stated."""
    from notchfit.vision.render.variety import draw_scene, render_draw

    from test_detection_scenes import _lab_geometries

    rng = np.random.default_rng(15)
    geoms = _lab_geometries()
    z, stated = [], 0
    for _ in range(8):
        d = draw_scene(rng, geoms, size=(960, 640), px_per_mm=50.0)
        r = render_draw(d, rng)
        det = detect_notches(r.image, None, d.geom,
                             mirror=mirror_without_camera(d.camera, r.image.shape[:2], d.plane[3]))
        if det.n_ok:
            z.append((det.scale_mm_per_px * 50.0 - 1) / (det.scale_sigma * 50.0))
        else:
            stated += int(np.isfinite(det.scale_sigma))
    assert len(z) >= 5 and np.all(np.abs(z) <= 3.0)
    assert stated == 0


def test_printed_tube_scale_next_to_the_corners_where_the_band_confirms_nothing():
    """The white printed tube on blue paper through a phone lens (``printed_b`` of the physically based
    gallery): across the band its shaded limbs pull the 50 % crossings 20 % inside, no corner passes the
    plane checks at that scale, and the widths next to the corners of a detection at the rough scale give
    the scale within 1 % (before: 25 % off, 0 corners). Every ok corner is its own, and the stated σ
    covers the scale's error."""
    import json
    from pathlib import Path

    from notchfit.io import load_geometry, load_image
    from notchfit.vision.render.pbr import PbrScene, PbrTruth, score_detection

    root = Path(__file__).resolve().parent.parent
    rec = json.loads((root / "tests" / "data" / "pbr" / "printed_b.json").read_text())
    scene, truth = PbrScene.from_dict(rec["scene"]), PbrTruth.from_dict(rec)
    img = load_image(root / "tests" / "data" / "pbr" / rec["image"])
    det = detect_notches(img, None, load_geometry(root / rec["geometry"]),
                         mirror=mirror_without_camera(truth.camera, img.shape[:2], truth.pose.plane[3]))
    s = score_detection(det, truth, scene.px_per_mm)
    assert s.ok >= 5 and s.wrong == 0 and s.invented == 0
    err = det.scale_mm_per_px * scene.px_per_mm - 1
    assert abs(err) <= 0.01 and abs(err) <= 3 * det.scale_sigma * scene.px_per_mm


def test_band_search_on_the_trimmed_silhouette_is_the_same_to_the_bit():
    """The rough band search runs its closings' distance transforms on the silhouette's box plus one empty
    row and column (``width.trim_box``: about half the pixels on the seed image's coarse copy). Inside the box the
    closings and distances are those of the untrimmed silhouette, so the band radii and slot counts are
    the same for any empty margin around it."""
    import cv2

    from notchfit.vision.detection.segment import band_directions, fill_thin_lines
    from notchfit.vision.detection.width import _close_disk, _distance_to, radius_candidates, trim_box

    rng = np.random.default_rng(7)
    region = np.zeros((90, 160), np.uint8)
    cv2.line(region, (14, 45), (146, 40), 1, 17)                  # a band 17 px wide with random notches
    for x in rng.integers(20, 140, 6):
        region[int(rng.integers(30, 38)):50, x:x + 4] = 0
    for margin in (0, 5, 40):
        big = cv2.copyMakeBorder(region, margin, margin + 3, margin + 1, margin, cv2.BORDER_CONSTANT, value=0)
        assert radius_candidates(big, max_close_px=20) == radius_candidates(region, max_close_px=20)
        box = trim_box(big)
        for r in (2, 5, 11):
            full, p = _close_disk(big, r, near=_distance_to(big, 22))
            trim, q = _close_disk(big[box], r, near=_distance_to(big[box], 22))
            a = cv2.distanceTransform(full, cv2.DIST_L2, 5)[p:-p, p:-p][box]
            b = cv2.distanceTransform(trim, cv2.DIST_L2, 5)[q:-q, q:-q]
            assert np.array_equal(a, b)
        # the streak fill's line closings add pixels only between the mask's: the same in the box
        across = band_directions(big, 5.0, 8.5)
        whole = fill_thin_lines(big, 7.0, across=across)
        assert np.array_equal(whole[box], fill_thin_lines(np.ascontiguousarray(big[box]), 7.0, across=across[box]))
        outside = whole.copy()
        outside[box] = 0
        assert not outside.any()
