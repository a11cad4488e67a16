"""Pieces of the diagnosis that do not need the simulator."""
import math

import numpy as np
import pytest

from notchfit.diagnosis import (CANDIDATES, CAUSES, folds_by_experiment, loading_stalls,
                                paired_z, rank_candidates)
from notchfit.diagnosis import peak_regimes as measured_regimes
from notchfit.diagnosis.noise import _effective_n
from notchfit.diagnosis.signatures import _loop_area, _release_tension


def test_causes_match_data_format_table():
    assert set(CAUSES) == {"proximal_friction", "static_friction", "joint_hysteresis",
                           "external_load", "stiffness_gradient", "calibration_error"}
    assert set(CANDIDATES) == set(CAUSES)


def test_fig11_regimes_from_data():
    """I up to the tension peak; II while the shape holds; III once it releases (Sec. IV, Fig. 11)."""
    T = np.r_[np.linspace(0, 25, 19), np.linspace(23, 0, 12)]
    tip = np.r_[np.linspace(0, 2.0, 19), [2.0, 1.98, 1.95, 1.9, 1.5, 1.0, 0.6, 0.3, 0.15, 0.1, 0.05, 0.0]]
    reg = measured_regimes(T, tip)
    assert list(reg[:19]) == ["I"] * 19
    assert list(reg[19:23]) == ["II"] * 4
    assert set(reg[23:]) == {"III"}


def test_loop_area_of_a_rectangle():
    T = np.array([0.0, 10.0, 10.0, 0.0])
    phi = np.array([0.0, 0.0, 1.0, 1.0])
    assert _loop_area(T, phi) == pytest.approx(10.0)
    # a path that retraces itself encloses nothing
    assert _loop_area(np.r_[T[:2], T[1::-1]], np.zeros(4)) == pytest.approx(0.0)


def test_release_tension_interpolates():
    T = np.array([0, 10, 20, 15, 10, 5, 0.0])
    phi = np.array([0, 1, 2, 2, 1, 0.5, 0.0])
    # half of the drop (2 -> 0) is reached at phi = 1, i.e. T = 10
    assert _release_tension(T, phi, None) == pytest.approx(10.0)


def test_effective_n_white_vs_correlated(rng):
    white = rng.normal(size=2000)
    assert _effective_n(white) == pytest.approx(2000, rel=0.1)
    ar = np.zeros(2000)
    for k in range(1, 2000):
        ar[k] = 0.9 * ar[k - 1] + rng.normal()
    # AR(1) with rho = 0.9: n (1 - rho)/(1 + rho) ~ n/19
    assert _effective_n(ar) == pytest.approx(2000 / 19, rel=0.35)


def test_paired_z_detects_improvement_and_respects_correlation(rng):
    base = [1.0 + 0.1 * rng.normal(size=40) for _ in range(4)]
    same = [b + 0.01 * rng.normal(size=40) for b in base]
    better = [0.8 * b for b in base]
    assert abs(paired_z(base, same)) < 3
    assert paired_z(base, better) > 10
    # a slowly varying difference counts as fewer independent samples: smaller z
    drift = [b - (0.02 + 0.05 * np.sin(np.linspace(0, 1, 40))) for b in base]
    white = [b - (0.02 + 0.05 * rng.permutation(np.sin(np.linspace(0, 1, 40)))) for b in base]
    assert paired_z(base, drift) < paired_z(base, white)


def test_folds_cover_every_experiment_once():
    for n in (2, 5, 6, 9):
        folds = folds_by_experiment(n)
        allv = np.sort(np.concatenate(folds))
        np.testing.assert_array_equal(allv, np.arange(n))
    with pytest.raises(ValueError, match="at least two"):
        folds_by_experiment(1)


def test_ranking_follows_signatures():
    sigs = [{"signature": "spatial_pattern", "value": 3.0}, {"signature": "loop_area_ratio", "value": 1.0}]
    assert rank_candidates(sigs, 2e-5)[0][0] == "calibration_error"
    sigs = [{"signature": "direction_asymmetry", "value": 0.05}]
    assert rank_candidates(sigs, 2e-5)[0][0] == "external_load"
    assert math.isfinite(rank_candidates([], 2e-5)[0][1])


def test_loading_stalls_counts_upper_ramp_steps_that_do_not_move():
    """Sec. IV-B Step 4 with μ_s >> μ_d: a step below the break-away excess moves nothing."""
    T = np.array([0.5, 5.0, 10.0, 15.0, 20.0, 25.0, 20.0, 10.0])
    pred = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.0, 0.6])
    meas = np.array([0.0, 0.2, 0.4, 0.6, 0.6, 1.0, 1.0, 0.6])     # stalled on 15 -> 20 N
    assert loading_stalls(T, meas, pred) == (1, 3)                 # steps above 12.5 N: 3
    assert loading_stalls(T, pred, pred) == (0, 3)
    # only the steps above `upper` x the peak count; nor does one that the model barely moves
    assert loading_stalls(T, meas, pred, upper=0.9) == (0, 1)
    flat = pred.copy()
    flat[4] = flat[3] + 0.005
    assert loading_stalls(T, meas, flat)[1] == 2


def test_ranking_points_to_static_friction_on_stalls():
    sigs = [{"signature": "loading_stalls", "value": 0.2}, {"signature": "loop_area_ratio", "value": 1.0}]
    top, _, why = rank_candidates(sigs, 2e-5)[0]
    assert top == "static_friction" and "stalls" in why
