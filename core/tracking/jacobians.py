"""Motion parameters, exact motion updates and the Jacobians of Yamamoto eqs. 2-3, A.2-A.8.

Motion of one frame (paper §2.1): the root moves by ``r`` (metres, in its own frame) and every
joint ``i`` turns by a small rotation ``phi_i`` about the axes of its own frame::

    p' = T_1 R_1 T_2 R_2 ... T_i R_i p_i                      (eq. 2)

A *full motion* is ``(translation (3,), rotvecs (B, 3))``; it is applied exactly with the exp
map (:func:`apply_motion`), ``local_i <- local_i @ exp([phi_i]x)`` and
``root_translation <- root_translation + R_root @ r``. The paper's Euler form
``Qz Qy Qx`` has the same first-order generators, so the Jacobian below is the paper's; the exp
map only changes the (second-order) finite step, and composes cleanly in the trajectory loop.

The *estimated* parameter vector ``x`` (eq. 3) holds the unmasked components only
(:class:`MotionLayout`): root translation axes first, then ``(joint, axis)`` rotation components
in joint order. Masked components are taken from a base motion (the prediction) when unpacking.

Jacobian columns in the camera frame (eq. A.2, with the generators of the *named* axes: the
printed ``N_x`` and ``N_z`` are swapped, see ``DESIGN.md``):

* root translation axis ``a``: ``H_1 K_a H_1^-1 p~ = R_root^c e_a``;
* rotation of joint ``j`` about its axis ``a`` (``j`` ancestor-or-self of the point's joint):
  ``H_j N_a H_j^-1 p~ = (R_j^c e_a) x (p - o_j^c)``,

where ``R_j^c``, ``o_j^c`` are joint ``j``'s orientation and origin in the camera frame. An image
row (eq. A.8) is ``g^T J`` with ``g = (1/z) [f_x E_X, f_y E_Y, -(X E_X + Y E_Y)]`` and centred
pixel coordinates ``X = u - c_x``, ``Y = v - c_y``.
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import exp_so3, log_so3


@dataclass(frozen=True, eq=False)
class MotionLayout:
    """Which motion components are estimated, and their order in ``x``.

    Attributes
    ----------
    n_joints : int
        B.
    translation_axes : ndarray, shape (T,), int
        Root translation axes (root frame) estimated, T <= 3.
    rotation_joints, rotation_axes : ndarray, shape (C,), int
        Joint and axis (0=X, 1=Y, 2=Z of the joint frame) of each rotation component.
    """

    n_joints: int
    translation_axes: np.ndarray
    rotation_joints: np.ndarray
    rotation_axes: np.ndarray

    @property
    def n_params(self):
        """Length of ``x``."""
        return len(self.translation_axes) + len(self.rotation_joints)

    @property
    def dof_mask(self):
        """(B, 3) bool: estimated rotation axes."""
        mask = np.zeros((self.n_joints, 3), dtype=bool)
        mask[self.rotation_joints, self.rotation_axes] = True
        return mask

    def names(self, skeleton):
        """Readable names ``'root.tx'``, ``'lfemur.rz'`` of the entries of ``x``."""
        out = [f"{skeleton.names[0]}.t{'xyz'[a]}" for a in self.translation_axes]
        out += [f"{skeleton.names[j]}.r{'xyz'[a]}"
                for j, a in zip(self.rotation_joints, self.rotation_axes)]
        return out


def motion_layout(skeleton, dof_mask=None, translation_mask=None, body=None):
    """Build the :class:`MotionLayout` of a skeleton.

    Parameters
    ----------
    skeleton : Skeleton
    dof_mask : array_like, shape (B, 3), bool, optional
        Rotation axes to estimate per joint (Blender: the axes not in ``lock_rotation``).
        Default: the skeleton's own ``dof_axes``.
    translation_mask : array_like, shape (3,), bool, optional
        Root translation axes (root frame) to estimate. Default: all three when the skeleton's
        root translates, none otherwise.
    body : BodyModel, optional
        When given, joints with no body part in their subtree are dropped: nothing in the
        image can measure their rotation (it would only add null-space columns).

    Returns
    -------
    MotionLayout
    """
    b = skeleton.n_joints
    if dof_mask is None:
        mask = np.zeros((b, 3), dtype=bool)
        for j, axes in enumerate(skeleton.dof_axes):
            mask[j, list(axes)] = True
    else:
        mask = np.array(dof_mask, dtype=bool)
        if mask.shape != (b, 3):
            raise ValueError(f"Expected dof_mask of shape ({b}, 3), got {mask.shape}")
    if translation_mask is None:
        tmask = np.full(3, bool(skeleton.root_translation))
    else:
        tmask = np.array(translation_mask, dtype=bool)
        if tmask.shape != (3,):
            raise ValueError(f"Expected translation_mask of shape (3,), got {tmask.shape}")
    if body is not None:
        mask = mask & subtree_has_part(skeleton, body)[:, None]
    joints, axes = np.nonzero(mask)
    return MotionLayout(n_joints=b, translation_axes=np.nonzero(tmask)[0],
                        rotation_joints=joints, rotation_axes=axes)


def subtree_has_part(skeleton, body):
    """(B,) bool: the joint or one of its descendants carries a body part."""
    has = np.zeros(skeleton.n_joints, dtype=bool)
    has[body.part_joints] = True
    for i in range(skeleton.n_joints - 1, 0, -1):
        has[skeleton.parents[i]] |= has[i]
    return has


def ancestor_matrix(skeleton):
    """(B, B) bool ``anc[k, j]``: joint ``j`` is joint ``k`` or one of its ancestors."""
    b = skeleton.n_joints
    anc = np.eye(b, dtype=bool)
    for i in range(1, b):
        anc[i] |= anc[skeleton.parents[i]]
    return anc


def pack(layout, translation, rotvecs):
    """Parameter vector ``x`` (n_params,) from a full motion ((3,), (B, 3))."""
    translation = np.asarray(translation, dtype=float)
    rotvecs = np.asarray(rotvecs, dtype=float)
    return np.concatenate([translation[layout.translation_axes],
                           rotvecs[layout.rotation_joints, layout.rotation_axes]])


def unpack(layout, x, base_translation, base_rotvecs):
    """Full motion from ``x``; components not in the layout are copied from the base motion.

    Parameters
    ----------
    layout : MotionLayout
    x : array_like, shape (n_params,)
    base_translation : array_like, shape (3,), metres
    base_rotvecs : array_like, shape (B, 3), radians

    Returns
    -------
    translation : ndarray, shape (3,)
    rotvecs : ndarray, shape (B, 3)
    """
    x = np.asarray(x, dtype=float)
    if x.shape != (layout.n_params,):
        raise ValueError(f"Expected x of shape ({layout.n_params},), got {x.shape}")
    t = np.array(base_translation, dtype=float)
    r = np.array(base_rotvecs, dtype=float)
    n_t = len(layout.translation_axes)
    t[layout.translation_axes] = x[:n_t]
    r[layout.rotation_joints, layout.rotation_axes] = x[n_t:]
    return t, r


def root_world_rotation(skeleton, local_rotations):
    """(..., 3, 3) root joint frame -> world: ``rest_rotations[0] @ local[..., 0]``."""
    return skeleton.rest_rotations[0] @ np.asarray(local_rotations)[..., 0, :, :]


def apply_motion(skeleton, root_translation, local_rotations, translation, rotvecs):
    """Pose after a full motion (eq. 2, exact: exp map for the rotations).

    Parameters
    ----------
    skeleton : Skeleton
    root_translation : array_like, shape (..., 3), metres (world)
    local_rotations : array_like, shape (..., B, 3, 3)
    translation : array_like, shape (..., 3), metres, root frame (before the motion)
    rotvecs : array_like, shape (..., B, 3), radians, each joint's own frame

    Returns
    -------
    root_translation : ndarray, shape (..., 3)
    local_rotations : ndarray, shape (..., B, 3, 3)
    """
    local = np.asarray(local_rotations, dtype=float)
    root = root_world_rotation(skeleton, local)
    t = np.asarray(root_translation, dtype=float) + np.einsum(
        "...ij,...j->...i", root, np.asarray(translation, dtype=float))
    return t, local @ exp_so3(rotvecs)


def motion_between(skeleton, root_translation_a, local_a, root_translation_b, local_b):
    """The full motion taking pose a to pose b (inverse of :func:`apply_motion`).

    Returns
    -------
    translation : ndarray, shape (..., 3), metres, root frame of pose a
    rotvecs : ndarray, shape (..., B, 3), radians
    """
    local_a = np.asarray(local_a, dtype=float)
    local_b = np.asarray(local_b, dtype=float)
    root = root_world_rotation(skeleton, local_a)
    dt = np.asarray(root_translation_b, dtype=float) - np.asarray(root_translation_a, dtype=float)
    return (np.einsum("...ji,...j->...i", root, dt),
            log_so3(np.swapaxes(local_a, -1, -2) @ local_b))


def point_jacobians(layout, ancestors, joints, points, rotations, origins):
    """3-D Jacobians ``d p' / d x`` of camera-frame points (eqs. 3, A.2).

    Parameters
    ----------
    layout : MotionLayout
    ancestors : ndarray, shape (B, B), bool
        :func:`ancestor_matrix`.
    joints : array_like, shape (M,), int
        Joint each point is attached to.
    points : array_like, shape (M, 3), metres, camera frame
    rotations : array_like, shape (B, 3, 3)
        Joint frame -> camera at the current pose.
    origins : array_like, shape (B, 3), metres, camera frame

    Returns
    -------
    ndarray, shape (M, 3, n_params)
    """
    points = np.asarray(points, dtype=float)
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    joints = np.asarray(joints, dtype=int)
    cols_t = rotations[0][:, layout.translation_axes]                       # (3, T)
    axes = rotations[layout.rotation_joints, :, layout.rotation_axes]        # (C, 3)
    lever = points[:, None, :] - origins[layout.rotation_joints][None]       # (M, C, 3)
    cols_r = np.cross(axes[None], lever)                                     # (M, C, 3)
    cols_r *= ancestors[joints][:, layout.rotation_joints][..., None]
    out = np.concatenate([np.broadcast_to(cols_t.T, (len(points),) + cols_t.T.shape),
                          cols_r], axis=1)
    return np.swapaxes(out, 1, 2)


def image_gradient_rows(camera, points, e_u, e_v):
    """The row vectors ``g`` of eq. A.8 (projection of 3-D motion onto the image gradient).

    ``g = (1/z) [f_x E_X, f_y E_Y, -(X E_X + Y E_Y)]``, ``X = f_x x / z``, ``Y = f_y y / z``,
    so that ``g . dp = E_X du + E_Y dv`` to first order (eqs. A.5-A.7); with lens distortion
    the gradient goes through the distortion's Jacobian (:meth:`PinholeCamera.gradient_rows`).

    Parameters
    ----------
    camera : PinholeCamera
    points : array_like, shape (..., 3), camera frame, metres
    e_u, e_v : array_like, shape (...)
        Image derivatives at the points' projections (intensity per pixel).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    return camera.gradient_rows(points, e_u, e_v)


