"""`notchfit simulate` (issue 5 item 6) on a synthetic study, with a model file and overrides."""
import pandas as pd
import pytest

from notchfit.cli import main
from notchfit.physics.friction import FrictionParams
from notchfit.io import save_params
from notchfit.studies.synth import generate_study, load_recipe


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim") / "study"
    generate_study(load_recipe("proximal_friction").scaled(n_experiments=2, n_up=5, n_down=6), d, seed=4)
    return d


def test_simulate_writes_simulation_csv(study, tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(study), "--out", str(out), "--no-figures"]) == 0
    df = pd.read_csv(out / "L045" / "simulation.csv")
    assert {"sample", "regime", "a", "b", "theta_1", "theta_27"} <= set(df.columns)
    assert set(df["regime"]) <= {"I", "II", "III"} and "I" in set(df["regime"])
    # the left pull bends toward negative θ (geometry.md signs)
    assert df["theta_1"].min() < -0.05


def test_model_file_and_overrides_change_the_prediction(study, tmp_path):
    base = tmp_path / "a"
    assert main(["simulate", str(study / "L045"), "--out", str(base), "--no-figures"]) == 0
    model = save_params(FrictionParams(proximal_beta=0.1), tmp_path / "m.toml", cause="proximal_friction")
    ext = tmp_path / "b"
    assert main(["simulate", str(study / "L045"), "--out", str(ext), "--model", str(model),
                 "--no-figures"]) == 0
    a = pd.read_csv(base / "simulation.csv")
    b = pd.read_csv(ext / "simulation.csv")
    assert (a["theta_1"] - b["theta_1"]).abs().max() > 1e-3
    # bad override: exit code 2 with a message, nothing written
    bad = tmp_path / "c"
    assert main(["simulate", str(study / "L045"), "--out", str(bad), "--param", "mu_x=1"]) == 2
    assert not (bad / "simulation.csv").exists()


def test_compare_simulation_on_its_own_prediction():
    """The comparison (notchfit.analysis.comparison) of a simulation with its own noise-free points:
    the predicted a, b are the least-squares line θ_j = a + b j through the simulated angles (Sec. IV-A),
    checked against numpy's polynomial fit, not the summary the simulation itself reports; the
    points fitted by the linear model are within 0.02 mm of the prediction's."""
    import numpy as np

    from notchfit.analysis.comparison import compare_simulation, comparison_table
    from notchfit.physics.friction import simulate
    from notchfit.physics.protocols import bend_unbend
    from notchfit.studies.synth import synthetic_points

    t, tl, tr, ids = bend_unbend(20.0, 0.45, n_up=6, n_down=5)
    res = simulate(t, tl, tr)
    pts, _ = synthetic_points(res.theta, res.geom, (0.004, -0.002, 0.2))
    comp = compare_simulation(res, pts, sigma=2e-5, samples=[int(s) for s in ids])
    j = np.arange(1, res.theta.shape[1] + 1)
    a_ref, b_ref = np.polynomial.polynomial.polyfit(j, res.theta.T, 1)
    np.testing.assert_allclose(comp.a_sim, a_ref, atol=1e-12)
    np.testing.assert_allclose(comp.b_sim, b_ref, atol=1e-12)
    assert np.ptp(comp.a_sim) > 0.05                          # the history bends the tube
    assert np.nanmax(comp.point_rms) < 0.02e-3        # linear fit of non-linear shapes: small, not zero
    assert np.all(comp.point_max >= comp.point_rms)
    pts[0] = np.nan                                   # a sample without points: NaN error, not a failure
    comp = compare_simulation(res, pts, sigma=2e-5)
    assert np.isnan(comp.point_rms[0]) and np.isfinite(comp.point_rms[1:]).all()
    df = comparison_table(comp, res)
    assert list(df.columns) == ["sample", "tension_left_N", "tension_right_N", "regime", "a_meas", "b_meas",
                                "a_sim", "b_sim", "point_rms_mm", "point_max_mm"]


def test_simulate_figures_are_the_friction_figures(study, tmp_path):
    """Figs. 18-19 of `simulate` come from notchfit.figures.friction (PNG and their data as CSV)."""
    out = tmp_path / "o"
    assert main(["simulate", str(study / "L045"), "--out", str(out)]) == 0
    d = pd.read_csv(out / "fig19_shape_parameters.csv")
    assert {"a_pred_rad", "a_meas_rad", "b_meas_rad", "point_rms_mm"} <= set(d.columns)
    assert len(pd.read_csv(out / "fig18_joint_angles.csv")) == 12 * 27
    assert (out / "fig18_joint_angles.png").stat().st_size > 1000
