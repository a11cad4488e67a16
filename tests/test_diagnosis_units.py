"""Pieces of the diagnosis that do not need the simulator."""
import math

import numpy as np
import pytest

from notchfit.analysis.diagnosis import CANDIDATES, CAUSES, folds_by_experiment, loading_stalls, paired_z, rank_candidates
from notchfit.analysis.diagnosis import peak_regimes as measured_regimes
from notchfit.analysis.diagnosis.noise import _effective_n
from notchfit.analysis.diagnosis.signatures import _loop_area, _release_tension


def test_causes_match_data_format_table():
    assert set(CAUSES) == {"proximal_friction", "static_friction", "joint_hysteresis",
                           "external_load", "stiffness_gradient", "calibration_error"}
    assert set(CANDIDATES) == set(CAUSES)


def test_fig11_regimes_from_data():
    """I up to the tension peak; II while the shape holds; III once it releases (Sec. IV, Fig. 11)."""
    T = np.r_[np.linspace(0, 25, 19), np.linspace(23, 0, 12)]
    tip = np.r_[np.linspace(0, 2.0, 19), [2.0, 1.98, 1.95, 1.9, 1.5, 1.0, 0.6, 0.3, 0.15, 0.1, 0.05, 0.0]]
    reg = measured_regimes(T, tip)
    assert list(reg[:19]) == ["I"] * 19
    assert list(reg[19:23]) == ["II"] * 4
    assert set(reg[23:]) == {"III"}


def test_loop_area_of_a_rectangle():
    T = np.array([0.0, 10.0, 10.0, 0.0])
    phi = np.array([0.0, 0.0, 1.0, 1.0])
    assert _loop_area(T, phi) == pytest.approx(10.0)
    # a path that retraces itself encloses nothing
    assert _loop_area(np.r_[T[:2], T[1::-1]], np.zeros(4)) == pytest.approx(0.0)


def test_release_tension_interpolates():
    T = np.array([0, 10, 20, 15, 10, 5, 0.0])
    phi = np.array([0, 1, 2, 2, 1, 0.5, 0.0])
    # half of the drop (2 -> 0) is reached at phi = 1, i.e. T = 10
    assert _release_tension(T, phi, None) == pytest.approx(10.0)


def test_effective_n_white_vs_correlated(rng):
    white = rng.normal(size=2000)
    assert _effective_n(white) == pytest.approx(2000, rel=0.1)
    ar = np.zeros(2000)
    for k in range(1, 2000):
        ar[k] = 0.9 * ar[k - 1] + rng.normal()
    # AR(1) with rho = 0.9: n (1 - rho)/(1 + rho) ~ n/19
    assert _effective_n(ar) == pytest.approx(2000 / 19, rel=0.35)


def test_paired_z_detects_improvement_and_respects_correlation(rng):
    base = [1.0 + 0.1 * rng.normal(size=40) for _ in range(4)]
    same = [b + 0.01 * rng.normal(size=40) for b in base]
    better = [0.8 * b for b in base]
    assert abs(paired_z(base, same)) < 3
    assert paired_z(base, better) > 10
    # a slowly varying difference counts as fewer independent samples: smaller z
    drift = [b - (0.02 + 0.05 * np.sin(np.linspace(0, 1, 40))) for b in base]
    white = [b - (0.02 + 0.05 * rng.permutation(np.sin(np.linspace(0, 1, 40)))) for b in base]
    assert paired_z(base, drift) < paired_z(base, white)


def test_folds_cover_every_experiment_once():
    for n in (2, 5, 6, 9):
        folds = folds_by_experiment(n)
        allv = np.sort(np.concatenate(folds))
        np.testing.assert_array_equal(allv, np.arange(n))
    with pytest.raises(ValueError, match="at least two"):
        folds_by_experiment(1)


def test_ranking_follows_signatures():
    sigs = [{"signature": "spatial_pattern", "value": 3.0}, {"signature": "loop_area_ratio", "value": 1.0}]
    assert rank_candidates(sigs, 2e-5)[0][0] == "calibration_error"
    sigs = [{"signature": "direction_asymmetry", "value": 0.05}]
    assert rank_candidates(sigs, 2e-5)[0][0] == "external_load"
    assert math.isfinite(rank_candidates([], 2e-5)[0][1])