def image_jacobian(layout, ancestors, joints, points, rotations, origins, g, translation_basis=None):
    """Coefficient matrix ``A`` of eq. 5 / A.9: rows ``g_m^T J_m`` without forming ``J``.

    For a rotation column ``(j, a)`` with axis ``w = R_j^c e_a``:
    ``g . (w x (p - o_j)) = w . (p x g) - g . (w x o_j)``, i.e. two small matrix products.

    Parameters
    ----------
    layout, ancestors, joints, points, rotations, origins
        As for :func:`point_jacobians`.
    g : array_like, shape (M, 3)
        :func:`image_gradient_rows`.
    translation_basis : array_like, shape (3, T'), optional
        Root-frame directions of the translation parameters (default: the layout's axes).

    Returns
    -------
    ndarray, shape (M, T' + C)
    """
    points = np.asarray(points, dtype=float)
    rotations = np.asarray(rotations, dtype=float)
    origins = np.asarray(origins, dtype=float)
    g = np.asarray(g, dtype=float)
    axes = rotations[layout.rotation_joints, :, layout.rotation_axes]        # (C, 3)
    w_x_o = np.cross(axes, origins[layout.rotation_joints])                 # (C, 3)
    a_rot = np.cross(points, g) @ axes.T - g @ w_x_o.T
    a_rot *= ancestors[np.asarray(joints, dtype=int)][:, layout.rotation_joints]
    if translation_basis is None:
        translation_basis = np.eye(3)[:, layout.translation_axes]
    a_tr = g @ (rotations[0] @ translation_basis)
    return np.concatenate([a_tr, a_rot], axis=1)
