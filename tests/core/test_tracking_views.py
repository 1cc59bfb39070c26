"""Several cameras in one tracking problem: one camera is today's tracker (frozen results of
main's code), a second view recovers the root's depth, the stacked rows are the derivatives of
every view's image, frame offsets, and the process pool with several views' frames."""

from pathlib import Path

import numpy as np
import pytest

from core.kinematics import exp_so3
from core.tracking import (MotionView, PinholeCamera, Pose, TrackingError, TrackingOptions,
                           TrackingProblem, interpolate_poses, joint_frames_in_camera,
                           sample_silhouette, track_interval, track_keyframes, view_weights)
from core.tracking.jacobians import apply_motion
from core.tracking.motion import (_candidate_points, _depth_columns, _level_template,
                                  _measured_points)
from tests.core.test_tracking_roi import _walker
from tests.core.test_tracking_trajectory import _sequence
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton

#: Results of main's tracker (commit c3f7243, before several cameras) on :func:`_single_view_runs`.
REFERENCE = Path(__file__).parent / "data" / "tracking_single_view_main.npz"
#: The options the frozen results were made with (everything added since switched off).
_FROZEN = TrackingOptions(acceptance=None, robust_loss="clip")
_FIELDS = ("root_translations", "local_rotations", "residuals", "ranks", "n_samples", "errors")


def _single_view_runs(wrap=lambda camera: camera, all_runs=True):
    """One camera: two intervals through ``track_keyframes`` (bidirectional seed), one interval
    with the forward seed and depth estimation, and one in a region of interest (only the first
    unless ``all_runs``). ``wrap`` turns the camera into what the problem is given (the camera,
    or a list of one). Acceptance off and the robust loss of before issue 20 (``'clip'``): the
    frozen results predate both (the blend, ``test_tracking_acceptance*.py``; the M-estimators,
    ``test_tracking_robust.py``)."""
    out = {}
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, wrap(cam))
    keys = [0, 4, 10]
    seq = track_keyframes(problem, frames, keys, roots[keys], local[keys],
                          _FROZEN.replace(max_iterations=2), processes=1)
    out["keys_roots"], out["keys_local"] = seq.root_translations, seq.local_rotations
    for i, r in enumerate(seq.intervals):
        for f in ("residuals", "ranks", "n_samples", "errors"):
            out[f"keys_{i}_{f}"] = getattr(r, f)
        out[f"keys_{i}_kept"] = r.kept_iteration
    if not all_runs:
        return out
    r = track_interval(problem, frames, Pose(roots[0], local[0]), Pose(roots[-1], local[-1]),
                       _FROZEN.replace(max_iterations=2, seed="forward", estimate_depth=True))
    for f in _FIELDS:
        out[f"depth_{f}"] = getattr(r, f)
    out["depth_kept"] = r.kept_iteration
    sk, body, cam, roots, local, frames = _walker(480, 400)
    problem = TrackingProblem(sk, body, wrap(cam))
    r = track_interval(problem, frames, Pose(roots[0], local[0]), Pose(roots[-1], local[-1]),
                       _FROZEN.replace(max_iterations=2))
    for f in _FIELDS:
        out[f"roi_{f}"] = getattr(r, f)
    out["roi_kept"] = r.kept_iteration
    return out


def test_one_camera_gives_main_results():
    """The same trajectories, eq. 4 values, ranks and point counts as main's single-camera
    tracker (frozen results; bit for bit on the machine that froze them, to rounding on any
    other BLAS); a list of one camera is the same problem."""
    ref = np.load(REFERENCE)
    runs = _single_view_runs()
    assert sorted(runs) == sorted(ref.files)
    for name in ref.files:
        if ref[name].dtype.kind in "iub":
            np.testing.assert_array_equal(runs[name], ref[name], err_msg=name)
        else:
            np.testing.assert_allclose(runs[name], ref[name], rtol=1e-9, atol=1e-11,
                                       err_msg=name)
    listed = _single_view_runs(lambda camera: [camera], all_runs=False)
    for name in listed:
        np.testing.assert_array_equal(listed[name], runs[name], err_msg=name)


