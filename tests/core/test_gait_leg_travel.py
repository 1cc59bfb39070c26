"""core.gait.leg_travel (issue 19 §2): the adapted style conditioned on the reference's legs'
travel, so that the planted prediction walks as far per cycle as the reference's legs did."""

import numpy as np
import pytest

from core.gait import adapt, observations_from_dofs
from core.gait.ekf import make_context
from core.gait.em import scaled_observations
from core.gait import leg_travel
from core.gait.leg_travel import (FLOOR_PERCENTILE, MIN_STANDING, _legs_speeds, fit_leg_travel, legs_speed,
                                  reference_legs_speed, robust_spread, style_legs_speed,
                                  style_precision, styles_legs_speeds)
from core.gait.planting import (CONTACT_BAND, foot_floors, legs_velocities, relative_feet,
                                standing_share)
from core.gait.root_travel import RootFrame
from core.gait.prediction import dofs_from_observations, predict, predict_styles
from core.gait.walk import WalkRequest, predict_walk
from tests.gait_data import adapted_walk

FPS = 60.0
N_REF = 100                 # 1.67 s observed (the bench's longest window)


@pytest.fixture(scope="module")
def walker():
    return adapted_walk("35_01", N_REF, FPS)


def test_the_legs_speed_of_a_captured_walk_is_its_root_speed(walker):
    """The measure itself, against the capture's own root: over a whole cycle the root travels
    as far as the legs carry it (the captured balls roll a few cm/s forward while they carry,
    docs/gait.md: within 8 %)."""
    model, skeleton, values, names, _, res = walker
    n = int(round(2 * np.pi / res.state[0]))
    tx, ty = names.index("root.tx"), names.index("root.ty")
    for end in (N_REF, N_REF + 37, len(values)):
        rows = values[end - n - 1:end]
        root = np.hypot(*(rows[-1, [tx, ty]] - rows[0, [tx, ty]])) * FPS / n
        for observed in (False, True):
            assert legs_speed(skeleton, rows, FPS, n, observed=observed) == pytest.approx(
                root, rel=0.08)


def test_style_precision_is_the_hessian_of_the_m_step_objective_with_the_offset_minimised(
        walker):
    """``P`` = ½ ∇² of ``min_b Σ ||y − μ w − b||² / r + (w − w̄)ᵀΛ(w − w̄) + bᵀΛ_b b`` (em.py's
    M-step objective at the filtered phases), by central differences of the objective with
    ``b`` minimised numerically per channel (it is quadratic: differences are exact up to
    rounding)."""
    model, _, _, _, obs, res = walker
    ctx = make_context(model, FPS)
    ys = scaled_observations(ctx, obs)
    mu = ctx.means(res.states[:, 1])                       # (N, J, D)

    def objective(w):
        e = ys - np.einsum("njd,j->nd", mu, w)
        lam = ctx.offset_prec
        b = e.sum(axis=0) / ctx.r / (len(e) / ctx.r + lam)  # argmin over b, per channel
        for _ in range(2):                                  # …checked by Newton steps on b
            grad = -2 * (e - b).sum(axis=0) / ctx.r + 2 * lam * b
            b = b - grad / (2 * len(e) / ctx.r + 2 * lam)
        d = w - ctx.w_mean
        return float(((e - b) ** 2).sum() / ctx.r + d @ ctx.w_prec @ d + b @ (lam * b))

    w0, h = res.w, 0.5
    hess = np.zeros((len(w0), len(w0)))
    eye = np.eye(len(w0)) * h
    for i in range(len(w0)):
        for j in range(i, len(w0)):
            hess[i, j] = hess[j, i] = (objective(w0 + eye[i] + eye[j])
                                       - objective(w0 + eye[i] - eye[j])
                                       - objective(w0 - eye[i] + eye[j])
                                       + objective(w0 - eye[i] - eye[j])) / (4 * h * h)
    p = style_precision(model, obs, res)
    np.testing.assert_allclose(p, 0.5 * hess, rtol=1e-6, atol=1e-6 * np.abs(p).max())


