"""The learned stylistic gait model and its file format.

Symbol table (D channels, J bases, S training styles, C phase samples per cycle)

================ ============ ===============================================================
name             shape        meaning
================ ============ ===============================================================
channel_names    (D,)         joint angles (training layout order), then root features
units            (D,)         ``'rad'``, ``'m'``, ``'m/s'``, ``'rad/s'``
angle_centre     (D,)         circular mean of every angle channel (rad; 0 elsewhere)
channel_scale    (D,)         physical = scaled × scale (1 for angles; root features scaled to
                              the angles' typical spread)
fps              float        model frame rate; ω is in radians per frame at this rate
bases            (J, C, D)    state bases Ȳ^j (scaled units), closed: row C-1 = row 0 (eq. 9)
styles           (S, J)       style parameters w^s of the training sequences
style_names      (S,)         their names
beta             (4,)         GP hyper-parameters (eq. 11)
A                (2, 2)       state transition [[1, 0], [1, 1]] on x = [ω, φ]
Q                (2, 2)       process noise per model frame (rad²/frame², rad²)
r                float        observation noise variance (scaled units²); R = r·I
style_mean       (J,)         mean of the training styles (prior mean of the M-step)
style_cov        (J, J)       their covariance (prior covariance before scaling)
periods          (S,)         training periods, model frames
lag_range        (2,)         period search range, seconds
dof_names        (n_dofs,)    the training DOF layout (used to write predicted DOF frames)
root_travel      bool         whether the seven root features are modelled
root_rest, root_order, forward_axis    the :class:`.root_travel.RootFrame`
cadence_style    (J,)         the style's change per unit log cadence (:mod:`.retiming`; zeros:
                              retiming plays the walk faster; version 1-2 files)
offset_var       (D,)         between-walker variance of a walker's posture offset (scaled
                              units²; the prior of the offset estimated when adapting); zeros:
                              no offset (version 1 files)
notes            str          free text: where the model comes from (credits, build recipe)
================ ============ ===============================================================

The model is saved as one ``.npz`` (no pickle; strings as fixed-width unicode arrays) with a
``format_version`` and, from version 2, a ``checksum``: the SHA-256 of every other entry's name,
dtype, shape and bytes (:func:`checksum`), checked at load so that a damaged or hand-edited file
is refused before its values are used. Version 1 files (no checksum, no offset) still load.
:meth:`GaitModel.load` / :meth:`GaitModel.from_bytes` raise :class:`GaitModelFileError` for
anything that is not a complete, consistent, finite model of a known version.
"""

import hashlib
import io
import zipfile
from dataclasses import dataclass, field

import numpy as np

from .gp import build_phase_gp
from .root_travel import RATE_FEATURES, ROOT_DOF_NAMES, ROOT_FEATURE_NAMES, ROOT_FEATURE_UNITS, \
    RootFrame

__all__ = ["FORMAT_VERSION", "GaitModel", "GaitModelFileError", "TRANSITION", "checksum"]

FORMAT_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)
# Matsubara §2.3: x_t = A x_{t-1} + v with x = [ω, φ]; the printed A = [0 1; 1 1] is a typo
# (DESIGN.md §2): ω stays constant and φ advances by ω.
TRANSITION = np.array([[1.0, 0.0], [1.0, 1.0]])
TRANSITION.setflags(write=False)


class GaitModelFileError(ValueError):
    """A model file (or byte string) is corrupt, incomplete or of an unknown format version."""


_STR_FIELDS = ("channel_names", "units", "style_names", "dof_names")
_ARRAY_FIELDS = ("angle_centre", "channel_scale", "bases", "styles", "beta", "A", "Q",
                 "style_mean", "style_cov", "periods", "lag_range", "root_rest",
                 "singular_values", "offset_var", "cadence_style")
# Fields absent from older files (their defaults apply): {field: first version with it}.
_NEW_IN = {"offset_var": 2, "notes": 2, "cadence_style": 3}
_SCALAR_FIELDS = ("fps", "r")
_TEXT_FIELDS = ("root_order", "alignment", "refinement", "notes")
_INT_FIELDS = ("forward_axis", "root_travel")

