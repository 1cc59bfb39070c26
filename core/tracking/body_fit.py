"""Fit the body model's envelope radii to the person in the footage (Fit Body to Footage).

The tracker's body is one tapered cylinder per bone (:mod:`.body_model`); its radii are the
armature's envelope radii. The defaults (:func:`core.armature.plausible_envelope_radii`) are a
generic adult: a round 12-15 cm torso, whatever the person. This module measures each bone's
radius at the keyed frames, where the animator has put the armature on the person, from the
edges of the person's silhouette in the footage. NumPy only; plain arrays in and out.

Method (:func:`fit_body_radii`)
-------------------------------
For every camera, keyed frame ``k``, bone ``b`` with a shape and position ``s`` along it
(``positions``, fractions of the bone away from the joints where neighbours overlap):

1. **Profile.** ``P`` = the point of the bone's axis at ``s`` (camera frame), ``w`` its unit
   axis, ``m = (w x P) / |w x P|``: the direction perpendicular to both the axis and the line
   of sight, which the image shows across the projected bone. A cylinder of radius ``rho``
   about the axis has its silhouette through ``P +- rho' m``, ``rho' = rho / sqrt(1 - rho^2 /
   D^2)``, ``D = |w x P|`` the distance from the camera to the axis line (the ray through that
   point is tangent to the cylinder: its distance to the axis is exactly ``rho``). So a grid of
   radii ``rho`` (``radius_step``) maps to pixels on both sides of the bone through the
   camera's projection, lens distortion included (:meth:`.PinholeCamera.project`): depth,
   perspective and the lens convert pixels to metres exactly.
2. **Edges.** At those pixels, the image gradient along the profile, ``|dI / d rho|`` (grey
   levels smoothed by ``blur_sigma`` pixels on the pyramid level where the body is at most
   ``body_pixels`` tall), divided by its mean over the side's profile: an edge strength in
   units of the profile's own texture, so that every frame and side votes alike.
3. **Occlusion.** The tracker's own ray casting (:func:`.body_model.ray_cast`) at the keyed
   pose: a profile pixel where another part is the front-most surface, nearer the camera than
   this bone's axis plus ``overlap_depth`` times its radius (in front of it, or overlapping it
   at its own depth), shows that part's edges, not this bone's: it is masked, with a margin of
   ``mask_margin`` pixels (the blur spreads the occluder's edge). A side with less than
   ``min_side_coverage`` of its pixels left is dropped. The first pass uses the current radii;
   the next one the radii just fitted (``passes``).
4. **Vote.** The body's two edges on a profile lie at ``rho - delta`` and ``rho + delta`` when
   the bone's axis is ``delta`` off the limb's centre (keys placed by hand or from joint
   detections are off by a centimetre or two). Each profile votes
   ``H(rho) = max_|delta| <= max_offset sqrt(E_left(rho + delta) E_right(rho - delta))`` (the
   geometric mean: both edges must be there), or ``one_side x E_side(rho)`` when the other side
   is masked. Texture inside the limb and in the background lies at other radii in every
   frame and at every position; the silhouette does not.
5. **Bone.** The straight taper ``r(s) = 2 a / (1 + t) (1 + (t - 1) s)`` (mean radius ``a`` on
   the grid, tail/head ratio ``t`` in ``[1 / max_taper, max_taper]``) whose mean vote over
   every profile of the bone is highest -- all cameras, keyed frames and positions, and those
   of its mirror bone (``mirror``: left and right get one shape, so that an outlier on one side
   is outvoted by the other): a robust consensus, since a frame or position whose edges are
   elsewhere adds a little everywhere rather than moving the peak. Ties between tapers go to
   the current one. The answer's mean radius stays within ``1 / max_change`` .. ``max_change``
   times the current one (plausible anatomy: the current radii are a plausible body, the
   defaults of :func:`core.armature.plausible_envelope_radii` or the animator's). The bone is
   fitted when that peak stands ``min_contrast`` times above the median score of every
   candidate searched (``min_radius`` .. ``search_radius``, below); otherwise, or when the bone
   is seen end-on, hidden, outside every image, or shorter than ``min_aspect`` times its radius
   (a blob whose outline is its ends, not its sides), it keeps its current radii and says why
   (:attr:`BodyFit.reasons`).

6. **Connected joints.** Where a bone's head is its parent's tail (Blender's *Connected*,
   ``connected``), the joint has one radius -- Blender draws that sphere with the parent's tail
   radius (:func:`join_connected_radii`): the mean of the fitted radii meeting there, taken by
   every bone at that joint, fitted or not. Applied after every pass.

Searched radii: ``min_radius`` .. ``search_radius = clip(max(search_factor x the larger
current radius, length_fraction x bone length), min_search, max_radius)``. Settings chosen on
rendered clips and the real benchmark: ``docs/tracking.md``, *Fit Body to Footage*.
"""

