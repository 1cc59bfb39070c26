"""Learning, predicting and model files behind the Gait panel, and the plain-argument functions
a script or a command line can call (``learn``, ``predict``, ``export_model``, ``import_model``:
names and numbers in, a summary dict out, :class:`~.rigs.GaitError` when they cannot run).

Models live in the file (``storage.py``); the stock library is always available.

Nothing is changed before every check has passed: a request that cannot be carried out raises
:class:`~.rigs.GaitError` first. Predict refuses what is not a gait (``core.gait.checks``) and
replaces its own earlier prediction instead of observing it: every prediction is recorded on
its action (``PROP_PREDICTION``: observed and predicted frames, a digest of the keys written);
while those keys are unchanged, a new Predict observes the frames before them and writes over
them.
"""

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path

import bpy
import numpy as np

from ...core import limits
from ...core.gait import (ObservationStream, OnlineEM, adapt, learn_model,
                          observations_from_dofs, restyle)
from ...core.gait.checks import check_gait, with_fit
from ...core.gait import keyed as keyed_reading
from ...core.gait.leg_travel import fit_leg_travel
from ...core.gait.walk import WalkRequest, predict_walk
from ...core.rigs import plain_list
from ...core.rigs.reading_offset import reading_offset_variance
from ...core.mocap import MocapParseError, asf_to_skeleton, read_amc, read_asf
from ..mocap.acclaim_bridge import find_asf_beside, scene_fps
from ..common.fcurves import (channelbag, ensure_action, keyframe_state, locked_channels,
                              modified_channels, not_editable)
from . import storage
from .rigs import (GaitError, _action_bag, channel_values, gait_rig, key_values, keyed_range,
                   read_dofs)

SETTINGS = storage.SETTINGS
PROP_PREDICTION = "track_and_stride_predictions"   # on an action: {object name: record}
MIN_OBSERVED_S = 0.5     # seconds the model needs to pick up a walker (the benchmark's shortest)


def gait_settings(scene):
    """The scene's live-preview settings."""
    return getattr(scene, SETTINGS)


def active_model(scene=None):
    """(name, model) that Predict and the live preview use (``scene`` is not needed: models
    are file-wide; kept for callers that pass it)."""
    return storage.active_entry()


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
    """Learn a model from armatures' actions and Acclaim files and store it in the file.

    Parameters
    ----------
    objects : sequence of bpy.types.Object
        Armatures with walking actions (Acclaim imports, CMU BVH conversions, or rigs with
        a body map: Rigify, Mixamo, a metarig …), one walker
        each.
    files : sequence of str
        ``.amc`` paths (their ``.asf`` beside them); the files of one subject (``08_01``,
        ``08_04``: the part before ``_``) count as one walker.
    n_styles : int
        Style dimensions (the paper's J); 0 picks them from the singular-value spectrum.
    range_mode : {'ACTION', 'SCENE'}
        Frames read from each armature.
    source_fps : float
        Capture rate of the files.

    Returns
    -------
    dict
        ``model`` (the stored name), ``styles``, ``style_count`` (J), ``sequences``, ``message``.
    """
    scene = context.scene
    try:
        n_styles = limits.check("n_styles", n_styles)
        source_fps = limits.check("learn_rate", source_fps)
    except limits.OutOfBounds as exc:
        raise GaitError(str(exc)) from None
    sequences, names, rates, styles, walkers = [], [], [], [], []
    for obj in objects:
        grig = gait_rig(obj)
        first, last = frame_range(grig, scene, range_mode)
        sequences.append(read_dofs(grig, np.arange(first, last + 1)))
        names.append(grig.dof_names)
        rates.append(scene_fps(scene))
        styles.append(obj.name)
        walkers.append(f"object {obj.name}")
    for path in files:
        values, dof_names, style = _file_sequence(path, source_fps)
        sequences.append(values)
        names.append(dof_names)
        rates.append(float(source_fps))
        styles.append(style)
        walkers.append(f"file {style.split('_')[0]}")
    if not sequences:
        raise GaitError("Nothing to learn from: select walking armatures or choose .amc files")
    try:
        model = learn_model(sequences, names, rates, styles, n_styles=n_styles or None,
                            walkers=walkers)
    except ValueError as exc:
        raise GaitError(f"Cannot learn a gait model: {exc}") from None
    item = storage.add_model(model, name)
    return {"status": "ok", "model": item.name, "styles": list(model.style_names),
            "style_count": model.n_bases, "sequences": len(sequences),
            "message": f"Learned {item.name}: {item.summary}"}


