"""Reference footage -> grayscale float frames, decoded with Blender's own means (never pip).

Sources: a MovieClip datablock (movie or image sequence), a movie file, or the first file of a
numbered image sequence. Image files load with ``bpy.data.images.load``. Movies are decoded by
Blender's FFmpeg into an Image datablock (source ``MOVIE``), frame by frame:

* ``Image.pixels`` shows the frame the image last gave an *image user* (``ima->lastframe``;
  without one it only ever shows the first frame), so the reader points an IMAGE texture's
  ``image_user.frame_current`` at the frame and samples the texture once
  (``Texture.evaluate``): Blender decodes that frame, caches it and ``pixels`` then reads it.
  No render, no file written; bit-identical to rendering the frame through the sequencer to
  PNG (what this module did before: 5-8x slower), tested on Blender 4.5, 5.0 and 5.2.
* The image stays open while a run reads its frames (:class:`FootageReader`): FFmpeg then
  decodes on from the frame before instead of seeking again from the movie's previous
  keyframe for each chunk (the Pose2Sim demo has one keyframe: a fresh seek to frame *k*
  decodes *k* frames, so reopening per chunk made reading quadratic in the clip's length).
  Decoded frames pass through Blender's image cache (bounded by *Preferences › System ›
  Memory Cache Limit*) and are freed when the reader closes.

Frame mapping: scene frame ``f`` shows footage frame ``f - scene_start + offset`` (0-based), like
a MovieClip's ``frame_start`` / ``frame_offset``. Grayscale = Rec. 709 luma of the stored
(display-referred) RGB values; rows top to bottom (Blender stores them bottom-up). An 8-bit
movie or image gives its stored bytes / 255. A movie of more than 8 bits per channel (10-bit
H.265, ProRes, FFV1 …) decodes to scene-linear floats in Blender 5: those are encoded with the
sRGB transfer function (clipped to [0, 1]) — what Blender's *Standard* view on an sRGB display
shows, and what the sequencer's 8-bit render gave (to its 1/255 quantisation).
"""

import os
import re
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


def _luma_into(image, out, buffer, display_encode_floats=False):
    """Rec. 709 luma of a loaded image into ``out`` (H, W), rows top to bottom.

    ``buffer`` is float32 scratch space of ``width * height * channels`` values (reused from
    frame to frame: a fresh 33 MB array per 1080x1920 frame costs its page faults every time).
    ``display_encode_floats``: a float image's values are sRGB-encoded first (movies, module
    docstring); float image files (EXR …) give their stored values, as they always did.
    """
    width, height = image.size
    channels = image.channels
    image.pixels.foreach_get(buffer)
    rows = buffer.reshape(height, width, channels)
    if channels < 3:
        out[::-1] = rows[..., 0]
        return
    rgb = rows[..., :3]
    if display_encode_floats and image.is_float:     # scene-linear: to display sRGB
        rgb = _srgb_encode(rgb)
    np.matmul(rgb, LUMA, out=out[::-1])     # Blender's rows are bottom-up


def _srgb_encode(linear):
    """The sRGB transfer function (IEC 61966-2-1) of linear values clipped to [0, 1]."""
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055).astype(np.float32)


def _read_sequence(files, indices, out):
    """Image files ``files[i]`` for ``i`` in ``indices`` as luma into ``out`` (N, H, W)."""
    height, width = out.shape[1:]
    buffer = None
    for k, index in enumerate(indices):
        if not os.path.isfile(files[index]):
            raise FootageError(f"Footage image {files[index]} is missing (moved or deleted "
                               "since the footage was chosen)")
        image = _load_image(files[index])
        try:
            if tuple(image.size) != (width, height):
                raise FootageError(f"{files[index]} is {image.size[0]}x{image.size[1]}, "
                                   f"the footage is {width}x{height}")
            size = width * height * image.channels
            if buffer is None or buffer.size != size:
                buffer = np.empty(size, dtype=np.float32)
            _luma_into(image, out[k], buffer)
        finally:
            bpy.data.images.remove(image)
    return out


_DECODER_NAME = "Track & Stride footage decoder"


