"""Geometries of real tubes (docs/geometry.md, "Real tubes"): per-joint dimensions, the section
backbone, one tendon in the lumen, pre-curvature, and the seed tube unchanged."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from notchfit.physics.geometry import Geometry, default_geometry, geometry_from_dict, notch_layout
from notchfit.io import load_geometry
from notchfit.physics.section import notch_section

DATA = Path(__file__).resolve().parent.parent / "datasets" / "geometry"
MM = 1e-3

WRIST = dict(n_joints=5, outer_radius=0.81 * MM, inner_radius=0.70 * MM, slot_width=0.8 * MM,
             slot_depth=1.40 * MM, p=1.6 * MM, slot_sides=(1,) * 5, backbone="section", tendons=("right",),
             tendon_path="lumen", cable_radius=0.05 * MM, r_x=None, r_z=None, channel_radius=None,
             mount_half_width=None, mount_bottom_z=None, cable_E=None, cable_A=None, cable_L0=None)


def test_per_joint_arrays_with_equal_values_give_the_scalar_layout_exactly():
    g = default_geometry()
    n = g.n_joints
    ga = g.replace(p=(g.p,) * (n - 1), slot_width=(g.slot_width,) * n, slot_depth=(g.slot_depth,) * n,
                   rest_angle=(0.0,) * n)
    la, ls = notch_layout(ga), notch_layout(g)
    np.testing.assert_allclose(la.straight, ls.straight, rtol=0, atol=1e-18)
    np.testing.assert_allclose(la.local, ls.local, rtol=0, atol=1e-18)
    np.testing.assert_array_equal(ga.closure_angles, g.closure_angles)
    assert ga.tip_z == pytest.approx(g.tip_z, abs=1e-15)


def test_seed_tube_properties_are_todays():
    g = default_geometry()
    assert g.joint_z[5] == 5 * 1.21e-3 and g.tip_z == 27 * 1.21e-3
    assert g.closure_angle == 2.0 * math.atan(0.42e-3 / (2.0 * 3.0e-3))      # today's formula, bit for bit
    np.testing.assert_array_equal(g.neutral_axis_x, 0.0)
    np.testing.assert_array_equal(g.moment_arms(+1), 2.5e-3)
    assert g.tendon_sides == (-1, 1) and g.rest_angles.sum() == 0


def test_one_sided_wrist_section_backbone():
    """OD 1.62 / ID 1.40 mm, 0.8 mm notches cut 1.40 mm deep: the bending axis sits on the
    remaining wall (York et al., ICRA 2015) and the slots close near 30°, not at 52.6°."""
    g = Geometry(**WRIST)
    s = notch_section(0.81 * MM, 0.70 * MM, 1.40 * MM)
    np.testing.assert_allclose(g.neutral_axis_x, -s.neutral_offset)          # away from the +x slots
    assert np.all(np.degrees(g.closure_angles) == pytest.approx(30.32, abs=0.05))
    np.testing.assert_allclose(g.moment_arms(+1), 0.65 * MM + s.neutral_offset)
    assert g.tendon_sides == (1,)
    assert g.replace(backbone="axis").closure_angle == pytest.approx(math.radians(52.6), abs=2e-3)
    with pytest.raises(ValueError, match="cable_E"):
        g.cable_stiffness


def test_shipped_wrist_files_load():
    g = load_geometry(DATA / "wrist_asymmetric.toml")
    assert g.n_joints == 5 and g.backbone == "section" and g.tendons == ("right",)
    assert g.n_points == 14 and notch_layout(g).n_points == 14
    t = load_geometry(DATA / "wrist_tip_first.toml")
    assert np.all(np.diff(t.section.second_moment) < 0)                   # deeper cuts toward the tip
    np.testing.assert_allclose(t.rest_angles, 0.035)
    np.testing.assert_allclose(t.joint_z, [0, 1.3e-3, 2.6e-3, 3.9e-3])


def test_non_uniform_spacing_and_tip_face():
    g = Geometry(**{**WRIST, "n_joints": 3, "slot_sides": (1, 1, 1), "p": (1.0 * MM, 1.5 * MM),
                    "tip_face_z": 4.0 * MM})
    np.testing.assert_allclose(g.joint_z, [0, 1.0 * MM, 2.5 * MM])
    lay = notch_layout(g)
    z_slot3 = lay.straight[[k for k in range(lay.n_points) if lay.joint[k] == 3], 1]
    np.testing.assert_allclose(z_slot3, [2.1 * MM, 2.9 * MM])
    assert lay.straight[lay.kind.index("tip"), 1] == 4.0 * MM
    assert Geometry(**{**WRIST, "n_joints": 3, "slot_sides": (1, 1, 1), "p": (1.0 * MM, 1.5 * MM)}).tip_z \
        == pytest.approx(4.0 * MM)


@pytest.mark.parametrize("change, message", [
    ({"slot_depth": 1.7 * MM}, "smaller than the tube diameter"),
    ({"slot_width": 1.7 * MM}, "overlap"),
    ({"inner_radius": None}, "inner_radius"),
    ({"inner_radius": 0.9 * MM}, "smaller than outer_radius"),
    ({"tendons": ("up",)}, "tendons"),
    ({"tendon_path": "sheath"}, "tendon_path"),
    ({"backbone": "spine"}, "backbone"),
    ({"rest_angle": 0.6}, "closure angle"),
    ({"slot_width": (0.8 * MM,) * 4}, "5 values"),
    ({"p": (1.6 * MM,) * 5}, "4 values"),
    ({"mount_half_width": 2 * MM}, "mount"),
    ({"slot_depth": float("nan")}, "finite"),
])
def test_invalid_geometries_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        Geometry(**{**WRIST, **change})


def test_channel_routing_needs_its_fields():
    with pytest.raises(ValueError, match="needs r_x"):
        Geometry(**{**WRIST, "tendon_path": "channel"})


def test_geometry_file_lists_and_messages():
    base = {"n_joints": 3, "p_mm": [1.0, 1.2], "outer_radius_mm": 0.81, "inner_radius_mm": 0.7,
            "slot_width_mm": 0.5, "slot_depth_mm": [1.3, 1.35, 1.4], "base_edge_z_mm": -1.0,
            "slot_sides": [1, 1, 1], "backbone": "section", "tendons": ["right"], "tendon_path": "lumen",
            "rest_angle_rad": 0.02}
    g = geometry_from_dict(base, "w.toml")
    assert g.p == (1.0 * MM, 1.2 * MM) and g.slot_depth[2] == pytest.approx(1.4 * MM)
    lines = {"slot_depth_mm": 7}
    with pytest.raises(ValueError, match=r"w.toml: line 7: slot_depth_mm must have 3 values"):
        geometry_from_dict({**base, "slot_depth_mm": [1.3, 1.4]}, "w.toml", line_of=lines.get)
    with pytest.raises(ValueError, match="tendons must be a list"):
        geometry_from_dict({**base, "tendons": "right"}, "w.toml")
    with pytest.raises(ValueError, match="missing geometry field"):
        geometry_from_dict({k: v for k, v in base.items() if k != "slot_width_mm"}, "w.toml")


@pytest.mark.parametrize("change, message", [
    ({"slot_sides": (1.5, 1, 1, 1, 1)}, "integers -1 or \\+1"),
    ({"slot_sides": (True, 1, 1, 1, 1)}, "integers -1 or \\+1"),
    ({"p": 1e300}, "unit error"),
    ({"slot_width": 2.0}, "unit error"),
    ({"n_joints": 10**6, "slot_sides": ()}, "from 1 to"),
])
def test_implausible_values_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        Geometry(**{**WRIST, **change})


def test_channels_and_mount_must_fit_the_tube():
    g = default_geometry()
    with pytest.raises(ValueError, match="r_x must not exceed"):
        g.replace(r_x=3.5e-3)
    with pytest.raises(ValueError, match="mount_half_width must be larger"):
        g.replace(mount_half_width=2e-3)