def test_the_fitted_style_s_legs_travel_as_far_as_the_reference_s_by_the_smallest_change(
        walker):
    model, skeleton, values, names, obs, res = walker
    ref = values[:N_REF]
    fit = fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual, speed_sd=0.0)
    n = int(round(2 * np.pi / res.state[0]))
    assert fit.changed
    speeds = [legs_speed(skeleton, ref[:end], FPS, n, root_frame=model.root_frame,
                         observed=True)
              for end in range(n + 1, N_REF + 1)]
    assert fit.reference_speed == np.mean(speeds)

    def speed(w):
        return style_legs_speed(model, skeleton, ref[-1], FPS, res.state[0], w, res.residual,
                                res.offset)

    assert fit.speed_before == speed(res.w) and fit.speed_after == speed(fit.w)
    assert abs(fit.speed_after - fit.reference_speed) < 1e-3
    # The step is along P⁻¹ ∇s (∇s by central differences of its own): the least change in the
    # posterior's metric; the plain gradient step to the same speed costs more.
    step = 1e-2
    grad = np.array([(speed(res.w + e) - speed(res.w - e)) / (2 * step)
                     for e in np.eye(len(res.w)) * step])
    p = style_precision(model, obs, res)
    direction = np.linalg.solve(p, grad)
    dw = fit.w - res.w
    assert abs(dw @ direction) / np.linalg.norm(dw) / np.linalg.norm(direction) > 1 - 1e-9
    plain = res.w + grad * (fit.reference_speed - fit.speed_before) / (grad @ grad)
    assert dw @ p @ dw < (plain - res.w) @ p @ (plain - res.w)
    # The planted prediction then travels at that speed over its whole cycles after the join.
    walk = predict_walk(model, skeleton, ref, FPS, res.state, fit.w, 4 * n, WalkRequest(),
                        offset=res.offset, residual=res.residual, start=res.last_observation)
    tx, ty = names.index("root.tx"), names.index("root.ty")
    rows = walk.dofs[-3 * n - 1:]
    travelled = np.hypot(*(rows[-1, [tx, ty]] - rows[0, [tx, ty]])) * FPS / (3 * n)
    assert travelled == pytest.approx(fit.reference_speed, rel=0.03)


def test_a_reference_shorter_than_a_cycle_keeps_the_adapted_style(walker):
    model, skeleton, values, names, _, _ = walker
    short = values[:40]                                    # 0.67 s: less than a cycle
    obs = observations_from_dofs(model, short, names, FPS)
    res = adapt(model, obs, fps=FPS)
    assert 2 * np.pi / res.state[0] > 40
    fit = fit_leg_travel(model, skeleton, short, FPS, obs, res, res.residual)
    assert not fit.changed and fit.w is not None and fit.w.tobytes() == res.w.tobytes()
    assert fit.reference_speed is None


def test_a_walk_on_the_spot_keeps_the_adapted_style(walker):
    """A reference whose legs do not carry it anywhere (the captured walk's legs walked on the
    spot: its root is carried with the stance foot) gives no travel to match."""
    model, skeleton, values, names, _, _ = walker
    ref = values[:N_REF].copy()
    obs = observations_from_dofs(model, ref, names, FPS)
    res = adapt(model, obs, fps=FPS)
    # The legs held still (every frame the first frame's angles): nothing carries the root.
    still = ref.copy()
    still[:, 6:] = ref[0, 6:]
    fit = fit_leg_travel(model, skeleton, still, FPS, obs, res, res.residual)
    assert not fit.changed and fit.w.tobytes() == res.w.tobytes()
    assert fit.reference_speed is not None and fit.reference_speed < 0.1


def test_by_default_the_style_moves_by_the_kalman_gain_of_the_reference_s_own_spread(walker):
    """σ = the spread of the reference's one-cycle legs' speeds (``robust_spread``): the step is
    the gain's share gᵀP⁻¹g / (gᵀP⁻¹g + σ²) of the constrained one, along the same direction."""
    model, skeleton, values, names, obs, res = walker
    ref = values[:N_REF]
    n = int(round(2 * np.pi / res.state[0]))
    mean, spread = reference_legs_speed(skeleton, ref, FPS, n, root_frame=model.root_frame)
    speeds = [legs_speed(skeleton, ref[:end], FPS, n, root_frame=model.root_frame,
                         observed=True)
              for end in range(n + 1, N_REF + 1)]
    assert len(speeds) == N_REF - n and spread == robust_spread(speeds) and 0 < spread < 0.05
    assert mean == np.mean(speeds)
    hard = fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual, speed_sd=0.0)
    soft = fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual)
    assert soft.w.tobytes() == fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual,
                                              speed_sd=spread).w.tobytes()
    # the gain, from the linearisation: Δs = gᵀΔw for both steps
    step = 1e-2

    def speed(w):
        return style_legs_speed(model, skeleton, ref[-1], FPS, res.state[0], w, res.residual,
                                res.offset)

    grad = np.array([(speed(res.w + e) - speed(res.w - e)) / (2 * step)
                     for e in np.eye(len(res.w)) * step])
    along = grad @ np.linalg.solve(style_precision(model, obs, res), grad)
    gain = along / (along + spread**2)
    assert 0 < gain < 1
    assert soft.speed_after - soft.speed_before == pytest.approx(
        gain * (soft.reference_speed - soft.speed_before), abs=1e-4)
    d_soft, d_hard = soft.w - res.w, hard.w - res.w
    assert d_soft @ d_hard / np.linalg.norm(d_soft) / np.linalg.norm(d_hard) > 1 - 1e-9


