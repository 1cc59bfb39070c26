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

from dataclasses import dataclass, field

import numpy as np

from ..kinematics import forward_kinematics

# Parts closer to the camera plane than this (metres) get a full-image bounding box.
_NEAR = 1e-3


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
    arr = np.array(value, dtype=float).reshape(shape) if np.size(value) == np.prod(shape) \
        else np.array(value, dtype=float)
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


def joint_frames_in_camera(skeleton, world2camera, root_translation, local_rotations):
    """Joint orientations and origins in the camera frame (FK followed by ``world2camera``).

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
    rot, pos = forward_kinematics(skeleton, local_rotations, root_translation)
    return w2c[:3, :3] @ rot, pos @ w2c[:3, :3].T + w2c[:3, 3]


def _interval_bounds(cx, cz, r, f, c):
    """Conservative image interval of the coordinate ``f * x / z + c`` over a sphere.

    x in [cx - r, cx + r], z in [cz - r, cz + r] (z > 0): extremes at the four corners.
    """
    zmin = cz - r
    zmax = cz + r
    cands = np.stack([(cx - r) / zmin, (cx - r) / zmax, (cx + r) / zmin, (cx + r) / zmax])
    return f * cands.min(axis=0) + c, f * cands.max(axis=0) + c


def part_bounds(model, camera, rotations, origins):
    """Conservative pixel bounding boxes of every part.

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    rotations : array_like, shape (B, 3, 3)
        Joint frame -> camera.
    origins : array_like, shape (B, 3), camera frame, metres

    Returns
    -------
    ndarray, shape (P + Q, 4)
        ``u_min, u_max, v_min, v_max`` in pixels (parts reaching the camera plane get
        ``-inf, inf, -inf, inf``).
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    # Cylinders: inside the hull of the two end spheres; boxes: inside their circumsphere.
    j = model.joints
    centres = [origins[j] + np.einsum("pij,pj->pi", rotations[j], model.starts),
               origins[j] + np.einsum("pij,pj->pi", rotations[j], model.ends)]
    rad = [model.radii[:, 0], model.radii[:, 1]]
    bj = model.box_joints
    box_c = origins[bj] + np.einsum("qij,qj->qi", rotations[bj], model.box_centres)
    box_r = np.linalg.norm(model.box_half_sizes, axis=1)
    out = []
    for c_list, r_list in ((centres, rad), ([box_c], [box_r])):
        lo_u, hi_u, lo_v, hi_v, near = [], [], [], [], []
        for c, r in zip(c_list, r_list):
            near.append(c[:, 2] - r <= _NEAR)
            z = np.where(near[-1], 1.0, c[:, 2])
            rr = np.where(near[-1], 0.0, r)
            a, b = _interval_bounds(c[:, 0], z, rr, camera.fx, camera.cx)
            lo_u.append(a), hi_u.append(b)
            a, b = _interval_bounds(c[:, 1], z, rr, camera.fy, camera.cy)
            lo_v.append(a), hi_v.append(b)
        box = np.stack([np.min(lo_u, axis=0), np.max(hi_u, axis=0),
                        np.min(lo_v, axis=0), np.max(hi_v, axis=0)], axis=1)
        box[np.any(near, axis=0)] = (-np.inf, np.inf, -np.inf, np.inf)
        out.append(box)
    return np.concatenate(out, axis=0)


@dataclass(frozen=True, eq=False)
class RayHits:
    """Result of :func:`ray_cast` for M pixels.

    Attributes
    ----------
    hit : ndarray, shape (M,), bool
    points : ndarray, shape (M, 3), metres, camera frame (NaN where no hit)
    depth : ndarray, shape (M,), metres (inf where no hit)
    parts : ndarray, shape (M,), int
        Part index (cylinders first, then boxes), -1 where no hit.
    joints : ndarray, shape (M,), int
        Joint carrying the part, -1 where no hit.
    normals : ndarray, shape (M, 3)
        Outward unit surface normal, camera frame (0 where no hit).
    """

    hit: np.ndarray
    points: np.ndarray
    depth: np.ndarray
    parts: np.ndarray
    joints: np.ndarray
    normals: np.ndarray


