"""The held-out fits of ``identify`` (issue 27): cheaper, the same answers bit for bit.

A held-out fit starts from the fit on every experiment, where that fit has already computed the
forward-difference Jacobian of its residuals (for its standard errors). The held-out fit's first
least-squares step takes its Jacobian from it — the rows of the experiments it keeps, the columns of
its unknowns, its own prior rows — instead of simulating every experiment once per unknown again; and
a held-out tube's fit, from the best of its probe grid and from that warm start, runs its two
least-squares runs apart (the grid's beside the fit on every experiment) and keeps the lower cost, as
one call from both starts does. Each shortcut is checked against the straightforward computation.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from notchfit.analysis.estimation import observe_study
from notchfit.analysis.estimation.solve import forward_jacobian
from notchfit.analysis.identify import default_free, make_problem, solve, specs_for
from notchfit.analysis.identify.problem import steps
from notchfit.studies.stock import synthetic_stock

import notchfit.analysis.identify.study  # noqa: F401  (the module, not the function of the same package)

study = sys.modules["notchfit.analysis.identify.study"]


@pytest.fixture(scope="module")
def fits():
    """A small stock (two wrists, two and three trials): its fits' tasks and outputs, keyed (key, part)."""
    exps, _ = synthetic_stock(3, trials=(3, 2, 0), n_up=8)
    obs = observe_study(exps, prefer="angles")
    base = study._base_models(obs, None)
    free = default_free(list(base.values()), [o.geom for o in obs])
    first = next(iter(base.values()))
    options = dict(n_starts=2, loss="linear", f_scale=3.0, max_nfev=100, ftol=1e-6, xtol=1e-6, diff_rel=2e-3,
                   rest_step=2e-4, sim_kw=dict(study.FIT_SOLVER))
    full = study._Task.full(obs, base, free, None, max(first.mu_s - first.mu_d, 0.0), options)
    tasks = study._tasks(full, heldout=True, by_tube=True, warm_start=True)
    full = study._fit(tasks[0])
    warm = study._warm_start(full, options)
    tasks = [tasks[0]] + [replace(t, warm=warm) if t.part == "warm" else t for t in tasks[1:]]
    return {(t.key, t.part): t for t in tasks}, full, options


def _problem(task, options):
    """The problem a task's fit solves, started where it starts."""
    train = [task.obs[i] for i in task.train]
    pb = make_problem(train, task.base, specs_for(task.free, [task.base[o.tube] for o in train]),
                      rest=True, depth=True, excess=task.excess, sim_kw=options["sim_kw"])
    return replace(pb, x0=study._warm_x(pb, task.warm)) if task.warm is not None else pb


@pytest.mark.parametrize("key", ["without A1", "without tube wrist_asymmetric"])
def test_seeded_jacobian_is_the_held_out_fits_own_bit_for_bit(fits, key):
    tasks, _, options = fits
    task = tasks[key, "warm"]
    pb = _problem(task, options)
    h = steps(pb, pb.x0, options["diff_rel"], options["rest_step"])
    seeded = task.warm.for_problem(pb, h)
    assert seeded is not None and seeded.shape == (pb.residuals(pb.x0).size, pb.x0.size)
    np.testing.assert_array_equal(seeded, forward_jacobian(pb, pb.x0, h))
    # another start or other steps: not the fit's Jacobian, none is given
    assert task.warm.for_problem(replace(pb, x0=pb.x0 + 1e-6 * h), h) is None
    assert task.warm.for_problem(pb, 2.0 * h) is None


@pytest.mark.parametrize("key", ["without B2", "without tube wrist_tip_first"])
def test_warm_fit_with_the_seeded_jacobian_lands_where_it_did_without(fits, key):
    tasks, _, _ = fits
    task = tasks[key, "warm"]
    seeded, plain = study._fit(task), study._fit(replace(task, seed_jacobian=False))
    np.testing.assert_array_equal(seeded.sol.x, plain.sol.x)
    for name, err in plain.preds.items():
        np.testing.assert_array_equal(seeded.preds[name], err)


def test_tube_fit_in_two_parts_is_the_one_call_from_both_starts(fits):
    tasks, _, options = fits
    key = "without tube wrist_asymmetric"
    grid, warm = study._fit(tasks[key, "grid"]), study._fit(replace(tasks[key, "warm"], seed_jacobian=False))
    merged = study._merge(grid, warm)
    pb = _problem(tasks[key, "grid"], options)
    x_warm = study._warm_x(pb, tasks[key, "warm"].warm)
    one = solve(pb, n_starts=1, starts=(x_warm,), errors=False, diff_rel=options["diff_rel"],
                rest_step=options["rest_step"])
    np.testing.assert_array_equal(merged.sol.x, one.x)
    assert merged.sol.loss_cost == pytest.approx(one.cost, rel=1e-12)