def learn(files=(), objects=(), name="Gait Model", n_styles=0, range_mode="ACTION",
          source_fps=120.0):
    """:func:`learn_gait` with plain arguments (object names, file paths) on the current scene;
    returns its summary dict."""
    objs = [_object(n) for n in objects]
    with limits.naming("api", outer_wins=True):
        return learn_gait(bpy.context, objs, [str(f) for f in files], name, n_styles,
                          range_mode, source_fps)


def _object(name):
    obj = bpy.data.objects.get(str(name)) if isinstance(name, str) else name
    if obj is None:
        raise GaitError(f"No object named {name!r} in this file")
    return obj


# ------------------------------------------------------------------------------ prediction
@dataclass
class PredictOptions:
    """What the predict operator asks for (see its properties for meanings and units).

    ``style_mode``: ``'OBSERVED'`` (the walker as adapted), ``'RESTYLE'`` (moved from
    ``restyle_from`` towards ``restyle_to`` by ``restyle_amount``, ``core.gait.restyle``) or
    ``'LIBRARY'`` (exactly the learned style ``library_style``, at its own cadence).
    ``retime``: ``'NATURAL'`` (a cadence change moves the style the way the training walkers'
    styles change with their pace) or ``'FAST_FORWARD'`` (the same walk played faster).
    ``turn``: degrees per second (positive: to the left; 0: straight on).
    ``model``: a model name of the file ('' = the active one) or the path of a model file."""

    range_mode: str = "ACTION"
    frame_start: int = 1
    frame_end: int = 100
    horizon: float = 2.0
    cadence: float = 1.0
    style_mode: str = "OBSERVED"
    restyle_from: str = ""
    restyle_to: str = ""
    restyle_amount: float = 1.0
    library_style: str = ""
    stride: float = 1.0
    root_travel: bool = True
    plant_feet: bool = True
    mannerisms: bool = True
    adaptation: str = "BATCH"
    target: str = "AFTER"
    model: str = ""
    retime: str = "NATURAL"
    turn: float = 0.0


#: PredictOptions fields that are numbers a user types -> their bound in ``core.limits``.
_BOUNDED = (("horizon", "length"), ("cadence", "cadence"), ("stride", "stride"),
            ("restyle_amount", "restyle_amount"), ("turn", "turn"))


def checked_options(options):
    """``options`` with every number checked against ``core.limits`` (:class:`GaitError`
    naming the value, its range and the option as the calling door names it)."""
    try:
        values = {field: limits.check(key, getattr(options, field)) for field, key in _BOUNDED}
        if options.range_mode == "CUSTOM":
            values["frame_start"], values["frame_end"] = limits.check_frame_range(
                "predict_frame", options.frame_start, options.frame_end)
    except limits.OutOfBounds as exc:
        raise GaitError(str(exc)) from None
    return replace(options, **values)


def resolve_model(name):
    """(name, model) for a Predict request: '' = the active model, a file's model name, the
    stock library's name, or the path of a model file (``.npz``)."""
    if not name:
        return storage.active_entry()
    if str(name).lower().endswith(".npz") or Path(name).is_file():
        from ...core.gait import GaitModel, GaitModelFileError
        try:
            return Path(name).name, GaitModel.load(name)
        except OSError as exc:
            raise GaitError(f"Cannot read {name}: {exc.strerror or exc}") from None
        except GaitModelFileError as exc:
            raise GaitError(str(exc)) from None
    return name, storage.model_by_name(name)


