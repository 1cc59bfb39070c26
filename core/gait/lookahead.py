"""Look-ahead prediction while a user scrubs or plays the timeline (the live-preview logic).

:class:`LookaheadPredictor` keeps an :class:`~.online.OnlineEM` in step with the frame the
user is looking at and returns the DOF frame predicted ``ahead`` frames later:

* a later frame at most ``replay`` frames on (playback, also when Blender drops frames to keep
  up, or scrubbing forwards): one online-EM step per frame in between;
* the same frame again: the cached prediction;
* any other frame (scrubbing backwards, a long jump): the filter restarts and replays the
  ``replay`` frames up to the new one (fewer at the start of the observed range) — after such
  a jump the result equals a fresh :class:`OnlineEM` run over those frames.

Plain arrays in and out: a callable reads DOF rows of given frames (Blender evaluates the
F-curves); the predicted row is in ``dof_names`` order.
"""

import numpy as np

from .features import ObservationStream, channel_columns
from .online import OnlineConfig, OnlineEM
from .prediction import predict_dofs

__all__ = ["LookaheadPredictor"]


class LookaheadPredictor:
    """Online-EM look-ahead over a stream of DOF frames.

    Parameters
    ----------
    model : GaitModel
    dof_names : sequence of str
        Names of the columns that ``read_dofs`` returns (must contain ``model.dof_names``).
    fps : float
        Frame rate of the frames.
    ahead : int
        Frames ahead to predict (≥ 1).
    replay : int
        Frames replayed after a jump (≥ 2).
    first_frame : int
        First frame that may be read (the start of the observed range).
    config : OnlineConfig, optional
    """

    def __init__(self, model, dof_names, fps, ahead, replay=60, first_frame=0, config=None):
        if int(ahead) < 1 or int(replay) < 2:
            raise ValueError(f"ahead must be >= 1 and replay >= 2, got {ahead}, {replay}")
        self.model = model
        self.fps = float(fps)
        self.ahead = int(ahead)
        self.replay = int(replay)
        self.first_frame = int(first_frame)
        self._cols = channel_columns(dof_names, model.dof_names, "model DOF channels")
        self._stream = ObservationStream(model, model.dof_names, fps)
        self._online = OnlineEM(model, fps=fps, config=config or OnlineConfig())
        self._last_frame = None
        self._last_row = None
        self._prediction = None
        self.replays = 0

    @property
    def online(self):
        """The underlying :class:`OnlineEM`."""
        return self._online

    def _push(self, row):
        self._last_obs = self._stream.push(row)
        self._online.step(self._last_obs)
        self._last_row = row

    def update(self, frame, read_dofs):
        """Assimilate ``frame`` and return the DOF row predicted ``ahead`` frames later.

        Parameters
        ----------
        frame : int
        read_dofs : callable
            ``read_dofs(frames: ndarray of int) -> ndarray (len(frames), n_columns)``.

        Returns
        -------
        ndarray, shape (len(model.dof_names),)
        """
        frame = int(frame)
        if frame == self._last_frame and self._prediction is not None:
            return self._prediction
        if self._last_frame is not None and 0 < frame - self._last_frame <= self.replay:
            frames = np.arange(self._last_frame + 1, frame + 1)
            rows = np.asarray(read_dofs(frames), dtype=float)[:, self._cols]
        else:
            self._online.reset()
            self._stream.reset()
            self.replays += 1
            start = max(self.first_frame, frame - self.replay + 1)
            rows = np.asarray(read_dofs(np.arange(start, frame + 1)), dtype=float)[:, self._cols]
        for row in rows:
            self._push(row)
        self._last_frame = frame
        online = self._online
        # The online forecast's offset and continuation (OnlineEM.predict) in DOF form.
        self._prediction = predict_dofs(self.model, [online.omega, online.phase], online.w,
                                        self.ahead, self._last_row, self.fps,
                                        offset=online.state.b, start=self._last_obs)[-1]
        return self._prediction
