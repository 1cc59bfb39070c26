"""What is tracked (:class:`TrackingProblem`) and how (:class:`TrackingOptions`)."""

from dataclasses import dataclass, field, replace

import numpy as np

from .acceptance import AcceptanceRule
from .body_model import BodyModel
from .camera import PinholeCamera
from ..kinematics import rest_pose
from .jacobians import ancestor_matrix, motion_layout
from .robust import LOSSES


class TrackingError(ValueError):
    """Invalid tracking input (shapes, poses, frames); the operator reports it."""


class TrackingCancelled(Exception):
    """Tracking was stopped on request (``track_keyframes(cancel=...)``); nothing is returned."""


@dataclass(frozen=True, eq=False)
class TrackingProblem:
    """Skeleton, body shapes, camera(s) and the estimated degrees of freedom.

    Parameters
    ----------
    skeleton : Skeleton
        Joint frames = the parts' frames (Blender: bone frames).
    body : BodyModel
        Shapes attached to the joints.
    camera : PinholeCamera or sequence of PinholeCamera
        Intrinsics and world -> camera pose of each view (static cameras). One camera, or
        several filming the same action (multi-view tracking, ``docs/tracking.md``): the
        frames passed to :func:`~.parallel.track_keyframes` / :func:`~.trajectory.track_interval`
        are then one stack per camera, in this order.
    dof_mask : array_like, shape (B, 3), bool, optional
        Rotation axes estimated per joint (Blender: not ``lock_rotation``); default the
        skeleton's ``dof_axes``. Joints whose subtree has no body part are never estimated.
    translation_mask : array_like, shape (3,), bool, optional
        Root translation axes (root frame) estimated; default all.
    regions : sequence of str, optional
        Body part of every joint for the per-part acceptance (``'torso and head'``,
        ``'left arm'``, ``'right arm'``, ``'left leg'``, ``'right leg'``: a rig's body map
        knows them, ``core.rigs.body_region``); default: guessed from the joint names
        (:func:`~.acceptance.body_parts`).

    Attributes
    ----------
    cameras : tuple of PinholeCamera
        Every view's camera (one entry for a single camera).
    camera : PinholeCamera
        The first view's camera (``cameras[0]``: the single camera of a one-view problem).
    layout : MotionLayout
        The estimated parameters ``x`` (eq. 3).
    ancestors : ndarray, shape (B, B), bool
    scales : ndarray, shape (n_params,)
        Unit of each parameter in metres of surface motion: 1 for the root translation, the
        reach of the joint's subtree (largest distance from the joint to its parts, rest pose)
        for a rotation. ``A`` is rank-tested and solved in these units (see ``motion.py``).
    """

    skeleton: object
    body: BodyModel
    camera: PinholeCamera
    dof_mask: np.ndarray = None
    translation_mask: np.ndarray = None
    regions: tuple = None
    cameras: tuple = field(init=False)
    layout: object = field(init=False)
    ancestors: np.ndarray = field(init=False)
    scales: np.ndarray = field(init=False)

    def __post_init__(self):
        if self.body.n_joints != self.skeleton.n_joints:
            raise TrackingError(f"body model has {self.body.n_joints} joints, skeleton "
                                f"{self.skeleton.n_joints}")
        cameras = (self.camera,) if isinstance(self.camera, PinholeCamera) else self.camera
        try:
            cameras = tuple(cameras)
        except TypeError:
            raise TrackingError("camera must be a PinholeCamera or a sequence of them") from None
        if not cameras or not all(isinstance(c, PinholeCamera) for c in cameras):
            raise TrackingError("camera must be a PinholeCamera or a non-empty sequence of them")
        object.__setattr__(self, "cameras", cameras)
        object.__setattr__(self, "camera", cameras[0])
        if self.regions is not None:
            regions = tuple(str(r) for r in self.regions)
            if len(regions) != self.skeleton.n_joints:
                raise TrackingError(f"Expected {self.skeleton.n_joints} regions, got "
                                    f"{len(regions)}")
            object.__setattr__(self, "regions", regions)
        layout = motion_layout(self.skeleton, self.dof_mask, self.translation_mask, self.body)
        object.__setattr__(self, "layout", layout)
        object.__setattr__(self, "dof_mask", layout.dof_mask)
        object.__setattr__(self, "translation_mask",
                           np.isin(np.arange(3), layout.translation_axes))
        object.__setattr__(self, "ancestors", ancestor_matrix(self.skeleton))
        object.__setattr__(self, "scales", parameter_scales(self.skeleton, self.body, layout,
                                                            self.ancestors))

    @property
    def n_views(self):
        """Number of cameras."""
        return len(self.cameras)


