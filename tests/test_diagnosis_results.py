"""Typed diagnosis results and their diagnosis.json dictionaries (lengths in m inside, mm in the file)."""
import pytest

from notchfit.analysis.diagnosis import CandidateResult, Gain, Signature
from notchfit.analysis.diagnosis.decision import decide


def test_signature_lengths_in_mm_in_the_file():
    d = Signature("heldout_rms_regime_I", 2e-4, "m", "t").to_dict()
    assert d == {"signature": "heldout_rms_regime_I", "value": pytest.approx(0.2), "unit": "mm", "text": "t"}
    assert Signature("unloading_hold", 1.5, "N", "t").to_dict()["value"] == 1.5


def _cand(cause, rms, significant):
    return CandidateResult(cause=cause, params={"x": 1.0}, n_params=1, train_rms=rms, heldout_rms=rms,
                           aic=0.0, z=5.0, excess_removed=0.5, significant=significant)


def test_candidate_and_gain_dictionaries():
    d = _cand("external_load", 1.5e-4, True).to_dict()
    assert list(d) == ["cause", "params", "n_params", "train_rms_mm", "heldout_rms_mm", "aic", "z",
                       "excess_removed", "significant"]
    assert d["heldout_rms_mm"] == pytest.approx(0.15)
    g = Gain(4e-4, 1e-4)
    assert g.reduction_pct == pytest.approx(75.0)
    assert g.to_dict() == {"baseline": pytest.approx(0.4), "extended": pytest.approx(0.1),
                           "reduction_pct": pytest.approx(75.0)}
    assert Gain(0.0, 0.0).reduction_pct == 0.0


def test_decision_rule():
    cands = [_cand("external_load", 2e-4, True), _cand("proximal_friction", 1e-4, True)]
    assert decide(True, cands) == "none"
    assert decide(False, cands) == "proximal_friction"
    assert decide(False, [_cand("external_load", 2e-4, True), _cand("proximal_friction", 1e-4, False)]) \
        == "unexplained"
    assert decide(False, []) == "unexplained"