def model_hold(model, grig):
    """Values (n_dofs,) at which to hold the joint angles the armature cannot show (a rig
    without fingers, toes or a second neck bone: ``grig.observed``): the model's mean pose,
    so that the walker is not taken to hold them at zero (``GaitSpace.dofs``'s ``hold``);
    None when the armature shows every angle."""
    if grig.observed.all():
        return None
    centre = dict(zip(model.angle_names, model.angle_centre[:model.n_angles]))
    return np.array([centre.get(name, 0.0) for name in grig.dof_names])


def _control_warnings(grig):
    """A warning when a mapped rig's controls could not put its parts on the prediction."""
    if grig.kind != "MAPPED":
        return []
    angle, dist = grig.last_errors
    if np.degrees(angle) <= 2.0 and dist <= 0.02:
        return []
    return [f"{grig.obj.name}'s controls could not put every part exactly on the predicted "
            f"walk: up to {np.degrees(angle):.1f}° and {100 * dist:.1f} cm off (the rig's "
            "constraints or limits, or an IK limb out of reach)"]


def _controls_said(grig):
    """' on the rig's FK controls …' for a mapped rig's report ('' for other armatures)."""
    if grig.kind != "MAPPED":
        return ""
    ik = sorted(limb for limb, mode in grig.mapped.modes.items() if mode == "IK")
    controls = len({st.control for st in grig.steps})
    where = f"IK {plain_list(ik)}" if ik else "FK"
    return (f" on {controls} controls of the {grig.mapped.body_map.rig} rig ({where}; "
            f"{grig.space.leg_length:.2f} m legs)")


def _model_columns(model, grig):
    lookup = {n: i for i, n in enumerate(grig.dof_names)}
    missing = [n for n in model.dof_names if n not in lookup]
    if missing:
        raise GaitError(f"{grig.obj.name} lacks joints the gait model knows: "
                        f"{', '.join(missing[:8])}{' …' if len(missing) > 8 else ''}")
    return np.array([lookup[n] for n in model.dof_names], dtype=int)


def _known_style(model, name, what):
    if name not in model.style_names:
        raise GaitError(f"{what}: the model has no style {name!r} (its styles: "
                        f"{', '.join(model.style_names)})")


@dataclass
class Adapted:
    """The observed walker: state at the last observed frame, style, posture offset, residual
    table ("mannerisms", batch only), the last observed frame, the adaptation result."""

    state: np.ndarray
    w: np.ndarray
    offset: np.ndarray
    residual: np.ndarray
    last: np.ndarray
    result: object = None


def reading_variance(model, grig):
    """The offset variance a rig's reading adds (``core.rigs.reading_offset``): a mapped rig is
    read through the CMU template's rest directions, which are not those of the skeleton its
    walk was made on. None for an Acclaim import (read on its own skeleton) and a CMU BVH
    conversion (its joints' local rotations are the subject's own, read as they are)."""
    return reading_offset_variance(model) if grig.kind == "MAPPED" else None


def _adapt(model, obs, fps, mode, dofs, known=None, reading_var=None):
    """The observed walker (:class:`Adapted`); only batch EM estimates the residual table
    (``core.gait.residual``). ``known``: the batch adaptation already made by the same call
    (``check_gait``'s check 9, ``GaitCheck.adapted``), reused. ``reading_var``: the reading's
    offset variance (:func:`reading_variance`)."""
    if mode == "ONLINE":
        stream = ObservationStream(model, model.dof_names, fps)
        online = OnlineEM(model, fps=fps)
        for row in dofs:
            last = stream.push(row)
            online.step(last)
        return Adapted(np.array([online.omega, online.phase]), online.w, online.state.b, None,
                       last)
    res = known if known is not None else adapt(model, obs, fps=fps, reading_var=reading_var)
    return Adapted(res.state, res.w, res.offset, res.residual, res.last_observation, res)


