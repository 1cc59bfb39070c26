"""Make ``background_median.jpg``: the shipped real footage's room with the person removed.

The *clutter* condition of the rendered tracking footage (``sample_scenes/conditions.py``,
issue 20) puts a real photograph behind the walker. It is made from the shipped Pose2Sim demo
(``sample_scenes/data/footage/pose2sim_single_person``, BSD-3-Clause; the result keeps its
licence): per camera the median of its 100 frames at a third of the size, where the person,
who stays in place doing a lunge, still leaves a ghost (pixels that differ from the median in
more than 8 % of the frames, opened and dilated) inpainted (OpenCV Telea); the four cameras
side by side. Needs OpenCV (the test environment's ``opencv-python-headless``)::

    .venv/bin/python sample_scenes/make_clutter_background.py
"""

from pathlib import Path

import cv2
import numpy as np

FOLDER = Path(__file__).resolve().parent / "data" / "footage" / "pose2sim_single_person"


def camera_background(path):
    """(640, 360, 3) uint8 BGR: one camera's median frame with the person's ghost inpainted."""
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(cv2.resize(frame[:, :1080], (360, 640), interpolation=cv2.INTER_AREA))
    stack = np.stack(frames)
    median = np.median(stack, axis=0).astype(np.uint8)
    moving = (np.abs(stack.astype(int) - median).sum(-1) > 40).mean(0)
    mask = (moving > 0.08).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    mask = cv2.dilate(mask, np.ones((15, 15), np.uint8))
    return cv2.inpaint(median, mask * 255, 9, cv2.INPAINT_TELEA)


def main():
    tiles = [camera_background(FOLDER / f"cam0{i}.mp4") for i in range(1, 5)]
    out = FOLDER / "background_median.jpg"
    cv2.imwrite(str(out), np.concatenate(tiles, axis=1), [cv2.IMWRITE_JPEG_QUALITY, 90])
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
