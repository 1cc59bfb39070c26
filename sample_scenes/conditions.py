"""Hard conditions for the rendered tracking footage (issue 20; no bpy).

Every synthetic clip used to be one textured walker on a plain textured wall: the tracker was
never shown another person, clutter, clothes, blur, compression or a backlit subject. A
*condition* changes one of those things in a CMU scene (``footage_scenes.ensure_footage(...,
condition=...)``, ``render_footage.py --condition``); the motion, the body and the cameras stay
the scene's, so a condition's clip is scored against the same ground truth.

``two_people``
    A second walker (another CMU subject's walk, :data:`SECOND_WALKERS`) walks the other way
    about 1.2 m nearer to the scene's usual camera and crosses in front of the first at the
    clip's middle frame (as that camera sees it). Its ground truth is saved beside the first's
    (``second_*`` arrays): it can be tracked too (several bodies, ``core.tracking.bodies``).
``clutter``
    The wall and floor show a real photograph: the rig room of the shipped real footage
    (``sample_scenes/data/footage/pose2sim_single_person``, BSD-3-Clause), the person removed
    by a median over its 100 frames and the ghost they leave inpainted
    (``make_clutter_background.py``): furniture, mats, a person standing in the back.
``clothing``
    Garments instead of a noise texture per part: a striped shirt over the torso and arms,
    low-contrast trousers over the legs, dark shoes, smooth skin for the head and hands.
    Neighbouring parts look alike and stripes leave motion along them unmeasured (the
    aperture problem).
``motion_blur``
    Each frame is the mean of three renders at -1/3, 0 and +1/3 of a frame (a 240-degree
    shutter; the ground truth is the middle one).
``compression``
    Each frame through JPEG at quality 20 (4:2:0 chroma): blocking and ringing, as in a
    heavily compressed phone video.
``low_contrast``
    Backlight: the body's textures at a quarter of their contrast and dark, the background
    bright, then sensor noise (1.5 grey levels, seeded per frame).

Post-processing (``compression``, ``low_contrast``'s noise, ``motion_blur``'s mean) is done on
the rendered 8-bit frames by :func:`finish_frame` (PIL and NumPy, deterministic).
"""

import io
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
#: The condition names, in the benchmark's order.
CONDITIONS = ("two_people", "clutter", "clothing", "motion_blur", "compression", "low_contrast")
#: The second walker of ``two_people``: the first of these trials that is not the clip's own.
SECOND_WALKERS = ("35_03", "35_04")
#: Metres between the two walkers' paths where they cross (towards the usual camera).
CROSSING_OFFSET = 1.2
#: ``motion_blur``: sub-frame offsets (frames) averaged into one frame.
BLUR_OFFSETS = (-1.0 / 3.0, 0.0, 1.0 / 3.0)
#: ``compression``: JPEG quality.
JPEG_QUALITY = 20
#: ``low_contrast``: body contrast and level, background level, noise (grey levels of 255).
BODY_CONTRAST, BODY_LEVEL, BACKGROUND_LEVEL, NOISE_GREY_LEVELS = 0.25, 0.12, 0.62, 1.5
#: ``clutter``: the photograph, metres covered by its height on the wall and by a tile on the floor.
BACKGROUND_PHOTO = (ROOT / "sample_scenes" / "data" / "footage" / "pose2sim_single_person"
                    / "background_median.jpg")
PHOTO_HEIGHT_M, FLOOR_TILE_M = 4.5, 6.0


def check_condition(condition):
    """``condition`` itself when it is None or one of :data:`CONDITIONS`, else ValueError."""
    if condition is not None and condition not in CONDITIONS:
        raise ValueError(f"unknown condition {condition!r}: one of {', '.join(CONDITIONS)}")
    return condition


def second_walker_trial(trial):
    """The CMU trial of the second walker for a clip of ``trial``."""
    return next(t for t in SECOND_WALKERS if t != trial)


def move_motion(skeleton, root_translation, local_rotations, rotation, translation):
    """A motion moved rigidly in the world: every joint frame ``x -> rotation x + translation``.

    Parameters
    ----------
    skeleton : Skeleton
    root_translation : ndarray, shape (N, 3)
    local_rotations : ndarray, shape (N, B, 3, 3)
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,)

    Returns
    -------
    root_translation, local_rotations
        The moved motion (only the root's entries change).
    """
    rest, offset = skeleton.rest_rotations[0], skeleton.offsets[0]
    local = np.array(local_rotations, dtype=float)
    # Root frame -> world is rest0 @ local0; rotated: R rest0 local0 = rest0 (rest0^T R rest0) local0.
    local[:, 0] = (rest.T @ rotation @ rest) @ local[:, 0]
    origins = np.asarray(root_translation, dtype=float) + offset
    return origins @ rotation.T + translation - offset, local


