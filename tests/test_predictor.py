"""The real-time predictor (issue 18): one tension sample at a time = the simulator on the whole history.

The paper's motivation for the friction model (Sec. I, IV-B) is a shape
estimate from measured tension during navigation. ``Predictor`` advances the
fast solver's state (Sec. IV-B Steps 1-4, the same kernel) by one interval per
sample; fed a history sample by sample it must return what
``friction.simulate`` returns for the whole history (issue 18: to 1e-9 rad),
on the seed tube (channel law) and on a real-tube wrist (capstan law, rest
angles, one tendon).
"""

from __future__ import annotations

import numpy as np
import pytest

from notchfit.physics.friction import FrictionParams, default_params, simulate
from notchfit.physics.geometry import default_geometry
from notchfit.io import datasets_dir, load_geometry
from notchfit.physics.notches import notch_points, point_projector
from notchfit.physics.predictor import Predictor
from notchfit.physics.protocols import bend_unbend


def _wrist(name="wrist_tip_first"):
    return load_geometry(datasets_dir() / "geometry" / f"{name}.toml")


def _run(pred, t, left, right):
    lv = [None] * len(t) if left is None else list(left)
    return [pred.step(a, b, c) for a, b, c in zip(t, lv, right)]


def _wrist_history():
    """Load to 1.5 N, unload to 0.2 N, reload: stick, slip both ways (capstan law)."""
    T = np.r_[np.linspace(0.0, 1.5, 10), np.linspace(1.3, 0.2, 7), np.linspace(0.5, 1.0, 4)]
    return 5.0 * np.arange(1, T.size + 1), T


@pytest.mark.parametrize("params", [FrictionParams(),
                                    FrictionParams(proximal_beta=0.1, hysteresis_torque=0.002),
                                    FrictionParams(hysteresis_torque=3e-3, hysteresis_onset=0.07,
                                                   hysteresis_yield=2e-3)],
                         ids=["paper", "band+hysteresis", "hysteresis-stop"])
def test_seed_tube_equals_simulate(params):
    """Seed tube, channel law (Sec. IV-B), Fig. 11 protocol with a 1 s ramp: predictor = simulate to 1e-9 rad.

    The hysteresis stop (onset and yield) holds a torque per joint between samples: the predictor
    carries it as state like the angles."""
    p = bend_unbend(25.0, 0.45, pull="right")
    t, tl, tr = np.asarray(p.time), np.asarray(p.tension_left), np.asarray(p.tension_right)
    ref = simulate(t, tl, tr, params, settle_time=5.0, ramp_time=1.0)
    out = _run(Predictor(params, settle_time=5.0, ramp_time=1.0), t, tl, tr)
    theta = np.array([o.theta for o in out])
    assert np.abs(theta - ref.theta).max() <= 1e-9
    assert np.abs(np.array([o.tension_right for o in out]) - ref.tension_right).max() <= 1e-9
    assert np.ptp(ref.theta) > 0.1                      # the history bends the tube


@pytest.mark.parametrize("law", ["capstan", "channel"])
def test_wrist_equals_simulate_and_points(law):
    """Tip-first wrist (rest angles, one tendon, material springs), both friction laws: angles to 1e-9 rad,
    notch points equal to notchfit.physics.notches.notch_points of those angles (Sec. IV-A projector)."""
    g = _wrist()
    params = default_params(g).replace(friction_law=law, mu_d=0.15, mu_s=0.17)
    t, T = _wrist_history()
    ref = simulate(t, None, T, params, g, settle_time=5.0)
    out = _run(Predictor(params, g, settle_time=5.0), t, None, T)
    theta = np.array([o.theta for o in out])
    assert np.abs(theta - ref.theta).max() <= 1e-9
    pts = np.array([o.points for o in out])
    assert np.abs(pts - notch_points(ref.theta, g)).max() <= 1e-12
    # friction leaves the unloading branch above the loading one (hysteresis, Sec. IV-B regimes I-III)
    assert ref.theta[12, -1] > np.interp(T[12], T[:10], ref.theta[:10, -1])


def test_reset_and_no_points():
    """reset() returns to the initial rest state: a second pass repeats the first exactly."""
    g = _wrist("wrist_asymmetric")
    t, T = _wrist_history()
    pred = Predictor(default_params(g).replace(mu_d=0.1, mu_s=0.11), g, points=False)
    first = np.array([o.theta for o in _run(pred, t, None, T)])
    assert pred.n_samples == len(t)
    pred.reset()
    second = _run(pred, t, None, T)
    assert np.array_equal(first, np.array([o.theta for o in second]))
    assert second[-1].points is None
    assert np.allclose(pred.theta, first[-1])
    second[-1].theta[0] = 1.0                     # results are copies: the state is untouched
    assert np.allclose(pred.theta, first[-1])


def test_point_projector_matches_notch_points():
    """The compiled one-shape projector equals notch_points (Sec. IV-A) on the seed tube and a wrist."""
    rng = np.random.default_rng(3)
    for g in (default_geometry(), _wrist()):
        th = rng.normal(0.0, 0.1, g.n_joints)
        assert np.abs(point_projector(g)(th) - notch_points(th, g)).max() <= 1e-15


def test_generator_laws_refused():
    """The generator's Bouc-Wen law is simulated by the reference solver only: the predictor refuses it."""
    with pytest.raises(ValueError, match="reference solver only"):
        Predictor(FrictionParams(bouc_wen_torque=1e-3, bouc_wen_stiffness=0.5))


def test_bad_inputs():
    """Time must increase; a tendon the geometry lacks carries nothing; load-cell offsets within 3 sigma_T clip."""
    g = _wrist()
    pred = Predictor(default_params(g), g, tension_sigma=0.05)
    pred.step(1.0, None, 0.2)
    with pytest.raises(ValueError, match="increase"):
        pred.step(1.0, None, 0.3)
    with pytest.raises(ValueError, match="no left tendon"):
        pred.step(2.0, 0.5, 0.3)
    with pytest.raises(ValueError, match=">= 0 N"):
        pred.step(2.0, None, -0.2)
    a = pred.step(2.0, None, -0.1)                 # within 3 sigma_T: zero tension
    b = Predictor(default_params(g), g)
    b.step(1.0, None, 0.2)
    assert np.array_equal(a.theta, b.step(2.0, None, 0.0).theta)
    with pytest.raises(ValueError, match="has a right tendon"):
        Predictor(default_params(g), g).step(1.0, None, None)
