"""core.gait.ekf: information-form EKF (eqs. 17-22) against the literal D x D form."""

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from core.gait.ekf import ekf_filter, ekf_predict, ekf_update, make_context, \
    observation_jacobian, observation_mean
from tests.gait_data import observations, small_model

A = np.array([[1.0, 0.0], [1.0, 1.0]])


@pytest.fixture(scope="module")
def ctx():
    return make_context(small_model())


def _literal_update(ctx, x_pred, p_pred, y, w):
    """Eqs. 19-22 as printed: K = P Hᵀ (H P Hᵀ + R)⁻¹ with the D x D inverse."""
    h = observation_jacobian(ctx, x_pred, w)
    s = h @ p_pred @ h.T + ctx.r * np.eye(len(y))
    gain = p_pred @ h.T @ np.linalg.inv(s)
    innov = y - observation_mean(ctx, x_pred[1], w)
    x = x_pred + gain @ innov
    p = (np.eye(2) - gain @ h) @ p_pred
    return x, p, multivariate_normal(np.zeros(len(y)), s).logpdf(innov)


def test_predict_is_eq17_18(ctx):
    x = np.array([0.1, 6.2])
    p = np.array([[1e-4, 2e-5], [2e-5, 3e-2]])
    x1, p1 = ekf_predict(x, p, ctx.Q)
    np.testing.assert_allclose(x1, A @ x, rtol=1e-15)
    np.testing.assert_allclose(p1, A @ p @ A.T + ctx.Q, rtol=1e-14)


def test_information_form_equals_literal_update(ctx):
    model = small_model()
    y = observations("35_05")[40] / ctx.scale
    for w, x_pred, p_pred in [
        (model.styles[2], np.array([0.095, 1.0]), np.diag([1e-4, 0.04])),
        (model.style_mean, np.array([0.1, 4.0]), np.array([[4e-5, 1e-4], [1e-4, 0.3]])),
    ]:
        x, p, loglik = ekf_update(ctx, x_pred, p_pred, y, w)
        x_ref, p_ref, loglik_ref = _literal_update(ctx, x_pred, p_pred, y, w)
        assert ctx.omega_min < x_ref[0] < ctx.omega_max        # no clipping in these cases
        np.testing.assert_allclose(x[0], x_ref[0], rtol=1e-9)
        np.testing.assert_allclose(x[1], x_ref[1] % (2 * np.pi), rtol=1e-9)
        np.testing.assert_allclose(p, p_ref, rtol=1e-8, atol=1e-15)
        np.testing.assert_allclose(loglik, loglik_ref, rtol=1e-9)


def test_jacobian_matches_finite_differences(ctx):
    w = small_model().styles[0]
    for phi in (0.2, 2.9, 5.5):
        h = observation_jacobian(ctx, [0.1, phi], w)
        eps = 1e-3  # five-point stencil: truncation O(eps⁴), rounding well below it

        def f(d):
            return observation_mean(ctx, phi + d * eps, w)

        fd = (f(-2) - 8 * f(-1) + 8 * f(1) - f(2)) / (12 * eps)
        np.testing.assert_allclose(h[:, 1], fd, atol=1e-8 * np.abs(fd).max())
        np.testing.assert_array_equal(h[:, 0], 0.0)              # μ does not depend on ω


