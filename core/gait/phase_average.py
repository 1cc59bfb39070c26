"""Phase-averaged prediction: the expected pose when the future phase is uncertain
(docs/gait.md, *Phase-averaged prediction*).

Mean propagation (§3.3) predicts ``μ(φ_t + k ω) w``: the pose *at* the predicted phase. The
phase is not known exactly: the filter's covariance ``P`` of ``[ω, φ]`` at the last observed
frame grows along the prediction,

    Var φ_{t+k} = P_φφ + 2 k s P_ωφ + k² s² P_ωω + Σ_{j<k} (j² s² q_ω + q_φ)      (A^k P A^kᵀ + …)

(``s`` the retiming factor, ``Q = diag(q_ω, q_φ)`` the model's process noise), and a cadence
estimated from a short window is uncertain by far more than a stride's natural variation. Under
phase uncertainty the prediction with the smallest expected squared error is the *expected*
pose ``E[μ(φ_{t+k} + ε)] w``, ``ε ~ N(0, σ_k²)``: the cycle's harmonics shrink by
``exp(−n² σ_k² / 2)``, so far ahead the prediction relaxes from a confident swing with the
wrong timing towards the walker's mean pose.

The bases' GP mean is ``μ(φ) = k(φ)ᵀ K⁻¹ Y`` with the eq. 11 kernel, stationary on the circle:
``k(Δ) = Σ_n c_n cos nΔ`` (:func:`.residual.kernel_spectrum`). Averaging over ``ε`` therefore
only changes the kernel row, ``E k(Δ + ε) = Σ_n c_n e^{−n²σ²/2} cos nΔ``: the phase-averaged
prediction is the same GP weights read with a smoothed kernel (exact, no sampling). The
residual table goes through the same weights, so it is averaged alike.

The filter's covariance is overconfident on a walker the model has never seen (its likelihood
treats the frames as independent and the bases as exact), so the variance is multiplied by a
calibration factor (``scale``). The factor that fits the observed window is proportional to how
badly the adapted walker explains it — the classical inflation of a least-squares covariance
by the reduced χ²: :func:`forecast_scale` = ``c ν``, ``ν`` the window's mean squared residual
(style, residual table and offset at the filtered phases) over the model's noise ``r``
(:func:`innovation_ratio`). ``c`` and the fixed factor used without a window were chosen on the
leave-one-walker-out inner folds (docs/gait.md).
"""

import numpy as np

from .residual import kernel_spectrum, residual_weights

__all__ = ["DEFAULT_INNOVATION_FACTOR", "DEFAULT_PHASE_VAR_SCALE", "averaged_kernel",
           "forecast_scale", "innovation_ratio", "phase_variances"]

# Calibration of the filter's phase variance, chosen on the leave-one-walker-out inner folds
# (mean over the six outer folds of the inner scores, summed over the 0.5, 1.0 and 1.67 s
# windows; docs/gait.md). Fixed factor (no window at hand): candidates 3-30, 20 best, 15 and
# 30 within 0.03°. Per unit of the window's normalised innovation ν: candidates 50-500, 150
# best (200 within 0.01°); 150 × the median ν of the inner folds (0.14) ≈ the fixed 20.
DEFAULT_PHASE_VAR_SCALE = 20.0
DEFAULT_INNOVATION_FACTOR = 150.0


def phase_variances(covariance, process_noise, n_frames, omega_scale=1.0,
                    scale=DEFAULT_PHASE_VAR_SCALE):
    """Variance of the phase at frames k = 0 … n_frames under the linear phase model.

    ``x_{k+1} = A x_k + v_k``, ``A = [[1, 0], [s, 1]]`` on ``[ω, φ]``, ``v ~ N(0, Q)``: the
    φφ element of ``A^k P A^kᵀ + Σ_{j<k} A^j Q A^jᵀ`` in closed form.

    Parameters
    ----------
    covariance : array_like, shape (2, 2)
        Filter covariance of ``[ω, φ]`` at the last observed frame (``adapt(...).covariance``).
    process_noise : array_like, shape (2, 2)
        ``Q`` per frame at the prediction's rate (``model.process_noise(fps)``); its diagonal is
        used.
    n_frames : int
    omega_scale : float
        Retiming factor (the cadence and its uncertainty scale with it).
    scale : float
        Calibration factor (≥ 0) on the whole variance.

    Returns
    -------
    ndarray, shape (n_frames + 1,), radians²
    """
    p = np.asarray(covariance, dtype=float)
    q = np.asarray(process_noise, dtype=float)
    if p.shape != (2, 2) or q.shape != (2, 2) or not (np.all(np.isfinite(p))
                                                     and np.all(np.isfinite(q))):
        raise ValueError(f"covariance and process_noise must be finite (2, 2), got {p.shape}, "
                         f"{q.shape}")
    if not (np.isfinite(scale) and scale >= 0 and np.isfinite(omega_scale) and omega_scale > 0):
        raise ValueError(f"scale must be >= 0 and omega_scale > 0, got {scale}, {omega_scale}")
    k = np.arange(int(n_frames) + 1, dtype=float)
    s = float(omega_scale)
    var = p[1, 1] + 2.0 * k * s * p[0, 1] + k**2 * s**2 * p[0, 0]
    # Σ_{j=0}^{k-1} (j² s² q_ω + q_φ) = s² q_ω (k-1) k (2k-1) / 6 + k q_φ
    var = var + s**2 * q[0, 0] * (k - 1.0) * k * (2.0 * k - 1.0) / 6.0 + q[1, 1] * k
    return float(scale) * np.maximum(var, 0.0)