def walk_request(model, options, walker, fps):
    """The :class:`~core.gait.walk.WalkRequest` of the options for the adapted walker."""
    w, factor, keep = None, 1.0, True
    if options.style_mode == "RESTYLE":
        _known_style(model, options.restyle_from, "Restyle from")
        _known_style(model, options.restyle_to, "Restyle to")
        w, factor = restyle(model, walker.w, options.restyle_from, options.restyle_to,
                            options.restyle_amount)
    elif options.style_mode == "LIBRARY":
        _known_style(model, options.library_style, "Library style")
        w = model.style(options.library_style)
        period = model.periods[model.style_names.index(options.library_style)] / model.fps
        factor = 2.0 * np.pi / (period * fps) / float(walker.state[0])
        keep = False
    return WalkRequest(w=w, style_cadence=factor, cadence=options.cadence,
                       retime=options.retime.lower(), travel=options.root_travel,
                       plant=options.plant_feet, stride=options.stride,
                       turn=float(np.radians(options.turn)), keep_walker=keep)


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


# ------------------------------------------------------------------------------ records
def _records(action):
    """{object name: record} of the predictions recorded on ``action``."""
    group = action.get(PROP_PREDICTION)
    if group is None:
        return {}
    return {str(name): {"observed": [int(v) for v in rec["observed"]],
                        "frames": [int(v) for v in rec["frames"]], "digest": str(rec["digest"])}
            for name, rec in group.items()}


def _record(action, obj):
    """The record of ``obj``'s last prediction on ``action`` (dict) or None."""
    return _records(action).get(obj.name)


def _co(fcurve):
    """(K, 2) float32 frames and values of an F-curve's keys (one ``foreach_get``)."""
    points = fcurve.keyframe_points
    co = np.empty(2 * len(points), dtype=np.float32)
    points.foreach_get("co", co)
    return co.reshape(-1, 2)


class _KeyReads:
    """The (K, 2) float32 keys (frame, value) of a bag's F-curves, each curve read once
    (``_co``) and kept: one call's checks read the same curves before it writes anything
    (issue 21). Not for after a write: build a new one (whose ``known`` a writer may fill),
    or call ``_co`` directly."""

    def __init__(self, bag):
        self.bag = bag
        self._read = {}

    @property
    def known(self):
        """The dict ``{(path, index): (K, 2) keys}`` behind the reader: a writer that knows a
        curve's keys after its write exactly (``rigs.key_values``'s ``known``) puts them here
        instead of having them read back."""
        return self._read

    def __call__(self, path, index):
        """The F-curve's keys, shape (K, 2), or None when the bag has no such curve."""
        key = (path, index)
        if key not in self._read:
            fcurve = self.bag.fcurves.find(path, index=index)
            self._read[key] = None if fcurve is None else _co(fcurve)
        return self._read[key]


def _keys_digest(bag, targets, first, last, keys=None):
    """SHA-1 of the keys (frame, value) in [first, last] of the target F-curves (``keys``: a
    :class:`_KeyReads` of ``bag`` made since its last change, else the curves are read)."""
    keys = _KeyReads(bag) if keys is None else keys
    digest = hashlib.sha1()
    for path, index, _ in targets:
        co = keys(path, index)
        if co is None:
            continue
        inside = (co[:, 0] >= first - 1e-4) & (co[:, 0] <= last + 1e-4)
        digest.update(f"{path}[{index}]".encode())
        digest.update(np.ascontiguousarray(co[inside]).tobytes())
    return digest.hexdigest()


def intact_prediction(bag, grig, action, keys=None):
    """The record of the object's earlier prediction on ``action`` when its keys are still as
    written (the animator has not changed them), else None."""
    rec = _record(action, grig.obj)
    if rec is None:
        return None
    first, last = rec["frames"]
    return rec if _keys_digest(bag, grig.targets(), first, last, keys) == rec["digest"] else None


def _store_record(action, obj, observed, frames, digest):
    records = _records(action)
    records[obj.name] = {"observed": [int(v) for v in observed],
                         "frames": [int(v) for v in frames], "digest": digest}
    action[PROP_PREDICTION] = records