def test_loading_stalls_counts_upper_ramp_steps_that_do_not_move():
    """Sec. IV-B Step 4 with μ_s >> μ_d: a step below the break-away excess moves nothing."""
    T = np.array([0.5, 5.0, 10.0, 15.0, 20.0, 25.0, 20.0, 10.0])
    pred = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.0, 0.6])
    meas = np.array([0.0, 0.2, 0.4, 0.6, 0.6, 1.0, 1.0, 0.6])     # stalled on 15 -> 20 N
    assert loading_stalls(T, meas, pred) == (1, 3)                 # steps above 12.5 N: 3
    assert loading_stalls(T, pred, pred) == (0, 3)
    # only the steps above `upper` x the peak count; nor does one that the model barely moves
    assert loading_stalls(T, meas, pred, upper=0.9) == (0, 1)
    flat = pred.copy()
    flat[4] = flat[3] + 0.005
    assert loading_stalls(T, meas, flat)[1] == 2


def test_ranking_points_to_static_friction_on_stalls():
    sigs = [{"signature": "loading_stalls", "value": 0.2}, {"signature": "loop_area_ratio", "value": 1.0}]
    top, _, why = rank_candidates(sigs, 2e-5)[0]
    assert top == "static_friction" and "stalls" in why


# ----------------------------------------------------------------------------- issue 19: two causes, angles, scope
def _prep(name="E1", metric="points", pulled=1, geom=None, S=4, tension=None):
    from notchfit.analysis.diagnosis import Prepared
    from notchfit.physics.geometry import default_geometry

    g = geom or default_geometry()
    shape = (S, g.n_points, 2) if metric == "points" else (S, g.n_joints)
    t = np.ones(S) if tension is None else np.asarray(tension, float)
    return Prepared(name=name, geom=g, time=np.arange(1.0, S + 1), tension_left=t,
                    tension_right=t, measured=np.zeros(shape), valid=np.ones(shape[:2], bool),
                    transform=None, sigma=1e-3, theta_free=np.zeros((S, g.n_joints)), free_residuals=None,
                    a=np.zeros(S), b=np.zeros(S), pulled=pulled, regime=np.array(["I"] * S), counter_tension=0.0,
                    metric=metric)


def test_second_candidates_keep_masked_ones_and_drop_noisy_static_friction():
    from notchfit.analysis.diagnosis import CandidateResult
    from notchfit.analysis.diagnosis.pairs import second_candidates

    def c(cause, rms, sig=False):
        return CandidateResult(cause, {}, 1, rms, rms, 0.0, 1.0, 0.1, sig)

    cands = [c("joint_hysteresis", 1.0, True), c("external_load", 3.0), c("static_friction", 1.5),
             c("calibration_error", 9.0), c("stiffness_gradient", 2.0)]
    # a candidate worse than the baseline alone stays (a dominant effect can mask it); static
    # friction only when significant alone
    assert second_candidates("joint_hysteresis", cands) == ["stiffness_gradient", "external_load",
                                                            "calibration_error"]
    assert second_candidates("joint_hysteresis", cands, max_second=1) == ["stiffness_gradient"]


