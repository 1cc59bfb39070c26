"""Body model of the tracker: tapered cylinders (and boxes) on the skeleton, vectorised ray casting.

Every part is rigidly attached to one joint frame of a :class:`~core.kinematics.Skeleton`:

* **tapered cylinder** (the paper's cylinders and frusta; Blender's bone envelope radii): the
  solid of revolution about the segment ``start -> end`` (joint frame, normally joint origin ->
  bone tail) whose radius grows linearly from ``radii[0]`` at ``start`` to ``radii[1]`` at
  ``end``, closed by two flat discs;
* **box** (the paper's hands/feet and the rigid box of §5.1): an axis-aligned box of the joint
  frame, ``centre +- half_size``.

Ray casting (:func:`ray_cast`) intersects camera rays with every part that can contain the
pixel (conservative projected bounding boxes) and keeps the **front-most** hit: parts occlude
each other. It returns, per pixel, the hit point in camera coordinates, its depth, the part and
joint it belongs to and the surface normal. Symbols: B joints, P cylinders, Q boxes, M rays.
"""

import functools
from dataclasses import dataclass, field

import numpy as np


# Parts closer to the camera plane than this (metres) get a full-image bounding box.
_NEAR = 1e-3
# (ray, part) cells handled at once by :func:`ray_cast` (its bounding-box test is a dense
# rays x parts table): the peak memory of a call is a fixed budget (about 40 bytes a cell:
# 40 MB), whatever the count of parts (a 706-bone rig has 455) and of rays (a profile search
# casts millions). The front-most search works on the (ray, part) pairs only.
PAIR_BUDGET = 1 << 20


@dataclass(frozen=True, eq=False)
class BodyModel:
    """Shapes attached to joints (see the module docstring).

    Attributes
    ----------
    n_joints : int
        B, joints of the skeleton the model belongs to.
    joints : ndarray, shape (P,), int
        Joint carrying each tapered cylinder.
    starts, ends : ndarray, shape (P, 3), metres
        Cylinder axis end points in the joint frame.
    radii : ndarray, shape (P, 2), metres
        Radius at ``starts`` and at ``ends`` (>= 0, not both 0).
    box_joints : ndarray, shape (Q,), int
    box_centres, box_half_sizes : ndarray, shape (Q, 3), metres
        Boxes in the joint frame (axis-aligned with it).
    names : tuple of str
        Part names, cylinders then boxes (for messages).
    """

    n_joints: int
    joints: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    radii: np.ndarray
    box_joints: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    box_centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    box_half_sizes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    names: tuple = ()

    def __post_init__(self):
        p = len(np.atleast_1d(self.joints))
        joints = np.asarray(self.joints, dtype=int).reshape(p)
        starts = _array(self.starts, (p, 3), "starts")
        ends = _array(self.ends, (p, 3), "ends")
        radii = _array(self.radii, (p, 2), "radii")
        q = len(np.atleast_1d(self.box_joints))
        box_joints = np.asarray(self.box_joints, dtype=int).reshape(q)
        centres = _array(self.box_centres, (q, 3), "box_centres")
        half = _array(self.box_half_sizes, (q, 3), "box_half_sizes")
        if p + q == 0:
            raise ValueError("A body model needs at least one part")
        if np.any(radii < 0) or np.any(radii.max(axis=1) <= 0):
            raise ValueError("radii must be >= 0 with a positive radius at one end")
        if np.any(np.linalg.norm(ends - starts, axis=1) <= 0):
            raise ValueError("cylinder axes must have a positive length")
        if np.any(half <= 0):
            raise ValueError("box half sizes must be positive")
        all_joints = np.concatenate([joints, box_joints])
        if np.any(all_joints < 0) or np.any(all_joints >= int(self.n_joints)):
            raise ValueError(f"part joints must be in 0..{int(self.n_joints) - 1}")
        names = tuple(self.names) or tuple(f"part{i}" for i in range(p + q))
        if len(names) != p + q:
            raise ValueError(f"Expected {p + q} names, got {len(names)}")
        for attr, value in (("n_joints", int(self.n_joints)), ("joints", joints),
                            ("starts", starts), ("ends", ends), ("radii", radii),
                            ("box_joints", box_joints), ("box_centres", centres),
                            ("box_half_sizes", half), ("names", names)):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, attr, value)

    @property
    def n_cylinders(self):
        return len(self.joints)

    @property
    def n_parts(self):
        """Cylinders plus boxes; part index ``p >= n_cylinders`` is box ``p - n_cylinders``."""
        return len(self.joints) + len(self.box_joints)

    @property
    def part_joints(self):
        """(P + Q,) joint index of every part (cylinders first)."""
        return np.concatenate([self.joints, self.box_joints])


