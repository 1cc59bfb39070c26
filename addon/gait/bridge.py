"""Gait models inside the .blend, learning from armatures and Acclaim files, and predicting a
walk onto an armature (the bridge behind the Gait panel's operators).

Models are stored on the scene (``scene.track_and_stride_gait.models``): name, the model's
``.npz`` bytes as base64 text (``GaitModel.to_bytes``), and a one-line summary, so they are
saved with the file. Decoded models are cached by content.

Nothing is changed before every check has passed: a request that cannot be carried out raises
:class:`~.rigs.GaitError` first.
"""

import base64
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np

from ...core.gait import (GaitModelFileError, GaitModel, ObservationStream, OnlineEM, adapt,
                          interpolate_styles, learn_model, mix_styles, observations_from_dofs,
                          predict_dofs)
from ...core.gait.foot_slide import planted_stride
from ...core.mocap import MocapParseError, asf_to_skeleton, read_amc, read_asf
from ..mocap.acclaim_bridge import find_asf_beside, scene_fps
from ..common.fcurves import (channelbag, ensure_action, keyframe_state, locked_channels,
                              modified_channels, not_editable)
from .rigs import (GaitError, channel_values, gait_rig, key_values, keyed_conflicts,
                   keyed_range, read_dofs)

SETTINGS = "track_and_stride_gait"   # Scene pointer property (addon/gait/props.py)
MAX_STYLES = 16                      # learned styles the redo panel's weight vector can address
_CACHE = {}


def gait_settings(scene):
    """The scene's gait settings (models, active index, preview settings)."""
    return getattr(scene, SETTINGS)


# ------------------------------------------------------------------------------ model storage
def encode_model(model):
    """A model as base64 text (stored in a StringProperty)."""
    return base64.b64encode(model.to_bytes()).decode("ascii")


def decode_model(text, name="model"):
    """The :class:`GaitModel` of stored text (cached by content); :class:`GaitError` if invalid."""
    key = hashlib.sha1(text.encode("ascii", "replace")).hexdigest()
    model = _CACHE.get(key)
    if model is None:
        try:
            model = GaitModel.from_bytes(base64.b64decode(text.encode("ascii"), validate=True),
                                         source=f"gait model {name!r}")
        except (ValueError, GaitModelFileError) as exc:
            raise GaitError(f"The stored gait model {name!r} cannot be read: {exc}") from None
        if len(_CACHE) > 8:
            _CACHE.clear()
        _CACHE[key] = model
    return model


def model_summary(model):
    """One line describing a model (J, styles, cadences)."""
    hz = model.fps / model.periods
    styles = ", ".join(model.style_names[:4]) + (" …" if len(model.style_names) > 4 else "")
    return (f"J={model.n_bases} from {len(model.style_names)} ({styles}); "
            f"cadence {hz.min():.2f}–{hz.max():.2f} cycles/s"
            f"{'; root travel' if model.root_travel else ''}")


def store_model(scene, model, name):
    """Add a model to the scene's list under a unique name and make it active."""
    settings = gait_settings(scene)
    taken = {item.name for item in settings.models}
    unique, k = name, 1
    while unique in taken:
        k += 1
        unique = f"{name}.{k:03d}"
    item = settings.models.add()
    item.name = unique
    item.data = encode_model(model)
    item.summary = model_summary(model)
    settings.active_model = len(settings.models) - 1
    return item


def active_model(scene):
    """(item, model) of the active list entry; :class:`GaitError` when there is none."""
    settings = gait_settings(scene)
    if len(settings.models) == 0:
        raise GaitError("No gait model in this file: learn one first (Gait › Learn)")
    index = min(max(settings.active_model, 0), len(settings.models) - 1)
    item = settings.models[index]
    return item, decode_model(item.data, item.name)


