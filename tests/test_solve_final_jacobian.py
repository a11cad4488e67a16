"""The least-squares runs of the estimation core skip the Jacobian that scipy would compute at the last
accepted point and then discard (its xtol test has already ended the run): same optimum, cost and
counts, bit for bit, with fewer residual evaluations."""
import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

from notchfit.analysis.estimation.solve import _Jacobian


def _residuals(x, calls):
    calls.append(1)
    t = np.linspace(0.0, 1.0, 40)
    return np.r_[x[0] * np.exp(-x[1] * t) + x[2] * t - (2.0 * np.exp(-1.3 * t) + 0.4 * t), 0.1 * (x - 0.5)]


def test_skipping_the_final_jacobian_changes_nothing_but_the_work():
    lo, hi = np.array([0.0, 0.0, -1.0]), np.array([5.0, 5.0, 1.0])
    for xtol in (1e-3, 1e-6):
        ref_calls, calls = [], []
        ref = least_squares(lambda x: _residuals(x, ref_calls), [1.0, 0.5, 0.0], jac="2-point", diff_step=2e-3,
                            bounds=(lo, hi), method="trf", ftol=1e-12, xtol=xtol, gtol=1e-15, x_scale="jac")
        fun = lambda x: _residuals(x, calls)   # noqa: E731
        jac = _Jacobian(lambda x: approx_derivative(fun, x, method="2-point", rel_step=2e-3, f0=fun(x),
                                                    bounds=(lo, hi)), xtol)
        res = least_squares(fun, [1.0, 0.5, 0.0], jac=jac, bounds=(lo, hi), method="trf", ftol=1e-12, xtol=xtol,
                            gtol=1e-15, x_scale="jac")
        assert ref.status in (3, 4)                   # ended by the xtol test
        np.testing.assert_array_equal(res.x, ref.x)
        assert res.cost == ref.cost and res.nfev == ref.nfev and res.status == ref.status
        assert jac.skipped == 1
        # one Jacobian (3 evaluations) less; each Jacobian here re-evaluates f0 (1 evaluation)
        assert len(calls) <= len(ref_calls) - 3 + (ref.njev - 1)
