"""Prediction bands of a tube never measured (issue 27): the identified shared parameters' covariance
plus the tube-to-tube scatter of rest angles and cut depths, carried to every notch angle by sigma
points (notchfit.analysis.estimation.bands.NewTubePrior, tube_band, BandPredictor.for_tube), and
through `notchfit simulate --model` (prediction_band.csv).

The coverage check: a material identified on two synthetic wrists of a stock (seeded), then twelve
new wrists of a third drawing, each cut off its drawing by fresh errors of the stated tolerance,
each predicted from its drawing alone: their 95 % intervals must cover 90-98 % of the measured
angles (measured: 96.1 %, 634 of 660).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.analysis.estimation.bands import BandPredictor, NewTubePrior, tube_band
from notchfit.analysis.identify import identify
from notchfit.cli import main
from notchfit.studies.recipes import recipe_from_dict
from notchfit.studies.stock import stock_geometries, stock_recipe, synthetic_stock
from notchfit.studies.synth import generate_study

#: the drawings' tolerance (a standard deviation) and the cut errors: drawn with it, clipped at 2.5 sigma
TOL = 10e-6
STOCK = {"depth_sd": TOL, "depth_tolerance": 2.5 * TOL}


@pytest.fixture(scope="module")
def geoms():
    return [g.replace(slot_depth_tolerance=TOL) for g in stock_geometries()]


@pytest.fixture(scope="module")
def two_tubes(geoms):
    exps, _ = synthetic_stock(11, trials=(3, 3, 0), geometries=geoms, **STOCK)
    return identify(exps, heldout=False, by_tube=False)


def test_new_tubes_are_covered_by_their_95_percent_bands(two_tubes, geoms):
    res = two_tubes
    prior = res.new_tube
    assert prior.names == ("E_lin", "E_se", "strain_lower", "strain_ratio", "mu_d") and prior.depth_sd is None
    assert res.model.rest_angle is None                      # the stock's model: a new tube gets its own unknowns
    inside, total = 0, 0
    for i in range(12):
        (e,), _ = synthetic_stock(100 + i, trials=(0, 0, 1), geometries=geoms, **STOCK)
        band = tube_band(res.model, e.geometry, e.time, None, e.tension_right, prior, noise_sd=e.angle_sigma)
        ok = np.isfinite(e.angles)
        inside += int(((e.angles >= band.lower) & (e.angles <= band.upper))[ok].sum())
        total += int(ok.sum())
    assert 0.90 <= inside / total <= 0.98, inside / total


def test_prior_round_trip_and_the_tube_unknowns(two_tubes, geoms):
    """The model file's table reads back exactly; a stock model gets the tube's rest angles and depth
    offsets as unknowns (p = k + 2n), a one-tube model (its rest angles known) the k shared ones only."""
    prior = two_tubes.new_tube
    back = NewTubePrior.from_metadata(json.loads(json.dumps(prior.as_metadata())))
    np.testing.assert_array_equal(back.cov, prior.cov)
    assert back.names == prior.names and back.rest_sd == prior.rest_sd and back.depth_sd is None
    g = geoms[2]
    mean, cov, make = prior.distribution(two_tubes.model, g)
    k = len(prior.names)
    assert mean.size == k + 2 * g.n_joints
    np.testing.assert_allclose(np.diag(cov)[-g.n_joints:], TOL ** 2)          # the drawing's tolerance
    p = make(mean)
    assert p.E_lin == pytest.approx(two_tubes.values["E_lin"], rel=1e-12)
    assert p.mu_s - p.mu_d == pytest.approx(two_tubes.model.mu_s - two_tubes.model.mu_d)
    np.testing.assert_allclose(p.rest_angles(g), g.rest_angles)
    one = two_tubes.model.replace(rest_angle=tuple(g.rest_angles))
    assert prior.distribution(one, g)[0].size == k
    with pytest.raises(ValueError, match="agree in size"):
        NewTubePrior.from_metadata({**prior.as_metadata(), "cov": [1.0]})


def test_band_predictor_for_a_tube_equals_the_history_band(two_tubes, geoms):
    """Sample by sample (the real-time predictor at every sigma point) = the whole history's band."""
    (e,), _ = synthetic_stock(5, trials=(0, 0, 1), geometries=geoms, **STOCK)
    band = tube_band(two_tubes.model, e.geometry, e.time, None, e.tension_right, two_tubes.new_tube,
                     settle_time=5.0)
    bp = BandPredictor.for_tube(two_tubes.model, e.geometry, two_tubes.new_tube, settle_time=5.0)
    steps = [bp.step(t, None, T).theta for t, T in zip(e.time, e.tension_right)]
    np.testing.assert_allclose(np.array([s.mean for s in steps]), band.mean, atol=1e-9)
    np.testing.assert_allclose(np.array([s.sd for s in steps]), band.sd, atol=1e-9)


def test_simulate_with_an_identified_model_writes_the_band(two_tubes, tmp_path, capsys):
    """simulate --model with identify's model file: prediction_band.csv per experiment (one row per sample
    and joint), the coverage printed and in simulate_run.json; simulation.csv unchanged in its columns."""
    io.save_params(two_tubes.model, tmp_path / "model.toml", prediction=two_tubes.new_tube.as_metadata())
    d = stock_recipe("new", "wrist_tip_first", [{"name": "N1", "peak_N": [1.6, 1.8]}], seed=5, n_up=6)
    generate_study(recipe_from_dict(d), tmp_path / "s", force=True)
    out = tmp_path / "out"
    assert main(["simulate", str(tmp_path / "s"), "--out", str(out), "--model", str(tmp_path / "model.toml"),
                 "--no-figures"]) == 0
    assert "95 % prediction band covers" in capsys.readouterr().out
    band = pd.read_csv(out / "N1" / "prediction_band.csv")
    assert list(band.columns) == ["sample", "joint", "theta_rad", "sd_rad", "lower_rad", "upper_rad",
                                  "measured_rad", "inside"]
    assert len(band) == 7 * 4 and (band["lower_rad"] < band["upper_rad"]).all()
    run = json.loads((out / "simulate_run.json").read_text())
    assert 0.0 <= run["band_coverage"]["N1"] <= 1.0
    assert "theta_1" in pd.read_csv(out / "N1" / "simulation.csv").columns