# Plausible ranges checked at load (docs/gait.md, *Errors*). A model learned from real motion
# lies orders of magnitude inside them (CMU walks and runs at 60 Hz: fps 60, r ≈ 0.03,
# lag_range (0.5, 2) s, periods 45-80 frames, Q eigenvalues 1e-8 … 3e-5, channel_scale
# 0.6 … 6, |bases| ≈ 0.2, |styles| ≈ 10, β ≈ [5e-4, 0.85, 9e-7, 8e6]); a finite file outside
# them is refused instead of overflowing or dividing by zero when adapting or predicting.
# "Scaled units" are the model's (radians for the joint angles; the root features are scaled to
# the angles' spread, see learning.py).
FPS_RANGE = (1.0, 1e4)              # model frame rate, frames per second
SECONDS_RANGE = (1e-3, 1e3)         # lag_range and the training periods, seconds
MIN_PERIOD_FRAMES = 2.0             # shorter periods alias (ω above π per frame)
R_RANGE = (1e-12, 1e6)              # r, scaled units²
Q_EIG_RANGE = (1e-20, 1e2)          # eigenvalues of Q (rad²/frame², rad²)
SCALE_RANGE = (1e-6, 1e6)           # channel_scale (learn_model floors it at 1e-6)
MAX_ANGLE_CENTRE = 2.0 * np.pi      # circular means lie within ±π
MAX_BASIS = 1e3                     # |bases| (SVD bases have unit-norm rows)
MAX_STYLE = 1e6                     # |styles|, |style_mean|
MAX_SCALED_VALUE = 1e3              # |styles @ bases|, |style_mean @ bases|, scaled units
STYLE_COV_EIG_RANGE = (1e-12, 1e12)  # eigenvalues of style_cov
BETA_RANGES = ((1e-20, 1e6),        # β1, RBF variance (scaled units²)
               (1e-6, 1e6),         # β2, RBF inverse squared length (unitless)
               (1e-20, 1e6),        # β3, linear-kernel variance (scaled units²)
               (1e-6, 1e20))        # β4, noise precision (1 / scaled units²)


def _within(values, bounds):
    """Every value finite and inside the closed range ``bounds``."""
    values = np.asarray(values, dtype=float)
    return bool(np.all(np.isfinite(values)) and np.all(values >= bounds[0])
                and np.all(values <= bounds[1]))


def _eigenvalues(matrix):
    """Eigenvalues of a symmetric (2-D, square) matrix, or None if it is not one."""
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.size == 0 \
            or not np.allclose(matrix, matrix.T, rtol=1e-9, atol=0.0):
        return None
    return np.linalg.eigvalsh(matrix)


