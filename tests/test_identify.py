"""``notchfit identify`` (issue 18): the model calibrated on a study, with held-out errors.

Synthetic wrists measured as notch angles against tendon tension, loading-only trials as real
labs run them, with seeded noise in the angles and in the load cells. The truth is the friction
simulator's reference solver (explicit Euler, Sec. IV-B) at a 2 ms damping time; identify fits
with the fast solver at 1 ms: data drawn from a model that is not the identified one. Issue 18's
numbers: parameters within 3 SE of the truth, held-out rms within 15 % of the injected angle
noise, a material identified on two wrists predicts a third wrist of another geometry to within
1.5x the noise.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.cli import main
from notchfit.analysis.estimation import choose_metric, observe_study, tube_labels
from notchfit.physics.friction import default_params
from notchfit.analysis.identify import default_free, identify, parse_free, zero_tension_samples
from notchfit.io import load_params
from notchfit.analysis.identify.problem import standard_errors
from notchfit.studies.recipes import recipe_from_dict
from notchfit.studies.synth import generate_study

TRUTH = {"E_lin": 45e9, "E_se": 3e9, "strain_lower": 0.014, "mu_d": 0.12}
ANGLE_NOISE_DEG = 0.5

THIRD_WRIST = """name = "wrist_c"
n_joints = 5
outer_radius_mm = 0.81
inner_radius_mm = 0.70
slot_width_mm = [0.6, 0.6, 0.7, 0.7, 0.7]
slot_depth_mm = [1.38, 1.40, 1.40, 1.42, 1.44]
p_mm = [1.4, 1.5, 1.5, 1.5]
rest_angle_rad = [0.03, 0.05, 0.04, 0.06, 0.03]
slot_sides = [1, 1, 1, 1, 1]
backbone = "section"
tendons = ["right"]
tendon_path = "lumen"
cable_radius_mm = 0.05
base_edge_z_mm = -1.0
"""


def _study(folder, experiments, *, seed=1, tension_noise=0.005, observe="angles", n_up=12):
    """A loading-only synthetic study of the TRUTH material (reference solver, 2 ms damping)."""
    d = {"name": "ident", "seed": seed, "geometry": "wrist_asymmetric", "observe": observe, "base": {},
         "fixed": {"spring_law": "material", "friction_law": "capstan", **TRUTH, "mu_s": TRUTH["mu_d"] + 0.01,
                   "damping_time": 2e-3},
         "noise": {"point_mm": 0.005, "tension_N": tension_noise, "displacement_step_mm": 0.0,
                   "angle_deg": ANGLE_NOISE_DEG},
         "plane": {"tx_mm": [-1.0, 1.0], "ty_mm": [-1.0, 1.0], "phi_deg": [-10.0, 10.0]},
         "protocol": {"n_up": n_up, "n_down": 0, "dt_s": 5.0, "pull": "right", "counter_N": 0.0},
         "experiments": experiments}
    generate_study(recipe_from_dict(d), folder, force=True)
    return io.read_study(folder)


def _trials(prefix, n, peak, geometry=None):
    return [{"name": f"{prefix}{i + 1}", "peak_N": list(peak), **({"geometry": geometry} if geometry else {})}
            for i in range(n)]


@pytest.fixture(scope="module")
def one_wrist(tmp_path_factory):
    return _study(tmp_path_factory.mktemp("one") / "study", _trials("T", 3, (2.4, 3.0)))


def test_identify_recovers_the_material_of_a_synthetic_wrist(one_wrist):
    """Defaults on one asymmetric wrist, three repeated loading-only trials: E_lin, E_se, strain_lower
    and mu_d within 3 SE of the truth; each trial predicted by a model fitted on the other two within
    15 % of the 0.5 deg angle noise (pooled), and no trial worse than 1.5x the noise."""
    res = identify(one_wrist)
    assert res.metric == "angles" and res.unit == "deg" and res.free == ("E_lin", "E_se", "strain_lower", "mu_d")
    assert res.tube_free == ("rest_angle", "slot_depth")
    for name, truth in TRUTH.items():
        assert abs(res.values[name] - truth) <= 3.0 * res.se[name], (name, res.values[name], res.se[name])
    assert abs(res.heldout_rms - ANGLE_NOISE_DEG) <= 0.15 * ANGLE_NOISE_DEG
    assert max(res.heldout.values()) < 1.5 * ANGLE_NOISE_DEG
    assert res.train_rms <= res.heldout_rms
    tube = res.tubes["wrist_asymmetric"]                          # drawn as the geometry file says
    assert np.all(np.abs(tube.rest_angles) <= 3.0 * tube.rest_se)
    assert np.all(np.abs(tube.depth_offsets) <= 3.0 * tube.depth_se)
    # the shared model of a one-tube study carries its rest angles, cut depths and the quasi-static damping
    assert res.model.rest_angle == tuple(tube.rest_angles) and res.model.damping_time == pytest.approx(1e-3)
    assert res.model.slot_depth_offset == tuple(tube.depth_offsets)
    # the lack of fit against the trials' scatter (issue 27): the true model is within the 0.5 deg scatter
    lof = res.lack_of_fit["wrist_asymmetric"]
    assert lof.overall.pure_error_rms == pytest.approx(ANGLE_NOISE_DEG, rel=0.2)
    assert not lof.overall.significant(0.01) and len(lof.by_response) == 5 and len(lof.by_range) == 3
    assert "Lack of fit against the trials' scatter" in res.summary()
    assert res.as_dict()["lack_of_fit"]["wrist_asymmetric"]["overall"]["df_pe"] > 0
    # the rest angles' prior: measured at zero force, reported beside the fitted ones
    assert np.all(np.abs(tube.rest_angles - tube.rest_prior) < 3 * tube.rest_prior_sd)
    assert res.as_dict()["tubes"]["wrist_asymmetric"]["slot_depth_prior_sd_um"] == pytest.approx(15.0)


def test_a_parameter_the_data_cannot_determine_is_fixed_and_said(tmp_path):
    """A wrist loaded only within its linear range (peaks 0.2-0.3 N: the outer fibre never reaches
    strain_lower) says nothing of the plateau: E_se and strain_lower are reported as not determined,
    fixed at their start values, never printed as a number with an error bar many times itself;
    E_lin stays identified (docs/models.md, the material law)."""
    exps = _study(tmp_path / "lin", _trials("L", 2, (0.2, 0.3)))
    res = identify(exps, free=("E_lin", "E_se", "strain_lower"), heldout=False)
    assert {"E_se", "strain_lower"} <= set(res.fixed) and "E_lin" in res.free
    assert not set(res.fixed) & set(res.free)
    assert res.identifiability["E_se"].verdict == "not determined"
    text = res.summary()
    assert "E_se_Pa" in text and "not determined by these data" in text
    d = res.as_dict()
    assert "E_se_Pa" in d["fixed_at_prior"] and "E_se_Pa" not in d["params"]
    assert d["identifiability"]["E_se_Pa"]["verdict"] == "not determined"


def test_material_from_two_wrists_predicts_a_third(tmp_path, capsys):
    """Two wrists of one stock (5-notch asymmetric, 4-notch tip-first pre-curved) identified together
    through the CLI; `simulate --model model.toml` predicts a third wrist of another geometry (its rest
    angles from its geometry file) to within 1.5x the angle noise."""
    exps = _trials("A", 2, (2.4, 3.0)) + _trials("B", 2, (1.5, 1.9), "wrist_tip_first")
    _study(tmp_path / "ab", exps, seed=2)
    (tmp_path / "wrist_c.toml").write_text(THIRD_WRIST)
    _study(tmp_path / "c", _trials("C", 2, (1.6, 2.2), str(tmp_path / "wrist_c.toml")), seed=3)
    out = tmp_path / "ident"
    assert main(["identify", str(tmp_path / "ab"), "--out", str(out), "--no-heldout"]) == 0
    data = json.loads((out / "identify.json").read_text())
    truth = json.loads((tmp_path / "ab" / "truth.json").read_text())["experiments"]
    assert truth["B1"]["geometry"] == "wrist_tip_first" and "geometry" not in truth["A1"]   # per-experiment tubes
    assert set(data["tubes"]) == {"wrist_asymmetric", "wrist_tip_first"}
    assert data["free_per_tube"] == ["rest_angle_rad", "slot_depth_offset_m"]
    assert set(data["free"]) == set(data["params"]) == set(data["se"])      # every free name has a value
    assert (out / "model_wrist_tip_first.toml").is_file()
    model = load_params(out / "model.toml")
    assert model.rest_angle is None and model.slot_depth_offset is None    # shared: no one tube's values
    assert main(["simulate", str(tmp_path / "c"), "--out", str(tmp_path / "pred"), "--model", str(out / "model.toml"),
                 "--no-figures"]) == 0
    errs = np.concatenate([pd.read_csv(tmp_path / "pred" / n / "simulation_vs_angles.csv")
                           .filter(like="err_").to_numpy().ravel() for n in ("C1", "C2")])
    rms = float(np.sqrt(np.nanmean(errs ** 2)))
    assert rms < 1.5 * ANGLE_NOISE_DEG, rms
    assert "tube wrist_asymmetric" not in capsys.readouterr().out     # --no-heldout: no per-tube refits


def test_identify_cli_contract_and_points_metric(tmp_path, capsys):
    """identify.json has the contract's keys; model.toml is read by load_params; a study of notch points
    is identified in mm (registration as the diagnosis's); --free with file keys; a bad --free is one
    line and exit 2."""
    _study(tmp_path / "pts", _trials("P", 2, (2.4, 3.0)), observe="points", n_up=8)
    out = tmp_path / "ident"
    assert main(["identify", str(tmp_path / "pts"), "--out", str(out), "--free",
                 "E_lin_Pa,E_se,strain_lower,mu_d"]) == 0
    data = json.loads((out / "identify.json").read_text())
    for key in ("free", "params", "se", "metric", "train_rms", "heldout_rms", "heldout"):
        assert key in data
    assert data["metric"] == "mm" and data["free"] == ["E_lin_Pa", "E_se_Pa", "strain_lower", "mu_d"]
    assert set(data["heldout"]) == {"P1", "P2"} and all(v > 0 for v in data["heldout"].values())
    # 5 um point noise; the 5 mN load-cell noise moves the tip by tens of um on the plateau
    assert data["train_rms"] <= data["heldout_rms"] < 0.1
    model = load_params(out / "model.toml")
    assert model.E_lin == pytest.approx(data["params"]["E_lin_Pa"], rel=1e-15)
    assert model.rest_angle is None                             # rest angles were not free
    capsys.readouterr()
    assert main(["identify", str(tmp_path / "pts"), "--out", str(tmp_path / "x"), "--free", "E_lin,bogus"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--free 'bogus'" in err[0]


def test_free_names_defaults_and_tubes(geom):
    """--free takes field names and file keys; the defaults follow each tube's laws; tubes are labelled by
    geometry name, made unique."""
    assert parse_free(["E_lin_Pa", " mu_d", "rest_angle_rad", "slot_depth_offset_m"]) == (
        "E_lin", "mu_d", "rest_angle", "slot_depth")
    with pytest.raises(ValueError, match="twice"):
        parse_free(["E_lin", "E_lin_Pa"])
    from notchfit.analysis.identify import specs_for
    with pytest.raises(ValueError, match="no tube of this study uses spring_law = 'rates'"):
        specs_for(("k_lin", "mu_d"), [default_params(io.load_geometry(io.datasets_dir() / "geometry"
                                                                      / "wrist_asymmetric.toml"))])
    wrist = io.load_geometry(io.datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    assert default_free([default_params(geom)], [geom]) == ("k_lin", "k_mid", "mu_d")
    assert default_free([default_params(wrist)], [wrist]) == ("E_lin", "E_se", "strain_lower", "mu_d", "rest_angle",
                                                              "slot_depth")
    other = wrist.replace(slot_depth=1.38e-3)
    assert tube_labels([wrist, other, wrist, geom]) == ["wrist_asymmetric", "wrist_asymmetric-2",
                                                        "wrist_asymmetric", "moses2015"]


def test_metric_rest_samples_and_model_rest_angles(one_wrist, tmp_path):
    """One metric per study; the rest samples are the zero-tension ones before the first load; a model's
    rest angles (rest_angle_rad) round-trip through model.toml and must fit the tube."""
    obs = observe_study(one_wrist, prefer="angles")
    idx = zero_tension_samples(obs[0])
    assert idx.size >= 1 and np.all(obs[0].tension_right[idx] <= 3 * obs[0].tension_sigma)
    assert np.all(np.diff(idx) == 1) and idx[0] == 0
    mixed = [one_wrist[0], io.with_points(one_wrist[1].__class__(**{**one_wrist[1].__dict__, "angles": None}),
                                          np.zeros((one_wrist[1].n_samples, 14, 2)))]
    with pytest.raises(ValueError, match="one kind of measurement"):
        choose_metric(mixed, prefer="angles", who="identify")
    p = default_params(one_wrist[0].geometry).replace(rest_angle=(0.01, 0.02, 0.0, -0.01, 0.03))
    io.save_params(p, tmp_path / "m.toml")
    assert load_params(tmp_path / "m.toml") == p
    assert "rest_angle_rad = [0.01, 0.02, 0.0, -0.01, 0.03]" in (tmp_path / "m.toml").read_text()
    np.testing.assert_array_equal(p.rest_angles(one_wrist[0].geometry), [0.01, 0.02, 0.0, -0.01, 0.03])
    with pytest.raises(ValueError, match="given for 3 joints"):
        p.replace(rest_angle=(0.0, 0.0, 0.0)).rest_angles(one_wrist[0].geometry)
    with pytest.raises(ValueError, match="closure"):
        p.replace(rest_angle=1.0).rest_angles(one_wrist[0].geometry)


class _Linear:
    """A linear least-squares problem in the interface standard_errors reads."""

    def __init__(self, A, y, clusters):
        self.A, self.y, self.cl = A, y, clusters
        self.hi = np.full(A.shape[1], np.inf)

    def residuals(self, x):
        return self.A @ x - self.y

    def measured(self):
        return np.ones(self.y.size, bool)

    def clusters(self):
        return self.cl


def test_standard_errors_of_a_linear_problem(rng):
    """On a linear model with independent noise the Gauss-Newton part is the OLS formula
    s^2 (A^T A)^-1 exactly, and the reported SE is never below it."""
    A = np.column_stack([np.ones(200), np.linspace(0.0, 1.0, 200)])
    y = A @ [1.0, 2.0] + rng.normal(0.0, 0.1, 200)
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = A @ x - y
    ols = np.sqrt(np.diag(np.linalg.inv(A.T @ A)) * (r @ r) / 198)
    se = standard_errors(_Linear(A, y, np.arange(200)), x, np.full(2, 1e-6))
    assert np.all(se >= ols * (1 - 1e-6))
    assert se == pytest.approx(ols, rel=0.25)            # the jackknife agrees for homoscedastic noise


@pytest.mark.parametrize("name", ["wrist_asymmetric", "default"])
def test_simulate_angles_rests_where_the_frictionless_statics_put_it(name):
    """The identification's inner loop against a closed form: without friction every sample of a step
    protocol rests where each joint's spring balances its tendon torques, τ_j(θ_j − θ0_j) = a_R,j T_R −
    a_L,j T_L (docs/models.md, "Real tubes: mechanics"), solved by inverting the piecewise-linear spring
    (PiecewiseLinearSpring.angle), not by the time-stepping solver; for a one-tendon wrist and the seed tube."""
    from notchfit.physics.cables import LEFT, RIGHT
    from notchfit.physics.friction import simulate_angles
    geom = io.load_geometry(io.datasets_dir() / "geometry" / f"{name}.toml")
    p = default_params(geom).replace(mu_d=0.0, mu_s=0.0)
    peak = 2.5 if geom.backbone == "section" else 20.0
    t = np.arange(1.0, 12.0) * 5.0
    TR = np.r_[np.linspace(0.0, peak, 6), np.linspace(peak, 0.0, 6)[1:]]
    TL = np.full_like(TR, 0.5) if "left" in geom.tendons else None
    theta = simulate_angles(t, TL, TR, p, geom)
    torque = np.outer(TR, np.abs(geom.moment_arms(RIGHT)))
    if TL is not None:
        torque -= np.outer(TL, np.abs(geom.moment_arms(LEFT)))
    spring = p.joint_spring(geom)
    expected = p.rest_angles(geom) + spring.angle(torque)
    np.testing.assert_allclose(theta, expected, rtol=0, atol=1e-12)
    # the loads pass the spring's first break: its plateau is checked, not only its linear part
    assert np.all(np.abs(expected - p.rest_angles(geom)).max(axis=0) > np.atleast_2d(spring.breaks)[:, 0])
    with pytest.raises(TypeError, match="unknown option"):
        simulate_angles(t, TL, TR, p, geom, tension_tol=0.1)


def test_model_file_fixes_what_is_not_free(one_wrist, tmp_path):
    """--model gives the values of everything not fitted: with the true model but E_se off by 50 % and
    only E_se free, identify recovers E_se (within 3 SE) and leaves the rest as the file says."""
    base = default_params(one_wrist[0].geometry).replace(**{**TRUTH, "E_se": 4.5e9}, mu_s=TRUTH["mu_d"] + 0.01,
                                                         damping_time=1e-3)
    io.save_params(base, tmp_path / "start.toml")
    out = tmp_path / "ident"
    study = one_wrist[0].path.parent
    assert main(["identify", str(study), "--out", str(out), "--model", str(tmp_path / "start.toml"),
                 "--free", "E_se", "--no-heldout"]) == 0
    data = json.loads((out / "identify.json").read_text())
    assert data["free"] == ["E_se_Pa"] and data["heldout_rms"] is None        # NaN (no refits) written as null
    assert abs(data["params"]["E_se_Pa"] - TRUTH["E_se"]) <= 3 * data["se"]["E_se_Pa"]
    model = load_params(out / "model.toml")
    assert (model.E_lin, model.strain_lower, model.mu_d) == (TRUTH["E_lin"], TRUTH["strain_lower"], TRUTH["mu_d"])
    assert model.rest_angle is None and model.slot_depth_offset is None
