"""A small limited-memory BFGS minimiser (NumPy only).

The core may not import SciPy (Blender does not bundle it), yet the MAP refinement (Matsubara
eqs. 7-10) and the GP hyper-parameter fit (marginal likelihood of eq. 11) need a smooth
unconstrained minimiser. This is the textbook L-BFGS (Nocedal & Wright, *Numerical
Optimization*, 2nd ed., Algorithm 7.4 two-loop recursion, Algorithms 3.5/3.6 strong-Wolfe line
search with cubic interpolation). The tests check it against ``scipy.optimize``.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["OptimizeResult", "minimize_lbfgs"]


@dataclass
class OptimizeResult:
    """Outcome of :func:`minimize_lbfgs`.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Best point found.
    fun : float
        Objective at ``x``.
    jac : ndarray, shape (n,)
        Gradient at ``x``.
    nit : int
        Iterations (accepted steps).
    nfev : int
        Objective/gradient evaluations.
    success : bool
        True when a convergence test was met (not the iteration limit or a failed search).
    message : str
    """

    x: np.ndarray
    fun: float
    jac: np.ndarray
    nit: int
    nfev: int
    success: bool
    message: str


def minimize_lbfgs(fun, x0, max_iter=500, memory=10, gtol=1e-6, ftol=1e-12):
    """Minimise a smooth function with L-BFGS.

    Parameters
    ----------
    fun : callable
        ``fun(x) -> (f, g)``: objective (float) and its gradient (ndarray, shape (n,)).
    x0 : array_like, shape (n,)
        Starting point.
    max_iter : int
        Maximum number of iterations.
    memory : int
        Number of correction pairs kept (the "m" of L-BFGS).
    gtol : float
        Stop when ``max|g| <= gtol``.
    ftol : float
        Stop when the relative decrease of ``f`` in one iteration is below ``ftol``
        (``(f_old - f) <= ftol * max(|f_old|, |f|, 1)``, SciPy's ``factr`` test).

    Returns
    -------
    OptimizeResult
        Never contains NaN: a non-finite objective or gradient at ``x0`` raises ``ValueError``;
        later non-finite trial points are rejected by the line search.
    """
    x = np.array(x0, dtype=float).ravel()
    f, g = _evaluate(fun, x)
    nfev = 1
    if not (np.isfinite(f) and np.all(np.isfinite(g))):
        raise ValueError("objective or gradient is not finite at the starting point")
    s_hist, y_hist, rho_hist = [], [], []
    message = "iteration limit reached"
    success = False
    nit = 0
    for nit in range(1, max_iter + 1):
        if np.max(np.abs(g)) <= gtol:
            message, success, nit = "gradient below gtol", True, nit - 1
            break
        direction = -_two_loop(g, s_hist, y_hist, rho_hist)
        slope = float(direction @ g)
        if not slope < 0:
            # Curvature information went bad (rounding): restart from steepest descent.
            s_hist.clear(), y_hist.clear(), rho_hist.clear()
            direction, slope = -g, -float(g @ g)
        # First iteration: a unit-length step; later the quasi-Newton step length 1.
        step0 = 1.0 if s_hist else min(1.0, 1.0 / max(np.max(np.abs(g)), 1e-300))
        step, f_new, g_new, evals = _wolfe_search(fun, x, f, g, direction, slope, step0)
        nfev += evals
        if step is None:
            message = "line search failed to find a lower point"
            success = np.max(np.abs(g)) <= np.sqrt(gtol)
            nit -= 1
            break
        s = step * direction
        y = g_new - g
        x = x + s
        f_old, f, g = f, f_new, g_new
        sy = float(s @ y)
        if sy > 1e-12 * float(y @ y):
            s_hist.append(s), y_hist.append(y), rho_hist.append(1.0 / sy)
            if len(s_hist) > memory:
                s_hist.pop(0), y_hist.pop(0), rho_hist.pop(0)
        if f_old - f <= ftol * max(abs(f_old), abs(f), 1.0):
            message, success = "relative reduction of f below ftol", True
            break
    return OptimizeResult(x=x, fun=float(f), jac=g, nit=nit, nfev=nfev, success=bool(success),
                          message=message)


def _evaluate(fun, x):
    f, g = fun(x)
    return float(f), np.asarray(g, dtype=float).ravel()


def _two_loop(g, s_hist, y_hist, rho_hist):
    """H_k g by the L-BFGS two-loop recursion (Nocedal & Wright Alg. 7.4)."""
    q = g.copy()
    alphas = []
    for s, y, rho in zip(reversed(s_hist), reversed(y_hist), reversed(rho_hist)):
        a = rho * float(s @ q)
        alphas.append(a)
        q -= a * y
    if s_hist:
        # Initial Hessian scaling gamma = s'y / y'y (N&W eq. 7.20).
        q *= float(s_hist[-1] @ y_hist[-1]) / float(y_hist[-1] @ y_hist[-1])
    for (s, y, rho), a in zip(zip(s_hist, y_hist, rho_hist), reversed(alphas)):
        b = rho * float(y @ q)
        q += (a - b) * s
    return q


def _wolfe_search(fun, x, f0, g0, d, slope0, step, c1=1e-4, c2=0.9, max_evals=30):
    """Strong-Wolfe line search (N&W Alg. 3.5 + zoom Alg. 3.6).

    Returns ``(step, f, g, n_evals)``; ``step`` is None when no acceptable point was found.
    """
    evals = 0
    prev_step, prev_f, prev_slope = 0.0, f0, slope0
    best = (None, f0, g0)
    for i in range(max_evals):
        f, g = _evaluate(fun, x + step * d)
        evals += 1
        if not (np.isfinite(f) and np.all(np.isfinite(g))):
            step = 0.5 * (prev_step + step)  # stepped into a non-finite region: shrink
            continue
        slope = float(g @ d)
        if f < best[1]:
            best = (step, f, g)
        if f > f0 + c1 * step * slope0 or (i > 0 and f >= prev_f):
            return _zoom(fun, x, f0, slope0, d, prev_step, prev_f, prev_slope, step, f, slope,
                         c1, c2, evals, max_evals, best)
        if abs(slope) <= -c2 * slope0:
            return step, f, g, evals
        if slope >= 0:
            return _zoom(fun, x, f0, slope0, d, step, f, slope, prev_step, prev_f, prev_slope,
                         c1, c2, evals, max_evals, best)
        prev_step, prev_f, prev_slope = step, f, slope
        step *= 2.0
    return best[0], best[1], best[2], evals


def _zoom(fun, x, f0, slope0, d, lo, f_lo, s_lo, hi, f_hi, s_hi, c1, c2, evals, max_evals,
          best):
    while evals < max_evals:
        step = _cubic_min(lo, f_lo, s_lo, hi, f_hi, s_hi)
        f, g = _evaluate(fun, x + step * d)
        evals += 1
        if not (np.isfinite(f) and np.all(np.isfinite(g))):
            hi, f_hi, s_hi = step, np.inf, 0.0
            continue
        slope = float(g @ d)
        if f < best[1]:
            best = (step, f, g)
        if f > f0 + c1 * step * slope0 or f >= f_lo:
            hi, f_hi, s_hi = step, f, slope
        else:
            if abs(slope) <= -c2 * slope0:
                return step, f, g, evals
            if slope * (hi - lo) >= 0:
                hi, f_hi, s_hi = lo, f_lo, s_lo
            lo, f_lo, s_lo = step, f, slope
        if abs(hi - lo) <= 1e-16 * max(abs(lo), abs(hi), 1e-300):
            break
    return best[0], best[1], best[2], evals


def _cubic_min(a, fa, da, b, fb, db):
    """Minimiser of the cubic interpolating (a, fa, da), (b, fb, db), safeguarded into the
    middle 80 % of the interval (bisection when the cubic is unusable)."""
    lo, hi = min(a, b), max(a, b)
    width = hi - lo
    step = 0.5 * (a + b)
    if np.isfinite(fb) and width > 0:
        d1 = da + db - 3.0 * (fa - fb) / (a - b)
        disc = d1 * d1 - da * db
        if disc >= 0:
            d2 = np.copysign(np.sqrt(disc), b - a)
            denom = db - da + 2.0 * d2
            if denom != 0:
                cand = b - (b - a) * (db + d2 - d1) / denom
                if np.isfinite(cand):
                    step = cand
    return float(np.clip(step, lo + 0.1 * width, hi - 0.1 * width))
