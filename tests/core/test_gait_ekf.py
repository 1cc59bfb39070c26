"""core.gait.ekf: information-form EKF (eqs. 17-22) against the literal D x D form."""

import dataclasses
import math
import re

import numpy as np
import pytest
from scipy.stats import gmean, multivariate_normal

from core.gait.ekf import FilterResult, _update, ekf_filter, ekf_predict, ekf_update, \
    make_context, observation_jacobian, observation_mean
from core.gait.model import FPS_RANGE
from core.gait.online import OnlineConfig
from tests.core.gait_online_reference import ref_update
from tests.gait_data import observations, small_model

A = np.array([[1.0, 0.0], [1.0, 1.0]])
# A process noise with off-diagonal terms (the learned models' Q is diagonal at their own rate).
Q_FULL = np.array([[1e-6, 3e-5], [3e-5, 1e-3]])


@pytest.fixture
def ctx():
    # Built per test (cheap): a module-scoped context would be built inside the first test only,
    # and mutation testing (make mutate) would then run only that test against FilterContext.
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
    x1, p1 = ekf_predict(x, p, Q_FULL)
    np.testing.assert_allclose(p1, A @ p @ A.T + Q_FULL, rtol=1e-14)


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


@pytest.mark.parametrize("full_q", [False, True])
def test_filter_equals_sequential_steps(ctx, full_q):
    if full_q:
        ctx = dataclasses.replace(ctx, Q=Q_FULL)
    w = small_model().styles[3]
    ys = observations("35_02")[:25] / ctx.scale
    x0, p0 = np.array([0.09, 0.5]), np.diag([1e-5, 0.05])
    res = ekf_filter(ctx, ys, w, x0, p0)
    x, p = x0, p0
    total = 0.0
    for t, y in enumerate(ys):
        if t:
            x, p = ekf_predict(x, p, ctx.Q)
        innovation = y - observation_mean(ctx, x[1], w)   # mean squared innovation per channel
        np.testing.assert_allclose(res.innovation_sq[t], np.mean(innovation**2), rtol=1e-10)
        x, p, loglik = ekf_update(ctx, x, p, y, w)
        total += loglik
        np.testing.assert_allclose(res.states[t], x, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(res.covariances[t], p, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(res.loglik, total, rtol=1e-12)
    np.testing.assert_array_equal(res.outliers, -1)


def test_an_unobserved_frame_is_the_update_with_every_channel_dropped(ctx):
    """A frame with no channel observed (NaN everywhere: a sparsely keyed range's
    frames between its keys) skips the kernel's products in ``ekf_filter``; every output is
    still the one the full update (``_update``, every channel dropped) gives, bit for bit,
    beside observed, partly observed and outlier frames, and the loop's own time update."""
    w = small_model().styles[3]
    ys = observations("35_02")[:40] / ctx.scale
    keyed = np.zeros(len(ys), dtype=bool)
    keyed[::9] = True                                   # frames 0, 9, 18, 27, 36 observed
    ys[~keyed] = np.nan
    ys[18, :10] = np.nan                                # partly observed
    ys[27, 40] += 20.0                                  # an outlier channel
    x0, p0 = np.array([0.09, 0.5]), np.diag([1e-5, 0.05])
    res = ekf_filter(ctx, ys, w, x0, p0)
    comb = ctx.combine(w)
    q00, q01, q11 = ctx.q_floats
    omega, phi = float(x0[0]), float(x0[1])
    a, b, c = float(p0[0, 0]), float(p0[0, 1]), float(p0[1, 1])
    total, rows, outliers = 0.0, [], []
    for t in range(len(ys)):
        if t:
            phi = phi + omega
            a, b, c = a + q00, a + b + q01, a + 2 * b + c + q11
        omega, phi, a, b, c, loglik, ee, count, outlier = _update(ctx, omega, phi, a, b, c,
                                                                  ys[t], comb)
        total += loglik
        rows.append((omega, phi, a, b, c, ee / max(count, 1)))
        outliers.append(outlier)
    rows = np.array(rows)
    np.testing.assert_array_equal(res.states, rows[:, :2])
    np.testing.assert_array_equal(res.covariances, rows[:, [2, 3, 3, 4]].reshape(-1, 2, 2))
    np.testing.assert_array_equal(res.innovation_sq, rows[:, 5])
    np.testing.assert_array_equal(res.outliers, outliers)
    assert res.loglik == total
    assert outliers[27] == 40 and np.all(res.innovation_sq[~keyed] == 0.0)
    assert np.all(np.diff(res.covariances[1:9, 1, 1]) > 0)  # unobserved: uncertainty grows


def test_extra_weights_add_to_the_style_weights(ctx):
    """``extra_weights`` enter the observation mean as ``k(φ)ᵀ E``: since ``Σ_j w_j α_j`` is
    linear in w, style w with ``E = combine(w2 - w)`` is the filter of style w2."""
    model = small_model()
    w, w2 = model.styles[0], model.styles[2]
    ys = observations("35_01")[:20] / ctx.scale
    x0, p0 = np.array([0.09, 0.5]), np.diag([1e-5, 0.05])
    a = ekf_filter(ctx, ys, w, x0, p0, extra_weights=ctx.combine(w2 - w))
    b = ekf_filter(ctx, ys, w2, x0, p0)
    plain = ekf_filter(ctx, ys, w, x0, p0)
    np.testing.assert_allclose(a.states, b.states, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.loglik, b.loglik, rtol=1e-9)
    assert not np.allclose(a.states, plain.states, rtol=1e-6)


def test_innovation_sq_counts_only_the_observed_channels(ctx):
    w = small_model().styles[1]
    ys = np.array(observations("35_01")[:3] / ctx.scale)
    ys[1, :10] = np.nan
    x0, p0 = np.array([0.09, 0.5]), np.diag([1e-5, 0.05])
    res = ekf_filter(ctx, ys, w, x0, p0)
    x_pred = ekf_predict(res.states[0], res.covariances[0], ctx.Q)[0]
    innovation = ys[1] - observation_mean(ctx, x_pred[1], w)
    np.testing.assert_allclose(res.innovation_sq[1], np.nanmean(innovation**2), rtol=1e-10)
    one = make_context(small_model(), channels=["lfemur.rx"])        # one channel: e² itself
    y = observations("35_01")[:1, :1] / one.scale
    res = ekf_filter(one, y, w, x0, p0)
    np.testing.assert_allclose(res.innovation_sq[0],
                               (y[0, 0] - observation_mean(one, x0[1], w)[0])**2, rtol=1e-10)


def test_posture_offset_row_is_added_to_the_mean(ctx):
    """GP weights with the walker's offset b as one more row (the online filter's layout) give
    the update of ``y - b`` with the plain weights: the mean is ``μ(φ) w + b``."""
    model = small_model()
    w = model.styles[2]
    y = np.asarray(observations("35_17")[50] / ctx.scale)
    b = np.linspace(-0.2, 0.3, ctx.n_channels)
    comb = ctx.combine(w)
    with_offset = _update(ctx, 0.09, 2.0, 1e-5, 0.0, 0.05, y, np.vstack([comb, b]))
    shifted = _update(ctx, 0.09, 2.0, 1e-5, 0.0, 0.05, y - b, comb)
    np.testing.assert_allclose(with_offset, shifted, rtol=1e-10, atol=1e-14)


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


def test_the_scratch_arrays_compute_what_fresh_arrays_did(ctx):
    """``_update`` writes the kernel pair and its products into arrays cached on the context:
    the same operations as the plain form (the reference's `ref_update` given the same kernel
    pair), so every output equals the plain form's bit for
    bit, for the style weights (P rows) and with the offset row (P + 1), alternating the two
    layouts, with a missing and an outlier channel, and the scratch's contents never leak into
    the next update."""
    model = small_model()
    y0 = observations("35_05")[40] / ctx.scale
    plain = ctx.combine(model.styles[2])
    with_offset = np.vstack([plain, np.full(plain.shape[1], 0.01)])
    rng = np.random.default_rng(3)
    missing = y0.copy()
    missing[5] = np.nan
    glitch = ctx.kernel_pair(2.0)[0] @ plain + 0.02     # close to the model at φ = 2 ...
    glitch[40] += 0.95 * np.pi                          # ... but one channel half a turn off
    left_out = set()
    for phi, y, comb in [(0.3, y0, plain), (2.0, y0, with_offset), (4.1, missing, plain),
                         (2.0, glitch, plain), (1.1, y0 + 0.01 * rng.normal(size=len(y0)),
                                                      plain), (2.0, glitch, with_offset)]:
        a, b, c = 1e-4, 2e-5, 0.04
        out = _update(ctx, 0.09, phi, a, b, c, y, comb)
        pair = ctx.kernel_pair(phi) if len(comb) == ctx.n_phases else ctx.kernel_pair_one(phi)
        assert out == ref_update(ctx, 0.09, phi, a, b, c, y, comb, pair=pair)
        left_out.add(out[8] >= 0)
    assert left_out == {True, False}


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


def test_context_holds_the_model_quantities_at_the_filter_rate():
    """Every precomputed quantity against its definition (module symbol table) at a frame rate
    other than the model's (30 fps: k = 2 model frames per filter frame) and a channel subset."""
    model = small_model()
    keep = list(model.channel_names[1::3])
    index = model.channel_index(keep)
    ctx = make_context(model, fps=30.0, channels=keep)
    assert ctx.fps == 30.0 and ctx.n_channels == len(keep)
    np.testing.assert_array_equal(ctx.channels, index)
    np.testing.assert_array_equal(ctx.scale, model.channel_scale[index])
    np.testing.assert_array_equal(ctx.rate_mask, model.rate_mask[index])
    assert ctx.rate_mask.any() and not ctx.rate_mask.all()
    np.testing.assert_array_equal(ctx.is_angle, model.is_angle[index])
    np.testing.assert_array_equal(ctx.turns, np.where(model.is_angle[index], 2 * np.pi, 0.0))
    assert ctx.is_angle.any() and not ctx.is_angle.all()
    # ω in radians per 30 fps frame: twice the model's per 60 fps frame
    lag_min, lag_max = model.lag_range
    np.testing.assert_allclose([ctx.omega_min, ctx.omega_max],
                               [2 * np.pi / (lag_max * 30.0), 2 * np.pi / (lag_min * 30.0)],
                               rtol=1e-15)
    np.testing.assert_allclose(ctx.omega_train, 2 * model.training_omegas(), rtol=1e-15)
    np.testing.assert_allclose(ctx.omega_mean, gmean(ctx.omega_train), rtol=1e-12)
    # Q of a random walk sampled every k = 2 model frames: diag(q_ω k³, q_φ k) (+ k² off-diagonal)
    np.testing.assert_allclose(ctx.Q, model.Q * [[8.0, 4.0], [4.0, 2.0]], rtol=1e-15)
    assert ctx.q_floats == (ctx.Q[0, 0], ctx.Q[0, 1], ctx.Q[1, 1])
    full = dataclasses.replace(ctx, Q=Q_FULL)
    assert full.q_floats == (1e-6, 3e-5, 1e-3)
    # style prior: precision of the training-style covariance widened 4 times, symmetric
    np.testing.assert_allclose(ctx.w_prec, np.linalg.inv(4.0 * model.style_cov), rtol=1e-10)
    np.testing.assert_array_equal(ctx.w_prec, ctx.w_prec.T)
    np.testing.assert_allclose(make_context(model, style_prior_scale=0.5).w_prec,
                               np.linalg.inv(0.5 * model.style_cov), rtol=1e-10)
    np.testing.assert_array_equal(ctx.w_mean, model.style_mean)
    np.testing.assert_allclose(ctx.w_prior_term, ctx.w_prec @ model.style_mean, rtol=1e-12)
    np.testing.assert_array_equal(ctx.w_prior_aug,
                                  np.column_stack([ctx.w_prec, ctx.w_prior_term]))


def test_context_means_are_the_gp_means():
    model = small_model()
    keep = list(model.channel_names[::4])
    ctx = make_context(model, channels=keep)
    phis = np.array([0.0, 0.7, 3.1, 5.9])
    ref = model.gp.mean(phis)[:, :, model.channel_index(keep)]
    np.testing.assert_allclose(ctx.means(phis), ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(ctx.means(0.7)[0], ref[1], rtol=1e-10,
                               atol=1e-12 * np.abs(ref).max())
    k = model.gp.kernel(phis)
    np.testing.assert_allclose(ctx.kernel_rows(phis), k, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(ctx.kernel_rows(phis[1:2]), k[1:2], rtol=1e-12, atol=1e-18)


def test_kernels_with_the_constant_column(ctx):
    """``kernel_pair_one`` / ``kernel_rows_one``: the kernels with one more column that is 1 in
    k and 0 in ∂k/∂φ."""
    gp = small_model().gp
    phis = np.array([0.4, 2.2, 4.8])
    k, dk = gp._k(phis)[:2]
    for i, phi in enumerate(phis):
        pair = ctx.kernel_pair_one(phi)
        assert pair.shape == (2, ctx.n_phases + 1)
        np.testing.assert_allclose(pair[0, :-1], k[i], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(pair[1, :-1], dk[i], rtol=1e-10,
                                   atol=1e-14 * np.abs(dk).max())
        assert pair[0, -1] == 1.0 and pair[1, -1] == 0.0
    rows = ctx.kernel_rows_one(phis)
    assert rows.shape == (3, ctx.n_phases + 1)
    np.testing.assert_allclose(rows[:, :-1], k, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(rows[:, -1], 1.0)


def test_cached_steps_decay_and_frames(ctx):
    steps = ctx.steps(5)
    np.testing.assert_array_equal(steps, [1.0, 2.0, 3.0, 4.0, 5.0])
    assert ctx.steps(5) is steps and not steps.flags.writeable
    assert ctx.steps(3).tolist() == [1.0, 2.0, 3.0]
    decay = ctx.decay(4, 0.5)
    np.testing.assert_allclose(decay[:, 0], np.exp(-np.arange(1, 5) / (0.5 * 60.0)), rtol=1e-15)
    assert decay.shape == (4, 1) and ctx.decay(4, 0.5) is decay and not decay.flags.writeable
    np.testing.assert_allclose(ctx.decay(2, 0.25)[:, 0], np.exp(-np.arange(1, 3) / 15.0),
                               rtol=1e-15)
    config = OnlineConfig(acquire_s=0.5, relock_s=0.1)
    assert ctx.online_frames(config) == (30, 6)
    assert ctx.online_frames(config) is ctx.online_frames(config)
    assert ctx.online_frames(OnlineConfig(acquire_s=0.25, relock_s=0.2)) == (15, 12)
    assert ctx.online_frames(config) == (30, 6)


def test_context_arguments_at_and_beyond_their_bounds():
    model = small_model()
    for fps in FPS_RANGE:                                   # the bounds themselves are allowed
        assert make_context(model, fps=fps).fps == fps
    bounds = f"between {FPS_RANGE[0]:g} and {FPS_RANGE[1]:g}"
    for fps in (FPS_RANGE[0] * 0.999, FPS_RANGE[1] * 1.001):
        with pytest.raises(ValueError, match=re.escape(bounds)):
            make_context(model, fps=fps)
    for bad in (0.0, -1.0):
        with pytest.raises(ValueError, match="style_prior_scale must be positive"):
            make_context(model, style_prior_scale=bad)
    make_context(model, outlier_ratio=0.5)                  # any positive ratio
    with pytest.raises(ValueError, match="^at least one channel must be observed$"):
        make_context(model, channels=[])
    one = make_context(model, channels=["lfemur.rx"])
    assert one.n_channels == 1


def test_posture_offset_prior():
    """The offset prior's precision is 1 / the between-walker variance; a channel without spread
    gets 1 / (1e-12 · the largest variance) (held at 0); no prior without offset or spread."""
    model = small_model()
    assert model.has_offset
    ctx = make_context(model)
    floor = 1e-12 * model.offset_var.max()        # (some channels have no spread at all)
    np.testing.assert_allclose(ctx.offset_prec, 1.0 / np.maximum(model.offset_var, floor),
                               rtol=1e-15)
    assert make_context(model, offset=False).offset_prec is None
    var = np.full(model.n_channels, 0.25)
    var[3] = 0.0
    spread = dataclasses.replace(model, offset_var=var)
    prec = make_context(spread).offset_prec
    np.testing.assert_allclose(prec[3], 1.0 / (0.25e-12), rtol=1e-12)
    np.testing.assert_allclose(np.delete(prec, 3), 4.0, rtol=1e-15)
    still = dataclasses.replace(model, offset_var=np.zeros(model.n_channels))
    assert make_context(still).offset_prec is None


def _outlier_of(ctx, y, w, x_pred=(0.09, 2.0), p_pred=(1e-5, 0.0, 0.05)):
    return _update(ctx, *x_pred, *p_pred, np.asarray(y, dtype=float), ctx.combine(w))[8]


def test_outlier_gate_edges():
    """The outlier test runs only for a large innovation (eᵀe > gate · n r) on more than one
    channel: a small deviation in one channel is used, a single channel is never left out, and
    two channels are enough."""
    model = small_model()
    w = model.styles[2]
    ctx = make_context(model, channels=list(model.channel_names[:32]))   # n = 32, a power of 2
    mean = ctx.kernel_pair(2.0)[0] @ ctx.combine(w)
    small = mean.copy()
    small[5] += math.sqrt(0.5 * ctx.n_channels * ctx.r)          # eᵀe ≈ n r / 2 < gate · n r
    assert _outlier_of(ctx, small, w) == -1
    big = mean.copy()
    big[5] += math.sqrt(4.0 * ctx.n_channels * ctx.r)
    assert _outlier_of(ctx, big, w) == 5
    # exactly at the gate (eᵀe = gate · n r; n r exact for n a power of 2): not beyond it
    off = dataclasses.replace(ctx, outlier_gate=np.inf)         # eᵀe of all 32 channels
    ee = _update(off, 0.09, 2.0, 1e-5, 0.0, 0.05, big, ctx.combine(w))[6]
    at_gate = dataclasses.replace(ctx, r=ee / ctx.n_channels)
    assert at_gate.outlier_gate * ctx.n_channels * at_gate.r == ee
    assert _outlier_of(at_gate, big, w) == -1
    single = make_context(model, channels=["lfemur.rx"])
    y = single.kernel_pair(2.0)[0] @ single.combine(w) + 10.0
    assert _outlier_of(single, y, w) == -1
    two = make_context(model, channels=["lfemur.rx", "rfemur.rx"])
    y = two.kernel_pair(2.0)[0] @ two.combine(w) + [0.0, 10.0]
    assert _outlier_of(two, y, w) == 1


def test_masked_sets_the_outlier_entries_missing():
    ys = np.arange(12.0).reshape(4, 3)
    res = FilterResult(states=None, covariances=None, loglik=0.0, innovation_sq=None,
                       outliers=np.array([0, -1, 2, -1]))
    masked = res.masked(ys)
    expected = ys.copy()
    expected[0, 0] = expected[2, 2] = np.nan
    np.testing.assert_array_equal(masked, expected)
    assert not np.isnan(ys).any()                            # the input is not changed
    clean = FilterResult(states=None, covariances=None, loglik=0.0, innovation_sq=None,
                         outliers=np.full(4, -1))
    assert clean.masked(ys) is ys
