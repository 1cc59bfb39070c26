"""Model channels from DOF arrays: joint angles plus root-travel features.

A model's observation vector ``y`` (D channels, physical units) is the training layout's joint
angles (every DOF that is not one of the six root DOFs; radians; the paper's 56 for CMU) followed,
when the model has root travel, by the seven root features of :mod:`.root_travel`. DOF arrays
come in the AMC/``Skeleton`` layout: ``(N, n_dofs)``, metres and radians, Z-up world, with their
channel names (``'root.tx'``, ``'lfemur.rx'``, …).

Angles are *placed near a centre* (the training data's circular mean per channel) as a
sequence, :func:`continuous_near`: the first frame within ±π of the centre, every later frame on
the branch nearest its predecessor (continuous in time), unless that carries it more than
:data:`CARRY_PAST_OPPOSITE` past the opposite side (centre ± π), where it is brought back within
±π. A channel hovering at the opposite side stays on one side (wrapping each frame on its own
tore CMU 05_10's right hip rx from 158.3° to -200.6° while the AMC goes 158.3 → 159.4°: 360°
steps the posture offset and the outlier test then absorbed, docs/gait.md *Stop 45*), and a
channel that a capture system spins whole turns (CMU 08_01 ``rthumb.rz`` goes from -70° to
-1150° mid-trial) still comes back near the centre, since the model is linear in the angles.
"""

import numpy as np

from .root_travel import ROOT_DOF_NAMES, RootFrame, root_features

__all__ = ["CARRY_PAST_OPPOSITE", "ObservationStream", "angle_channel_names", "channel_columns",
           "continuous_near", "dof_observations", "observations_from_dofs", "wrap_near"]

#: How far past the opposite side of the centre (radians beyond ±π) :func:`continuous_near`
#: carries an angle on continuously before bringing it back within ±π. Wider than the swing of
#: a channel hovering at the opposite side (05_10's right hip, 126_06's left shoulder), narrower
#: than the whole turn of a spinning channel (08_01's and 91_27's right thumbs, which a margin of
#: 160° carries off); a quarter turn. Every shipped gait clip gives ``wrap_near``'s observations
#: for margins of 20° to 135° (docs/gait.md, *Stop 45*).
CARRY_PAST_OPPOSITE = 0.5 * np.pi


def channel_columns(channel_names, wanted, what="channels"):
    """Column index of every name of ``wanted`` in ``channel_names``.

    Raises
    ------
    ValueError
        Naming the missing channels, or repeated names in ``channel_names``.
    """
    names = [str(n) for n in channel_names]
    if len(set(names)) != len(names):
        dupes = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"channel names must be unique; repeated: {dupes}")
    lookup = {n: i for i, n in enumerate(names)}
    missing = [n for n in wanted if n not in lookup]
    if missing:
        raise ValueError(f"{what} missing from the given channel names: {missing}")
    return np.array([lookup[n] for n in wanted], dtype=int)


def angle_channel_names(channel_names):
    """Joint-angle channels of a DOF layout: every name that is not a root DOF."""
    return [str(n) for n in channel_names if str(n) not in ROOT_DOF_NAMES]


def wrap_near(values, centre):
    """``centre + wrap(values - centre)`` with wrap to [-π, π); NaN entries stay NaN.

    Parameters
    ----------
    values : array_like, shape (..., K), radians
    centre : array_like, shape (K,), radians
    """
    values = np.asarray(values, dtype=float)
    return centre + np.mod(values - centre + np.pi, 2.0 * np.pi) - np.pi


def _carry(previous, wrapped, centre):
    """One frame of :func:`continuous_near`: ``wrapped`` (wrap_near of the frame) moved by the
    whole turns that bring it nearest ``previous`` (the output of the frame before), unless that
    lies more than π + CARRY_PAST_OPPOSITE from ``centre``. Elementwise; ``wrapped`` itself
    (bit for bit) wherever it lies within π of ``previous``."""
    turns = np.round((previous - wrapped) / (2.0 * np.pi))
    carried = wrapped + 2.0 * np.pi * turns
    return np.where(np.abs(carried - centre) <= np.pi + CARRY_PAST_OPPOSITE, carried, wrapped)


def continuous_near(values, centre):
    """Angle sequences placed near ``centre`` and continuous in time (module docstring).

    ``out[0] = wrap_near(values[0], centre)``; ``out[t]`` is ``values[t]`` moved by whole turns
    onto the branch nearest ``out[t-1]`` when that lies within π + :data:`CARRY_PAST_OPPOSITE`
    of the centre, else ``wrap_near(values[t], centre)``. A channel whose wrapped steps all stay
    within π is ``wrap_near``'s, bit for bit; :class:`ObservationStream` gives the same rows
    frame by frame (the same arithmetic, :func:`_carry`).

    Parameters
    ----------
    values : array_like, shape (N, K), radians
    centre : array_like, shape (K,), radians

    Returns
    -------
    ndarray, shape (N, K), radians
    """
    centre = np.asarray(centre, dtype=float)
    out = wrap_near(values, centre)
    if len(out) < 2:
        return out
    # Only channels where some wrapped step moves by a turn can leave wrap_near's values; before
    # their first such step every frame is wrap_near's (the carry moves by zero turns).
    moved = np.round((out[:-1] - out[1:]) / (2.0 * np.pi)) != 0
    cols = np.flatnonzero(moved.any(axis=0))
    if cols.size:
        first = int(np.flatnonzero(moved[:, cols].any(axis=1))[0]) + 1
        part, c = out[:, cols], centre[cols]
        for t in range(first, len(out)):
            part[t] = _carry(part[t - 1], part[t], c)
        out[:, cols] = part
    return out


