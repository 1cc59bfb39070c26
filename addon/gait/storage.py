"""Gait models of a .blend file (seen by every scene), the built-in stock library, model files.

Blender has no per-file place for add-on data, so the models live on one hidden text datablock,
``.Track & Stride Gait Models`` (fake user, so it is saved even though nothing uses it; its body
says what it is), as a registered pointer property (``addon/gait/props.py``): a list of
``(name, data, summary, builtin)`` entries and the active index. ``data`` is the model's ``.npz``
bytes (``GaitModel.to_bytes``, with its checksum) as base64 text. The first entry is always the
built-in stock library (``core.gait.stock``), which is not copied into the file: its entry only
names it. A file without the text (every new file) has no models of its own and predicts with
the stock library; the text is created when the first model is learned or imported.

Files saved before this (models stored per scene, ``scene.track_and_stride_gait.models``) are
migrated when they are loaded (``load_post``) or when the add-on is enabled: their models move
into the file's list, the scene lists are emptied.

Decoded models are cached by content (SHA-1 of the text).
"""

import base64
import hashlib
from pathlib import Path

import bpy

from ...core.gait import GaitModel, GaitModelFileError
from ...core.gait.stock import STOCK_NAME, load_stock_library
from .rigs import GaitError

STORE_TEXT = ".Track & Stride Gait Models"
STORE_PROP = "track_and_stride_gait_store"     # PointerProperty on bpy.types.Text (props.py)
SETTINGS = "track_and_stride_gait"             # Scene PointerProperty: preview settings
STORE_NOTE = ("This text keeps the gait models of Track & Stride (3D Viewport > Sidebar > "
              "Track & Stride > Gait) in this file. Deleting it deletes them.\n")
_CACHE = {}


# ------------------------------------------------------------------------------ encoding
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


def stock_model():
    """The built-in stock library; :class:`GaitError` if the installation lacks it."""
    try:
        return load_stock_library()
    except GaitModelFileError as exc:
        raise GaitError(str(exc)) from None


def model_summary(model):
    """One line describing a model in an animator's words (styles, cadences)."""
    hz = model.fps / model.periods
    styles = ", ".join(model.style_names[:5]) + (" …" if len(model.style_names) > 5 else "")
    return (f"{len(model.style_names)} styles ({styles}); "
            f"{hz.min():.2f}–{hz.max():.2f} strides/s"
            f"{'; moves forward' if model.root_travel else ''}")


# ------------------------------------------------------------------------------ the store
def find_store():
    """The file's model list (``TS_GaitStore``) or None when the file has none yet."""
    text = bpy.data.texts.get(STORE_TEXT)
    return getattr(text, STORE_PROP, None) if text is not None else None


def ensure_store():
    """The file's model list, created (with its stock entry) when missing."""
    store = find_store()
    if store is not None:
        return store
    text = bpy.data.texts.new(STORE_TEXT)
    text.use_fake_user = True
    text.write(STORE_NOTE)
    store = getattr(text, STORE_PROP)
    item = store.models.add()
    item.name = STOCK_NAME
    item.builtin = True
    item.summary = f"Built in: {model_summary(stock_model())}"
    store.active_model = 0
    return store


def entries():
    """[(name, builtin)] of every model the file offers (the stock library first)."""
    store = find_store()
    if store is None:
        return [(STOCK_NAME, True)]
    return [(item.name, item.builtin) for item in store.models]


def _item_model(item):
    return stock_model() if item.builtin else decode_model(item.data, item.name)


def model_by_name(name):
    """The model called ``name`` (the stock library's name works in every file)."""
    store = find_store()
    if store is not None:
        for item in store.models:
            if item.name == name:
                return _item_model(item)
    if name == STOCK_NAME:
        return stock_model()
    known = ", ".join(n for n, _ in entries())
    raise GaitError(f"No gait model named {name!r} in this file (models: {known})")


def active_entry():
    """(name, model) of the model Predict and the live preview use."""
    store = find_store()
    if store is None or len(store.models) == 0:
        return STOCK_NAME, stock_model()
    index = min(max(store.active_model, 0), len(store.models) - 1)
    item = store.models[index]
    return item.name, _item_model(item)


def add_model(model, name):
    """Store a model under a unique name and make it active; returns the entry."""
    store = ensure_store()
    taken = {item.name for item in store.models}
    unique, k = name, 1
    while unique in taken:
        k += 1
        unique = f"{name}.{k:03d}"
    item = store.models.add()
    item.name = unique
    item.data = encode_model(model)
    item.summary = model_summary(model)
    store.active_model = len(store.models) - 1
    return item


def remove_active():
    """Remove the active entry (never the built-in one); returns its name."""
    store = find_store()
    if store is None or len(store.models) == 0:
        raise GaitError("No gait model of this file to remove")
    index = min(store.active_model, len(store.models) - 1)
    item = store.models[index]
    if item.builtin:
        raise GaitError(f"{item.name} is built into Track & Stride and cannot be removed")
    name = item.name
    store.models.remove(index)
    store.active_model = max(0, min(index, len(store.models) - 1))
    return name


# ------------------------------------------------------------------------------ model files
def export_model(path, name=None):
    """Write a model (by name, default the active one) to an ``.npz`` model file.

    Returns
    -------
    (str, GaitModel, Path) : the model's name, the model and the path written
    """
    name, model = (name, model_by_name(name)) if name else active_entry()
    path = Path(path)
    if path.suffix.lower() != ".npz":
        path = path.with_suffix(path.suffix + ".npz") if path.suffix else path.with_suffix(".npz")
    try:
        model.save(path)
    except OSError as exc:
        raise GaitError(f"Cannot write {path}: {exc.strerror or exc}") from None
    return name, model, path


def import_model(path, name=None):
    """Read a model file into the file's list (unique name, made active); returns the entry."""
    path = Path(path)
    try:
        model = GaitModel.load(path)
    except OSError as exc:
        raise GaitError(f"Cannot read {path.name}: {exc.strerror or exc}") from None
    except GaitModelFileError as exc:
        raise GaitError(str(exc)) from None
    stem = path.name[:-4] if path.name.lower().endswith(".npz") else path.stem
    return add_model(model, name or stem), model


# ------------------------------------------------------------------------------ migration
def migrate_scene_models():
    """Move models stored per scene (files saved before models were file-wide) into the file's
    list; a model already there (same data) is not duplicated. Returns the number moved."""
    moved = 0
    for scene in bpy.data.scenes:
        settings = getattr(scene, SETTINGS, None)
        if settings is None or len(settings.models) == 0 or scene.library is not None:
            continue
        store = ensure_store()
        stored = {item.data for item in store.models}
        for old in settings.models:
            if old.data and old.data not in stored:
                try:
                    model = decode_model(old.data, old.name)
                except GaitError:
                    continue          # unreadable: left where it was, reported on use
                add_model(model, old.name)
                stored.add(old.data)
                moved += 1
        readable = [i for i, old in enumerate(settings.models) if old.data in stored]
        for i in reversed(readable):
            settings.models.remove(i)
    return moved
