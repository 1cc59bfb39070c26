"""Study (issue 22): what a half-resolution read of a movie frame costs in Blender, per step.

Run with the bpy venv: ``.venv/bin/python benchmarks/studies/decode_scaled.py MOVIE [N]``.

For each of the first N frames, in one process: Blender decodes the frame (``Texture.evaluate``
on an IMAGE texture whose image user picks it, as ``addon/tracking/footage.py`` does); its
full-resolution luma is read (``Image.pixels.foreach_get`` + the luma matmul); then the decoded
frame is scaled to half size in C (``Image.scale(w // 2, h // 2, frame=...)``) and its luma read
again. Prints the median milliseconds of each step and checks that the half-size luma is the
2x2 mean of the full one (to Blender's 8-bit rounding) for every frame: that the scaled read
follows the movie instead of freezing on the first frame (what ``Image.scale`` without ``frame``
did, docs/tracking.md, session 35).
"""

import sys
import time

import bpy
import numpy as np

LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def luma(image, buffer, out):
    width, height = image.size
    image.pixels.foreach_get(buffer[:width * height * 4])
    t = time.perf_counter()
    rows = buffer[:width * height * 4].reshape(height, width, 4)
    np.matmul(rows[..., :3], LUMA, out=out[::-1])
    return time.perf_counter() - t


def main(path, n):
    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    tex = bpy.data.textures.new("decoder", "IMAGE")
    tex.image = image
    tex.image_user.frame_duration = image.frame_duration
    buffer = np.empty(width * height * 4, np.float32)
    full = np.empty((height, width), np.float32)
    half = np.empty((height // 2, width // 2), np.float32)
    times = {k: [] for k in ("decode", "full pixels", "full luma", "scale", "half pixels", "half luma")}
    worst = 0.0
    previous = None
    for i in range(n):
        t0 = time.perf_counter()
        tex.image_user.frame_current = i + 1
        tex.evaluate((0.0, 0.0, 0.0))
        t1 = time.perf_counter()
        lf = luma(image, buffer, full)
        t2 = time.perf_counter()
        image.scale(width // 2, height // 2, frame=i + 1)
        t3 = time.perf_counter()
        lh = luma(image, buffer, half)
        t4 = time.perf_counter()
        times["decode"].append(t1 - t0)
        times["full pixels"].append(t2 - t1 - lf)
        times["full luma"].append(lf)
        times["scale"].append(t3 - t2)
        times["half pixels"].append(t4 - t3 - lh)
        times["half luma"].append(lh)
        mean = full.reshape(height // 2, 2, width // 2, 2).mean(axis=(1, 3))
        worst = max(worst, float(np.abs(half - mean).max()))
        if previous is not None:
            moved = float(np.abs(full - previous).mean())
            assert moved > 0, f"frame {i + 1} equals the frame before"
        previous = full.copy()
    for key, values in times.items():
        print(f"{key:12s} {1000 * np.median(values):6.2f} ms (min {1000 * min(values):6.2f})")
    print(f"half luma vs the 2x2 mean of the full luma: max |difference| {worst:.5f} "
          f"({worst * 255:.2f} / 255)")


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    main(argv[0], int(argv[1]) if len(argv) > 1 else 30)