def side_camera(width=200, height=160, f=420.0):
    """Camera 3 m to the side of the two-arm body (world -X), looking along +X, Z up: its line
    of sight is perpendicular to :func:`front_camera`'s."""
    w2c = np.eye(4)
    w2c[:3, :3] = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]
    w2c[:3, 3] = -w2c[:3, :3] @ np.array([-3.0, 0.0, 1.0])
    return PinholeCamera(fx=f, fy=f * 1.02, cx=(width - 1) / 2 + 3.0, cy=(height - 1) / 2,
                         width=width, height=height, world2camera=w2c)


def _depth_motion(n=10):
    """The two-arm body swinging its arms while it moves 25 cm towards the front camera and
    back (a sine: the keys' linear interpolation misses it), seen from the front and the side."""
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cams = [front_camera(200, 160, f=420.0), side_camera()]
    s = np.linspace(0.0, 1.0, n + 1)
    local = np.broadcast_to(np.eye(3), (n + 1, 5, 3, 3)).copy()
    local[:, 0] = exp_so3(np.stack([0 * s, 0 * s, 0.25 * np.sin(2.0 * s)], 1))
    local[:, 1] = exp_so3(np.stack([0.35 * np.sin(3.0 * s), -0.5 - 0.2 * s, 0 * s], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.4 * s ** 2, 0 * s, 0 * s], 1))
    local[:, 3] = exp_so3(np.stack([0 * s, 0.9 + 0.1 * s, 0.2 * s], 1))
    local[:, 4] = exp_so3(np.stack([0.2 + 0.4 * np.sin(2.5 * s), 0 * s, 0 * s], 1))
    roots = np.stack([0.1 * s, -0.25 * np.sin(np.pi * s), 0.03 * np.sin(3 * s)], 1)
    frames = [render(sk, body, cam, roots, local) for cam in cams]
    return sk, body, cams, roots, local, frames


@pytest.fixture(scope="module")
def depth_scene():
    return _depth_motion()


def test_a_second_view_recovers_the_root_depth(depth_scene):
    """One camera leaves the root's motion along its line of sight to the interpolation (the
    paper's §5.3); with a second camera at right angles the root depth is measured."""
    sk, body, cams, roots, local, frames = depth_scene
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    options = TrackingOptions(max_iterations=2)
    axis = cams[0].rotation[2]                          # the front camera's line of sight (world)

    def depth_error(cameras, stacks):
        res = track_interval(TrackingProblem(sk, body, cameras), stacks, start, end, options)
        assert not res.diverged
        return np.abs((res.root_translations - roots) @ axis)[1:-1].mean(), res

    one, res_one = depth_error(cams[0], frames[0])
    two, res_two = depth_error(cams, frames)
    interp = np.abs((interpolate_poses(sk, start, end, 10)[0] - roots) @ axis)[1:-1].mean()
    assert interp > 0.1                                     # metres: a real depth motion
    assert one > 0.5 * interp                               # one view: mostly the interpolation
    assert two < one / 3.0
    assert res_two.ranks.mean() > res_one.ranks.mean() + 1       # rank over all views
    np.testing.assert_array_equal(res_two.view_samples.sum(axis=0), res_two.n_samples)
    assert np.all(res_two.view_samples > 0)


