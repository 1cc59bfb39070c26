"""Learning a stylistic gait model from training sequences (Matsubara §2).

Pipeline: DOF arrays → model channels (joint angles + root features, resampled to the model
rate) → scaled units → alignment (eqs. 3-5) → SVD factorisation (eq. 6) → MAP refinement
(eqs. 7-10, optional) → GP observation model (eq. 11) → noise levels and priors used when
adapting to a new walker.
"""

import numpy as np

from ..mocap import resample
from .alignment import ALIGNMENT_MODES, align_sequences, phase_shift, rotate_profile
from .factorization import factorize, reconstruct
from .features import angle_channel_names, continuous_near, dof_observations
from .gp import fit_phase_gp
from .map_refinement import refine_map
from .retiming import cadence_style_direction
from .model import GaitModel
from .root_travel import ROOT_DOF_NAMES, ROOT_FEATURE_NAMES, ROOT_FEATURE_UNITS, RootFrame

__all__ = ["learn_model"]

DEFAULT_ENERGY = 0.99
# Process noise defaults at the model rate (chosen on validation splits of the *training* trials,
# docs/gait.md): ω random walk with a standard deviation of 0.1 % of the mean training ω per
# frame (a walker's cadence is steady; changes of gait are caught by re-acquisition), phase noise
# 0.005 rad per frame.
DEFAULT_Q_OMEGA_REL = 0.001
DEFAULT_Q_PHI = 0.005


def _as_list(value, count, what, scalar_items=False):
    """One value per sequence: ``value`` itself when shared, else its items (a list of scalars
    is per sequence when ``scalar_items``; a list of strings is always one shared value)."""
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) \
            and not isinstance(value[0], str) and (scalar_items or not np.isscalar(value[0])):
        if len(value) != count:
            raise ValueError(f"expected one {what} per sequence ({count}), got {len(value)}")
        return list(value)
    return [value] * count