def crossing_placement(main_path, own_path, eye, middle):
    """Rotation about Z and translation that make a walk cross in front of another.

    Parameters
    ----------
    main_path, own_path : ndarray, shape (N, 2)
        Ground positions of the first walker's and the second walker's root.
    eye : ndarray, shape (3,)
        The usual camera's position.
    middle : int
        The frame where they cross.

    Returns
    -------
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,)
        Applied to the second walker (:func:`move_motion`): it walks against the first's
        heading, its root at ``middle`` :data:`CROSSING_OFFSET` metres from the first's
        towards the camera, on their line of sight.
    """
    heading = main_path[-1] - main_path[0]
    own = own_path[-1] - own_path[0]
    angle = np.arctan2(-heading[1], -heading[0]) - np.arctan2(own[1], own[0])
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    towards = eye[:2] - main_path[middle]
    target = main_path[middle] + CROSSING_OFFSET * towards / np.linalg.norm(towards)
    shift = target - rotation[:2, :2] @ own_path[middle]
    return rotation, np.array([shift[0], shift[1], 0.0])


# -- textures ------------------------------------------------------------------------------------

def _stripes(size, period, colours, rng, noise=0.06):
    """Horizontal stripes (along the texture's v axis) of alternating colours, a little noise."""
    v = (np.arange(size) * period / size) % 1.0
    band = (v < 0.5).astype(float)[:, None, None]
    rgb = band * colours[0] + (1.0 - band) * colours[1]
    rgb = np.broadcast_to(rgb, (size, size, 3)) + noise * (rng.random((size, size, 1)) - 0.5)
    return rgb


def _smooth(size, colour, amount, rng):
    from sample_scenes.footage_scenes import fractal_noise
    lum = fractal_noise(rng, size)
    return colour * (1.0 + amount * (lum[..., None] - 0.5))


def garment(part_name, seed, size=128):
    """RGBA texture (size, size, 4) of what a part wears (``clothing``)."""
    rng = np.random.default_rng(seed)
    name = part_name.lower()
    if any(k in name for k in ("femur", "tibia", "hip", "thigh", "shin", "leg", "knee")):
        rgb = _smooth(size, np.array([0.16, 0.2, 0.34]), 0.35, rng)        # dark trousers
    elif any(k in name for k in ("foot", "toe")):
        rgb = _smooth(size, np.array([0.1, 0.08, 0.07]), 0.5, rng)         # shoes
    elif any(k in name for k in ("head", "neck", "wrist", "hand", "thumb", "finger")):
        rgb = _smooth(size, np.array([0.78, 0.6, 0.5]), 0.12, rng)         # skin
    else:                                                                  # the shirt
        rgb = _stripes(size, 8, (np.array([0.85, 0.82, 0.75]), np.array([0.55, 0.12, 0.12])),
                       rng)
    return np.concatenate([np.clip(rgb, 0, 1), np.ones((size, size, 1))], axis=-1)


def backlit(rgba, body):
    """``low_contrast``: a body texture dark and at a quarter of its contrast, or a background
    texture bright."""
    out = np.array(rgba, dtype=float)
    if body:
        out[..., :3] = BODY_LEVEL + BODY_CONTRAST * out[..., :3]
    else:
        out[..., :3] = BACKGROUND_LEVEL + (1.0 - BACKGROUND_LEVEL) * out[..., :3]
    return np.clip(out, 0, 1)


def background_photo():
    """RGBA float (H, W, 4) of :data:`BACKGROUND_PHOTO`, row 0 at the top."""
    from PIL import Image
    rgb = np.asarray(Image.open(BACKGROUND_PHOTO).convert("RGB"), dtype=float) / 255.0
    return np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,))], axis=-1)


# -- frames --------------------------------------------------------------------------------------

def finish_frame(condition, renders, frame_index):
    """The stored frame (H, W, 3) uint8 of a condition from its render(s) (H, W, 3) uint8:
    the mean of the sub-frame renders (``motion_blur``), JPEG (``compression``), sensor noise
    (``low_contrast``); other conditions: the render as it is."""
    renders = [np.asarray(r) for r in renders]
    if condition == "motion_blur":
        mean = np.mean([r.astype(float) for r in renders], axis=0)
        return np.clip(np.rint(mean), 0, 255).astype(np.uint8)
    frame = renders[0]
    if condition == "compression":
        from PIL import Image
        buffer = io.BytesIO()
        Image.fromarray(frame).save(buffer, format="JPEG", quality=JPEG_QUALITY, subsampling=2)
        return np.asarray(Image.open(io.BytesIO(buffer.getvalue())).convert("RGB"))
    if condition == "low_contrast":
        rng = np.random.default_rng(1000 + frame_index)
        noisy = frame.astype(float) + rng.normal(0.0, NOISE_GREY_LEVELS, frame.shape)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    return frame
