"""Synthetic stocks: several wrists cut from one tube stock, measured as notch angles, in memory.

A lab identifies a stock's material on the wrists it has measured and predicts a new wrist from its
drawing. :func:`synthetic_stock` makes such a study with its ground truth: three asymmetric-notch
wrists of different drawings (5-notch uniform, 4-notch tip-first and pre-curved, 5-notch with
graded depths), each *cut* off its drawing by a per-notch error drawn within the cutting tolerance,
loading-only trials from rest to a drawn peak tension, angles with Gaussian noise and load cells
with their own. The truth's model may carry a hidden effect (any :class:`FrictionParams` field,
e.g. a tension–compression asymmetry ``strain_ratio``). The experiments are
:class:`notchfit.io.Experiment` objects that no file backs (``path`` names the stock), ready for
:func:`notchfit.analysis.identify.identify`; the truth is returned beside them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import Experiment, datasets_dir, load_geometry
from ..physics.friction import default_params, simulate_angles
from ..physics.geometry import Geometry, geometry_from_dict

__all__ = ["MATERIAL_TRUTH", "StockTruth", "stock_geometries", "stock_recipe", "synthetic_stock"]

#: The stock's material and friction (superelastic nitinol, a tendon in the lumen).
MATERIAL_TRUTH = {"E_lin": 45e9, "E_se": 3e9, "strain_lower": 0.014, "mu_d": 0.12, "mu_s": 0.13,
                  "damping_time": 1e-3}

#: A third drawing: 5 notches, depths graded from base to tip (the base's shallow cuts leave a wall
#: whose cut face lies up to 1.27 times farther from the neutral axis than its back), pre-curved.
_WRIST_C = {"name": "wrist_c", "n_joints": 5, "outer_radius_mm": 0.81, "inner_radius_mm": 0.70,
            "slot_width_mm": [0.6, 0.6, 0.7, 0.7, 0.7], "slot_depth_mm": [1.26, 1.30, 1.34, 1.38, 1.42],
            "p_mm": [1.4, 1.5, 1.5, 1.5], "rest_angle_rad": [0.03, 0.05, 0.04, 0.06, 0.03],
            "slot_sides": [1, 1, 1, 1, 1], "backbone": "section", "tendons": ["right"], "tendon_path": "lumen",
            "cable_radius_mm": 0.05, "base_edge_z_mm": -1.0}


def stock_geometries() -> tuple[Geometry, ...]:
    """The three drawings of :func:`synthetic_stock`: the shipped ``wrist_asymmetric`` and
    ``wrist_tip_first``, and a graded 5-notch wrist."""
    shipped = [load_geometry(datasets_dir() / "geometry" / f"{n}.toml") for n in ("wrist_asymmetric", "wrist_tip_first")]
    return (*shipped, geometry_from_dict(_WRIST_C, "wrist_c"))


@dataclass(frozen=True)
class StockTruth:
    """The ground truth of a synthetic stock.

    Attributes
    ----------
    params : dict
        Tube name -> the :class:`FrictionParams` that made its trials (the cut-depth errors as
        ``slot_depth_offset``, the hidden effect included).
    depth_errors : dict
        Tube name -> (n,) how far each notch was cut from its drawing [m].
    effect : dict
        The hidden effect's fields (empty: none).
    angle_sigma, tension_sigma : float
        The noise [rad], [N].
    """

    params: dict
    depth_errors: dict
    effect: dict
    angle_sigma: float
    tension_sigma: float


@dataclass(frozen=True)
class _Loading:
    """A loading-only trial's protocol: rest, then ``n_up`` steps to ``peak`` [N], a sample every ``dt`` [s]."""

    peak: float
    n_up: int
    dt: float


@dataclass(frozen=True)
class _Noise:
    """The measurement noise: of the angles [rad] and of the load cells [N]."""

    angle_sigma: float
    tension_sigma: float


def _trial(name, geom, params, loading: _Loading, noise: _Noise, rng, path) -> Experiment:
    """One loading-only trial of the wrist ``geom`` cut as ``params``: measured angles and tensions."""
    T = np.r_[0.0, np.linspace(loading.peak / loading.n_up, loading.peak, loading.n_up)]
    time = loading.dt * np.arange(1, T.size + 1)
    theta = simulate_angles(time, None, T, params, geom)
    angles = theta + rng.normal(0.0, noise.angle_sigma, theta.shape)
    reading = np.round(T + rng.normal(0.0, noise.tension_sigma, T.shape), 4)
    reading = np.maximum(reading, -3.0 * noise.tension_sigma)
    samples = pd.DataFrame({"sample": np.arange(1, T.size + 1), "time_s": time, "tension_right_N": reading})
    return Experiment(name=name, path=Path(path) / name, description="synthetic stock trial", geometry=geom,
                      mirror=False, calibration_path=None, point_sigma=None, tension_sigma=noise.tension_sigma,
                      samples=samples, points=None, image_paths=None, ramp_time=0.0, angles=angles,
                      angle_sigma=noise.angle_sigma)


