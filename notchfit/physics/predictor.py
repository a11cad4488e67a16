"""A real-time shape estimate from measured tension, one sample at a time (Sec. IV-B).

The seed paper's motivation for its friction model is navigation: the shape of
the manipulator estimated from the measured cable tension as the procedure
goes on. :func:`notchfit.physics.friction.simulate` takes a whole history; a
:class:`Predictor` holds the simulator's state — joint angles, the tension
profile of each cable, every link's stick/slip state, the proximal band — and
advances it by one interval per new sample with the fast solver's kernel
(:func:`notchfit.physics._friction_kernels.fast_intervals`), the same state machine in
the same order. Fed the samples of a history one by one it returns what
``simulate(..., method="fast")`` returns for the whole history (bit for bit;
tested to 1e-9 rad), at a cost per sample that does not grow with the
history.

Each notch angle's prediction interval (the identified parameters' covariance and the
tube-to-tube scatter of an identified model) comes from one predictor per sigma point:
:meth:`notchfit.analysis.estimation.bands.BandPredictor.for_tube`.

Input protocol (as :func:`notchfit.physics.friction.simulate`): the model starts at
rest (θ = θ0, no tension, every link sticking) ``settle_time`` before the
first sample; between samples the tensions move linearly to the new sample's
over ``ramp_time`` and are then held until it is taken.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from . import _friction_kernels as _k
from .friction import FrictionParams, default_params
from .friction_params import _kernel_inputs, check_fast_laws
from .geometry import Geometry, default_geometry
from .notches import _points_one, point_projector

__all__ = ["Prediction", "Predictor"]


@dataclass(frozen=True)
class Prediction:
    """The estimate after one sample.

    Attributes
    ----------
    time : float [s]
    theta : ndarray (n,) [rad]
        Joint angles (rest angles included).
    points : ndarray (m, 2) [m]
        Manipulator-frame notch points of ``theta`` (:func:`notchfit.physics.notches.notch_points`);
        None when the predictor was made with ``points=False``.
    tension_left, tension_right : ndarray (n,) [N]
        Cable tension where each cable crosses joints 1..n.

    The arrays are fresh copies: the predictor keeps no reference to them.
    """

    time: float
    theta: np.ndarray
    points: np.ndarray | None
    tension_left: np.ndarray
    tension_right: np.ndarray


class Predictor:
    """Joint angles and notch points from one tension sample at a time (module docstring).

    Parameters
    ----------
    params : FrictionParams, optional
        Default :func:`notchfit.physics.friction.default_params` of the geometry.
    geom : Geometry, optional
        Default: the seed tube.
    ramp_time : float
        Seconds over which the tension moves to each new sample's [s] (0: a step).
    settle_time : float
        Time at rest before the first sample [s] (``simulate`` defaults to the
        median interval of its history, which a real-time stream does not know:
        give the same value to both to compare them).
    tension_sigma : float, optional
        ``σ_T`` [N]: readings down to ``-3 σ_T`` are taken as zero (load-cell
        offset, :func:`notchfit.physics.friction.clip_load_cell`); None: every reading must be >= 0.
    points : bool
        Also project the notch points at every sample (``Prediction.points``).
    h_min, h_max, growth, dtheta_max, order, land_sticks, max_events, max_micro, settle_tol, settle_maxiter :
        The fast solver's options, as :func:`notchfit.physics.friction.simulate`.
    """

    def __init__(self, params: FrictionParams | None = None, geom: Geometry | None = None, *,
                 ramp_time: float = 0.0, settle_time: float = 5.0, tension_sigma: float | None = None,
                 points: bool = True, h_min: float = 3e-3, h_max: float = 0.05, growth: float = 1.5,
                 dtheta_max: float = 5e-4, order: int | None = None, land_sticks: bool = True,
                 max_events: int | None = None, max_micro: int | None = None, settle_tol: float = 1e-13,
                 settle_maxiter: int = 200):
        self.geom = default_geometry() if geom is None else geom
        self.params = default_params(self.geom) if params is None else params
        if not isinstance(self.params, FrictionParams):
            raise ValueError(f"params must be a FrictionParams, got {type(self.params).__name__}")
        for name, v in (("settle_time", settle_time), ("h_min", h_min), ("h_max", h_max)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0 s, got {v}")
        if not (math.isfinite(ramp_time) and ramp_time >= 0):
            raise ValueError(f"ramp_time must be >= 0 s, got {ramp_time}")
        if not (math.isfinite(growth) and growth >= 1):
            raise ValueError(f"growth must be >= 1, got {growth}")
        if tension_sigma is not None and not (math.isfinite(tension_sigma) and tension_sigma >= 0):
            raise ValueError(f"tension_sigma must be >= 0 N, got {tension_sigma}")
        p = self.params
        check_fast_laws(p)
        if order is None:
            order = 2 if (p.tip_force_x != 0.0 or p.tip_force_z != 0.0) else 1
        if order not in (1, 2):
            raise ValueError(f"order must be 1 or 2, got {order}")
        n = self.geom.n_joints
        self._J, self._par = _kernel_inputs(p, self.geom)
        self._opts = np.array([ramp_time, h_min, h_max, growth,
                               max(64, 4 * n) if max_events is None else int(max_events),
                               max(1000, 40 * n) if max_micro is None else int(max_micro),
                               settle_tol, settle_maxiter, float(bool(land_sticks)), dtheta_max, order], dtype=float)
        self.settle_time = float(settle_time)
        self.tension_sigma = tension_sigma
        self._tables = point_projector(self.geom).tables
        self._points = bool(points)
        self._has = (("left" in self.geom.tendons), ("right" in self.geom.tendons))
        self.reset()

    def reset(self) -> None:
        """Back to the initial rest state (no sample taken yet)."""
        n = self.geom.n_joints
        m = max(n - 1, 0)
        # float state: θ, T_L, T_R (n each), the band's base tensions (2); int state: sL, sR
        self._state = np.zeros(4 * n + 2)     # θ, T_L, T_R, the stops' torques, the band's base tensions
        self._state[:n] = self._J[_k.J_TH0]
        self._links = np.zeros(2 * m, np.int8)
        # inputs: time, T_L, T_R of the new sample; time, T_L, T_R of the previous; first
        self._inp = np.zeros(7)
        self._last = None
        self.n_samples = 0

    @property
    def theta(self) -> np.ndarray:
        """Current joint angles (n,) [rad] (a copy)."""
        return self._state[:self.geom.n_joints].copy()

    def _reading(self, value, side: int, name: str) -> float:
        """One tension reading, checked and clipped like ``simulate``'s."""
        if not self._has[side]:
            if value not in (None, 0, 0.0):
                raise ValueError(f"the geometry has no {name} tendon: tension_{name} must be None or 0")
            return 0.0
        if value is None:
            raise ValueError(f"the geometry has a {name} tendon: tension_{name} is required")
        v = float(value)
        if not math.isfinite(v):
            raise ValueError(f"tension_{name} must be finite, got {v}")
        if v < 0.0:
            sig = self.tension_sigma
            if sig is None or v < -3.0 * sig:
                raise ValueError(f"tension_{name} must be >= 0 N (cables only pull; readings down to -3 sigma_T "
                                 f"count as zero), got {v}")
            v = 0.0
        return v

    def step(self, time: float, tension_left: float | None = None,
             tension_right: float | None = None) -> Prediction:
        """Advance to a new sample and return the estimate there.

        Parameters
        ----------
        time : float [s]
            Later than the previous sample's.
        tension_left, tension_right : float or None [N]
            Measured tensions; None (or 0) for a tendon the geometry lacks.

        Returns
        -------
        Prediction
        """
        t = float(time)
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t}")
        inp = self._inp
        inp[1] = self._reading(tension_left, 0, "left")
        inp[2] = self._reading(tension_right, 1, "right")
        if self._last is None:
            inp[3], inp[4], inp[5], inp[6] = t - self.settle_time, 0.0, 0.0, 1.0
        else:
            if not t > self._last:
                raise ValueError(f"time must increase: got {t} s after {self._last} s")
            inp[3], inp[4], inp[5], inp[6] = self._last, self._prev[0], self._prev[1], 0.0
        inp[0] = t
        theta, tl, tr, pts = _step(inp, self._state, self._links, self._par, self._J, self._opts, self._tables,
                                   self._points)
        self._last = t
        self._prev = (inp[1], inp[2])
        self.n_samples += 1
        return Prediction(t, theta, pts if self._points else None, tl, tr)


@njit(cache=True)
def _step(inp, state, links, par, J, opts, tables, with_points):  # pragma: no cover
    """One interval of :func:`notchfit.physics._friction_kernels.fast_intervals` and, ``with_points``, the
    points (those of :func:`notchfit.physics.notches.points_kernel`, from the projector's ``tables``,
    :attr:`notchfit.physics.notches.PointProjector.tables`), compiled in one call."""
    n = J.shape[1]
    m = links.shape[0] // 2
    th, TL, TR, hS, band = state[:n], state[n:2 * n], state[2 * n:3 * n], state[3 * n:4 * n], state[4 * n:]
    out = _k.fast_intervals(inp[0:1], inp[1:2], inp[2:3], inp[3], inp[4], inp[5], inp[6] != 0.0, th, TL, TR,
                            links[:m], links[m:], band, hS, par, J, opts[0], opts[1], opts[2], opts[3], int(opts[4]),
                            int(opts[5]), opts[6], int(opts[7]), opts[8] != 0.0, opts[9], int(opts[10]))
    pts = np.empty((tables[0].shape[0], 2))
    if with_points:
        _points_one(th, tables, pts)
    return th.copy(), out[1][0], out[2][0], pts
