"""Fits stalled at their start (notchfit.analysis.estimation.solve.stalled_at_start), which the candidates'
screen cross-validates (notchfit.analysis.diagnosis.study._singles, tested in test_diagnosis_units.py;
docs/diagnosis.md, step 5; docs/history.md, 2026-11-28).

The screen leaves a candidate out when its in-sample error on all experiments is not below the best
significant held-out error: a model's held-out error is not below its in-sample one *at its optimum*. On the
reduced Bouc-Wen hysteresis study of seed 2 the hysteresis candidate's screen fit took no step from its best
probe (every trial step raised the non-smooth cost until the trust region fell below ``xtol``), 0.80 mm
in-sample against an optimum near 0.15 mm, and proximal friction was named alone. A fit that did not leave
its start though its linear model there promised a decrease (``Solution.stalled``) is no such bound: that
candidate is cross-validated.
"""
import numpy as np

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
