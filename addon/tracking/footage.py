"""Reference footage -> grayscale float frames, decoded with Blender's own means (never pip).

Sources: a MovieClip datablock (movie or image sequence), a movie file, or the first file of a
numbered image sequence. Movies are decoded by Blender's FFmpeg: a temporary scene holds a VSE
movie strip and renders the needed frames to PNG (``bpy.data.images.load(movie).pixels`` only
ever gives the first frame); image files load with ``bpy.data.images.load``.

Frame mapping: scene frame ``f`` shows footage frame ``f - scene_start + offset`` (0-based), like
a MovieClip's ``frame_start`` / ``frame_offset``. Grayscale = Rec. 709 luma of the stored
(display-referred) RGB values; rows top to bottom (Blender stores them bottom-up).
"""

import os
import re
import shutil
import tempfile
from dataclasses import dataclass

import bpy
import numpy as np

MOVIE_EXTENSIONS = (".mp4", ".mov", ".avi", ".mkv", ".webm", ".mpg", ".mpeg", ".m4v", ".ogv", ".dv", ".flv")
LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


class FootageError(ValueError):
    """Footage cannot be read (the message names the file and the reason)."""


@dataclass(frozen=True)
class Footage:
    """Where frames come from.

    Attributes
    ----------
    kind : {'MOVIE', 'SEQUENCE'}
    path : str
        The movie file, or the first image of the sequence.
    scene_start : int
        Scene frame that shows footage frame ``offset``.
    offset : int
        Footage frame (0-based) shown at ``scene_start``.
    n_frames : int
        Frames available.
    width, height : int
        Pixels.
    files : tuple of str
        A sequence's image files, listed once when the footage is described (a file deleted
        later is reported by name, not silently skipped); empty for a movie.
    """

    kind: str
    path: str
    scene_start: int
    offset: int
    n_frames: int
    width: int
    height: int
    files: tuple = ()

    def footage_index(self, scene_frame):
        """0-based footage frame shown at ``scene_frame``."""
        return int(scene_frame) - self.scene_start + self.offset

    def covers(self, scene_frame):
        """Whether ``scene_frame`` has a footage frame."""
        return 0 <= self.footage_index(scene_frame) < self.n_frames


def _sequence_files(first_path):
    """Files of the numbered sequence that starts at ``first_path`` (consecutive numbers)."""
    folder, name = os.path.split(os.path.abspath(first_path))
    stem, ext = os.path.splitext(name)
    match = re.match(r"^(.*?)(\d+)$", stem)
    if not match:
        return [os.path.join(folder, name)]
    prefix, digits = match.groups()
    number = int(digits)
    files = []
    while True:
        candidate = os.path.join(folder, f"{prefix}{str(number).zfill(len(digits))}{ext}")
        if not os.path.isfile(candidate):
            break
        files.append(candidate)
        number += 1
    return files


def _image_size(path):
    image = _load_image(path)
    try:
        return tuple(image.size)
    finally:
        bpy.data.images.remove(image)


def _load_image(path):
    try:
        image = bpy.data.images.load(path, check_existing=False)
    except RuntimeError as exc:
        raise FootageError(f"Cannot read image {path}: {exc}") from None
    if image.size[0] == 0 or image.size[1] == 0:
        bpy.data.images.remove(image)
        raise FootageError(f"Cannot read image {path}: empty or unsupported")
    return image


def footage_from_path(path, scene_start=1, offset=0):
    """Describe a movie file or an image sequence (given by its first file).

    Raises
    ------
    FootageError
        Missing or unreadable file.
    """
    path = bpy.path.abspath(path)
    if not path or not os.path.isfile(path):
        raise FootageError(f"Footage file not found: {path or '(none)'}")
    if path.lower().endswith(MOVIE_EXTENSIONS):
        try:
            clip = bpy.data.movieclips.load(path, check_existing=False)
        except RuntimeError as exc:
            raise FootageError(f"Cannot open movie {path}: {exc}") from None
        try:
            width, height = clip.size
            n_frames = clip.frame_duration
        finally:
            bpy.data.movieclips.remove(clip)
        if width == 0 or n_frames == 0:
            raise FootageError(f"Cannot decode movie {path}")
        return Footage("MOVIE", path, int(scene_start), int(offset), int(n_frames), int(width), int(height))
    files = _sequence_files(path)
    width, height = _image_size(files[0])
    return Footage("SEQUENCE", files[0], int(scene_start), int(offset), len(files), width, height,
                   tuple(files))


def footage_from_clip(clip):
    """Describe a MovieClip datablock's footage (its frame_start and frame_offset apply)."""
    if clip is None:
        raise FootageError("No movie clip selected")
    footage = footage_from_path(clip.filepath, scene_start=clip.frame_start, offset=clip.frame_offset)
    return footage