def test_contribution_shares_add_up_to_the_removed_discrepancy():
    """Shapley shares over the two orders of adding the causes: they add to one, and the cause that
    removes more in both orders gets the larger share (docs/diagnosis.md)."""
    from notchfit.analysis.diagnosis import HeldOut
    from notchfit.analysis.diagnosis.pairs import contributions

    p = _prep(metric="angles")
    a, b = "external_load", "stiffness_gradient"
    errs = {"baseline": 0.05, a: 0.02, b: 0.045, f"{a}+{b}": 0.01}       # rms per angle [rad]
    held = {k: HeldOut(tuple(k.split("+")) if k != "baseline" else (), {0: np.full(p.measured.shape, e)},
                       {0: np.zeros(p.measured.shape)}, {0: np.full(4, 1e-6)}) for k, e in errs.items()}
    values = {"tip_force_x": 0.1, "tip_force_z": 0.0, "stiffness_gradient": 0.2}
    out = contributions((a, b), held, (p,), 1e-6, values, metric="angles")
    assert [c.cause for c in out] == [a, b]
    assert sum(c.share for c in out) == pytest.approx(1.0)
    msB, msA, msb, msAB = 0.05**2, 0.02**2, 0.045**2, 0.01**2
    assert out[0].share == pytest.approx(0.5 * ((msB - msA) + (msb - msAB)) / (msB - msAB))
    assert out[0].with_rms == pytest.approx(0.01) and out[0].without_rms == pytest.approx(0.045)
    assert out[1].gain_pct == pytest.approx(50.0)                       # b added last: 0.02 -> 0.01
    assert out[1].params == {"stiffness_gradient": 0.2} and out[0].without_key == b


def test_scope_skips_what_angle_data_cannot_show_and_keeps_a_tip_load_on_a_section_backbone():
    """Angle data cannot show a calibration warp; a tip load acts on any pivot chain (Eqs. 18-20 on the
    wrist's own chain), so it is tried on a wrist whose pivots are off its axis."""
    from notchfit.analysis.diagnosis.scope import applicable_causes
    from notchfit.analysis.diagnosis.signatures import skipped_signatures
    from notchfit.io import load_geometry
    from notchfit.studies.synth import _geometry_source

    wrist = load_geometry(_geometry_source("wrist_asymmetric"))
    bend_unbend = [0.0, 2.0, 4.0, 1.0]
    preps = (_prep("R1", "angles", geom=wrist, tension=bend_unbend), _prep("R2", "angles", geom=wrist))
    usable, skipped, reveal = applicable_causes(preps, CAUSES)
    assert set(skipped) == {"calibration_error"}
    assert usable == ("proximal_friction", "static_friction", "joint_hysteresis", "external_load",
                      "stiffness_gradient")
    assert set(skipped_signatures(preps)) == {"spatial_pattern", "direction_asymmetry"}
    # angle data could be measured as points (a tip load acts on any pivot chain, Eqs. 18-20)
    assert set(reveal) == {"calibration_error"} and "notch points" in reveal["calibration_error"]
    seed = (_prep("L", pulled=-1, tension=bend_unbend), _prep("R", pulled=1))
    assert applicable_causes(seed, CAUSES) == (CAUSES, {}, {}) and skipped_signatures(seed) == {}


def test_scope_skips_what_a_loading_only_one_direction_protocol_cannot_reveal():
    """No trial unloads: a loop (joint hysteresis) or a proximal capstan band cannot show; each is skipped
    with its reason and the experiment that would reveal it. A tip load is still tried with one pull
    direction (its torques change with the bend). A fall within the load-cell noise is no unloading."""
    from notchfit.analysis.diagnosis.scope import applicable_causes, unloads

    loading = [0.0, 1.0, 2.0, 3.0]
    preps = (_prep("A", tension=loading), _prep("B", tension=[0.0, 1.0, 2.0, 1.99]))
    assert not unloads(preps[1]) and unloads(_prep("C", tension=[0.0, 2.0, 3.0, 0.5]))
    usable, skipped, reveal = applicable_causes(preps, CAUSES)
    assert set(skipped) == {"proximal_friction", "joint_hysteresis"}
    assert usable == ("static_friction", "external_load", "stiffness_gradient", "calibration_error")
    assert "unloads" in skipped["joint_hysteresis"]
    assert reveal["joint_hysteresis"].startswith("unload one trial") and "joint hysteresis" in reveal["joint_hysteresis"]