def learn_model(sequences, channel_names, fps, names=None, *, n_styles=None,
                energy=DEFAULT_ENERGY, n_phase=33, alignment="mean", refinement="map",
                root_travel=True, model_fps=60.0, lag_range=(0.5, 2.0), gp_beta=None,
                root_frame=None, q_omega_rel=DEFAULT_Q_OMEGA_REL, q_phi=DEFAULT_Q_PHI,
                obs_noise=None, walkers=None, offset=True, notes=""):
    """Learn a :class:`GaitModel` from periodic training motions.

    Parameters
    ----------
    sequences : list of array_like, each shape (N_i, n_dofs)
        DOF arrays in the AMC/``Skeleton`` layout: metres (root translation, Z-up world) and
        radians. Each must hold at least one complete gait cycle.
    channel_names : sequence of str, or list of sequences of str
        DOF names of the columns (``Skeleton.dof_names()``), shared or one list per sequence.
        The joint-angle channels are those of the first sequence that are not root DOFs.
    fps : float or list of float
        Frame rate(s) of the sequences.
    names : sequence of str, optional
        Style names (default ``'style0'``, …). Sequences that share a name become one learned
        style: the mean of their cycles re-aligned to the model's mean cycle (``_merge_named``)
        and the geometric mean of their periods (the style prior and the offset prior still see
        every sequence).
    n_styles : int, optional
        J. Default: the smallest J holding ``energy`` of the singular-value spectrum.
    energy : float
        Energy threshold for J.
    n_phase : int
        C, phase samples per cycle (including the closing one).
    alignment : {'mean', 'one'}
        Mean of all complete cycles (default) or one cycle per sequence (the paper).
    refinement : {'map', 'svd'}
        MAP refinement (eqs. 7-10, default) or the plain SVD solution.
    root_travel : bool
        Model the seven root-travel features too (needs the six root DOFs).
    model_fps : float
        Model frame rate (the paper: 60 Hz); sequences are resampled to it.
    lag_range : (float, float)
        Period search range, seconds.
    gp_beta : array_like, shape (4,), optional
        Fixed GP hyper-parameters instead of maximum marginal likelihood.
    root_frame : RootFrame, optional
        Root rest rotation / angle order / forward axis (default CMU).
    q_omega_rel, q_phi : float
        Process noise standard deviations per model frame: ω as a fraction of the mean training
        ω, φ in radians.
    obs_noise : float, optional
        Observation noise variance r (scaled units²). Default: leave-one-out residual of the
        factorisation plus the within-sequence cycle-to-cycle variance.
    walkers : sequence of str, optional
        Who walks in each sequence (pieces of one capture, or several captures of one person,
        share a label). Default: every sequence is a walker of its own.
    offset : bool
        Learn the prior of a walker's posture offset (``GaitModel.offset_var``, the variance of
        the walkers' mean poses; ``docs/gait.md``, *Posture offset*). Needs two walkers or more;
        False (or a single walker) gives a model without offset.
    notes : str
        Free text stored with the model (where it comes from).

    Returns
    -------
    GaitModel

    Raises
    ------
    ValueError
        Naming the sequence that is too short, has mismatched columns or misses channels.
    """
    if len(sequences) == 0:
        raise ValueError("need at least one walk")
    count = len(sequences)
    if alignment not in ALIGNMENT_MODES:
        raise ValueError(f"alignment must be one of {ALIGNMENT_MODES}, got {alignment!r}")
    if refinement not in ("map", "svd"):
        raise ValueError(f"refinement must be 'map' or 'svd', got {refinement!r}")
    name_lists = _as_list(channel_names, count, "channel-name list")
    rates = _as_list(fps, count, "frame rate", scalar_items=True)
    names = [f"style{i}" for i in range(count)] if names is None else [str(n) for n in names]
    if len(names) != count:
        raise ValueError(f"expected {count} style names, got {len(names)}")
    frame = root_frame or RootFrame()
    angle_names = angle_channel_names(name_lists[0])
    if not angle_names:
        raise ValueError("no joint-angle channels among the channel names")

    observed = []
    for i, (seq, cols, rate) in enumerate(zip(sequences, name_lists, rates)):
        seq = np.asarray(seq, dtype=float)
        cols = [str(c) for c in cols]
        try:
            if seq.ndim != 2 or seq.shape[1] != len(cols):
                raise ValueError(f"expected shape (N, {len(cols)}), got {seq.shape}")
            if not rate > 0:
                raise ValueError(f"fps must be positive, got {rate}")
            if rate != model_fps:
                angle_cols = [k for k, c in enumerate(cols) if c not in ROOT_DOF_NAMES[:3]]
                seq = resample(seq, rate, model_fps, angle_cols)
            observed.append(dof_observations(seq, cols, model_fps, angle_names, root_travel,
                                             frame))
        except ValueError as exc:
            raise ValueError(f"the walk {names[i]}: {exc}") from None

    n_angles = len(angle_names)
    stacked = np.vstack(observed)
    centre = np.zeros(stacked.shape[1])
    # Circular mean of every joint angle over all training frames.
    centre[:n_angles] = np.arctan2(np.sin(stacked[:, :n_angles]).mean(0),
                                   np.cos(stacked[:, :n_angles]).mean(0))
    for obs in observed:
        obs[:, :n_angles] = continuous_near(obs[:, :n_angles], centre[:n_angles])
    stacked = np.vstack(observed)

    channel = list(angle_names) + (list(ROOT_FEATURE_NAMES) if root_travel else [])
    units = ["rad"] * n_angles + (list(ROOT_FEATURE_UNITS) if root_travel else [])
    scale = _channel_scale(stacked, units, n_angles)
    scaled = [obs / scale for obs in observed]
    if walkers is not None and len(walkers) != count:
        raise ValueError(f"expected one walker label per sequence ({count}), got {len(walkers)}")
    offset_var = _offset_variance(scaled, walkers) if offset else np.zeros(len(channel))

    try:
        aligned = align_sequences(scaled, model_fps, n_phase, alignment, lag_range)
    except ValueError as exc:
        message = str(exc)
        if message.startswith("sequence "):
            index = int(message.split()[1].rstrip(":"))
            message = f"the walk {names[index]}:" + message.split(":", 1)[1]
        raise ValueError(message) from None
    styles, bases, singular = factorize(aligned.cycles, n_styles, energy)
    if refinement == "map":
        result = refine_map(aligned.cycles, styles, bases)
        styles, bases = result.styles, result.bases
    else:
        bases = bases.copy()
        bases[:, -1] = bases[:, 0]  # the GP uses the distinct rows; close the cycle (eq. 9)
    gp = fit_phase_gp(bases[:, :-1], gp_beta)

    if obs_noise is None:
        obs_noise = _loo_residual(aligned.cycles, styles.shape[1]) \
            + _within_variance(scaled, aligned)
    omega_mean = float(np.exp(np.mean(np.log(2.0 * np.pi / aligned.periods))))
    q = np.diag([(q_omega_rel * omega_mean) ** 2, q_phi**2])
    cov = np.cov(styles.T, ddof=1).reshape(styles.shape[1], -1) if count > 1 \
        else np.zeros((styles.shape[1],) * 2)
    cov = cov + 1e-6 * max(float(np.trace(cov)), float(np.sum(styles**2)) / count) \
        * np.eye(len(cov))
    cadence_style = np.zeros(styles.shape[1])
    if root_travel:
        fwd, height = (channel.index(n) for n in ("root.v_forward", "root.height"))
        cycles = aligned.cycles[:, :-1]
        cadence_style = cadence_style_direction(styles, aligned.periods / model_fps,
                                                cycles[:, :, fwd].mean(axis=1) * scale[fwd],
                                                cycles[:, :, height].mean(axis=1)
                                                * scale[height])
    named, named_styles, named_periods = _merge_named(names, styles, aligned.periods,
                                                      bases)
    return GaitModel(channel_names=channel, units=units, angle_centre=centre,
                     channel_scale=scale, fps=model_fps, bases=bases, styles=named_styles,
                     style_names=named, beta=gp.beta, Q=q, r=float(obs_noise),
                     style_mean=styles.mean(axis=0), style_cov=cov, periods=named_periods,
                     lag_range=np.asarray(lag_range, dtype=float),
                     dof_names=[str(c) for c in name_lists[0]], root_travel=root_travel,
                     root_rest=frame.rest, root_order=frame.order,
                     forward_axis=frame.forward_axis, singular_values=singular,
                     alignment=alignment, refinement=refinement, offset_var=offset_var,
                     cadence_style=cadence_style, notes=str(notes))