def _cylinder_hits(d, a, w, length, r0, r1):
    """First hit parameter ``t`` (point ``t d``) of rays on tapered cylinders, pairwise.

    d : (K, 3) ray directions (camera at the origin); a : (K, 3) axis start; w : (K, 3) unit
    axis; length, r0, r1 : (K,). Returns t (K,) (inf where missed) and the surface id
    (0 lateral, 1 start disc, 2 end disc).
    """
    k = (r1 - r0) / length
    o = -a                                             # ray origin relative to the axis start
    o_w = np.einsum("ki,ki->k", o, w)
    d_w = np.einsum("ki,ki->k", d, w)
    rho0 = r0 + k * o_w
    # |q_perp|^2 = (r0 + k s)^2 with q = o + t d, s = q . w: a quadratic in t.
    qa = np.einsum("ki,ki->k", d, d) - (1.0 + k * k) * d_w * d_w
    qb = 2.0 * (np.einsum("ki,ki->k", o, d) - o_w * d_w - k * d_w * rho0)
    qc = np.einsum("ki,ki->k", o, o) - o_w * o_w - rho0 * rho0
    disc = qb * qb - 4.0 * qa * qc
    best = np.full(len(d), np.inf)
    surface = np.zeros(len(d), dtype=int)
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        for sign in (-1.0, 1.0):
            t = (-qb + sign * sq) / (2.0 * qa)
            s = o_w + t * d_w
            ok = (disc >= 0) & (np.abs(qa) > 1e-12) & (t > 0) & (s >= 0) & (s <= length)
            better = ok & (t < best)
            best = np.where(better, t, best)
        for sid, (s0, radius) in enumerate(((0.0, r0), (length, r1)), start=1):
            t = (s0 - o_w) / d_w
            q = o + t[:, None] * d
            perp2 = np.einsum("ki,ki->k", q, q) - s0 * s0
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
    lo = np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2))
    hi = np.where(np.isnan(t1), np.inf, np.maximum(t1, t2))
    # A ray parallel to a slab hits only if its origin lies between the planes.
    parallel = dl == 0
    inside = np.abs(o) <= half
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
    t_near = lo.max(axis=1)
    t_far = hi.min(axis=1)
    ok = (t_near <= t_far) & (t_near > 0)
    return np.where(ok, t_near, np.inf), lo.argmax(axis=1)


