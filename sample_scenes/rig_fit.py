"""Fit a test rig's skeleton to the CMU subject's, as an animator fits a metarig to a character.

The test rigs (:mod:`rig_scenes`) walk subject 35's captured walk (:mod:`rig_walk`): every
mapped deforming bone takes its CMU bone's rotation change from rest after its rest direction is
aligned with the CMU bone's, the hips are placed on the CMU's hip joints, every other head
follows its kinematic parent with the rig's own rest offsets. A rig of other proportions (the
stock metarig: thigh 0.473 / shin 0.400 m against subject 35's 0.418-0.430 / 0.447-0.451, hips
0.173 m apart against 0.190) then walks subject 35's angles on legs that carry it differently
(its feet slide; ``docs/gait_rigs.md``, *The root and angle differences decomposed*).

:func:`fit_skeleton` moves the rig's joints so that the walk puts every mapped joint where the
CMU skeleton has it, **keeping each bone's rest direction and roll** (the rig's rest-pose
conventions: the metarig's A-pose arms and forward-leaning hips, Mixamo's T-pose): with ``q_p``
the smallest rotation taking the kinematic parent ``p``'s rest direction to its CMU bone's,

* a bone's head is its parent's head plus ``q_pᵀ (h_c - h_cp)`` (``h_c``: the CMU rest head of
  the bone's CMU source, ``h_cp``: of the parent's), so that ``rig_walk``'s
  ``head = head_p + R_cp(t) R_cp0ᵀ q_p (rest offset)`` is the CMU joint's position;
  the thighs and the first spine bone, whose parent is the hips, are placed the same way
  from the rig's hip midpoint (which stays where it is) and the CMU's;
* a bone's length is its CMU source's head to the next mapped CMU joint along the chain (the
  forearm runs from the elbow to the CMU ``hand``'s head: radius and wrist, the forearm's twist
  segment); the toes take the CMU toes' length; chain ends without a CMU length (the head,
  the hands: their tails are the mesh's, fingers and face hang from them) and the hips bone
  (CMU's root is a point) keep theirs, the hips bone ending at the first spine bone;
* bones that are no mapped part (face, fingers, pelvis, breast, heel, leaf bones) move rigidly
  with their nearest mapped ancestor (with its tail when they start there, else its head).

Left and right are fitted each to their own side (subject 35's are not symmetric: femurs
0.418 / 0.430 m). NumPy only (``rig_scenes`` applies the result to edit bones).
"""

import numpy as np

from sample_scenes.rig_specs import PART_PARENTS, PARTS, SIDES

#: CMU bones whose world rotation each part takes (one per rig bone of the part, spread over
#: them in order): ``rig_walk`` keys the walk with them, the fit places the joints by them.
CMU_SOURCE = {"hips": ("root",), "spine": ("lowerback", "upperback"), "chest": ("thorax",),
              "neck": ("lowerneck", "upperneck"), "head": ("head",)}
for _s, _c, _ in SIDES:
    CMU_SOURCE.update({f"clavicle.{_s}": (f"{_c}clavicle",), f"upper_arm.{_s}": (f"{_c}humerus",),
                       f"forearm.{_s}": (f"{_c}radius",), f"hand.{_s}": (f"{_c}hand",),
                       f"thigh.{_s}": (f"{_c}femur",), f"shin.{_s}": (f"{_c}tibia",),
                       f"foot.{_s}": (f"{_c}foot",), f"toe.{_s}": (f"{_c}toes",)})
#: The part a chain continues into (the next joint along it); parts absent end a chain.
CHAIN_CHILD = {"spine": "chest", "chest": "neck", "neck": "head"}
for _s, _, _ in SIDES:
    CHAIN_CHILD.update({f"clavicle.{_s}": f"upper_arm.{_s}", f"upper_arm.{_s}": f"forearm.{_s}",
                        f"forearm.{_s}": f"hand.{_s}", f"thigh.{_s}": f"shin.{_s}",
                        f"shin.{_s}": f"foot.{_s}", f"foot.{_s}": f"toe.{_s}"})
#: Chain ends that take the CMU bone's own length (the others keep the rig's).
CMU_LENGTH_ENDS = tuple(f"toe.{s}" for s, _, _ in SIDES)


