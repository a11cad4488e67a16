"""The physics candidates of issue 27's search (what the per-tube freedom was absorbing), as identify fits them.

The tension–compression asymmetry of superelastic nitinol (strain_ratio): the plateau starts where the
back fibre reaches strain_lower in tension or the cut fibre reaches strain_ratio x strain_lower in
compression, the section's fibre distances from notchfit.physics.section (Roark's segment moments).
"""

from __future__ import annotations

import numpy as np
import pytest

from notchfit import io
from notchfit.analysis.identify import parse_free, specs_for
from notchfit.physics.friction import FrictionParams, default_params
from notchfit.physics.section import notch_section
from notchfit.physics.springs import material_spring


@pytest.fixture(scope="module")
def tip_first():
    return io.load_geometry(io.datasets_dir() / "geometry" / "wrist_tip_first.toml")


def test_asymmetric_onset_against_the_section(tip_first):
    """Onset δ = min(ε h / c_back, r ε h / c_cut) from the section's own fibres; r = 1 is the symmetric law
    (the most strained fibre) bit for bit; a stiffer compression side moves the onset only of the notches
    whose cut fibre governs."""
    g = tip_first
    sec = notch_section(g.outer_radius, g.inner_radius, g.slot_depths)
    h, eps = g.slot_widths, 0.014
    sym = material_spring(g, 45e9, 3e9, eps)
    one = material_spring(g, 45e9, 3e9, eps, strain_ratio=1.0)
    np.testing.assert_array_equal(sym.breaks, one.breaks)
    np.testing.assert_array_equal(sym.breaks[:, 0], eps * h / np.maximum(sec.back_fibre, sec.cut_fibre))
    asym = material_spring(g, 45e9, 3e9, eps, strain_ratio=1.5)
    expected = np.minimum(eps * h / sec.back_fibre, 1.5 * eps * h / sec.cut_fibre)
    np.testing.assert_allclose(asym.breaks[:, 0], expected, rtol=1e-15)
    cut_governs = sec.cut_fibre > sec.back_fibre
    assert cut_governs.any() and not cut_governs.all()
    assert np.all(asym.breaks[cut_governs, 0] > sym.breaks[cut_governs, 0])
    np.testing.assert_array_equal(asym.breaks[~cut_governs, 0], sym.breaks[~cut_governs, 0])
    np.testing.assert_array_equal(asym.rates, sym.rates)
    with pytest.raises(ValueError, match="strain_ratio must be positive"):
        material_spring(g, 45e9, 3e9, eps, strain_ratio=0.0)


def test_strain_ratio_in_model_files_and_free(tip_first, tmp_path):
    """Written to a model file only when not 1 (a model file of the symmetric law is unchanged), read back;
    identify fits it with --free strain_ratio, on the material law only."""
    p = default_params(tip_first)
    io.save_params(p, tmp_path / "a.toml")
    assert "strain_ratio" not in (tmp_path / "a.toml").read_text()
    io.save_params(p.replace(strain_ratio=1.4), tmp_path / "b.toml")
    assert io.load_params(tmp_path / "b.toml").strain_ratio == 1.4
    assert parse_free(["strain_ratio"]) == ("strain_ratio",)
    spec, = specs_for(("strain_ratio",), [p])
    assert spec.log and spec.lower < 1.0 < 1.5 < spec.upper
    with pytest.raises(ValueError, match="spring_law = 'material'"):
        specs_for(("strain_ratio",), [FrictionParams()])


def test_strain_ratio_is_identified_where_the_cut_face_governs(tip_first):
    """By default only for tubes with a notch whose cut face lies >= 5 % farther from the neutral axis
    than its back (the tip-first wrist's shallow base notch: 11 %), not for the uniform wrist (4 %)."""
    from notchfit.analysis.identify import default_free
    uniform = io.load_geometry(io.datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    assert "strain_ratio" not in default_free([default_params(uniform)], [uniform])
    assert default_free([default_params(tip_first)], [tip_first])[:5] == ("E_lin", "E_se", "strain_lower",
                                                                         "strain_ratio", "mu_d")
