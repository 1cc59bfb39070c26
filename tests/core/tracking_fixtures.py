"""Small synthetic skeletons, bodies, cameras and a pure-NumPy renderer for the tracking tests.

The renderer ray-casts the body model (``core.tracking.ray_cast``) and paints every part with a
smooth procedural texture fixed in the part's frame, over a smooth static background: frames
with exactly known poses and exact brightness constancy, without Blender.
"""

import numpy as np

from core.kinematics import Skeleton, exp_so3
from core.tracking.body_model import BodyModel, joint_frames_in_camera, ray_cast
from core.tracking.camera import PinholeCamera


def chain_skeleton(rng, depth=6, branch=True):
    """A random chain of ``depth`` joints (plus a side branch), all 3 rotation DOFs."""
    n = depth + (2 if branch else 0)
    parents = [-1] + list(range(depth - 1))
    if branch:
        parents += [1, depth]            # a branch off joint 1, and a child of that branch
    offsets = [[0.1, -0.2, 3.0]] + [list(rng.normal(0, 0.05, 3) + [0, 0.25, 0]) for _ in range(n - 1)]
    rest = exp_so3(rng.normal(0, 0.4, (n, 3)))
    tails = np.tile([0.0, 0.22, 0.0], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    return Skeleton(names=tuple(f"j{i}" for i in range(n)), parents=parents, offsets=offsets,
                    rest_rotations=rest, tails=tails, dof_axes=((0, 1, 2),) * n, limits=None,
                    root_translation=True)


def chain_body(skeleton, radius=0.05):
    n = skeleton.n_joints
    return BodyModel(n_joints=n, joints=np.arange(n), starts=np.zeros((n, 3)),
                     ends=skeleton.tails, radii=np.full((n, 2), radius),
                     names=skeleton.names)


def camera(width=320, height=240, f=300.0):
    return PinholeCamera(fx=f, fy=f * 1.05, cx=width / 2 - 0.3, cy=height / 2 + 0.7, width=width,
                         height=height, world2camera=np.eye(4))


def random_pose(rng, skeleton, scale=0.4):
    local = exp_so3(rng.normal(0, scale, (skeleton.n_joints, 3)))
    return rng.normal(0, 0.1, 3), local


def two_arm_skeleton(names=("torso", "front", "front2", "back", "back2")):
    """A torso (root, a box) with a front arm and a back arm, both hinged at the shoulder.

    Seen by :func:`front_camera` the back arm can be put exactly behind the front arm.
    Joints: 0 torso, 1 front upper arm, 2 front forearm, 3 back upper arm, 4 back forearm.
    Arm bones hang along -Z (world); the camera looks along +Y.
    """
    down = np.array([[0.0, 0.0, -0.3]])
    return Skeleton(names=tuple(names), parents=[-1, 0, 1, 0, 3],
                    offsets=[[0.0, 0.0, 1.0], [0.0, -0.15, 0.0], [0.0, 0.0, -0.3],
                             [0.0, 0.15, 0.0], [0.0, 0.0, -0.3]],
                    rest_rotations=np.broadcast_to(np.eye(3), (5, 3, 3)),
                    tails=np.concatenate([[[0.0, 0.0, 0.4]], down, down, down, down]),
                    dof_axes=((0, 1, 2),) * 5, limits=None, root_translation=True)


def two_arm_swing(s, turn=0.3):
    """The two-arm body swinging both arms, turning (``turn`` rad) and moving, at times ``s``
    in [0, 1] (F,): roots (F, 3) and local rotations (F, 5, 3, 3)."""
    z = 0 * s
    local = np.broadcast_to(np.eye(3), (len(s), 5, 3, 3)).copy()
    local[:, 0] = exp_so3(np.stack([z, z, turn * np.sin(2.0 * s)], 1))
    local[:, 1] = exp_so3(np.stack([0.6 * np.sin(4.0 * s), -0.5 - 0.3 * s, z], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.8 * s ** 2, z, z], 1))
    local[:, 3] = exp_so3(np.stack([z, 0.9 + 0.1 * s, 0.5 * np.sin(3 * s)], 1))
    local[:, 4] = exp_so3(np.stack([0.2 + 0.7 * np.sin(3.5 * s), z, z], 1))
    roots = np.stack([0.15 * s, 0.05 * s, 0.03 * np.sin(3 * s)], 1)
    return roots, local


def two_arm_body(skeleton):
    return BodyModel(n_joints=5, joints=[1, 2, 3, 4], starts=np.zeros((4, 3)),
                     ends=skeleton.tails[1:], radii=np.full((4, 2), 0.06),
                     box_joints=[0], box_centres=[[0.0, 0.0, -0.2]],
                     box_half_sizes=[[0.25, 0.1, 0.5]],
                     names=("front", "front2", "back", "back2", "torso"))


