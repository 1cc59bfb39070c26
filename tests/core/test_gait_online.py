"""core.gait.online: online EM (eqs. 14-16, 24-27), class vs pure functions, re-acquisition."""

import numpy as np
import pytest

from core.gait import OnlineConfig, OnlineEM, estimate_period, online_forecast, online_init, \
    online_step, predict
from core.gait.ekf import ekf_predict, ekf_update, make_context
from tests.gait_data import observations, small_model


def test_class_equals_pure_functions():
    model = small_model()
    obs = observations("35_05")[:60]
    online = OnlineEM(model)
    ctx = make_context(model)
    config = OnlineConfig()
    state = online_init(ctx, config)
    for y in obs:
        online.step(y)
        state = online_step(ctx, config, state, y / ctx.scale)
        for a, b in zip(online.state, state):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(online.predict(30), online_forecast(ctx, state, 30))


def _run(model, obs, config=None):
    ctx = make_context(model)
    config = config or OnlineConfig()
    states = [online_init(ctx, config)]
    for y in obs:
        states.append(online_step(ctx, config, states[-1], y / ctx.scale))
    return ctx, config, states


def test_locked_step_is_ekf_plus_online_m_step():
    model = small_model()
    obs = observations("35_05")[:40]
    ctx, config, states = _run(model, obs)
    prev, new = states[30], states[31]
    assert prev.locked and new.locked and new.relocks == prev.relocks
    y = obs[30] / ctx.scale
    x_pred, p_pred = ekf_predict(prev.x, prev.P, ctx.Q)                   # eqs. 17-18
    x, p, _ = ekf_update(ctx, x_pred, p_pred, y - prev.b, prev.w)         # eqs. 19-22 on y - b
    np.testing.assert_allclose(new.x, x, rtol=1e-12)
    np.testing.assert_allclose(new.P, p, rtol=1e-12)
    eta = 1.0 / (1.0 + config.forgetting / prev.eta)                     # eq. 27
    mu = ctx.means(np.array([x[1]]))[0]                                   # μ(x̂_t), eq. 29
    s_mm = (1 - eta) * prev.s_mm + eta * mu @ mu.T                        # eq. 25
    s_my = (1 - eta) * prev.s_my + eta * mu @ y                           # eq. 26
    s_m = (1 - eta) * prev.s_m + eta * mu                                 # ⟪μ⟫
    s_y = (1 - eta) * prev.s_y + eta * y                                  # ⟪y⟫
    # eq. 24 + priors with the posture offset: the full (J + Dc) normal equations.
    j, d = model.n_bases, ctx.n_channels
    ridge = eta * ctx.r
    lhs = np.block([[s_mm + ridge * ctx.w_prec, s_m],
                    [s_m.T, np.diag(1.0 + ridge * ctx.offset_prec)]])
    sol = np.linalg.solve(lhs, np.concatenate([s_my + ridge * ctx.w_prec @ ctx.w_mean, s_y]))
    np.testing.assert_allclose(new.eta, eta, rtol=1e-14)
    np.testing.assert_allclose(new.s_mm, s_mm, rtol=1e-12)
    np.testing.assert_allclose(new.s_my, s_my, rtol=1e-12)
    np.testing.assert_allclose(new.s_m, s_m, rtol=1e-12)
    np.testing.assert_allclose(new.w, sol[:j], rtol=1e-9)
    np.testing.assert_allclose(new.b, sol[j:j + d], rtol=1e-8, atol=1e-12)


def test_discounted_average_is_eq14():
    """⟪f⟫_T = η_T Σ_t (Π_{s>t} λ) f_t with η_T = 1/Σ_t Π_{s>t} λ (eq. 14) for the frames after
    locking, whose start statistics count as a plain average of the acquisition window."""
    model = small_model()
    obs = observations("35_05")[:60]
    ctx, config, states = _run(model, obs)
    lock = next(i for i, s in enumerate(states) if s.locked)
    lam = config.forgetting
    start = states[lock]
    n0 = round(1.0 / start.eta)                     # acquisition frames averaged (λ = 1)
    weights = [lam ** (len(states) - 1 - t) for t in range(lock + 1, len(states))]
    total = sum(weights) + n0 * lam ** (len(states) - 1 - lock)
    f_sum = start.s_my * n0 * lam ** (len(states) - 1 - lock)
    for t, wt in zip(range(lock + 1, len(states)), weights):
        mu = ctx.means(np.array([states[t].x[1]]))[0]
        f_sum = f_sum + wt * mu @ (obs[t - 1] / ctx.scale)
    np.testing.assert_allclose(states[-1].eta, 1.0 / total, rtol=1e-12)
    np.testing.assert_allclose(states[-1].s_my, f_sum / total, rtol=1e-10)


