"""The second-cause step when the candidates' screen left a candidate out of the first step
(notchfit.analysis.diagnosis.pairs.second_step; docs/diagnosis.md, "Two causes at once").

The screen leaves out a candidate whose fit on every experiment is not below the best candidate's
held-out error; that fit is one local fit, started where the baseline compensated the effect. On the
reduced Bouc-Wen hysteresis study of seed 2 the hysteresis fit stopped at 0.80 mm in-sample (its optimum
on every experiment is near 0.15 mm), proximal friction was named first and the hysteresis then came in
as a false "second" cause. A pair the screen finds worth a cross-validation is evidence that its second
candidate moves the data: that candidate is cross-validated alone before the pair, and the first
decision is retaken with it.
"""
from types import SimpleNamespace

import numpy as np

from notchfit.analysis.diagnosis.pairs import second_step
from notchfit.analysis.diagnosis.specs import Thresholds


class _Held:
    """Held-out errors of one model: the same mean squared error on every sample of one experiment."""

    calibrations = ()

    def __init__(self, mse: float):
        self.mse = mse

    def sample_mse(self, preps):
        return [np.full(12, self.mse)]


def _screen(second):
    """In-sample errors of the pair screen: the pair with ``b`` removes 90 % of ``a``'s error."""
    fit = SimpleNamespace(stalled=False)
    return {"a": (fit, 1.0, "first"), **{f"a+{c}": (fit, 0.1 if c == "b" else 0.99, "first") for c in second}}


class _Stop(Exception):
    """The pairs' cross-validation was reached."""


def _step(alone_mse: float, rival):
    """``second_step`` from ``a`` (held-out 1.0) with second candidates ``b`` and ``c``: the calls made to
    cross-validate candidates alone and pairs, and the step's outcome (None when the pairs were reached)."""
    held, calls = {"a": _Held(1.0)}, []

    def single(causes):
        calls.append(("single", tuple(causes)))
        return {c: _Held(alone_mse) for c in causes}

    def run(models, starts):
        calls.append(("pairs", tuple(models)))
        raise _Stop

    try:
        out = second_step("a", held, [None], run, 0.01, ["b", "c"], Thresholds(), screen=_screen, single=single,
                          rival=lambda: rival(held))
    except _Stop:
        out = None
    return out, calls


def test_a_screened_out_candidate_is_cross_validated_alone_and_can_displace_the_first_cause():
    out, calls = _step(0.05, lambda held: "b" if held["b"].mse < held["a"].mse else "")
    assert out is not None, "the pairs are not cross-validated once the first cause is displaced"
    c2, hp, res, screened, displaced = out
    assert displaced == "b" and c2 is None and hp == {} and res == ()
    assert calls == [("single", ("b",))]          # only the pair the screen chose; its candidate alone
    assert "a+b" in screened


def test_without_a_rival_the_candidate_alone_comes_before_its_pair():
    out, calls = _step(0.5, lambda held: "")
    assert out is None
    assert calls == [("single", ("b",)), ("pairs", (("a", "b"),))]


def test_a_pair_whose_screen_fit_stalled_at_its_start_is_cross_validated():
    """The pair screen reads an in-sample error as a bound on the held-out one, which holds only at an
    optimum: a pair fit that stalled at its start (Calibration.stalled) is cross-validated whatever its
    in-sample error, after the pairs the screen chose, as the first step does with its candidates."""
    from notchfit.analysis.diagnosis.pairs import _to_cross_validate

    def screen(ms: dict, stalled=()):
        out = {"a": (SimpleNamespace(stalled=False), 1.0, "first")}
        out.update({f"a+{c}": (SimpleNamespace(stalled=c in stalled), v, "first") for c, v in ms.items()})
        return out

    ms = {"b": 0.5, "c": 0.99, "d": 0.6}
    args = (0.1, 0.5, 1.05, 2)                       # noise, min_excess_removed, screen_tol, max_cv
    assert _to_cross_validate("a", list(ms), screen(ms), *args) == ["b"]
    assert _to_cross_validate("a", list(ms), screen(ms, stalled=("c",)), *args) == ["b", "c"]
    weak = {"b": 0.95, "c": 0.99}                    # no pair earns a cross-validation in sample
    assert _to_cross_validate("a", list(weak), screen(weak), *args) == []
    assert _to_cross_validate("a", list(weak), screen(weak, stalled=("c",)), *args) == ["c"]