# ------------------------------------------------------------------------------ learning
def frame_range(grig, scene, mode, start=0, end=0):
    """Integer frames ``(first, last)`` to read from an armature: the keyed range of the
    channels the gait rig reads (``'ACTION'``; keys on other channels do not count), the
    scene's range (``'SCENE'``) or ``(start, end)`` (``'CUSTOM'``)."""
    obj = grig.obj
    if mode == "SCENE":
        first, last = scene.frame_start, scene.frame_end
    elif mode == "CUSTOM":
        first, last = start, end
    else:
        lo, hi = keyed_range(grig)
        first, last = int(np.ceil(lo - 1e-4)), int(np.floor(hi + 1e-4))
    if last <= first:
        raise GaitError(f"The frame range {first}–{last} of {obj.name} is empty")
    return int(first), int(last)


def _file_sequence(path, source_fps):
    """(DOF rows, DOF names, style name) of an Acclaim motion file."""
    asf_path = find_asf_beside(path)
    if asf_path is None:
        raise GaitError(f"No .asf skeleton found beside {Path(path).name}")
    try:
        asf = read_asf(asf_path)
        values = read_amc(path, asf, fps=source_fps).values
    except (MocapParseError, OSError) as exc:
        raise GaitError(str(exc)) from None
    return values, tuple(asf_to_skeleton(asf).dof_names()), Path(path).name.split(".")[0]


def learn_gait(context, objects=(), files=(), name="Gait Model", n_styles=0, range_mode="ACTION",
               source_fps=120.0):
    """Learn a model from armatures' actions and Acclaim files and store it in the scene.

    Parameters
    ----------
    objects : sequence of bpy.types.Object
        Armatures (Acclaim imports or CMU BVH conversions) with walking actions.
    files : sequence of str
        ``.amc`` paths (their ``.asf`` beside them).
    n_styles : int
        J; 0 picks it from the singular-value spectrum.
    range_mode : {'ACTION', 'SCENE'}
        Frames read from each armature.
    source_fps : float
        Capture rate of the files.

    Returns
    -------
    item, summary : the stored list entry and a report line
    """
    scene = context.scene
    sequences, names, rates, styles = [], [], [], []
    for obj in objects:
        grig = gait_rig(obj)
        first, last = frame_range(grig, scene, range_mode)
        sequences.append(read_dofs(grig, np.arange(first, last + 1)))
        names.append(grig.dof_names)
        rates.append(scene_fps(scene))
        styles.append(obj.name)
    for path in files:
        values, dof_names, style = _file_sequence(path, source_fps)
        sequences.append(values)
        names.append(dof_names)
        rates.append(float(source_fps))
        styles.append(style)
    if not sequences:
        raise GaitError("Nothing to learn from: select walking armatures or choose .amc files")
    try:
        model = learn_model(sequences, names, rates, styles, n_styles=n_styles or None)
    except ValueError as exc:
        raise GaitError(f"Cannot learn a gait model: {exc}") from None
    item = store_model(scene, model, name)
    return item, f"Learned {item.name}: {item.summary}"


# ------------------------------------------------------------------------------ prediction
@dataclass
class PredictOptions:
    """What the predict operator asks for (see its properties for meanings and units)."""

    range_mode: str = "ACTION"
    frame_start: int = 1
    frame_end: int = 100
    horizon: float = 2.0
    cadence: float = 1.0
    style_mode: str = "ADAPTED"
    style_a: str = ""
    style_b: str = ""
    blend: float = 0.5
    weights: tuple = field(default_factory=tuple)
    stride: float = 1.0
    root_travel: bool = True
    plant_feet: bool = True
    walker_detail: bool = True
    adaptation: str = "BATCH"
    target: str = "AFTER"


def _model_columns(model, grig):
    lookup = {n: i for i, n in enumerate(grig.dof_names)}
    missing = [n for n in model.dof_names if n not in lookup]
    if missing:
        raise GaitError(f"{grig.obj.name} lacks joints the gait model knows: "
                        f"{', '.join(missing[:8])}{' …' if len(missing) > 8 else ''}")
    return np.array([lookup[n] for n in model.dof_names], dtype=int)


def resolve_style(model, options, adapted):
    """The style vector (J,) the options ask for."""
    if options.style_mode == "BLEND":
        for name in (options.style_a, options.style_b):
            if name not in model.style_names:
                raise GaitError(f"Unknown style {name!r}; the model has "
                                f"{', '.join(model.style_names)}")
        return interpolate_styles(model, options.style_a, options.style_b, options.blend)
    if options.style_mode == "WEIGHTS":
        weights = np.zeros(len(model.style_names))
        given = np.asarray(options.weights, dtype=float)[:len(weights)]
        weights[:len(given)] = given
        try:
            return mix_styles(model, weights)
        except ValueError as exc:
            raise GaitError(f"Style weights: {exc}") from None
    return adapted