def test_stacked_rows_are_the_derivatives_of_every_view(depth_scene):
    """Eq. 5 rows of each view (its camera, the body's shared parameters, depth estimated with
    two views) against finite differences of where the points go in that view's image. The
    images are linear ramps, so the image gradient is exact and only the geometry is tested."""
    sk, body, cams, roots, local, _ = depth_scene
    problem = TrackingProblem(sk, body, cams)
    options = TrackingOptions()
    pose = (roots[3:4], local[3:4])
    ramps = [(0.0011, -0.0007), (-0.0006, 0.0013)]
    views = []
    for cam, (a, b) in zip(cams, ramps):
        v, u = np.mgrid[0:cam.height, 0:cam.width]
        image = 0.3 + a * u + b * v
        rot, org = joint_frames_in_camera(sk, cam.world2camera, *pose)
        views.append(MotionView(camera=cam, pyramid=[np.stack([image, image])], finest_level=0,
                                image_pairs=np.array([[0, 1]]), frames_cam=(rot, org),
                                samples=sample_silhouette(body, cam, rot, org, 600)))
    candidates = [_candidate_points(problem, options, view, 1) for view in views]
    measurable, _, points, view_samples = _measured_points(problem, options, views, candidates, 1)
    cols = _depth_columns(problem, options, views, view_samples)
    np.testing.assert_allclose(cols[0], np.eye(3))          # both views see it: depth estimated
    layout, scales = problem.layout, problem.scales
    n_t = len(layout.translation_axes)
    weak = np.concatenate([np.zeros(n_t, dtype=bool), ~measurable[0, layout.rotation_joints]])
    factor = (~weak / scales)[None, None, :]
    h = 1e-6
    for view, pts, (a, b) in zip(views, points, ramps):
        rows = _level_template(problem, view, pts, 0, cols, factor)
        ok = rows.ok[0]
        assert ok.sum() > 100

        def intensity(x_s):
            x = x_s / scales
            r = np.zeros((1, sk.n_joints, 3))
            r[0, layout.rotation_joints, layout.rotation_axes] = x[n_t:]
            moved = joint_frames_in_camera(sk, view.camera.world2camera,
                                           *apply_motion(sk, *pose, cols[0] @ x[:n_t], r))
            jts = rows.joints[0, ok]
            p = np.einsum("sij,sj->si", moved[0][0, jts], rows.local_points[0, ok]) \
                + moved[1][0, jts]
            uv = view.camera.project(p)
            return a * uv[:, 0] + b * uv[:, 1]

        for k in np.nonzero(~weak)[0]:
            step = np.zeros(layout.n_params)
            step[k] = h
            fd = (intensity(step) - intensity(-step)) / (2 * h)
            np.testing.assert_allclose(rows.a[0, ok, k], fd, rtol=1e-4,
                                       atol=1e-6 * np.abs(fd).max())
    # 'equal' weighting: every view's weighted rows have the same RMS norm.
    templates = [_level_template(problem, view, pts, 0, cols, factor)
                 for view, pts in zip(views, points)]
    w = view_weights("equal", templates, np.ones((2, 1)))
    norms = [np.sqrt(np.mean(np.sum((wv[0] * t.a[0, t.ok[0]]) ** 2, axis=1)))
             for wv, t in zip(w, templates)]
    np.testing.assert_allclose(norms, 1.0)


def test_pool_equals_serial_with_two_views(depth_scene):
    sk, body, cams, roots, local, frames = depth_scene
    problem = TrackingProblem(sk, body, cams)
    keys = [0, 4, 10]
    options = TrackingOptions(max_iterations=1)
    serial = track_keyframes(problem, frames, keys, roots[keys], local[keys], options, processes=1)
    pooled = track_keyframes(problem, frames, keys, roots[keys], local[keys], options, processes=2)
    np.testing.assert_array_equal(serial.root_translations, pooled.root_translations)
    np.testing.assert_array_equal(serial.local_rotations, pooled.local_rotations)
    for a, b in zip(serial.intervals, pooled.intervals):
        np.testing.assert_array_equal(a.errors, b.errors)
        np.testing.assert_array_equal(a.view_samples, b.view_samples)


