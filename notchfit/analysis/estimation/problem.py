"""One least-squares problem assembled from parameter blocks, and the simulations it evaluates.

Unknowns ``x`` (optimiser coordinates), in this order:

1. the *shared* scalar parameters (:class:`~notchfit.analysis.estimation.specs.ParamSpec`:
   log scale for moduli and rates, the study's scale for tube-sized ones);
2. per-tube blocks (:class:`Block` with a tube ``owner``): ``rest_angle`` [rad]
   and ``slot_depth_offset`` [m] per joint;
3. per-experiment blocks (an experiment ``owner``): ``registration``, the
   correction (dtx [m], dty [m], dphi [rad]) of an experiment's registration.

Residuals: for each experiment, the friction simulator (Sec. IV-B, fast
solver) driven by its measured tensions and protocol under the model of ``x``
(:attr:`Problem.model`), measured like the experiment (:attr:`Problem.measure`:
joint angles, or notch points registered in the plane, Sec. IV-A) and whitened
by the experiment's σ (:func:`whitened`), stacked; then the rows of a
Gaussian prior on linear combinations of ``x`` (whitened: ``(a·x − mean)/σ``).

``identify`` builds it with per-tube blocks and the cut-depth prior;
``diagnose`` with the baseline's and candidates' scalars and, for a
calibration warp, per-experiment registrations. The solvers and standard
errors are in :mod:`notchfit.analysis.estimation.solve`.
"""

from __future__ import annotations

import hashlib
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ...physics.friction import FrictionParams, simulate_angles
from ...physics.notches import notch_points, to_plane
from .observations import Observations

__all__ = ["Block", "Problem", "Simulations", "history_key", "measure_registered", "whitened", "with_values"]


class Simulations:
    """Fast-solver joint angles cached by (experiment's inputs, protocol, parameters).

    A finite-difference Jacobian perturbs parameters that need no new
    simulation (registrations, point warps) and revisits the same models; the
    cache makes those evaluations cost only the measurement. The key is the
    simulator's whole input (the experiment's times, tensions and geometry,
    its protocol, the model), so one cache may serve several problems: the
    process-wide one of :meth:`shared` lets the folds of a cross-validation
    reuse the simulations they have in common (the same training experiment
    under the same start model or probe), bit for bit.

    Parameters
    ----------
    sim_kw : dict, optional
        Options of the fast solver (:func:`notchfit.physics.friction.simulate_angles`).
    max_items : int
        The cache is emptied when it holds this many histories.

    Attributes
    ----------
    runs : int
        Histories simulated (cache misses) since creation or :meth:`reset`.
    hits : int
        Histories served from the cache.
    run_seconds : float
        CPU seconds of this process spent in those simulations [s] (the simulator's input checks
        included): with ``runs`` what a benchmark reports as the simulator's share of a fit.
    """

    def __init__(self, sim_kw: dict | None = None, max_items: int = 4096):
        self.sim_kw = dict(sim_kw or {})
        self.max_items = max_items
        self._d: dict = {}
        self.runs, self.hits, self.run_seconds = 0, 0, 0.0

    def reset(self) -> None:
        """Empty the cache and zero its counters."""
        self._d.clear()
        self.runs, self.hits, self.run_seconds = 0, 0, 0.0

    @classmethod
    def shared(cls, sim_kw: dict | None = None, max_items: int = 8192) -> Simulations:
        """The process-wide cache for the solver options ``sim_kw`` (created on first use; a forked
        worker starts with its parent's). ``max_items`` bounds its memory: (S, n) angles per history,
        about 55 MB for 31 samples of the 27-joint seed tube."""
        key = tuple(sorted((sim_kw or {}).items()))
        sims = _SHARED.get(key)
        if sims is None:
            sims = _SHARED[key] = cls(sim_kw, max_items)
        return sims

    def theta(self, obs: Observations, params: FrictionParams) -> np.ndarray:
        """Simulated joint angles [rad] (S, n) of ``obs`` driven by its measured tensions and protocol
        (read-only: a cached array may be handed to other callers)."""
        key = (history_key(obs), obs.ramp_time, params)
        th = self._d.get(key)
        if th is None:
            if len(self._d) >= self.max_items:
                self._d.clear()
            t = time.process_time()
            th = predict(obs, params, self.sim_kw)
            self.runs += 1
            self.run_seconds += time.process_time() - t
            th.setflags(write=False)
            self._d[key] = th
        else:
            self.hits += 1
        return th