def test_the_spread_is_the_median_absolute_deviation_as_a_normal_standard_deviation():
    """``robust_spread``: the median of the absolute deviations from the median, times
    1/Φ⁻¹(3/4); a slip shared by a minority of the windows does not widen it (docs/gait_rigs.md,
    *Stop 40*), where the standard deviation measures the slip."""
    steps = np.array([-3.0, -1.0, 0.0, 1.0, 3.0]) * 0.01
    assert robust_spread(1.1 + steps) == pytest.approx(0.01 / 0.6744897501960817, rel=1e-12)
    rng = np.random.default_rng(19)
    assert robust_spread(rng.normal(1.1, 0.02, 200_000)) == pytest.approx(0.02, rel=0.01)
    steady = 1.1 + np.linspace(-0.004, 0.004, 11)
    slipped = steady + np.where(np.arange(11) >= 7, 0.08, 0.0)     # 4 of 11 windows
    assert np.std(slipped) > 5 * np.std(steady)
    assert robust_spread(slipped) < 2 * robust_spread(steady) + 1e-12


def test_the_reference_s_windows_are_each_window_s_legs_speed(walker):
    """:func:`reference_legs_speed` does the legs' forward kinematics once for the whole
    reference: each window's speed is :func:`legs_speed` of that window alone (a row's feet
    depend on the row only), so the mean and spread are the per-window ones."""
    model, skeleton, values, _, _, res = walker
    n = int(round(2 * np.pi / res.state[0]))
    ref = values[:N_REF]
    speeds = [legs_speed(skeleton, ref[:end], FPS, n, root_frame=model.root_frame,
                         observed=True)
              for end in range(n + 1, N_REF + 1)]
    assert len(speeds) > 10
    mean, spread = reference_legs_speed(skeleton, ref, FPS, n, root_frame=model.root_frame)
    assert mean == np.mean(speeds)                                  # batched windows: bit for bit
    assert spread == robust_spread(speeds)


def test_many_styles_at_once_are_each_style_alone_and_the_plain_prediction_s(walker):
    """styles_legs_speeds (the gradient's 2J + 1 styles' cycles at once: one GP mean, one
    forward kinematics, the root integrations and the speeds batched): each style's speed is,
    bit for bit, legs_speed of its cycle predicted the plain way (predict, then
    dofs_from_observations), and predict_styles' frames are predict's."""
    model, skeleton, values, names, _, res = walker
    ref = values[:N_REF]
    omega = float(res.state[0])
    n = int(round(2 * np.pi / omega))
    styles = res.w + np.random.default_rng(7).normal(scale=0.5, size=(4, len(res.w)))
    for residual in (None, res.residual):
        batch = styles_legs_speeds(model, skeleton, ref[-1], FPS, omega, styles, residual,
                                   res.offset)
        frames = predict_styles(model, [omega, 0.0], styles, n + 1, residual=residual,
                                offset=res.offset)
        cols = [names.index(c) for c in model.dof_names]
        for w, speed, cycle in zip(styles, batch, frames):
            plain = predict(model, [omega, 0.0], w, n + 1, residual=residual, offset=res.offset)
            assert cycle.tobytes() == plain.tobytes()
            rows = np.tile(ref[-1], (n + 1, 1))
            rows[:, cols] = dofs_from_observations(model, plain, ref[-1, cols], FPS)
            assert speed == legs_speed(skeleton, rows, FPS, n, root_frame=model.root_frame)