def test_pool_equals_serial_with_unsynchronised_cameras(depth_scene):
    """A child process gets only the frames of the interval it takes (cut per camera: a view,
    a NaN-padded copy, or nothing where the camera filmed none of them): the serial results."""
    sk, body, cams, roots, local, frames = depth_scene
    problem = TrackingProblem(sk, body, cams)
    options = TrackingOptions(max_iterations=1)
    k = [0, 3, 4, 6, 7, 10]
    stacks = [frames[0][:5], frames[1][6:]]
    runs = [track_keyframes(problem, stacks, k, roots[k], local[k], options, processes=p,
                            frame_offsets=[0, 6]) for p in (1, 3)]
    np.testing.assert_array_equal(runs[0].root_translations, runs[1].root_translations)
    np.testing.assert_array_equal(runs[0].local_rotations, runs[1].local_rotations)
    for a, b in zip(runs[0].intervals, runs[1].intervals):
        np.testing.assert_array_equal(a.errors, b.errors)
        np.testing.assert_array_equal(a.view_samples, b.view_samples)
        assert a.reason == b.reason
    assert "no camera filmed frames 4..6" not in runs[1].intervals[2].reason


def test_frame_offsets(depth_scene):
    """A camera's stack starting later (offset) is cut at the right frames; frames a camera did
    not film give no rows in it; an interval no camera filmed keeps the interpolation."""
    sk, body, cams, roots, local, frames = depth_scene
    problem = TrackingProblem(sk, body, cams)
    options = TrackingOptions(max_iterations=1, seed="interpolation")
    keys = [2, 6]
    ref = track_keyframes(problem, frames, keys, roots[keys], local[keys], options, processes=1)
    shifted = track_keyframes(problem, [frames[0][1:], frames[1][2:9]], keys, roots[keys],
                              local[keys], options, processes=1, frame_offsets=[1, 2])
    np.testing.assert_array_equal(shifted.local_rotations, ref.local_rotations)
    np.testing.assert_array_equal(shifted.intervals[0].errors, ref.intervals[0].errors)
    # The side camera starts at clip frame 4: frame pairs 2-3 and 3-4 are the front view's only.
    late = track_keyframes(problem, [frames[0], frames[1][4:]], keys, roots[keys], local[keys],
                           options, processes=1, frame_offsets=[0, 4])
    samples = late.intervals[0].view_samples
    assert np.all(samples[1, :2] == 0) and np.all(samples[1, 2:] > 0) and np.all(samples[0] > 0)
    # Clip frames 0..3 are filmed by the front camera alone, 7..10 by the side camera alone,
    # 4..6 by none: that interval keeps the interpolation.
    k = [0, 3, 4, 6, 7, 10]
    gap = track_keyframes(problem, [frames[0][:4], frames[1][7:]], k, roots[k], local[k],
                          options, processes=1, frame_offsets=[0, 7])
    first, _, unfilmed, _, last = gap.intervals
    assert first.view_levels[1] is None and first.n_samples.sum() > 0
    assert last.view_levels[0] is None and last.n_samples.sum() > 0
    assert "no camera filmed frames 4..6" in unfilmed.reason and unfilmed.n_samples.sum() == 0
    np.testing.assert_allclose(gap.local_rotations[4:7],
                               interpolate_poses(sk, Pose(roots[4], local[4]),
                                                 Pose(roots[6], local[6]), 2)[1], atol=1e-12)
    with pytest.raises(TrackingError, match="one frame stack per camera"):
        track_keyframes(problem, frames[0], keys, roots[keys], local[keys])
    with pytest.raises(TrackingError, match="camera 1: Expected frames of shape"):
        track_keyframes(problem, [frames[0], frames[0][:, :10]], keys, roots[keys], local[keys])
    with pytest.raises(TrackingError, match=r"within 4\.\.10"):
        track_keyframes(problem, [frames[0][4:], frames[1][4:]], keys, roots[keys], local[keys],
                        frame_offsets=[4, 4])
