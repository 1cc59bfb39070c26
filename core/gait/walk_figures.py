"""How a walk looks to an animator: the floor it stands on, sliding feet, root travel against
what the legs do, stride and swing (``docs/gait.md``, *Restyle and retime*).

These figures judge a predicted (restyled, retimed) walk the way an animator does, on the DOF
rows keyed onto the walker's own skeleton (forward kinematics, Z-up world, metres):

* **Contact point**: the ball of the foot (CMU ``ltoes``/``rtoes`` joint origins); the *lower
  foot* of a frame is the lower of the two.
* **Floor** (:func:`contact_height`): the height the lower foot stands at, the 20th percentile of
  its height over a range (a walk always has a foot down; a run's flight frames lie above it).
* **Contact frames**: the lower foot within ``CONTACT_BAND`` (2.5 cm) of the floor and moving
  vertically slower than ``CONTACT_VZ`` (0.15 m/s).
* **Skate**: horizontal speed of the lower foot on contact frames, cm/s (mean and 90th
  percentile). **Slip**: its signed component along the walking direction (− = backwards).
* **Root vs legs**: root speed over the legs' implied speed on the contact frames, where the
  implied speed is the root speed minus the contact foot's (the root speed that would keep it
  still): 1 when the stance foot stays put, < 1 when it moonwalks.
* **Lowest foot**: per step (half a cycle) the lowest height of the lower foot, minus the floor;
  the median over steps, cm. Negative: through the floor.
* **Stride**: root distance per cycle (left + right step), m; **hip swing** and **knee range**:
  peak-to-peak flexion (the femur's and tibia's X angle), degrees, mean of both legs.
The heading drift and the join's acceleration are measured by ``benchmarks/gait_restyle.py``
(they need the reference and the capture).
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import chain_kinematics
from .foot_slide import CMU_FEET
from .root_travel import RootFrame, _directions, heading_angles, root_rotations

__all__ = ["CONTACT_BAND", "CONTACT_VZ", "FootTracks", "contact_frames", "contact_height",
           "foot_tracks", "lowest_foot", "skate_and_slip", "walk_summary"]

CONTACT_BAND = 0.025      # m above the floor
CONTACT_VZ = 0.15         # m/s vertical speed
FLOOR_PERCENTILE = 20.0


@dataclass(frozen=True)
class FootTracks:
    """World trajectories of a walk's feet and root.

    Attributes
    ----------
    left, right, root : ndarray, shape (N, 3), metres
    heading : ndarray, shape (N,), radians (unwrapped)
    fps : float
    """

    left: np.ndarray
    right: np.ndarray
    root: np.ndarray
    heading: np.ndarray
    fps: float
    root_frame: RootFrame = None

    @property
    def lower(self):
        """(N, 3) the lower foot of every frame."""
        return np.where((self.right[:, 2] < self.left[:, 2])[:, None], self.right, self.left)


def foot_tracks(skeleton, dofs, fps, feet=CMU_FEET, root_frame=None):
    """:class:`FootTracks` of DOF rows (``skeleton``'s layout) by forward kinematics."""
    dofs = np.asarray(dofs, dtype=float)
    index = [skeleton.index(f) for f in feet]
    heads, _ = chain_kinematics(skeleton, dofs, index)
    frame = root_frame or RootFrame(rest=skeleton.rest_rotations[0])
    root_cols = [skeleton.dof_names().index(n) for n in
                 ("root.tx", "root.ty", "root.tz", "root.rx", "root.ry", "root.rz")]
    heading = heading_angles(root_rotations(dofs[:, root_cols], frame), frame)
    return FootTracks(heads[index[0]], heads[index[1]], heads[0], heading, float(fps), frame)


def contact_height(tracks):
    """Floor height (m): the 20th percentile of the lower foot's height over the range."""
    return float(np.percentile(tracks.lower[:, 2], FLOOR_PERCENTILE))


def contact_frames(tracks, floor):
    """Boolean (N - 1,) for frames 1 … N-1: the lower foot is within the contact band of the
    floor and barely moves vertically (module docstring)."""
    low = tracks.lower
    vz = np.abs(np.diff(low[:, 2])) * tracks.fps
    return (low[1:, 2] < floor + CONTACT_BAND) & (vz < CONTACT_VZ)


def _forward(tracks, heading):
    """Unit horizontal walking directions (N, 2) at headings ``heading``."""
    return _directions(heading, tracks.root_frame)[0]


def skate_and_slip(tracks, floor):
    """Skate (mean, p90) and slip of the lower foot on contact frames, and root / legs speeds.

    Returns
    -------
    dict
        ``skate_cm_s``, ``skate_p90_cm_s``, ``slip_cm_s``, ``root_speed``, ``legs_speed``
        (m/s), ``root_vs_legs``, ``contact_share`` (of frames).
    """
    contact = contact_frames(tracks, floor)
    fps = tracks.fps
    # The lower foot of frame t, followed from t-1 (the same foot on both frames).
    lower_right = tracks.right[:, 2] < tracks.left[:, 2]
    foot = np.where(lower_right[1:, None], np.diff(tracks.right, axis=0),
                    np.diff(tracks.left, axis=0))[:, :2] * fps
    root = np.diff(tracks.root, axis=0)[:, :2] * fps
    fwd = _forward(tracks, 0.5 * (tracks.heading[1:] + tracks.heading[:-1]))
    if not contact.any():
        nan = float("nan")
        return {"skate_cm_s": nan, "skate_p90_cm_s": nan, "slip_cm_s": nan, "root_speed": nan,
                "legs_speed": nan, "root_vs_legs": nan, "contact_share": 0.0}
    speed = np.linalg.norm(foot[contact], axis=1)
    slip = np.sum(foot * fwd, axis=1)[contact]
    root_fwd = np.sum(root * fwd, axis=1)[contact]
    legs = float(np.mean(root_fwd - slip))
    return {"skate_cm_s": 100 * float(speed.mean()),
            "skate_p90_cm_s": 100 * float(np.percentile(speed, 90)),
            "slip_cm_s": 100 * float(slip.mean()), "root_speed": float(root_fwd.mean()),
            "legs_speed": legs,
            "root_vs_legs": float(root_fwd.mean()) / legs if abs(legs) > 1e-9 else float("nan"),
            "contact_share": float(contact.mean())}


def lowest_foot(tracks, floor, period_frames):
    """Median over steps (half cycles) of the lower foot's lowest height, minus the floor (m),
    and the lowest of all (m)."""
    z = tracks.lower[:, 2] - floor
    step = max(2, int(round(period_frames / 2)))
    mins = [z[a:a + step].min() for a in range(0, len(z) - step + 1, step)] or [z.min()]
    return float(np.median(mins)), float(z.min())


def walk_summary(skeleton, dofs, fps, period_frames, floor=None, feet=CMU_FEET):
    """Every figure of the module docstring for a walk (DOF rows), as a dict.

    ``floor``: the height to judge against (default: the walk's own contact height)."""
    tracks = foot_tracks(skeleton, dofs, fps, feet)
    floor = contact_height(tracks) if floor is None else float(floor)
    out = skate_and_slip(tracks, floor)
    low, lowest = lowest_foot(tracks, floor, period_frames)
    names = skeleton.dof_names()
    cycle = int(round(period_frames))
    horizontal = np.diff(tracks.root[:, :2], axis=0) * fps
    fwd = _forward(tracks, 0.5 * (tracks.heading[1:] + tracks.heading[:-1]))
    speed = float(np.mean(np.sum(horizontal * fwd, axis=1)))
    dofs = np.asarray(dofs, dtype=float)

    def ptp(name):
        col = names.index(name)
        return float(np.degrees(np.ptp(dofs[-cycle:, col]))) if len(dofs) >= cycle else \
            float(np.degrees(np.ptp(dofs[:, col])))

    out.update({"floor_m": floor, "lowest_foot_cm": 100 * low, "lowest_foot_min_cm": 100 * lowest,
                "below_floor_share": float(np.mean(tracks.lower[:, 2] < floor - 0.02)),
                "speed_m_s": speed, "period_s": period_frames / fps,
                "steps_per_min": 120.0 * fps / period_frames,
                "stride_m": speed * period_frames / fps,
                "hip_swing_deg": 0.5 * (ptp("lfemur.rx") + ptp("rfemur.rx")),
                "knee_range_deg": 0.5 * (ptp("ltibia.rx") + ptp("rtibia.rx"))})
    return out
