"""Is the observed range a gait the model can continue? (``docs/gait.md``, *Saying no*)

Predict and the live preview must not key a confident walk onto motion that is not one. The
checks, on the observed joint angles (physical units) and, after adapting, on the model's fit:

1. **Motion**: the RMS deviation of the model's *gait channels* (the joint angles that move
   most in the model's mean cycle: hips, knees, ankles for CMU) from their mean over the range
   must reach ``MIN_MOTION_DEG`` (1°). A frozen pose is refused.
2. **Rhythm**: when the range is long enough to test (about 1 s for a 0.5-2 s period search),
   the periodicity test learning uses (:func:`.alignment.periodicity`) must find a period with a
   strength of at least ``MIN_STRENGTH`` (0.3, the segmentation's, :mod:`.segments`). Shorter
   ranges (predicting from less than a cycle) skip this test and say so.
3. **Alternating legs**: in the model's cycles the left and right gait channels alternate
   (their pooled zero-lag correlation, :func:`legs_together`, is negative). Observed legs that
   move together (correlation above ``MAX_LEGS_TOGETHER``, 0.8: a jump, a hop, a squat) are
   refused. On the leave-one-walker-out test windows of real walks the correlation stays below
   0.3 (0.5 s windows; 0.14 at 1.67 s); a jump gives 1.
4. **Fit score** (after adapting): the share of the gait channels' variance over the range that
   the adapted style and posture offset explain, ``1 - SSE / SST`` (no residual table: that
   would explain anything). Below ``WARN_FIT`` (0.5) the prediction is made with a warning that
   quotes the score. Leave-one-walker-out windows: median 0.7-0.85 for regular walkers, about
   0.1 (down to -0.5) for the sneaking walks of CMU 139 when no careful walker was learned.

Refusals say why in plain words; nothing is changed by the caller then.
"""

from dataclasses import dataclass

import numpy as np

from .alignment import periodicity
from .segments import MIN_STRENGTH

__all__ = ["GaitCheck", "MAX_LEGS_TOGETHER", "MIN_MOTION_DEG", "WARN_FIT", "check_gait",
           "fit_score", "gait_channels", "legs_together"]

MIN_MOTION_DEG = 1.0
MAX_LEGS_TOGETHER = 0.8
WARN_FIT = 0.5
N_GAIT_CHANNELS = 8


@dataclass(frozen=True)
class GaitCheck:
    """Outcome of :func:`check_gait`.

    Attributes
    ----------
    motion_deg : float
        RMS motion of the gait channels over the range, degrees.
    period_s, strength : float or None
        Period (seconds) and periodicity strength; None when the range is too short to test.
    legs_together : float or None
        Mean zero-lag correlation of the left/right gait-channel pairs (None without pairs).
    fit : float or None
        Fit score (:func:`fit_score`), when an adaptation was given.
    refusal : str or None
        Why the range is not a gait to continue (plain words), or None.
    warning : str or None
        A caution to report with the result, or None.
    """

    motion_deg: float
    period_s: float = None
    strength: float = None
    legs_together: float = None
    fit: float = None
    refusal: str = None
    warning: str = None


def gait_channels(model, count=N_GAIT_CHANNELS):
    """Indices of the ``count`` joint-angle channels that move most in the model's mean cycle."""
    cycle = np.einsum("j,jcd->cd", model.style_mean, model.bases)[:-1, :model.n_angles]
    return np.sort(np.argsort(-cycle.var(axis=0))[:count])


def _leg_pairs(model, channels):
    """(left, right) index pairs among ``channels`` whose names differ only by l/r."""
    names = model.channel_names
    pairs = []
    for i in channels:
        name = names[i]
        if name.startswith("l"):
            other = "r" + name[1:]
            if other in names:
                pairs.append((i, names.index(other)))
    return pairs


def legs_together(values, pairs):
    """Pooled zero-lag correlation of left/right channel pairs over a range: ``Σ x_l·x_r /
    sqrt(Σ|x_l|² Σ|x_r|²)`` with mean-removed signals (pairs that hardly move weigh little);
    about -1 for alternating legs, +1 for legs moving together, 0 when nothing moves."""
    values = np.asarray(values, dtype=float)
    left = values[:, [a for a, _ in pairs]]
    right = values[:, [b for _, b in pairs]]
    left = left - left.mean(axis=0)
    right = right - right.mean(axis=0)
    den = float(np.sqrt(np.sum(left**2) * np.sum(right**2)))
    return float(np.sum(left * right)) / den if den > 0 else 0.0


def fit_score(model, observations, result):
    """Share of the gait channels' variance explained by an adaptation (``1 - SSE/SST``).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        The observed range, physical units (all model channels).
    result : AdaptResult
        ``adapt(model, observations, ...)``.
    """
    ys = np.asarray(observations, dtype=float) / model.channel_scale
    fitted = model.gp.observation_mean(result.states[:, 1], result.w)
    if result.offset is not None:
        fitted = fitted + result.offset
    cols = gait_channels(model)
    sse = float(np.sum((ys[:, cols] - fitted[:, cols]) ** 2))
    sst = float(np.sum((ys[:, cols] - ys[:, cols].mean(axis=0)) ** 2))
    return 1.0 - sse / sst if sst > 0 else float("-inf")


def check_gait(model, observations, fps, result=None, what="the observed frames"):
    """Checks 1-3 of the module docstring, and the fit score when ``result`` is given.

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units (``observations_from_dofs``).
    fps : float
    result : AdaptResult, optional
    what : str
        How messages name the range (e.g. ``"frames 1–100 of Walker"``).

    Returns
    -------
    GaitCheck
    """
    obs = np.asarray(observations, dtype=float)
    cols = gait_channels(model)
    angles = obs[:, cols]
    motion = float(np.degrees(np.sqrt(np.mean((angles - angles.mean(axis=0)) ** 2))))
    if motion < MIN_MOTION_DEG:
        return GaitCheck(motion, refusal=f"The legs hold still in {what} ({motion:.2f}° of "
                                         f"motion): there is no walk to continue")
    pairs = _leg_pairs(model, cols)
    together = None
    if pairs:
        together = legs_together(obs, pairs)
        alternate = legs_together(np.einsum("j,jcd->cd", model.style_mean,
                                            model.bases)[:-1], pairs) < 0
        if alternate and together > MAX_LEGS_TOGETHER:
            return GaitCheck(motion, legs_together=together,
                             refusal=f"Both legs move together in {what} (correlation "
                                     f"{together:.2f}): that is a jump, hop or squat, not a walk "
                                     f"or run the gait model can continue")
    period = strength = None
    try:
        frames, strength = periodicity(obs[:, :model.n_angles], fps,
                                       tuple(model.lag_range))
        period = frames / fps
    except ValueError as exc:
        if "shorter than one cycle" not in str(exc):
            return GaitCheck(motion, legs_together=together,
                             refusal=f"No repeating step in {what}: {exc}")
    if strength is not None and strength < MIN_STRENGTH:
        return GaitCheck(motion, period, strength, together,
                         refusal=f"No steady rhythm in {what}: the motion repeats with a "
                                 f"strength of {strength:.2f} (a walk or run reaches "
                                 f"{MIN_STRENGTH:g} or more)")
    fit = warning = None
    if result is not None:
        fit = fit_score(model, obs, result)
        if fit < WARN_FIT:
            warning = (f"the gait model explains only {100 * max(fit, 0.0):.0f} % of the leg "
                       f"motion in {what} (fit score {fit:.2f}): check the result")
    return GaitCheck(motion, period, strength, together, fit, None, warning)