#: The process-wide caches of :meth:`Simulations.shared`, by solver options.
_SHARED: dict = {}
#: :func:`history_key` of the experiments seen, by object (weak: dropped with the experiment).
_HISTORY_KEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def history_key(obs: Observations) -> bytes:
    """A digest of what the simulator is driven with besides the model and the protocol: the experiment's
    name, sample times, tensions and geometry (computed once per experiment object)."""
    key = _HISTORY_KEYS.get(obs)
    if key is None:
        h = hashlib.blake2b(digest_size=20)
        arrays = (obs.time, obs.tension_left, obs.tension_right)
        for part in (obs.name.encode(), repr(obs.geom).encode(),
                     *(np.ascontiguousarray(a, dtype=float).tobytes() for a in arrays)):
            h.update(len(part).to_bytes(8, "little"))
            h.update(part)
        key = _HISTORY_KEYS[obs] = h.digest()
    return key


def predict(obs: Observations, params: FrictionParams, sim_kw: dict | None = None) -> np.ndarray:
    """Joint angles (S, n) [rad] of one experiment under ``params`` (not cached)."""
    left, right = obs.tendon_tensions
    return simulate_angles(obs.time, left, right, params, obs.geom, ramp_time=obs.ramp_time, **(sim_kw or {}))


def with_values(params: FrictionParams, values: dict, excess: float, **per_joint) -> FrictionParams:
    """``params`` with scalar ``values`` (``μ_s = μ_d + excess`` when ``μ_d`` is among them) and per-joint
    values of one tube (``rest_angle=``, ``slot_depth_offset=``)."""
    kw = dict(values)
    if "mu_d" in kw:
        kw["mu_s"] = kw["mu_d"] + excess
    for name, v in per_joint.items():
        if v is not None:
            kw[name] = tuple(float(a) for a in v)
    return params.replace(**kw)


def measure_registered(obs: Observations, theta: np.ndarray, registration=None, transform=None) -> np.ndarray:
    """What ``obs`` would measure for joint angles ``theta`` (S, n): the angles, or the notch points in
    the plane frame [m] under its registration (``transform``, default its own; plus a correction
    ``(dtx, dty, dphi)``)."""
    if obs.metric == "angles":
        return theta
    T = transform or obs.transform
    tx, ty, phi = T.tx, T.ty, T.phi
    if registration is not None:
        tx, ty, phi = tx + registration[0], ty + registration[1], phi + registration[2]
    return to_plane(notch_points(theta, obs.geom), tx, ty, phi, T.mirror)


def whitened(obs: Observations, predicted: np.ndarray) -> np.ndarray:
    """Residuals ``(predicted − measured)/σ`` of one experiment, flattened; zero where not measured."""
    r = (np.asarray(predicted, dtype=float) - obs.measured) / obs.sigma
    r[~obs.valid] = 0.0
    return r.ravel()


@dataclass(frozen=True)
class Block:
    """Unknowns of one tube or one experiment: ``size`` values of ``name`` owned by ``owner``.

    ``kind`` is ``"tube"`` or ``"experiment"``; ``step`` the finite-difference step [SI].
    """

    name: str
    owner: str
    size: int
    kind: str = "tube"
    step: float = 2e-4


def _default_measure(obs, theta, values, blocks):
    return measure_registered(obs, theta, blocks.get("registration"))