def _array(value, shape, name):
    arr = np.array(value, dtype=float)
    if arr.size == 0 and np.prod(shape) == 0:
        arr = arr.reshape(shape)
    if arr.shape != shape:
        raise ValueError(f"Expected {name} of shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def body_model_from_skeleton(skeleton, radii, min_length=0.02):
    """One tapered cylinder per bone, from the joint origin to the bone tail.

    Parameters
    ----------
    skeleton : Skeleton
    radii : array_like, shape (B, 2), metres
        Head and tail radius per joint (e.g. Blender's ``head_radius`` / ``tail_radius`` or
        :func:`core.armature.plausible_envelope_radii`). Joints with both radii 0 get no part.
    min_length : float, metres
        Bones shorter than this get no part (CMU fingers, the zero-length root of a BVH...).

    Returns
    -------
    BodyModel
    """
    radii = np.asarray(radii, dtype=float)
    b = skeleton.n_joints
    if radii.shape != (b, 2):
        raise ValueError(f"Expected radii of shape ({b}, 2), got {radii.shape}")
    lengths = np.linalg.norm(skeleton.tails, axis=1)
    keep = np.nonzero((lengths >= min_length) & (radii.max(axis=1) > 0))[0]
    return BodyModel(n_joints=b, joints=keep, starts=np.zeros((len(keep), 3)),
                     ends=skeleton.tails[keep], radii=radii[keep],
                     names=tuple(skeleton.names[j] for j in keep))


@functools.lru_cache(maxsize=16)
def _depth_groups(skeleton):
    """Joints grouped by tree depth (children of one group all have parents in earlier groups)."""
    depth = np.zeros(skeleton.n_joints, dtype=int)
    for i in range(1, skeleton.n_joints):
        depth[i] = depth[skeleton.parents[i]] + 1
    return [np.nonzero(depth == d)[0] for d in range(1, depth.max() + 1)]


def joint_frames_in_camera(skeleton, world2camera, root_translation, local_rotations):
    """Joint orientations and origins in the camera frame (FK followed by ``world2camera``).

    Same result as :func:`core.kinematics.forward_kinematics` (then ``world2camera``), computed
    one tree depth at a time (all joints of a depth in one batched product) because the tracker
    calls it for small batches of poses very often.

    Parameters
    ----------
    skeleton : Skeleton
    world2camera : array_like, shape (4, 4)
    root_translation : array_like, shape (N, 3), metres (world)
    local_rotations : array_like, shape (N, B, 3, 3)

    Returns
    -------
    rotations : ndarray, shape (N, B, 3, 3)
        Joint frame -> camera frame.
    origins : ndarray, shape (N, B, 3), metres, camera frame
    """
    w2c = np.asarray(world2camera, dtype=float)
    local = np.asarray(local_rotations, dtype=float)
    root_translation = np.asarray(root_translation, dtype=float)
    b = skeleton.n_joints
    if local.ndim != 4 or local.shape[1:] != (b, 3, 3):
        raise ValueError(f"Expected local_rotations of shape (N, {b}, 3, 3), got {local.shape}")
    n = len(local)
    if root_translation.shape != (n, 3):
        raise ValueError(f"Expected root_translation of shape ({n}, 3), got "
                         f"{root_translation.shape}")
    rot = np.empty((n, b, 3, 3))
    org = np.empty((n, b, 3))
    # Joint frames -> their parents: rest @ local (all joints at once).
    rel = skeleton.rest_rotations @ local
    rot[:, 0] = w2c[:3, :3] @ rel[:, 0]
    org[:, 0] = (skeleton.offsets[0] + root_translation) @ w2c[:3, :3].T + w2c[:3, 3]
    for group in _depth_groups(skeleton):
        parent = skeleton.parents[group]
        rp = rot[:, parent]
        rot[:, group] = rp @ rel[:, group]
        org[:, group] = org[:, parent] + np.einsum("nkij,kj->nki", rp, skeleton.offsets[group])
    return rot, org


@dataclass(frozen=True, eq=False)
class PartGeometry:
    """Parts in the camera frame at one or several poses (leading axes ``...``).

    Attributes
    ----------
    starts, axes : ndarray, shape (..., P, 3)
        Cylinder axis start (metres) and unit axis.
    lengths, r0, r1 : ndarray, shape (P,)
        Axis length and end radii (pose independent).
    box_centres : ndarray, shape (..., Q, 3)
    box_rotations : ndarray, shape (..., Q, 3, 3)
        Box frame -> camera.
    box_half_sizes : ndarray, shape (Q, 3)
    """

    starts: np.ndarray
    axes: np.ndarray
    lengths: np.ndarray
    r0: np.ndarray
    r1: np.ndarray
    box_centres: np.ndarray
    box_rotations: np.ndarray
    box_half_sizes: np.ndarray


def part_geometry(model, rotations, origins):
    """Camera-frame geometry of every part (see :class:`PartGeometry`).

    Parameters
    ----------
    model : BodyModel
    rotations : array_like, shape (..., B, 3, 3)
        Joint frame -> camera.
    origins : array_like, shape (..., B, 3), metres, camera frame
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    j = model.joints
    rj = rotations[..., j, :, :]
    starts = origins[..., j, :] + np.einsum("...pij,pj->...pi", rj, model.starts)
    seg = model.ends - model.starts
    lengths = np.linalg.norm(seg, axis=1)
    axes = np.einsum("...pij,pj->...pi", rj, seg / lengths[:, None])
    bj = model.box_joints
    rb = rotations[..., bj, :, :]
    centres = origins[..., bj, :] + np.einsum("...qij,qj->...qi", rb, model.box_centres)
    return PartGeometry(starts=starts, axes=axes, lengths=lengths, r0=model.radii[:, 0],
                        r1=model.radii[:, 1], box_centres=centres, box_rotations=rb,
                        box_half_sizes=model.box_half_sizes)


def _sphere_interval(c, cz, r, f, offset):
    """Conservative image interval of ``f x / z + offset`` over a sphere (centre c, cz; radius r).

    x in [c - r, c + r] and z in [cz - r, cz + r] (z > 0): the extremes are at the corners.
    """
    zmin, zmax = cz - r, cz + r
    lo = np.minimum((c - r) / zmin, (c - r) / zmax)
    hi = np.maximum((c + r) / zmin, (c + r) / zmax)
    return f * lo + offset, f * hi + offset


def part_bounds(model, camera, geometry):
    """Conservative pixel bounding boxes of every part.

    A tapered cylinder lies inside the convex hull of its two end spheres, a box inside its
    circumsphere; perspective projection maps a convex hull into the hull of the images.

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    geometry : PartGeometry
        From :func:`part_geometry`, leading axes ``...``.

    Returns
    -------
    ndarray, shape (..., P + Q, 4)
        ``u_min, u_max, v_min, v_max`` in pixels; parts reaching the camera plane get
        ``-inf, inf, -inf, inf``.
    """
    g = geometry
    ends = g.starts + g.axes * g.lengths[:, None]
    spheres = [(g.starts, g.r0), (ends, g.r1),
               (g.box_centres, np.linalg.norm(g.box_half_sizes, axis=1))]
    out = []
    for group in ((spheres[0], spheres[1]), (spheres[2],)):
        lo_u = hi_u = lo_v = hi_v = near = None
        for c, r in group:
            n = c[..., 2] - r <= _NEAR
            z = np.where(n, 1.0, c[..., 2])
            rr = np.where(n, 0.0, r)
            a, b = _sphere_interval(c[..., 0], z, rr, camera.fx, camera.cx)
            e, f = _sphere_interval(c[..., 1], z, rr, camera.fy, camera.cy)
            if lo_u is None:
                lo_u, hi_u, lo_v, hi_v, near = a, b, e, f, n
            else:
                lo_u, hi_u = np.minimum(lo_u, a), np.maximum(hi_u, b)
                lo_v, hi_v = np.minimum(lo_v, e), np.maximum(hi_v, f)
                near = near | n
        box = camera.widen_for_distortion(np.stack([lo_u, hi_u, lo_v, hi_v], axis=-1))
        box[near] = (-np.inf, np.inf, -np.inf, np.inf)
        out.append(box)
    return np.concatenate(out, axis=-2)


@dataclass(frozen=True, eq=False)
class RayHits:
    """Result of :func:`ray_cast` for M pixels.

    Attributes
    ----------
    hit : ndarray, shape (M,), bool
    points : ndarray, shape (M, 3), metres, camera frame (NaN where no hit)
    depth : ndarray, shape (M,), metres (z; inf where no hit)
    parts : ndarray, shape (M,), int
        Part index (cylinders first, then boxes), -1 where no hit.
    joints : ndarray, shape (M,), int
        Joint carrying the part, -1 where no hit.
    normals : ndarray, shape (M, 3) or None
        Outward unit surface normal, camera frame (0 where no hit), when requested.
    """

    hit: np.ndarray
    points: np.ndarray
    depth: np.ndarray
    parts: np.ndarray
    joints: np.ndarray
    normals: np.ndarray = None


def take_pairs(table, first, second):
    """``table[first, second]`` for index arrays of one shape, as one flat gather.

    ``np.take`` of the rows of the table seen as (A * B, ...) at ``first * B + second``: the
    same values as NumPy's two-index fancy indexing, which costs about twice as much on the
    tracker's (pose, part) and (frame, joint) lookups (docs/tracking.md, issue 22, session 38).

    Parameters
    ----------
    table : ndarray, shape (A, B, ...)
    first, second : ndarray of int, broadcast to one shape (...K)
        In [0, A) and [0, B): not checked, and unlike fancy indexing a negative index does
        not count from the end (the tracker's frame, pose, joint and part indices are never
        negative).

    Returns
    -------
    ndarray, shape (...K) + table.shape[2:]
    """
    table = np.asarray(table)
    flat = table.reshape((-1,) + table.shape[2:])
    return np.take(flat, np.asarray(first) * table.shape[1] + second, axis=0)


def _cylinder_hits(d, a, w, length, r0, r1):
    """First hit ``t`` (point ``t d``, camera at the origin) of rays on tapered cylinders, pairwise.

    d : (K, 3) ray directions; a : (K, 3) axis start; w : (K, 3) unit axis; length, r0, r1 : (K,).
    Returns t (K,) (inf where missed) and the surface hit (0 lateral, 1 start disc, 2 end disc).
    """
    k = (r1 - r0) / length
    o = -a                                             # ray origin relative to the axis start
    o_w = np.einsum("ki,ki->k", o, w)
    d_w = np.einsum("ki,ki->k", d, w)
    rho0 = r0 + k * o_w
    # |q_perp|^2 = (r0 + k s)^2 for q = o + t d, s = q . w: a quadratic in t.
    dd = np.einsum("ki,ki->k", d, d)
    od = np.einsum("ki,ki->k", o, d)
    qa = dd - (1.0 + k * k) * d_w * d_w
    qb = 2.0 * (od - o_w * d_w - k * d_w * rho0)
    oo = np.einsum("ki,ki->k", o, o)
    qc = oo - o_w * o_w - rho0 * rho0
    disc = qb * qb - 4.0 * qa * qc
    best = np.full(len(d), np.inf)
    surface = np.zeros(len(d), dtype=int)
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.maximum(disc, 0.0))
        valid = (disc >= 0) & (np.abs(qa) > 1e-12)
        for sign in (-1.0, 1.0):
            t = (-qb + sign * sq) / (2.0 * qa)
            s = o_w + t * d_w
            ok = valid & (t > 0) & (s >= 0) & (s <= length)
            best = np.where(ok & (t < best), t, best)
        for sid, (s0, radius) in enumerate(((0.0, r0), (length, r1)), start=1):
            t = (s0 - o_w) / d_w
            # |o + t d|^2 - s0^2 = squared distance from the axis on the cap plane.
            perp2 = oo + 2.0 * t * od + t * t * dd - s0 * s0
            ok = (np.abs(d_w) > 1e-12) & (t > 0) & (perp2 <= radius * radius)
            better = ok & (t < best)
            best = np.where(better, t, best)
            surface = np.where(better, sid, surface)
    return best, surface


def _box_hits(d, centre, axes, half):
    """First hit ``t`` of rays on oriented boxes (slab method), pairwise, and the hit face axis.

    d : (K, 3); centre : (K, 3); axes : (K, 3, 3) box frame -> camera; half : (K, 3).
    """
    o = np.einsum("kji,kj->ki", axes, -centre)          # ray origin in the box frame
    dl = np.einsum("kji,kj->ki", axes, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - o) / dl
        t2 = (half - o) / dl
    lo = np.minimum(t1, t2)
    hi = np.maximum(t1, t2)
    # A ray parallel to a slab hits only if its origin lies between the planes.
    parallel = dl == 0
    inside = np.abs(o) <= half
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
    t_near = lo.max(axis=1)
    t_far = hi.min(axis=1)
    ok = (t_near <= t_far) & (t_near > 0)
    return np.where(ok, t_near, np.inf), lo.argmax(axis=1)


def _pair_hits(model, geo, d, ray_idx, part_idx, frames):
    """Hit depth and surface id of (ray, part) pairs; rays have z = 1 so ``t`` is the depth."""
    n_cyl = model.n_cylinders
    t = np.full(len(ray_idx), np.inf)
    face = np.zeros(len(ray_idx), dtype=np.int8)
    cyl = part_idx < n_cyl
    if np.any(cyl):
        mi, pi = ray_idx[cyl], part_idx[cyl]
        fi = frames[mi]
        t[cyl], face[cyl] = _cylinder_hits(np.take(d, mi, axis=0), take_pairs(geo.starts, fi, pi),
                                           take_pairs(geo.axes, fi, pi), geo.lengths[pi],
                                           geo.r0[pi], geo.r1[pi])
    if not np.all(cyl):
        box = ~cyl
        mi, q = ray_idx[box], part_idx[box] - n_cyl
        fi = frames[mi]
        t[box], face[box] = _box_hits(np.take(d, mi, axis=0), take_pairs(geo.box_centres, fi, q),
                                      take_pairs(geo.box_rotations, fi, q), geo.box_half_sizes[q])
    return t, face


def _front_most(model, d, ray_idx, part_idx, t, face):
    """Per ray, the nearest hit among its pairs: (hit, depth, parts, face). Ties go to the
    lower part index.

    Unbuffered minima over the pairs (``np.minimum.at``): the depth of each ray, then the
    lowest part among the pairs at that depth. Work and memory grow with the pairs and rays,
    not with rays x parts (a dense (rays, parts) table and its ``argmin`` cost 5x the time on
    the real footage's silhouettes, docs/tracking.md, issue 22 stop 36). Rays without a hit
    have depth inf, part -1 and face 0.
    """
    m = len(d)
    depth = np.full(m, np.inf)
    np.minimum.at(depth, ray_idx, t)
    hit = np.isfinite(depth)
    at_depth = (t == depth[ray_idx]) & np.isfinite(t)
    rays, candidates = ray_idx[at_depth], part_idx[at_depth]
    parts = np.full(m, model.n_parts)
    np.minimum.at(parts, rays, candidates)
    winner = candidates == parts[rays]                  # one pair per hit ray
    faces = np.zeros(m, dtype=np.int8)
    faces[rays[winner]] = face[at_depth][winner]
    parts[~hit] = -1
    return hit, depth, parts, faces


def _hits(model, geo, d, frames, ray_idx, part_idx, normals):
    t, face = _pair_hits(model, geo, d, ray_idx, part_idx, frames)
    hit, depth, parts, face = _front_most(model, d, ray_idx, part_idx, t, face)
    hit_rows = np.flatnonzero(hit)
    points = np.full(d.shape, np.nan)
    points[hit_rows] = d[hit_rows] * depth[hit_rows, None]
    joints = np.where(hit, model.part_joints[np.maximum(parts, 0)], -1)
    out_normals = _normals(model, geo, frames, points, parts, face, hit) if normals else None
    return RayHits(hit=hit, points=points, depth=depth, parts=parts, joints=joints,
                   normals=out_normals)


def ray_cast(model, camera, rotations, origins, pixels, frames=None, normals=False,
             geometry=None, bounds=None):
    """Front-most body surface point seen through each pixel (occlusion between parts).

    Every ray is intersected with every part whose conservative bounding box
    (:func:`part_bounds`) contains the pixel; the nearest intersection wins. Rays are cast
    :data:`PAIR_BUDGET` (ray, part) cells at a time (fixed peak memory).

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    rotations : array_like, shape (B, 3, 3) or (N, B, 3, 3)
        Joint frame -> camera frame at the pose(s) (see :func:`joint_frames_in_camera`).
    origins : array_like, shape (B, 3) or (N, B, 3), metres, camera frame
    pixels : array_like, shape (M, 2), pixels (u, v)
    frames : array_like, shape (M,), int, optional
        Pose index of each ray when N poses are given (rays of many frames in one call).
    normals : bool
        Also compute surface normals.
    geometry, bounds : optional
        :func:`part_geometry` / :func:`part_bounds` if already computed.

    Returns
    -------
    RayHits
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if pixels.ndim != 2 or pixels.shape[1] != 2:
        raise ValueError(f"Expected pixels of shape (M, 2), got {pixels.shape}")
    if rotations.ndim == 3:
        rotations, origins = rotations[None], origins[None]
    m = len(pixels)
    frames = np.zeros(m, dtype=int) if frames is None else np.asarray(frames, dtype=int)
    if frames.shape != (m,):
        raise ValueError(f"Expected frames of shape ({m},), got {frames.shape}")
    geo = part_geometry(model, rotations, origins) if geometry is None else geometry
    if bounds is None:
        bounds = part_bounds(model, camera, geo)
    step = max(1, PAIR_BUDGET // max(model.n_parts, 1))
    if m <= step:
        return _cast(model, camera, geo, bounds, pixels, frames, normals)
    blocks = [_cast(model, camera, geo, bounds, pixels[a:a + step], frames[a:a + step], normals)
              for a in range(0, m, step)]
    return RayHits(**{name: (None if getattr(blocks[0], name) is None else
                             np.concatenate([getattr(b, name) for b in blocks]))
                      for name in ("hit", "points", "depth", "parts", "joints", "normals")})


def _cast(model, camera, geo, bounds, pixels, frames, normals):
    """:func:`ray_cast` of a block of rays (all at once)."""
    b = bounds[frames]                                   # (M, P + Q, 4)
    u, v = pixels[:, 0:1], pixels[:, 1:2]
    inside = (u >= b[..., 0]) & (u <= b[..., 1]) & (v >= b[..., 2]) & (v <= b[..., 3])
    del b
    ray_idx, part_idx = np.nonzero(inside)
    return _hits(model, geo, camera.rays(pixels, only=ray_idx), frames, ray_idx, part_idx, normals)


def _normals(model, geo, frames, points, parts, face, hit):
    """Outward unit normals at hit points (see :func:`ray_cast`)."""
    out = np.zeros(points.shape)
    n_cyl = model.n_cylinders
    sel = np.nonzero(hit & (parts < n_cyl))[0]
    if len(sel):
        pi, fi = parts[sel], frames[sel]
        a, w = geo.starts[fi, pi], geo.axes[fi, pi]
        rel = points[sel] - a
        s = np.einsum("ki,ki->k", rel, w)
        perp = rel - s[:, None] * w
        k = (geo.r1[pi] - geo.r0[pi]) / geo.lengths[pi]
        # Gradient of |q_perp|^2 - (r0 + k s)^2 (up to a factor 2; rho > 0 on the surface).
        lateral = perp - ((geo.r0[pi] + k * s) * k)[:, None] * w
        f = face[sel]
        n = np.where((f == 0)[:, None], lateral, np.where((f == 1)[:, None], -w, w))
        out[sel] = n / np.linalg.norm(n, axis=1, keepdims=True)
    sel = np.nonzero(hit & (parts >= n_cyl))[0]
    if len(sel):
        q, fi = parts[sel] - n_cyl, frames[sel]
        rot = geo.box_rotations[fi, q]
        local = np.einsum("kji,kj->ki", rot, points[sel] - geo.box_centres[fi, q])
        rows = np.arange(len(sel))
        ax = face[sel].astype(int)
        n_local = np.zeros((len(sel), 3))
        n_local[rows, ax] = np.sign(local[rows, ax])
        out[sel] = np.einsum("kij,kj->ki", rot, n_local)
    return out


@dataclass(frozen=True, eq=False)
class SilhouetteSamples:
    """Model points seen on a regular pixel grid, for N poses (:func:`sample_silhouette`).

    Attributes
    ----------
    frames : ndarray, shape (M,), int
        Pose index of each sample (sorted).
    pixels : ndarray, shape (M, 2)
        Grid pixels (u, v) that hit the model.
    points : ndarray, shape (M, 3), metres, camera frame
    joints, parts : ndarray, shape (M,), int
    interior : ndarray, shape (M,), bool
        Every grid point within the edge margin hits the same part: away from silhouette and
        occlusion edges.
    strides : ndarray, shape (N,)
        Grid spacing per pose, pixels (each sample stands for ``stride**2`` pixels).
    grid_origin : ndarray, shape (N, 2)
        Pixel (u, v) of each pose's first grid node.
    grid_shape : ndarray, shape (N, 2), int
        Rows and columns of each pose's grid.
    grid_start : ndarray, shape (N,), int
        Offset of each pose's nodes in ``node_parts`` / ``node_depth`` (row-major).
    node_parts : ndarray, shape (G,), int
        Part seen at every grid node (-1: background).
    node_depth : ndarray, shape (G,)
        Depth at every grid node (inf: background).
    occluded : ndarray, shape (M,), bool, or None
        Samples hidden behind another body (:func:`.occluders.hide_behind`; None: not
        tested). They are not ``interior`` and their nodes read as background.
    """

    frames: np.ndarray
    pixels: np.ndarray
    points: np.ndarray
    joints: np.ndarray
    parts: np.ndarray
    interior: np.ndarray
    strides: np.ndarray
    grid_origin: np.ndarray
    grid_shape: np.ndarray
    grid_start: np.ndarray
    node_parts: np.ndarray
    node_depth: np.ndarray
    occluded: np.ndarray = None

    @property
    def count(self):
        return len(self.pixels)

    @property
    def n_poses(self):
        return len(self.strides)

    def counts(self):
        """(N,) samples per pose."""
        return np.bincount(self.frames, minlength=self.n_poses)

    def poses(self, first, stop):
        """The samples of poses ``first .. stop - 1``, renumbered from 0."""
        a, b = np.searchsorted(self.frames, [first, stop])
        g0 = self.grid_start[first] if first < self.n_poses else len(self.node_parts)
        g1 = self.grid_start[stop] if stop < self.n_poses else len(self.node_parts)
        return SilhouetteSamples(
            frames=self.frames[a:b] - first, pixels=self.pixels[a:b], points=self.points[a:b],
            joints=self.joints[a:b], parts=self.parts[a:b], interior=self.interior[a:b],
            strides=self.strides[first:stop], grid_origin=self.grid_origin[first:stop],
            grid_shape=self.grid_shape[first:stop],
            grid_start=self.grid_start[first:stop] - g0, node_parts=self.node_parts[g0:g1],
            node_depth=self.node_depth[g0:g1],
            occluded=None if self.occluded is None else self.occluded[a:b])

    def subset(self, index):
        """Only the samples ``index`` (grids kept)."""
        return SilhouetteSamples(
            frames=self.frames[index], pixels=self.pixels[index], points=self.points[index],
            joints=self.joints[index], parts=self.parts[index], interior=self.interior[index],
            strides=self.strides, grid_origin=self.grid_origin, grid_shape=self.grid_shape,
            grid_start=self.grid_start, node_parts=self.node_parts, node_depth=self.node_depth,
            occluded=None if self.occluded is None else self.occluded[index])

    def lookup(self, poses, pixels):
        """Part and depth at the grid node nearest to each pixel (-1 / inf outside the grid).

        Parameters
        ----------
        poses : array_like, shape (K,), int
        pixels : array_like, shape (K, 2)

        Returns
        -------
        parts : ndarray, shape (K,), int
        depth : ndarray, shape (K,)
        """
        poses = np.asarray(poses, dtype=int)
        pixels = np.asarray(pixels, dtype=float)
        stride = self.strides[poses]
        rel = (pixels - self.grid_origin[poses]) / stride[:, None]
        rel = np.where(np.isfinite(rel), rel, -1.0)
        col = np.rint(rel[:, 0]).astype(np.intp)
        row = np.rint(rel[:, 1]).astype(np.intp)
        rows, cols = self.grid_shape[poses, 0], self.grid_shape[poses, 1]
        ok = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
        node = np.where(ok, self.grid_start[poses] + row * cols + col, 0)
        if len(self.node_parts) == 0:
            return np.full(len(poses), -1), np.full(len(poses), np.inf)
        return (np.where(ok, self.node_parts[node], -1),
                np.where(ok, self.node_depth[node], np.inf))


def projected_area(model, camera, geometry):
    """Rough projected area (pixels) of the body per pose, parts counted separately, (...,)."""
    area, box = _part_areas(camera, geometry)
    return area.sum(axis=-1) + box.sum(axis=-1)


def part_areas(model, camera, geometry):
    """Rough projected area (pixels) of every part on its own (..., P + Q), cylinders first."""
    area, box = _part_areas(camera, geometry)
    return np.concatenate([area, np.broadcast_to(box, area.shape[:-1] + box.shape[-1:])],
                          axis=-1)


def _part_areas(camera, geometry):
    """Cylinders' (..., P) and boxes' (..., Q) rough projected areas, pixels."""
    g = geometry
    f = 0.5 * (camera.fx + camera.fy)
    ends = g.starts + g.axes * g.lengths[:, None]
    za = np.maximum(g.starts[..., 2], _NEAR)
    zb = np.maximum(ends[..., 2], _NEAR)
    ua = g.starts[..., :2] / za[..., None] * f
    ub = ends[..., :2] / zb[..., None] * f
    da = 2.0 * g.r0 * f / za
    db = 2.0 * g.r1 * f / zb
    area = np.linalg.norm(ub - ua, axis=-1) * 0.5 * (da + db) + 0.785 * np.maximum(da, db) ** 2
    zc = np.maximum(g.box_centres[..., 2], _NEAR)
    box = 3.0 * np.sort(g.box_half_sizes, axis=1)[:, 1:].prod(axis=1) * (f / zc) ** 2
    return area, box


def _capsule_rows(model, camera, geo, poses, parts, v):
    """Column range (u_lo, u_hi) where row ``v`` may meet each part (conservative, pixels).

    A tapered cylinder lies inside the hull of its two end spheres, whose images lie inside
    discs of radius ``f r / (z - r)`` (stretched by up to ``1 + tan^2`` of the off-axis angle)
    around the projected end points: inside the 2-D capsule of the projected axis with the
    larger radius. A capsule is convex, so it cuts a row to one interval: the union of the row
    with the two end discs and with the band along the segment. Boxes and parts near the camera
    plane get ``(-inf, inf)``.
    """
    k = len(poses)
    u_lo, u_hi = np.full(k, -np.inf), np.full(k, np.inf)
    cyl = np.nonzero(parts < model.n_cylinders)[0]
    if not len(cyl):
        return u_lo, u_hi
    f, p, v = poses[cyl], parts[cyl], v[cyl]
    a = take_pairs(geo.starts, f, p)
    b = a + take_pairs(geo.axes, f, p) * geo.lengths[p][:, None]
    r0, r1 = geo.r0[p], geo.r1[p]
    za, zb = a[:, 2] - r0, b[:, 2] - r1
    near = (za <= _NEAR) | (zb <= _NEAR)
    za, zb = np.where(near, 1.0, za), np.where(near, 1.0, zb)
    za_c, zb_c = np.maximum(a[:, 2], _NEAR), np.maximum(b[:, 2], _NEAR)
    ua = camera.fx * a[:, 0] / za_c + camera.cx
    va = camera.fy * a[:, 1] / za_c + camera.cy
    ub = camera.fx * b[:, 0] / zb_c + camera.cx
    vb = camera.fy * b[:, 1] / zb_c + camera.cy
    stretch_a = 1.0 + (a[:, 0] ** 2 + a[:, 1] ** 2) / za_c ** 2
    stretch_b = 1.0 + (b[:, 0] ** 2 + b[:, 1] ** 2) / zb_c ** 2
    radius = max(camera.fx, camera.fy) * np.maximum(stretch_a * r0 / za, stretch_b * r1 / zb) + 1.0
    if camera.distortion is not None:   # the lens moves the capsule by up to this much
        radius = radius + camera.distortion_margin_near(
            np.minimum(ua, ub) - radius, np.maximum(ua, ub) + radius,
            np.minimum(va, vb) - radius, np.maximum(va, vb) + radius)
    lo, hi = np.full(len(cyl), np.inf), np.full(len(cyl), -np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        # End discs.
        for uc, vc in ((ua, va), (ub, vb)):
            h2 = radius ** 2 - (v - vc) ** 2
            half = np.sqrt(np.maximum(h2, 0.0))
            lo = np.where(h2 >= 0, np.minimum(lo, uc - half), lo)
            hi = np.where(h2 >= 0, np.maximum(hi, uc + half), hi)
        # Band: 0 <= (q - a) . d <= L and |(q - a) . n| <= R, q = (u, v); linear in u.
        du, dv = ub - ua, vb - va
        length = np.hypot(du, dv)
        dx, dy = du / np.maximum(length, 1e-12), dv / np.maximum(length, 1e-12)
        along0 = (v - va) * dy                      # along = (u - ua) dx + along0
        across0 = (v - va) * dx                     # across = -(u - ua) dy + across0
        band_lo, band_hi = np.full(len(cyl), -np.inf), np.full(len(cyl), np.inf)
        for coef, const, low, high in ((dx, along0, 0.0, length), (-dy, across0, -radius, radius)):
            t1 = (low - const) / coef
            t2 = (high - const) / coef
            nz = np.abs(coef) > 1e-12
            inside = (const >= low) & (const <= high)
            band_lo = np.where(nz, np.maximum(band_lo, np.minimum(t1, t2)),
                               np.where(inside, band_lo, np.inf))
            band_hi = np.where(nz, np.minimum(band_hi, np.maximum(t1, t2)),
                               np.where(inside, band_hi, -np.inf))
        ok = band_lo <= band_hi
        lo = np.where(ok, np.minimum(lo, ua + band_lo), lo)
        hi = np.where(ok, np.maximum(hi, ua + band_hi), hi)
    u_lo[cyl] = np.where(near, -np.inf, lo)
    u_hi[cyl] = np.where(near, np.inf, hi)
    return u_lo, u_hi


def sample_silhouette(model, camera, rotations, origins, budget, min_stride=1.0, edge_margin=1.5):
    """Ray-cast a regular pixel grid over the model's image at N poses: about ``budget`` hits each.

    The grid spacing is chosen from the projected area so that the silhouette holds about
    ``budget`` grid points (never denser than ``min_stride`` pixels): the cost does not grow with
    the image resolution. Rays are paired only with the parts whose bounding box covers them
    (a sub-rectangle of the grid, enumerated without testing every node), and all poses are
    cast in one vectorised call.

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    rotations : array_like, shape (N, B, 3, 3)
    origins : array_like, shape (N, B, 3)
    budget : int
    min_stride : float, pixels
    edge_margin : float, pixels
        A sample is ``interior`` when every grid node within this distance (at least the
        8 neighbours) hits the same part.

    Returns
    -------
    SilhouetteSamples
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    if rotations.ndim != 4:
        raise ValueError(f"Expected rotations of shape (N, B, 3, 3), got {rotations.shape}")
    n = len(rotations)
    geo = part_geometry(model, rotations, origins)
    bounds = part_bounds(model, camera, geo)                       # (N, P + Q, 4)
    area = projected_area(model, camera, geo)
    lo_u = np.maximum(0.0, bounds[..., 0].min(axis=1))
    hi_u = np.minimum(camera.width - 1.0, bounds[..., 1].max(axis=1))
    lo_v = np.maximum(0.0, bounds[..., 2].min(axis=1))
    hi_v = np.minimum(camera.height - 1.0, bounds[..., 3].max(axis=1))
    empty = ~((hi_u >= lo_u) & (hi_v >= lo_v))
    span = np.where(empty, 1.0, (hi_u - lo_u + 1.0) * (hi_v - lo_v + 1.0))
    strides = np.maximum(float(min_stride), np.sqrt(np.minimum(area, span) / max(int(budget), 1)))
    cols = np.where(empty, 0, np.floor((hi_u - lo_u) / strides + 1e-9).astype(int) + 1)
    rows = np.where(empty, 0, np.floor((hi_v - lo_v) / strides + 1e-9).astype(int) + 1)
    origin = np.stack([lo_u, lo_v], axis=1)
    sizes = rows * cols
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    total = int(sizes.sum())
    # All grid nodes: pose, row, column -> pixel.
    node_pose = np.repeat(np.arange(n), sizes)
    k = np.arange(total) - start[node_pose]
    node_row, node_col = np.divmod(k, np.maximum(cols[node_pose], 1))
    # Column by column: the same products and sums as origin + stride * (col, row), without the
    # (total, 2) integer stack and its broadcast (docs/tracking.md, issue 22, session 38).
    node_stride = strides[node_pose]
    pixels = np.empty((total, 2))
    np.add(origin[node_pose, 0], node_stride * node_col, out=pixels[:, 0])
    np.add(origin[node_pose, 1], node_stride * node_row, out=pixels[:, 1])
    # Pairs (node, part): the grid sub-rectangle inside each part's bounding box.
    s = strides[:, None]
    c0 = np.clip(np.ceil((bounds[..., 0] - lo_u[:, None]) / s - 1e-9), 0, cols[:, None])
    c1 = np.clip(np.floor((bounds[..., 1] - lo_u[:, None]) / s + 1e-9) + 1, 0, cols[:, None])
    r0 = np.clip(np.ceil((bounds[..., 2] - lo_v[:, None]) / s - 1e-9), 0, rows[:, None])
    r1 = np.clip(np.floor((bounds[..., 3] - lo_v[:, None]) / s + 1e-9) + 1, 0, rows[:, None])
    # One grid row of one part's rectangle at a time: the 2-D capsule bound of the part cuts
    # each row to a column interval, so only plausible (node, part) pairs are generated.
    h = np.maximum(r1 - r0, 0).astype(int).ravel()
    b_pose, b_part = np.divmod(np.arange(h.size), bounds.shape[1])
    row_block = np.repeat(np.arange(h.size), h)
    row = r0.ravel()[row_block].astype(int) + np.arange(row_block.size) \
        - np.repeat(np.cumsum(h) - h, h)
    pose, part = b_pose[row_block], b_part[row_block]
    lo = c0.ravel()[row_block]
    hi = c1.ravel()[row_block]
    cut_lo, cut_hi = _capsule_rows(model, camera, geo, pose, part,
                                   lo_v[pose] + strides[pose] * row)
    lo = np.maximum(lo, np.ceil((cut_lo - lo_u[pose]) / strides[pose] - 1e-9))
    hi = np.minimum(hi, np.floor((cut_hi - lo_u[pose]) / strides[pose] + 1e-9) + 1)
    width = np.maximum(hi - lo, 0).astype(int)
    pair_row = np.repeat(np.arange(row.size), width)
    col = lo[pair_row].astype(int) + np.arange(pair_row.size) - np.repeat(np.cumsum(width) - width,
                                                                         width)
    pp = pose[pair_row]
    ray_idx = start[pp] + row[pair_row] * cols[pp] + col
    part_idx = part[pair_row]
    hits = _hits(model, geo, camera.rays(pixels, only=ray_idx), node_pose, ray_idx, part_idx,
                 normals=False)
    interior = np.zeros(total, dtype=bool)
    for f in range(n):
        if sizes[f] == 0:
            continue
        labels = hits.parts[start[f]:start[f] + sizes[f]].reshape(rows[f], cols[f])
        r = max(1, int(np.ceil(edge_margin / strides[f])))
        pad = np.full((rows[f] + 2 * r, cols[f] + 2 * r), -1, dtype=labels.dtype)
        pad[r:r + rows[f], r:r + cols[f]] = labels                  # np.pad's result, cheaper
        same = np.ones(labels.shape, dtype=bool)
        for dv in range(-r, r + 1):
            for du in range(-r, r + 1):
                if dv or du:
                    same &= pad[r + dv:r + dv + rows[f], r + du:r + du + cols[f]] == labels
        interior[start[f]:start[f] + sizes[f]] = same.ravel()
    hit = np.flatnonzero(hits.hit)
    return SilhouetteSamples(frames=node_pose[hit], pixels=pixels[hit], points=hits.points[hit],
                             joints=hits.joints[hit], parts=hits.parts[hit],
                             interior=interior[hit], strides=strides, grid_origin=origin,
                             grid_shape=np.stack([rows, cols], axis=1), grid_start=start,
                             node_parts=hits.parts, node_depth=hits.depth)