from dataclasses import dataclass

import numpy as np

from .body_model import (BodyModel, body_model_from_skeleton, joint_frames_in_camera,
                         part_geometry, ray_cast)
from .image import gaussian_blur, pyr_down, sample_with_gradient

__all__ = ["BodyFit", "BodyFitError", "BodyFitOptions", "fit_body_radii",
           "join_connected_radii", "mirror_bones", "search_radii"]

# Points closer to the camera plane than this (metres) are not sampled.
_NEAR = 1e-2
# Smallest median score a contrast is taken against (units of a profile's mean edge strength):
# keeps the contrast finite on a textureless image (median 0).
_MEDIAN_FLOOR = 0.1
# Profile samples (keys x positions x sides x radii) of the bones measured at once: the peak
# memory of a fit is this budget (about 0.5 KB a sample: 500 MB at most), whatever the count
# of bones (a 706-bone rig) and the image size; the votes kept per bone are 8 bytes a sample.
PROFILE_BUDGET = 1 << 20


class BodyFitError(ValueError):
    """The body cannot be fitted from these inputs (the message says why)."""


@dataclass(frozen=True)
class BodyFitOptions:
    """Settings of :func:`fit_body_radii` (module docstring; chosen on rendered clips).

    Attributes
    ----------
    positions : tuple of float
        Fractions along each bone (joint 0 -> tail 1) where profiles are taken.
    radius_step : float, metres
        Spacing of the radius grid.
    min_radius, max_radius : float, metres
        Smallest radius searched; largest radius ever searched.
    search_factor, length_fraction, min_search : float
        Largest radius searched for a bone: ``clip(max(search_factor * current radius,
        length_fraction * length), min_search, max_radius)``.
    max_offset : float, metres
        Largest offset of the bone's axis from the limb's centre allowed per profile.
    body_pixels : float, pixels
        The body is measured on the pyramid level where it is at most this tall (finer levels
        add texture noise and cost).
    blur_sigma : float, pixels
        Gaussian smoothing at that level before the gradient.
    min_view_angle : float, degrees
        Profiles of a bone closer than this to the line of sight (seen end-on) are not taken.
    min_side_coverage : float
        Share of a side's profile pixels that must be unoccluded and inside the image.
    mask_margin : float, pixels
        Profile pixels this close to an occluding part are masked too.
    overlap_depth : float
        Another part occludes a profile pixel when it is hit nearer than the bone's axis plus
        this many times the bone's current radius (parts that overlap it at its own depth).
    one_side : float
        Weight of a profile's single visible edge when its other side is masked.
    min_contrast : float
        Peak score of a bone over the median score of its candidates, to be fitted.
    max_taper : float
        Largest ratio between the tail and the head radius (either way).
    taper_steps : int
        Tail/head ratios tried (geometric, ``1 / max_taper`` .. ``max_taper``).
    passes : int
        Fitting passes (occlusion from the current radii, then from the fitted ones).
    max_change : float
        The fitted mean radius stays within this factor of the current one (either way).
    min_aspect : float
        Bones shorter than this many times their larger current radius are blobs, not
        cylinders: their outline is their ends, not their sides; they keep their radii.
    """

    positions: tuple = (0.25, 0.375, 0.5, 0.625, 0.75)
    radius_step: float = 0.002
    min_radius: float = 0.012
    max_radius: float = 0.3
    search_factor: float = 1.8
    length_fraction: float = 0.5
    min_search: float = 0.06
    max_offset: float = 0.02
    body_pixels: float = 500.0
    blur_sigma: float = 1.0
    min_view_angle: float = 30.0
    min_side_coverage: float = 0.3
    mask_margin: float = 2.0
    overlap_depth: float = 1.0
    one_side: float = 0.5
    min_contrast: float = 1.5
    max_taper: float = 1.6
    taper_steps: int = 15
    passes: int = 2
    max_change: float = 1.5
    min_aspect: float = 1.5