def _check_dofs(dofs, channel_names):
    dofs = np.asarray(dofs, dtype=float)
    if dofs.ndim == 1:
        dofs = dofs[None]
    if dofs.ndim != 2:
        raise ValueError(f"Expected DOFs of shape (N, n_dofs), got {dofs.shape}")
    if dofs.shape[1] != len(channel_names):
        raise ValueError(f"DOF array has {dofs.shape[1]} columns but {len(channel_names)} "
                         "channel names were given")
    return dofs


def dof_observations(dofs, channel_names, fps, angle_names, root_travel=True, root_frame=None,
                     angle_centre=None):
    """Observation rows (joint angles, then root features) from a DOF array.

    Parameters
    ----------
    dofs : array_like, shape (N, n_dofs)
        Metres and radians (AMC/``Skeleton`` layout).
    channel_names : sequence of str, length n_dofs
    fps : float
        Frames per second of ``dofs``.
    angle_names : sequence of str
        Joint-angle channels to extract, in model order.
    root_travel : bool
        Append the seven root features (needs the six root DOFs and N >= 2).
    root_frame : RootFrame, optional
    angle_centre : array_like, shape (len(angle_names),), optional
        Place the angles near these values (radians), continuous in time
        (:func:`continuous_near`).

    Returns
    -------
    ndarray, shape (N, len(angle_names) + 7·root_travel)
    """
    channel_names = [str(n) for n in channel_names]
    dofs = _check_dofs(dofs, channel_names)
    if not np.all(np.isfinite(dofs)):
        raise ValueError("DOF values must be finite")
    angles = dofs[:, channel_columns(channel_names, angle_names, "joint-angle channels")]
    if angle_centre is not None:
        angles = continuous_near(angles, angle_centre)
    if not root_travel:
        return angles
    root = dofs[:, channel_columns(channel_names, ROOT_DOF_NAMES, "root DOF channels")]
    return np.hstack([angles, root_features(root, fps, root_frame or RootFrame())])


def observations_from_dofs(model, dofs, channel_names, fps):
    """A model's observations (N, D), physical units, from a DOF array.

    Parameters
    ----------
    model : GaitModel
    dofs : array_like, shape (N, n_dofs)
        Metres and radians, AMC/``Skeleton`` layout; N >= 2 when the model has root travel.
    channel_names : sequence of str, length n_dofs
        Must contain the model's joint-angle channels (and the six root DOFs if the model has
        root travel); other columns are ignored.
    fps : float
        Frame rate of ``dofs`` (velocities are per second, so any rate works).

    Returns
    -------
    ndarray, shape (N, D)
        Columns ``model.channel_names``; angles placed near the training centre, continuous
        in time (:func:`continuous_near`).
    """
    return dof_observations(dofs, channel_names, fps, model.angle_names, model.root_travel,
                            model.root_frame, model.angle_centre[:model.n_angles])


class ObservationStream:
    """Frame-by-frame observations for online adaptation (causal root features).

    ``push(dof_row)`` returns the model observation of that frame, equal to the corresponding
    row of :func:`dof_observations` on the whole sequence (angles bit for bit: the same
    :func:`continuous_near` carry from the frame before) except on the very first frame, whose
    root rates (``root.v_forward``, ``root.v_left``, ``root.yaw_rate``) are unknown and returned
    as NaN: the filters treat NaN channels as *missing* (they are skipped).

    Parameters
    ----------
    model : GaitModel
    channel_names : sequence of str
        Names of the DOF columns that will be pushed.
    fps : float
        Frame rate of the pushed frames.
    """

    def __init__(self, model, channel_names, fps):
        self._names = [str(n) for n in channel_names]
        self._angle_cols = channel_columns(self._names, model.angle_names, "joint-angle channels")
        self._root_cols = (channel_columns(self._names, ROOT_DOF_NAMES, "root DOF channels")
                           if model.root_travel else None)
        if not fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self._fps = float(fps)
        self._model = model
        self._previous = None
        self._angles = None

    def reset(self):
        """Forget the previous frame (the next push starts a new sequence)."""
        self._previous = None
        self._angles = None

    def push(self, dof_row):
        """Observation (D,) of one DOF frame (n_dofs,)."""
        row = _check_dofs(dof_row, self._names)
        if row.shape[0] != 1 or not np.all(np.isfinite(row)):
            raise ValueError("push() takes one finite DOF frame")
        model = self._model
        centre = model.angle_centre[:model.n_angles]
        angles = wrap_near(row[0, self._angle_cols], centre)
        if self._angles is not None:
            angles = _carry(self._angles, angles, centre)
        self._angles = angles.copy()
        if self._root_cols is None:
            return angles
        root = row[:, self._root_cols]
        if self._previous is None:
            feats = root_features(np.vstack([root, root]), self._fps, model.root_frame)[1]
            feats[[1, 2, 3]] = np.nan
        else:
            feats = root_features(np.vstack([self._previous, root]), self._fps,
                                  model.root_frame)[1]
        self._previous = root
        return np.concatenate([angles, feats])