def synthetic_stock(seed: int = 0, *, trials=(5, 4, 4), effect: dict | None = None,
                    depth_tolerance: float = 15e-6, depth_sd: float = 10e-6, peaks=((2.2, 3.0), (1.4, 1.9), (2.6, 3.4)),
                    n_up: int = 10, dt: float = 5.0, angle_sigma: float = np.radians(0.5),
                    tension_sigma: float = 0.005, geometries=None) -> tuple[list, StockTruth]:
    """Trials of three wrists of one stock, with the truth (module docstring).

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``: every draw (cut errors, peaks, noise) follows from it.
    trials : sequence of int
        Trials per tube (default 5, 4, 4: 13 trials).
    effect : dict, optional
        Hidden effect: :class:`FrictionParams` fields of the truth (e.g. ``{"strain_ratio": 1.4}``).
    depth_tolerance, depth_sd : float [m]
        Each notch is cut ``N(0, depth_sd)`` off its drawing, clipped to ``±depth_tolerance``.
    peaks : sequence of (float, float) [N]
        Per tube, the range of the trials' peak tensions (drawn uniformly).
    n_up, dt : int, float [s]
        Steps from rest to the peak, and the time between samples.
    angle_sigma, tension_sigma : float [rad], [N]
        Measurement noise.
    geometries : sequence of Geometry, optional
        The drawings (default :func:`stock_geometries`).

    Returns
    -------
    experiments : list of Experiment
        Tube by tube, named ``<tube letter><trial>`` (A1, ..., C4).
    truth : StockTruth
    """
    rng = np.random.default_rng(seed)
    geoms = stock_geometries() if geometries is None else tuple(geometries)
    effect = dict(effect or {})
    exps, params, errors = [], {}, {}
    noise = _Noise(angle_sigma, tension_sigma)
    for k, (geom, n_trials, (lo, hi)) in enumerate(zip(geoms, trials, peaks)):
        err = np.clip(rng.normal(0.0, depth_sd, geom.n_joints), -depth_tolerance, depth_tolerance)
        p = default_params(geom).replace(**MATERIAL_TRUTH, **effect, slot_depth_offset=tuple(err))
        params[geom.name], errors[geom.name] = p, err
        letter = "ABCDEFGH"[k]
        for i in range(n_trials):
            loading = _Loading(float(rng.uniform(lo, hi)), n_up, dt)
            exps.append(_trial(f"{letter}{i + 1}", geom, p, loading, noise, rng, f"<synthetic stock {seed}>"))
    return exps, StockTruth(params, errors, effect, angle_sigma, tension_sigma)


def stock_recipe(name: str, geometry: str, experiments, *, seed: int = 0, n_up: int = 8,
                 **fixed) -> dict:
    """A synth recipe (:func:`notchfit.studies.recipes.recipe_from_dict`) of loading-only trials of one wrist
    of the stock's material (:data:`MATERIAL_TRUTH`), measured as angles (0.5° noise, 5 mN load cells).

    Parameters
    ----------
    geometry : str
        A shipped geometry's name or a geometry file.
    experiments : sequence of dict
        The recipe's experiments (``name``, ``peak_N``).
    seed, n_up :
        The recipe's seed and the steps from rest to the peak.
    **fixed
        Further truth fields (e.g. ``rest_angle``).
    """
    return {"name": name, "seed": seed, "geometry": geometry, "observe": "angles", "base": {},
            "fixed": {"spring_law": "material", "friction_law": "capstan", **MATERIAL_TRUTH, **fixed},
            "noise": {"point_mm": 0.0, "tension_N": 0.005, "displacement_step_mm": 0.0, "angle_deg": 0.5},
            "plane": {"tx_mm": 0.0, "ty_mm": 0.0, "phi_deg": 0.0},
            "protocol": {"n_up": n_up, "n_down": 0, "dt_s": 5.0, "pull": "right", "counter_N": 0.0},
            "experiments": list(experiments)}