def _remove_keys(bag, targets, first, last):
    """Delete the keys in [first, last] of the target F-curves; every other key keeps its exact
    state (co, handles, interpolation, handle types, easing, type, easing parameters)."""
    extra = (("type", np.int32), ("back", np.float32), ("amplitude", np.float32),
             ("period", np.float32))
    for path, index, _ in targets:
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None or len(fcurve.keyframe_points) == 0:
            continue
        points = fcurve.keyframe_points
        state = keyframe_state(fcurve)
        inside = (state["co"][:, 0] >= first - 1e-4) & (state["co"][:, 0] <= last + 1e-4)
        if not inside.any():
            continue
        more = {}
        for prop, dtype in extra:
            array = np.empty(len(points), dtype=dtype)
            points.foreach_get(prop, array)
            more[prop] = array
        keep = ~inside
        points.clear()
        points.add(int(keep.sum()))
        for prop, array in list(state.items()) + list(more.items()):
            points.foreach_set(prop, np.ascontiguousarray(array[keep]).reshape(-1))
        fcurve.update()


def _conflicts(bag, targets, first, last, ignore=None, keys=None):
    """Number of target F-curves with keys in [first, last] (keys in ``ignore`` = (a, b), an
    earlier prediction about to be replaced, do not count; ``keys`` as in ``_keys_digest``)."""
    keys = _KeyReads(bag) if keys is None else keys
    count = 0
    for path, index, _ in targets:
        co = keys(path, index)
        if co is None or len(co) == 0:
            continue
        co = co[:, 0]
        hit = (co >= first - 1e-4) & (co <= last + 1e-4)
        if ignore is not None:
            hit &= ~((co >= ignore[0] - 1e-4) & (co <= ignore[1] + 1e-4))
        count += bool(hit.any())
    return count


def _count_keys(bag, targets, first, last, keys=None):
    keys = _KeyReads(bag) if keys is None else keys
    total = 0
    for path, index, _ in targets:
        co = keys(path, index)
        if co is not None and len(co):
            co = co[:, 0]
            total += int(np.sum((co >= first - 1e-4) & (co <= last + 1e-4)))
    return total


# ------------------------------------------------------------------------------ predict
def keyed_frames(grig, first, last, keys=None):
    """(N,) bool over frames ``first … last``: the frames holding a key on any F-curve the
    rig reads (a key off the frame grid marks its nearest frame; ``keys`` as in
    ``_keys_digest``)."""
    keys = _KeyReads(_action_bag(grig.obj)) if keys is None else keys
    hit = np.zeros(last - first + 1, dtype=bool)
    for path, index, _ in grig.reads():
        co = keys(path, index)
        if co is None or not len(co):
            continue
        at = np.rint(co[:, 0].astype(float)).astype(int) - first
        hit[at[(at >= 0) & (at < len(hit))]] = True
    return hit


def _observed_range(grig, scene, options, bag, record, keys=None):
    """(first, last) frames to observe: the keyed range up to an intact earlier prediction
    (which is replaced, not observed), the scene's, or the custom one (``keys`` as in
    ``_keys_digest``)."""
    keys = _KeyReads(bag) if keys is None else keys
    obj = grig.obj
    if options.range_mode == "ACTION":
        lo, hi = keyed_range(grig, keys)
        first = int(np.ceil(lo - 1e-4))
        last = record["observed"][1] if record is not None else int(np.floor(hi + 1e-4))
    else:
        first, last = frame_range(grig, scene, options.range_mode, options.frame_start,
                                  options.frame_end)
        if record is not None and first <= record["frames"][1] and last >= record["frames"][0]:
            a, b = record["frames"]
            raise GaitError(f"Frames {a}–{b} of {obj.animation_data.action.name} are an earlier "
                            f"prediction: observe frames before {a}, or use Reference Frames › "
                            f"Keyed Range to replace that prediction")
    if last <= first:
        raise GaitError(f"The frame range {first}–{last} of {obj.name} is empty")
    if _count_keys(bag, grig.reads(), first, last, keys) == 0:
        raise GaitError(f"Frames {first}–{last} of {obj.name} hold no keys on the bones the gait "
                        f"model reads: key or import a few steps of the walk there first")
    fps = scene_fps(scene)
    n_obs = last - first + 1
    if n_obs / fps < MIN_OBSERVED_S - 1e-9:
        raise GaitError(f"Observed {n_obs} frames ({n_obs / fps:.2f} s) is too short: the model "
                        f"needs at least {MIN_OBSERVED_S:g} s of the walk to pick up its step")
    return first, last


