"""Measured joint angles through the analyses (issue 18): shape models fitted in angle space,
simulation against measured angles, and the commands on an experiment with angles and no points.

The shape models of Sec. IV-A (``θ = B · params``, notchfit.physics.shapes) fitted to measured angles
are linear least squares: closed forms checked here against the normal equations; the
simulation's angle residual is ``θ_sim − θ_meas`` in degrees (docs/data-formats.md,
``simulation_vs_angles.csv``).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.cli import main
from notchfit.analysis.comparison import angle_residuals, angle_rms, compare_angles
from notchfit.analysis.fitting import fit_angles
from notchfit.analysis.fitting.angles import estimate_angle_sigma
from notchfit.physics.friction import FrictionParams, simulate
from notchfit.studies.synth import generate_study, load_recipe
from notchfit.units import DEG


def _linear_angles(S=8, n=5, a=0.02, b=0.01):
    j = np.arange(1, n + 1)
    return np.linspace(0.2, 1.0, S)[:, None] * (a + b * j)[None, :]


def test_linear_model_recovers_noise_free_angles_and_cc_is_the_mean():
    """Noise-free θ_j = a + b j: the linear model is exact; cc's a is the mean of the measured
    angles (its normal equation) and its residuals sum to zero."""
    th = _linear_angles()
    th[3, 2] = np.nan                                  # one angle not measured
    fit = fit_angles(th, ("cc", "linear", "quadratic"), sigma=0.5 * DEG)
    lin = fit.get("linear")
    assert np.nanmax(np.abs(lin.residuals)) < 1e-14 and np.all(lin.success)
    np.testing.assert_allclose(lin.b, np.linspace(0.2, 1.0, 8) * 0.01, rtol=1e-12)
    cc = fit.get("cc")
    np.testing.assert_allclose(cc.a, np.nanmean(th, axis=1), rtol=1e-12)
    assert np.allclose(np.nansum(cc.residuals, axis=1), 0.0, atol=1e-15)
    assert np.isnan(cc.residuals[3, 2]) and cc.n_angles[3] == 4
    # cc: se_a = σ / sqrt(measured angles) (variance of a mean); b fixed at 0
    np.testing.assert_allclose(cc.se_a, 0.5 * DEG / np.sqrt(cc.n_angles), rtol=1e-12)
    assert np.all(cc.se_b == 0.0)


def test_sigma_estimate_and_failed_samples():
    """σ from the pooled quadratic residuals matches the injected noise (seeded, 400 samples);
    a sample with fewer measured angles than parameters fails with the reason."""
    rng = np.random.default_rng(11)
    th = _linear_angles(S=400) + rng.normal(0.0, 0.3 * DEG, (400, 5))
    assert estimate_angle_sigma(th) == pytest.approx(0.3 * DEG, rel=0.05)
    th[0, 1:] = np.nan
    fit = fit_angles(th, ("linear", "free"))
    assert not fit.get("linear").success[0] and "1 measured angles for 2 parameters" in fit.get("linear").message[0]
    assert fit.get("free").success.sum() == 399


def test_angle_residuals_and_rms():
    """Residuals are θ_pred − θ_meas where measured; rms pooled over every measured angle, per sample, per joint."""
    pred = np.array([[0.1, 0.2], [0.3, 0.4]])
    meas = np.array([[0.1, 0.1], [np.nan, 0.7]])
    r = angle_residuals(pred, meas)
    assert np.isnan(r[1, 0]) and r[0, 1] == pytest.approx(0.1) and r[1, 1] == pytest.approx(-0.3)
    assert angle_rms(r) == pytest.approx(math.sqrt((0.01 + 0.09) / 3))
    np.testing.assert_allclose(angle_rms(r, axis=1), [math.sqrt(0.01 / 2), 0.3])
    np.testing.assert_allclose(angle_rms(r, axis=0), [0.0, math.sqrt(0.1 / 2)])
    assert math.isnan(angle_rms(np.full((2, 2), np.nan)))


def test_compare_angles_of_a_simulation(geom):
    """compare_angles on the seed tube: zero residual against its own prediction; a constant offset
    of 1° appears as an rms of exactly 1° in every sample and joint."""
    t = 5.0 * np.arange(1, 7)
    res = simulate(t, np.full(6, 0.45), np.linspace(0.45, 12.0, 6))
    comp = compare_angles(res, res.theta + 1.0 * DEG, samples=range(1, 7))
    assert comp.rms == pytest.approx(1.0 * DEG, rel=1e-12)
    np.testing.assert_allclose(comp.joint_rms, 1.0 * DEG, rtol=1e-12)
    np.testing.assert_allclose(comp.b_meas, comp.b_sim, atol=1e-12)      # an offset moves a, not b


@pytest.fixture(scope="module")
def angle_study(tmp_path_factory):
    """Two synthetic wrists' experiments measured as angles only (0.5° noise, exact tensions) and the true model."""
    tmp = tmp_path_factory.mktemp("angles")
    recipe = load_recipe("wrist_asymmetric").replace(observe="angles", tension_sigma_N=0.0,
                                                     angle_sigma_deg=0.5).scaled(n_experiments=2, n_up=8, n_down=8)
    generate_study(recipe, tmp / "study", seed=5)
    truth = json.loads((tmp / "study" / "truth.json").read_text())
    params = FrictionParams(**{k: tuple(v) if isinstance(v, list) else v for k, v in truth["params"].items()})
    io.save_params(params, tmp / "true.toml")
    return tmp, truth