@dataclass(frozen=True, eq=False)
class BodyFit:
    """Result of :func:`fit_body_radii` for a skeleton of B bones.

    Attributes
    ----------
    radii : ndarray, shape (B, 2), metres
        Head and tail radius: fitted where ``fitted``, else the input radii -- except at a
        connected joint shared with a fitted bone, whose one radius every bone there takes
        (:func:`join_connected_radii`).
    fitted : ndarray, shape (B,), bool
    reasons : tuple of str, (B,)
        Why a bone kept its radii ('' where it was fitted): 'no shape', 'shorter than it is
        wide', 'seen end-on', 'hidden or outside the image', 'no clear edge'.
    contrast : ndarray, shape (B,)
        Peak score over the median score (NaN where not measured).
    profiles : ndarray, shape (B,), int
        Profiles that voted (all cameras, keyed frames and positions).
    levels : tuple of int
        Pyramid level measured on, per camera.
    """

    radii: np.ndarray
    fitted: np.ndarray
    reasons: tuple
    contrast: np.ndarray
    profiles: np.ndarray
    levels: tuple

    @property
    def n_fitted(self):
        return int(np.count_nonzero(self.fitted))


def _check_inputs(skeleton, radii, cameras, frames, key_roots, key_locals):
    b = skeleton.n_joints
    radii = np.asarray(radii, dtype=float)
    if radii.shape != (b, 2):
        raise BodyFitError(f"Expected radii of shape ({b}, 2), got {radii.shape}")
    if not np.all(np.isfinite(radii)) or np.any(radii < 0):
        raise BodyFitError("Envelope radii must be finite and >= 0")
    key_roots = np.asarray(key_roots, dtype=float)
    key_locals = np.asarray(key_locals, dtype=float)
    k = len(key_roots)
    if k == 0 or key_roots.shape != (k, 3):
        raise BodyFitError(f"Expected key_roots of shape (K, 3) with K >= 1, got "
                           f"{key_roots.shape}")
    if key_locals.shape != (k, b, 3, 3):
        raise BodyFitError(f"Expected key_locals of shape ({k}, {b}, 3, 3), got "
                           f"{key_locals.shape}")
    if not (np.all(np.isfinite(key_roots)) and np.all(np.isfinite(key_locals))):
        raise BodyFitError("Key poses must be finite")
    single = not isinstance(cameras, (list, tuple))
    cameras = [cameras] if single else list(cameras)
    frames = [frames] if single else list(frames)
    if not cameras or len(frames) != len(cameras):
        raise BodyFitError(f"Expected one stack of frames per camera, got {len(frames)} for "
                           f"{len(cameras)} cameras")
    out = []
    for v, (camera, stack) in enumerate(zip(cameras, frames)):
        stack = np.asarray(stack)
        if stack.shape != (k, camera.height, camera.width):
            raise BodyFitError(f"Camera {v}: expected frames of shape ({k}, {camera.height}, "
                               f"{camera.width}) (one per key, the camera's size), got "
                               f"{stack.shape}")
        out.append(stack)
    return radii, cameras, out, key_roots, key_locals


def search_radii(radii, lengths, options):
    """Largest radius searched per part, (P,) metres (module docstring)."""
    o = options
    upper = np.maximum(o.search_factor * np.max(radii, axis=1), o.length_fraction * lengths)
    return np.clip(upper, o.min_search, o.max_radius)