def _check_target(obj, grig, options, bag, frames, record, keys=None):
    """Refusals about the keys the prediction would write (After Observed; ``keys`` as in
    ``_keys_digest``)."""
    anim = obj.animation_data
    if options.target != "AFTER":
        return
    ignore = tuple(record["frames"]) if record is not None else None
    clash = _conflicts(bag, grig.targets(), frames[0], frames[-1], ignore, keys)
    if clash:
        raise GaitError(f"Frames {frames[0]}–{frames[-1]} already hold keys on {clash} "
                        f"F-curves of {anim.action.name}: choose Target › New Action, a shorter "
                        f"length, or an earlier reference range")
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


def predict_gait(context, obj, options):
    """Observe, check, adapt, predict and key the prediction on ``obj`` (module docstring).

    Returns
    -------
    dict
        ``status`` ('ok' or 'warning'), ``object``, ``action``, ``model``, ``observed`` and
        ``predicted`` frame ranges, ``keys`` written, ``strides_per_s``, ``fit`` (fit score),
        ``period_s`` (observed, None when too short to test), ``keyed_poses`` (the keyed
        frames observed when the range is sparsely keyed, ``core.gait.keyed``; None when every
        frame was observed), ``replaced`` (an earlier prediction's frames or None),
        ``warnings`` and ``message`` (the report line).
    """
    scene = context.scene
    fps = scene_fps(scene)
    options = checked_options(options)
    model_name, model = resolve_model(options.model)
    grig = gait_rig(obj)
    anim = obj.animation_data
    message = not_editable(obj, anim.action if anim is not None and options.target == "AFTER"
                           else None)
    if message:
        raise GaitError(message)
    cols = _model_columns(model, grig)
    bag = _action_bag(obj)                               # refuses an armature without action
    action = obj.animation_data.action
    # The checks before the writes read each curve's keys once (nothing changes them until the
    # writes; the digest stored after writing reads the written curves afresh).
    keys = _KeyReads(bag)
    record = intact_prediction(bag, grig, action, keys)
    first, last = _observed_range(grig, scene, options, bag, record, keys)
    dofs, residual = read_dofs(grig, np.arange(first, last + 1), model_hold(model, grig),
                               residual=True)
    model_dofs = dofs[:, cols]
    obs = observations_from_dofs(model, model_dofs, model.dof_names, fps)
    what = f"frames {first}–{last} of {obj.name}"
    reading = reading_variance(model, grig)
    check = check_gait(model, obs, fps, what=what, first_frame=first, reading_var=reading)
    if check.refusal:
        raise GaitError(check.refusal)
    # A sparsely keyed range (a few poses the animator keyed): the batch adaptation observes
    # the keyed frames only, the phase dynamics carry the walker across the frames between,
    # and the walker's travel is the keyed root's (docs/gait.md, *Stop 43*).
    keyed = keyed_frames(grig, first, last, keys)
    sparse = options.adaptation != "ONLINE" and keyed_reading.sparsely_keyed(keyed, fps)
    seen = keyed_reading.keyed_observations(obs, keyed) if sparse else obs
    walker = _adapt(model, seen, fps, options.adaptation, model_dofs,
                    None if sparse else check.adapted, reading)
    if sparse and not keyed[-1]:  # the continuation starts from the last frame Blender shows
        walker.last = np.array(obs[-1], dtype=float)
    # What the rig's pose holds beyond the model's DOFs (its rest convention against the CMU
    # template's), carried from the reference's last cycle: the character keeps its posture.
    omega = float(np.asarray(walker.state, dtype=float)[0])       # observed, rad per frame
    cycle = 2.0 * np.pi / omega if np.isfinite(omega) and omega > 0 else len(dofs)
    carried = None if residual is None else residual.carried(cycle)
    # The skeleton the walk is planted on: a mapped rig's joints as the carried residual
    # puts them (GaitSpace.planted_skeleton: the balls of the feet are the keyed rig's).
    skeleton = grig.skeleton if carried is None else \
        grig.space.planted_skeleton(carried.rotations)
    if walker.result is not None:
        root_xy = [list(grig.dof_names).index(n) for n in ("root.tx", "root.ty")]
        if sparse:                                        # the fit of the keyed poses
            check = with_fit(check, model, obs[keyed],
                             replace(walker.result, states=walker.result.states[keyed]), what)
        else:
            check = with_fit(check, model, obs, walker.result, what)
        # The legs carry the prediction (planted root): the style's legs travel as far as the
        # reference's did (core.gait.leg_travel; issue 19, a walk tracked from footage) -- a
        # sparsely keyed reference's as far as its keyed root did.
        walker.w = fit_leg_travel(model, skeleton, dofs, fps, seen, walker.result,
                                  walker.residual if options.mannerisms else None,
                                  reference_speed=keyed_reading.keyed_root_speed(
                                      dofs[:, root_xy], keyed, fps) if sparse else None).w
    n = int(round(options.horizon * fps))
    length = limits.name_of("length")
    if n < 1:
        raise GaitError(f"{length} {options.horizon:g} s is shorter than one frame at "
                        f"{fps:g} fps: give at least {1 / fps:.3g} s")
    if last + n > limits.MAXFRAME:
        raise GaitError(f"{length} {options.horizon:g} s would key frames {last + 1}–{last + n}, "
                        f"after {limits.last_frame_text()}: give a shorter {length} or observe "
                        "earlier frames")
    frames = last + np.arange(1, n + 1)
    if options.target == "AFTER":
        _check_target(obj, grig, options, bag, frames, record, keys)
    try:
        request = walk_request(model, options, walker, fps)
        walk = predict_walk(model, skeleton, dofs, fps, walker.state, walker.w, n, request,
                            offset=walker.offset,
                            residual=walker.residual if options.mannerisms else None,
                            start=walker.last)
    except ValueError as exc:
        raise GaitError(str(exc)) from None
    full = walk.dofs
    if not np.all(np.isfinite(full)):
        raise GaitError(f"The prediction for {obj.name} is not finite: nothing was keyed")
    values = channel_values(grig, bag, full, last, dofs[-1], frames=frames, residual=carried)
    # Every check has passed: change the scene.
    replaced = None
    if options.target == "AFTER":
        if record is not None:
            replaced = tuple(record["frames"])
            _remove_keys(bag, grig.targets(), *replaced)
        target_bag = bag
    else:
        target_bag = _new_action_from_range(obj, bag, first, last)
    # The digest of what was written: the keys the writes know (new keys after the old ones,
    # in order: what a read would give, bit for bit), the other curves read afresh.
    written_keys = _KeyReads(target_bag)
    written = key_values(grig, target_bag, frames, values, known=written_keys.known)
    new_action = obj.animation_data.action
    _store_record(new_action, obj, (first, last), (frames[0], frames[-1]),
                  _keys_digest(target_bag, grig.targets(), frames[0], frames[-1], written_keys))
    hz = fps * walk.omega / (2.0 * np.pi)
    warnings = [check.warning] if check.warning else []
    warnings += _control_warnings(grig)
    style = {"OBSERVED": "as observed", "LIBRARY": f"library style {options.library_style}",
             "RESTYLE": f"restyled {options.restyle_from} → {options.restyle_to} "
                        f"×{options.restyle_amount:g}"}[options.style_mode]
    if options.cadence != 1.0:
        style += (", retimed like a person" if request.retime == "natural"
                  and np.any(model.cadence_style) else ", played faster" if
                  options.cadence > 1.0 else ", played slower")
    speed = _speed(full, grig.dof_names, fps)
    if grig.kind == "MAPPED":
        speed /= grig.space.scale                        # the character's metres
    travel = ("on the spot" if not options.root_travel else
              f"{speed:.2f} m/s" + (" with the feet planted" if options.plant_feet else ""))
    text = (f"Predicted {n} frames ({n / fps:.2f} s) after frame {last} with {model_name}: "
            f"{hz:.2f} strides/s, {style}, {travel}"
            + (f"; read from your {int(keyed.sum())} keyed poses (Blender's in-betweens "
               "are not a walk)" if sparse else "")
            + f"; {written} keys in {new_action.name}{_controls_said(grig)}"
            + (f", replacing the earlier prediction of frames {replaced[0]}–{replaced[1]}"
               if replaced else "")
            + (f"; fit score {check.fit:.2f}" if check.fit is not None else ""))
    return {"status": "warning" if warnings else "ok", "object": obj.name,
            "action": new_action.name, "model": model_name, "observed": [first, last],
            "predicted": [int(frames[0]), int(frames[-1])], "keys": int(written),
            "strides_per_s": float(hz), "speed_m_s": float(speed), "floor_m": walk.floor,
            "fit": check.fit, "period_s": check.period_s,
            "keyed_poses": int(keyed.sum()) if sparse else None,
            "replaced": list(replaced) if replaced else None, "warnings": warnings,
            "message": text}


