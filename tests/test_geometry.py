import numpy as np
import pytest

from notchfit.physics.geometry import Geometry, notch_layout
from notchfit.io import load_geometry


def test_default_toml_matches_geometry_md(geom):
    assert geom.n_joints == 27
    assert geom.p == pytest.approx(1.21e-3)
    assert geom.r_x == pytest.approx(2.5e-3) and geom.r_z == pytest.approx(0.2e-3)
    assert geom.slot_sides[0] == -1 and geom.slot_sides[1] == 1  # odd left, even right
    assert geom.n_points == 58
    assert geom == Geometry()  # dataclass defaults equal the shipped TOML


def test_slot_closes_near_014(geom):
    assert geom.closure_angle == pytest.approx(0.14, abs=0.002)


def test_sec3b_cable_stiffness(geom):
    # k_c = EA/L0 = 4.17e4 N/m; the paper prints it truncated as 4.1e4 (Sec. III-B)
    assert geom.cable_stiffness == pytest.approx(1.8e11 * 5.1e-8 / 0.22)
    assert geom.cable_stiffness == pytest.approx(4.1e4, rel=0.02)


def test_numbering_geometry_md(geom):
    lay = notch_layout(geom)
    R, p, w = geom.outer_radius, geom.p, geom.slot_width
    s = lay.straight
    np.testing.assert_allclose(s[0], [-R, -1e-3])      # point 1 base left
    np.testing.assert_allclose(s[1], [R, -1e-3])       # point 2 base right
    np.testing.assert_allclose(s[2], [R, p - w / 2])   # point 3: joint 2 proximal
    np.testing.assert_allclose(s[28], [R, 27 * p])     # point 29 tip right
    np.testing.assert_allclose(s[29], [-R, 27 * p])    # point 30 tip left
    np.testing.assert_allclose(s[30], [-R, 26 * p + w / 2])  # 31: joint 27 distal
    np.testing.assert_allclose(s[57], [-R, -w / 2])    # 58: joint 1 proximal
    assert lay.link[57] == 0 and lay.link[30] == 27 and lay.link[28] == 27
    # anticlockwise: right side increasing z, left side decreasing z
    assert np.all(np.diff(s[2:28, 1]) > 0) and np.all(np.diff(s[30:58, 1]) < 0)


def test_five_joint_layout(geom5):
    lay = notch_layout(geom5)
    assert lay.n_points == 4 + 2 * 5
    # right slots at joints 1, 2, 4 -> 6 points after the two base corners
    assert list(lay.joint[2:8]) == [1, 1, 2, 2, 4, 4]
    assert list(lay.kind[8:10]) == ["tip", "tip"]
    assert list(lay.joint[10:]) == [5, 5, 3, 3]


def _write(tmp_path, text):
    f = tmp_path / "g.toml"
    f.write_text(text)
    return f


BASE = (Path := __import__("pathlib").Path)(__file__).parents[1] / "datasets" / "geometry" / "default.toml"


def test_toml_missing_field(tmp_path):
    text = "\n".join(line for line in BASE.read_text().splitlines() if not line.startswith("p_mm"))
    with pytest.raises(ValueError, match=r"g\.toml: missing geometry field\(s\) p_mm"):
        load_geometry(_write(tmp_path, text))


def test_toml_negative_field(tmp_path):
    text = BASE.read_text().replace("r_x_mm = 2.5", "r_x_mm = -2.5")
    with pytest.raises(ValueError, match="r_x_mm must be positive"):
        load_geometry(_write(tmp_path, text))


def test_toml_bad_sides_and_other_n(tmp_path):
    text = BASE.read_text().replace("n_joints = 27", "n_joints = 5").replace(
        'slot_sides = "alternating"', "slot_sides = [1, 1, -1, 1, -1]")
    g = load_geometry(_write(tmp_path, text))
    assert g.n_joints == 5 and g.slot_sides == (1, 1, -1, 1, -1)
    with pytest.raises(ValueError, match="slot_sides must have n_joints=5"):
        load_geometry(_write(tmp_path, text.replace("[1, 1, -1, 1, -1]", "[1, -1]")))
    with pytest.raises(ValueError, match="not valid TOML"):
        load_geometry(_write(tmp_path, "p_mm = = 1"))


def test_default_geometry_is_the_shipped_default_file():
    import dataclasses

    from notchfit.physics.geometry import default_geometry

    shipped, default = load_geometry("default"), default_geometry()
    for f in dataclasses.fields(Geometry):
        assert getattr(shipped, f.name) == getattr(default, f.name), f.name
    assert shipped == default == Geometry()


def test_toml_errors_name_the_line(tmp_path):
    from notchfit.io import TomlError, TomlFileNotFoundError

    text = BASE.read_text()
    line = 1 + text.splitlines().index(next(s for s in text.splitlines() if s.startswith("r_x_mm")))
    with pytest.raises(TomlError, match=rf"g\.toml: line {line}: r_x_mm must be positive"):
        load_geometry(_write(tmp_path, text.replace("r_x_mm = 2.5", "r_x_mm = -2.5")))
    with pytest.raises(TomlError, match=r"g\.toml: line 2: unknown geometry field\(s\) bogus_mm"):
        load_geometry(_write(tmp_path, "# a comment\nbogus_mm = 1\n" + text))
    with pytest.raises(TomlError, match=r"g\.toml: line 1: bad TOML"):
        load_geometry(_write(tmp_path, "p_mm = = 1"))
    with pytest.raises(TomlFileNotFoundError, match="geometry file not found"):
        load_geometry(tmp_path / "none.toml")