def _level_for(camera, origins, options):
    """Pyramid level where the keyed bodies (joint origins) are at most ``body_pixels`` tall."""
    ok = origins[..., 2] > _NEAR
    if not np.any(ok):
        return 0
    pix = camera.project(np.where(ok[..., None], origins, [0.0, 0.0, 1.0]))
    size = max((float(np.max(np.ptp(p[m], axis=0))) if m.sum() > 1 else 0.0)
               for p, m in zip(pix, ok))
    if not np.isfinite(size) or size <= options.body_pixels:
        return 0
    return int(np.floor(np.log2(size / options.body_pixels)))


def _working_frames(frames, level, sigma):
    """Frames reduced ``level`` times and blurred, float32 (K, h, w)."""
    out = []
    for image in frames:
        image = np.asarray(image, dtype=np.float32)
        finite = np.isfinite(image)
        if not finite.all():
            image = np.where(finite, image, np.float32(image[finite].mean() if finite.any() else 0))
        for _ in range(level):
            image = pyr_down(image)
        out.append(gaussian_blur(image, sigma) if sigma > 0 else image)
    return np.stack(out)


def _profile_pixels(geo, camera, grid, options):
    """Pixels of every profile (module docstring, step 1).

    Returns pix (K, P, S, 2, G, 2), inside (same without the last axis) and end_on (K, P, S).
    """
    o = options
    s = np.asarray(o.positions, dtype=float)
    axis_pts = geo.starts[:, :, None] + geo.axes[:, :, None] * (
        s[None, None, :, None] * geo.lengths[None, :, None, None])      # (K, P, S, 3)
    cross = np.cross(np.broadcast_to(geo.axes[:, :, None], axis_pts.shape), axis_pts)
    dist = np.linalg.norm(cross, axis=-1)                              # D, (K, P, S)
    m = cross / np.maximum(dist, 1e-9)[..., None]
    sin_view = dist / np.maximum(np.linalg.norm(axis_pts, axis=-1), 1e-9)
    end_on = sin_view < np.sin(np.radians(o.min_view_angle))
    # rho' of the tangent ray: the exact silhouette of a cylinder of radius rho.
    ratio = np.clip(grid / np.maximum(dist, 1e-9)[..., None], 0.0, 0.999)
    rho_p = grid / np.sqrt(1.0 - ratio ** 2)                           # (K, P, S, G)
    sides = np.array([-1.0, 1.0])[:, None, None]
    pts = (axis_pts[:, :, :, None, None, :]
           + sides * rho_p[:, :, :, None, :, None] * m[:, :, :, None, None, :])
    front = pts[..., 2] > _NEAR
    pix = camera.project(np.where(front[..., None], pts, [0.0, 0.0, 1.0]))
    inside = (front & (pix[..., 0] >= 0) & (pix[..., 0] <= camera.width - 1)
              & (pix[..., 1] >= 0) & (pix[..., 1] <= camera.height - 1))
    return pix, inside, end_on, axis_pts[..., 2]