def _speed(dofs, names, fps):
    """Mean horizontal root speed (m/s) of DOF rows."""
    cols = [list(names).index(n) for n in ("root.tx", "root.ty")]
    if len(dofs) < 2:
        return 0.0
    step = np.diff(np.asarray(dofs)[:, cols], axis=0)
    return float(np.linalg.norm(step, axis=1).mean() * fps)


def predict(obj, model="", frames=None, horizon=2.0, **options):
    """:func:`predict_gait` with plain arguments on the current scene.

    Parameters
    ----------
    obj : str
        The armature's name.
    model : str
        A model of the file by name, the stock library's name, a model file's path, or ''
        (the active model).
    frames : (int, int), optional
        The reference frames; default: the keyed range.
    horizon : float
        Seconds to predict.
    **options
        Other :class:`PredictOptions` fields (``cadence``, ``style_mode``, ``restyle_from`` …).

    Returns
    -------
    dict
        :func:`predict_gait`'s summary.
    """
    kwargs = dict(options, model=str(model or ""), horizon=float(horizon))
    if frames is not None:
        kwargs.update(range_mode="CUSTOM", frame_start=int(frames[0]), frame_end=int(frames[1]))
    unknown = set(kwargs) - set(PredictOptions.__dataclass_fields__)
    if unknown:
        raise GaitError(f"Unknown predict options: {', '.join(sorted(unknown))}")
    return predict_gait(bpy.context, _object(obj), PredictOptions(**kwargs))


# ------------------------------------------------------------------------------ model files
def export_model(path, model=""):
    """Write a model of the file (by name; '' = the active one) to a model file.

    Returns
    -------
    dict
        ``model``, ``path``, ``styles``, ``message``.
    """
    name, found, written = storage.export_model(path, model or None)
    return {"status": "ok", "model": name, "path": str(written),
            "styles": list(found.style_names),
            "message": f"Exported {name} to {written.name}"}


def import_model(path, name=""):
    """Read a model file into the file's models (made active).

    Returns
    -------
    dict
        ``model`` (the stored name), ``path``, ``styles``, ``message``.
    """
    item, model = storage.import_model(path, name or None)
    return {"status": "ok", "model": item.name, "path": str(path),
            "styles": list(model.style_names),
            "message": f"Imported {item.name}: {item.summary}"}
