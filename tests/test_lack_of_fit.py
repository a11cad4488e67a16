"""Pure error and lack of fit (notchfit.analysis.lack_of_fit) against the textbook decomposition.

The identities and the test are those of a regression with replicates
(Draper & Smith, Applied Regression Analysis, 3rd ed., Sec. 2.1; NIST/SEMATECH
e-Handbook, Sec. 4.4.4.3). Checked here: the sum-of-squares identity, the
F statistic against scipy's one-way ANOVA (an independent implementation of
the same test for a model that predicts the grand mean), the calibration of
the p-value under the null hypothesis, and the power against a known bias.
"""

import numpy as np
import pytest
from scipy import stats

from notchfit.analysis.lack_of_fit import (Trial, lack_of_fit, lack_of_fit_table, loading_direction,
                                           replicate_groups, study_lack_of_fit)


def _replicated(rng, *, groups=12, reps=4, sigma=0.3, bias=0.0):
    """Group means, replicated noisy observations and their ground truth."""
    mu = rng.normal(0.0, 2.0, groups)
    g = np.repeat(np.arange(groups), reps)
    y = mu[g] + rng.normal(0.0, sigma, g.size)
    return {"y": y, "g": g, "mu": mu, "pred": mu[g] + bias}


def test_sums_of_squares_add_up_when_predictions_are_constant_in_a_group():
    """SS_res = SS_pe + SS_lof exactly (Draper & Smith Eq. 2.1.9) for a group-constant prediction."""
    d = _replicated(np.random.default_rng(1), bias=0.2)
    r = lack_of_fit(d["y"], d["pred"], d["g"])
    ss_res = r.residual_rms ** 2 * r.n_obs
    ss_pe = r.pure_error_rms ** 2 * r.df_pe
    ss_lof = r.F * r.df_lof * r.pure_error_rms ** 2
    assert ss_res == pytest.approx(ss_pe + ss_lof, rel=1e-12)


def test_F_equals_one_way_anova_for_the_grand_mean():
    """A model predicting the grand mean (one parameter): F is scipy's one-way ANOVA F."""
    d = _replicated(np.random.default_rng(2), groups=7, reps=5)
    grand = np.full_like(d["y"], d["y"].mean())
    r = lack_of_fit(d["y"], grand, d["g"], n_params=1)
    ref = stats.f_oneway(*[d["y"][d["g"] == k] for k in range(7)])
    assert r.F == pytest.approx(ref.statistic, rel=1e-10)
    assert r.p_value == pytest.approx(ref.pvalue, rel=1e-8)


def test_null_hypothesis_p_values_are_calibrated_and_scatter_is_sigma():
    """With the true means as predictions, p < 0.05 in about 5 % of studies; s_pe estimates σ."""
    rng = np.random.default_rng(3)
    p, s = [], []
    for _ in range(400):
        d = _replicated(rng, sigma=0.5)
        r = lack_of_fit(d["y"], d["pred"], d["g"])
        p.append(r.p_value)
        s.append(r.pure_error_rms)
    rate = np.mean(np.array(p) < 0.05)
    assert 0.025 <= rate <= 0.08, rate              # binomial(400, 0.05): 0.05 ± 2.7 sd
    assert np.mean(s) == pytest.approx(0.5, rel=0.03)


def test_a_bias_beyond_the_scatter_is_found_and_sized():
    """A constant model bias of 3σ/2 is significant and its lack-of-fit rms recovers the bias."""
    d = _replicated(np.random.default_rng(4), groups=20, reps=4, sigma=0.2, bias=0.3)
    r = lack_of_fit(d["y"], d["pred"], d["g"])
    assert r.significant()
    assert r.lack_of_fit_rms == pytest.approx(0.3, rel=0.15)


def test_table_rows_per_response_and_force_range():
    rng = np.random.default_rng(5)
    groups, reps, k = 9, 3, 4
    g = np.repeat(np.arange(groups), reps)
    force = np.repeat(np.linspace(0.0, 2.0, groups), reps) + rng.normal(0, 0.01, g.size)
    truth = np.outer(force, np.arange(1, k + 1) * 0.1)
    y = truth + rng.normal(0.0, 0.01, truth.shape)
    pred = truth.copy()
    pred[:, 2] += 0.05                                   # the model misses notch 3 only
    t = lack_of_fit_table(y, pred, g, force, unit="rad", n_ranges=3)
    assert [r.label for r in t.by_response] == ["joint 1", "joint 2", "joint 3", "joint 4"]
    assert [r.significant() for r in t.by_response] == [False, False, True, False]
    assert len(t.by_range) == 3 and sum(r.n_groups for r in t.by_range) == groups * k   # (group, notch) pairs
    assert "joint 3" in t.summary() and "lack of fit" in t.verdict()
    assert t.as_dict()["overall"]["n_groups"] == groups * k


def test_without_replicates_the_verdict_says_so():
    y = np.arange(6.0)
    t = lack_of_fit_table(y[:, None], y[:, None], np.full(6, -1), y, unit="deg")
    assert not t.has_replicates
    assert "cannot be measured" in t.summary()


