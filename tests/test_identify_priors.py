"""identify's per-tube priors (issue 27): rest angles tied to the angles measured at zero force, cut
depths to the drawing's tolerance, both as whitened residual rows of the least-squares problem."""

from __future__ import annotations

import numpy as np
import pytest

from notchfit import io
from notchfit.analysis.estimation import observe_study, zero_tension_samples
from notchfit.analysis.identify import make_problem, specs_for
from notchfit.analysis.identify.problem import _rest_prior
from notchfit.analysis.identify.specs import DEPTH_TOLERANCE, REST_SIGMA_GEOMETRY, base_model
from notchfit.studies.recipes import recipe_from_dict
from notchfit.studies.stock import stock_recipe
from notchfit.studies.synth import generate_study

REST_TRUE = (0.02, 0.035, -0.01, 0.05, 0.0)
ANGLE_SIGMA = np.radians(0.5)


@pytest.fixture(scope="module")
def precurved(tmp_path_factory):
    """Three loading-only trials of a pre-curved 5-notch wrist whose geometry file says 0 rest angles."""
    d = stock_recipe("prior", "wrist_asymmetric", [{"name": f"T{i + 1}", "peak_N": [2.0, 2.6]} for i in range(3)],
                     seed=4, rest_angle=list(REST_TRUE))
    folder = tmp_path_factory.mktemp("prior") / "study"
    generate_study(recipe_from_dict(d), folder, force=True)
    return observe_study(io.read_study(folder), prefer="angles")


def _problem(obs, geom=None, **kw):
    base = {o.tube: base_model(geom or o.geom) for o in obs}
    specs = specs_for(("E_lin", "mu_d"), list(base.values()))
    return make_problem(obs, base, specs, rest=True, depth=True, excess=0.01, **kw)


def test_rest_prior_is_the_zero_force_measurement_with_its_standard_error(precurved):
    """The prior's mean is the mean of the samples taken at zero force (the truth's rest angles within
    3 standard errors), its σ the angle noise over those samples (σ_θ/√N) or the trials' scatter, never
    the geometry file's 0 rad."""
    obs = precurved
    n_rest = sum(zero_tension_samples(o).size for o in obs)
    assert n_rest >= 3
    mean, sd = _rest_prior(obs, obs[0].tube, base_model(obs[0].geom), None)
    assert np.all(sd >= ANGLE_SIGMA / np.sqrt(n_rest) * (1 - 1e-9))
    assert np.all(sd < 3 * ANGLE_SIGMA / np.sqrt(n_rest))
    assert np.all(np.abs(mean - REST_TRUE) < 3 * sd), (np.degrees(mean), np.degrees(sd))


def test_priors_enter_the_problem_as_whitened_rows(precurved):
    """The last rows of the residuals are (rest − prior mean)/σ per joint, then offset/σ_depth per notch and
    the tube's mean offset over its σ; a geometry's slot_depth_tolerance_mm sets σ_depth, an explicit
    depth_sigma overrides it, and without one the 15 um default holds."""
    obs = precurved
    pb = _problem(obs)
    mean, sd = _rest_prior(obs, obs[0].tube, base_model(obs[0].geom).replace(E_lin=50e9, mu_d=0.1, mu_s=0.11), None)
    n, k = 5, pb.k
    x = pb.x0.copy()
    x[k:k + n] = mean + 2.0 * sd                           # two σ off the measured rest angles
    x[k + n:k + 2 * n] = np.arange(1, 6) * 1e-6            # offsets of 1..5 um
    tail = pb.residuals(x)[-(2 * n + 1):]
    np.testing.assert_allclose(tail[:n], 2.0, rtol=1e-9)
    np.testing.assert_allclose(tail[n:2 * n], np.arange(1, 6) * 1e-6 / DEPTH_TOLERANCE, rtol=1e-9)
    np.testing.assert_allclose(tail[-1], 3e-6 / 2e-6, rtol=1e-9)
    np.testing.assert_allclose(pb.x0[k:k + n], mean, atol=1e-12)   # the fit starts at the measurement
    tight = obs[0].geom.replace(slot_depth_tolerance=5e-6)
    obs_t = tuple(o.__class__(**{**o.__dict__, "geom": tight}) for o in obs)
    tail = _problem(obs_t).residuals(x)[-(2 * n + 1):]
    np.testing.assert_allclose(tail[n:2 * n], np.arange(1, 6) * 1e-6 / 5e-6, rtol=1e-9)
    tail = _problem(obs_t, depth_sigma=20e-6).residuals(x)[-(2 * n + 1):]
    np.testing.assert_allclose(tail[n:2 * n], np.arange(1, 6) * 1e-6 / 20e-6, rtol=1e-9)


def test_without_rest_samples_the_prior_is_the_geometry_file(precurved):
    """Trials that start loaded measure no rest angle: the prior is the geometry's rest angles with σ 1°."""
    o = precurved[0]
    keep = np.arange(zero_tension_samples(o).size, o.time.size)
    cut = o.__class__(**{**o.__dict__, **{f: getattr(o, f)[keep] for f in
                                          ("time", "tension_left", "tension_right", "measured", "valid",
                                           "theta_free", "a", "b", "regime")}})
    assert zero_tension_samples(cut).size == 0
    mean, sd = _rest_prior((cut,), cut.tube, base_model(cut.geom), None)
    np.testing.assert_array_equal(mean, cut.geom.rest_angles)
    np.testing.assert_array_equal(sd, REST_SIGMA_GEOMETRY)


def test_geometry_file_key_slot_depth_tolerance(tmp_path):
    """slot_depth_tolerance_mm is read in mm, must be positive, and names its line when it is not."""
    src = (io.datasets_dir() / "geometry" / "wrist_asymmetric.toml").read_text()
    (tmp_path / "g.toml").write_text(src + "slot_depth_tolerance_mm = 0.008\n")
    assert io.load_geometry(tmp_path / "g.toml").slot_depth_tolerance == pytest.approx(8e-6)
    (tmp_path / "bad.toml").write_text(src + "slot_depth_tolerance_mm = -0.01\n")
    with pytest.raises(ValueError, match=r"line \d+: slot_depth_tolerance_mm must be positive"):
        io.load_geometry(tmp_path / "bad.toml")