def _tracked_walk(right_lower, cycle=36, cycles=3, fps=30.0, skim=0.0):
    """A synthetic walk as tracking leaves it: the root at 0.95-1.45 m/s along +X (the speed
    oscillating twice a cycle), each ball (contact point) still in the world over its stance
    (60 % of the cycle, the feet half a cycle apart), swinging to its next spot 0.3 m ahead
    of the root's landing position over a 6 cm arc; the right foot's whole track stands
    ``right_lower`` metres under the left's. ``skim``: the last share of each swing goes on at
    the stance's height (a tracked foot down before it has stopped). Returns the feet relative to the root (N, 2, 3),
    the root DOFs (N, 6), the stance masks (N, 2) and the root's X."""
    n = cycle * cycles + 1
    t = np.arange(n, dtype=float)
    speed = 1.2 + 0.25 * np.cos(4 * np.pi * t / cycle)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) / fps)])

    def x_at(frame):                       # before frame 0 the root went at 1.2 m/s
        return float(np.interp(frame, t, x)) if frame >= 0 else x[0] + 1.2 * frame / fps

    feet, stances = np.zeros((n, 2, 3)), np.zeros((n, 2), dtype=bool)
    for f, (offset, side, base) in enumerate(((0.0, 0.1, 0.0), (0.5, -0.1, -right_lower))):
        for i in range(n):
            k = np.floor(t[i] / cycle + offset)
            p = t[i] / cycle + offset - k
            land = (k - offset) * cycle
            spot = x_at(land) + 0.3
            if p < 0.6:
                feet[i, f] = spot, side, base
                stances[i, f] = True
            else:
                s = (p - 0.6) / 0.4
                ease = s ** 3 * (10 - 15 * s + 6 * s * s)
                nxt = x_at(land + cycle) + 0.3
                arc = 0.06 * np.sin(np.pi * min(s / (1.0 - skim), 1.0))
                feet[i, f] = spot + (nxt - spot) * ease, side, base + arc
    root = np.zeros((n, 6))
    root[:, 0], root[:, 2] = x, 0.9
    return feet - root[:, None, :3], root, stances, x


