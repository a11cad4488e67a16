"""Synthetic one-tendon wrists through the command line: `simulate` with the true parameters
reproduces the true joint angles to 1e-9 rad and the notch points to the injected noise; `fit`
works on the one-sided wrist. (The synthetic drive's tensions lie on samples.csv's 0.1 mN grid,
so with noise-free load cells the file holds the true tensions exactly.)"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from notchfit import io
from notchfit.cli import main
from notchfit.physics.friction import FrictionParams
from notchfit.studies.synth import generate_study, load_recipe


def test_simulate_with_the_true_model_reproduces_the_wrist(tmp_path, capsys):
    recipe = load_recipe("wrist_asymmetric").replace(tension_sigma_N=0.0).scaled(n_experiments=2)
    generate_study(recipe, tmp_path / "study", seed=3)
    truth = json.loads((tmp_path / "study" / "truth.json").read_text())
    params = FrictionParams(**{k: tuple(v) if isinstance(v, list) else v for k, v in truth["params"].items()})
    io.save_params(params, tmp_path / "true.toml")
    out = tmp_path / "sim"
    assert main(["simulate", str(tmp_path / "study"), "--out", str(out), "--model", str(tmp_path / "true.toml"),
                 "--no-figures"]) == 0
    noise_mm = recipe.point_sigma_mm
    for name, ex in truth["experiments"].items():
        sim = pd.read_csv(out / name / "simulation.csv")
        theta = sim[[f"theta_{j}" for j in range(1, 6)]].to_numpy()
        np.testing.assert_allclose(theta, np.array(ex["theta_rad"]), rtol=0, atol=1e-9)
        cmp = pd.read_csv(out / name / "simulation_vs_measured.csv")
        rms = np.sqrt(np.nanmean(cmp["point_rms_mm"].to_numpy() ** 2))
        assert rms < 2.0 * noise_mm          # the registration leaves about the injected noise
    assert main(["fit", str(tmp_path / "study"), "--models", "cc,linear,free", "--out", str(tmp_path / "fit"),
                 "--no-figures"]) == 0
    fits = io.read_fits(tmp_path / "fit" / next(iter(truth["experiments"])) / "fits.csv")
    free = fits[fits["model"] == "free"]
    assert np.median(free["rms_mm"]) < 2.0 * noise_mm