def _merge_named(names, styles, periods, bases):
    """One style per distinct name (first-appearance order): the mean of its pieces' cycles,
    each re-aligned to the model's mean cycle; geometric-mean period.

    ``align_sequences`` aligns every training cycle with one reference sequence, and a piece
    unlike that reference can land at another phase: five of the stock library's nine careful
    pieces sat a quarter cycle off the common phase and one 0.4 cycle (every other style's
    pieces within 0.03 cycle of it), so their plain mean cancelled much of the legs' motion
    (one foot never came down) and the cadence direction, learned at the common phase, swung
    the legs a quarter cycle late (docs/gait.md, *The three misses*). So each piece's cycle ``Σ_j w_j Ȳ^j`` is shifted to the phase that best
    matches the mean cycle of all the pieces ``Σ_j w̄_j Ȳ^j`` (eq. 4's cross-correlation,
    :func:`~.alignment.phase_shift`), and the name's cycles are averaged and projected back
    onto the bases (least squares). Without shared names the learned styles stay as they are.
    """
    order = list(dict.fromkeys(names))
    if len(order) == len(names):
        return names, styles, periods
    index = np.array([order.index(n) for n in names])
    flat = bases.reshape(len(bases), -1).T  # (C·D, J)
    reference = reconstruct(styles.mean(axis=0)[None], bases)[0]
    merged, cycle = [], []
    for k in range(len(order)):
        members = np.flatnonzero(index == k)
        cycle.append(np.exp(np.log(periods[members]).mean()))
        aligned = [rotate_profile(profile, phase_shift(reference, profile))
                   for profile in reconstruct(styles[members], bases)]
        merged.append(np.linalg.lstsq(flat, np.mean(aligned, axis=0).ravel(), rcond=None)[0])
    return order, np.array(merged), np.array(cycle)


def _offset_variance(scaled, walkers):
    """Between-walker variance (D,) of the walkers' mean poses in scaled units (ddof 1): the
    prior of a new walker's posture offset. Zeros with fewer than two walkers."""
    groups = list(range(len(scaled))) if walkers is None else [str(g) for g in walkers]
    frames = {}
    for g, obs in zip(groups, scaled):
        frames.setdefault(g, []).append(obs)
    if len(frames) < 2:
        return np.zeros(scaled[0].shape[1])
    means = np.array([np.vstack(v).mean(axis=0) for v in frames.values()])
    return means.var(axis=0, ddof=1)


def _channel_scale(stacked, units, n_angles):
    """1 for every angle channel (radians, the paper's units); a non-angle channel is scaled so
    that its spread over the training frames equals the median spread of the joint angles."""
    spread = stacked.std(axis=0)
    moving = spread[:n_angles][spread[:n_angles] > 1e-9]
    typical = float(np.median(moving)) if len(moving) else 1.0
    scale = np.ones(stacked.shape[1])
    for k, unit in enumerate(units):
        if unit != "rad":
            scale[k] = max(spread[k] / typical, 1e-6)
    return scale


def _loo_residual(cycles, n_styles):
    """Mean squared residual (per element) of every aligned cycle projected on the J bases
    learned from the *other* cycles: how well the factorisation describes a new walker."""
    count = len(cycles)
    if count < 2:
        return max(float(np.var(cycles)) * 1e-2, 1e-12)
    flat = cycles.reshape(count, -1)
    errors = []
    for s in range(count):
        others = np.delete(flat, s, axis=0)
        _, _, vt = np.linalg.svd(others, full_matrices=False)
        basis = vt[:min(n_styles, len(others))]
        coef = basis @ flat[s]
        errors.append(np.mean((flat[s] - coef @ basis) ** 2))
    return max(float(np.mean(errors)), 1e-12)


def _within_variance(scaled, aligned):
    """Mean squared deviation of the training frames from their own sequence's aligned cycle
    (cycle-to-cycle variability), evaluated at each frame's phase."""
    errors = []
    for seq, cycle, period, start in zip(scaled, aligned.cycles, aligned.periods,
                                         aligned.starts):
        p = len(cycle) - 1
        pos = ((np.arange(len(seq)) - start) / period % 1.0) * p
        lo = np.minimum(np.floor(pos).astype(int), p - 1)
        frac = (pos - lo)[:, None]
        fitted = cycle[lo] * (1.0 - frac) + cycle[lo + 1] * frac
        errors.append(np.mean((seq - fitted) ** 2))
    return float(np.mean(errors))
