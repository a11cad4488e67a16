"""The candidates' screen and fits that did not leave their start (notchfit.analysis.diagnosis.study._singles;
docs/diagnosis.md, "Two causes at once"; docs/history.md, 2026-11-28).

The screen leaves a candidate out when its in-sample error on all experiments is not below the best
significant held-out error: a model's held-out error is not below its in-sample one *at its optimum*. On the
reduced Bouc-Wen hysteresis study of seed 2 the hysteresis candidate's screen fit took no step from its best
probe (every trial step raised the non-smooth cost until the trust region fell below ``xtol``), 0.80 mm
in-sample against an optimum near 0.15 mm, and proximal friction was named alone. A fit that did not leave
its start (``Solution.moved``) is no such bound: that candidate is cross-validated.
"""
from types import SimpleNamespace

import numpy as np

from notchfit.analysis.diagnosis import study
from notchfit.analysis.estimation.solve import solve


class _Plateaus:
    """One parameter, residuals ``y(x) - 2`` with ``y`` the smooth identity or a staircase of 0.01-wide
    steps (a cost flat between its kinks: a 2-point finite difference of step 2e-3·x sees no slope)."""

    lo, hi = np.array([0.0]), np.array([5.0])

    def __init__(self, stairs: bool):
        self.stairs = stairs

    def residuals(self, x):
        y = np.floor(x[0] * 100.0) / 100.0 if self.stairs else x[0]
        return np.array([y - 2.0, 0.5 * (y - 2.0)])

    def steps(self, x, rel, block_steps=None):
        return rel * np.maximum(np.abs(x), 1.0)

    def measured(self):
        return np.ones(2, dtype=bool)


def test_a_run_that_took_no_step_from_its_start_is_not_moved():
    x0 = [np.array([0.505])]
    smooth = solve(_Plateaus(False), x0, jac="2-point", errors=False)
    flat = solve(_Plateaus(True), x0, jac="2-point", errors=False)
    assert smooth.moved and abs(smooth.x[0] - 2.0) < 1e-3
    assert not flat.moved and flat.x[0] == 0.505 and flat.cost > smooth.cost + 1.0   # far from its optimum


def _singles(monkeypatch, moved_b: bool):
    """``_singles`` on candidates a, b, c: in-sample (on all experiments) 0.50, 0.64, 1.00; held-out a 0.7,
    b 0.2 (both significant), c 0.9. b's screen fit left its start or not. Returns the cross-validation
    calls, the candidates left out and the reasons recorded."""
    ins = {"a": 0.25, "b": 0.64, "c": 1.0}
    held = {"a": 0.7, "b": 0.2, "c": 0.9}
    screen = {c: (SimpleNamespace(moved=moved_b or c != "b"), ms, "single") for c, ms in ins.items()}
    monkeypatch.setattr(study, "screen_singles", lambda order, *a, **k: {c: screen[c] for c in order})
    calls = []

    def single(causes):
        calls.append(tuple(causes))
        return {c: held[c] for c in causes}

    def score(c, singles):
        return SimpleNamespace(cause=c, heldout_rms=singles[c], significant=True)

    st = SimpleNamespace(preps=[SimpleNamespace(metric="points")], scales=None, base=None, skipped={})
    opts = SimpleNamespace(screen=True, say=lambda msg: None, calibrate_kw={}, jobs=1, screen_ratio=1.0)
    singles, _, left = study._singles(st, opts, ["a", "b", "c"], SimpleNamespace(start=dict), single, score)
    return calls, singles, left, st.skipped.get("screened", {})


def test_a_screen_fit_that_did_not_leave_its_start_is_cross_validated(monkeypatch):
    calls, singles, left, why = _singles(monkeypatch, moved_b=False)
    assert calls == [("a",), ("b",)] and set(singles) == {"a", "b"}
    assert left == ("c",) and "b's held-out" in why["c"]          # c's bound is against the better b


def test_a_screen_fit_that_moved_bounds_its_held_out_error(monkeypatch):
    calls, singles, left, why = _singles(monkeypatch, moved_b=True)
    assert calls == [("a",)]                                         # 0.64 >= 0.7²: b and c left out
    assert left == ("b", "c") and "a's held-out" in why["b"]