def _profiles(model, camera, frames, rotations, origins, grid, upper, occluders, options):
    """Normalised edge strength of every profile (module docstring, steps 1-3).

    Returns strength (K, P, S, 2, G), zero where masked; mask (same, bool); end_on and seen
    (K, P, S): some side of the profile is in the image and unoccluded (edges or not).
    """
    o = options
    geo = part_geometry(model, rotations, origins)
    pix, inside, end_on, depth = _profile_pixels(geo, camera, grid, o)
    # Profile direction in the image, d pixel / d rho (outwards on both sides).
    tangent = np.gradient(pix, axis=4)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=-1, keepdims=True), 1e-12)
    within = grid <= (upper[None, :, None, None, None] + o.max_offset)
    valid = inside & within & ~end_on[..., None, None]
    idx = np.nonzero(valid)
    flat_pix = pix[idx]
    # Occlusion by other parts nearer the camera than this bone's axis (the tracker's caster).
    hits = ray_cast(occluders, camera, rotations, origins, flat_pix, frames=idx[0])
    s = np.asarray(o.positions, dtype=float)
    # The occluders' current radii of these parts (the model may be some of the bones only).
    row = np.minimum(np.searchsorted(occluders.joints, model.joints), occluders.n_cylinders - 1)
    now = np.where((occluders.joints[row] == model.joints)[:, None], occluders.radii[row],
                   model.radii)
    r_now = now[:, :1] + (now[:, 1:] - now[:, :1]) * s
    reach = depth + o.overlap_depth * r_now                             # (K, P, S)
    occluded = (hits.hit & (hits.joints != np.asarray(model.joints)[idx[1]])
                & (hits.depth < reach[idx[:3]]))
    _, e_u, e_v = sample_with_gradient(frames, flat_pix[:, 0], flat_pix[:, 1], frames=idx[0])
    strength = np.abs(e_u * tangent[idx][:, 0] + e_v * tangent[idx][:, 1])
    blocked = np.zeros(valid.shape, dtype=bool)
    blocked[tuple(i[occluded] for i in idx)] = True
    # Mask a margin (pixels of arc length along the profile) around the occluder too.
    arc = np.concatenate([np.zeros(pix.shape[:-2] + (1,)),
                          np.cumsum(np.linalg.norm(np.diff(pix, axis=-2), axis=-1), axis=-1)],
                         axis=-1)
    last = np.maximum.accumulate(np.where(blocked, arc, -np.inf), axis=-1)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(blocked, arc, np.inf), -1), axis=-1), -1)
    mask = valid & (np.minimum(arc - last, nxt - arc) > o.mask_margin)
    values = np.zeros(valid.shape)
    values[idx] = strength
    values[~mask] = 0.0
    # Normalise per side over its unmasked searched range.
    count = np.count_nonzero(mask, axis=-1)
    mean = values.sum(axis=-1) / np.maximum(count, 1)
    side_seen = count / np.maximum(np.count_nonzero(within, axis=-1), 1) >= o.min_side_coverage
    mask &= (side_seen & (mean > 0))[..., None]
    strength = np.where(mask, values / np.where(mean > 0, mean, 1.0)[..., None], 0.0)
    return strength, mask, end_on, side_seen.any(axis=-1)


def _votes(strength, mask, n_offset, one_side):
    """H(rho) per profile (module docstring, step 4): (K, P, S, G), and which profiles voted
    (K, P, S)."""
    left, right = strength[..., 0, :], strength[..., 1, :]
    g = strength.shape[-1]
    best = np.zeros(left.shape)
    for j in range(-n_offset, n_offset + 1):
        # left edge at rho + delta, right edge at rho - delta (delta = j steps).
        a = np.zeros(left.shape)
        b = np.zeros(right.shape)
        lo, hi = max(0, -j), min(g, g - j)
        a[..., lo:hi] = left[..., lo + j:hi + j]
        lo, hi = max(0, j), min(g, g + j)
        b[..., lo:hi] = right[..., lo - j:hi - j]
        np.maximum(best, np.sqrt(a * b), out=best)
    seen_left, seen_right = mask[..., 0, :], mask[..., 1, :]
    alone = one_side * (np.where(seen_right, 0.0, left) + np.where(seen_left, 0.0, right))
    return np.maximum(best, alone), mask.any(axis=(-1, -2))


