"""The estimation core (notchfit.analysis.estimation): one noise rule, the block layout of one problem, its solution
and standard errors against closed forms, the leave-one-out splits."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from notchfit.analysis.estimation import Block, Observations, ParamSpec, Problem, folds, grid_starts, solve, tension_sigma, tube_folds, whitened
from notchfit.analysis.estimation.problem import Simulations
from notchfit.physics.friction import LOAD_CELL_SIGMA, FrictionParams, simulate_angles
from notchfit.physics.geometry import default_geometry


def _obs(name, tube, measured, sigma=0.1):
    """Angle observations of the seed tube (S samples), NaN = not measured."""
    g = default_geometry()
    S = measured.shape[0]
    return Observations(name=name, geom=g, time=np.arange(1.0, S + 1), tension_left=np.zeros(S),
                        tension_right=np.ones(S), measured=measured, valid=np.isfinite(measured), transform=None,
                        sigma=sigma, theta_free=measured, free_residuals=None, a=np.zeros(S), b=np.zeros(S),
                        pulled=1, regime=np.array(["I"] * S), counter_tension=0.0, metric="angles", tube=tube)


class _LinearSims:
    """Stands in for the simulator: θ_sj = p0 + p1 (j+1) + offset_j, linear in the unknowns."""

    def theta(self, obs, params):
        p0, p1, off = params
        n = obs.geom.n_joints
        return np.tile(p0 + p1 * np.arange(1, n + 1) + np.asarray(off), (obs.time.size, 1))


def _model(o, values, tube):
    return (values["p0"], values["p1"], tuple(tube.get("offset", np.zeros(o.geom.n_joints))))


def test_one_load_cell_rule():
    """experiment.toml's tension_N when given, else the data format's 0.05 N (never 0: a silent file is
    not a noise-free load cell)."""
    assert tension_sigma(SimpleNamespace(tension_sigma=None)) == LOAD_CELL_SIGMA == 0.05
    assert tension_sigma(SimpleNamespace(tension_sigma=0.11)) == 0.11


def test_whitened_residuals_are_zero_where_not_measured():
    m = np.array([[0.1, np.nan, 0.3, 0.0, 0.0]] * 2)
    r = whitened(_obs("a", "t", m, sigma=0.1), np.full((2, 5), 0.2))
    np.testing.assert_allclose(r.reshape(2, 5), [[1.0, 0.0, -1.0, 2.0, 2.0]] * 2)


def _problem(rng, noise=0.01):
    """Two tubes sharing p0, p1; tube B has free per-joint offsets with a Gaussian prior (σ = 0.05)."""
    truth = {"p0": 0.02, "p1": 0.01}
    n = default_geometry().n_joints
    off = rng.normal(0.0, 0.02, n)
    base = truth["p0"] + truth["p1"] * np.arange(1, n + 1)
    obs = [_obs("A1", "A", np.tile(base, (6, 1)) + rng.normal(0, noise, (6, n)), noise),
           _obs("B1", "B", np.tile(base + off, (6, 1)) + rng.normal(0, noise, (6, n)), noise)]
    specs = (ParamSpec("p0", -1.0, 1.0, 0.0, probes=(-0.1, 0.1)), ParamSpec("p1", -1.0, 1.0, 0.0))
    blocks = (Block("offset", "B", n, step=1e-4),)
    x0 = np.zeros(2 + n)
    lo, hi = np.r_[-1.0, -1.0, np.full(n, -0.5)], np.r_[1.0, 1.0, np.full(n, 0.5)]
    prior = np.c_[np.zeros((n, 2)), np.eye(n) / 0.05]
    pb = Problem(tuple(obs), specs, (1.0, 1.0), blocks, x0, lo, hi, prior, model=_model, sims=_LinearSims())
    return pb, truth, off


def test_problem_layout_solution_and_standard_errors(rng):
    """The unknowns in block order; the fit of a linear problem equals its closed-form (prior-weighted)
    least-squares solution, and the standard errors are at least the Gauss-Newton ones."""
    pb, truth, off = _problem(rng)
    n = off.size
    x = np.r_[0.5, 0.25, np.arange(n) * 0.1]
    assert pb.values(x) == {"p0": 0.5, "p1": 0.25}
    np.testing.assert_array_equal(pb.tube_values(x)["B"]["offset"], np.arange(n) * 0.1)
    assert pb.residuals(x).size == 2 * 6 * n + n and pb.measured().sum() == 2 * 6 * n
    assert set(pb.clusters()[pb.measured()]) == set(range(12))         # one cluster per sample
    starts, nprobe = grid_starts(pb, 1)
    sol = solve(pb, starts, nfev=nprobe, ftol=1e-12, xtol=1e-12)
    # closed form: the residuals are linear in x, r = A x - y
    r0 = pb.residuals(np.zeros_like(x))
    A = np.column_stack([pb.residuals(np.eye(x.size)[i]) - r0 for i in range(x.size)])
    x_ls = np.linalg.lstsq(A, -r0, rcond=None)[0]
    np.testing.assert_allclose(sol.x, x_ls, atol=1e-8)
    assert abs(sol.x[0] - truth["p0"]) < 5 * sol.se[0] and abs(sol.x[1] - truth["p1"]) < 5 * sol.se[1]
    keep = pb.measured()
    r = A @ sol.x + r0
    gn = np.sqrt(np.diag(np.linalg.inv(A.T @ A)) * (r[keep] @ r[keep]) / (keep.sum() - x.size))
    assert np.all(sol.se >= gn * (1 - 1e-6))


def test_leave_one_out_splits():
    assert [f.tolist() for f in folds(3)] == [[0], [1], [2]]
    assert [f.tolist() for f in folds(5, max_folds=2)] == [[0, 2, 4], [1, 3]]
    m = np.zeros((2, 5))
    obs = [_obs("a", "A", m), _obs("b", "B", m), _obs("c", "A", m)]
    assert {t: f.tolist() for t, f in tube_folds(obs).items()} == {"A": [0, 2], "B": [1]}
    assert tube_folds(obs[:1]) == {}


@pytest.fixture
def rng():
    return np.random.default_rng(24)


def test_simulations_count_their_work():
    """The cache counts the histories it simulated and served, and its result equals the simulator's."""
    o = _obs("a", "t", np.zeros((3, 27)))
    sims, p = Simulations(), FrictionParams()
    th = sims.theta(o, p)
    assert np.array_equal(th, simulate_angles(o.time, o.tension_left, o.tension_right, p, o.geom))
    assert sims.theta(o, p) is th and sims.theta(o, p.replace(mu_d=0.3)) is not th
    assert (sims.runs, sims.hits) == (2, 1) and sims.run_seconds > 0.0
    sims.reset()
    assert (sims.runs, sims.hits, sims.run_seconds) == (0, 0, 0.0)
    sims.theta(o, p)
    assert sims.runs == 1
