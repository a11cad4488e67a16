"""Each detector stage alone, on small synthetic images with exactly known answers (issue 15)."""

import math

import cv2
import numpy as np
import pytest

from notchfit.detection import DetectorOptions, detect_notches
from notchfit.detection.base import find_base, holder_mask, image_side
from notchfit.detection.lines import intersect, robust_group_lines
from notchfit.detection.outline import bridge_slots, crop_region, slot_mouths
from notchfit.detection.refine import CornerSpecs, refine_pass
from notchfit.detection.segment import fill_holes, largest_region, segment
from notchfit.detection.view import DiameterScale
from notchfit.detection.width import measure_diameter, rough_radius
from notchfit.render import polygon_coverage


def _image(polys, shape, bg=200.0, fg=40.0, blur=1.0, noise=0.0, rng=None):
    cov = polygon_coverage(polys, shape, supersample=16)
    img = bg + (fg - bg) * cov
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    if noise > 0:
        img = img + rng.normal(0, noise, img.shape)
    return img.astype(np.float32)


def _rect(u0, v0, u1, v1):
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)


def test_options_are_one_frozen_dataclass():
    o = DetectorOptions()
    with pytest.raises(Exception):
        o.pair_tol = 1.0
    assert o.replace(pair_tol=0.2).pair_tol == 0.2 and o.pair_tol == 0.3


@pytest.mark.parametrize("bg,fg", [(200.0, 40.0), (30.0, 180.0)])
def test_segment_either_polarity_under_a_light_gradient(bg, fg):
    """The mask is exactly the pixels more than half covered, dark on light and light on dark."""
    H, W = 120, 160
    poly = _rect(40.2, 30.7, 110.6, 80.3)
    cov = polygon_coverage([poly], (H, W), supersample=16)
    ramp = np.linspace(0.85, 1.15, W)[None, :]
    img = ((bg + (fg - bg) * cov) * ramp).astype(np.float32)
    seg = segment(img)
    assert seg.mask is not None and np.sign(seg.contrast) == np.sign(fg - bg)
    np.testing.assert_array_equal(seg.mask.astype(bool), cov > 0.5)


def test_fill_holes_keeps_slot_sized_holes():
    m = np.zeros((60, 80), np.uint8)
    m[10:50, 10:70] = 1
    m[20:24, 20:24] = 0          # slot-sized hole (16 px)
    m[15:45, 40:44] = 0          # a long streak (120 px)
    out = fill_holes(m, keep_area=(5, 40))
    assert out[20:24, 20:24].sum() == 0 and out[15:45, 40:44].all()


def test_largest_region():
    m = np.zeros((50, 50), np.uint8)
    m[5:10, 5:10] = 1
    m[20:40, 15:45] = 1
    reg, box = largest_region(m)
    assert box == (15, 20, 30, 20) and reg.sum() == 600


def _notched_band(n=4, width=40, slot_w=6, depth=16, length=200, v0=30, u0=20):
    """A horizontal band with n notches from the top edge, polygon in px."""
    pts = [(u0, v0)]
    for k in range(n):
        a = u0 + 30 + 40 * k
        pts += [(a, v0), (a, v0 + depth), (a + slot_w, v0 + depth), (a + slot_w, v0)]
    pts += [(u0 + length, v0), (u0 + length, v0 + width), (u0, v0 + width)]
    return np.array(pts, float)


def test_bridge_slots_finds_every_slot_and_its_mouth():
    poly = _notched_band()
    img = _image([poly], (100, 260), blur=0.0)
    mask = (img < 120).astype(np.uint8)
    reg, box = largest_region(mask)
    roi, off = crop_region(reg, box, mask.shape, 7)
    ol = bridge_slots(roi, off, mask.shape, r_close=5, slot_area=6 * 16, slot_area_range=(0.15, 4.0), sgn=1.0)
    assert len(ol.slot_ids) == 4
    mouths = slot_mouths(ol)
    firsts = sorted(ol.contour[v[0]][0] + ol.offset[0] for v in mouths.values())
    # each mouth starts at a notch's first edge (within the 1-px raster)
    assert np.allclose(firsts, [50 + 40 * k for k in range(4)], atol=2.0)