def test_recorded_protocol_is_used_and_missing_one_is_said():
    from notchfit.analysis.diagnosis.scope import resolve_protocol

    preps = (_prep("A"), _prep("B"))
    out, prot, cal = resolve_protocol(preps, {"A": 4.0, "B": 4.0}, None, None)
    assert cal is None and prot["source"] == {"A": "experiment.toml", "B": "experiment.toml"}
    out, prot, _ = resolve_protocol(preps, {"A": 4.0, "B": None}, None, None, estimate=False)
    assert [p.ramp_time for p in out] == [0.0, 0.0] and prot["source"]["B"] == "assumed"
    assert "B" in prot["text"] and "step" in prot["text"]


def test_angle_metric_in_the_file():
    from notchfit.analysis.diagnosis import CandidateResult, Gain
    from notchfit.analysis.estimation import choose_metric
    from notchfit.units import DEG

    d = CandidateResult("joint_hysteresis", {}, 3, DEG, 2 * DEG, 0.0, 4.0, 0.5, True).to_dict("angles")
    assert d["heldout_rms_deg"] == pytest.approx(2.0) and "heldout_rms_mm" not in d
    assert Gain(2 * DEG, DEG).to_dict("angles")["extended"] == pytest.approx(1.0)

    class E:
        def __init__(self, name, points, angles):
            self.name, self.points, self.angles = name, points, angles

    assert choose_metric([E("a", 1, 1), E("b", 1, None)]) == "points"
    assert choose_metric([E("a", None, 1), E("b", 1, 1)]) == "angles"
    with pytest.raises(ValueError, match="one kind of measurement"):
        choose_metric([E("a", None, 1), E("b", 1, None)])


def test_heldout_lack_of_fit_against_repeated_trials():
    """Three trials repeat one bend/unbend (same tube, pull, counter-tension): held-out predictions of the
    true curve are within the trials' scatter; a curve off by five times the noise has a significant lack
    of fit (Draper & Smith 1998, Sec. 2.1). A trial against another counter-tension repeats none of them."""
    import dataclasses

    from notchfit.analysis.diagnosis.replicates import heldout_lack_of_fit

    rng = np.random.default_rng(3)
    t = np.array([0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0])
    trials = []
    for k, counter in enumerate((0.0, 0.0, 0.0, 1.5)):
        p = _prep(f"T{k}", "angles", S=t.size, tension=t)
        noisy = 0.1 * t[:, None] + rng.normal(0.0, 0.01, (t.size, p.geom.n_joints))      # (S, n) [rad]
        trials.append(dataclasses.replace(p, measured=noisy, counter_tension=counter, tension_sigma=0.01))
    exact = {i: np.repeat(0.1 * t[:, None], p.geom.n_joints, 1) for i, p in enumerate(trials)}
    lof = heldout_lack_of_fit(trials, exact, alpha=0.01)
    assert lof.has_replicates and not lof.overall.significant(0.01)
    # loading and unloading are apart; the fourth trial joins no group: 7 groups of the first three
    # (four loading values, three unloading ones) per joint
    assert lof.overall.n_groups == 7 * trials[0].geom.n_joints
    assert lof.overall.n_obs == 3 * t.size * trials[0].geom.n_joints
    off = {i: v + 0.05 for i, v in exact.items()}
    bad = heldout_lack_of_fit(trials, off, alpha=0.01)
    assert bad.overall.significant(0.01) and bad.overall.lack_of_fit_rms == pytest.approx(np.degrees(0.05), rel=0.2)


def _screened_singles(monkeypatch, in_sample: dict, heldout: dict, significant: set, *, screen=True, stalled=()):
    """:func:`study._singles` with a fake screen (in-sample mse per cause; the fits of ``stalled`` stalled at
    their start) and fake cross-validations (held-out rms per cause); returns the causes cross-validated, in
    order, and what it returned."""
    from types import SimpleNamespace

    from notchfit.analysis.diagnosis import CandidateResult
    from notchfit.analysis.diagnosis import study

    monkeypatch.setattr(study, "screen_singles", lambda order, *a, **k: {
        c: (SimpleNamespace(stalled=c in stalled), in_sample[c], "single") for c in order})
    done = []

    def single(cs):
        done.extend(cs)
        return {c: c for c in cs}

    def score(c, singles):
        return CandidateResult(c, {}, 1, heldout[c], heldout[c], 0.0, 5.0, 1.0, c in significant)

    opts = SimpleNamespace(screen=screen, screen_ratio=1.0, say=lambda m: None, calibrate_kw={}, candidate_kw={}, jobs=1)
    st = SimpleNamespace(preps=(SimpleNamespace(metric="points"),), scales=None, base=None, skipped={})
    full = SimpleNamespace(start=lambda: {})
    out = study._singles(st, opts, list(in_sample), full, single, score)
    return done, out, st.skipped


