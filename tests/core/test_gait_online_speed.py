"""core.gait.online: the optimised online step computes what the plain formulation does.

The online step (E-step, online M-step, 0.5 s forecast) is tuned for per-call overhead (fused
products, cached constants, fewer NumPy calls; docs/gait.md *Speed*). These tests run it next to
``tests/core/gait_online_reference.py`` — the step as it was before the tuning, with every kernel
and GP mean evaluated the plain way from the GP (Matsubara eqs. 11-12) — on streams that visit
every branch (acquisition, locked tracking, a walk → run re-acquisition, missing channels, a
glitch channel, a model without posture offset) and require the same states and forecasts.
Timings are a benchmark's business (``make bench-gait``, ``speed`` in build/bench/gait.json).
"""

import numpy as np
import pytest

from core.gait import OnlineConfig, online_forecast, online_init, online_step
from core.gait.ekf import make_context
from tests.core.gait_online_reference import ref_online_forecast, ref_online_step
from tests.gait_data import observations, small_model

RTOL = 1e-10


def _stream():
    """Walk → run → walk with missing channels and a glitch channel (physical units)."""
    walk, run = observations("35_06"), observations("35_18")
    stream = np.vstack([walk[:100], run[:70], walk[200:260]]).copy()
    stream[120:126, 56:60] = np.nan                     # root channels missing for a while
    stream[140, 40] += 0.95 * np.pi                      # one channel half a turn off
    return stream


def _assert_same_state(fast, ref, t):
    assert fast.locked == ref.locked and fast.relocks == ref.relocks, t
    assert (fast.frames, fast.window, fast.cooldown) == (ref.frames, ref.window, ref.cooldown), t
    for name in ("x", "P", "w", "stats", "eta", "comb", "level", "baseline", "b"):
        a, b = np.asarray(getattr(fast, name)), np.asarray(getattr(ref, name))
        np.testing.assert_allclose(a, b, rtol=RTOL, atol=RTOL * max(np.abs(b).max(), 1e-300),
                                   err_msg=f"{name} at frame {t}")
    np.testing.assert_allclose(fast.recent_nu, ref.recent_nu, rtol=RTOL, atol=1e-300)
    if ref.s_aug is None:
        assert fast.s_aug is None
    else:
        np.testing.assert_allclose(fast.s_aug, ref.s_aug, rtol=RTOL,
                                   atol=RTOL * np.abs(ref.s_aug).max())


@pytest.mark.parametrize("offset", [True, False])
def test_optimised_step_equals_the_reference_formulation(offset):
    model = small_model()
    ctx = make_context(model, offset=offset)
    assert (ctx.offset_prec is not None) == offset
    config = OnlineConfig()
    fast = ref = online_init(ctx, config)
    saw = {"acquiring": 0, "locked": 0, "missing": 0}
    for t, y in enumerate(_stream() / ctx.scale):
        fast = online_step(ctx, config, fast, y)
        ref = ref_online_step(ctx, config, ref, y)
        _assert_same_state(fast, ref, t)
        saw["locked" if fast.locked else "acquiring"] += 1
        saw["missing"] += bool(np.isnan(y).any()) and fast.locked
        if t % 5 == 0 or t > 160:
            for kw in ({}, {"omega_scale": 1.3}, {"blend_s": 0.0}):
                expected = ref_online_forecast(ctx, ref, 30, **kw)
                np.testing.assert_allclose(online_forecast(ctx, fast, 30, **kw), expected,
                                           rtol=RTOL, atol=RTOL * np.abs(expected).max(),
                                           err_msg=f"forecast {kw} at frame {t}")
    # The stream went through every branch: acquisition, tracking, re-acquisition, gaps.
    assert fast.relocks >= 1 and saw["acquiring"] > 0 and saw["locked"] > 150
    assert saw["missing"] > 0


def test_small_solve_equals_numpy_and_raises_on_a_singular_system():
    """The M-step's J × J solve of the packed ``[A | b]`` gives np.linalg.solve's answer on
    the split system and raises on a singular one."""
    from core.gait import online

    rng = np.random.default_rng(3)
    a = rng.standard_normal((5, 5))
    system = np.column_stack([a @ a.T + np.eye(5), rng.standard_normal(5)])
    expected = np.linalg.solve(system[:, :5], system[:, 5])
    np.testing.assert_array_equal(online._solve(system), expected)
    np.testing.assert_allclose(system[:, :5] @ online._solve(system), system[:, 5], atol=1e-12)
    singular = system.copy()
    singular[:, :5] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        online._solve(singular)


def test_the_m_step_s_solver_gives_np_linalg_solve_s_bits_and_its_errors(monkeypatch):
    """The online M-step calls NumPy's LAPACK gufunc directly (stop 40): the same bits as
    ``np.linalg.solve`` on the systems it solves (symmetric positive definite, 4 and 13
    styles), NaN where the system holds NaN, and ``LinAlgError`` on a singular system, with no
    warning on the way (pytest.ini makes a RuntimeWarning from core an error); without the
    gufunc, ``np.linalg.solve``."""
    from core.gait import online
    rng = np.random.default_rng(3)
    for n in (4, 13):
        for _ in range(50):
            m = rng.standard_normal((n, 3 * n))
            lhs = np.column_stack([m @ m.T + 0.1 * np.eye(n), rng.standard_normal(n)])
            want = np.linalg.solve(lhs[:, :n], lhs[:, n])
            assert online._solve(lhs).tobytes() == want.tobytes()
    lhs[1, 2] = np.nan
    assert np.isnan(online._solve(lhs)).any()
    singular = np.zeros((4, 5))
    with pytest.raises(np.linalg.LinAlgError):
        online._solve(singular)
    monkeypatch.setattr(online, "_SOLVE1", None)
    with pytest.raises(np.linalg.LinAlgError):
        online._solve(singular)
    lhs[1, 2] = 0.5
    assert online._solve(lhs).tobytes() == np.linalg.solve(lhs[:, :13], lhs[:, 13]).tobytes()


def test_the_m_step_s_kernel_row_is_the_context_s():
    """The online M-step's kernel row, written into cached arrays (stop 40), equals
    ``kernel_value`` bit for bit, call after call."""
    from core.gait.online import _kernel_value
    ctx = make_context(small_model())
    for phi in np.linspace(-1.0, 8.0, 37):
        assert _kernel_value(ctx, float(phi)).tobytes() == ctx.kernel_value(float(phi)).tobytes()