def source_of(part, k, n):
    """The CMU bone whose rotation bone ``k`` of ``n`` of ``part`` takes (``rig_walk``'s rule)."""
    sources = CMU_SOURCE[part]
    return sources[min(k * len(sources) // n, len(sources) - 1)]


def cmu_rest(subject_asf):
    """Subject's CMU skeleton at rest: {bone: (head (3,), tail (3,))}, metres, world (Z up,
    facing -Y, the subject's left at +X: the frame of ``rig_walk.source_walk``)."""
    from core.kinematics import forward_kinematics
    from core.mocap import asf_to_skeleton, read_asf
    sk = asf_to_skeleton(read_asf(subject_asf))
    rot, pos = forward_kinematics(sk, np.broadcast_to(np.eye(3), (1, sk.n_joints, 3, 3)),
                                  np.zeros((1, 3)))
    tails = np.einsum("jab,jb->ja", rot[0], sk.tails)
    return {n: (pos[0, i].copy(), pos[0, i] + tails[i]) for i, n in enumerate(sk.names)}


def smallest_rotation(a, b):
    """The smallest rotation (3, 3) taking unit vector ``a`` to unit vector ``b``."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1.0 + 1e-12:
        raise ValueError("opposite directions: no unique smallest rotation")
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _unit(v):
    return v / np.linalg.norm(v)


def fit_skeleton(heads, tails, parents, parts, cmu):
    """New heads and tails of a rig fitted to a CMU skeleton (module docstring).

    Parameters
    ----------
    heads, tails : dict of str -> ndarray (3,)
        Every bone's rest head and tail in the rig's frame, which must be ``cmu``'s frame
        (same axes, same unit).
    parents : dict of str -> str or None
    parts : dict of str -> tuple of str
        Part (:data:`rig_specs.PARTS`) -> the rig's mapped deforming bones, root to tip.
    cmu : dict of str -> (ndarray (3,), ndarray (3,))
        The CMU skeleton's rest heads and tails (:func:`cmu_rest`, in the rig's frame).

    Returns
    -------
    new_heads, new_tails : dict of str -> ndarray (3,)
        For every bone of ``heads``.
    """
    heads = {n: np.asarray(h, float) for n, h in heads.items()}
    tails = {n: np.asarray(t, float) for n, t in tails.items()}
    new_h, new_t = {}, {}
    source, cmu_dir, q = {}, {}, {}
    for part in PARTS:
        bones = parts[part]
        for k, b in enumerate(bones):
            source[b] = source_of(part, k, len(bones))
    for b, c in source.items():
        h, t = cmu[c]
        cmu_dir[b] = _unit(t - h) if np.linalg.norm(t - h) > 1e-9 else np.array([0.0, 0.0, 1.0])
        q[b] = smallest_rotation(_unit(tails[b] - heads[b]), cmu_dir[b])

    hips = parts["hips"][0]
    thighs = [parts[f"thigh.{s}"][0] for s, _, _ in SIDES]
    rig_mid = np.mean([heads[b] for b in thighs], axis=0)
    cmu_mid = np.mean([cmu[source[b]][0] for b in thighs], axis=0)

    def next_joint(part, k):
        """CMU head of the next mapped joint along the chain after bone ``k`` of ``part``."""
        bones = parts[part]
        if k + 1 < len(bones):
            return cmu[source[bones[k + 1]]][0]
        child = CHAIN_CHILD.get(part)
        return cmu[source[parts[child][0]]][0] if child else None

    for part in PARTS[1:]:
        bones = parts[part]
        parent_part = PART_PARENTS[part]
        for k, b in enumerate(bones):
            p = bones[k - 1] if k else parts[parent_part][-1]
            offset = cmu[source[b]][0] - (cmu_mid if p == hips else cmu[source[p]][0])
            anchor = rig_mid if p == hips else new_h[p]
            new_h[b] = anchor + q[p].T @ offset
            d = _unit(tails[b] - heads[b])
            following = next_joint(part, k)
            if following is not None:
                length = float(np.linalg.norm(following - cmu[source[b]][0]))
            elif part in CMU_LENGTH_ENDS:
                length = float(np.linalg.norm(cmu[source[b]][1] - cmu[source[b]][0]))
            else:
                length = float(np.linalg.norm(tails[b] - heads[b]))
            new_t[b] = new_h[b] + length * d
    # The hips bone: its own direction and length, ending where the first spine bone now starts
    # (as far from it as before).
    first_spine = parts["spine"][0]
    new_t[hips] = new_h[first_spine] + (tails[hips] - heads[first_spine])
    new_h[hips] = new_t[hips] - (tails[hips] - heads[hips])

    # Everything else rigidly with its nearest mapped ancestor.
    mapped = set(new_h)
    scale = max(np.linalg.norm(tails[b] - heads[b]) for b in mapped)
    for name in heads:
        if name in mapped:
            continue
        a = parents[name]
        while a is not None and a not in mapped:
            a = parents[a]
        if a is None:
            shift = np.zeros(3)
        elif np.linalg.norm(heads[name] - tails[a]) < 1e-4 * scale:
            shift = new_t[a] - tails[a]
        else:
            shift = new_h[a] - heads[a]
        new_h[name], new_t[name] = heads[name] + shift, tails[name] + shift
    return new_h, new_t


def fitted_lengths(heads, tails, parts):
    """{part: length} of a rig's mapped chains (sum of the part's bones), for reports/tests."""
    return {p: float(sum(np.linalg.norm(tails[b] - heads[b]) for b in bones))
            for p, bones in parts.items()}