class _MovieDecoder:
    """One movie open in Blender: an Image (source MOVIE) and an IMAGE texture whose image
    user picks the frame (module docstring). Frame numbers are 0-based here."""

    def __init__(self, footage):
        path = footage.path
        if not os.path.isfile(path):
            raise FootageError(f"Footage file {path} is missing (moved or deleted since the "
                               "footage was chosen)")
        try:
            image = bpy.data.images.load(path, check_existing=False)
        except RuntimeError as exc:
            raise FootageError(f"Blender cannot decode {path}: {exc}") from None
        self.path, self.image, self.texture = path, image, None
        try:
            if image.source != "MOVIE" or tuple(image.size) != (footage.width, footage.height):
                raise FootageError(f"Blender cannot decode {path} as the movie it was "
                                   f"({footage.width}x{footage.height}) when the footage was "
                                   "chosen")
            image.name = _DECODER_NAME          # what the Blend File view shows meanwhile
            self.n_frames = image.frame_duration
            self.texture = bpy.data.textures.new(_DECODER_NAME, "IMAGE")
            self.texture.image = image
            self.texture.image_user.frame_duration = self.n_frames
            self.buffer = np.empty(footage.width * footage.height * image.channels,
                                   dtype=np.float32)
        except BaseException:
            self.close()
            raise

    def read_into(self, index, out):
        """Footage frame ``index`` (0-based) as luma into ``out`` (H, W)."""
        if index >= self.n_frames:       # Blender would repeat the last frame: refuse instead
            raise FootageError(f"Blender cannot decode {self.path}: it holds {self.n_frames} "
                               f"frames, frame {index + 1} is needed")
        self.texture.image_user.frame_current = index + 1   # Blender's movie frames count from 1
        self.texture.evaluate((0.0, 0.0, 0.0))              # the image user acquires that frame
        if tuple(self.image.size) != out.shape[::-1]:
            raise FootageError(f"Blender could not decode frame {index + 1} of {self.path}")
        _luma_into(self.image, out, self.buffer, display_encode_floats=True)

    def close(self):
        """Remove the texture and the image (with its decoder and cached frames); idempotent."""
        for collection, attr in ((bpy.data.textures, "texture"), (bpy.data.images, "image")):
            block = getattr(self, attr)
            setattr(self, attr, None)
            if block is not None:
                try:
                    collection.remove(block)
                except ReferenceError:  # already gone (a file was loaded): nothing to remove
                    pass


class FootageReader:
    """Reads grey frames of one footage, chunk after chunk (a context manager; :meth:`close`).

    A movie is opened on the first read and stays open until :meth:`close` (module docstring:
    sequential reading costs one decode per frame, in any chunking); an image sequence has
    nothing to keep open.
    """

    def __init__(self, footage):
        self.footage = footage
        self._movie = None

    def read(self, scene_frames, out=None):
        """Grayscale frames for scene frames.

        Parameters
        ----------
        scene_frames : sequence of int
        out : ndarray, shape (N, height, width), float32, optional
            Where to write the frames (a slice of the caller's array: no copy).

        Returns
        -------
        ndarray, shape (N, height, width), float32 in [0, 1]

        Raises
        ------
        FootageError
            A frame outside the footage, or a file that cannot be read (the message names it).
        """
        footage = self.footage
        indices = [footage.footage_index(f) for f in scene_frames]
        outside = [f for f, i in zip(scene_frames, indices) if not 0 <= i < footage.n_frames]
        if outside:
            raise FootageError(f"Scene frames {outside[0]}..{outside[-1]} lie outside the footage "
                               f"({footage.n_frames} frames starting at scene frame "
                               f"{footage.scene_start})")
        shape = (len(indices), footage.height, footage.width)
        if out is None:
            out = np.empty(shape, dtype=np.float32)
        elif out.shape != shape or out.dtype != np.float32:
            raise ValueError(f"Expected out of shape {shape}, float32; got {out.shape}, {out.dtype}")
        if footage.kind == "SEQUENCE":
            files = footage.files or tuple(_sequence_files(footage.path))
            return _read_sequence(files, indices, out)
        if not os.path.isfile(footage.path):
            raise FootageError(f"Footage file {footage.path} is missing (moved or deleted since "
                               "the footage was chosen)")
        if self._movie is None:
            self._movie = _MovieDecoder(footage)
        try:
            for k, index in enumerate(indices):
                self._movie.read_into(index, out[k])
        except BaseException:
            self.close()
            raise
        return out

    def close(self):
        """Free the open movie (its Image and texture datablocks); safe to call twice."""
        if self._movie is not None:
            movie, self._movie = self._movie, None
            movie.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read_frames(footage, scene_frames):
    """Grayscale frames for scene frames (:meth:`FootageReader.read`, opened and closed here).

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
    with FootageReader(footage) as reader:
        return reader.read(scene_frames)
