"""core.gait.keyed (stop 43, issue 19 §2): a walk keyed at a few frames is observed at its keys
only (the frames between missing), and its travel is the keyed root's."""

import numpy as np
import pytest

from core.gait import adapt, observations_from_dofs
from core.gait.ekf import ekf_filter, make_context
from core.gait.em import scaled_observations
from core.gait.initial_phase import _score_one, grid_search, phase_tables
from core.gait.keyed import (SPARSE_KEY_GAP_S, keyed_observations, keyed_root_speed,
                             sparsely_keyed)
from core.gait.leg_travel import reference_legs_speed
from tests.core.test_gait_leg_travel import _keyed
from tests.gait_data import adapted_walk, observations, small_model

FPS = 60.0
STEP = 30                   # keys every 0.5 s: the bench's keys-only spacing (about half a cycle)
STARTS = (0, 10, 37)        # where the keyed piece of CMU 35_01 begins (frames at 60 fps)


@pytest.fixture(scope="module")
def walker():
    return adapted_walk("35_01", 100, FPS)


def _pieces(walker):
    """Per start: the captured piece (3 · STEP + 1 rows), Blender-like interpolation of its
    keys every STEP rows, the keyed mask."""
    _, _, values, _, _, _ = walker
    for start in STARTS:
        captured = values[start:start + 3 * STEP + 1]
        keyed = np.zeros(len(captured), dtype=bool)
        keyed[::STEP] = True
        yield captured, _keyed(captured, STEP), keyed


def _phase_gap(a, b):
    return abs((a - b + np.pi) % (2 * np.pi) - np.pi)


def test_a_walk_observed_at_four_keys_adapts_to_the_walkers_cadence_and_phase(walker):
    """Four keys 0.5 s apart of a captured walk, adapted on the keys only: the cadence within
    5 % and the last frame's phase within 0.25 rad of the adaptation to the whole capture
    (measured: 0.978-1.002, 0.02-0.11 rad). Every frame of the keys' interpolation read as
    observed (main before stop 43) misses both on one of the pieces (0.86 and 1.04 rad) and
    the phase on another (0.51 rad)."""
    model, _, _, names, _, _ = walker
    misses = 0
    for captured, interpolated, keyed in _pieces(walker):
        truth = adapt(model, observations_from_dofs(model, captured, names, FPS), fps=FPS)
        obs = observations_from_dofs(model, interpolated, names, FPS)
        keys = adapt(model, keyed_observations(obs, keyed), fps=FPS)
        assert abs(keys.state[0] / truth.state[0] - 1.0) < 0.05, (keys.state, truth.state)
        assert _phase_gap(keys.state[1], truth.state[1]) < 0.25, (keys.state, truth.state)
        every = adapt(model, obs, fps=FPS)
        misses += abs(every.state[0] / truth.state[0] - 1.0) >= 0.05
        misses += _phase_gap(every.state[1], truth.state[1]) >= 0.25
    assert misses >= 2


def test_the_keyed_roots_speed_is_the_walkers_and_the_interpolated_legs_are_not(walker):
    """The keyed root's path from key to key over the time is the capture's root speed to 1 %
    (measured 0.1 %); the legs' travel of the interpolation (each window read as a stop 42
    reference) is 15 % or more slow on every piece (0.44-1.03 m/s for a root at 1.26-1.29)."""
    _, skeleton, _, names, _, res = walker
    xy = [names.index("root.tx"), names.index("root.ty")]
    n = int(round(2 * np.pi / res.state[0]))
    for captured, interpolated, keyed in _pieces(walker):
        root = np.linalg.norm(captured[-1, xy] - captured[0, xy]) * FPS / (len(captured) - 1)
        speed, spread = keyed_root_speed(interpolated[:, xy], keyed, FPS)
        assert speed == pytest.approx(root, rel=0.01)
        assert 0.0 <= spread < 0.05 * speed
        legs, _ = reference_legs_speed(skeleton, interpolated, FPS, n)
        assert legs < 0.85 * root, (legs, root)


def test_the_keyed_roots_speed_is_its_path_over_the_keys_time():
    xy = np.array([[0.0, 0.0], [9.0, 9.0], [3.0, 4.0], [7.0, 7.0], [6.0, 8.0]])
    keyed = np.array([True, False, True, False, True])
    speed, spread = keyed_root_speed(xy, keyed, 2.0)
    assert speed == (5.0 + 5.0) / 2.0          # 4 frames at 2 fps
    assert spread == 0.0
    with pytest.raises(ValueError, match="two keyed frames"):
        keyed_root_speed(xy, np.eye(5, dtype=bool)[0], 2.0)