def test_online_tracks_a_cmu_walk():
    model = small_model()
    obs = observations("35_06")
    online = OnlineEM(model)
    for y in obs[:90]:
        online.step(y)
    period = estimate_period(obs[:, :56], 60.0)
    np.testing.assert_allclose(online.omega, 2 * np.pi / period, rtol=0.05)
    # The online forecast is the §3.3 prediction from the current state, style and offset,
    # continuing from the last frame.
    kw = dict(offset=online.state.b, start=obs[89], fps=60.0)
    np.testing.assert_allclose(online.predict(30), predict(model, online.state.x, online.w, 30,
                                                           **kw), rtol=1e-10, atol=1e-12)
    retimed = online.predict(30, omega_scale=1.2)
    np.testing.assert_allclose(retimed, predict(model, online.state.x, online.w, 30, 1.2, **kw),
                               rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(online.predict(30, blend_s=0.0),
                               predict(model, online.state.x, online.w, 30, offset=kw["offset"]),
                               rtol=1e-10, atol=1e-12)


def test_relocks_when_the_walker_starts_running():
    model = small_model()
    walk, run = observations("35_06")[:120], observations("35_18")
    online = OnlineEM(model)
    for y in walk:
        online.step(y)
    assert online.state.relocks == 0
    for y in run[:40]:
        online.step(y)
    assert online.state.relocks >= 1
    period = estimate_period(run[:, :56], 60.0)
    np.testing.assert_allclose(online.omega, 2 * np.pi / period, rtol=0.1)


def test_missing_values_and_errors():
    model = small_model()
    obs = observations("35_05")[:40].copy()
    obs[::3, 56:60] = np.nan
    online = OnlineEM(model, config=OnlineConfig(forgetting=0.95))
    for y in obs:
        state = online.step(y)
        for name in ("x", "P", "w", "s_mm", "s_my", "eta", "comb", "recent_nu", "level"):
            assert np.all(np.isfinite(getattr(state, name))), name
    assert np.all(np.isfinite(online.predict(30)))
    with pytest.raises(ValueError, match=r"shape \(63,\)"):
        online.step(obs[0, :50])
    with pytest.raises(ValueError, match="finite"):
        online.step(np.full(63, np.inf))
    with pytest.raises(ValueError, match="forgetting"):
        OnlineConfig(forgetting=1.5)
    with pytest.raises(ValueError, match="omega_scale"):
        online.predict(10, omega_scale=0.0)
    online.reset()
    assert online.state.frames == 0 and not online.state.locked


def test_trigger_level_and_baseline_average():
    config = OnlineConfig()
    assert config.trigger(10.0) == config.relock_threshold                # absolute cap
    assert config.trigger(0.01) == config.relock_floor                    # floor
    assert config.trigger(1.0) == pytest.approx(config.relock_ratio)      # relative
    assert OnlineConfig(relock_ratio=np.inf).trigger(0.01) == config.relock_threshold
    with pytest.raises(ValueError, match="baseline_rate"):
        OnlineConfig(baseline_rate=1.5)
    with pytest.raises(ValueError, match="relock_min_frames"):
        OnlineConfig(relock_min_frames=1.5)
    # The baseline is the slow average of ν over the locked frames, starting at 1.
    model = small_model()
    ctx, config, states = _run(model, observations("35_06")[:80])
    lock = next(i for i, s in enumerate(states) if s.locked)
    assert states[lock].baseline == 1.0
    base = 1.0
    for s in states[lock + 1:]:
        base += config.baseline_rate * (s.recent_nu[-1] - base)
        assert s.baseline == pytest.approx(base, rel=1e-12)


def test_relative_trigger_catches_a_phase_jump_the_absolute_level_misses():
    """Two pieces of one walk spliced with a jump of 30 frames (about half a cycle): the innovation
    rises far above the walker's baseline but stays under the absolute level."""
    model = small_model()
    obs = observations("35_06")
    spliced = np.vstack([obs[:90], obs[120:]])
    for config, caught in ((OnlineConfig(), True), (OnlineConfig(relock_ratio=np.inf), False)):
        online = OnlineEM(model, config=config)
        for y in spliced[:90]:
            online.step(y)
        assert online.state.relocks == 0
        for y in spliced[90:100]:
            online.step(y)
        assert (online.state.relocks > 0) == caught
    # After re-acquisition the phase follows the second piece: the forecast matches it.
    online = OnlineEM(model)
    for y in spliced[:130]:
        online.step(y)
    plain = OnlineEM(model, config=OnlineConfig(relock_ratio=np.inf))
    for y in spliced[:130]:
        plain.step(y)
    truth = spliced[130:160, :56]
    err = np.sqrt(np.mean((online.predict(30)[:, :56] - truth) ** 2))
    err_plain = np.sqrt(np.mean((plain.predict(30)[:, :56] - truth) ** 2))
    assert err < 0.5 * err_plain


def test_a_single_outlier_frame_does_not_start_re_acquisition():
    """One frame above the trigger waits for a second (no grid attempt, no cooldown); two
    consecutive ones are scored."""
    model = small_model()
    obs = observations("35_06")
    online = OnlineEM(model)
    for y in obs[:90]:
        online.step(y)
    bad = obs[90:92].copy()
    bad[:, :56] += 0.5
    state = online.step(bad[0])
    assert state.level > OnlineConfig().trigger(state.baseline)
    assert state.cooldown == 0 and state.relocks == 0
    state = online.step(bad[1])
    assert state.cooldown > 0 or state.relocks == 1
    # Scoring from the first frame (relock_min_frames=0) tries at once and then cools down.
    eager = OnlineEM(model, config=OnlineConfig(relock_min_frames=0))
    for y in obs[:90]:
        eager.step(y)
    state = eager.step(bad[0])
    assert state.cooldown > 0 or state.relocks == 1


def test_a_glitch_channel_is_skipped_by_the_e_and_m_steps():
    """While tracking, a frame with one channel half a turn off updates the filter exactly like
    the frame with that channel missing, and does not start re-acquisition."""
    model = small_model()
    obs = observations("35_06")
    online = OnlineEM(model)
    for y in obs[:90]:
        online.step(y)
    ctx, config, state = online.context, online.config, online.state
    glitch, missing = obs[90].copy(), obs[90].copy()
    glitch[40] += 0.95 * np.pi
    missing[40] = np.nan
    a = online_step(ctx, config, state, glitch / ctx.scale)
    b = online_step(ctx, config, state, missing / ctx.scale)
    for name in ("x", "P", "w", "s_mm", "s_my", "eta", "level", "baseline"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12)
    assert a.cooldown == 0 and a.relocks == 0