@pytest.mark.parametrize("side", ["top", "bottom", "left", "right"])
def test_base_end_found_in_every_orientation(side):
    """A wide holder and a 2R band: the base is the holder's end, on the right image side."""
    H = W = 200
    holder = _rect(60, 0, 140, 50)          # base at the top, touching the border
    tube = _rect(85, 50, 115, 170)          # 30 px wide: R = 15
    rot = {"top": 0, "right": 1, "bottom": 2, "left": 3}[side]
    pts = []
    for p in (holder, tube):
        q = p.copy()
        for _ in range(rot):             # rotate 90° clockwise in the image: (u, v) -> (W-1-v, u)
            q = np.stack([W - 1 - q[:, 1], q[:, 0]], 1)
        pts.append(q)
    cov = polygon_coverage(pts[:1], (H, W), supersample=8) + polygon_coverage(pts[1:], (H, W), supersample=8)
    mask = (cov > 0.5).astype(np.uint8)
    reg, box = largest_region(mask)
    roi, off = crop_region(reg, box, mask.shape, 5)
    ol = bridge_slots(roi, off, mask.shape, r_close=3, slot_area=20.0, slot_area_range=(0.15, 4.0), sgn=1.0)
    dist = lambda i, j: float(np.linalg.norm(ol.contour[i] - ol.contour[j]))
    be, why = find_base(ol, (holder_mask(ol.region, 17.25), holder_mask(ol.region, 17.25, regrow=False)), R_lo=15.0, dist=dist, sgn=1.0, min_tube_run_R=2.0,
                        min_base_run_R=2.0, corner_turn_deg=50.0, pair_tol=0.3)
    assert be is not None, why
    assert be.side == side and be.kind == "holder" and be.corners
    # the corners are where the tube meets the holder, 2R apart (plus the bridging fillets, r_close each)
    assert abs(dist(be.i_right, be.i_left) - 30.0) <= 2 * 3


def test_holder_mask_removes_the_tube_and_keeps_the_holder():
    m = np.zeros((120, 120), np.uint8)
    m[0:40, 20:100] = 1                    # holder at the border, 80 x 40
    m[40:110, 50:70] = 1                   # tube 20 wide
    h = holder_mask(m, 1.15 * 10)
    assert h[45:110, 50:70].sum() == 0 or h[60:110, 50:70].sum() == 0
    assert h[0:40, 20:100].mean() > 0.97


def test_image_side():
    assert [image_side(v) for v in ((0, -1), (0, 2), (-3, 1), (2, 0.5))] == ["top", "bottom", "left", "right"]


def test_robust_lines_and_intersection():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 20, 41)
    a = np.stack([t, 0.5 * t + 3], 1) + rng.normal(0, 0.01, (41, 2))
    a[5] += [0, 4]                         # an outlier
    b = np.stack([10 - 0.3 * t, 2 * t], 1)
    pts = np.concatenate([a, b])
    grp = np.repeat([0, 1], 41)
    c, d, n, *_ = robust_group_lines(pts, grp, 2)
    assert n[0] == 40
    X = intersect(c[0], d[0], c[1], d[1])
    # exact: 0.5 u + 3 = v on line a; u = 10 - 0.15 v on line b
    v = (0.5 * 10 + 3) / (1 + 0.5 * 0.15)
    np.testing.assert_allclose(X, [10 - 0.15 * v, v], atol=0.01)


def test_refine_pass_finds_an_l_corner_to_a_twentieth_of_a_pixel():
    """An L-shaped (convex, 90°) corner of a dark square, blurred, with noise: 50 % crossings + line fits."""
    rng = np.random.default_rng(3)
    X = np.array([60.37, 40.81])
    ang = 0.3
    R = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    sq = X + np.array([[0, 0], [0, 50], [-50, 50], [-50, 0]], float) @ R.T   # corner at X
    img = _image([sq], (120, 120), blur=1.0, noise=2.0, rng=rng)
    # anticlockwise outline on the screen with sgn = -1: incoming edge ...
    Din = (R @ [0, -1.0])[None]                 # travelling down the right edge into the corner
    Dout = (R @ [-1.0, 0])[None]
    sp = CornerSpecs(X[None] + [[1.2, -0.8]], Din, Dout, np.array([40.0]), np.array([40.0]), np.zeros(2, bool))
    cam = DiameterScale(1e-5, (120, 120))
    best = None
    for sgn in (1.0, -1.0):
        Cn, *_ , ok, blur, _, _ = refine_pass(img, np.zeros(2), cam, sp, sgn, s0=4, s_end=3, h=6, step=0.5,
                                              lim=0.25, min_points=5, contrast=-160.0)
        if ok[0]:
            best = (sgn, Cn[0], blur)
    assert best is not None, "neither edge polarity refined the corner"
    assert np.linalg.norm(best[1] - X) < 0.05
    assert 0.8 < best[2] < 1.25


def test_measure_diameter_of_a_band():
    W0 = 37.3
    band = np.array([[10, 20.2], [190, 20.2], [190, 20.2 + W0], [10, 20.2 + W0]])
    img = _image([band], (100, 200), blur=1.5)
    st = np.array([[u, 20.2, 0.0, 1.0] for u in (50, 80, 120, 150)])
    w = measure_diameter(img, np.zeros(2), st, 40.0, -160.0, 1.5)
    np.testing.assert_allclose(w, W0, atol=0.05)


def test_rough_radius_prefers_the_thin_band_to_the_holder():
    m = np.zeros((300, 300), np.uint8)
    m[0:120, 40:260] = 1                   # a big holder at the border
    m[120:290, 135:165] = 1                # a 30-px tube with notches
    for v in range(140, 280, 30):
        m[v:v + 6, 135:147] = 0
    r = rough_radius(m, 5)
    assert 13 <= r <= 17.5


def test_no_camera_and_a_blank_image_is_no_manipulator(geom):
    det = detect_notches(np.full((200, 300), 128, np.uint8), None, geom)
    assert det.image_status == "no_manipulator" and np.isnan(det.points).all()