def _adapt(model, obs, fps, mode, dofs):
    """(state [ω, φ] at the last frame, style, walker residual table or None) from the observed
    window; only batch EM estimates the residual table (``core.gait.residual``)."""
    if mode == "ONLINE":
        stream = ObservationStream(model, model.dof_names, fps)
        online = OnlineEM(model, fps=fps)
        for row in dofs:
            online.step(stream.push(row))
        return np.array([online.omega, online.phase]), online.w, None
    res = adapt(model, obs, fps=fps)
    return res.state, res.w, res.residual


def _new_action_from_range(obj, bag, first, last):
    """A new action for ``obj`` holding exact copies of the keys of ``bag`` in
    [first, last]; the old action is kept (fake user) and left untouched. Returns its bag."""
    anim = obj.animation_data
    old = anim.action
    old.use_fake_user = True
    anim.action = bpy.data.actions.new(f"{old.name} Predicted")
    action, slot = ensure_action(obj, anim.action.name)
    new_bag = channelbag(action, slot, ensure=True)
    groups = {}
    for fcurve in bag.fcurves:
        state = keyframe_state(fcurve)
        keep = (state["co"][:, 0] >= first - 1e-4) & (state["co"][:, 0] <= last + 1e-4)
        copy = new_bag.fcurves.new(fcurve.data_path, index=fcurve.array_index)
        if fcurve.group is not None:
            name = fcurve.group.name
            groups[name] = groups.get(name) or new_bag.groups.new(name)
            copy.group = groups[name]
        copy.extrapolation = fcurve.extrapolation
        points = copy.keyframe_points
        points.add(int(keep.sum()))
        for prop, array in state.items():
            points.foreach_set(prop, np.ascontiguousarray(array[keep]).reshape(-1))
        # The rest of a key: its type (Keyframe, Breakdown, ...) and easing parameters.
        source = fcurve.keyframe_points
        for prop, dtype in (("type", np.int32), ("back", np.float32),
                            ("amplitude", np.float32), ("period", np.float32)):
            array = np.empty(len(source), dtype=dtype)
            source.foreach_get(prop, array)
            points.foreach_set(prop, np.ascontiguousarray(array[keep]))
    return new_bag


def planted_factor(grig, model, state, w, n, last_dofs, cols, fps, options, residual=None):
    """Stride factor that keeps the stance foot planted (``core.gait.planted_stride``) for
    the prediction as the model makes it; 1 when disabled or without root travel."""
    feet = ("ltoes", "rtoes")
    if not (options.plant_feet and options.root_travel and model.root_travel) \
            or any(f not in grig.skeleton.names for f in feet):
        return 1.0
    raw = predict_dofs(model, state, w, n, last_dofs[cols], fps, omega_scale=options.cadence,
                       residual=residual)
    rows = np.tile(last_dofs, (n + 1, 1))
    rows[1:, cols] = raw
    return planted_stride(grig.skeleton, rows, feet)


def _observe(grig, model, scene, options):
    """(first, last, DOF rows of [first, last]) after the shortest-cycle check."""
    fps = scene_fps(scene)
    first, last = frame_range(grig, scene, options.range_mode, options.frame_start,
                              options.frame_end)
    n_obs = last - first + 1
    shortest = float(np.min(model.periods)) / model.fps
    if n_obs / fps < shortest:
        raise GaitError(f"Observed {n_obs} frames ({n_obs / fps:.2f} s) is shorter than one gait "
                        f"cycle (the quickest learned walker needs {shortest:.2f} s): observe "
                        f"at least one full cycle")
    return first, last, read_dofs(grig, np.arange(first, last + 1))