def ray_cast(model, camera, rotations, origins, pixels, bounds=None):
    """Front-most body surface point seen through each pixel (occlusion between parts).

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    rotations : array_like, shape (B, 3, 3)
        Joint frame -> camera frame at the pose (see :func:`joint_frames_in_camera`).
    origins : array_like, shape (B, 3), metres, camera frame
    pixels : array_like, shape (M, 2), pixels (u, v)
    bounds : array_like, shape (P + Q, 4), optional
        :func:`part_bounds` if already computed.

    Returns
    -------
    RayHits
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if pixels.ndim != 2 or pixels.shape[1] != 2:
        raise ValueError(f"Expected pixels of shape (M, 2), got {pixels.shape}")
    if bounds is None:
        bounds = part_bounds(model, camera, rotations, origins)
    m = len(pixels)
    n_cyl = model.n_cylinders
    u, v = pixels[:, 0:1], pixels[:, 1:2]
    inside = (u >= bounds[:, 0]) & (u <= bounds[:, 1]) & (v >= bounds[:, 2]) & (v <= bounds[:, 3])
    ray_idx, part_idx = np.nonzero(inside)
    d_all = camera.rays(pixels)
    t_mat = np.full((m, model.n_parts), np.inf)
    face = np.zeros((m, model.n_parts), dtype=int)
    cyl = part_idx < n_cyl
    if np.any(cyl):
        mi, pi = ray_idx[cyl], part_idx[cyl]
        j = model.joints[pi]
        a = origins[j] + np.einsum("kij,kj->ki", rotations[j], model.starts[pi])
        axis = np.einsum("kij,kj->ki", rotations[j], model.ends[pi] - model.starts[pi])
        length = np.linalg.norm(axis, axis=1)
        t, surf = _cylinder_hits(d_all[mi], a, axis / length[:, None], length,
                                 model.radii[pi, 0], model.radii[pi, 1])
        t_mat[mi, pi] = t
        face[mi, pi] = surf
    box = ~cyl
    if np.any(box):
        mi, pi = ray_idx[box], part_idx[box]
        q = pi - n_cyl
        j = model.box_joints[q]
        centre = origins[j] + np.einsum("kij,kj->ki", rotations[j], model.box_centres[q])
        t, ax = _box_hits(d_all[mi], centre, rotations[j], model.box_half_sizes[q])
        t_mat[mi, pi] = t
        face[mi, pi] = ax
    parts = np.argmin(t_mat, axis=1) if model.n_parts else np.zeros(m, dtype=int)
    depth = t_mat[np.arange(m), parts]
    hit = np.isfinite(depth)
    parts = np.where(hit, parts, -1)
    points = np.where(hit[:, None], d_all * np.where(hit, depth, 0.0)[:, None], np.nan)
    normals = _normals(model, rotations, origins, points, parts, face[np.arange(m), np.maximum(parts, 0)],
                       hit)
    joints = np.where(hit, model.part_joints[np.maximum(parts, 0)], -1)
    return RayHits(hit=hit, points=points, depth=depth, parts=parts, joints=joints, normals=normals)


def _normals(model, rotations, origins, points, parts, face, hit):
    """Outward unit normals at hit points (see :func:`ray_cast`)."""
    out = np.zeros_like(np.nan_to_num(points))
    n_cyl = model.n_cylinders
    sel = np.nonzero(hit & (parts < n_cyl))[0]
    if len(sel):
        pi = parts[sel]
        j = model.joints[pi]
        a = origins[j] + np.einsum("kij,kj->ki", rotations[j], model.starts[pi])
        axis = np.einsum("kij,kj->ki", rotations[j], model.ends[pi] - model.starts[pi])
        length = np.linalg.norm(axis, axis=1)
        w = axis / length[:, None]
        rel = points[sel] - a
        s = np.einsum("ki,ki->k", rel, w)
        perp = rel - s[:, None] * w
        k = (model.radii[pi, 1] - model.radii[pi, 0]) / length
        # Gradient of |q_perp|^2 - (r0 + k s)^2, up to a factor 2 (rho > 0 on the surface).
        rho = model.radii[pi, 0] + k * s
        lateral = perp - (rho * k)[:, None] * w
        f = face[sel]
        n = np.where((f == 0)[:, None], lateral, np.where((f == 1)[:, None], -w, w))
        out[sel] = n / np.linalg.norm(n, axis=1, keepdims=True)
    sel = np.nonzero(hit & (parts >= n_cyl))[0]
    if len(sel):
        q = parts[sel] - n_cyl
        j = model.box_joints[q]
        rot = rotations[j]
        centre = origins[j] + np.einsum("kij,kj->ki", rot, model.box_centres[q])
        local = np.einsum("kji,kj->ki", rot, points[sel] - centre)
        ax = face[sel]
        n_local = np.zeros((len(sel), 3))
        n_local[np.arange(len(sel)), ax] = np.sign(local[np.arange(len(sel)), ax])
        out[sel] = np.einsum("kij,kj->ki", rot, n_local)
    return out


@dataclass(frozen=True, eq=False)
class SilhouetteSamples:
    """Model points seen on a regular pixel grid (:func:`sample_silhouette`), hits only.

    Attributes
    ----------
    pixels : ndarray, shape (M, 2)
        Grid pixels (u, v) that hit the model.
    points : ndarray, shape (M, 3), metres, camera frame
    joints : ndarray, shape (M,), int
    parts : ndarray, shape (M,), int
    interior : ndarray, shape (M,), bool
        The four grid neighbours hit the same part: away from silhouette and occlusion edges.
    stride : float
        Grid spacing in pixels (each sample stands for ``stride**2`` pixels).
    """

    pixels: np.ndarray
    points: np.ndarray
    joints: np.ndarray
    parts: np.ndarray
    interior: np.ndarray
    stride: float

    @property
    def count(self):
        return len(self.pixels)


def projected_area(model, camera, rotations, origins):
    """Rough projected area (pixels) of the body, parts counted separately (overlaps twice)."""
    j = model.joints
    a = origins[j] + np.einsum("pij,pj->pi", rotations[j], model.starts)
    b = origins[j] + np.einsum("pij,pj->pi", rotations[j], model.ends)
    f = 0.5 * (camera.fx + camera.fy)
    za = np.maximum(a[:, 2], _NEAR)
    zb = np.maximum(b[:, 2], _NEAR)
    ua = np.stack([a[:, 0] / za, a[:, 1] / za], axis=1) * f
    ub = np.stack([b[:, 0] / zb, b[:, 1] / zb], axis=1) * f
    da = 2.0 * model.radii[:, 0] * f / za
    db = 2.0 * model.radii[:, 1] * f / zb
    area = np.linalg.norm(ub - ua, axis=1) * 0.5 * (da + db) + 0.785 * np.maximum(da, db) ** 2
    bj = model.box_joints
    zc = np.maximum((origins[bj] + np.einsum("qij,qj->qi", rotations[bj], model.box_centres))[:, 2],
                    _NEAR)
    box_area = 3.0 * (np.sort(model.box_half_sizes, axis=1)[:, 1:].prod(axis=1)) * (f / zc) ** 2
    return float(area.sum() + box_area.sum())


def sample_silhouette(model, camera, rotations, origins, budget, min_stride=1.0, edge_margin=1.5):
    """Ray-cast a regular pixel grid over the model's image: about ``budget`` hits.

    The grid spacing is chosen from the projected area so that the silhouette holds about
    ``budget`` grid points (never denser than ``min_stride`` pixels); the cost therefore does
    not grow with the image resolution.

    Parameters
    ----------
    model : BodyModel
    camera : PinholeCamera
    rotations : array_like, shape (B, 3, 3)
    origins : array_like, shape (B, 3)
    budget : int
    min_stride : float, pixels
    edge_margin : float, pixels
        A sample is ``interior`` when every grid point within this distance (at least the
        8 neighbours) hits the same part.

    Returns
    -------
    SilhouetteSamples
    """
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    bounds = part_bounds(model, camera, rotations, origins)
    lo_u = max(0.0, float(bounds[:, 0].min()))
    hi_u = min(camera.width - 1.0, float(bounds[:, 1].max()))
    lo_v = max(0.0, float(bounds[:, 2].min()))
    hi_v = min(camera.height - 1.0, float(bounds[:, 3].max()))
    empty = SilhouetteSamples(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0, dtype=int),
                              np.zeros(0, dtype=int), np.zeros(0, dtype=bool), 1.0)
    if not (hi_u >= lo_u and hi_v >= lo_v):
        return empty
    area = min(projected_area(model, camera, rotations, origins),
               (hi_u - lo_u + 1.0) * (hi_v - lo_v + 1.0))
    stride = max(float(min_stride), float(np.sqrt(area / max(int(budget), 1))))
    us = np.arange(lo_u, hi_u + 1e-9, stride)
    vs = np.arange(lo_v, hi_v + 1e-9, stride)
    grid_u, grid_v = np.meshgrid(us, vs)
    pixels = np.stack([grid_u.ravel(), grid_v.ravel()], axis=1)
    hits = ray_cast(model, camera, rotations, origins, pixels, bounds=bounds)
    labels = hits.parts.reshape(len(vs), len(us))
    k = max(1, int(np.ceil(edge_margin / stride)))
    pad = np.pad(labels, k, constant_values=-1)
    same = np.ones(labels.shape, dtype=bool)
    rows, cols = labels.shape
    for dv in range(-k, k + 1):
        for du in range(-k, k + 1):
            if dv or du:
                same &= pad[k + dv:k + dv + rows, k + du:k + du + cols] == labels
    same = same.ravel()
    h = hits.hit
    return SilhouetteSamples(pixels=pixels[h], points=hits.points[h], joints=hits.joints[h],
                             parts=hits.parts[h], interior=same[h], stride=stride)
