"""core.gait.optimize: the NumPy L-BFGS against scipy.optimize and exact solutions."""

import numpy as np
import pytest
from scipy.optimize import minimize, rosen, rosen_der

from core.gait.optimize import minimize_lbfgs


@pytest.mark.parametrize("n", [2, 10])
def test_rosenbrock_matches_scipy(n):
    x0 = np.full(n, -1.2)
    x0[1::2] = 1.0
    ours = minimize_lbfgs(lambda x: (rosen(x), rosen_der(x)), x0, max_iter=2000, gtol=1e-9,
                          ftol=0.0)
    ref = minimize(lambda x: (rosen(x), rosen_der(x)), x0, jac=True, method="L-BFGS-B",
                   options=dict(maxiter=2000, gtol=1e-9, ftol=0.0))
    assert ours.success, ours.message
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(ours.x, np.ones(n), atol=1e-6)
    assert ours.fun <= ref.fun + 1e-10


def test_convex_quadratic_reaches_linear_solve():
    rng = np.random.default_rng(0)
    m = rng.normal(size=(30, 30))
    a = m @ m.T + 30 * np.eye(30)
    b = rng.normal(size=30)
    res = minimize_lbfgs(lambda x: (0.5 * x @ a @ x - b @ x, a @ x - b), np.zeros(30),
                         gtol=1e-10, ftol=0.0)
    np.testing.assert_allclose(res.x, np.linalg.solve(a, b), rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(res.jac, a @ res.x - b, atol=1e-9)


def test_non_finite_start_raises():
    with pytest.raises(ValueError, match="not finite"):
        minimize_lbfgs(lambda x: (np.nan, x), np.zeros(3))


def test_rejects_non_finite_trial_points():
    # log barrier: infinite outside x > 0; the search must stay inside and converge to 1.
    def fun(x):
        if x[0] <= 0:
            return np.inf, np.array([np.nan])
        return x[0] - np.log(x[0]), np.array([1.0 - 1.0 / x[0]])

    res = minimize_lbfgs(fun, [5.0], gtol=1e-10)
    assert np.isfinite(res.fun)
    np.testing.assert_allclose(res.x, [1.0], atol=1e-6)
