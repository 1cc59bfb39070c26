"""MediaPipe Pose on a video: 2D landmarks, 3D world landmarks, and how long it took.

Benchmark-only (``.venv-bench``: ``requirements-bench.txt``); never imported by ``core/`` or
``addon/``. MediaPipe's legacy ``mediapipe.solutions.pose`` runs offline with the models
bundled in its wheel (``model_complexity=1``: ``pose_landmark_full.tflite``); OpenCV decodes
the video (the same H.264 stream Blender decodes for the tracker).

Passes (:data:`PASSES`):

``reference``
    video mode (the person's region is carried from frame to frame), ``smooth_landmarks``
    **off**: no temporal filtering in the reference.
``flipped``
    the same on every frame mirrored left-right; landmarks mapped back (``u -> W - 1 - u``)
    and their left/right labels exchanged. A second, nearly independent look at each frame
    (test-time augmentation) that the triangulation uses as extra views.
``peer``
    MediaPipe as a user runs it (video mode, its defaults: landmark smoothing on): the peer
    whose monocular 3D (``pose_world_landmarks``) and speed the tracker is compared with.

Pixels: MediaPipe's normalised ``(x, y)`` measure from the image's top-left *corner*; the
project's pixel centres (``docs/conventions.md``) are ``u = x W - 0.5``, ``v = y H - 0.5``.
"""

import time
from dataclasses import dataclass

import cv2
import numpy as np

from .reference import LANDMARKS, MIRROR

PASSES = ("reference", "flipped", "peer")
MODEL_COMPLEXITY = 1


@dataclass(frozen=True, eq=False)
class Detections:
    """One MediaPipe pass over one video.

    Attributes
    ----------
    pixels : ndarray, shape (F, 33, 2)
        Landmarks, pixel centres of the decoded frame (NaN where no person was found).
    visibility : ndarray, shape (F, 33)
        MediaPipe's ``visibility`` (0 where no person).
    world : ndarray, shape (F, 33, 3)
        ``pose_world_landmarks``: metres, origin between the hips, x right, y down, z away
        from the camera (NaN where no person).
    seconds : float
        Wall time of decoding and inference over the whole video (model set-up excluded).
    width, height : int
        Decoded frame size.
    """

    pixels: np.ndarray
    visibility: np.ndarray
    world: np.ndarray
    seconds: float
    width: int
    height: int

    @property
    def frames_per_second(self):
        return len(self.pixels) / self.seconds


def mediapipe_version():
    import mediapipe
    return mediapipe.__version__


def detect(video, mode):
    """Run one pass (:data:`PASSES`) of MediaPipe Pose over ``video``.

    Returns
    -------
    Detections
    """
    import mediapipe as mp
    if mode not in PASSES:
        raise ValueError(f"mode must be one of {PASSES}, got {mode!r}")
    options = {"static_image_mode": False, "model_complexity": MODEL_COMPLEXITY}
    if mode != "peer":
        options["smooth_landmarks"] = False
    capture = cv2.VideoCapture(str(video))
    if not capture.isOpened():
        raise RuntimeError(f"OpenCV cannot open {video}")
    pixels, visibility, world = [], [], []
    width = height = 0
    with mp.solutions.pose.Pose(**options) as pose:
        tic = time.perf_counter()
        while True:
            ok, bgr = capture.read()
            if not ok:
                break
            height, width = bgr.shape[:2]
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            if mode == "flipped":
                rgb = np.ascontiguousarray(rgb[:, ::-1])
            result = pose.process(rgb)
            if result.pose_landmarks is None:
                pixels.append(np.full((len(LANDMARKS), 2), np.nan))
                visibility.append(np.zeros(len(LANDMARKS)))
                world.append(np.full((len(LANDMARKS), 3), np.nan))
                continue
            lm = result.pose_landmarks.landmark
            pixels.append([(p.x * width - 0.5, p.y * height - 0.5) for p in lm])
            visibility.append([p.visibility for p in lm])
            world.append([(p.x, p.y, p.z) for p in result.pose_world_landmarks.landmark])
        seconds = time.perf_counter() - tic
    capture.release()
    pixels, visibility, world = (np.array(a, dtype=float) for a in (pixels, visibility, world))
    if not len(pixels):
        raise RuntimeError(f"OpenCV decoded no frame of {video}")
    if mode == "flipped":
        pixels[..., 0] = width - 1 - pixels[..., 0]
        world[..., 0] = -world[..., 0]
        pixels, visibility, world = pixels[:, MIRROR], visibility[:, MIRROR], world[:, MIRROR]
    return Detections(pixels, visibility, world, seconds, width, height)


def read_frames(video, indices):
    """RGB frames (uint8, (H, W, 3)) of ``video`` at 0-based ``indices``, decoded in order."""
    wanted = set(int(i) for i in indices)
    capture = cv2.VideoCapture(str(video))
    out, k = {}, 0
    while wanted - out.keys():
        ok, bgr = capture.read()
        if not ok:
            break
        if k in wanted:
            out[k] = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        k += 1
    capture.release()
    return [out[int(i)] for i in indices]