def parameter_scales(skeleton, body, layout, ancestors):
    """Metres of surface motion per unit of each parameter (rest pose; see TrackingProblem)."""
    rot, org = rest_pose(skeleton)
    j = body.joints
    ends = np.concatenate([org[j] + np.einsum("pij,pj->pi", rot[j], body.starts),
                           org[j] + np.einsum("pij,pj->pi", rot[j], body.ends)])
    radius = np.concatenate([body.radii[:, 0], body.radii[:, 1]])
    owner = np.concatenate([j, j])
    bj = body.box_joints
    ends = np.concatenate([ends, org[bj] + np.einsum("qij,qj->qi", rot[bj], body.box_centres)])
    radius = np.concatenate([radius, np.linalg.norm(body.box_half_sizes, axis=1)])
    owner = np.concatenate([owner, bj])
    scales = np.ones(layout.n_params)
    n_t = len(layout.translation_axes)
    for c, joint in enumerate(layout.rotation_joints):
        sub = ancestors[owner, joint]
        reach = np.linalg.norm(ends[sub] - org[joint], axis=1) + radius[sub]
        scales[n_t + c] = max(float(reach.max()), 1e-3) if np.any(sub) else 1.0
    return scales


#: Accepted ``TrackingOptions.view_weighting`` values.
VIEW_WEIGHTINGS = ("none", "equal", "noise")


