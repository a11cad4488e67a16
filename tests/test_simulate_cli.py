"""`notchfit simulate` (issue 5 item 6) on a synthetic study, with a model file and overrides."""
import pandas as pd
import pytest

from notchfit.cli import main
from notchfit.friction import FrictionParams, save_params
from notchfit.synth import generate_study, load_recipe


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
