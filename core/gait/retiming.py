"""Retiming as a person would: how a walker's style changes with cadence, learned from the
training walks (``docs/gait.md``, *Restyle and retime*).

Playing a walk faster (the paper's retiming, ω × s) keeps its stride and joint ranges: at 1.6×
a normal walk becomes 171 steps per minute with a normal walk's hip swing, where people who walk
faster take longer steps and swing their legs and arms further. The model learns the direction
in style space along which its training walks change with their pace:

1. **Walks only.** A training sequence is a walk when its Froude number ``v² / (g h)`` (mean
   forward speed v, mean root height h as the leg length) is below ``WALK_FROUDE`` (0.5, the
   walk-run transition of dynamic similarity); sequences on the spot (v < ``MIN_SPEED``) are
   left out.
2. **Style against pace.** Over the walks, the least-squares slope ``b`` of the style on the log
   dimensionless speed ``x = log(v / √(g h))`` (the population's gait changes with speed —
   strides, swings — and these relations hold across walkers, where cadence alone mixes pace
   with style: a sneaking walk can be quick and short), and the slope ``γ`` of ``x`` on the log
   cadence (how much faster people walk when they step faster; about 1.1 on the CMU walks).
3. ``cadence_style = γ b``: retiming by a factor c moves the style by ``log(c) ×
   cadence_style`` (:func:`.walk.predict_walk`).

With fewer than ``MIN_WALKS`` walks, or no spread of pace or cadence among them, the direction
is zero and retiming plays the walk faster.
"""

import numpy as np

__all__ = ["GRAVITY", "MIN_SPEED", "MIN_WALKS", "WALK_FROUDE", "cadence_style_direction"]

GRAVITY = 9.81
WALK_FROUDE = 0.5
MIN_SPEED = 0.05       # m/s
MIN_WALKS = 3


def cadence_style_direction(styles, periods_s, speeds, heights):
    """The style's change per unit log cadence (module docstring).

    Parameters
    ----------
    styles : array_like, shape (S, J)
        Styles of the training sequences (not merged by name).
    periods_s : array_like, shape (S,)
        Their cycle periods, seconds.
    speeds : array_like, shape (S,)
        Mean forward root speed of each sequence, m/s.
    heights : array_like, shape (S,)
        Mean root height of each sequence, m.

    Returns
    -------
    ndarray, shape (J,)
    """
    styles = np.asarray(styles, dtype=float)
    speeds = np.asarray(speeds, dtype=float)
    heights = np.maximum(np.asarray(heights, dtype=float), 1e-3)
    log_f = -np.log(np.asarray(periods_s, dtype=float))
    walk = (speeds > MIN_SPEED) & (speeds**2 / (GRAVITY * heights) < WALK_FROUDE)
    if walk.sum() < MIN_WALKS:
        return np.zeros(styles.shape[1])
    pace = np.log(speeds[walk] / np.sqrt(GRAVITY * heights[walk]))
    pace = pace - pace.mean()
    cadence = log_f[walk] - log_f[walk].mean()
    if pace @ pace < 1e-12 or cadence @ cadence < 1e-12:
        return np.zeros(styles.shape[1])
    slope = pace @ (styles[walk] - styles[walk].mean(axis=0)) / (pace @ pace)
    gamma = (cadence @ pace) / (cadence @ cadence)
    return gamma * slope