def test_sparse_means_keys_further_apart_than_the_gap_somewhere_in_the_range():
    fps = 30.0
    assert SPARSE_KEY_GAP_S * fps == pytest.approx(3.0)
    for every, sparse in ((1, False), (2, False), (3, False), (4, True), (15, True)):
        keyed = np.zeros(46, dtype=bool)
        keyed[::every] = True
        keyed[-1] = True
        assert sparsely_keyed(keyed, fps) is sparse, every
    dense = np.ones(46, dtype=bool)
    assert not sparsely_keyed(dense, fps)
    dense[20:25] = False                                 # one hole of 0.2 s
    assert sparsely_keyed(dense, fps)
    ends = np.ones(46, dtype=bool)
    ends[-5:] = False                                    # the range runs 0.17 s past the keys
    assert sparsely_keyed(ends, fps)
    assert not sparsely_keyed(np.eye(46, dtype=bool)[3], fps)   # one key: nothing to read
    assert sparsely_keyed(dense, fps, gap_s=0.1) and not sparsely_keyed(dense, fps, gap_s=0.5)


def test_keyed_observations_leave_the_frames_between_missing():
    obs = np.arange(12.0).reshape(4, 3)
    out = keyed_observations(obs, [True, False, False, True])
    np.testing.assert_array_equal(out[[0, 3]], obs[[0, 3]])
    assert np.isnan(out[1:3]).all() and not np.isnan(obs).any()


def test_the_grid_scores_the_observed_frames_at_their_times():
    """A window with unobserved frames (NaN rows) is scored on its observed frames at their
    times: each candidate's cost is the single-candidate score of those rows with their frame
    indices; values in the other rows would change it, and so would the rows packed as
    consecutive frames."""
    model = small_model()
    ctx = make_context(model)
    ys = observations("35_03")[:46] / ctx.scale
    keyed = np.zeros(len(ys), dtype=bool)
    keyed[::15] = True
    grid = grid_search(ctx, np.where(keyed[:, None], ys, np.nan))
    mu, mtm = phase_tables(ctx)
    rows = ys[keyed]
    yy = float(np.sum(rows * rows))
    for i, j in ((3, 2), (11, 7), (20, 17)):
        _, cost, _, _, _ = _score_one(ctx, rows, mu, mtm, grid.omegas[i], grid.phis[j], yy,
                                      times=np.flatnonzero(keyed))
        assert cost == pytest.approx(grid.costs[i, j], rel=1e-9)
    assert grid.phi_last == pytest.approx((grid.phi0 + grid.omega * 45) % (2 * np.pi))
    refined = grid_search(ctx, np.where(keyed[:, None], ys, np.nan), refine=True)
    assert refined.cost <= grid.cost
    other = observations("35_01")[:46] / ctx.scale
    filled = grid_search(ctx, np.where(keyed[:, None], ys, other))
    assert not np.array_equal(filled.costs, grid.costs)
    packed = grid_search(ctx, rows)
    assert not np.array_equal(packed.costs, grid.costs)
    with pytest.raises(ValueError, match="no frame"):
        grid_search(ctx, np.full_like(ys, np.nan))


def test_an_unobserved_frame_is_the_time_update_alone():
    """The EKF across a frame with no observed channel: the state and covariance are the
    time update's (eqs. 17-18), the frame adds nothing to the likelihood."""
    model = small_model()
    ctx = make_context(model)
    ys = scaled_observations(ctx, observations("35_03")[:10])
    holed = ys.copy()
    holed[5] = np.nan
    x0, p0 = np.array([0.1, 1.0]), np.diag([1e-4, 0.1])
    w = model.styles[0]
    full = ekf_filter(ctx, holed, w, x0, p0)
    cut = ekf_filter(ctx, holed[:5], w, x0, p0)
    a = np.array([[1.0, 0.0], [1.0, 1.0]])
    q = np.array([[ctx.q_floats[0], ctx.q_floats[1]], [ctx.q_floats[1], ctx.q_floats[2]]])
    pred = a @ cut.states[4]
    assert full.states[5][0] == pytest.approx(pred[0], rel=1e-12)
    assert full.states[5][1] == pytest.approx(pred[1] % (2 * np.pi), rel=1e-12)
    np.testing.assert_allclose(full.covariances[5], a @ cut.covariances[4] @ a.T + q,
                               rtol=1e-12)
    one = ekf_filter(ctx, holed[:6], w, x0, p0)
    assert one.loglik == cut.loglik


def test_a_reference_speed_given_is_the_one_the_style_s_legs_are_fitted_to(walker):
    """``fit_leg_travel(..., reference_speed=(speed, spread))`` uses the speed given instead of
    the legs' travel of the reference: with a spread of 0 (a constraint) the fitted style's
    legs travel at it, 10 % faster or slower than the capture's own reading."""
    from core.gait.leg_travel import SPEED_TOLERANCE, fit_leg_travel, style_legs_speed
    model, skeleton, values, names, obs, res = walker
    reference = values[:len(obs)]
    plain = fit_leg_travel(model, skeleton, reference, FPS, obs, res)
    for factor in (0.9, 1.1):
        goal = factor * plain.reference_speed
        fit = fit_leg_travel(model, skeleton, reference, FPS, obs, res,
                             reference_speed=(goal, 0.0))
        assert fit.reference_speed == goal and fit.changed
        legs = style_legs_speed(model, skeleton, reference[-1], FPS, float(res.state[0]),
                                fit.w, offset=res.offset)
        assert abs(legs - goal) < 10 * SPEED_TOLERANCE, (legs, goal)