def _target_bag(obj, grig, options, first, last, frames):
    """The channelbag to key into: the action's own (after a conflict check) or a new one."""
    anim = obj.animation_data
    bag = channelbag(anim.action, anim.action_slot)
    if options.target != "AFTER":
        return _new_action_from_range(obj, bag, first, last)
    clash = keyed_conflicts(bag, grig.targets(), frames[0], frames[-1])
    if clash:
        raise GaitError(f"Frames {frames[0]}–{frames[-1]} already hold keys on {clash} "
                        f"F-curves of {anim.action.name}: choose Target › New Action, a shorter "
                        f"horizon, or an earlier observed range")
    locked = locked_channels(bag, grig.targets())
    if locked:
        raise GaitError(f"{len(locked)} F-curve{'s' * (len(locked) != 1)} of "
                        f"{anim.action.name} that the prediction writes "
                        f"{'are' if len(locked) != 1 else 'is'} locked ({', '.join(locked[:3])}"
                        f"{' …' if len(locked) > 3 else ''}): unlock "
                        f"{'them' if len(locked) != 1 else 'it'} or choose Target › New Action")
    # The observation was read through the curves' modifiers: keys written under them would
    # apply them twice (a Noise doubled, a Cycles period stretched).
    modified = modified_channels(bag, grig.targets())
    if modified:
        one = len(modified) == 1
        raise GaitError(f"{len(modified)} F-curve{'s' * (not one)} of {anim.action.name} that "
                        f"the prediction writes {'has' if one else 'have'} active modifiers "
                        f"({', '.join(modified[:3])}{' …' if len(modified) > 3 else ''}): keys "
                        f"written under a modifier would apply it twice; mute or remove "
                        f"{'it' if one else 'them'} (Graph Editor › Sidebar › Modifiers) or choose "
                        "Target › New Action")
    return bag


def predict_gait(context, obj, options):
    """Observe, adapt, predict and key the prediction on ``obj`` (module docstring).

    Returns
    -------
    str
        Report line.
    """
    scene = context.scene
    fps = scene_fps(scene)
    item, model = active_model(scene)
    grig = gait_rig(obj)
    anim = obj.animation_data
    message = not_editable(obj, anim.action if anim is not None and options.target == "AFTER"
                           else None)
    if message:
        raise GaitError(message)
    cols = _model_columns(model, grig)
    first, last, dofs = _observe(grig, model, scene, options)
    model_dofs = dofs[:, cols]
    obs = observations_from_dofs(model, model_dofs, model.dof_names, fps)
    state, w_adapted, residual = _adapt(model, obs, fps, options.adaptation, model_dofs)
    period = 2.0 * np.pi / state[0]
    if len(dofs) < period:
        raise GaitError(f"Observed {len(dofs)} frames ({len(dofs) / fps:.2f} s) is shorter than "
                        f"one gait cycle of this walker (about {period / fps:.2f} s): observe "
                        f"more frames")
    w = resolve_style(model, options, w_adapted)
    # The walker's own details belong to the adapted style only: restyled gaits use the
    # learned templates as they are.
    if not (options.walker_detail and options.style_mode == "ADAPTED"):
        residual = None
    n = int(round(options.horizon * fps))
    if n < 1:
        raise GaitError("The horizon is shorter than one frame")
    k = planted_factor(grig, model, state, w, n, dofs[-1], cols, fps, options, residual)
    try:
        pred = predict_dofs(model, state, w, n, model_dofs[-1], fps, omega_scale=options.cadence,
                            stride=k * options.stride, travel=options.root_travel,
                            residual=residual)
    except ValueError as exc:
        raise GaitError(str(exc)) from None
    full = np.tile(dofs[-1], (n, 1))
    full[:, cols] = pred
    frames = last + np.arange(1, n + 1)
    anim = obj.animation_data
    values = channel_values(grig, channelbag(anim.action, anim.action_slot), full, last, dofs[-1])
    written = key_values(grig, _target_bag(obj, grig, options, first, last, frames), frames, values)
    return (f"Predicted {n} frames ({n / fps:.2f} s) after frame {last} with {item.name}: "
            f"{fps / period * options.cadence:.2f} cycles/s, style "
            f"{options.style_mode.lower()}, stride ×{k:.2f}{' (planted)' if k != 1.0 else ''}; "
            f"{written} keys in {obj.animation_data.action.name}")