def test_simulate_compares_measured_angles_in_degrees(angle_study, capsys):
    """simulate on angles-only experiments with the true model: simulation_vs_angles.csv holds the
    per-sample rms and per-joint errors in degrees; their rms is the injected 0.5° noise."""
    tmp, truth = angle_study
    out = tmp / "sim"
    assert main(["simulate", str(tmp / "study"), "--out", str(out), "--model", str(tmp / "true.toml"),
                 "--no-figures"]) == 0
    errs = []
    for name in truth["experiments"]:
        cmp = pd.read_csv(out / name / "simulation_vs_angles.csv")
        cols = [f"err_{j}_deg" for j in range(1, 6)]
        assert list(cmp.columns[:11]) == ["sample", "tension_left_N", "tension_right_N", "regime", "a_meas",
                                          "b_meas", "a_sim", "b_sim", "rms_deg", "max_deg", "n_angles"]
        e = cmp[cols].to_numpy()
        np.testing.assert_allclose(cmp["rms_deg"], np.sqrt(np.mean(e ** 2, axis=1)), rtol=1e-12)
        errs.append(e)
        assert not (out / name / "simulation_vs_measured.csv").exists()
    rms = float(np.sqrt(np.mean(np.concatenate(errs) ** 2)))
    assert 0.5 * 0.85 < rms < 0.5 * 1.15
    run = json.loads((out / "simulate_run.json").read_text())
    assert set(run["angle_rms_deg"]) == set(truth["experiments"])
    assert "prediction rms" in capsys.readouterr().out


def test_fit_angles_only_experiments(angle_study):
    """fit on angles-only experiments: angle_fits.csv and jointwise.csv per experiment; the free model is
    exact, the linear model leaves about the noise (the wrist bends nearly linearly along its notches)."""
    tmp, truth = angle_study
    out = tmp / "fit"
    assert main(["fit", str(tmp / "study"), "--models", "cc,linear,free", "--out", str(out)]) == 0
    name = next(iter(truth["experiments"]))
    fits = pd.read_csv(out / name / "angle_fits.csv")
    jw = pd.read_csv(out / name / "jointwise.csv")
    assert set(fits["model"]) == {"cc", "linear", "free"} and not (out / name / "fits.csv").exists()
    assert fits.loc[fits["model"] == "free", "rms_deg"].max() < 1e-9
    lin = jw[jw["model"] == "linear"]["err_deg"].to_numpy()
    assert 0.2 < float(np.sqrt(np.mean(lin ** 2))) < 1.0
    assert list(jw.columns) == ["sample", "model", "joint", "err_deg"]
