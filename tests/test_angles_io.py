"""angles.csv: measured joint angles of an experiment (docs/data-formats.md, "angles.csv").

Real-tube labs measure notch angles (lines on the cut faces, an EM sensor per segment)
instead of notch corner points; `sample,joint,theta_deg` (or `theta_rad`, exactly one of the
two), joint 1..n from the base, a missing angle a missing row or NaN, weighted by
`[uncertainty] angle_deg`. Every reader error names the file and the line.
"""
import math

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.studies.synth import load_recipe, synthesize, write_study
from notchfit.units import DEG


def _samples(S=4):
    return pd.DataFrame({"sample": np.arange(1, S + 1), "time_s": 5.0 * np.arange(1, S + 1),
                         "tension_left_N": np.zeros(S), "tension_right_N": np.linspace(0.0, 1.5, S)})


def _angles(n, S=4):
    th = np.linspace(0.0, 0.3, S)[:, None] * np.linspace(1.0, 0.5, n)[None, :]
    th[2, 1] = np.nan                                # one angle not measured
    return th


def _experiment(tmp_path, geom, **kw):
    return io.write_experiment(tmp_path / "w1", name="w1", samples=_samples(), angles=_angles(geom.n_joints),
                               angle_sigma=0.5 * DEG, **kw)


def test_round_trip_angles_only_experiment(tmp_path, geom):
    folder = _experiment(tmp_path, geom)
    assert not (folder / "notch_points.csv").exists()
    exp = io.read_experiment(folder)
    assert exp.points is None and exp.angles.shape == (4, geom.n_joints)
    np.testing.assert_allclose(exp.angles, _angles(geom.n_joints), rtol=0, atol=1e-15)
    assert np.isnan(exp.angles[2, 1]) and exp.angle_sigma == pytest.approx(0.5 * DEG, rel=1e-12)
    assert "angle_deg = 0.5" in (folder / "experiment.toml").read_text()


def test_theta_rad_column_and_missing_rows(tmp_path, geom):
    folder = _experiment(tmp_path, geom)
    (folder / "angles.csv").write_text("sample,joint,theta_rad\n1,1,0.01\n3,27,-0.2\n4,5,nan\n")
    exp = io.read_experiment(folder)
    assert exp.angles[0, 0] == 0.01 and exp.angles[2, 26] == -0.2
    assert np.isfinite(exp.angles).sum() == 2           # every other angle is missing


@pytest.mark.parametrize("text, line, message", [
    ("sample,joint,theta_deg,theta_rad\n1,1,1.0,0.01\n", 1, "both theta_deg and theta_rad"),
    ("sample,joint\n1,1\n", 1, "missing column theta_deg or theta_rad"),
    ("sample,theta_deg\n1,1.0\n", 1, "missing column(s) joint"),
    ("sample,joint,theta_deg\n1,1,1.0\n1,28,2.0\n", 3, "joint 28 out of range 1..27"),
    ("sample,joint,theta_deg\n1,0,1.0\n", 2, "joint 0 out of range"),
    ("sample,joint,theta_deg\n1,1,1.0\n1,1,2.0\n", 3, "duplicate joint 1 of sample 1 (first on line 2)"),
    ("sample,joint,theta_deg\n9,1,1.0\n", 2, "sample 9 is not in samples.csv"),
    ("sample,joint,theta_deg\n1,1,inf\n", 2, "not finite"),
    ("sample,joint,theta_deg\n1,1,-1e3\n", 2, "beyond a joint's physical range"),
    ("sample,joint,theta_deg\n1,1,1;5\n", 2, "non-numeric"),
    ("sample,joint,theta_deg\n1,1.5,2\n", 2, "not an integer"),
])
def test_angles_errors_name_file_and_line(tmp_path, geom, text, line, message):
    folder = _experiment(tmp_path, geom)
    (folder / "angles.csv").write_text(text)
    with pytest.raises(io.InputFileError) as err:
        io.read_experiment(folder)
    msg = str(err.value)
    assert str(folder / "angles.csv") in msg and f"line {line}" in msg and message in msg, msg


def test_angle_uncertainty_must_be_positive(tmp_path, geom):
    folder = _experiment(tmp_path, geom)
    toml = (folder / "experiment.toml").read_text().replace("angle_deg = 0.5", "angle_deg = -1")
    (folder / "experiment.toml").write_text(toml)
    with pytest.raises(ValueError, match=r"\[uncertainty\] angle_deg must be a positive number"):
        io.read_experiment(folder)


def test_angles_table_layout_round_trip():
    th = np.array([[0.1, np.nan], [math.radians(2.0), -0.05]])
    df = io.angles_table(th, [3, 7])
    assert list(df.columns) == ["sample", "joint", "theta_deg"] and len(df) == 3
    back = io.angles_from_table(df.assign(theta=df["theta_deg"] * DEG), [3, 7], 2)
    np.testing.assert_allclose(back, th, rtol=1e-15)


def test_synthetic_wrist_with_angle_data_returns_its_truth(tmp_path):
    """observe = "angles": angles.csv holds the true angles plus the recipe's seeded noise."""
    recipe = load_recipe("wrist_asymmetric").replace(observe="angles", angle_sigma_deg=0.3).scaled(n_experiments=2)
    study = synthesize(recipe, seed=5, method="fast")
    e = study.experiments[0]
    assert e.points is None and e.angles.shape == e.theta.shape
    resid = (e.angles - e.theta) / DEG
    assert abs(resid.std() / 0.3 - 1.0) < 0.25 and abs(resid.mean()) < 0.15
    write_study(study, tmp_path / "s")
    exp = io.read_experiment(tmp_path / "s" / e.name)
    assert exp.points is None and not (tmp_path / "s" / e.name / "notch_points.csv").exists()
    np.testing.assert_allclose(exp.angles, e.angles, rtol=0, atol=1e-12)
    assert exp.angle_sigma == pytest.approx(0.3 * DEG)


def test_true_tensions_are_what_samples_csv_holds():
    """With noise-free load cells the file's tensions are the true ones (the 0.1 mN grid)."""
    recipe = load_recipe("wrist_asymmetric").replace(tension_sigma_N=0.0).scaled(n_experiments=1)
    e = synthesize(recipe, seed=1, method="fast").experiments[0]
    np.testing.assert_array_equal(e.samples["tension_right_N"].to_numpy(), e.tension_right)