def test_a_centimetre_between_the_two_feet_s_stances_does_not_change_the_legs_speed():
    """Stop 42 (docs/gait.md, *contact per foot*): a tracked walk's two stances never stand at
    one height (a keyless stance locked under the keys' floor: lock41 measured the metarig's
    legs' speed 1.074 -> 1.006 m/s from that alone). Each foot is read against its own floor
    (its ``FLOOR_PERCENTILE``-th percentile over the cycle window): the reading of a walk
    whose right foot stands 1.5 cm under the left is the level walk's, and both are the
    root's own travel (the stance ball is still in the world). One floor for both feet (the
    lower foot's percentile, main before stop 42) read the 1.5 cm walk 0.8 % slower."""
    fps, cycle = 30.0, 36
    frame = RootFrame(rest=np.eye(3), forward_axis=0)
    windows = np.arange(2 * cycle + 1)[:, None] + np.arange(cycle + 1)    # one cycle each
    level, lowered = (_tracked_walk(d, cycle, fps=fps) for d in (0.0, 0.015))
    rel, root, stances, x = lowered
    true = (x[windows[:, -1]] - x[windows[:, 0]]) * fps / cycle
    speeds = [_legs_speeds(r[windows], q[windows], fps, frame, observed=True)
              for r, q, _, _ in (level, lowered)]
    np.testing.assert_allclose(speeds[1], speeds[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(speeds[1], true, rtol=0.005)
    # Each stance frame is read on the floor (its own), the swing's high frames are not.
    w = windows[0]
    floors = foot_floors(rel[w][..., 2], root[w, 2], FLOOR_PERCENTILE)
    assert floors[0] - floors[1] == pytest.approx(0.015, abs=1e-9)
    _, _, above = legs_velocities(rel[w], root[w, 2], floors, fps, per_foot=True,
                                  root_velocity=np.diff(root[w, :2], axis=0) * fps)
    both = stances[w][1:] & stances[w][:-1]
    assert (above[both] < 1e-9).all()
    assert (above[~(stances[w][1:] | stances[w][:-1])] > CONTACT_BAND).any()


def test_a_foot_down_before_it_has_stopped_does_not_carry_an_observed_walk():
    """Stop 42: the tracked Rigify FK walk's left foot came down to its floor while still
    moving forward at about 1 m/s; read against its own floor it took the weight a frame early
    and the legs' speed fell 1.104 -> 1.055 m/s. An observed walk's foot carries only while it
    moves over the ground (the root at its own velocity) slower than ``SWING_SPEED``: with the
    last fifth of every swing skimming the floor the reading is still the root's travel, and
    without the root's velocity (the feet judged by their height alone) it is not."""
    fps, cycle = 30.0, 36
    frame = RootFrame(rest=np.eye(3), forward_axis=0)
    windows = np.arange(2 * cycle + 1)[:, None] + np.arange(cycle + 1)
    rel, root, stances, x = _tracked_walk(0.015, cycle, fps=fps, skim=0.2)
    true = (x[windows[:, -1]] - x[windows[:, 0]]) * fps / cycle
    np.testing.assert_allclose(_legs_speeds(rel[windows], root[windows], fps, frame,
                                            observed=True), true, rtol=0.005)
    w = windows[0]
    floors = foot_floors(rel[w][..., 2], root[w, 2], FLOOR_PERCENTILE)
    ahead = np.tile([1.0, 0.0], (cycle, 1))
    by_height, _, _ = legs_velocities(rel[w], root[w, 2], floors, fps, ahead, per_foot=True)
    assert abs(by_height[:, 0].mean() - true[0]) > 0.01


def _keyed(rows, step):
    """``rows`` keyed every ``step`` rows and interpolated between the keys by cubic Hermite
    curves with Catmull-Rom tangents (the keys' central differences, one-sided at the ends):
    like Blender's Bézier keys with automatic handles, a smooth curve through the keys."""
    keys = np.asarray(rows)[::step]
    tangents = np.gradient(keys, axis=0)
    s = (np.arange(step) / step)[:, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, 3 * s**2 - 2 * s**3, s**3 - s**2
    pieces = [h00 * keys[i] + h10 * tangents[i] + h01 * keys[i + 1] + h11 * tangents[i + 1]
              for i in range(len(keys) - 1)]
    return np.concatenate(pieces + [keys[-1:]])


def test_a_walk_whose_feet_never_stand_is_read_with_one_floor(walker, monkeypatch):
    """Stop 42, *keys only* (docs/gait.md): Predict from a walk's four keys with Blender's
    interpolation between them has feet that slide through every stance; read per foot (a
    foot moving over the ground does not carry) the bench's keys-only metarig read 1.366 m/s
    for a root at 1.19 and predicted 36.4 cm (21.1 with one floor). The captured walk's feet
    stand (within ``CONTACT_BAND`` of their floor, slower than ``STAND_SPEED`` over the
    ground) in about half its steps, its interpolation from keys every 0.5 s (the bench's
    spacing) in almost none: the interpolation is read with one floor, as a style's cycle,
    the capture per foot."""
    model, skeleton, values, names, _, res = walker
    n = int(round(2 * np.pi / res.state[0]))
    root = [names.index(c) for c in ("root.tx", "root.ty", "root.tz")]
    step = int(FPS / 2)

    def share(rows):
        rel, z = relative_feet(skeleton, rows), rows[:, root[2]]
        return standing_share(rel, z, foot_floors(rel[..., 2], z, FLOOR_PERCENTILE), FPS,
                              np.diff(rows[:, root[:2]], axis=0) * FPS)

    for start in (0, 10, 37):
        captured = values[start:start + 3 * step + 1]
        keyed = _keyed(captured, step)
        assert keyed.shape == captured.shape
        np.testing.assert_array_equal(keyed[::step], captured[::step])
        assert share(keyed[-(n + 1):]) < MIN_STANDING / 2
        assert share(captured[-(n + 1):]) > 2 * MIN_STANDING
        one = legs_speed(skeleton, keyed, FPS, n)
        assert legs_speed(skeleton, keyed, FPS, n, observed=True) == one
        per_foot = legs_speed(skeleton, captured, FPS, n, observed=True)
        monkeypatch.setattr(leg_travel, "MIN_STANDING", 0.0)    # every window per foot
        assert legs_speed(skeleton, captured, FPS, n, observed=True) == per_foot
        assert legs_speed(skeleton, keyed, FPS, n, observed=True) != one
        monkeypatch.undo()
