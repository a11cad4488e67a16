"""Broyden's rank-one Jacobian updates between finite differences (estimation.solve._Secant; Madsen, Nielsen &
Tingleff 2004, "Methods for non-linear least squares problems", §3.4), checked against finite differences."""
import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

from notchfit.analysis.estimation.solve import _Jacobian, _Secant

T = np.linspace(0.0, 1.0, 40)
LO, HI = np.array([0.0, 0.0, -1.0]), np.array([5.0, 5.0, 1.0])


def _residuals(x):
    return np.r_[x[0] * np.exp(-x[1] * T) + x[2] * T - (2.0 * np.exp(-1.3 * T) + 0.4 * T), 0.1 * (x - 0.5)]


def _fd(fun):
    return lambda x: approx_derivative(fun, x, method="2-point", rel_step=2e-3, f0=fun(x), bounds=(LO, HI))


def _run(fun, jac, x0=(1.0, 0.5, 0.0), xtol=1e-10):
    return least_squares(fun, np.array(x0), jac=jac, bounds=(LO, HI), method="trf", ftol=1e-12, xtol=xtol,
                         gtol=1e-12, x_scale="jac")


def test_an_update_meets_the_secant_condition_and_is_exact_for_a_linear_model():
    A = np.random.default_rng(3).normal(size=(12, 3))
    b = np.arange(12.0)
    lin = lambda x: A @ x - b                                                 # noqa: E731
    sec = _Secant(lin, _fd(lin), max_updates=5)
    x0, x1 = np.array([0.5, 0.2, 0.1]), np.array([0.7, -0.1, 0.3])
    sec.residuals(x0)
    J0 = sec(x0)
    sec.residuals(x1)                                        # one step tried and accepted: an update
    J1 = sec(x1)
    assert sec.differences == 1 and sec.updates == 1
    np.testing.assert_allclose(J1 @ (x1 - x0), lin(x1) - lin(x0), rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(J1, J0, atol=1e-9)             # A Δx = Δr: a linear model's Jacobian stays
    np.testing.assert_allclose(J1, A, rtol=1e-6, atol=1e-6)


def test_a_rejected_step_or_the_limit_of_updates_refreshes_by_differences():
    sec = _Secant(_residuals, _fd(_residuals), max_updates=2)
    xs = [np.array([1.0, 0.5, 0.0]) + 0.01 * k for k in range(5)]
    sec.residuals(xs[0]); sec(xs[0])
    sec.residuals(xs[1]); sec(xs[1])                          # update 1
    sec.residuals(xs[2]); sec(xs[2])                          # update 2
    sec.residuals(xs[3]); sec(xs[3])                          # the limit: differences
    assert sec.differences == 2
    sec.residuals(xs[3] + 1.0)                                # a trial rejected ...
    sec.residuals(xs[4]); J = sec(xs[4])                      # ... then one accepted: differences
    assert sec.differences == 3
    np.testing.assert_array_equal(J, _fd(_residuals)(xs[4]))


def test_least_squares_with_updates_reaches_the_finite_difference_optimum_with_fewer_jacobians():
    ref = _run(_residuals, _fd(_residuals))
    sec = _Secant(_residuals, _fd(_residuals), max_updates=3)
    res = _run(sec.residuals, _Jacobian(sec, 1e-10))
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-4)          # both ended by a tolerance test
    assert abs(res.cost - ref.cost) <= 1e-9 * ref.cost
    assert sec.differences < ref.njev
    # the updated Jacobian at the end stays close to differences there (smooth model)
    np.testing.assert_allclose(sec.J, _fd(_residuals)(sec.x), rtol=0.05, atol=0.05)


def test_only_the_candidates_fold_fits_get_the_secant_option(monkeypatch):
    """``run_folds(cause_kw=...)`` adds its options to the candidates' and pairs' fold fits, never to the
    baseline's (whose fits and held-out errors stay those of differences at every accepted point)."""
    from notchfit.analysis.diagnosis import crossval
    from notchfit.analysis.diagnosis.specs import StudyScales

    seen = []

    class Stop(Exception):
        pass

    def fake_batch(func, tasks, **kw):
        seen.extend(tasks)
        raise Stop

    monkeypatch.setattr(crossval, "run_batch", fake_batch)
    folds = crossval.folds_by_experiment(3)
    try:
        crossval.run_folds((object(),) * 3, folds, [None, "external_load", ("external_load", "stiffness_gradient")],
                           calibrate_kw={"ftol": 1e-3}, scales=StudyScales(), cause_kw={"secant": 3})
    except Stop:
        pass
    kws = {t.cause: t.calibrate_kw for t in seen}
    assert kws[()] == {"ftol": 1e-3}
    assert kws[("external_load",)] == kws[("external_load", "stiffness_gradient")] == {"ftol": 1e-3, "secant": 3}


def test_a_step_the_jacobian_described_poorly_is_followed_by_differences():
    """Across a kink (the slope 1 becomes 3 at 0.6) the accepted step lowers the cost by 0.36 of the 1.0 the
    Jacobian predicted: with ``ratio`` 0.75 no update, differences at the new point."""
    kink = lambda x: np.maximum(x, 3.0 * x - 1.2) - 1.0                         # noqa: E731
    fd = lambda x: approx_derivative(kink, x, method="2-point", rel_step=1e-6)    # noqa: E731
    for ratio, differences in ((0.0, 1), (0.75, 2)):
        sec = _Secant(kink, fd, max_updates=3, ratio=ratio)
        x0, x1 = np.array([0.0, 0.0]), np.array([1.0, 0.0])
        sec.residuals(x0); sec(x0)
        sec.residuals(x1); J = sec(x1)
        assert sec.differences == differences
        if differences == 2:
            np.testing.assert_allclose(J, np.diag([3.0, 1.0]), atol=1e-5)