@dataclass(frozen=True, eq=False)
class Problem:
    """One least-squares problem (module docstring).

    Attributes
    ----------
    obs : tuple of Observations
    specs : tuple of ParamSpec
        The shared scalar parameters.
    scales : tuple of float
        The study scale of each spec (1 for most).
    blocks : tuple of Block
        Per-tube, then per-experiment unknowns, in the order of ``x``.
    x0, lo, hi : ndarray
        Start and bounds in optimiser coordinates.
    prior : ndarray (r, p)
        Each row adds the residual ``prior[r] @ x - prior_offset[r]`` (a Gaussian prior, whitened).
    model : callable
        ``model(obs, values, tube_blocks) -> FrictionParams``: the simulator's model of one experiment
        from the shared values (SI, by name) and its tube's blocks (``{name: (n,) values}``).
    measure : callable
        ``measure(obs, theta, values, experiment_blocks) -> predicted``: what the experiment would measure.
    sims : Simulations
    prior_offset : ndarray (r,) or None
        The prior rows' means (None: zero-mean priors).
    """

    obs: tuple
    specs: tuple
    scales: tuple
    blocks: tuple
    x0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    prior: np.ndarray
    model: Callable
    measure: Callable = _default_measure
    sims: Simulations = field(default_factory=Simulations)
    prior_offset: np.ndarray | None = None

    def prior_residuals(self, x) -> np.ndarray:
        """The whitened residuals of the priors, ``prior @ x - prior_offset`` (r,)."""
        r = self.prior @ np.asarray(x, dtype=float)
        return r if self.prior_offset is None else r - self.prior_offset

    @property
    def k(self) -> int:
        """Number of shared scalars."""
        return len(self.specs)

    def values(self, x) -> dict:
        """Shared parameter values by name (SI)."""
        return {s.name: s.from_x(float(v), c) for s, c, v in zip(self.specs, self.scales, x[:self.k])}

    def block_values(self, x, kind: str | None = None) -> dict:
        """Owner -> {block name: values} of the blocks (of one ``kind``)."""
        out, i = {}, self.k
        for b in self.blocks:
            if kind is None or b.kind == kind:
                out.setdefault(b.owner, {})[b.name] = np.asarray(x[i:i + b.size], dtype=float)
            i += b.size
        return out

    def tube_values(self, x) -> dict:
        """Tube -> {block name: (n,) values} of its unknowns."""
        return self.block_values(x, "tube")

    def params(self, x) -> dict:
        """Tube -> the simulator's model of ``x`` (the first experiment of each tube decides)."""
        vals, per = self.values(x), self.tube_values(x)
        out = {}
        for o in self.obs:
            if o.tube not in out:
                out[o.tube] = self.model(o, vals, per.get(o.tube, {}))
        return out

    def predicted(self, i: int, x) -> tuple[np.ndarray, np.ndarray]:
        """Experiment ``i``'s predicted measurement and joint angles (S, n) [rad] under ``x``."""
        o = self.obs[i]
        vals = self.values(x)
        theta = self.sims.theta(o, self.model(o, vals, self.tube_values(x).get(o.tube, {})))
        return self.measure(o, theta, vals, self.block_values(x, "experiment").get(o.name, {})), theta

    def residuals(self, x) -> np.ndarray:
        """Whitened residuals of every experiment, stacked (zeros where not measured), then the prior's."""
        x = np.asarray(x, dtype=float)
        vals = self.values(x)
        tubes, exps = self.tube_values(x), self.block_values(x, "experiment")
        models = {}
        out = []
        for o in self.obs:
            if o.tube not in models:
                models[o.tube] = self.model(o, vals, tubes.get(o.tube, {}))
            theta = self.sims.theta(o, models[o.tube])
            out.append(whitened(o, self.measure(o, theta, vals, exps.get(o.name, {}))))
        return np.concatenate(out + [self.prior_residuals(x)])

    def clusters(self) -> np.ndarray:
        """The sample each residual belongs to (cluster ids for the standard errors; -1: a prior's)."""
        out, base = [], 0
        for o in self.obs:
            S = o.time.size
            out.append(base + np.repeat(np.arange(S), o.measured.shape[1] * o.values_per_item))
            base += S
        out.append(np.full(self.prior.shape[0], -1))
        return np.concatenate(out)

    def measured(self) -> np.ndarray:
        """Which residuals are measured values (bool, the layout of :meth:`residuals`; False for the prior's)."""
        return np.concatenate([np.repeat(o.valid[..., None], o.values_per_item, axis=-1).ravel() for o in self.obs]
                              + [np.zeros(self.prior.shape[0], bool)])

    def steps(self, x, rel: float, block_steps: dict | None = None) -> np.ndarray:
        """Absolute finite-difference steps: ``rel`` of a shared parameter's value (log coordinates: ``rel``
        itself; others ``rel`` of the larger of the value and a tenth of the bound range); a block's own
        step, or ``block_steps[name]``."""
        h = np.empty(np.size(x))
        for i, s in enumerate(self.specs):
            h[i] = rel if s.log else rel * max(abs(float(x[i])), 0.1 * (self.hi[i] - self.lo[i]))
        i = self.k
        for b in self.blocks:
            h[i:i + b.size] = (block_steps or {}).get(b.name, b.step)
            i += b.size
        return h