def averaged_kernel(beta, phis, phases, variances):
    """Rows of the eq. 11 kernel (noise excluded) averaged over Gaussian phase noise.

    ``E_ε k(φ_i + ε − φ_p)``, ``ε ~ N(0, variances[i])``; with zero variance this is the
    kernel itself (to the spectrum's truncation, 1e-12 relative).

    Parameters
    ----------
    beta : array_like, shape (4,)
    phis : array_like, shape (n,)
        Query phases, radians.
    phases : array_like, shape (P,)
        The GP's training phases.
    variances : array_like, shape (n,)
        Phase variances, radians².

    Returns
    -------
    ndarray, shape (n, P)
    """
    spec = kernel_spectrum(beta)
    phis = np.asarray(phis, dtype=float)
    var = np.asarray(variances, dtype=float)
    if var.shape != phis.shape or np.any(~np.isfinite(var)) or np.any(var < 0):
        raise ValueError(f"variances must be non-negative, shape {phis.shape}, got {var.shape}")
    n = np.arange(len(spec), dtype=float)
    damp = spec[None, :] * np.exp(-0.5 * np.multiply.outer(var, n**2))      # (n, H)
    # cos n(φ_i − φ_p) = cos nφ_i cos nφ_p + sin nφ_i sin nφ_p
    query = np.multiply.outer(phis, n)
    train = np.multiply.outer(np.asarray(phases, dtype=float), n)
    return (damp * np.cos(query)) @ np.cos(train).T + (damp * np.sin(query)) @ np.sin(train).T


def innovation_ratio(model, result, observations):
    """ν: mean squared residual of the adapted walker on its window over the model's noise r.

    ``e_t = y_t − (μ(φ_t) ŵ + k(φ_t)ᵀ K⁻¹ T + b)`` in scaled units at the filtered phases
    (angles wrapped), averaged over the observed entries (NaN = unobserved skipped).

    Parameters
    ----------
    model : GaitModel
    result : AdaptResult
        ``adapt(model, observations, ...)`` (``states``, ``w``, ``residual``, ``offset``).
    observations : array_like, shape (N, D)
        The window it was adapted on, physical units, all model channels.

    Returns
    -------
    float
    """
    obs = np.asarray(observations, dtype=float)
    phis = np.asarray(result.states, dtype=float)[:, 1]
    if obs.shape != (len(phis), model.n_channels):
        raise ValueError(f"observations must be ({len(phis)}, {model.n_channels}) (the adapted "
                         f"window), got {obs.shape}")
    fit = model.gp.observation_mean(phis, result.w)
    if result.residual is not None:
        fit = fit + model.gp.kernel(phis) @ residual_weights(model, result.residual)
    if result.offset is not None:
        fit = fit + np.asarray(result.offset)
    diff = obs - model.to_physical(fit)
    diff[:, model.is_angle] = (diff[:, model.is_angle] + np.pi) % (2.0 * np.pi) - np.pi
    scaled = diff / model.channel_scale
    ok = np.isfinite(scaled)
    if not ok.any():
        raise ValueError("the window has no observed value")
    return float(np.mean(scaled[ok] ** 2) / model.r)


def forecast_scale(model, result, observations, factor=DEFAULT_INNOVATION_FACTOR):
    """``phase_var_scale`` for :func:`.predict` calibrated on the window: ``factor · ν``."""
    if not (np.isfinite(factor) and factor >= 0):
        raise ValueError(f"factor must be non-negative, got {factor}")
    return float(factor) * innovation_ratio(model, result, observations)