def _taper_vote(vote, voted, grid, upper, allowed, current, options):
    """Head and tail radius of one bone whose straight taper has the highest mean vote over
    all its profiles (module docstring, step 5), and that peak's contrast.

    vote : (M, S, G) (M = cameras x keyed frames); voted : (M, S) bool; upper : largest mean
    radius searched, metres; allowed : (lowest, highest) mean radius the answer may take (the
    contrast is measured against every candidate searched).
    """
    o = options
    s = np.asarray(o.positions, dtype=float)
    band = grid[(grid >= o.min_radius) & (grid <= upper)]
    ok = (band >= allowed[0]) & (band <= allowed[1])
    if not voted.any() or len(band) < 3 or not ok.any():
        return None, np.nan
    tapers = np.geomspace(1.0 / o.max_taper, o.max_taper, o.taper_steps)
    r = (2.0 * band[:, None, None] / (1.0 + tapers[None, :, None])
         * (1.0 + (tapers[None, :, None] - 1.0) * s))                  # (A, T, S)
    x = np.clip(r / (grid[1] - grid[0]), 0.0, len(grid) - 1.000001)
    i0 = np.floor(x).astype(int)
    f = x - i0
    kk, ss = np.nonzero(voted)
    v = vote[kk, ss]                                                     # (M', G)
    rows = np.arange(len(kk))[:, None, None]
    col0 = np.moveaxis(i0[..., ss], -1, 0)                              # (M', A, T)
    frac = np.moveaxis(f[..., ss], -1, 0)
    score = (v[rows, col0] * (1.0 - frac) + v[rows, col0 + 1] * frac).mean(axis=0)   # (A, T)
    covered = score > 0
    med = float(np.median(score[covered])) if covered.any() else 0.0
    ratio = current[1] / current[0] if current[0] > 0 and current[1] > 0 else 1.0
    # Ties (a taper the votes cannot tell apart) go to the current taper.
    score = score - 1e-3 * np.abs(np.log(tapers / ratio))
    score[~ok] = -np.inf
    a, t = np.unravel_index(int(np.argmax(score)), score.shape)
    head = 2.0 * band[a] / (1.0 + tapers[t])
    return np.array([head, head * tapers[t]]), score[a, t] / max(med, _MEDIAN_FLOOR)