def front_camera(width=160, height=120, f=220.0):
    """Camera 3 m in front of the two-arm body (world -Y), looking along +Y, Z up."""
    w2c = np.eye(4)
    w2c[:3, :3] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]   # x, -z, y
    w2c[:3, 3] = -w2c[:3, :3] @ np.array([0.0, -3.0, 1.0])
    return PinholeCamera(fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2,
                         width=width, height=height, world2camera=w2c)


def _texture(local, part):
    """Smooth pattern (values in about [0.1, 0.9]) fixed in the part frame; metres in."""
    x, y, z = local[:, 0], local[:, 1], local[:, 2]
    k = 25.0 + 4.0 * part
    return (0.5 + 0.18 * np.sin(k * x + 2.0 * part) * np.cos(0.8 * k * y + part)
            + 0.12 * np.sin(1.3 * k * z + 0.5 * k * x) + 0.1 * np.cos(0.7 * k * (y + z)))


def render(skeleton, body, cam, roots, local):
    """Grayscale frames (N, H, W) float32 of the body at N poses, over a static background."""
    rot, org = joint_frames_in_camera(skeleton, cam.world2camera, np.atleast_2d(roots),
                                      local.reshape(-1, skeleton.n_joints, 3, 3))
    v, u = np.mgrid[0:cam.height, 0:cam.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    background = 0.5 + 0.2 * np.sin(0.21 * u + 0.3) * np.cos(0.17 * v) + 0.1 * np.sin(0.05 * (u + 2 * v))
    out = np.empty((len(rot), cam.height, cam.width), dtype=np.float32)
    for f in range(len(rot)):
        hits = ray_cast(body, cam, rot[f], org[f], pixels)
        img = background.ravel().copy()
        h = np.nonzero(hits.hit)[0]
        j = hits.joints[h]
        local_pts = np.einsum("mji,mj->mi", rot[f, j], hits.points[h] - org[f, j])
        img[h] = _texture(local_pts, hits.parts[h])
        out[f] = img.reshape(cam.height, cam.width)
    return out


def render_bodies(people, cam, seeds=None):
    """Grayscale frames (N, H, W) float32 of several bodies over the static background of
    :func:`render`, each pixel showing the nearest body's surface (people hide each other).

    ``people``: sequence of (skeleton, body, roots (N, 3), local (N, B, 3, 3)); ``seeds``: per
    body, an offset of its texture's part numbers (default 0, 10, 20, ...), so that the bodies
    look different.
    """
    seeds = range(0, 10 * len(people), 10) if seeds is None else seeds
    n = len(people[0][2])
    v, u = np.mgrid[0:cam.height, 0:cam.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    background = 0.5 + 0.2 * np.sin(0.21 * u + 0.3) * np.cos(0.17 * v) + 0.1 * np.sin(0.05 * (u + 2 * v))
    out = np.empty((n, cam.height, cam.width), dtype=np.float32)
    frames_cam = [joint_frames_in_camera(sk, cam.world2camera, np.atleast_2d(roots),
                                         local.reshape(-1, sk.n_joints, 3, 3))
                  for sk, _, roots, local in people]
    for f in range(n):
        img = background.ravel().copy()
        depth = np.full(len(pixels), np.inf)
        for (sk, body, _, _), (rot, org), seed in zip(people, frames_cam, seeds):
            hits = ray_cast(body, cam, rot[f], org[f], pixels)
            h = np.nonzero(hits.hit & (hits.points[:, 2] < depth))[0]
            j = hits.joints[h]
            local_pts = np.einsum("mji,mj->mi", rot[f, j], hits.points[h] - org[f, j])
            img[h] = _texture(local_pts, hits.parts[h] + seed)
            depth[h] = hits.points[h, 2]
        out[f] = img.reshape(cam.height, cam.width)
    return out


def many_bone_skeleton(rng, n_bones=706):
    """A synthetic rig of ``n_bones`` short bones (a random tree, ``parents[i] < i``), about a
    person's size, 3 m in front of an identity camera -- as many bones as a generated Rigify
    rig (706), most of them small (fingers, face), for memory tests."""
    parents = [-1] + [int(rng.integers(max(0, i - 8), i)) for i in range(1, n_bones)]
    offsets = rng.normal(0.0, 0.03, (n_bones, 3))
    offsets[0] = [0.0, 0.0, 3.0]
    tails = rng.normal(0.0, 0.04, (n_bones, 3)) + [0.0, 0.08, 0.0]
    return Skeleton(names=tuple(f"b{i}" for i in range(n_bones)), parents=parents,
                    offsets=offsets, rest_rotations=exp_so3(rng.normal(0, 0.3, (n_bones, 3))),
                    tails=tails, dof_axes=((0, 1, 2),) * n_bones, limits=None,
                    root_translation=True)