def test_candidates_cross_validated_in_in_sample_order_until_none_can_beat_the_best(monkeypatch):
    mm2 = 1e-6
    in_sample = {"joint_hysteresis": 0.08 * mm2, "proximal_friction": 0.014 * mm2, "external_load": 0.39 * mm2,
                 "stiffness_gradient": 0.017 * mm2}
    heldout = {"joint_hysteresis": 0.29e-3, "proximal_friction": 0.13e-3, "external_load": 0.65e-3,
               "stiffness_gradient": 0.125e-3}
    done, (singles, _, left), skipped = _screened_singles(monkeypatch, in_sample, heldout,
                                                          {"proximal_friction", "joint_hysteresis"})
    # proximal first (significant, 0.13 mm held-out = 0.0169 mm²); the gradient's in-sample 0.017 mm² is not
    # below it: every later one left out, the gradient too (its held-out 0.125 mm would not be reached in
    # practice: a held-out error is not below the in-sample one)
    assert done == ["proximal_friction"]
    assert left == ("stiffness_gradient", "joint_hysteresis", "external_load")
    assert set(skipped["screened"]) == set(left) and "0.130 mm" in skipped["screened"]["external_load"]
    # without a significant candidate every one is cross-validated, in in-sample order
    done, (_, _, left), skipped = _screened_singles(monkeypatch, in_sample, heldout, set())
    assert done == ["proximal_friction", "stiffness_gradient", "joint_hysteresis", "external_load"]
    assert left == () and "screened" not in skipped
    # the screen switched off: every candidate in the given order, none fitted on all experiments first
    done, (_, screen, _), _ = _screened_singles(monkeypatch, in_sample, heldout, {"proximal_friction"},
                                                screen=False)
    assert done == list(in_sample) and screen == {}


def test_a_screen_fit_stalled_at_its_start_is_cross_validated(monkeypatch):
    """A stalled screen fit (:func:`notchfit.analysis.estimation.solve.stalled_at_start`) bounds nothing: the
    reduced Bouc-Wen study of seed 2, whose hysteresis fit stalled at 0.80 mm in-sample against proximal
    friction's held-out 0.78 mm (docs/history.md, 2026-11-28). The candidates left out are then bounded by
    the better one."""
    mm2 = 1e-6
    in_sample = {"proximal_friction": 0.5 * mm2, "joint_hysteresis": 0.64 * mm2, "external_load": 1.5 * mm2}
    heldout = {"proximal_friction": 0.78e-3, "joint_hysteresis": 0.24e-3, "external_load": 1.3e-3}
    sig = {"proximal_friction", "joint_hysteresis"}
    done, (_, _, left), skipped = _screened_singles(monkeypatch, in_sample, heldout, sig)
    assert done == ["proximal_friction"] and left == ("joint_hysteresis", "external_load")
    done, (_, _, left), skipped = _screened_singles(monkeypatch, in_sample, heldout, sig,
                                                    stalled={"joint_hysteresis"})
    assert done == ["proximal_friction", "joint_hysteresis"] and left == ("external_load",)
    assert "joint_hysteresis's held-out 0.240 mm" in skipped["screened"]["external_load"]
    # every one left stalled: none left out
    done, (_, _, left), skipped = _screened_singles(monkeypatch, in_sample, heldout, sig,
                                                    stalled={"joint_hysteresis", "external_load"})
    assert done == ["proximal_friction", "joint_hysteresis", "external_load"] and left == ()
    assert "screened" not in skipped