def _view_votes(model, occluders, camera, frames, rotations, origins, grid, upper, options):
    """Votes of one camera: (K, P, S, G); voted, end_on, seen (K, P, S); level. Bones are
    measured a few at a time (:data:`PROFILE_BUDGET` profile samples)."""
    o = options
    level = _level_for(camera, origins, o)
    cam = camera.at_level(level)
    work = _working_frames(frames, level, o.blur_sigma)
    per_bone = len(frames) * len(o.positions) * 2 * len(grid)
    step = max(1, PROFILE_BUDGET // max(per_bone, 1))
    parts = []
    for first in range(0, model.n_cylinders, step):
        some = _some_parts(model, slice(first, first + step))
        strength, mask, end_on, seen = _profiles(some, cam, work, rotations, origins, grid,
                                                 upper[first:first + step], occluders, o)
        parts.append(_votes(strength, mask, int(round(o.max_offset / o.radius_step)),
                            o.one_side) + (end_on, seen))
        del strength, mask
    vote, voted, end_on, seen = (np.concatenate([p[i] for p in parts], axis=1)
                                 for i in range(4))
    return vote, voted, end_on, seen, level


def _some_parts(model, which):
    """The cylinders ``which`` (a slice) of ``model`` as a body model of their own."""
    return BodyModel(n_joints=model.n_joints, joints=model.joints[which],
                     starts=model.starts[which], ends=model.ends[which],
                     radii=model.radii[which], names=model.names[which])


def fit_body_radii(skeleton, radii, cameras, frames, key_roots, key_locals, options=None,
                   mirror=None, connected=None):
    """Envelope radii that fit the person seen at the keyed frames (module docstring).

    Parameters
    ----------
    skeleton : Skeleton
        Joint frame = bone frame (``docs/tracking.md``).
    radii : array_like, shape (B, 2), metres
        Current head and tail radii: which bones have a shape (both 0, or shorter than 2 cm:
        none, left alone), the occlusion model of the first pass, the searched range and the
        fallback.
    cameras : PinholeCamera or list of PinholeCamera
        The camera(s) that filmed the footage, posed in the skeleton's (armature) space; lens
        distortion included.
    frames : array_like, shape (K, H, W), or a list of them (one per camera)
        Grayscale footage at the K keyed frames (row 0 = top), each the size of its camera.
    key_roots : array_like, shape (K, 3), metres
    key_locals : array_like, shape (K, B, 3, 3)
        The keyed poses (``forward_kinematics`` convention), K >= 1.
    options : BodyFitOptions, optional
    mirror : array_like, shape (B,), int, optional
        Each bone's mirror image (the other side of the body; -1: none), e.g.
        :func:`mirror_bones`: a bone and its mirror get one shape from both their profiles.
    connected : array_like, shape (B,), bool, optional
        Bones whose head is their parent's tail, one joint with one radius (Blender's
        ``use_connect``; module docstring, step 6). The input radii should already agree
        there (as Blender draws them); the result does.

    Returns
    -------
    BodyFit

    Raises
    ------
    BodyFitError
        Inputs of the wrong shape or not finite, frames not of their camera's size, no bone
        with a shape.
    """
    o = options or BodyFitOptions()
    radii, cameras, frames, key_roots, key_locals = _check_inputs(
        skeleton, radii, cameras, frames, key_roots, key_locals)
    try:
        model = body_model_from_skeleton(skeleton, radii)
    except ValueError:
        raise BodyFitError("No bone has a shape (envelope radii) to fit") from None
    poses = [joint_frames_in_camera(skeleton, c.world2camera, key_roots, key_locals)
             for c in cameras]
    lengths = np.linalg.norm(model.ends - model.starts, axis=1)
    upper = search_radii(model.radii, lengths, o)
    grid = np.arange(0.0, upper.max() + o.max_offset + 1.5 * o.radius_step, o.radius_step)
    n = model.n_cylinders
    partner = _partners(model, mirror, skeleton.n_joints)
    connected = _connected(connected, skeleton)
    joined = radii
    for _ in range(max(1, int(o.passes))):
        occluders = body_model_from_skeleton(skeleton, joined)
        views = [_view_votes(model, occluders, c, f, rot, org, grid, upper, o)
                 for c, f, (rot, org) in zip(cameras, frames, poses)]
        vote = np.concatenate([v[0] for v in views])                 # (V K, P, S, G)
        voted = np.concatenate([v[1] for v in views])
        end_on = np.concatenate([v[2] for v in views])
        seen = np.concatenate([v[3] for v in views])
        new, fitted = model.radii.copy(), np.zeros(n, dtype=bool)
        reasons, contrast = [""] * n, np.full(n, np.nan)
        usable = np.ones(n, dtype=bool)
        for i in range(n):
            if lengths[i] < o.min_aspect * model.radii[i].max():
                reasons[i] = "shorter than it is wide"
            elif end_on[:, i].all():
                reasons[i] = "seen end-on"
            elif not seen[:, i].any():
                reasons[i] = "hidden or outside the image"
            usable[i] = not reasons[i]
        for i in np.nonzero(usable)[0]:
            # Both sides of the body vote for one shape (module docstring, step 5).
            both = [i] + [p for p in (partner[i],) if p >= 0 and usable[p]]
            mean = model.radii[i].mean()
            value, contrast[i] = _taper_vote(
                np.concatenate(vote[:, both].swapaxes(0, 1)),
                np.concatenate(voted[:, both].swapaxes(0, 1)), grid, upper[both].min(),
                (mean / o.max_change, mean * o.max_change), model.radii[i], o)
            if value is None or not contrast[i] >= o.min_contrast:
                reasons[i] = "no clear edge"
                continue
            new[i], fitted[i] = np.clip(value, o.min_radius, upper[both].min()), True
        b = skeleton.n_joints
        out_fitted = np.zeros(b, dtype=bool)
        out_fitted[model.joints] = fitted
        joined = join_connected_radii(_scatter(radii, model, new), skeleton.parents, connected,
                                      out_fitted)
    out_reasons = ["no shape"] * b
    for i, j in enumerate(model.joints):
        out_reasons[j] = reasons[i]
    out_contrast = np.full(b, np.nan)
    out_contrast[model.joints] = contrast
    out_profiles = np.zeros(b, dtype=int)
    out_profiles[model.joints] = voted.sum(axis=(0, 2))
    return BodyFit(radii=joined, fitted=out_fitted,
                   reasons=tuple(out_reasons), contrast=out_contrast, profiles=out_profiles,
                   levels=tuple(v[4] for v in views))


def join_connected_radii(radii, parents, connected, fitted):
    """One radius per connected joint (module docstring, step 6).

    Blender draws a connected bone's head with its parent's tail radius and ignores its own
    ``head_radius`` (``overlay_armature.cc``, ``bone_draw_envelope``); its own edit tools keep
    both equal. Here the joint's radius is the mean of the fitted radii meeting there (the
    parent's tail, each connected child's head); where none was fitted, the parent's tail.

    Parameters
    ----------
    radii : array_like, shape (B, 2), metres
        Head and tail radius per bone.
    parents : array_like, shape (B,), int
        Parent index (-1 for the root).
    connected : array_like, shape (B,), bool
        Bones whose head is their parent's tail.
    fitted : array_like, shape (B,), bool
        Bones whose radii were measured (the others follow them at a shared joint).

    Returns
    -------
    ndarray, shape (B, 2)
        ``radii`` with ``out[b, 0] == out[parents[b], 1]`` for every connected bone ``b``.
    """
    out = np.array(radii, dtype=float, copy=True)
    parents = np.asarray(parents, dtype=int)
    connected = np.asarray(connected, dtype=bool) & (parents >= 0)
    fitted = np.asarray(fitted, dtype=bool)
    for p in np.unique(parents[connected]):
        children = np.nonzero(connected & (parents == p))[0]
        measured = ([out[p, 1]] if fitted[p] else []) + [out[c, 0] for c in children if fitted[c]]
        value = float(np.mean(measured)) if measured else out[p, 1]
        out[p, 1] = value
        out[children, 0] = value
    return out


def _connected(connected, skeleton):
    """``connected`` checked as (B,) bool (all False when None)."""
    b = skeleton.n_joints
    if connected is None:
        return np.zeros(b, dtype=bool)
    connected = np.asarray(connected)
    if connected.shape != (b,):
        raise BodyFitError(f"Expected connected of shape ({b},), got {connected.shape}")
    return connected.astype(bool) & (np.asarray(skeleton.parents) >= 0)


def _partners(model, mirror, n_joints):
    """Part index of each part's mirror image (-1: none), (P,)."""
    partner = np.full(model.n_cylinders, -1)
    if mirror is None:
        return partner
    mirror = np.asarray(mirror, dtype=int)
    if mirror.shape != (n_joints,) or np.any(mirror >= n_joints):
        raise BodyFitError(f"Expected mirror of shape ({n_joints},) with bone indices or -1, "
                           f"got {mirror.shape}")
    part_of = np.full(n_joints, -1)
    part_of[model.joints] = np.arange(model.n_cylinders)
    for p, j in enumerate(model.joints):
        if mirror[j] >= 0 and mirror[j] != j:
            partner[p] = part_of[mirror[j]]
    return partner


def mirror_bones(names):
    """Index of each bone's mirror image by name, -1 where none, (B,) int.

    Recognises Blender's conventions (``hand.L`` / ``hand.R``, ``_L`` / ``_R``, ``-l`` / ``-r``,
    ``L_`` / ``R_`` prefixes, ``Left`` / ``Right`` anywhere, any case of these) and CMU's /
    Acclaim's ``l`` / ``r`` prefix (``lfemur`` / ``rfemur``) when both names exist.
    """
    names = list(names)
    index = {n: i for i, n in enumerate(names)}
    swaps = [("left", "right"), ("Left", "Right"), ("LEFT", "RIGHT")]
    out = np.full(len(names), -1)
    for i, name in enumerate(names):
        candidates = []
        for a, b in swaps:
            if a in name:
                candidates.append(name.replace(a, b))
            if b in name:
                candidates.append(name.replace(b, a))
        for sep in ".-_ ":
            for a, b in (("L", "R"), ("l", "r"), ("R", "L"), ("r", "l")):
                if name.endswith(sep + a):
                    candidates.append(name[:-1] + b)
                if name.startswith(a + sep):
                    candidates.append(b + name[1:])
        if name[:1] in ("l", "r"):
            candidates.append({"l": "r", "r": "l"}[name[0]] + name[1:])
        out[i] = next((index[c] for c in candidates if c in index and c != name), -1)
    return out


def _scatter(radii, model, part_radii):
    """(B, 2) radii with the model's parts set to ``part_radii`` (P, 2)."""
    out = np.array(radii, dtype=float, copy=True)
    out[model.joints] = part_radii
    return out