@dataclass(frozen=True, eq=False)
class GaitModel:
    """A learned stylistic gait model (see the module symbol table).

    Build with :func:`core.gait.learn_model`; persist with :meth:`save` / :meth:`load` or
    :meth:`to_bytes` / :meth:`from_bytes`. Immutable; arrays are read-only.
    """

    channel_names: tuple
    units: tuple
    angle_centre: np.ndarray
    channel_scale: np.ndarray
    fps: float
    bases: np.ndarray
    styles: np.ndarray
    style_names: tuple
    beta: np.ndarray
    Q: np.ndarray
    r: float
    style_mean: np.ndarray
    style_cov: np.ndarray
    periods: np.ndarray
    lag_range: np.ndarray
    dof_names: tuple
    root_travel: bool
    root_rest: np.ndarray
    root_order: str = "XYZ"
    forward_axis: int = 2
    A: np.ndarray = field(default_factory=lambda: TRANSITION.copy())
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    alignment: str = "mean"
    refinement: str = "map"
    offset_var: np.ndarray = None
    cadence_style: np.ndarray = None
    notes: str = ""
    format_version: int = FORMAT_VERSION

    def __post_init__(self):
        set_ = object.__setattr__
        if self.offset_var is None:
            set_(self, "offset_var", np.zeros(len(self.channel_names)))
        if self.cadence_style is None:
            bases = np.asarray(self.bases)
            set_(self, "cadence_style", np.zeros(bases.shape[0] if bases.ndim == 3 else 0))
        for name in _STR_FIELDS:
            set_(self, name, tuple(str(v) for v in getattr(self, name)))
        for name in _ARRAY_FIELDS:
            arr = np.array(getattr(self, name), dtype=float)
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"model field {name} must be finite")
            arr.setflags(write=False)
            set_(self, name, arr)
        set_(self, "fps", float(self.fps))
        set_(self, "r", float(self.r))
        set_(self, "root_travel", bool(self.root_travel))
        set_(self, "forward_axis", int(self.forward_axis))
        self._validate()
        set_(self, "root_frame", RootFrame(self.root_rest, self.root_order, self.forward_axis))
        # Derived, not saved: the GP of eq. 11 on the distinct phase samples of the bases.
        set_(self, "gp", build_phase_gp(self.bases[:, :-1], self.beta))
        set_(self, "is_angle", np.array([u == "rad" for u in self.units]))
        set_(self, "rate_mask", np.array([n in RATE_FEATURES for n in self.channel_names]))

    def _validate(self):
        d = len(self.channel_names)
        j = self.bases.shape[0] if self.bases.ndim == 3 else -1
        # The channel layout learn_model writes: the joint angles of dof_names (every DOF that
        # is not a root DOF, in order), then the root features when root_travel is set.
        angles = [n for n in self.dof_names if n not in ROOT_DOF_NAMES]
        root = list(ROOT_FEATURE_NAMES) if self.root_travel else []
        checks = [
            (len(set(self.dof_names)) == len(self.dof_names), "DOF names must be unique"),
            (not self.root_travel or all(n in self.dof_names for n in ROOT_DOF_NAMES),
             "a model with root travel needs the six root DOFs in dof_names"),
            (len(angles) > 0 and list(self.channel_names) == angles + root,
             "channel names must be the joint-angle DOF names"
             + (" followed by the root features" if root else "")),
            (list(self.units) == ["rad"] * len(angles)
             + (list(ROOT_FEATURE_UNITS) if root else []),
             "units must be 'rad' per joint angle" + (" then the root features' units"
                                                      if root else "")),
            (self.bases.ndim == 3 and self.bases.shape[2] == d and self.bases.shape[1] >= 5,
             f"bases must be (J, C>=5, {d}), got {self.bases.shape}"),
            (len(set(self.channel_names)) == d, "channel names must be unique"),
            (len(self.units) == d, f"units must have {d} entries"),
            (self.angle_centre.shape == (d,), f"angle_centre must be ({d},)"),
            (self.channel_scale.shape == (d,) and np.all(self.channel_scale > 0),
             f"channel_scale must be ({d},) positive"),
            (self.styles.ndim == 2 and self.styles.shape[1] == j,
             f"styles must be (S, {j}), got {self.styles.shape}"),
            (len(self.style_names) == len(self.styles), "one style name per style"),
            (self.beta.shape == (4,) and np.all(self.beta > 0), "beta must be 4 positive values"),
            (self.A.shape == (2, 2) and np.array_equal(self.A, TRANSITION),
             "A must be [[1, 0], [1, 1]]"),
            (self.Q.shape == (2, 2) and np.all(np.linalg.eigvalsh(self.Q) > 0),
             "Q must be a (2, 2) positive-definite matrix"),
            (self.r > 0 and np.isfinite(self.r), "r must be positive"),
            (self.style_mean.shape == (j,) and self.style_cov.shape == (j, j),
             "style prior must be (J,) and (J, J)"),
            (self.periods.shape == (len(self.styles),) and np.all(self.periods > 0),
             "one positive period per style"),
            (self.lag_range.shape == (2,) and 0 < self.lag_range[0] < self.lag_range[1],
             "lag_range must be (min, max) seconds"),
            (self.fps > 0 and np.isfinite(self.fps), "fps must be positive"),
            (self.offset_var.shape == (d,) and np.all(self.offset_var >= 0),
             f"offset_var must be ({d},) non-negative"),
            (self.cadence_style.shape == (j,), f"cadence_style must be ({j},)"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(f"inconsistent gait model: {message}")
        self._validate_ranges()

    def _validate_ranges(self):
        """The plausible ranges of the module constants (the shapes are already checked)."""
        q_eig, cov_eig = _eigenvalues(self.Q), _eigenvalues(self.style_cov)
        checks = [
            (_within(self.fps, FPS_RANGE), f"fps {self.fps:g} outside {FPS_RANGE}"),
            (_within(self.lag_range, SECONDS_RANGE)
             and self.lag_range[0] * self.fps >= MIN_PERIOD_FRAMES,
             f"lag_range {self.lag_range.tolist()} s outside {SECONDS_RANGE} s or shorter than "
             f"{MIN_PERIOD_FRAMES:g} frames"),
            (_within(self.periods / self.fps, SECONDS_RANGE)
             and np.all(self.periods >= MIN_PERIOD_FRAMES),
             f"periods must lie within {SECONDS_RANGE} s and {MIN_PERIOD_FRAMES:g} frames or "
             f"more"),
            (_within(self.r, R_RANGE), f"r {self.r:g} outside {R_RANGE}"),
            (q_eig is not None and _within(q_eig, Q_EIG_RANGE),
             f"Q must be symmetric with eigenvalues within {Q_EIG_RANGE}"),
            (all(_within(b, rng) for b, rng in zip(self.beta, BETA_RANGES)),
             f"beta {self.beta.tolist()} outside {BETA_RANGES}"),
            (_within(self.channel_scale, SCALE_RANGE),
             f"channel_scale outside {SCALE_RANGE}"),
            (np.all(np.abs(self.angle_centre) <= MAX_ANGLE_CENTRE),
             f"angle_centre must lie within ±{MAX_ANGLE_CENTRE:g} rad"),
            (np.all(np.abs(self.bases) <= MAX_BASIS), f"bases must lie within ±{MAX_BASIS:g}"),
            (np.all(self.offset_var <= MAX_SCALED_VALUE**2),
             f"offset_var must lie within {MAX_SCALED_VALUE**2:g} scaled units²"),
            (np.all(np.abs(self.styles) <= MAX_STYLE)
             and np.all(np.abs(self.style_mean) <= MAX_STYLE)
             and np.all(np.abs(self.cadence_style) <= MAX_STYLE),
             f"styles, style_mean and cadence_style must lie within ±{MAX_STYLE:g}"),
            (cov_eig is not None and _within(cov_eig, STYLE_COV_EIG_RANGE),
             f"style_cov must be symmetric with eigenvalues within {STYLE_COV_EIG_RANGE}"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(f"implausible gait model: {message}")
        # The cycles the model describes (training styles and the prior mean) in scaled units.
        cycles = np.concatenate((self.styles, self.style_mean[None]), axis=0) \
            @ self.bases.reshape(self.n_bases, -1)
        if not np.all(np.abs(cycles) <= MAX_SCALED_VALUE):
            raise ValueError(f"implausible gait model: styles @ bases (and style_mean @ bases) "
                             f"must lie within ±{MAX_SCALED_VALUE:g} scaled units")

    # ---------------------------------------------------------------- sizes and lookups
    @property
    def n_channels(self):
        """D."""
        return len(self.channel_names)

    @property
    def n_bases(self):
        """J (dimension of a style)."""
        return self.bases.shape[0]

    @property
    def n_phase(self):
        """C, phase samples per cycle including the closing one."""
        return self.bases.shape[1]

    @property
    def has_offset(self):
        """Whether adapting estimates a walker's posture offset (``offset_var`` not all zero)."""
        return bool(np.any(self.offset_var > 0))

    @property
    def n_angles(self):
        """Number of joint-angle channels (they come first)."""
        return self.n_channels - 7 * self.root_travel

    @property
    def angle_names(self):
        """The joint-angle channel names (training DOF order)."""
        return self.channel_names[:self.n_angles]

    @property
    def R(self):
        """Observation noise covariance ``r·I`` (D × D, scaled units²)."""
        return self.r * np.eye(self.n_channels)

    def channel_index(self, names):
        """Indices of model channels by name; ``ValueError`` naming unknown channels."""
        lookup = {n: i for i, n in enumerate(self.channel_names)}
        names = [str(n) for n in names]
        unknown = [n for n in names if n not in lookup]
        if unknown:
            raise ValueError(f"unknown channels {unknown}; the model has "
                             f"{', '.join(self.channel_names)}")
        return np.array([lookup[n] for n in names], dtype=int)

    def style(self, name):
        """Style vector (J,) of a training sequence by name."""
        try:
            return self.styles[self.style_names.index(str(name))].copy()
        except ValueError:
            raise ValueError(f"unknown style {name!r}; known: {', '.join(self.style_names)}") \
                from None

    def to_scaled(self, y):
        """Physical observations (..., D) -> scaled model units."""
        return np.asarray(y, dtype=float) / self.channel_scale

    def to_physical(self, z):
        """Scaled model units (..., D) -> physical units."""
        return np.asarray(z, dtype=float) * self.channel_scale

    # ---------------------------------------------------------------- time parameters
    def omega_range(self, fps=None):
        """(ω_min, ω_max) in radians per frame at ``fps`` from the period search range."""
        fps = self.fps if fps is None else float(fps)
        return 2.0 * np.pi / (self.lag_range[1] * fps), 2.0 * np.pi / (self.lag_range[0] * fps)

    def training_omegas(self, fps=None):
        """Phase velocities 2π / T^s of the training styles, radians per frame at ``fps``."""
        fps = self.fps if fps is None else float(fps)
        return 2.0 * np.pi / (self.periods / self.fps * fps)

    def process_noise(self, fps=None):
        """Q at ``fps``: with k = model fps / fps frames, ``diag(q_ω k³, q_φ k)`` (a
        continuous-time random walk of ω and of φ sampled at a different rate)."""
        fps = self.fps if fps is None else float(fps)
        k = self.fps / fps
        return self.Q * np.array([[k**3, k**2], [k**2, k]])

    # ---------------------------------------------------------------- persistence
    def _arrays(self):
        out = {"format_version": np.array(FORMAT_VERSION)}
        for name in _STR_FIELDS:
            out[name] = np.array(getattr(self, name), dtype=str)
        for name in _ARRAY_FIELDS:
            out[name] = np.asarray(getattr(self, name))
        for name in _SCALAR_FIELDS:
            out[name] = np.array(getattr(self, name), dtype=float)
        for name in _TEXT_FIELDS:
            out[name] = np.array(str(getattr(self, name)))
        for name in _INT_FIELDS:
            out[name] = np.array(int(getattr(self, name)))
        out["checksum"] = np.array(checksum(out))
        return out

    def to_bytes(self):
        """The model as ``.npz`` bytes (what :meth:`save` writes): the same model gives the same
        bytes (entries in name order, no timestamps: ``np.savez`` stamps each entry with the
        time of writing), so a rebuilt stock library is byte-identical when its values are."""
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
            for name, value in sorted(self._arrays().items()):
                info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                entry = io.BytesIO()
                np.lib.format.write_array(entry, np.asanyarray(value), allow_pickle=False)
                archive.writestr(info, entry.getvalue())
        return buffer.getvalue()

    def save(self, path):
        """Write the model to one ``.npz`` file at ``path``."""
        with open(path, "wb") as handle:
            handle.write(self.to_bytes())

    @classmethod
    def from_bytes(cls, data, source="<bytes>"):
        """Model from :meth:`to_bytes` output; :class:`GaitModelFileError` if invalid."""
        try:
            with np.load(io.BytesIO(bytes(data)), allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
        except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, NotImplementedError,
                RuntimeError) as exc:
            # NotImplementedError / RuntimeError: a damaged entry header naming an unsupported
            # compression method.
            raise GaitModelFileError(f"{source}: not a gait model file: "
                                     f"{_unreadable_reason(bytes(data[:4]), exc)}") from None
        return cls._from_arrays(arrays, source)

    @classmethod
    def load(cls, path):
        """Read a model written by :meth:`save`; :class:`GaitModelFileError` if invalid."""
        with open(path, "rb") as handle:
            data = handle.read()
        return cls.from_bytes(data, source=str(path))

    @classmethod
    def _from_arrays(cls, arrays, source):
        if "format_version" not in arrays:
            raise GaitModelFileError(f"{source}: not a gait model file (no format_version)")
        try:
            version = int(arrays["format_version"])
        except (TypeError, ValueError):
            raise GaitModelFileError(f"{source}: unreadable format_version") from None
        if version not in READABLE_VERSIONS:
            raise GaitModelFileError(f"{source}: gait model format version {version} is not "
                                     f"supported (this build reads versions "
                                     f"{', '.join(map(str, READABLE_VERSIONS))})")
        if version >= 2:
            stored = arrays.get("checksum")
            if stored is None or stored.dtype.kind != "U" or stored.shape != ():
                raise GaitModelFileError(f"{source}: gait model without its checksum")
            if str(stored) != checksum(arrays):
                raise GaitModelFileError(f"{source}: checksum mismatch: the gait model file was "
                                         "changed or damaged")
        required = _STR_FIELDS + _ARRAY_FIELDS + _SCALAR_FIELDS + _TEXT_FIELDS + _INT_FIELDS
        required = tuple(k for k in required if _NEW_IN.get(k, 1) <= version)
        missing = [k for k in required if k not in arrays]
        if missing:
            raise GaitModelFileError(f"{source}: incomplete gait model, missing {missing}")
        kwargs = {}
        try:
            for name in _STR_FIELDS:
                if arrays[name].dtype.kind != "U":
                    raise ValueError(f"{name} must be text")
                kwargs[name] = tuple(arrays[name].tolist())
            for name in _ARRAY_FIELDS:
                if name not in arrays:           # an older file: the default applies
                    continue
                if arrays[name].dtype.kind not in "fiu":
                    raise ValueError(f"{name} must be numeric")
                kwargs[name] = arrays[name]
            for name in _SCALAR_FIELDS:
                kwargs[name] = float(arrays[name])
            for name in _TEXT_FIELDS:
                if name in arrays:               # "notes": absent from version 1 files
                    kwargs[name] = str(arrays[name])
            for name in _INT_FIELDS:
                kwargs[name] = int(arrays[name])
            return cls(**kwargs)
        except (ValueError, TypeError, np.linalg.LinAlgError) as exc:
            raise GaitModelFileError(f"{source}: invalid gait model ({exc})") from None


def checksum(arrays):
    """SHA-256 (hex) of a model file's entries other than ``checksum``: name, dtype, shape and
    C-order bytes of each, in name order.

    Parameters
    ----------
    arrays : dict {name: ndarray}
    """
    digest = hashlib.sha256()
    for name in sorted(k for k in arrays if k != "checksum"):
        value = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}|{value.dtype.str}|{value.shape}|".encode())
        digest.update(value.tobytes())
    return digest.hexdigest()


def _unreadable_reason(head, exc):
    """Why bytes starting with ``head`` are not a model file, in plain words (NumPy's own
    messages speak of pickles and ``allow_pickle``, and some repeat the path)."""
    if not head:
        return "the file is empty"
    if head[:2] != b"PK":
        return ("it is another kind of file (a model file is a NumPy .npz archive exported by "
                "Track & Stride)")
    if isinstance(exc, EOFError) or "truncated" in str(exc).lower() or \
            "end-of-central-directory" in str(exc).lower() or isinstance(exc, zipfile.BadZipFile):
        return "the archive is damaged or cut short (copy the file again)"
    if "pickle" in str(exc).lower() or "object arrays" in str(exc).lower():
        return ("it holds Python objects, which a model file never does (not made by Track & "
                "Stride, or altered)")
    return "its contents are damaged (an array cannot be read)"