def test_replicate_groups_join_trials_not_samples_of_one_trial():
    trial = np.array(["a", "a", "b", "b", "c", "a"])
    cond = np.array([1, 1, 1, 1, 1, 2])
    tension = np.array([0.50, 1.00, 0.55, 1.05, 2.0, 0.5])
    g = replicate_groups(trial, cond, tension, tol=0.1)
    assert g[0] == g[2] != -1 and g[1] == g[3] != -1 and g[0] != g[1]
    assert g[4] == -1                 # no other trial near 2.0 N
    assert g[5] == -1                 # another condition (e.g. unloading)


def test_replicate_groups_do_not_chain_along_a_ramp():
    """A slow ramp in two trials: groups stay within max_width, not one group for the whole ramp."""
    t = np.linspace(0.0, 3.0, 61)
    trial = np.r_[np.zeros(61), np.ones(61)]
    g = replicate_groups(trial, np.zeros(122), np.r_[t, t + 0.01], tol=0.1, max_width=0.2)
    spans = [np.ptp(np.r_[t, t + 0.01][g == k]) for k in np.unique(g[g >= 0])]
    assert max(spans) <= 0.2 + 1e-12 and len(spans) >= 10


def test_loading_direction():
    assert loading_direction([0.0, 1.0, 2.0, 2.0, 1.0], tol=0.01).tolist() == [0, 1, 1, 0, -1]


def _trials(rng, *, n_trials=4, sigma=0.01, bias_joint=None, bias=0.0, above=np.inf):
    """Loading ramps of one 3-joint tube: each trial's set-points jittered by 0.03 N (near replicates), the
    response 0.2 rad/N; the model exact except ``bias`` on ``bias_joint`` above the tension ``above``."""
    out = []
    for i in range(n_trials):
        T = np.r_[0.0, np.linspace(0.5, 3.0, 6)] + np.r_[0.0, rng.uniform(-0.03, 0.03, 6)]
        truth = np.outer(T, [0.2, 0.15, 0.1])
        pred = truth.copy()
        if bias_joint is not None:
            pred[T > above, bias_joint] += bias
        out.append(Trial(f"T{i}", "tube", truth + rng.normal(0.0, sigma, truth.shape), pred, T))
    return out


def test_study_lack_of_fit_near_replicates_and_where_the_model_misses():
    """Near replicates (set-points within 0.03 N on a 0.2 rad/N slope): the scatter is the noise, not the
    slope's 6 mrad of spread; a 0.05 rad bias of joint 3 above 2 N is found on joint 3 and in the top force
    range only."""
    rng = np.random.default_rng(7)
    ok = study_lack_of_fit(_trials(rng), unit="rad")["tube"]
    assert ok.overall.pure_error_rms == pytest.approx(0.01, rel=0.3)
    assert not ok.overall.significant(0.01)
    bad = study_lack_of_fit(_trials(rng, bias_joint=2, bias=0.05, above=2.0), unit="rad")["tube"]
    assert bad.overall.significant(0.001)
    sig = {r.label for r in bad.by_response if r.significant(0.001)}
    assert sig == {"joint 3"}
    top = max(bad.by_range, key=lambda r: float(r.label.split("-")[1].split()[0]))
    assert top.significant(0.001) and top.lack_of_fit_rms > 0.02
    assert not any(r.significant(0.001) for r in bad.by_range if r is not top)
    assert "joint 3" in bad.summary() and bad.as_dict()["overall"]["df_pe"] > 0


def test_fit_prints_and_records_the_lack_of_fit(tmp_path, capsys):
    """notchfit fit: each shape model's lack of fit against the trials' scatter is printed and written to
    fit_run.json (lack_of_fit: model -> tube -> rows); constant curvature misses a tip-first wrist's
    uneven bending far beyond the 0.5 deg scatter."""
    import json

    from notchfit.cli import main
    from notchfit.studies.recipes import recipe_from_dict
    from notchfit.studies.stock import stock_recipe
    from notchfit.studies.synth import generate_study
    d = stock_recipe("lof", "wrist_tip_first", [{"name": f"T{i + 1}", "peak_N": [1.8, 1.9]} for i in range(3)],
                     seed=3)
    generate_study(recipe_from_dict(d), tmp_path / "s", force=True)
    assert main(["fit", str(tmp_path / "s"), "--out", str(tmp_path / "o"), "--no-figures",
                 "--models", "cc,free"]) == 0
    out = capsys.readouterr().out
    assert "cc: Lack of fit against the trials' scatter" in out
    lof = json.loads((tmp_path / "o" / "fit_run.json").read_text())["lack_of_fit"]
    cc = lof["cc"]["wrist_tip_first"]
    assert cc["unit"] == "deg" and cc["overall"]["p_value"] < 1e-6
    assert cc["overall"]["pure_error_rms"] == pytest.approx(0.5, rel=0.35)
    assert [r["label"] for r in cc["by_response"]] == [f"joint {j}" for j in range(1, 5)]
    assert len(cc["by_range"]) >= 2
