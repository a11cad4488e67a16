"""The candidates' screen and fits that did not leave their start (notchfit.analysis.diagnosis.study._singles;
docs/diagnosis.md, "Two causes at once"; docs/history.md, 2026-11-28).

The screen leaves a candidate out when its in-sample error on all experiments is not below the best
significant held-out error: a model's held-out error is not below its in-sample one *at its optimum*. On the
reduced Bouc-Wen hysteresis study of seed 2 the hysteresis candidate's screen fit took no step from its best
probe (every trial step raised the non-smooth cost until the trust region fell below ``xtol``), 0.80 mm
in-sample against an optimum near 0.15 mm, and proximal friction was named alone. A fit that did not leave
its start though its linear model there promised a decrease (``Solution.stalled``) is no such bound: that
candidate is cross-validated.
"""
from types import SimpleNamespace

import numpy as np

from notchfit.analysis.diagnosis import study
from notchfit.analysis.estimation.solve import stalled_at_start


def test_a_run_that_ended_at_its_start_is_stalled_only_where_its_linear_model_promised_a_decrease():
    """``stalled_at_start``: residuals ``r = J x - y`` at ``x0 = 0``; the Gauss–Newton step of an exact linear
    model removes the part of ``r`` in the span of ``J``."""
    J = np.array([[1.0, 0.0], [0.0, 2.0], [0.0, 0.0]])
    r_far = np.array([-1.0, 1.0, 0.5])              # the step promises ½(1 + 1) of ½(2.25)
    r_opt = np.array([0.0, 0.0, 0.5])               # gradient Jᵀr = 0: an optimum, nothing promised
    x0 = np.zeros(2)
    kw = dict(xtol=1e-3, ftol=1e-3)
    assert stalled_at_start(r_far, J, x0, x0 + 1e-9, **kw)
    assert not stalled_at_start(r_opt, J, x0, x0, **kw)
    assert not stalled_at_start(r_far, J, x0, x0 + 0.1, **kw)      # it left its start
    assert not stalled_at_start(r_far, None, x0, x0, **kw)
    # the threshold is the fit's ftol of the cost: a promise of 1e-4 of it is not a stall at ftol 1e-3
    tiny = np.array([-1e-2, 0.0, 1.0])
    assert not stalled_at_start(tiny, J, x0, x0, **kw) and stalled_at_start(tiny, J, x0, x0, xtol=1e-3, ftol=1e-5)


def _singles(monkeypatch, stalled_b: bool):
    """``_singles`` on candidates a, b, c: in-sample (on all experiments) 0.50, 0.64, 1.00; held-out a 0.7,
    b 0.2 (both significant), c 0.9. b's screen fit stalled at its start or not. Returns the cross-validation
    calls, the candidates left out and the reasons recorded."""
    ins = {"a": 0.25, "b": 0.64, "c": 1.0}
    held = {"a": 0.7, "b": 0.2, "c": 0.9}
    screen = {c: (SimpleNamespace(stalled=stalled_b and c == "b"), ms, "single") for c, ms in ins.items()}
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


def test_a_screen_fit_that_stalled_at_its_start_is_cross_validated(monkeypatch):
    calls, singles, left, why = _singles(monkeypatch, stalled_b=True)
    assert calls == [("a",), ("b",)] and set(singles) == {"a", "b"}
    assert left == ("c",) and "b's held-out" in why["c"]          # c's bound is against the better b


def test_a_screen_fit_that_did_not_stall_bounds_its_held_out_error(monkeypatch):
    calls, singles, left, why = _singles(monkeypatch, stalled_b=False)
    assert calls == [("a",)]                                         # 0.64 >= 0.7²: b and c left out
    assert left == ("b", "c") and "a's held-out" in why["b"]
