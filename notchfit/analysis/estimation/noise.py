"""The noise floor: the error a perfect model would leave on an experiment.

``2 σ_p²`` per notch point from the point uncertainty (``σ_θ²`` per measured
angle), plus the load-cell uncertainty ``σ_T`` (:func:`notchfit.analysis.estimation.tension_sigma`)
propagated through the model: the tensions the simulator is driven with are
the noisy measured ones. With the paper's ±0.11 N load cells the second term
dominates (about 0.1 mm).
"""

from __future__ import annotations

import zlib

import numpy as np

from ...physics.friction import FrictionParams, simulate_angles
from ...physics.notches import notch_points
from .observations import Observations
from .problem import Simulations

__all__ = ["noise_floor"]


def _frame_free(obs: Observations, theta) -> np.ndarray:
    """What is compared, in a frame that does not depend on the registration: notch points in the
    manipulator frame (a rigid registration keeps distances) or the joint angles."""
    return theta if obs.metric == "angles" else notch_points(theta, obs.geom)


def _seed_of(obs: Observations, seed: int) -> list:
    """The draws' seed of one experiment: ``[seed, S, round(1e6 σ_T), crc32(name)]``: each experiment its own
    draws (with one noise vector for every experiment of a length, the trials of a study all drew low or
    high at the same samples, and the error of few draws did not average out over them)."""
    return [seed, len(obs.time), int(1e6 * obs.tension_sigma), zlib.crc32(obs.name.encode())]


def _draws(obs: Observations, rng, draws: int, matched: bool | None) -> np.ndarray:
    """The load-cell noise of each draw (draws, 2, S) [N], left and right tendon; with ``matched`` (None: on
    a tube with one tendon) each sample's noise rescaled so that its mean square over the draws is ``σ_T²``
    exactly."""
    e = rng.normal(0.0, obs.tension_sigma, (draws, 2, len(obs.time)))
    if matched is None:
        matched = len(obs.geom.tendons) == 1
    if matched:
        rms = np.sqrt(np.mean(e**2, axis=0))
        e = e * (obs.tension_sigma / np.where(rms > 0, rms, 1.0))
    return e


def noise_floor(obs: Observations, params: FrictionParams, sims: Simulations | None = None, *,
                draws: int = 4, seed: int = 0, matched: bool | None = None) -> np.ndarray:
    """Expected squared error of a perfect model, per sample [m² per point or rad² per angle] (S,).

    Point noise gives ``2 σ_p²`` (angle noise ``σ_θ²``). The load-cell noise's
    effect is estimated by Monte Carlo: the experiment is re-simulated
    with independent Gaussian noise of standard deviation ``σ_T`` added to
    every measured tension, and the mean squared change of the predicted
    measurement is added. Independent per-sample noise matters more than a
    common offset: a small spurious reversal of the tension makes cables
    stick and changes the friction history.

    On a tube with one tendon each sample's noise is moment-matched over the draws (``matched``): rescaled
    so that its mean square is ``σ_T²`` exactly. Where the response is smooth over the noise and driven by
    the sample's own tension (one tendon, no friction history: a wrist loading along its superelastic curve)
    the squared change of a sample is ``‖J_s‖² ε_s²``, so the floor is then the linearised propagation
    ``σ_T² ‖J_s‖²`` with any number of draws, where a few independent draws scatter widely on the few
    samples of a superelastic snap that carry the floor. With two tendons, whose noise meets in every sample
    and whose cables stick and slip against each other, matching is not exact and was found biased low, so
    two tendons keep independent draws (measurements: docs/diagnosis.md and docs/history.md).

    Parameters
    ----------
    obs : Observations
    params : FrictionParams
        The model.
    sims : Simulations, optional
        Where the noise-free prediction is cached.
    draws : int
        Monte Carlo draws (0: measurement noise only).
    seed : int
        Seed of the draws: ``numpy.random.default_rng([seed, S, round(1e6 σ_T), crc32(name)])``.
    matched : bool, optional
        Moment-match each sample's noise over the draws (False: independent Gaussian draws; default: on a
        tube with one tendon).

    Returns
    -------
    ndarray, shape (S,) [m² or rad²]
    """
    floor = np.full(len(obs.time), obs.point_factor * obs.sigma**2)
    if not obs.tension_sigma or draws < 1:
        return floor
    ref = _frame_free(obs, (sims or Simulations()).theta(obs, params))
    noise = _draws(obs, np.random.default_rng(_seed_of(obs, seed)), draws, matched)
    acc = np.zeros(len(obs.time))
    # a tendon the tube lacks carries no tension, with or without noise
    has = {side: side in obs.geom.tendons for side in ("left", "right")}
    for el, er in noise:
        tl = np.maximum(obs.tension_left + el, 0.0)
        tr = np.maximum(obs.tension_right + er, 0.0)
        th = simulate_angles(obs.time, tl if has["left"] else None, tr if has["right"] else None, params, obs.geom,
                             ramp_time=obs.ramp_time)
        d = _frame_free(obs, th) - ref
        d2 = np.sum(d**2, axis=-1) if obs.metric == "points" else d**2
        d2[~obs.valid] = np.nan
        acc += np.nanmean(d2, axis=1)
    return floor + acc / draws
