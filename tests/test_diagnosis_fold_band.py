"""The baseline folds' prediction band (issue 28: no false alarm from a fold's own extrapolation).

A fold fitted on some trials knows its parameters up to ``C = (JᵀJ)⁻¹`` of its whitened Jacobian; a held-out
prediction's variance is ``diag(J_h C J_hᵀ)`` (linear propagation). Checked against closed forms: the
straight line's slope variance, the sigma-point band of a linear model, and the hat matrix's trace (a fit
predicting its own training data: the variances, in units of σ², add up to the number of parameters).
"""
import numpy as np

from notchfit.analysis.diagnosis.calibration import calibrate, fold_band
from notchfit.analysis.diagnosis.crossval import HeldOut
from notchfit.analysis.diagnosis.decision import explain
from notchfit.analysis.estimation.bands import gauss_newton_covariance, linear_band, prediction_band
from notchfit.analysis.estimation.observations import observe_study
from notchfit.io import read_study
from notchfit.studies.synth import load_recipe, synthesize, write_study
from notchfit.units import DEG


def test_covariance_of_a_line_fit_is_the_textbook_one():
    """y = a + b x with noise σ: var(b) = σ²/Σ(x − x̄)², var(a) = σ² Σx²/(n Σ(x − x̄)²) (whitened: σ = 1)."""
    x = np.linspace(0.0, 3.0, 7)
    sigma = 0.2
    J = np.column_stack([np.ones_like(x), x]) / sigma
    C = gauss_newton_covariance(J)
    sxx = np.sum((x - x.mean()) ** 2)
    np.testing.assert_allclose(C[1, 1], sigma**2 / sxx, rtol=1e-12)
    np.testing.assert_allclose(C[0, 0], sigma**2 * np.sum(x**2) / (x.size * sxx), rtol=1e-12)


def test_linear_band_equals_the_sigma_point_band_of_a_linear_model(rng):
    """For a linear model the sigma points' variance is exactly J C Jᵀ (Nørgaard et al. 2000, Sec. 3)."""
    A = rng.normal(size=(5, 3))
    L = rng.normal(size=(3, 3))
    C = L @ L.T
    mu = rng.normal(size=3)
    sig = prediction_band(lambda v: A @ v, mu, C, noise_sd=0.1)
    lin = linear_band(A @ mu, A, C, noise_sd=0.1)
    np.testing.assert_allclose(lin.sd, sig.sd, rtol=1e-10)
    np.testing.assert_allclose(lin.mean, sig.mean, rtol=1e-10)


def test_a_fold_predicting_its_own_training_data_has_the_hat_matrix_trace(tmp_path):
    """Held out = the training experiments: Σ var/σ² over every measured angle is trace(H) = p, the number of
    fitted parameters (the hat matrix ``J C Jᵀ`` of a full-rank least squares)."""
    r = load_recipe("null").scaled(n_experiments=2, n_up=5, n_down=4).replace(observe="angles", angle_sigma_deg=0.2)
    write_study(synthesize(r, seed=2, method="fast"), tmp_path / "study")
    preps = observe_study(read_study(tmp_path / "study"), "angles")
    cal = calibrate(preps, None, errors=False)
    var = fold_band(preps, cal, preps, bound_prior=False, tension_noise=False)
    assert len(var) == 2 and all(v.shape == (p.time.size,) for v, p in zip(var, preps))

    def trace(var):
        return sum(float(np.nansum(v * p.valid.sum(axis=1))) / p.sigma**2 for v, p in zip(var, preps))

    assert not cal.tubes                                # the seed tube: no per-tube unknowns, no priors
    np.testing.assert_allclose(trace(var), len(cal.values), rtol=1e-6)
    # the bounds as a prior only narrow the band (0 < their trace < p)
    assert 0.0 < trace(fold_band(preps, cal, preps, tension_noise=False)) < len(cal.values)
    # the training trials' load-cell noise (0.11 N here) only widens it
    assert trace(fold_band(preps, cal, preps, bound_prior=False)) > len(cal.values)


RULE = dict(none_tol=0.5, z_crit=3.0, min_removed=0.3)


def test_heldout_band_and_the_floor_in_words():
    """The held-out band's mean over every sample; the explanation states the floor with both parts."""
    held = HeldOut((), band={0: np.array([1.0, 3.0]), 1: np.array([np.nan, 2.0])})
    assert held.mean_band() == 2.0 and HeldOut(()).mean_band() == 0.0
    text = explain("none", [], [], 0.55 * DEG, 0.3 * DEG, metric="angles", **RULE, band_rms=0.4 * DEG)
    assert "0.550° rms against a floor of 0.500° (noise 0.300°, the folds' prediction uncertainty 0.400°)" in text
    assert "noise floor" in explain("none", [], [], 0.55 * DEG, 0.3 * DEG, metric="angles", **RULE)


def test_the_training_tension_noise_gives_the_sandwich_of_a_misweighted_fit():
    """A model linear in its parameters and in each sample's measured tension, fitted by least squares weighted
    by the measurement σ alone: the parameters' covariance is ``C Jᵀ Σ J C``, ``Σ = I + σ_T² Σ_s b_s b_sᵀ / σ²``
    (``b_s`` the rows of sample ``s``'s response to its tension: the load-cell noise moves every point of a
    sample together), ``C = (JᵀJ)⁻¹``. Two trials, the second with no tendon of that side."""
    import dataclasses
    from types import SimpleNamespace

    from notchfit.analysis.diagnosis.calibration import _tension_sandwich

    rng = np.random.default_rng(3)
    S, m, p, sigma = 5, 3, 2, 0.1

    @dataclasses.dataclass(frozen=True, eq=False)
    class Trial:
        tension_left: np.ndarray
        tension_right: np.ndarray
        tension_sigma: float
        geom: SimpleNamespace
        slope: np.ndarray                               # (S, m): each row's response to its sample's tension
        A: np.ndarray                                   # (S m, p)

    def trial(tendons, sig_t):
        return Trial(rng.uniform(0, 2, S), rng.uniform(0, 2, S), sig_t, SimpleNamespace(tendons=tendons),
                     rng.normal(0, 1, (S, m)), rng.normal(0, 1, (S * m, p)))

    @dataclasses.dataclass(frozen=True)
    class Toy:
        obs: tuple

        def residuals(self, x):
            return np.concatenate([(o.A @ x + (o.slope * o.tension_right[:, None]).ravel()) / sigma for o in self.obs])

        def clusters(self):
            return np.repeat(np.arange(S * len(self.obs)), m)

    obs = (trial(("right",), 0.05), trial(("left",), 0.05))
    pb, x = Toy(obs), rng.normal(0, 1, p)
    J = np.vstack([o.A for o in obs]) / sigma
    C = np.linalg.inv(J.T @ J)
    Sigma = np.eye(J.shape[0])
    b = obs[0].slope * 0.05 / sigma                       # the first trial's samples only
    for s in range(S):
        v = np.zeros(J.shape[0])
        v[s * m:(s + 1) * m] = b[s]
        Sigma += np.outer(v, v)
    np.testing.assert_allclose(_tension_sandwich(pb, x, J, C), C @ J.T @ Sigma @ J @ C, rtol=1e-6, atol=1e-12)