def test_fast_kernel_rows_equal_the_gp_kernel(ctx):
    """The filters' precomputed-weight kernels (one small product per phase) equal eq. 11 and its
    φ-derivative as the GP evaluates them."""
    gp = small_model().gp
    phis = np.array([0.0, 0.3, 2.9, 5.5, 7.1, -1.2])
    k, dk = gp._k(phis)[:2]
    for i, phi in enumerate(phis):
        pair = ctx.kernel_pair(phi)
        np.testing.assert_allclose(pair[0], k[i], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(pair[1], dk[i], rtol=1e-10, atol=1e-14 * np.abs(dk).max())
        np.testing.assert_allclose(ctx.kernel_value(phi), k[i], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(ctx.kernel_rows(phis), k, rtol=1e-12, atol=1e-18)


def test_filter_equals_sequential_steps(ctx):
    w = small_model().styles[3]
    ys = observations("35_02")[:25] / ctx.scale
    x0, p0 = np.array([0.09, 0.5]), np.diag([1e-5, 0.05])
    res = ekf_filter(ctx, ys, w, x0, p0)
    x, p = x0, p0
    total = 0.0
    for t, y in enumerate(ys):
        if t:
            x, p = ekf_predict(x, p, ctx.Q)
        x, p, loglik = ekf_update(ctx, x, p, y, w)
        total += loglik
        np.testing.assert_allclose(res.states[t], x, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(res.covariances[t], p, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(res.loglik, total, rtol=1e-12)


def test_missing_channels_equal_a_channel_subset():
    model = small_model()
    full = make_context(model)
    keep = [n for n in model.channel_names if not n.startswith("root.")]
    sub = make_context(model, channels=keep)
    y = observations("35_01")[30] / full.scale
    y_missing = y.copy()
    y_missing[56:] = np.nan
    x_pred, p_pred = np.array([0.09, 2.0]), np.diag([1e-5, 0.05])
    a = ekf_update(full, x_pred, p_pred, y_missing, model.styles[2])
    b = ekf_update(sub, x_pred, p_pred, y[:56], model.styles[2])
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, rtol=1e-12)


def test_an_outlier_channel_is_left_out_like_a_missing_one(ctx):
    """A glitch in one channel (half a turn, like CMU 08_01's rthumb.rz) dominates a large
    innovation: the update equals the one with that channel missing. A large innovation spread
    over all channels (a real change of motion) is used as it is."""
    model = small_model()
    w = model.styles[2]
    x_pred, p_pred = np.array([0.09, 2.0]), np.diag([1e-5, 0.05])
    y = ctx.kernel_pair(2.0)[0] @ ctx.combine(w) + 0.02      # close to the model
    glitch, missing = y.copy(), y.copy()
    glitch[40] += 0.95 * np.pi
    missing[40] = np.nan
    for u, v in zip(ekf_update(ctx, x_pred, p_pred, glitch, w),
                    ekf_update(ctx, x_pred, p_pred, missing, w)):
        np.testing.assert_allclose(u, v, rtol=1e-12)
    off = make_context(model, outlier_ratio=np.inf)                  # test disabled
    assert not np.allclose(ekf_update(off, x_pred, p_pred, glitch, w)[0],
                           ekf_update(off, x_pred, p_pred, missing, w)[0], rtol=1e-6)
    spread = y + 0.3                                                # every channel far off
    for u, v in zip(ekf_update(ctx, x_pred, p_pred, spread, w),
                    ekf_update(off, x_pred, p_pred, spread, w)):
        np.testing.assert_array_equal(u, v)
    # Together with a missing channel; the filter reports frame and channel.
    both = glitch.copy()
    both[3] = np.nan
    ref = missing.copy()
    ref[3] = np.nan
    for u, v in zip(ekf_update(ctx, x_pred, p_pred, both, w),
                    ekf_update(ctx, x_pred, p_pred, ref, w)):
        np.testing.assert_allclose(u, v, rtol=1e-12)
    ys = np.vstack([y, both, y])
    res = ekf_filter(ctx, ys, w, x_pred, p_pred)
    np.testing.assert_array_equal(res.outliers, [-1, 40, -1])
    masked = res.masked(ys)
    assert np.isnan(masked[1, 40]) and np.isnan(masked[1, 3])
    np.testing.assert_array_equal(np.isnan(masked).sum(), 2)
    with pytest.raises(ValueError, match="outlier_ratio"):
        make_context(model, outlier_ratio=0.0)


def test_outputs_stay_defined_for_wild_observations(ctx):
    w = small_model().styles[0]
    x, p, loglik = ekf_update(ctx, [0.1, 1.0], np.diag([1e-3, 1.0]), np.full(63, 1e6), w)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(p)) and np.isfinite(loglik)
    assert ctx.omega_min <= x[0] <= ctx.omega_max and 0 <= x[1] < 2 * np.pi


def test_context_errors():
    model = small_model()
    with pytest.raises(ValueError, match="unknown channels"):
        make_context(model, channels=["lfemur.rx", "wing.rz"])
    with pytest.raises(ValueError, match="fps"):
        make_context(model, fps=0.0)