def _pixels_gray(image):
    width, height = image.size
    channels = image.channels
    buffer = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(buffer)
    rgba = buffer.reshape(height, width, channels)[::-1]
    if channels >= 3:
        return np.ascontiguousarray(rgba[..., :3] @ LUMA)
    return np.ascontiguousarray(rgba[..., 0])


def _read_sequence(files, indices, width, height):
    out = np.empty((len(indices), height, width), dtype=np.float32)
    for k, index in enumerate(indices):
        if not os.path.isfile(files[index]):
            raise FootageError(f"Footage image {files[index]} is missing (moved or deleted "
                               "since the footage was chosen)")
        image = _load_image(files[index])
        try:
            if tuple(image.size) != (width, height):
                raise FootageError(f"{files[index]} is {image.size[0]}x{image.size[1]}, "
                                   f"the footage is {width}x{height}")
            out[k] = _pixels_gray(image)
        finally:
            bpy.data.images.remove(image)
    return out


def _render_frames(scene):
    """Render the scene's frame range (its output settings) with Blender's renderer."""
    bpy.ops.render.render(animation=True, scene=scene.name)


def _strip_length(strip):
    """Frames of a sequencer strip between its handles: ``duration`` from Blender 5.2 on,
    ``frame_final_duration`` before (deprecated in 5.2, removed in 6.0)."""
    if "duration" in strip.bl_rna.properties:
        return strip.duration
    return strip.frame_final_duration


def _decode_movie(footage, first, last, folder):
    """Render movie frames first..last (0-based) to PNG files via a temporary VSE scene.

    Raises
    ------
    FootageError
        The movie is gone or Blender cannot decode or render it (the sequencer makes a
        one-frame strip of a missing file and renders black: that is caught too).
    """
    if not os.path.isfile(footage.path):
        raise FootageError(f"Footage file {footage.path} is missing (moved or deleted since the "
                           "footage was chosen)")
    scene = bpy.data.scenes.new("Track & Stride footage decoder")
    try:
        editor = scene.sequence_editor_create()
        try:
            strip = editor.strips.new_movie("footage", footage.path, 1, 1)
        except RuntimeError as exc:
            raise FootageError(f"Blender cannot decode {footage.path}: {exc}") from None
        length = _strip_length(strip)
        if length < last + 1:
            raise FootageError(f"Blender cannot decode {footage.path}: it holds "
                               f"{length} frames, frame {last + 1} is needed")
        strip.colorspace_settings.name = "sRGB"
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.sequencer_colorspace_settings.name = "sRGB"
        scene.render.resolution_x, scene.render.resolution_y = footage.width, footage.height
        scene.render.resolution_percentage = 100
        scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
        scene.render.use_sequencer = True
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_mode = "RGB"
        scene.render.image_settings.color_depth = "8"
        scene.frame_start, scene.frame_end = first + 1, last + 1
        scene.render.filepath = os.path.join(folder, "frame_")
        try:
            _render_frames(scene)
        except RuntimeError as exc:
            raise FootageError(f"Blender could not decode frames {first + 1}–{last + 1} of "
                               f"{footage.path}: {exc}") from None
    finally:
        bpy.data.scenes.remove(scene)
    return [os.path.join(folder, f"frame_{i + 1:04d}.png") for i in range(first, last + 1)]


def read_frames(footage, scene_frames):
    """Grayscale frames for scene frames.

    Parameters
    ----------
    footage : Footage
    scene_frames : sequence of int

    Returns
    -------
    ndarray, shape (N, height, width), float32 in [0, 1]

    Raises
    ------
    FootageError
        A frame outside the footage, or a file that cannot be read.
    """
    indices = [footage.footage_index(f) for f in scene_frames]
    outside = [f for f, i in zip(scene_frames, indices) if not 0 <= i < footage.n_frames]
    if outside:
        raise FootageError(f"Scene frames {outside[0]}..{outside[-1]} lie outside the footage "
                           f"({footage.n_frames} frames starting at scene frame {footage.scene_start})")
    if footage.kind == "SEQUENCE":
        files = footage.files or tuple(_sequence_files(footage.path))
        return _read_sequence(files, indices, footage.width, footage.height)
    first, last = min(indices), max(indices)
    folder = tempfile.mkdtemp(prefix="ts-footage-")
    try:
        files = _decode_movie(footage, first, last, folder)
        missing = [f for f in files if not os.path.isfile(f)]
        if missing:
            raise FootageError(f"Blender could not decode frames of {footage.path}")
        return _read_sequence(files, [i - first for i in indices], footage.width, footage.height)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
