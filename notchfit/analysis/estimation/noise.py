"""The noise floor: the error a perfect model would leave on an experiment.

``2 σ_p²`` per notch point from the point uncertainty (``σ_θ²`` per measured
angle), plus the load-cell uncertainty ``σ_T`` (:func:`notchfit.analysis.estimation.tension_sigma`)
propagated through the model: the tensions the simulator is driven with are
the noisy measured ones. With the paper's ±0.11 N load cells the second term
dominates (about 0.1 mm).
"""

from __future__ import annotations

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


def noise_floor(obs: Observations, params: FrictionParams, sims: Simulations | None = None, *,
                draws: int = 4, seed: int = 0) -> np.ndarray:
    """Expected squared error of a perfect model, per sample [m² per point or rad² per angle] (S,).

    Point noise gives ``2 σ_p²`` (angle noise ``σ_θ²``). The load-cell noise's
    effect is estimated by Monte Carlo: the experiment is re-simulated
    ``draws`` times with independent Gaussian noise of standard deviation
    ``σ_T`` added to every measured tension, and the mean squared change of
    the predicted measurement is added. Independent per-sample noise matters
    more than a common offset: a small spurious reversal of the tension makes
    cables stick and changes the friction history.

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
        Seed of the draws: ``numpy.random.default_rng([seed, S, round(1e6 σ_T)])``.

    Returns
    -------
    ndarray, shape (S,) [m² or rad²]
    """
    floor = np.full(len(obs.time), obs.point_factor * obs.sigma**2)
    if not obs.tension_sigma or draws < 1:
        return floor
    ref = _frame_free(obs, (sims or Simulations()).theta(obs, params))
    rng = np.random.default_rng([seed, len(obs.time), int(1e6 * obs.tension_sigma)])
    acc = np.zeros(len(obs.time))
    # a tendon the tube lacks carries no tension, with or without noise
    has = {side: side in obs.geom.tendons for side in ("left", "right")}
    for _ in range(draws):
        tl = np.maximum(obs.tension_left + rng.normal(0.0, obs.tension_sigma, len(obs.time)), 0.0)
        tr = np.maximum(obs.tension_right + rng.normal(0.0, obs.tension_sigma, len(obs.time)), 0.0)
        th = simulate_angles(obs.time, tl if has["left"] else None, tr if has["right"] else None, params, obs.geom,
                             ramp_time=obs.ramp_time)
        d = _frame_free(obs, th) - ref
        d2 = np.sum(d**2, axis=-1) if obs.metric == "points" else d**2
        d2[~obs.valid] = np.nan
        acc += np.nanmean(d2, axis=1)
    return floor + acc / draws