@dataclass(frozen=True)
class TrackingOptions:
    """Numerical settings of the tracker (defaults tuned on the rendered walk, see docs).

    Attributes
    ----------
    tau : float
        Rank threshold of eqs. 6-7: singular values with ``sigma_i / sigma_1 < tau`` count as 0.
    sample_budget : int
        Model points per frame used in ``A x = b`` (the highest-gradient interior points).
    candidate_budget : int
        Points of the silhouette sampling grid per frame (candidates; eq. 4 is scored on them).
    levels : int
        Pyramid levels used coarse-to-fine, ending at the finest working level.
    finest_level : int or None
        Finest pyramid level tracked; ``None`` picks the coarsest level on which the body's
        projected height (keyed poses) still exceeds ``body_pixels``: the frame cost then stays
        the same at any resolution.
    body_pixels : float
        See ``finest_level``.
    min_body_pixels : float
        Coarser pyramid levels than the one where the body is this tall are not used.
    warp_iterations : int
        Re-linearisations (warp, re-solve) per pyramid level.
    step_tol : float
        Stop a level's iterations when the largest update is below this (radians / metres).
    robust_loss : {'tukey', 'huber', 'clip'}
        How samples that do not match the body (another person in front, clutter, occluders,
        highlights) are kept from pulling the estimate (``core.tracking.robust``, issue 20):
        ``'tukey'`` (Tukey's biweight) or ``'huber'`` M-estimators, by iteratively reweighted
        least squares on the rows of eq. 5 (each view's threshold from its own residuals'
        scale, ``1.4826 median |r|`` per frame), and the same loss summed in eq. 4 (the
        trajectory judge). ``'clip'``: the tracker before issue 20 (residuals clipped at
        ``robust_clip`` standard deviations of the mean absolute residual, rows unweighted,
        eq. 4 a sum of squares). Default ``'tukey'`` with ``robust_scale='frame'`` and
        ``robust_start=2`` (docs/tracking.md, *Robust estimation*, *Default*).
    robust_threshold : float
        The M-estimator's threshold ``c`` in units of that scale (Tukey: a residual beyond
        ``c`` scales has no weight; Huber: its weight falls as ``c / |u|``). Chosen by
        cross-validation across clips and conditions (docs/tracking.md, *Robust estimation*).
    robust_scale : {'frame', 'joint', 'pooled'}
        Where the IRLS scale is measured (``motion._irls``): per frame pair and view, per frame
        pair, view and joint, or per joint over every frame pair and view of a pass.
    robust_gradient : bool
        Standardise each residual by its image gradient before it is weighted
        (``motion._irls``): a misaligned point's residual grows with its gradient.
    robust_reweight : int
        IRLS weights are re-estimated (and the weighted system decomposed again, eqs. 6-7) on
        every ``robust_reweight``-th re-linearisation of a pyramid level, starting with its
        first; in between the level keeps its weights and its decomposition and only the
        residuals are new (``motion._coarse_to_fine``). 1 (default): every re-linearisation
        (plain IRLS); ``warp_iterations`` or more: once per level, at the cost of the
        unweighted tracker's one decomposition per level -- faster on the real footage, but
        it fails the core tests' accuracy bounds on clean renders (docs/tracking.md, *Robust
        estimation: its cost*).
    robust_start : int
        Re-linearisations of each pyramid level taken with the ``'clip'`` update (residuals
        clipped, rows unweighted) before IRLS weights the rows: the weights are computed at an
        estimate that has converged on the level, so a limb still converging (large residuals
        that are signal, not outliers) is not set aside on a clean render. 0: IRLS from the
        level's first re-linearisation (the robust estimate as it came in); ``>=
        warp_iterations``: the ``'clip'`` motion estimate with the robust eq. 4. Default 2 of
        the 3 re-linearisations (docs/tracking.md, *Robust estimation*, *Default*).
    robust_clip : float
        ``robust_loss='clip'`` (and the first ``robust_start`` re-linearisations) only:
        photometric residuals are clipped at this many standard deviations (estimated per
        frame from the mean absolute residual).
    max_iterations : int
        Trajectory iterations (track, accumulate, correct, score).
    patience : int
        Stop after this many iterations without a new minimum of eq. 4.
    divergence_factor : float
        An eq. 4 error above this multiple of the best so far counts as divergence.
    min_visible_fraction : float
        A frame whose silhouette samples drop below this fraction of the initial trajectory's
        counts as divergence (model lost / left the image).
    limit_margin : float, radians
        Joint limits, widened to include both keyed poses, are enforced with this margin.
    drift_tol, drift_max_iterations
        Newton stopping rule of the orientation correction (eq. 14).
    min_samples : int
        Fewer usable points than this in a frame: no measurement, the prediction is kept.
    seed : {'interpolation', 'forward', 'bidirectional'}
        Start of the loop. ``'interpolation'`` is the paper's; the others first track frame to
        frame from the key(s) (the model starts aligned with the body) and start the loop from
        that (see ``trajectory.seed_trajectory``); the interpolation is still scored and kept
        if it is better. On the rendered walk the bidirectional seed cuts the error left by the
        paper's start by a third when keys are 20+ frames apart (benchmark); it costs about two
        iterations.
    root_displacement : {'measured', 'accumulated'}
        Orientation that turns the root's estimated translation (root frame) into a world
        displacement before accumulation: the trajectory pose it was measured on, or eq. 24's
        accumulated uncorrected orientation (the paper; drift in that orientation then leaks
        into the position).
    estimate_depth : bool
        Also estimate the root's motion along the optical axis (see
        ``motion.translation_columns``); off by default, as in the paper (§5.3). Set it for a
        rigid object (one part, e.g. the §5.1 box), whose scale change measures its depth.
    min_part_samples : int
        A joint whose subtree shows fewer points than this is not measured in that frame: its
        columns of ``A`` are dropped and it takes the prediction (hidden or tiny parts).
    roi_margin : float or None
        The pyramid is built on a window of the frames around the body only
        (``trajectory.region_of_interest``): the body's bounding box over the keys and the
        interpolation, widened by this fraction of its larger side on every side. ``None``:
        whole frames. The cost of the pyramid then follows the body's size, not the frame's;
        the tracking result is the same (to rounding) as long as the body stays inside.
    min_improvement : float
        An iteration counts as an improvement (for ``patience``) only when it lowers the best
        eq. 4 error by more than this fraction; the minimum is kept either way. 0: any
        decrease counts (default; see docs/tracking.md, *Validation*).
    view_weighting : {'none', 'equal', 'noise'}
        Several cameras: how each view's rows of eq. 5 are weighted before they are stacked
        (``motion.view_weights``). ``'none'`` (default): as they come. Every view gives at
        most ``sample_budget`` points whatever the body's size in its pixels, and a row is the
        image gradient times the view's pixels per metre: a view counts by how precisely its
        image measures the motion in metres (least squares with the same intensity noise in
        every view). ``'equal'``: each view's rows scaled to the same RMS row norm (every view
        counts the same, however coarsely it sees the body); ``'noise'``: each view's rows
        divided by its robust residual scale (noise plus model misfit, per frame and pyramid
        level). One camera: no weighting at all. Chosen on the validation clips
        (docs/tracking.md, *Several cameras*).
    keypoint_weight : float
        Cameras with 2D keypoints (:mod:`.keypoint_cue`, issue 24): how many image samples'
        worth one keypoint coordinate is in the rows of every frame pair, each in its own noise
        units (the image rows' robust scale, the keypoints' robust scale in pixels). 0 (the
        default): no such rows -- on the real footage they made the result worse (a
        detector's jitter enters every frame pair; ``docs/tracking.md``).
    keypoint_fusion_weight : float
        Cameras with 2D keypoints: after tracking, every in-between frame is fitted to the
        keypoints smoothed over time, with the tracked pose as the prior
        (:mod:`.keypoint_fusion`). With two keys: the prior's weight, in keypoint noise units
        per rad^2, each interval fused on its own; with three keys or more
        (``keypoint_drift_scale`` > 0) the weight comes from the tracker's drift measured on the
        keypoints, the clip is fused only where that drift is significant
        (:data:`.keypoint_fusion.DRIFT_SIGNIFICANCE`), and this only switches the fusion on.
        0: no fusion. Default chosen on one camera of the real footage.
    keypoint_drift_scale : float
        With three keys or more (the keypoints' noise measured at held-out keys): the
        fusion runs once over the whole clip after every interval is tracked, its prior's
        weight the inverse of the tracker's drift **measured on these cameras** -- the
        disagreement between keypoints and tracked pose beyond the keypoints' noise
        (:func:`.keypoint_fusion.pooled_drift`) -- times this scale
        (:func:`.keypoint_fusion.measured_prior_weights`); ``keypoint_fusion_weight`` then
        only switches it on. 0: each interval fused on its own with ``keypoint_fusion_weight``
        and the drift law (as with two keys). Default chosen on one camera of the real footage.
    keypoint_smoothing : float
        Seconds on each side of the keypoints' smoothing over time before the fusion: the
        most whole frames at ``frame_rate`` within it (default 1/12 s: 5 frames at 60 fps,
        the window chosen on the real footage; 2 at 24 or 30 fps). 0: none.
    depth_from_views : bool
        Several cameras: estimate the root's motion along every axis in frames that two or
        more views measure (their lines of sight differ, so together they measure depth);
        otherwise depth follows ``estimate_depth`` like one camera.
    view_tau : float or None
        Rank threshold (as ``tau``) of a frame's stacked system when two or more views measure
        it; None: ``tau``. Several views condition ``A`` better than one: the validation clips
        gain from a lower threshold there (0.01; docs/tracking.md *Several cameras*).
    limit_action : {'reject', 'clamp'} or None
        A tracked trajectory with an estimated joint outside its limits (widened to the keys,
        plus ``limit_margin``): ``'reject'`` -- it is not used (the seed is dropped, the loop
        stops as diverged); ``'clamp'`` -- the joint's angles are clamped into the limits and
        the trajectory is scored like any other. None: ``'reject'`` with one camera (the
        single-camera tracker as it was), ``'clamp'`` with several (chosen on the validation
        clips, docs/tracking.md *Several cameras*).
    occluder_margin : float, metres
        Several bodies (``core.tracking.bodies``): another body's envelopes are widened by this
        much before the points hidden behind them are left out (its pose is an estimate too).
    acceptance : AcceptanceRule or None
        Never worse than the interpolation: per interval and body part, the tracked motion is
        kept only where the footage supports it, else the part keeps the keys' interpolation
        (``core.tracking.acceptance``; variant and thresholds chosen in docs/tracking.md *Never
        worse than the interpolation*). None: every part keeps the tracked motion (the
        evidence is still reported in ``IntervalResult.acceptance``, nothing rejected).
    foot_lock : bool
        Planted feet: where a tracked foot stands (low and slow), the leg is solved so that it
        does not slide (:mod:`core.tracking.foot_lock`); keys unchanged. On by default.
    frame_rate : float
        Frames per second of the clip (the foot lock's "slow" is a speed).
    up : tuple of 3 float
        The world's up direction in the problem's space (the armature's; any length): the
        foot lock's heights are measured along it. (0, 0, 1): Blender's Z, for an armature
        object that is not turned (an FBX import turned 90° about X has its up along +Y).
    """

    tau: float = 0.02
    sample_budget: int = 1200
    candidate_budget: int = 4000
    levels: int = 3
    finest_level: int = None
    body_pixels: float = 300.0
    min_body_pixels: float = 50.0
    warp_iterations: int = 3
    step_tol: float = 1e-4
    robust_loss: str = "tukey"
    robust_threshold: float = 4.685
    robust_scale: str = "frame"
    robust_gradient: bool = False
    robust_reweight: int = 1
    robust_start: int = 2
    robust_clip: float = 3.0
    max_iterations: int = 4
    patience: int = 2
    divergence_factor: float = 4.0
    min_visible_fraction: float = 0.25
    limit_margin: float = float(np.radians(30.0))
    drift_tol: float = 1e-10
    drift_max_iterations: int = 20
    min_samples: int = 20
    min_part_samples: int = 15
    seed: str = "bidirectional"
    root_displacement: str = "measured"
    estimate_depth: bool = False
    roi_margin: float = 0.25
    min_improvement: float = 0.0
    view_weighting: str = "none"
    depth_from_views: bool = True
    view_tau: float = 0.01
    limit_action: str = None
    occluder_margin: float = 0.03
    keypoint_weight: float = 0.0
    keypoint_fusion_weight: float = 1000.0
    keypoint_drift_scale: float = 0.1
    keypoint_smoothing: float = 5.0 / 60.0
    acceptance: AcceptanceRule = AcceptanceRule()
    foot_lock: bool = True
    frame_rate: float = 24.0
    up: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        if not (np.isfinite(self.frame_rate) and self.frame_rate > 0):
            raise ValueError(f"frame_rate must be a positive number, got {self.frame_rate}")
        up = np.asarray(self.up, dtype=float)
        if up.shape != (3,) or not np.all(np.isfinite(up)) or not np.linalg.norm(up) > 0:
            raise ValueError(f"up must be a non-zero finite 3-vector, got {self.up!r}")
        if self.seed not in ("interpolation", "forward", "bidirectional"):
            raise ValueError(f"seed must be 'interpolation', 'forward' or 'bidirectional', got "
                             f"{self.seed!r}")
        if self.root_displacement not in ("measured", "accumulated"):
            raise ValueError(f"root_displacement must be 'measured' or 'accumulated', got "
                             f"{self.root_displacement!r}")
        if self.roi_margin is not None and not self.roi_margin >= 0.0:
            raise ValueError(f"roi_margin must be >= 0 or None, got {self.roi_margin}")
        if self.robust_loss not in LOSSES:
            raise ValueError(f"robust_loss must be one of {', '.join(map(repr, LOSSES))}, got "
                             f"{self.robust_loss!r}")
        if self.robust_scale not in ("frame", "joint", "pooled"):
            raise ValueError(f"robust_scale must be 'frame', 'joint' or 'pooled', got "
                             f"{self.robust_scale!r}")
        if not (isinstance(self.robust_start, (int, np.integer)) and self.robust_start >= 0):
            raise ValueError(f"robust_start must be an integer >= 0, got {self.robust_start!r}")
        if not self.robust_threshold > 0.0:
            raise ValueError(f"robust_threshold must be > 0, got {self.robust_threshold}")
        if self.view_weighting not in VIEW_WEIGHTINGS:
            raise ValueError(f"view_weighting must be one of "
                             f"{', '.join(map(repr, VIEW_WEIGHTINGS))}, got "
                             f"{self.view_weighting!r}")
        if not (np.isfinite(self.keypoint_weight) and self.keypoint_weight >= 0.0):
            raise ValueError(f"keypoint_weight must be >= 0, got {self.keypoint_weight}")
        if not (np.isfinite(self.keypoint_fusion_weight) and self.keypoint_fusion_weight >= 0.0):
            raise ValueError(f"keypoint_fusion_weight must be >= 0, got "
                             f"{self.keypoint_fusion_weight}")
        if not (np.isfinite(self.keypoint_drift_scale) and self.keypoint_drift_scale >= 0.0):
            raise ValueError(f"keypoint_drift_scale must be >= 0, got "
                             f"{self.keypoint_drift_scale}")
        if not (np.isfinite(self.keypoint_smoothing) and self.keypoint_smoothing >= 0.0):
            raise ValueError(f"keypoint_smoothing must be >= 0 seconds, got "
                             f"{self.keypoint_smoothing}")
        if not 0.0 <= self.min_improvement < 1.0:
            raise ValueError(f"min_improvement must be in [0, 1), got {self.min_improvement}")
        if not 0.0 < self.tau < 1.0:
            raise ValueError(f"tau must be in (0, 1), got {self.tau}")
        if self.view_tau is not None and not 0.0 < self.view_tau < 1.0:
            raise ValueError(f"view_tau must be in (0, 1) or None, got {self.view_tau}")
        if self.limit_action not in (None, "reject", "clamp"):
            raise ValueError(f"limit_action must be 'reject', 'clamp' or None, got "
                             f"{self.limit_action!r}")
        for name in ("sample_budget", "candidate_budget", "levels", "warp_iterations",
                     "max_iterations", "patience", "min_samples", "robust_reweight"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")

    def replace(self, **changes):
        """A copy with some fields changed."""
        return replace(self, **changes)

    def resolved_limit_action(self, problem):
        """``limit_action`` for a problem (None: by its number of cameras)."""
        if self.limit_action is not None:
            return self.limit_action
        return "reject" if problem.n_views == 1 else "clamp"
